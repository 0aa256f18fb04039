"""The only shared rclpy helpers of seapup (node shells import these; pure cores never do).

- :mod:`seapup_common.ros.node`: node entry (``run_node``), parameters declared
  from a package's YAML, QoS profiles, Python logging routed to ROS logging;
- :mod:`seapup_common.ros.messages`: conversions between ROS messages and the
  pure contract's dataclasses (:mod:`seapup_common.contract`).
"""
