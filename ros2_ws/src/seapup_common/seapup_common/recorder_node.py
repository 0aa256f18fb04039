"""The ``recorder`` node: records topics into a rosbag2 (v9, MCAP) bag, as ``ros2 bag record``.

A thin shell over :class:`seapup_common.bag.BagWriter`. It subscribes raw
(CDR bytes, nothing decoded) to each entry of ``topics`` -- ``/topic`` as soon
as the graph reports its type, ``/topic:pkg/msg/Type`` at once, so a recorder
started before the publishers misses nothing (its bag channel is declared, with
the publishers' offered QoS, when they appear or at its first message, and a
best-effort publisher gets a best-effort subscription) -- or, with ``all``, to every
topic that appears (less those matching ``exclude``). Like rosbag2 it adapts
its subscription QoS to the publishers (:func:`seapup_common.ros.graph.adapted_qos`)
and stores their offered QoS profiles and the topic's type hash.

Times are the graph's: the log time is the graph's time when the message was
received -- the node clock on a wall-clock graph; under sim time
(``use_sim_time``) the ``/clock`` value current when DDS received the message,
raised to the time its samples' header stamps show the graph has reached and
never before the message's own stamp (the rules, ``max_stamp_lead`` and
``max_stamp_jump``: :mod:`seapup_common.log_time`); the publish time the DDS
source timestamp on a wall clock and, under sim time (which stands still
between samples), the log time.

A sample said again is recorded once: a message that carries its sample's
time (header-first types, ``/clock``'s Clock, ``/tf``'s TFMessage) and whose
bytes equal the previous message recorded on its topic is not written
(``record_repeats`` true writes every copy, as rosbag2 does). A lockstep graph
says a sample again by design (the simulator's handshake repeats t_0 on
``/clock`` until the first command; after a hold it says the held sample again
when it resumes before the sample was answered), so without this how many
copies a bag holds would depend on wall time.

What the transport lost is said: a sample DDS reports lost to a subscription (a
reliable writer that dropped it from its history before repairing it, a
best-effort one that was not delivered) is counted per topic, warned about at
once and named when the bag is closed -- a bag with holes never looks whole
(a publisher that matches after a topic's first message is logged too).

The bag is flushed and fsync'd every ``flush_interval`` (a ``kill -9`` loses
at most that) and finalised on SIGINT/SIGTERM or after ``max_duration``
seconds of graph time.
"""
from __future__ import annotations

import importlib
import os
import re
import time
from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from rcl_interfaces.msg import ParameterDescriptor, ParameterType
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from seapup_common.bag import BagWriter, header_stamp_ns, make_typestore
from seapup_common.log_time import SimLogTime
from seapup_common.ros.graph import adapted_qos, qos_to_rosbag2
from seapup_common.ros.node import declare_from_package_file, path_or_empty, regular_expression, run_node, topic_names
from seapup_common.topics import CLOCK

__all__ = ["RecorderNode", "main", "message_class", "project_msg_files", "default_bag_path"]

#: Types that carry their sample's time though they do not begin with a header (see the module docstring).
SAMPLE_TIMED_TYPES = ("rosgraph_msgs/msg/Clock", "tf2_msgs/msg/TFMessage")
#: Subscriptions for topics named with their type before any publisher exists.
EAGER_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)


def message_class(type_name: str):
    """The Python class of ``pkg/msg/Type`` (rclpy has no type-less subscription)."""
    try:
        package, kind, name = type_name.split("/")
        return getattr(importlib.import_module(f"{package}.{kind}"), name)
    except (ValueError, ImportError, AttributeError):
        raise ValueError(f"unknown message type {type_name[:80]!r} (expected pkg/msg/Type of an "
                         "installed package)") from None


def project_msg_files() -> dict[str, Path]:
    """The .msg files of seapup_msgs, by full type name."""
    share = Path(get_package_share_directory("seapup_msgs"))
    return {f"seapup_msgs/msg/{p.stem}": p for p in sorted((share / "msg").glob("*.msg"))}


def default_bag_path() -> Path:
    root = Path(os.environ.get("SEAPUP_ROOT", "."))
    return root / "bags" / time.strftime("rosbag2_%Y_%m_%d-%H_%M_%S", time.gmtime())


class RecorderNode(Node):
    """rclpy shell around a :class:`BagWriter` (see module docstring)."""

    #: Its callbacks take the message info (DDS receive and source times): always spun by the single-threaded
    #: executor (rclpy 7.1's events executor cannot deliver it; :func:`seapup_common.ros.node.declare_executor`).
    MESSAGE_INFO = True

    def __init__(self, **kwargs):
        super().__init__("recorder", **kwargs)
        p = declare_from_package_file(self, "seapup_common", "recorder.yaml", {
            "topics": ParameterDescriptor(type=ParameterType.PARAMETER_STRING_ARRAY, read_only=True),
        }, section="recorder", ranges={"flush_interval": (0.0, 3600.0), "max_bag_size": (0, 2**62),
                                       "max_bag_duration": (0.0, 1e7), "max_stamp_lead": (0.0, 3600.0),
                                       "max_stamp_jump": (0.0, 1e7),
                                       "max_duration": (0.0, 1e7), "discovery_period": (0.01, 60.0)},
            allowed={"topics": topic_names(typed=True), "exclude": regular_expression(),
                     "bag_path": path_or_empty("the bag directory to create (must not exist)")})
        entries = [t for t in p["topics"] if t]
        self.record_all = bool(p["all"])
        self.exclude = re.compile(p["exclude"]) if p["exclude"] else None
        if not entries and not self.record_all:
            raise ValueError("nothing to record: give topics or set all:=true")
        self.wanted = [e.split(":", 1)[0] for e in entries]
        self.sim_time = bool(self.get_parameter("use_sim_time").value)
        self.record_repeats = bool(p["record_repeats"])
        self.repeats = 0  # samples said again, not recorded again
        self._last: dict[str, bytes] = {}  # per sample-timed topic: the bytes last recorded
        # under sim time: the log times (seapup_common.log_time: /clock at receipt, the time so far, stamps)
        self.log_times = SimLogTime(int(p["max_stamp_lead"] * 1e9), int(p["max_stamp_jump"] * 1e9))
        if self.sim_time:
            from rosgraph_msgs.msg import Clock
            self.create_subscription(Clock, CLOCK, self._on_clock, EAGER_QOS)
        path = p["bag_path"] or str(default_bag_path())
        self.typestore = make_typestore(project_msg_files())
        self.bag = BagWriter(path, self.typestore, flush_interval=p["flush_interval"],
                             max_bag_size=p["max_bag_size"], max_bag_duration=p["max_bag_duration"]).open()
        self.stamped: dict[str, bool] = {}
        self.sample_timed: dict[str, bool] = {}  # the message carries its sample's time (repeats: once)
        self.drain_on_shutdown = True  # run_node takes the messages already received before closing,
        self.drain_budget = 8.0        # however many a recorder behind a fast graph has queued (it stops when idle)
        self.received = 0
        self.last_received_ns = 0
        self._heard: set[str] = set()  # topics a message has arrived on
        self.max_duration = float(p["max_duration"])
        self._first_ns: int | None = None
        self.subscribed: dict[str, str] = {}
        self.subscriptions_by_topic: dict = {}
        self.eager: set[str] = set()  # typed topics subscribed before any publisher was seen
        self.lost: dict[str, int] = {}  # per topic: samples DDS reported lost (module docstring)
        for entry in entries:
            if ":" in entry:
                self._subscribe(*entry.split(":", 1), publishers=[])
        self.discovery = self.create_timer(p["discovery_period"], self._discover)
        self.get_logger().info(f"recording {', '.join(self.wanted) or 'all topics'} into {self.bag.path}")

    def _discover(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if topic in self.subscribed:
                if topic in self.eager:
                    self._adapt_eager(topic)
                continue
            wanted = topic in self.wanted or (self.record_all and not (self.exclude and self.exclude.search(topic)))
            if not wanted:
                continue
            publishers = self.get_publishers_info_by_topic(topic)
            if not publishers:
                continue  # only subscribers so far: wait for a publisher to know its QoS
            self._subscribe(topic, types[0], publishers)
        if not self.record_all and len(self.subscribed) == len(self.wanted) and not self.eager:
            self.discovery.cancel()

    def _subscribe(self, topic: str, type_name: str, publishers) -> None:
        qos = adapted_qos(publishers) if publishers else EAGER_QOS
        self.subscriptions_by_topic[topic] = self.create_subscription(
            message_class(type_name), topic, lambda raw, info, t=topic: self._record(t, raw, info), qos, raw=True,
            event_callbacks=self._events(topic))
        if publishers:
            self._add_to_bag(topic, type_name, publishers)
        else:
            self.eager.add(topic)  # the bag's channel waits for the publishers' offered QoS
        self.subscribed[topic] = type_name
        fields = self.typestore.fielddefs.get(type_name, ((), []))[1]
        self.stamped[topic] = bool(fields) and fields[0][0] == "header"
        self.sample_timed[topic] = self.stamped[topic] or type_name in SAMPLE_TIMED_TYPES
        self.get_logger().info(f"recording {topic} [{type_name}]")

    def _events(self, topic: str) -> SubscriptionEventCallbacks:
        """A subscription's DDS events: samples lost, publishers matched (module docstring)."""
        return SubscriptionEventCallbacks(message_lost=lambda status, t=topic: self._on_lost(t, status),
                                          matched=lambda status, t=topic: self._on_matched(t, status),
                                          use_default_callbacks=False)

    def _on_lost(self, topic: str, status) -> None:
        self.lost[topic] = self.lost.get(topic, 0) + int(status.total_count_change)
        self.get_logger().warn(f"{topic}: {int(status.total_count_change)} sample(s) lost in transport "
                               f"({self.lost[topic]} so far): the bag has a hole there")

    def _on_matched(self, topic: str, status) -> None:
        if int(status.current_count_change) > 0 and topic in self._heard:  # after the first message: a newcomer
            self.get_logger().info(f"{topic}: a publisher matched after the first message "
                                   f"({int(status.current_count)} now)")

    def _add_to_bag(self, topic: str, type_name: str, publishers) -> None:
        offered = [qos_to_rosbag2(i.qos_profile) for i in publishers]
        type_hash = str(publishers[0].topic_type_hash) if publishers else ""
        self.bag.add_topic(topic, type_name, qos=offered, type_hash=type_hash)

    def _adapt_eager(self, topic: str) -> None:
        """A typed topic's publishers appeared: record their QoS, and match a best-effort or latched one.

        The eager subscription is reliable and volatile; it cannot match a
        best-effort publisher, and it never gets what a transient-local
        publisher (``/tf_static``) latched before the two matched: then it is
        replaced by one adapted to the publishers -- for a latched topic only
        while nothing has arrived on it (else the replacement would take the
        latched message a second time).
        """
        publishers = self.get_publishers_info_by_topic(topic)
        if not publishers:
            return
        self.eager.discard(topic)
        adapted = adapted_qos(publishers)
        latched = adapted.durability == DurabilityPolicy.TRANSIENT_LOCAL and topic not in self._heard
        if adapted.reliability != EAGER_QOS.reliability or latched:
            self.destroy_subscription(self.subscriptions_by_topic[topic])
            type_name = self.subscribed[topic]
            self.subscriptions_by_topic[topic] = self.create_subscription(
                message_class(type_name), topic, lambda raw, info, t=topic: self._record(t, raw, info),
                adapted, raw=True, event_callbacks=self._events(topic))
        if topic not in self.bag.topics:
            self._add_to_bag(topic, self.subscribed[topic], publishers)

    def _on_clock(self, msg, info) -> None:
        self.log_times.on_clock(int(info.get("received_timestamp", 0)),
                                msg.clock.sec * 1_000_000_000 + msg.clock.nanosec)

    def _record(self, topic: str, raw: bytes, info) -> None:
        self.received += 1
        # when the middleware received it (the drain at a stop takes what came before the stop)
        self.last_received_ns = int(info.get("received_timestamp", 0)) or time.time_ns()
        if topic not in self.bag.topics:  # first message of a typed topic: its publisher exists now
            self._add_to_bag(topic, self.subscribed[topic], self.get_publishers_info_by_topic(topic))
        if topic not in self._heard:
            self._heard.add(topic)
            self.get_logger().info(f"first message on {topic}")  # the publisher's side has matched us too
        if not self.record_repeats and self.sample_timed.get(topic):
            raw = bytes(raw)
            if self._last.get(topic) == raw:
                self.repeats += 1   # the same sample said again (module docstring)
                return
            self._last[topic] = raw
        log_ns = self.get_clock().now().nanoseconds
        if self.sim_time:
            stamp = header_stamp_ns(raw) if self.stamped.get(topic) else None
            log_ns, distrusted = self.log_times.log_time(int(info.get("received_timestamp", 0)), stamp, log_ns)
            if distrusted:
                self.get_logger().warn(f"{topic}: header stamp {stamp * 1e-9:.3f} s is more than max_stamp_jump "
                                       f"ahead of the graph's time ({log_ns * 1e-9:.3f} s): logged at that time",
                                       throttle_duration_sec=5.0)
        publish_ns = log_ns if self.sim_time else int(info.get("source_timestamp", log_ns))
        self.bag.write(topic, raw, log_ns, publish_ns)
        if self._first_ns is None:
            self._first_ns = log_ns
        if self.max_duration > 0 and (log_ns - self._first_ns) * 1e-9 >= self.max_duration:
            self.get_logger().info(f"max_duration {self.max_duration:g} s reached")
            raise KeyboardInterrupt("max_duration reached")  # run_node finalises the bag

    def destroy_node(self):
        self.bag.close()
        said_again = f" ({self.repeats} repeats of a sample not recorded again)" if self.repeats else ""
        self.get_logger().info(f"closed {self.bag.path}: {self.bag.count} messages{said_again}")
        if self.lost:
            self.get_logger().warn("samples lost in transport, not in the bag: "
                                   + ", ".join(f"{t} {n}" for t, n in sorted(self.lost.items())))
        return super().destroy_node()


def main(args=None) -> int:
    return run_node(RecorderNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
