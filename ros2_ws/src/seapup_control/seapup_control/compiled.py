"""The navigator's Kalman filter steps and the MFOL law's sample compiled with numba (issue 44: a mission flown in
process).

:class:`seapup_control.navigation.Navigator` keeps the NumPy reference (``compiled=False``): the prediction
``x += T R v``, ``P += T^2 R diag(var) R^T + q_walk T I`` (inflated while coasting), and the Joseph-form
update of a fix (H = I) or of one component (the depth, H a unit row), each about ten small array operations
a sample in NumPy. Here each is one call on the filter's arrays, in place, in the reference's order of
operations (no ``fastmath``), so the two agree to rounding (``test/test_navigation.py`` flies both along
whole runs).

:class:`seapup_control.mfol_controller.MFOLController` keeps its NumPy sample as the reference
(``compiled=False``); :func:`mfol_sample` is that sample of eq. 5.6 (the gains interpolated at the measured surge
speed, the offset at the reference's, sec. 4.6; the back-calculated integrators) in one call, about twenty small
array operations in NumPy. Its products and solves are the same BLAS and LAPACK calls as the reference's (numba
calls scipy's), in the same order, so the two give the same bits here (``test/test_mfol_controller.py`` flies
both and says so if a machine's libraries differ: then they agree to rounding).

``cache=True``: compiled once per machine (``./seapup setup`` warms it, :func:`warm`).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["predict", "fuse_component", "fuse_fix", "mfol_sample", "position_sample", "explicit_design", "warm"]

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


@njit(**_JIT)
def _interpolation(speeds, speed):
    """(i, j, w) of the schedule's linear interpolation at ``speed`` (``GainSchedule._weights``): held beyond the
    first and last operating points."""
    last = speeds.shape[0] - 1
    if last == 0 or speed <= speeds[0]:
        return 0, 0, 0.0
    if speed >= speeds[last]:
        return last, last, 0.0
    # side "left", as bisect_left; kept within the table whatever the speed (a NaN: the caller never passes one)
    j = min(max(np.searchsorted(speeds, speed) - 1, 0), last - 1)
    return j, j + 1, (speed - speeds[j]) / (speeds[j + 1] - speeds[j])


@njit(**_JIT)
def mfol_sample(speeds, both, offsets, work, counts, u, v, w, r, ref_u, ref_v, ref_w, ref_r, starting, limit,
                anti_windup):
    """One sample of the MFOL law (eq. 5.6, module docstring) for the outputs (u, v, w, r) and the reference
    (ref_u, ref_v, ref_w, ref_r), in place in ``work`` (6, n): its rows the integrators q (re-set first from row 1,
    the command to start from, when ``starting``: the bumpless start), then written the error, the command before
    saturation, the command, and 1.0 where saturated (counted in ``counts``). ``speeds`` (points,), ``both``
    (points, 2, n, n): each operating point's (K_int, K_err), ``offsets`` (points, n): its u0."""
    n = work.shape[1]
    q, error = work[0], work[2]
    i, j, x = _interpolation(speeds, u)
    if x == 0.0 and i == j:   # at a point or beyond the ends: the point's gains
        k_int, k_err = both[i, 0].copy(), both[i, 1].copy()
    else:                     # each element as (1 - x) K_i + x K_j
        k_int = (1 - x) * both[i, 0] + x * both[j, 0]
        k_err = (1 - x) * both[i, 1] + x * both[j, 1]
    i, j, x = _interpolation(speeds, ref_u)
    u0 = offsets[i].copy() if x == 0.0 and i == j else (1 - x) * offsets[i] + x * offsets[j]
    error[0], error[1], error[2], error[3] = ref_u - u, ref_v - v, ref_w - w, ref_r - r
    if starting:
        q[:] = np.linalg.solve(k_int, work[1] - u0)
    proportional = k_err @ error
    raw = k_int @ q + proportional + u0
    command = np.minimum(np.maximum(raw, -limit), limit)
    if anti_windup:   # the state that reproduces the held command, then integrate (a singular K_int raises here,
        held = np.linalg.solve(k_int, command - proportional - u0) + error   # before the counts change)
    else:
        held = q + error
    q[:] = held
    work[3] = raw
    work[4] = command
    for k in range(n):
        saturated = abs(raw[k]) > limit
        work[5, k] = 1.0 if saturated else 0.0
        counts[k] += saturated


@njit(**_JIT)
def _wrap(angle):
    """``seapup_common.frames.wrap_angle`` of a float: to (-pi, pi]."""
    wrapped = (angle + math.pi) % (2 * math.pi) - math.pi
    return math.pi if wrapped == -math.pi else wrapped


@njit(**_JIT)
def _max(a, b):
    """Python's ``max(a, b)``: ``a`` unless ``b`` is greater (the same zero's sign as the reference's)."""
    return b if b > a else a


@njit(**_JIT)
def _min(a, b):
    """Python's ``min(a, b)``: ``a`` unless ``b`` is smaller."""
    return b if b < a else a


@njit(**_JIT)
def position_sample(x, y, z, phi, theta, psi, has_reference, rx, ry, rz, ryaw, feedforward, gains, speed_limits,
                    yaw_gain, max_yaw_rate, acceleration_limits, period, last, out, limited):
    """One sample of the global position controller (``seapup_control.position_control``, sec. 4.2): the body
    velocities (u, v, w, r) wanted for the estimated pose (x, y, z, phi, theta, psi) and the setpoint (rx, ry, rz,
    ryaw) plus its ``feedforward`` rate -- zero without a setpoint -- each moved from ``last`` by at most its
    acceleration limit times ``period`` into ``out``, ``limited`` where that held it back. The reference's float
    arithmetic in its order (PositionController.update with ``compiled=False``)."""
    w0 = w1 = w2 = w3 = 0.0
    if has_reference:
        cf, sf, ct, st = math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta)
        cp, sp = math.cos(psi), math.sin(psi)
        r00, r01, r02 = cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf
        r10, r11, r12 = sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf
        r20, r21, r22 = -st, ct * sf, ct * cf
        dx, dy, dz = rx - x, ry - y, rz - z
        fx, fy, fz, fr = feedforward[0], feedforward[1], feedforward[2], feedforward[3]
        w0 = gains[0] * (r00 * dx + r10 * dy + r20 * dz) + (r00 * fx + r10 * fy + r20 * fz)
        w1 = gains[1] * (r01 * dx + r11 * dy + r21 * dz) + (r01 * fx + r11 * fy + r21 * fz)
        w2 = gains[2] * (r02 * dx + r12 * dy + r22 * dz) + (r02 * fx + r12 * fy + r22 * fz)
        scale = _max(_max(1.0, abs(w0) / speed_limits[0]), abs(w1) / speed_limits[1])
        w0 /= scale
        w1 /= scale
        w2 = _min(_max(w2, -speed_limits[2]), speed_limits[2])
        w3 = _min(_max(yaw_gain * _wrap(ryaw - psi) + fr, -max_yaw_rate), max_yaw_rate)
    for i in range(4):
        want = w0 if i == 0 else (w1 if i == 1 else (w2 if i == 2 else w3))
        step = acceleration_limits[i] * period
        value = last[i] + _min(_max(want - last[i], -step), step)
        out[i] = value
        limited[i] = abs(want - value) > 1e-12


@njit(error_model="numpy", **_JIT)   # a singular matrix's condition is inf (1 / 0), as numpy's
def explicit_design(phi, gamma, k, c, min_rcond, k_int, k_err):
    """The explicit self-tuner's redesign from a finite estimate (``ExplicitSelfTuner._designed`` after its
    trace and pole rules; sec. 7.3, eq. 4.18-4.19, 4.10-4.11): B0^-1 = Gamma, B1^-1 = (I - Phi)^-1 Gamma, the
    two-term gains of ``seapup_control.mfol.design`` for the loop poles ``k``, ``c`` into ``k_int``, ``k_err``.
    Returns (0, rcond) for a design; (1, rcond) when the row-equilibrated Gamma's reciprocal condition is below
    ``min_rcond``; (2, rcond) when the design fails (B0^-1 or B1^-1 with a condition above 1e12 or not finite;
    an exactly singular I - Phi raises numpy's LinAlgError), (3, rcond) for non-finite gains -- the caller then
    asks the reference why. The reference's LAPACK
    routines (the condition by the SVD, dgesdd; solves and inverses by dgesv) and products in its order."""
    n = phi.shape[0]
    scaled = np.empty((n, n))
    for i in range(n):
        largest = 0.0
        for j in range(n):
            largest = max(largest, abs(gamma[i, j]))
        largest = max(largest, 1e-300)
        for j in range(n):
            scaled[i, j] = gamma[i, j] / largest
    rcond = 1.0 / np.linalg.cond(scaled)
    if not rcond >= min_rcond:
        return 1, rcond
    identity = np.eye(n)
    b1inv = np.linalg.solve(identity - phi, gamma)   # an exactly singular I - Phi raises, as the reference's
    # B0^-1 or B1^-1 the reference refuses: a condition (dgesdd) beyond 1e12 or not finite
    condition0, condition1 = np.linalg.cond(gamma), np.linalg.cond(b1inv)
    if not (math.isfinite(condition0) and condition0 <= 1e12 and math.isfinite(condition1) and condition1 <= 1e12):
        return 2, rcond
    b0 = np.linalg.solve(gamma, identity)
    b1 = np.linalg.solve(b1inv, identity)
    for j in range(n):
        integral, proportional = (1.0 - k[j]) * (1.0 - c[j]), 2.0 - k[j] - c[j]
        for i in range(n):
            k_int[i, j] = b0[i, j] * integral
            k_err[i, j] = b0[i, j] * proportional - b1[i, j]
            if not (math.isfinite(k_int[i, j]) and math.isfinite(k_err[i, j])):
                return 3, rcond
    return 0, rcond


def warm() -> None:
    """Compile (or load from the cache) the kernels with the types the navigator, the MFOL law and the position
    controller pass."""
    x, P, v = np.zeros(3), np.eye(3), np.ones(3)
    predict(x, P, np.zeros(3), v, v, 0.2, 1e-4, 1.0)
    fuse_component(x, P, 2, 1.0, 0.01, 10.0)
    fuse_fix(x, P, v, v, 10.0)
    fix = np.ones(3)
    fix.setflags(write=False)   # a Reading's value is read-only: its own specialisation
    fuse_fix(x, P, fix, v, 10.0)
    for points in (1, 3):
        speeds, both, offsets = np.arange(float(points)), np.tile(np.eye(4), (points, 2, 1, 1)), np.zeros((points, 4))
        for array in (speeds, both, offsets):
            array.setflags(write=False)   # the schedule's tables are read-only
        mfol_sample(speeds, both, offsets, np.zeros((6, 4)), np.zeros(4, dtype=np.int64), 0.1, 0.0, 0.0, 0.0,
                    0.2, 0.0, 0.0, 0.0, True, 0.6, True)
    tables = tuple(np.ones(k) for k in (4, 3, 3, 4))
    position_sample(0.0, 0.0, 1.0, 0.0, 0.0, 0.0, True, 1.0, 0.0, 1.0, 0.5, *tables[:3], 0.5, 0.26, tables[3], 0.2,
                    np.zeros(4), np.zeros(4), np.zeros(4, dtype=np.bool_))
    gains = np.zeros((4, 4)), np.zeros((4, 4))
    explicit_design(0.5 * np.eye(4), 0.1 * np.eye(4), np.full(4, 0.8), np.full(4, 0.8), 1e-4, *gains)
