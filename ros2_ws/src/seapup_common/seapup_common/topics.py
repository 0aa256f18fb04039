"""The Seapup graph's topics and their message types: the one list every recorder request is made from.

A recorder told ``/topic:pkg/msg/Type`` subscribes before any publisher exists (nothing of a
fast lockstep run is lost); :func:`typed` builds those entries from this table.
"""
from __future__ import annotations

__all__ = ["TOPIC_TYPES", "typed"]

#: Topic -> message type (rosbag2 spelling ``pkg/msg/Type``).
TOPIC_TYPES = {
    "/clock": "rosgraph_msgs/msg/Clock",
    "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
    "/seapup/thrusters/command": "seapup_msgs/msg/BladePitch",
    "/seapup/thrusters/applied": "seapup_msgs/msg/BladePitch",
    "/seapup/truth/odometry": "nav_msgs/msg/Odometry",
    "/seapup/sensors/velocity": "geometry_msgs/msg/TwistWithCovarianceStamped",
    "/seapup/sensors/imu": "sensor_msgs/msg/Imu",
    "/seapup/sensors/depth": "seapup_msgs/msg/Depth",
    "/seapup/sensors/position": "geometry_msgs/msg/PoseWithCovarianceStamped",
    "/seapup/sensors/altitude": "sensor_msgs/msg/Range",
    "/seapup/navigation/odometry": "nav_msgs/msg/Odometry",
    "/seapup/velocity_controller/reference": "geometry_msgs/msg/TwistStamped",
    "/seapup/position_controller/reference": "geometry_msgs/msg/PoseStamped",
    "/seapup/self_test/samples": "seapup_msgs/msg/SelfTestSample",
    "/seapup/identifier/model": "seapup_msgs/msg/IdentifiedModel",
}


def typed(*topics: str) -> list[str]:
    """``["/topic:pkg/msg/Type", ...]`` for a recorder's ``topics`` parameter.

    Raises
    ------
    KeyError
        Naming a topic missing from :data:`TOPIC_TYPES`.
    """
    unknown = [t for t in topics if t not in TOPIC_TYPES]
    if unknown:
        raise KeyError(f"no message type known for {unknown}; add them to seapup_common.topics.TOPIC_TYPES")
    return [f"{t}:{TOPIC_TYPES[t]}" for t in topics]
