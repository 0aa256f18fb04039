"""The simulator's per-sample messages as serialised bytes (rclpy shell code).

What :mod:`seapup_common.ros.messages` builds as message objects, this packs
straight into the bytes a publisher sends (:class:`~seapup_common.ros.cdr.Packer`),
with the same conventions: stamps t_k, frames ``odom_ned``/``base_link_frd``,
ENU/FLU through :mod:`seapup_common.frames`, the same covariances. Each
method's bytes deserialise to the message its ``messages`` counterpart builds
(tested field for field); the simulator publishes these, so a sample costs a
few microseconds per message instead of about fifty.
"""
from __future__ import annotations

import math

import numpy as np
from geometry_msgs.msg import PoseWithCovarianceStamped, TwistWithCovarianceStamped, Vector3Stamped, WrenchStamped
from nav_msgs.msg import Odometry, Path
from sensor_msgs.msg import Imu, Range
from rosgraph_msgs.msg import Clock
from seapup_msgs.msg import BladePitch, Depth, SampleManifest
from tf2_msgs.msg import TFMessage

from seapup_common import frames
from seapup_common.contract import Reading
from seapup_common.ros.cdr import Packer, Restamper
from seapup_common.ros.messages import UNKNOWN_VARIANCE

__all__ = ["SampleEncoder", "command_bytes"]

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
