"""A controller's per-sample inputs from serialised bytes (raw subscriptions).

A velocity controller hears three or four messages per sample (the velocity,
the applied blade pitch, ``/clock``, often a reference). Typed subscriptions
build a message object per message -- a dozen nested objects for a
``TwistWithCovarianceStamped`` -- only to read a few numbers out of it. These
read the numbers straight from the bytes
(:mod:`seapup_common.ros.sample_bytes`) and give what the typed conversions of
:mod:`seapup_common.ros.messages` give, bit for bit. Whatever the fast readers
do not take (another frame or length, a non-finite value) is deserialised by
rclpy and converted as before, so every refusal and its reason is the typed
path's; bytes rclpy cannot deserialise either are refused as malformed, in the
same counters.
"""
from __future__ import annotations

from geometry_msgs.msg import TwistStamped, TwistWithCovarianceStamped
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock
from seapup_msgs.msg import BladePitch

from seapup_common.contract import Command, ContractError, Reference
from seapup_common.ros.messages import SampleFeed, command_from_msg, reference_from_msg, stamp_to_ns
from seapup_common.ros.sample_bytes import decode_blade_pitch, decode_clock, decode_reference, decode_velocity

__all__ = ["MalformedMessageError", "message_of", "reference_of", "command_of", "clock_of", "RawSampleFeed"]


class MalformedMessageError(ContractError):
    """Bytes that rclpy cannot deserialise as the subscription's message type."""


def message_of(data: bytes, msg_type: type):
    """``data`` deserialised as ``msg_type`` by rclpy (MalformedMessageError when it cannot)."""
    try:
        return deserialize_message(data, msg_type)
    except Exception as exc:  # noqa: BLE001 - rclpy raises RMWError and others for bytes it cannot read
        raise MalformedMessageError(f"{len(data)} bytes are not a {msg_type.__name__}: {exc}") from None


def reference_of(data: bytes) -> tuple[Reference, int]:
    """(reference, stamp [ns]) of a ``TwistStamped``'s bytes: :func:`~seapup_common.ros.messages.reference_from_msg`
    (ContractError when refused, MalformedMessageError when unreadable)."""
    decoded = decode_reference(data)
    if decoded is not None:
        return decoded[1], decoded[0]
    msg = message_of(data, TwistStamped)
    return reference_from_msg(msg), stamp_to_ns(msg.header.stamp)


def command_of(data: bytes) -> tuple[Command, int]:
    """(command, stamp [ns]) of a ``BladePitch``'s bytes: :func:`~seapup_common.ros.messages.command_from_msg`
    (InvalidBladePitchError when refused, MalformedMessageError when unreadable: both ValueErrors)."""
    decoded = decode_blade_pitch(data)
    if decoded is not None:
        return decoded[1], decoded[0]
    msg = message_of(data, BladePitch)
    return command_from_msg(msg), stamp_to_ns(msg.header.stamp)


def clock_of(data: bytes) -> int:
    """The time [ns] of a ``rosgraph_msgs/Clock``'s bytes (MalformedMessageError when unreadable)."""
    t_ns = decode_clock(data)
    return t_ns if t_ns is not None else stamp_to_ns(message_of(data, Clock).clock)


class RawSampleFeed:
    """:class:`~seapup_common.ros.messages.SampleFeed` for velocity bytes: the same stamp gate, collector and
    policy, the same refusals (and malformed bytes refused with them).

    Parameters
    ----------
    feed : SampleFeed
        The typed feed whose collector, policy, stamp gate and ``rejected`` callback are used.
    """

    def __init__(self, feed: SampleFeed):
        self.feed = feed

    def clock(self, data: bytes, logger) -> int | None:
        """The sample to answer after this ``/clock`` message (``SampleFeed.clock`` of the bytes), or None;
        unreadable bytes are ignored with a warning on ``logger`` (no clock publisher sends such)."""
        try:
            return self.feed.policy.on_clock(clock_of(data))
        except MalformedMessageError as exc:
            logger.warn(f"/clock message ignored: {exc}", throttle_duration_sec=2.0)
            return None

    def velocity(self, data: bytes) -> int | None:
        """The sample to answer after this velocity message, or None (refused: counted by ``rejected``)."""
        feed = self.feed
        decoded = decode_velocity(data)
        if decoded is None:   # not the plain layout, or refused: the typed path, with its reasons
            try:
                msg = message_of(data, TwistWithCovarianceStamped)
            except MalformedMessageError as exc:
                feed.rejected(str(exc))
                return None
            return feed.velocity(msg)
        t_ns, velocity, rates = decoded
        if not feed.stamps.accept(t_ns):
            feed.rejected(feed.stamps.why(t_ns))
            return None
        feed.collector.latest["velocity"] = velocity
        feed.collector.latest["rates"] = rates
        return feed.policy.on_sample(t_ns)
