"""The navigator's Kalman filter steps compiled with numba (issue 44: a mission flown in process).

:class:`seapup_control.navigation.Navigator` keeps the NumPy reference (``compiled=False``): the prediction
``x += T R v``, ``P += T^2 R diag(var) R^T + q_walk T I`` (inflated while coasting), and the Joseph-form
update of a fix (H = I) or of one component (the depth, H a unit row), each about ten small array operations
a sample in NumPy. Here each is one call on the filter's arrays, in place, in the reference's order of
operations (no ``fastmath``), so the two agree to rounding (``test/test_navigation.py`` flies both along
whole runs). ``cache=True``: compiled once per machine (``./seapup setup`` warms it, :func:`warm`).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["predict", "fuse_component", "fuse_fix", "warm"]

_JIT = {"cache": True, "nogil": True}


@njit(**_JIT)
def predict(x, P, attitude, velocity, variance, dt, q_walk, inflation):
    """Dead reckoning over ``dt`` (module docstring), in place; ``inflation`` 1 unless coasting."""
    cf, sf = math.cos(attitude[0]), math.sin(attitude[0])
    ct, st = math.cos(attitude[1]), math.sin(attitude[1])
    cp, sp = math.cos(attitude[2]), math.sin(attitude[2])
    R = np.empty((3, 3))
    R[0, 0], R[0, 1], R[0, 2] = cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf
    R[1, 0], R[1, 1], R[1, 2] = sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf
    R[2, 0], R[2, 1], R[2, 2] = -st, ct * sf, ct * cf
    for i in range(3):
        x[i] += dt * (R[i, 0] * velocity[0] + R[i, 1] * velocity[1] + R[i, 2] * velocity[2])
    dt2 = dt * dt
    for i in range(3):
        for j in range(3):
            q = (dt2 * R[i, 0] * variance[0] * R[j, 0] + dt2 * R[i, 1] * variance[1] * R[j, 1]
                 + dt2 * R[i, 2] * variance[2] * R[j, 2])
            if i == j:
                q += q_walk * dt
            P[i, j] += inflation * q


@njit(**_JIT)
def _joseph(P, K, index, variance):
    """P <- (I - K e_index^T) P (I - K e_index^T)^T + K variance K^T, symmetrised (Joseph form)."""
    A = np.empty((3, 3))   # (I - K H) P
    for i in range(3):
        for j in range(3):
            A[i, j] = P[i, j] - K[i] * P[index, j]
    B = np.empty((3, 3))   # A (I - K H)^T + K Rm K^T
    for i in range(3):
        for j in range(3):
            B[i, j] = A[i, j] - A[i, index] * K[j] + K[i] * variance * K[j]
    for i in range(3):
        for j in range(3):
            P[i, j] = 0.5 * (B[i, j] + B[j, i])


@njit(**_JIT)
def fuse_component(x, P, index, y, variance, gate):
    """One position component measured (H the unit row ``index``): False, nothing changed, if its normalised
    innovation squared exceeds ``gate``; else x and P updated in place."""
    innovation = y - x[index]
    s = P[index, index] + variance
    if innovation * (innovation / s) > gate:
        return False
    K = np.empty(3)
    for i in range(3):
        K[i] = P[index, i] * (1.0 / s)
    for i in range(3):
        x[i] += K[i] * innovation
    _joseph(P, K, index, variance)
    return True


@njit(**_JIT)
def fuse_fix(x, P, y, variance, gate):
    """A fix of the whole position (H = I, Rm = diag(variance)): False, nothing changed, beyond ``gate``; else
    the Kalman update in Joseph form, in place (the three components one after another is the same update
    for a diagonal Rm, to rounding)."""
    innovation = y - x
    S = P + np.diag(variance)
    if innovation @ np.linalg.solve(S, innovation) > gate:
        return False
    for index in range(3):
        fuse_component(x, P, index, y[index], variance[index], math.inf)
    return True


def warm() -> None:
    """Compile (or load from the cache) the kernels with the types the navigator passes."""
    x, P, v = np.zeros(3), np.eye(3), np.ones(3)
    predict(x, P, np.zeros(3), v, v, 0.2, 1e-4, 1.0)
    fuse_component(x, P, 2, 1.0, 0.01, 10.0)
    fuse_fix(x, P, v, v, 10.0)
    fix = np.ones(3)
    fix.setflags(write=False)   # a Reading's value is read-only: its own specialisation
    fuse_fix(x, P, fix, v, 10.0)
