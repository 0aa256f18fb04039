"""ROS messages <-> the pure contract's dataclasses (rclpy shell code).

One helper per message kind, each direction. The pure cores speak
:mod:`seapup_common.contract` (``Measurement``, ``Reading``, ``Command``) and
plain arrays in SI, NED/FRD; node shells convert at the edge with these. What
comes in from the graph is checked on the way: a message with a wrong length
or a non-finite number raises (:class:`~seapup_common.contract.ContractError`
or :class:`~seapup_common.blade_pitch.InvalidBladePitchError`) instead of
reaching a controller.

Conventions (README "Nodes"): stamps are sim time t_k; velocities and rates
in ``base_link_frd``; attitude as the quaternion of ``base_link_frd`` in
``odom_ned``; positions in ``odom_ned``; ENU/FLU only through
:mod:`seapup_common.frames`.
"""
from __future__ import annotations

import math

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import (PoseStamped, PoseWithCovarianceStamped, TransformStamped, TwistStamped,
                               TwistWithCovarianceStamped, Vector3Stamped, WrenchStamped)
from nav_msgs.msg import Odometry, Path
from sensor_msgs.msg import Imu, Range
from tf2_msgs.msg import TFMessage
from seapup_msgs.msg import BladePitch, Depth

from seapup_common import frames
from seapup_common.contract import (Command, ContractError, LatestReadings, Measurement, NavigationEstimate, Reading,
                                     Reference)

__all__ = ["ns_to_stamp", "stamp_to_ns", "command_to_msg", "command_from_msg",
           "velocity_to_msg", "velocity_from_msg", "imu_to_msg", "attitude_from_imu",
           "position_to_msg", "position_from_msg", "depth_to_msg", "depth_from_msg",
           "altitude_to_msg", "altitude_from_msg", "odometry_ned", "odometry_enu",
           "vector3_stamped", "wrench_stamped", "MeasurementCollector", "SampleFeed",
           "estimate_to_odometry", "estimate_from_odometry", "pose_setpoint_to_msg", "pose_setpoint_from_msg",
           "reference_to_msg", "reference_from_msg", "diagnostic_array", "transforms_enu", "static_transforms", "path_ned",
           "UNKNOWN_VARIANCE"]

#: Variance that says "this quantity is not measured" (e.g. orientation of an acoustic fix).
UNKNOWN_VARIANCE = 1e9


def ns_to_stamp(t_ns: int) -> Time:
    """A ``builtin_interfaces/Time`` from integer nanoseconds."""
    sec, nanosec = divmod(int(t_ns), 1_000_000_000)
    return Time(sec=sec, nanosec=nanosec)


def stamp_to_ns(stamp) -> int:
    """Integer nanoseconds of a stamp (``Time`` or ``Clock.clock``)."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _header(msg, t_ns: int, frame_id: str):
    msg.header.stamp = ns_to_stamp(t_ns)
    msg.header.frame_id = frame_id
    return msg


def _xyz(v) -> tuple[float, float, float]:
    return float(v.x), float(v.y), float(v.z)


def _set_xyz(target, values) -> None:
    target.x, target.y, target.z = (float(x) for x in values)


def _quaternion(q) -> np.ndarray:
    return np.array([q.x, q.y, q.z, q.w], float)


def _set_quaternion(target, q) -> None:
    target.x, target.y, target.z, target.w = (float(x) for x in q)


def _check_frame(msg, expected: str, what: str) -> None:
    """Refuse a sensor reading in any frame but the one its instrument publishes in (the simulator's, REP-105 and
    REP-156: body readings in ``base_link_frd``, positions and depths in ``odom_ned``): a reading in ``map``,
    ``odom`` or ``odom_enu`` would be fused with the wrong axes or sign."""
    if msg.header.frame_id != expected:
        raise ContractError(f"{what} must be in {expected}, got frame {msg.header.frame_id!r}")


def _diag3(cov, offset: int = 0) -> np.ndarray:
    c = np.asarray(cov, float).reshape(int(round(math.sqrt(len(cov)))), -1)
    return np.diag(c)[offset:offset + 3].copy()


# -- commands -----------------------------------------------------------------
def command_to_msg(command: Command, t_ns: int | None = None, frame_id: str = "") -> BladePitch:
    """A ``BladePitch`` for ``command``, stamped ``t_ns`` (default: the command's stamp)."""
    if t_ns is None:
        t_ns = 0 if math.isnan(command.stamp) else int(round(command.stamp * 1e9))
    msg = _header(BladePitch(), t_ns, frame_id)
    msg.pitch = [float(x) for x in command.blade_pitch]
    return msg


def command_from_msg(msg: BladePitch) -> Command:
    """The :class:`Command` of a ``BladePitch`` (raises InvalidBladePitchError if unusable)."""
    return Command(np.array(msg.pitch, float), stamp_to_ns(msg.header.stamp) * 1e-9)


# -- sensors --------------------------------------------------------------------
def velocity_to_msg(velocity: Reading, rates: Reading, t_ns: int) -> TwistWithCovarianceStamped:
    """Doppler log and rate gyros as a twist in base_link_frd (diagonal covariance)."""
    msg = _header(TwistWithCovarianceStamped(), t_ns, frames.FRAME_FRD)
    _set_xyz(msg.twist.twist.linear, velocity.value)
    _set_xyz(msg.twist.twist.angular, rates.value)
    msg.twist.covariance = np.diag(np.concatenate([np.broadcast_to(velocity.variance, 3),
                                                   np.broadcast_to(rates.variance, 3)])).ravel()
    return msg


def velocity_from_msg(msg: TwistWithCovarianceStamped) -> tuple[Reading, Reading]:
    """(velocity, rates) readings of a twist in base_link_frd."""
    _check_frame(msg, frames.FRAME_FRD, "velocity")
    t = stamp_to_ns(msg.header.stamp) * 1e-9
    var = np.diag(np.asarray(msg.twist.covariance, float).reshape(6, 6))
    m = Measurement.build(t, velocity=_xyz(msg.twist.twist.linear), rates=_xyz(msg.twist.twist.angular),
                          variances={"velocity": var[:3], "rates": var[3:]})
    return m.velocity, m.rates


def imu_to_msg(attitude: Reading, rates: Reading, specific_force, t_ns: int) -> Imu:
    """Attitude (as the quaternion of base_link_frd in odom_ned), rates and specific force.

    The accelerometer's covariance is left zero: unknown (REP-145).
    """
    msg = _header(Imu(), t_ns, frames.FRAME_FRD)
    _set_quaternion(msg.orientation, frames.euler_to_quaternion(*attitude.value))
    msg.orientation_covariance = np.diag(np.broadcast_to(attitude.variance, 3)).ravel()
    _set_xyz(msg.angular_velocity, rates.value)
    msg.angular_velocity_covariance = np.diag(np.broadcast_to(rates.variance, 3)).ravel()
    _set_xyz(msg.linear_acceleration, specific_force)
    return msg


def attitude_from_imu(msg: Imu) -> Reading:
    """Euler angles (phi, theta, psi) of an Imu's orientation (base_link_frd in odom_ned)."""
    _check_frame(msg, frames.FRAME_FRD, "IMU reading")
    q = _quaternion(msg.orientation)
    if not np.all(np.isfinite(q)) or not 0.5 < np.linalg.norm(q) < 1.5:
        raise ContractError(f"IMU orientation is not a unit quaternion: {q.tolist()}")
    t = stamp_to_ns(msg.header.stamp) * 1e-9
    m = Measurement.build(t, attitude=frames.quaternion_to_euler(q / np.linalg.norm(q)),
                          variances={"attitude": _diag3(msg.orientation_covariance)})
    return m.attitude


def position_to_msg(position: Reading, t_ns: int) -> PoseWithCovarianceStamped:
    """An acoustic fix in odom_ned; the orientation is not measured (huge variance)."""
    msg = _header(PoseWithCovarianceStamped(), t_ns, frames.FRAME_NED)
    _set_xyz(msg.pose.pose.position, position.value)
    msg.pose.pose.orientation.w = 1.0
    var = np.broadcast_to(position.variance, 3)
    msg.pose.covariance = np.diag(np.concatenate([var, [UNKNOWN_VARIANCE] * 3])).ravel()
    return msg


def position_from_msg(msg: PoseWithCovarianceStamped) -> Reading:
    """The position reading of an acoustic fix in odom_ned."""
    _check_frame(msg, frames.FRAME_NED, "position fix")
    t = stamp_to_ns(msg.header.stamp) * 1e-9
    m = Measurement.build(t, position=_xyz(msg.pose.pose.position),
                          variances={"position": _diag3(msg.pose.covariance)})
    return m.position


def depth_to_msg(depth: Reading, t_ns: int) -> Depth:
    msg = _header(Depth(), t_ns, frames.FRAME_NED)
    msg.depth, msg.variance = float(depth.value), float(depth.variance)
    return msg


def depth_from_msg(msg: Depth) -> Reading:
    """The depth reading (ContractError in another frame than odom_ned or not finite)."""
    _check_frame(msg, frames.FRAME_NED, "depth")
    m = Measurement.build(stamp_to_ns(msg.header.stamp) * 1e-9, depth=msg.depth,
                          variances={"depth": msg.variance})
    return m.depth


def altitude_to_msg(altitude: Reading, t_ns: int, *, field_of_view: float, min_range: float,
                    max_range: float) -> Range:
    """An altimeter range along body z (sensor_msgs/Range, ultrasound). An invalid reading (no echo: the
    seabed beyond ``max_range``, out of the beam, or inside the transducer's blanking distance ``min_range``,
    where an acoustic altimeter hears nothing either) is sent as range +inf, REP-117's "no object detected",
    so a reader knows the sample had no altitude rather than waiting for one."""
    msg = _header(Range(), t_ns, frames.FRAME_FRD)
    msg.radiation_type = Range.ULTRASOUND
    msg.field_of_view, msg.min_range, msg.max_range = float(field_of_view), float(min_range), float(max_range)
    if altitude.valid:
        msg.range, msg.variance = float(altitude.value), float(altitude.variance)
    else:
        msg.range, msg.variance = math.inf, 0.0
    return msg


def altitude_from_msg(msg: Range) -> Reading:
    """The altitude reading; invalid when the range is outside [min_range, max_range] (REP-117)."""
    t = stamp_to_ns(msg.header.stamp) * 1e-9
    if not (math.isfinite(msg.range) and msg.min_range <= msg.range <= msg.max_range):
        return Reading.invalid()
    return Measurement.build(t, altitude=msg.range, variances={"altitude": msg.variance}).altitude


# -- truth and environment ----------------------------------------------------------
def odometry_ned(state, t_ns: int) -> Odometry:
    """Pose and body twist of a 12-state (thesis order) as odom_ned -> base_link_frd."""
    x = np.asarray(state, float)
    msg = _header(Odometry(), t_ns, frames.FRAME_NED)
    msg.child_frame_id = frames.FRAME_FRD
    _set_xyz(msg.pose.pose.position, x[:3])
    _set_quaternion(msg.pose.pose.orientation, frames.euler_to_quaternion(*x[3:6]))
    _set_xyz(msg.twist.twist.linear, x[6:9])
    _set_xyz(msg.twist.twist.angular, x[9:12])
    return msg


def odometry_enu(state, t_ns: int) -> Odometry:
    """The same as :func:`odometry_ned` in REP-105 odom -> base_link (ENU/FLU)."""
    x = np.asarray(state, float)
    msg = _header(Odometry(), t_ns, frames.FRAME_ENU)
    msg.child_frame_id = frames.FRAME_FLU
    _set_xyz(msg.pose.pose.position, frames.ned_to_enu(x[:3]))
    q = frames.orientation_ned_frd_to_enu_flu(frames.euler_to_quaternion(*x[3:6]))
    _set_quaternion(msg.pose.pose.orientation, q)
    _set_xyz(msg.twist.twist.linear, frames.frd_to_flu(x[6:9]))
    _set_xyz(msg.twist.twist.angular, frames.frd_to_flu(x[9:12]))
    return msg


def _transform(parent: str, child: str, t_ns: int, translation, rotation) -> TransformStamped:
    msg = _header(TransformStamped(), t_ns, parent)
    msg.child_frame_id = child
    _set_xyz(msg.transform.translation, translation)
    _set_quaternion(msg.transform.rotation, rotation)
    return msg


def transforms_enu(state, t_ns: int) -> TFMessage:
    """``/tf`` of a 12-state: ``odom`` -> ``base_link`` (REP-105, ENU/FLU), the pose of :func:`odometry_enu`.

    The frame tree is ``odom`` -> ``base_link`` -> ``base_link_frd`` and ``odom`` -> ``odom_ned``
    (:func:`static_transforms`): one parent per frame, as tf2 requires, with the thesis's NED/FRD frames
    (REP-156's ``_ned``/``_frd`` suffixes) fixed to their ROS counterparts."""
    x = np.asarray(state, float)
    q = frames.orientation_ned_frd_to_enu_flu(frames.euler_to_quaternion(*x[3:6]))
    return TFMessage(transforms=[_transform(frames.FRAME_ENU, frames.FRAME_FLU, t_ns, frames.ned_to_enu(x[:3]), q)])


def path_ned(points, t_ns: int) -> Path:
    """A polyline of NED points as ``nav_msgs/Path`` in ``odom_ned`` (every pose stamped t_k, orientation
    identity): the umbilical's shape."""
    msg = _header(Path(), t_ns, frames.FRAME_NED)
    for p in np.asarray(points, float).reshape(-1, 3):
        pose = _header(PoseStamped(), t_ns, frames.FRAME_NED)
        _set_xyz(pose.pose.position, p)
        pose.pose.orientation.w = 1.0
        msg.poses.append(pose)
    return msg


def static_transforms(t_ns: int) -> TFMessage:
    """``/tf_static``: ``odom_ned`` in ``odom`` (x north = y east, z down = -z up) and ``base_link_frd`` in
    ``base_link`` (a half turn about x), both fixed."""
    zero = (0.0, 0.0, 0.0)
    return TFMessage(transforms=[
        _transform(frames.FRAME_ENU, frames.FRAME_NED, t_ns, zero, frames.QUATERNION_NED_IN_ENU),
        _transform(frames.FRAME_FLU, frames.FRAME_FRD, t_ns, zero, frames.QUATERNION_FRD_IN_FLU)])


# -- the hierarchy: navigation estimate, pose setpoints, velocity references ---------
def estimate_to_odometry(estimate: NavigationEstimate, t_ns: int) -> Odometry:
    """A navigation estimate as nav_msgs/Odometry, odom_ned -> base_link_frd, with its covariances.

    Pose covariance: position from the filter, orientation unknown
    (:data:`UNKNOWN_VARIANCE`, the navigator does not estimate it); twist
    covariance zero (unknown, REP-145).
    """
    msg = _header(Odometry(), t_ns, frames.FRAME_NED)
    msg.child_frame_id = frames.FRAME_FRD
    _set_xyz(msg.pose.pose.position, estimate.position)
    _set_quaternion(msg.pose.pose.orientation, frames.euler_to_quaternion(*estimate.attitude))
    cov = np.zeros((6, 6))
    cov[:3, :3] = estimate.position_cov
    cov[3:, 3:] = np.eye(3) * UNKNOWN_VARIANCE
    msg.pose.covariance = cov.ravel().tolist()
    _set_xyz(msg.twist.twist.linear, estimate.velocity)
    _set_xyz(msg.twist.twist.angular, estimate.rates)
    return msg


def estimate_from_odometry(msg: Odometry) -> NavigationEstimate:
    """A navigation estimate from odom_ned Odometry (ContractError on another frame or non-finite values)."""
    if msg.header.frame_id != frames.FRAME_NED:
        raise ContractError(f"navigation odometry in frame {msg.header.frame_id!r}: expected {frames.FRAME_NED}")
    position = np.array(_xyz(msg.pose.pose.position))
    attitude = frames.quaternion_to_euler(_quaternion(msg.pose.pose.orientation))
    cov = np.array(msg.pose.covariance, dtype=float).reshape(6, 6)[:3, :3]
    velocity, rates = np.array(_xyz(msg.twist.twist.linear)), np.array(_xyz(msg.twist.twist.angular))
    if not all(np.all(np.isfinite(a)) for a in (position, attitude, cov, velocity, rates)):
        raise ContractError("navigation odometry with non-finite values")
    return NavigationEstimate(stamp_to_ns(msg.header.stamp) * 1e-9, position, cov, attitude, velocity, rates)


def pose_setpoint_to_msg(position, yaw: float, t_ns: int) -> PoseStamped:
    """A setpoint (x, y, z in odom_ned, yaw) as PoseStamped stamped with the time it is for."""
    msg = _header(PoseStamped(), t_ns, frames.FRAME_NED)
    _set_xyz(msg.pose.position, position)
    _set_quaternion(msg.pose.orientation, frames.euler_to_quaternion(0.0, 0.0, yaw))
    return msg


def pose_setpoint_from_msg(msg: PoseStamped) -> tuple[np.ndarray, float, int]:
    """(position, yaw, stamp_ns) of a PoseStamped setpoint in odom_ned (ContractError otherwise).

    Only the yaw of the orientation is used (the hierarchy controls x, y, z, yaw; roll and pitch are
    the vehicle's own, sec. 4.2); a non-unit or non-finite quaternion is refused.
    """
    if msg.header.frame_id != frames.FRAME_NED:
        raise ContractError(f"pose reference in frame {msg.header.frame_id!r}: expected {frames.FRAME_NED}")
    position = np.array(_xyz(msg.pose.position))
    q = _quaternion(msg.pose.orientation)
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(q))):
        raise ContractError(f"pose reference must be finite, got {position.tolist()}, {q.tolist()}")
    if abs(float(np.linalg.norm(q)) - 1.0) > 1e-3:
        raise ContractError(f"pose reference orientation is not a unit quaternion (norm {np.linalg.norm(q):.4g})")
    return position, float(frames.quaternion_to_euler(q)[2]), stamp_to_ns(msg.header.stamp)


def reference_to_msg(reference: Reference, t_ns: int) -> TwistStamped:
    """A body-velocity reference (u, v, w, r) as TwistStamped in base_link_frd, for sample ``t_ns``."""
    msg = _header(TwistStamped(), t_ns, frames.FRAME_FRD)
    _set_xyz(msg.twist.linear, reference.velocity[:3])
    msg.twist.angular.z = float(reference.velocity[3])
    return msg


def reference_from_msg(msg: TwistStamped) -> Reference:
    """(u, v, w, r) from a TwistStamped in base_link_frd (ContractError if not finite or another frame)."""
    if msg.header.frame_id not in ("", frames.FRAME_FRD):
        raise ContractError(f"reference frame {msg.header.frame_id!r}: expected {frames.FRAME_FRD}")
    return Reference([msg.twist.linear.x, msg.twist.linear.y, msg.twist.linear.z, msg.twist.angular.z])


def diagnostic_array(name: str, level, message: str, values: dict, t_ns: int,
                     hardware_id: str = "seapup_control") -> DiagnosticArray:
    """One node's ``/diagnostics`` status: ``values`` as key/value strings, stamped ``t_ns``."""
    status = DiagnosticStatus(level=level, name=name, hardware_id=hardware_id, message=message,
                              values=[KeyValue(key=str(k), value=str(v)) for k, v in values.items()])
    array = DiagnosticArray(status=[status])
    array.header.stamp = ns_to_stamp(t_ns)
    return array


def vector3_stamped(vector, t_ns: int, frame_id: str) -> Vector3Stamped:
    msg = _header(Vector3Stamped(), t_ns, frame_id)
    _set_xyz(msg.vector, vector)
    return msg


def wrench_stamped(wrench, t_ns: int, frame_id: str) -> WrenchStamped:
    """Force (first three) and moment (last three) of a 6-vector."""
    w = np.asarray(wrench, float)
    msg = _header(WrenchStamped(), t_ns, frame_id)
    _set_xyz(msg.wrench.force, w[:3])
    _set_xyz(msg.wrench.torque, w[3:])
    return msg


class MeasurementCollector(LatestReadings):
    """Keeps the latest reading of each sensor topic and assembles a :class:`Measurement`.

    A controller node feeds it every sensor message as it arrives and asks
    for the measurement at its sample time, by the rule of
    :class:`~seapup_common.contract.LatestReadings`: readings older than
    ``max_age`` [s] at that time are reported invalid (a dead sensor is not a
    reading); readings stamped after it are not used yet.

    Parameters
    ----------
    max_age : dict, optional
        Per-field age limit [s] (default :data:`~seapup_common.contract.MAX_AGE`: 1 s for velocity, rates,
        attitude, depth and altitude; 5 s for position fixes).
    """

    def __init__(self, max_age: dict | None = None):
        super().__init__(max_age)
        self.rejected = 0
        self.last_error = ""

    @staticmethod
    def readings(msg) -> list[tuple[str, Reading]]:
        """The readings one sensor message carries, by measurement field; raises ContractError or
        ValueError if it is unusable (nothing is kept: a validity check)."""
        if isinstance(msg, TwistWithCovarianceStamped):
            velocity, rates = velocity_from_msg(msg)
            return [("velocity", velocity), ("rates", rates)]
        if isinstance(msg, Imu):
            return [("attitude", attitude_from_imu(msg))]
        if isinstance(msg, PoseWithCovarianceStamped):
            return [("position", position_from_msg(msg))]
        if isinstance(msg, Depth):
            return [("depth", depth_from_msg(msg))]
        if isinstance(msg, Range):
            return [("altitude", altitude_from_msg(msg))]
        raise ContractError(f"not a sensor message: {type(msg).__name__}")

    def add(self, msg) -> bool:
        """Take one sensor message; return False (and count it) if it is unusable."""
        try:
            readings = self.readings(msg)
        except (ContractError, ValueError) as exc:
            self.rejected += 1
            self.last_error = str(exc)
            return False
        for name, reading in readings:
            self.keep(name, reading)
        return True


class SampleFeed:
    """The sample inputs of a node that answers samples: sensor messages into a :class:`MeasurementCollector`,
    sample stamps and ``/clock`` into a :class:`~seapup_common.lockstep.SamplePolicy`.

    :meth:`velocity` and :meth:`clock` return the sample to answer now (or None); a message the
    collector refuses (non-finite, malformed, another frame) or stamped far ahead of the graph's time
    is counted and passed to ``rejected`` with the reason, never used.

    Parameters
    ----------
    collector : MeasurementCollector
    policy : seapup_common.lockstep.SamplePolicy
    rejected : callable
        ``rejected(reason)``: the node counts and logs it.
    """

    def __init__(self, collector: MeasurementCollector, policy, rejected):
        from seapup_common.lockstep import StampGate
        self.collector, self.policy, self.rejected = collector, policy, rejected
        self.stamps = StampGate()

    def velocity(self, msg) -> int | None:
        """A velocity (sample) message: the sample to answer, or None (also for a stamp far ahead of the
        graph's time: :class:`~seapup_common.lockstep.StampGate`)."""
        stamp = stamp_to_ns(msg.header.stamp)
        if not self.stamps.accept(stamp):
            self.rejected(self.stamps.why(stamp))
            return None
        if not self.collector.add(msg):
            self.rejected(self.collector.last_error)
            return None
        return self.policy.on_sample(stamp_to_ns(msg.header.stamp))

    def clock(self, msg) -> int | None:
        """A ``/clock`` message: the sample to answer (the simulator's repeated t_k), or None."""
        return self.policy.on_clock(stamp_to_ns(msg.clock))
