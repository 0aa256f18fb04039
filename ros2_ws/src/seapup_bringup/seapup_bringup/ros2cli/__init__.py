"""The substitute for the parts of ros2cli, launch and rosbag2 that the PyPI wheels lack: ``./seapup launch``
(:mod:`~seapup_bringup.ros2cli.launch`), ``./seapup ros2 ...`` (topic, node, param, service, action) and
``./seapup bag`` (record, play, info)."""
