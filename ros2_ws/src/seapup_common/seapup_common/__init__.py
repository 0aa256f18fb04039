"""Seapup shared infrastructure: the pure contract every package agrees on, and the only
shared rclpy helpers.

Pure core (numpy/scipy/yaml/rosbags, never rclpy): :mod:`~seapup_common.blade_pitch`
(limits and validation), :mod:`~seapup_common.frames` (NED/FRD <-> ENU/FLU),
:mod:`~seapup_common.contract` (Measurement, Reference, Command, VelocityController),
:mod:`~seapup_common.config` (typed YAML loading), :mod:`~seapup_common.random_streams`,
:mod:`~seapup_common.bag` (rosbag2/MCAP I/O), :mod:`~seapup_common.parameters` (ROS
params files read without ROS), :mod:`~seapup_common.processes` (domain leases, child
node processes). rclpy shells: :mod:`seapup_common.ros`, and the ``recorder`` node
(:mod:`seapup_common.recorder_node`: topics into a rosbag2/MCAP bag, as ``ros2 bag record``).

Dependencies point one way: seapup_msgs <- seapup_common <- seapup_sim, seapup_control,
seapup_ident <- seapup_bringup.
"""

#: Python loggers of the pure cores (``logging.getLogger(__name__)`` in their modules): a node routes their
#: records to its ROS logger (:mod:`seapup_common.ros.node`), a campaign keeps them with each run's row.
CORE_LOGGERS = ("seapup_common", "seapup_sim", "seapup_control", "seapup_ident")
