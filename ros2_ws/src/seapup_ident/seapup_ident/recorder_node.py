"""The ``recorder`` node: records topics into a rosbag2/MCAP bag.

A thin shell over :class:`seapup_ident.bag.BagRecorder`. It subscribes raw
(CDR bytes, nothing decoded) to each entry of ``topics``: ``/topic`` is
subscribed as soon as the ROS graph reports its type, ``/topic:pkg/msg/Type``
at once (nothing published before that is missed for want of discovery). It
stamps messages with the receive time of the node clock and closes the bag
cleanly on SIGINT/SIGTERM.
"""
from __future__ import annotations

import importlib
import os
import time
from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy

from seapup_ident.bag import BagRecorder, make_typestore
from seapup_sim.node_main import declare_from_package_file, run_node

__all__ = ["RecorderNode", "main"]

RECORD_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)


def message_class(type_name: str):
    """The Python class of ``pkg/msg/Type`` (rclpy has no type-less subscription)."""
    package, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), name)


def project_msg_files() -> dict[str, Path]:
    """The .msg files of seapup_msgs, by full type name."""
    share = Path(get_package_share_directory("seapup_msgs"))
    return {f"seapup_msgs/msg/{p.stem}": p for p in sorted((share / "msg").glob("*.msg"))}


def default_bag_path() -> Path:
    root = Path(os.environ.get("SEAPUP_ROOT", "."))
    return root / "bags" / time.strftime("%Y%m%d_%H%M%S", time.gmtime())


class RecorderNode(Node):
    """rclpy shell around a :class:`BagRecorder` (see module docstring)."""

    def __init__(self, **kwargs):
        super().__init__("recorder", **kwargs)
        declare_from_package_file(self, "seapup_ident", "recorder.yaml")
        entries = [t for t in self.get_parameter("topics").value if t]
        self.wanted = [e.split(":", 1)[0] for e in entries]
        path = self.get_parameter("bag_path").value or str(default_bag_path())
        self.bag = BagRecorder(path, make_typestore(project_msg_files())).open()
        self.subscribed: dict[str, str] = {}
        for entry in entries:
            if ":" in entry:
                self._subscribe(*entry.split(":", 1))
        self.discovery = self.create_timer(self.get_parameter("discovery_period").value,
                                           self._discover)
        self.get_logger().info(f"recording {', '.join(self.wanted)} into {self.bag.path}")

    def _discover(self) -> None:
        known = dict(self.get_topic_names_and_types())
        for topic in self.wanted:
            if topic in self.subscribed or topic not in known:
                continue
            self._subscribe(topic, known[topic][0])
        if len(self.subscribed) == len(self.wanted):
            self.discovery.cancel()

    def _subscribe(self, topic: str, type_name: str) -> None:
        self.create_subscription(message_class(type_name), topic,
                                 lambda raw, t=topic, m=type_name: self._record(t, m, raw),
                                 RECORD_QOS, raw=True)
        self.subscribed[topic] = type_name
        self.get_logger().info(f"recording {topic} [{type_name}]")

    def _record(self, topic: str, type_name: str, raw: bytes) -> None:
        self.bag.write(topic, type_name, self.get_clock().now().nanoseconds, raw)

    def destroy_node(self):
        self.bag.close()
        self.get_logger().info(f"closed {self.bag.path}: {self.bag.count} messages")
        return super().destroy_node()


def main(args=None) -> int:
    return run_node(RecorderNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
