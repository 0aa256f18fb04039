"""The one place where NED/FRD meets ENU/FLU.

Vehicle quantities are kept as in the thesis and the marine REP-156 draft:
world frame ``odom_ned`` (x north, y east, z down) and body frame
``base_link_frd`` (x forward, y right, z down). Where seapup publishes the
REP-103/REP-105 conventions (``odom`` east-north-up, ``base_link``
forward-left-up) every conversion goes through this module:

    v_enu = M v_ned,   M = [[0, 1, 0], [1, 0, 0], [0, 0, -1]]
    v_flu = F v_frd,   F = diag(1, -1, -1)
    R_enu_flu = M R_ned_frd F

Quaternions are (x, y, z, w) as in ROS messages, scalar part w >= 0: the z-y-x
Euler rotation of eq. 2.1 as the product q_z(psi) q_y(theta) q_x(phi) of three
axis rotations, written out here (importing ``scipy.spatial`` costs every node
process 0.3 s); the tests check them against ``scipy.spatial.transform.Rotation``.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["NED_TO_ENU", "FRD_TO_FLU", "FRAME_NED", "FRAME_FRD", "FRAME_ENU", "FRAME_FLU",
           "euler_to_quaternion", "quaternion_to_euler", "euler_through_quaternion", "ned_to_enu", "frd_to_flu",
           "orientation_ned_frd_to_enu_flu", "covariance6_to_enu_flu", "rotation_body_to_ned", "wrap_angle",
           "QUATERNION_NED_IN_ENU", "QUATERNION_FRD_IN_FLU"]

FRAME_NED, FRAME_FRD = "odom_ned", "base_link_frd"
FRAME_ENU, FRAME_FLU = "odom", "base_link"
NED_TO_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
FRD_TO_FLU = np.diag([1.0, -1.0, -1.0])


def euler_to_quaternion(phi: float, theta: float, psi: float) -> np.ndarray:
    """(x, y, z, w) of the z-y-x Euler rotation (roll phi, pitch theta, yaw psi) of eq. 2.1."""
    return np.array(_quaternion_of(phi, theta, psi))


def _quaternion_of(phi: float, theta: float, psi: float) -> tuple:
    """:func:`euler_to_quaternion` in plain floats."""
    cf, sf = math.cos(0.5 * phi), math.sin(0.5 * phi)
    ct, st = math.cos(0.5 * theta), math.sin(0.5 * theta)
    cp, sp = math.cos(0.5 * psi), math.sin(0.5 * psi)
    x, y, z, w = _unit(sf * ct * cp - cf * st * sp, cf * st * cp + sf * ct * sp, cf * ct * sp - sf * st * cp,
                       cf * ct * cp + sf * st * sp)
    if w < 0.0 or (w == 0.0 and next(c for c in (x, y, z) if c != 0.0) < 0.0):
        x, y, z, w = -x, -y, -z, -w
    return x, y, z, w


def euler_through_quaternion(phi: float, theta: float, psi: float, normalise: bool = True) -> tuple:
    """(phi, theta, psi) as a message carries Euler angles: to a quaternion (:func:`euler_to_quaternion`) and
    back (:func:`quaternion_to_euler`), the receiver normalising the quaternion first when ``normalise``
    (``q / np.linalg.norm(q)``); plain floats, the same bits as those array functions (tested), at a fraction
    of their cost -- the in-process hierarchy pays it several times a sample."""
    x, y, z, w = _quaternion_of(float(phi), float(theta), float(psi))
    if normalise:
        x, y, z, w = _unit(x, y, z, w)
    return _euler_of(x, y, z, w)


def _unit(x: float, y: float, z: float, w: float) -> tuple:
    """(x, y, z, w) / |q| in plain floats: the norm summed in order, as numpy's ``q.dot(q)`` of four values."""
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if n == 0.0:   # no rotation at all: NaN, as numpy's 0 / 0
        return (math.nan,) * 4
    return x / n, y / n, z / n, w / n


def quaternion_to_euler(q) -> np.ndarray:
    """(phi, theta, psi) of a quaternion (x, y, z, w), z-y-x convention (normalised first).

    At pitch +-90 deg (gimbal lock) the roll is taken as 0 and the yaw carries the rotation about the vertical.
    """
    q = np.asarray(q, float)
    if q.shape != (4,):
        raise ValueError(f"a quaternion has 4 components (x, y, z, w), got shape {q.shape}")
    return np.array(_euler_of(*q.tolist()))


def _euler_of(x: float, y: float, z: float, w: float) -> tuple:
    """:func:`quaternion_to_euler` in plain floats."""
    x, y, z, w = _unit(x, y, z, w)
    sin_theta = 2.0 * (w * y - x * z)
    if abs(sin_theta) >= 1.0 - 1e-12:
        theta = math.copysign(0.5 * math.pi, sin_theta)
        psi = -2.0 * math.copysign(1.0, sin_theta) * math.atan2(x, w)
        return 0.0, theta, float(wrap_angle(psi))
    phi = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    theta = math.asin(sin_theta)
    psi = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return phi, theta, psi


def _product(a, b) -> np.ndarray:
    """Hamilton product a b of quaternions (x, y, z, w): rotate by b, then by a."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz])


def _canonical(q) -> np.ndarray:
    """The unit quaternion with w >= 0 (q and -q are the same rotation)."""
    q = np.asarray(q, float)
    q = q / math.sqrt(q.dot(q))   # np.linalg.norm's sqrt(q . q), without its overhead
    w = float(q[3])
    return -q if w < 0.0 or (w == 0.0 and q[np.flatnonzero(q)[0]] < 0.0) else q


#: NED_TO_ENU (a half turn about the horizontal axis between north and east) and FRD_TO_FLU (a half turn about
#: x) as quaternions.
_Q_NED_TO_ENU = np.array([math.sqrt(0.5), math.sqrt(0.5), 0.0, 0.0])
_Q_FRD_TO_FLU = np.array([1.0, 0.0, 0.0, 0.0])
#: The fixed rotations of the frame tree published on ``/tf_static`` (x, y, z, w): ``odom_ned`` in ``odom``
#: (p_enu = M p_ned) and ``base_link_frd`` in ``base_link`` (p_flu = F p_frd).
QUATERNION_NED_IN_ENU = _Q_NED_TO_ENU.copy()
QUATERNION_FRD_IN_FLU = _Q_FRD_TO_FLU.copy()


def ned_to_enu(v) -> np.ndarray:
    """A world vector (position, velocity) from NED to ENU."""
    return NED_TO_ENU @ np.asarray(v, float)


def frd_to_flu(v) -> np.ndarray:
    """A body vector (velocity, rate, force) from FRD to FLU."""
    return FRD_TO_FLU @ np.asarray(v, float)


def orientation_ned_frd_to_enu_flu(q_ned_frd) -> np.ndarray:
    """Quaternion of base_link (FLU) in odom (ENU) from that of FRD in NED: R_enu_flu = M R_ned_frd F."""
    return _canonical(_product(_product(_Q_NED_TO_ENU, np.asarray(q_ned_frd, float)), _Q_FRD_TO_FLU))


def covariance6_to_enu_flu(cov, world_first: bool) -> np.ndarray:
    """A 6x6 covariance (ROS row-major 36 or 6x6) re-expressed in ENU/FLU.

    ``world_first``: the first three variables are world-frame (pose: position
    in NED, rotation about body axes FRD); otherwise both halves are body-frame
    (twist in FRD).
    """
    c = np.asarray(cov, float).reshape(6, 6)
    j = np.zeros((6, 6))
    j[:3, :3] = NED_TO_ENU if world_first else FRD_TO_FLU
    j[3:, 3:] = FRD_TO_FLU
    return j @ c @ j.T


def rotation_body_to_ned(phi: float, theta: float, psi: float) -> np.ndarray:
    """Rotation matrix R with v_ned = R v_body (z-y-x Euler angles, eq. 2.1)."""
    cf, sf = math.cos(phi), math.sin(phi)
    ct, st = math.cos(theta), math.sin(theta)
    cp, sp = math.cos(psi), math.sin(psi)
    return np.array([
        [cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf],
        [sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf],
        [-st, ct * sf, ct * cf],
    ])


def wrap_angle(angle):
    """An angle (or array of angles) wrapped to (-pi, pi] [rad].

    >>> float(wrap_angle(3 * math.pi / 2))
    -1.5707963267948966
    """
    if isinstance(angle, float):   # Python's float % is numpy's mod (fmod, then the divisor's sign): the same bits
        wrapped = (float(angle) + math.pi) % (2 * math.pi) - math.pi
        return math.pi if wrapped == -math.pi else wrapped
    wrapped = np.mod(np.asarray(angle, dtype=float) + math.pi, 2 * math.pi) - math.pi
    wrapped = np.where(wrapped == -math.pi, math.pi, wrapped)
    return float(wrapped) if np.ndim(wrapped) == 0 else wrapped
