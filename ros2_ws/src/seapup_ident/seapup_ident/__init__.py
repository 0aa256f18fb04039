"""Seapup system identification (thesis ch. 6) and bag recording/replay."""
