"""The simulator node's ROS-facing helpers (parameter declaration, message building): shell code, kept out of
the pure cores of :mod:`seapup_sim`."""
