"""One message per control sample: what the ``open_loop`` and ``reference_schedule`` nodes share.

With ``lockstep`` the publisher answers each ``/clock`` sample t_k of a lockstep simulator once,
stamped t_k, with the schedule's value at t_k (the simulator repeats t_k until it is answered);
otherwise it publishes on a timer every ``sample_period`` for the time since it started (node
clock, so ``use_sim_time`` works). Nothing is sent before ``wait_for_subscribers`` subscriptions
are matched (the plant, a recorder), so no sample is lost at start. Every change of the publisher's matched
subscriptions after the first message is logged (:func:`sample_publisher_events`): a listener that drops out
mid-run shows in the node's log, and so does what was sent (:meth:`SamplePublisher.summary`, logged as the
node is destroyed).
"""
from __future__ import annotations

from typing import Callable

from rclpy.node import Node
from rosgraph_msgs.msg import Clock

from seapup_common.ros.graph import SubscriberGate
from seapup_common.ros.messages import stamp_to_ns
from seapup_common.ros.node import RELIABLE_QOS
from seapup_common.topics import CLOCK

__all__ = ["SamplePublisher", "sample_publisher_events"]


def sample_publisher_events(node: Node, sampler: Callable[[], "SamplePublisher | None"]):
    """Event callbacks for a :class:`SamplePublisher`'s publisher: a subscription matched or unmatched once
    samples flow is logged with the count (``sampler`` gives the publisher's sampler, None while it is built)."""
    from rclpy.event_handler import PublisherEventCallbacks

    def matched(status) -> None:
        current = sampler()
        if current is not None and current.sent:
            change = int(status.current_count_change)
            node.get_logger().info(f"{'a subscription matched' if change > 0 else 'a subscription left'} after "
                                   f"{current.sent} sample(s) sent: {int(status.current_count)} matched now")
    return PublisherEventCallbacks(matched=matched, use_default_callbacks=False)


class SamplePublisher:
    """Publish ``message_at(t_ns, elapsed)`` on ``publisher`` once per sample (see module docstring)."""

    def __init__(self, node: Node, publisher, message_at: Callable[[int, float], object], *, lockstep: bool,
                 sample_period: float, wait_for_subscribers: int):
        self.node, self.publisher, self.message_at = node, publisher, message_at
        self.gate = SubscriberGate([(publisher, wait_for_subscribers)])
        self.start = node.get_clock().now()
        self.sent = 0
        self.last_sent_ns: int | None = None   # the stamp of the newest sample sent
        self._last_clock = None
        if lockstep:
            node.create_subscription(Clock, CLOCK, self._on_clock, RELIABLE_QOS)
        else:
            node.create_timer(sample_period, self._tick)

    def _publish(self, t_ns: int, elapsed: float) -> None:
        if not self.gate.ready():
            return
        self.publisher.publish(self.message_at(t_ns, elapsed))
        self.sent += 1
        self.last_sent_ns = t_ns

    def summary(self) -> str:
        """What was sent, for the node's last log line (a listener that missed samples can be told from a
        publisher that skipped them)."""
        last = "none" if self.last_sent_ns is None else f"the last stamped {self.last_sent_ns * 1e-9:.3f} s"
        return f"sent {self.sent} sample(s) on {self.publisher.topic_name}, {last}"

    def _on_clock(self, msg: Clock) -> None:
        t_ns = stamp_to_ns(msg.clock)
        if t_ns == self._last_clock or not self.gate.ready():
            return  # the simulator repeats t_k until someone answers: answer once, when heard
        self._last_clock = t_ns
        self._publish(t_ns, t_ns * 1e-9)

    def _tick(self) -> None:
        now = self.node.get_clock().now()
        self._publish(now.nanoseconds, max((now - self.start).nanoseconds * 1e-9, 0.0))
