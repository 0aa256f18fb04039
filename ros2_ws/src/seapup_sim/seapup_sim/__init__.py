"""Seapup ROV simulation: vehicle and environment models (pure core) and node shells.

Pure-core modules import numpy/scipy only and never rclpy; node modules
(``*_node.py``) are thin rclpy shells over them.
"""
