"""Seapup system identification (thesis ch. 6)."""
