"""The per-sample messages as serialised bytes, both ways (rclpy shell code).

What :mod:`seapup_common.ros.messages` builds as message objects, this packs
straight into the bytes a publisher sends (:class:`~seapup_common.ros.cdr.Packer`),
with the same conventions: stamps t_k, frames ``odom_ned``/``base_link_frd``,
ENU/FLU through :mod:`seapup_common.frames`, the same covariances. Each
method's bytes deserialise to the message its ``messages`` counterpart builds
(tested field for field); the simulator publishes these, so a sample costs a
few microseconds per message instead of about fifty.

The other way, :class:`StampedDoubles` reads the bytes of a message that is a
header and then only ``float64`` fields (``TwistWithCovarianceStamped``,
``TwistStamped``, ``BladePitch``) in its usual frames with one
``struct.unpack_from``, and :func:`decode_velocity`, :func:`decode_reference`
and :func:`decode_blade_pitch` turn them into what
:func:`~seapup_common.ros.messages.velocity_from_msg`,
:func:`~seapup_common.ros.messages.reference_from_msg` and
:func:`~seapup_common.ros.messages.command_from_msg` return for the same
message, bit for bit. They answer None for anything else -- another frame,
another length, big-endian bytes, a non-finite reading: the caller then
deserialises with rclpy and converts as before, so a refusal (and its reason)
is exactly the typed path's, and bytes rclpy cannot read are refused too.
"""
from __future__ import annotations

import math
import struct

import numpy as np
from geometry_msgs.msg import (PoseWithCovarianceStamped, TwistStamped, TwistWithCovarianceStamped, Vector3Stamped,
                               WrenchStamped)
from nav_msgs.msg import Odometry, Path
from sensor_msgs.msg import Imu, Range
from rosgraph_msgs.msg import Clock
from seapup_msgs.msg import BladePitch, Depth, SampleManifest
from tf2_msgs.msg import TFMessage

from seapup_common import frames
from seapup_common.contract import Command, Reading, Reference
from seapup_common.ros.cdr import ENCAPSULATION_CDR_LE, Packer, Restamper
from seapup_common.ros.messages import UNKNOWN_VARIANCE

__all__ = ["SampleEncoder", "command_bytes", "StampedDoubles", "decode_velocity", "decode_reference",
           "decode_blade_pitch", "blade_pitch_values", "decode_clock"]

_NS = 1_000_000_000


def _stamp(t_ns: int) -> list:
    return list(divmod(int(t_ns), _NS))


def _three(variance) -> list:
    """A reading's variance as three floats (a scalar applies to each component)."""
    return np.broadcast_to(np.asarray(variance, float), 3).tolist()


def _diagonal(values: list) -> list:
    """The row-major n x n matrix with ``values`` on its diagonal."""
    n = len(values)
    matrix = [0.0] * (n * n)
    matrix[::n + 1] = values
    return matrix


_COMMAND = Packer(BladePitch)


def command_bytes(blade_pitch, t_ns: int) -> bytes:
    """A controller's command: :func:`~seapup_common.ros.messages.command_to_msg` (no frame) as bytes."""
    return _COMMAND.pack(_stamp(t_ns) + np.asarray(blade_pitch, float).tolist())


class SampleEncoder:
    """Bytes of each message the simulator publishes at a sample; one packer per message kind."""

    def __init__(self):
        frd, ned = {"header.frame_id": frames.FRAME_FRD}, {"header.frame_id": frames.FRAME_NED}
        self._applied = Packer(BladePitch, frd)
        self._velocity = Packer(TwistWithCovarianceStamped, frd)
        self._imu = Packer(Imu, frd)
        self._position = Packer(PoseWithCovarianceStamped, ned)
        self._depth = Packer(Depth, ned)
        self._altitude = Packer(Range, frd)
        self._truth = Packer(Odometry, {**ned, "child_frame_id": frames.FRAME_FRD})
        self._odom = Packer(Odometry, {"header.frame_id": frames.FRAME_ENU, "child_frame_id": frames.FRAME_FLU})
        self._vector = {frame: Packer(Vector3Stamped, {"header.frame_id": frame})
                        for frame in (frames.FRAME_NED, frames.FRAME_FRD)}
        self._wrench = {frame: Packer(WrenchStamped, {"header.frame_id": frame})
                        for frame in (frames.FRAME_NED, frames.FRAME_FRD)}
        self._tf = Packer(TFMessage, {"transforms[0].header.frame_id": frames.FRAME_ENU,
                                      "transforms[0].child_frame_id": frames.FRAME_FLU}, {"transforms": 1})
        self._paths: dict[int, Packer] = {}
        self._clock = Packer(Clock)
        self._manifests: dict[tuple, Restamper] = {}

    def clock(self, t_ns: int) -> bytes:
        """``rosgraph_msgs/Clock`` at ``t_ns``."""
        return self._clock.pack(_stamp(t_ns))

    def manifest(self, topics, t_ns: int) -> bytes:
        """``SampleManifest`` of ``topics`` (one serialisation per distinct list, then restamped)."""
        key = tuple(topics)
        if key not in self._manifests:
            self._manifests[key] = Restamper(SampleManifest(topics=list(key)))
        return self._manifests[key].pack(t_ns)

    def applied(self, blade_pitch, t_ns: int) -> bytes:
        """:func:`~seapup_common.ros.messages.command_to_msg` in ``base_link_frd``."""
        return self._applied.pack(_stamp(t_ns) + np.asarray(blade_pitch, float).tolist())

    def velocity(self, velocity: Reading, rates: Reading, t_ns: int) -> bytes:
        """:func:`~seapup_common.ros.messages.velocity_to_msg`."""
        return self._velocity.pack(_stamp(t_ns) + np.asarray(velocity.value, float).tolist()
                                   + np.asarray(rates.value, float).tolist()
                                   + _diagonal(_three(velocity.variance) + _three(rates.variance)))

    def imu(self, attitude: Reading, rates: Reading, specific_force, t_ns: int) -> bytes:
        """:func:`~seapup_common.ros.messages.imu_to_msg` (accelerometer covariance zero: unknown)."""
        q = frames.euler_to_quaternion(*attitude.value).tolist()
        return self._imu.pack(_stamp(t_ns) + q + _diagonal(_three(attitude.variance))
                              + np.asarray(rates.value, float).tolist() + _diagonal(_three(rates.variance))
                              + np.asarray(specific_force, float).tolist() + [0.0] * 9)

    def position(self, position: Reading, t_ns: int) -> bytes:
        """:func:`~seapup_common.ros.messages.position_to_msg` (orientation not measured)."""
        return self._position.pack(_stamp(t_ns) + np.asarray(position.value, float).tolist() + [0.0, 0.0, 0.0, 1.0]
                                   + _diagonal(_three(position.variance) + [UNKNOWN_VARIANCE] * 3))

    def depth(self, depth: Reading, t_ns: int) -> bytes:
        """:func:`~seapup_common.ros.messages.depth_to_msg`."""
        return self._depth.pack(_stamp(t_ns) + [float(depth.value), float(depth.variance)])

    def altitude(self, altitude: Reading, t_ns: int, *, field_of_view: float, min_range: float,
                 max_range: float) -> bytes:
        """:func:`~seapup_common.ros.messages.altitude_to_msg` (+inf when invalid, REP-117)."""
        reading = [float(altitude.value), float(altitude.variance)] if altitude.valid else [math.inf, 0.0]
        return self._altitude.pack(_stamp(t_ns) + [Range.ULTRASOUND, float(field_of_view), float(min_range),
                                                   float(max_range)] + reading)

    def odometry_ned(self, state, t_ns: int) -> bytes:
        """:func:`~seapup_common.ros.messages.odometry_ned`: odom_ned -> base_link_frd, covariances zero."""
        x = np.asarray(state, float)
        q = frames.euler_to_quaternion(*x[3:6]).tolist()
        return self._truth.pack(_stamp(t_ns) + x[:3].tolist() + q + [0.0] * 36 + x[6:12].tolist() + [0.0] * 36)

    def odometry_enu(self, state, t_ns: int) -> bytes:
        """:func:`~seapup_common.ros.messages.odometry_enu`: REP-105 odom -> base_link."""
        x = np.asarray(state, float)
        q = frames.orientation_ned_frd_to_enu_flu(frames.euler_to_quaternion(*x[3:6])).tolist()
        return self._odom.pack(_stamp(t_ns) + frames.ned_to_enu(x[:3]).tolist() + q + [0.0] * 36
                               + frames.frd_to_flu(x[6:9]).tolist() + frames.frd_to_flu(x[9:12]).tolist()
                               + [0.0] * 36)

    def transforms_enu(self, state, t_ns: int) -> bytes:
        """:func:`~seapup_common.ros.messages.transforms_enu`: ``/tf``, odom -> base_link."""
        x = np.asarray(state, float)
        q = frames.orientation_ned_frd_to_enu_flu(frames.euler_to_quaternion(*x[3:6])).tolist()
        return self._tf.pack(_stamp(t_ns) + frames.ned_to_enu(x[:3]).tolist() + q)

    def path_ned(self, points, t_ns: int) -> bytes:
        """:func:`~seapup_common.ros.messages.path_ned`: a polyline in ``odom_ned`` (the umbilical's shape)."""
        xyz = np.asarray(points, float).reshape(-1, 3)
        n = len(xyz)
        if n not in self._paths:
            strings = {"header.frame_id": frames.FRAME_NED, **{f"poses[{i}].header.frame_id": frames.FRAME_NED
                                                               for i in range(n)}}
            self._paths[n] = Packer(Path, strings, {"poses": n})
        stamp = _stamp(t_ns)
        values = list(stamp)
        for p in xyz.tolist():
            values += stamp + p + [0.0, 0.0, 0.0, 1.0]
        return self._paths[n].pack(values)

    def vector3_stamped(self, vector, t_ns: int, frame_id: str) -> bytes:
        """:func:`~seapup_common.ros.messages.vector3_stamped` (``odom_ned`` or ``base_link_frd``)."""
        return self._vector[frame_id].pack(_stamp(t_ns) + np.asarray(vector, float).tolist())

    def wrench_stamped(self, wrench, t_ns: int, frame_id: str) -> bytes:
        """:func:`~seapup_common.ros.messages.wrench_stamped` (``odom_ned`` or ``base_link_frd``)."""
        return self._wrench[frame_id].pack(_stamp(t_ns) + np.asarray(wrench, float).tolist())


class StampedDoubles:
    """Read the bytes of a ``std_msgs/Header`` + ``float64`` fields message in one of a few frames.

    For each frame the layout is fixed (XCDR1 little-endian, as :class:`~seapup_common.ros.cdr.Packer`
    writes it and ``rmw_fastrtps`` sends it): the stamp, the frame's length and bytes, padding to 8, then
    the doubles. :meth:`decode` checks the encapsulation, the total length and the frame bytes and unpacks
    the rest in one call; anything else is not decoded (None), never guessed at.

    Parameters
    ----------
    msg_type : type
        A generated message class whose fields after the header are all ``float64`` (checked: a packed
        message of distinct values must read back the same, else ``TypeError``).
    frame_ids : iterable of str
        The frames read (the frame of any other message: None).

    Examples
    --------
    >>> from seapup_msgs.msg import BladePitch
    >>> reader = StampedDoubles(BladePitch, ["base_link_frd"])
    >>> reader.decode(command_bytes([0.1, 0.2, 0.3, 0.4], 1_500_000_000)) is None   # no frame: not read
    True
    >>> reader.decode(SampleEncoder().applied([0.1, 0.2, 0.3, 0.4], 1_500_000_000))
    (1500000000, 'base_link_frd', (0.1, 0.2, 0.3, 0.4))
    """

    def __init__(self, msg_type: type, frame_ids):
        self.msg_type = msg_type
        self._layouts: dict[int, list] = {}   # total length -> [(frame bytes, frame, struct)]
        for frame in frame_ids:
            packer = Packer(msg_type, {"header.frame_id": frame})
            count = len(packer.fields) - 2
            text = frame.encode() + b"\x00"
            pad = -(12 + len(text)) % 8
            layout = struct.Struct(f"<iI{4 + len(text)}s{pad}x{count}d")
            probe = [3, 4] + [float(i) + 0.5 for i in range(count)]
            if len(ENCAPSULATION_CDR_LE) + layout.size != packer.size or \
                    layout.unpack_from(packer.pack(probe), 4) != (3, 4, struct.pack("<I", len(text)) + text,
                                                                    *probe[2:]):
                raise TypeError(f"{msg_type.__name__} is not a header and float64 fields")
            self._layouts.setdefault(packer.size, []).append((layout.unpack_from(packer.pack(probe), 4)[2], frame,
                                                              layout))

    def decode(self, data: bytes) -> tuple[int, str, tuple] | None:
        """(stamp [ns], frame, the doubles in field order), or None when ``data`` is not one of the layouts."""
        layouts = self._layouts.get(len(data))
        if layouts is None or data[:4] != ENCAPSULATION_CDR_LE:
            return None
        for text, frame, layout in layouts:
            sec, nanosec, found, *values = layout.unpack_from(data, 4)
            if found == text:
                return sec * _NS + nanosec, frame, tuple(values)
        return None


def _finite(values) -> bool:
    return all(map(math.isfinite, values))


def _frozen(values) -> np.ndarray:
    arr = np.array(values, dtype=float)
    arr.setflags(write=False)
    return arr


_VELOCITY = StampedDoubles(TwistWithCovarianceStamped, [frames.FRAME_FRD])
_REFERENCE = StampedDoubles(TwistStamped, [frames.FRAME_FRD, ""])
_BLADE_PITCH = StampedDoubles(BladePitch, [frames.FRAME_FRD, ""])
_CLOCK = struct.Struct("<iI")


def decode_velocity(data: bytes) -> tuple[int, Reading, Reading] | None:
    """(stamp [ns], velocity, rates) of a ``TwistWithCovarianceStamped``'s bytes in ``base_link_frd``: what
    :func:`~seapup_common.ros.messages.velocity_from_msg` returns for it (values and covariance diagonals
    as read-only arrays, stamped t). None for any other message or a reading with a non-finite value or
    variance (what the typed path refuses, with its reason)."""
    decoded = _VELOCITY.decode(data)
    if decoded is None:
        return None
    t_ns, _, values = decoded
    variances = values[6::7]           # the covariance's diagonal (row-major 6 x 6 after the twist)
    if not _finite(values[:6] + variances):
        return None
    t = t_ns * 1e-9
    return (t_ns, Reading(_frozen(values[:3]), t, _frozen(variances[:3])),
            Reading(_frozen(values[3:6]), t, _frozen(variances[3:])))


def decode_reference(data: bytes) -> tuple[int, Reference] | None:
    """(stamp [ns], reference (u, v, w, r)) of a ``TwistStamped``'s bytes in ``base_link_frd`` or no frame:
    :func:`~seapup_common.ros.messages.reference_from_msg`, which raises the same ContractError for a
    non-finite value. None for any other message."""
    decoded = _REFERENCE.decode(data)
    if decoded is None:
        return None
    t_ns, _, (x, y, z, _p, _q, r) = decoded
    return t_ns, Reference([x, y, z, r])


def blade_pitch_values(data: bytes) -> tuple[int, tuple] | None:
    """(stamp [ns], the four pitches as read, unchecked) of a ``BladePitch``'s bytes in ``base_link_frd`` or no
    frame; None for any other message (the simulator checks a command itself, counting what it refuses)."""
    decoded = _BLADE_PITCH.decode(data)
    return None if decoded is None else (decoded[0], decoded[2])


def decode_blade_pitch(data: bytes) -> tuple[int, Command] | None:
    """(stamp [ns], command) of a ``BladePitch``'s bytes in ``base_link_frd`` or no frame:
    :func:`~seapup_common.ros.messages.command_from_msg`, which raises the same InvalidBladePitchError for
    a non-finite pitch. None for any other message."""
    decoded = blade_pitch_values(data)
    if decoded is None:
        return None
    t_ns, pitch = decoded
    return t_ns, Command(np.array(pitch, float), t_ns * 1e-9)


def decode_clock(data: bytes) -> int | None:
    """The time [ns] of a ``rosgraph_msgs/Clock``'s bytes, or None if they are not one."""
    if len(data) != len(ENCAPSULATION_CDR_LE) + _CLOCK.size or data[:4] != ENCAPSULATION_CDR_LE:
        return None
    sec, nanosec = _CLOCK.unpack_from(data, 4)
    return sec * _NS + nanosec
