"""The Euler angles' round trip through a message's quaternion compiled with numba (issue 44: a mission flown in
process pays it several times a sample).

:func:`seapup_common.frames.euler_through_quaternion` stays the reference: z-y-x Euler angles (eq. 2.1) to the
quaternion a ``geometry_msgs/Quaternion`` carries, normalised on receipt when asked, and back. Here the same
scalar arithmetic, in the same order, calls the same C library's ``sin``, ``cos``, ``atan2`` and ``asin`` (no
``fastmath``), so the two give the same bits (``test/test_frames.py`` compares them over random and edge angles);
:func:`rows` does it for every row of an array at once (a log's attitudes). ``cache=True``: compiled once per
machine (:func:`warm`).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["euler_through_quaternion", "rows", "warm"]

_JIT = {"cache": True, "nogil": True}


@njit(**_JIT)
def _unit(x, y, z, w):
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if n == 0.0:   # no rotation at all: NaN, as numpy's 0 / 0
        return math.nan, math.nan, math.nan, math.nan
    return x / n, y / n, z / n, w / n


@njit(**_JIT)
def euler_through_quaternion(phi, theta, psi, normalise):
    """(phi, theta, psi) as a message carries them (:func:`seapup_common.frames.euler_through_quaternion`)."""
    cf, sf = math.cos(0.5 * phi), math.sin(0.5 * phi)
    ct, st = math.cos(0.5 * theta), math.sin(0.5 * theta)
    cp, sp = math.cos(0.5 * psi), math.sin(0.5 * psi)
    x, y, z, w = _unit(sf * ct * cp - cf * st * sp, cf * st * cp + sf * ct * sp, cf * ct * sp - sf * st * cp,
                       cf * ct * cp + sf * st * sp)
    negative = w < 0.0
    if w == 0.0:   # the first non-zero of (x, y, z) decides the sign
        first = x if x != 0.0 else (y if y != 0.0 else z)
        negative = first < 0.0
    if negative:
        x, y, z, w = -x, -y, -z, -w
    if normalise:
        x, y, z, w = _unit(x, y, z, w)
    x, y, z, w = _unit(x, y, z, w)   # quaternion_to_euler normalises first
    sin_theta = 2.0 * (w * y - x * z)
    if abs(sin_theta) >= 1.0 - 1e-12:   # gimbal lock: roll 0, the yaw carries the rotation about the vertical
        psi = -2.0 * math.copysign(1.0, sin_theta) * math.atan2(x, w)
        wrapped = (psi + math.pi) % (2 * math.pi) - math.pi
        return 0.0, math.copysign(0.5 * math.pi, sin_theta), math.pi if wrapped == -math.pi else wrapped
    return (math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y)), math.asin(sin_theta),
            math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))


@njit(**_JIT)
def rows(angles, normalise):
    """:func:`euler_through_quaternion` of every row of ``angles`` (n, 3): a new (n, 3) array."""
    out = np.empty_like(angles)
    for i in range(angles.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = euler_through_quaternion(angles[i, 0], angles[i, 1], angles[i, 2],
                                                                   normalise)
    return out


def warm() -> None:
    """Compile (or load from the cache) the kernels with the types their callers pass."""
    euler_through_quaternion(0.1, 0.2, 0.3, True)
    rows(np.zeros((1, 3)), True)
