"""Seapup autopilots (thesis ch. 4-5, 7): pure-core control laws and node shells."""
