"""The vehicle's physics step compiled with numba: the same equations as the NumPy reference.

:class:`~seapup_sim.vehicle.VehicleModel` and :class:`~seapup_sim.integrator.VehicleIntegrator`
stay the reference implementation (and the only one a model that overrides ``derivatives`` -- the
linearised model of eq. 3.2 -- ever uses). This module evaluates the same right-hand side (eq.
2.1-2.3: rigid-body and added-mass Coriolis in Kirchhoff form, the hydrodynamic derivative table of
sec. 2.3.3, the hydrostatics of sec. 2.3.2, the thrusters' K_T(J, beta) of eq. 2.18 with the momentum
drag of eq. 2.19 -- or N fixed-pitch thrusters' static curve, a table or a polynomial, behind a mixer:
:class:`~seapup_sim.thrusters.FixedPitchThrusters`) and the same fourth-order Runge-Kutta step with the
exactly solved lag of the blade pitches (or the thrusters' commands),
as compiled kernels on arrays packed from the model (:func:`pack`). Both are tested equal to 1e-12 on
random states, inputs and every shipped configuration (``test/test_compiled.py``).

Decisions:

- one kernel call is one physics step: of one vehicle (:func:`rk4_checked`), or of N vehicles (or a contiguous part
  of them, on one of several threads), each by the same single-vehicle kernel (:func:`rk4_batch`, :class:`seapup_sim.batch.BatchPlant`: vehicle i equals the
  vehicle stepped alone, bit for bit). The other work between physics steps -- the current's
  Gauss-Markov update (eq. 2.29), configuration events -- stays in
  :class:`~seapup_sim.simulation.Simulation` (and :class:`seapup_sim.batch.BatchCurrent`), so each has one
  implementation.
- the umbilical's closed-form quasi-static cable (sec. 2.3.4, 3.8) is a kernel too (:func:`cable_solve`,
  used by :class:`seapup_sim.umbilical.Umbilical`); its rare cold start stays with the reference's Brent
  bracket.
- no ``fastmath``: the operations happen in the reference's order, so the two agree to rounding and
  the mirror symmetries of the model (sway to port and starboard) hold exactly as before.
- kernels are compiled once per machine (``cache=True``: numba's cache beside this file, or its
  user-wide cache where that is read-only). The integrator imports this module (and so numba) on its
  first step, so a process that never steps a plant does not pay for it.
- ``SEAPUP_PLANT=numpy`` in the environment selects the reference everywhere (as does the absence of
  numba), for comparisons and for debugging with Python tracebacks inside the equations
  (:func:`seapup_sim.integrator.default_backend`).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = ["Packed", "pack", "pack_batch", "derivatives", "rk4_checked", "rk4_batch", "rhs",
           "rotation", "cable_solve", "CABLE_OUT", "polar_to_ned", "cos_product", "warm", "work_size", "rk4_scratch"]

_JIT = dict(cache=True, nogil=True)



class Packed(NamedTuple):
    """A vehicle configuration as the kernels read it (everything but the thrusters' efficiency,
    which events change while a run goes on and is passed at each call).

    The model's constant matrices are stored row-compressed (:data:`SPARSE_ROWS`): they are mostly zeros
    (the baseline's rigid-body mass matrix has 6 non-zeros of 36, the thruster maps 28 of 72), and a
    product that skips exact zeros adds the same terms in the same order as the dense one, so it gives the
    same bits for every finite input (``s + 0.0 * x`` is ``s``: a sum begun at +0.0 is never -0.0)."""

    sp_ptr: np.ndarray       # (rows + 1,) int64: row starts in sp_idx / sp_val
    sp_idx: np.ndarray       # (nnz,) int64: column of each non-zero
    sp_val: np.ndarray       # (nnz,): its value
    h_axis: np.ndarray       # (n,) int64: each hydrodynamic term's axis
    h_coef: np.ndarray       # (n,): its coefficient
    h_signed: np.ndarray     # (n, w) int64: indices of its signed factors (6: the constant 1)
    h_absolute: np.ndarray   # (n, w) int64: indices of its |.| factors
    directions: np.ndarray   # (N, 3): unit thrust axes
    scalars: np.ndarray      # k_beta, beta_0, rho n^2 D^4, k_j/(n D), momentum-drag scale, epsilon,
                             # W - B, the hydrostatic arm W r_G - B r_B (3), then the thrusters' kind
                             # (KIND_*), a fixed-pitch curve's deadband and how it is read (CURVE_*)
    curve_x: np.ndarray      # a fixed-pitch thrust curve: the commands of its table (CURVE_TABLE), or unused
    curve_y: np.ndarray      # its thrusts [N] there, or its polynomial's coefficients (CURVE_POLYNOMIAL)


#: The matrices of :class:`Packed`'s row-compressed block, each by its first row: the rigid-body mass, the
#: added mass, the inverse of their sum (6 x 6 each), the velocity of each thruster centre from nu (3N x 6;
#: zeros for fixed-pitch thrusters, which have no momentum drag), then the installed thrust matrix (6 x N:
#: c G, or a fixed-pitch set's B) and the wrench of forces at the thruster centres (6 x 3N): for N thrusters
#: those two start at :func:`thrust_rows` (30 and 36 for the Seapup's four).
M_RIGID, M_ADDED, M_INV, POINT_MAP = 0, 6, 12, 18
#: the thrusters' kind (scalars[10]) and how a fixed-pitch curve is read (scalars[12])
KIND_CONTROLLABLE_PITCH, KIND_FIXED_PITCH = 0.0, 1.0
CURVE_POLYNOMIAL, CURVE_TABLE = 0.0, 1.0


@njit(inline="always", **_JIT)
def thrust_rows(n):
    """(first row of the thrust matrix, of the force map) in the row-compressed block, for n thrusters."""
    return POINT_MAP + 3 * n, POINT_MAP + 3 * n + 6


@njit(inline="always", **_JIT)
def work_size(n):
    """Scratch floats :func:`rhs` needs for n thrusters."""
    return 76 + 7 * n


@njit(inline="always", **_JIT)
def rk4_scratch(n):
    """Scratch floats of one RK4 step for n thrusters: the three lagged commands, four stages, the stage
    state, :func:`rhs`'s work."""
    return 3 * n + 5 * 12 + work_size(n)


def _row_compressed(matrices) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(row starts, columns, values) of the non-zeros of ``matrices`` stacked by rows."""
    ptr, idx, val = [0], [], []
    for a in matrices:
        for row in np.asarray(a, dtype=np.float64):
            cols = np.flatnonzero(row)
            idx.extend(cols.tolist())
            val.extend(row[cols].tolist())
            ptr.append(len(idx))
    return (np.array(ptr, dtype=np.int64), np.array(idx, dtype=np.int64).reshape(-1),
            np.array(val, dtype=np.float64).reshape(-1))


def pack(model) -> Packed:
    """The arrays of ``model`` (a :class:`~seapup_sim.vehicle.VehicleModel`) the kernels need."""
    th, hydro = model.thrusters, model.hydro
    width = hydro._signed.shape[1] if len(hydro.terms) else 1
    n = len(hydro.terms)
    hydrostatics = [model.weight - model.buoyancy, *model._hydrostatic_arm]
    if th.kind == "fixed_pitch":   # no momentum drag: zero point and force maps
        curve, count = th.curve, th.count
        if curve._droops:   # a curve that turns back: its monotone envelope, as ThrustCurve.thrust reads it
            mode, cx, cy = CURVE_TABLE, curve._grid, curve._monotone
        elif curve.table is not None:
            mode, cx, cy = CURVE_TABLE, curve.table[:, 0], curve.table[:, 1]
        else:
            mode, cx, cy = CURVE_POLYNOMIAL, np.zeros(1), curve.coefficients
        maps = (np.zeros((3 * count, 6)), np.zeros((6, 3 * count)))
        scalars = [0.0] * 6 + hydrostatics + [KIND_FIXED_PITCH, curve.deadband, mode]
    else:
        cx, cy, maps = np.zeros(1), np.zeros(1), (th._point_map, th._force_map)
        scalars = [th.k_beta, th.zero_thrust_pitch, th._thrust_scale, th.k_j / (th.shaft_speed * th.diameter),
                   th._md_scale, th.momentum_drag_epsilon] + hydrostatics + [KIND_CONTROLLABLE_PITCH, 0.0,
                                                                             CURVE_POLYNOMIAL]
    sp_ptr, sp_idx, sp_val = _row_compressed([model.m_rigid, model.m_added, model.m_inv, maps[0], th.matrix,
                                              maps[1]])
    return Packed(
        sp_ptr=sp_ptr, sp_idx=sp_idx, sp_val=sp_val,
        h_axis=np.ascontiguousarray(hydro._axis if n else np.zeros(0), dtype=np.int64),
        h_coef=np.ascontiguousarray(hydro._coef if n else np.zeros(0), dtype=np.float64),
        h_signed=np.ascontiguousarray(hydro._signed if n else np.zeros((0, width)), dtype=np.int64),
        h_absolute=np.ascontiguousarray(hydro._absolute if n else np.zeros((0, width)), dtype=np.int64),
        directions=np.ascontiguousarray(th.directions, dtype=np.float64), scalars=np.array(scalars, dtype=np.float64),
        curve_x=np.ascontiguousarray(cx, dtype=np.float64), curve_y=np.ascontiguousarray(cy, dtype=np.float64))


@njit(inline="always", **_JIT)
def matvec(a, x, out):
    for i in range(a.shape[0]):
        s = 0.0
        for j in range(a.shape[1]):
            s += a[i, j] * x[j]
        out[i] = s


@njit(inline="always", **_JIT)
def spmv(ptr, idx, val, first, rows, x, out):
    """``out = A x`` for rows ``first`` ... ``first + rows - 1`` of the row-compressed block (:class:`Packed`)."""
    for i in range(rows):
        s = 0.0
        for k in range(ptr[first + i], ptr[first + i + 1]):
            s += val[k] * x[idx[k]]
        out[i] = s


@njit(inline="always", **_JIT)
def rotation(phi, theta, psi, rot):
    """R with v_ned = R v_body (z-y-x Euler angles, eq. 2.1; frames.rotation_body_to_ned) into ``rot``."""
    cf, sf = math.cos(phi), math.sin(phi)
    ct, st = math.cos(theta), math.sin(theta)
    cp, sp = math.cos(psi), math.sin(psi)
    rot[0, 0] = cp * ct
    rot[0, 1] = cp * st * sf - sp * cf
    rot[0, 2] = cp * st * cf + sp * sf
    rot[1, 0] = sp * ct
    rot[1, 1] = sp * st * sf + cp * cf
    rot[1, 2] = sp * st * cf - cp * sf
    rot[2, 0] = -st
    rot[2, 1] = ct * sf
    rot[2, 2] = ct * cf


@njit(inline="always", **_JIT)
def kirchhoff(ptr, idx, val, first, nu, out, m):
    """``-[w x p_v ; w x p_w + v x p_v]`` with p = M nu (vehicle.kirchhoff_coriolis), M the block's rows
    from ``first``; ``m`` (6,) scratch."""
    spmv(ptr, idx, val, first, 6, nu, m)
    a, b, c, d, e, f = m[0], m[1], m[2], m[3], m[4], m[5]
    u, v, w, p, q, r = nu[0], nu[1], nu[2], nu[3], nu[4], nu[5]
    out[0] = -(q * c - r * b)
    out[1] = -(r * a - p * c)
    out[2] = -(p * b - q * a)
    out[3] = -(q * f - r * e) - (v * c - w * b)
    out[4] = -(r * d - p * f) - (w * a - u * c)
    out[5] = -(p * e - q * d) - (u * b - v * a)


@njit(inline="always", **_JIT)
def fixed_pitch_thrust(command, deadband, mode, curve_x, curve_y):
    """:meth:`seapup_sim.thrusters.ThrustCurve.thrust` of one command: clipped to [-1, 1], the deadband's
    rescaling, then the table (np.interp) or the polynomial (Horner's scheme, as numpy's polyval)."""
    c = min(max(command, -1.0), 1.0)
    if deadband > 0.0:
        sign = 1.0 if c > 0.0 else (-1.0 if c < 0.0 else 0.0)
        c = sign * max(abs(c) - deadband, 0.0) / (1.0 - deadband)
    if mode == CURVE_TABLE:
        return np.interp(c, curve_x, curve_y)
    value = curve_y[curve_y.shape[0] - 1]
    for i in range(curve_y.shape[0] - 2, -1, -1):
        value = curve_y[i] + value * c
    return value


@njit(**_JIT)
def rhs(x, pitch, current, use_current, external, use_external, thrusters_on, efficiency,
        sp_ptr, sp_idx, sp_val, h_axis, h_coef, h_signed, h_absolute, directions, scalars, curve_x, curve_y, out,
        work):
    """x' (eq. 2.1-2.3) into ``out`` (12,); VehicleModel.derivatives term by term, for N thrusters of either
    kind (``pitch``: the Seapup's blade pitches, or fixed-pitch thrusters' lagged commands). ``work``: at least
    :func:`work_size` (N) floats of scratch (no allocation in the kernel)."""
    n = directions.shape[0]
    phi, theta = x[3], x[4]
    cf, sf = math.cos(phi), math.sin(phi)
    ct = math.cos(theta)
    rot = work[6:15].reshape((3, 3))
    rotation(phi, theta, x[5], rot)
    nu = x[6:12]
    nu_r = work[15:21]
    nu_r[:] = nu
    if use_current:
        for i in range(3):
            s = 0.0
            for j in range(3):
                s += rot[j, i] * current[j]
            nu_r[i] -= s
    rigid = work[21:27]
    kirchhoff(sp_ptr, sp_idx, sp_val, M_RIGID, nu, rigid, work[0:6])
    added = work[27:33]
    kirchhoff(sp_ptr, sp_idx, sp_val, M_ADDED, nu_r, added, work[0:6])
    hydro = work[33:39]
    hydro[:] = 0.0
    ext = work[39:46]
    ext[:6] = nu_r
    ext[6] = 1.0
    for k in range(h_coef.shape[0]):
        signed = 1.0
        for i in range(h_signed.shape[1]):
            signed *= ext[h_signed[k, i]]
        absolute = 1.0
        for i in range(h_absolute.shape[1]):
            absolute *= abs(ext[h_absolute[k, i]])
        hydro[h_axis[k]] += h_coef[k] * signed * absolute
    dx, dy, dz = rot[2, 0], rot[2, 1], rot[2, 2]
    net, ax, ay, az = scalars[6], scalars[7], scalars[8], scalars[9]
    static = work[46:52]
    static[0] = net * dx
    static[1] = net * dy
    static[2] = net * dz
    static[3] = ay * dz - az * dy
    static[4] = az * dx - ax * dz
    static[5] = ax * dy - ay * dx
    tau = work[52:58]
    for i in range(6):
        tau[i] = rigid[i] + added[i] + hydro[i] + static[i]
    thrust_matrix, force_map = thrust_rows(n)
    vel = work[58:58 + 3 * n]
    thrust = work[58 + 3 * n:58 + 4 * n]
    drag = work[58 + 4 * n:58 + 7 * n]
    wrench = work[58 + 7 * n:64 + 7 * n]
    moment = work[64 + 7 * n:70 + 7 * n]
    if thrusters_on and scalars[10] == KIND_FIXED_PITCH:   # FixedPitchThrusters.wrench: B (eff * T(c))
        for j in range(n):
            thrust[j] = efficiency[j] * fixed_pitch_thrust(pitch[j], scalars[11], scalars[12], curve_x, curve_y)
        spmv(sp_ptr, sp_idx, sp_val, thrust_matrix, 6, thrust, wrench)
        for i in range(6):
            tau[i] += wrench[i]
    elif thrusters_on:
        k_beta, beta0, thrust_scale, kj_nd, md_scale, eps = (scalars[0], scalars[1], scalars[2], scalars[3],
                                                            scalars[4], scalars[5])
        spmv(sp_ptr, sp_idx, sp_val, POINT_MAP, 3 * n, nu_r, vel)
        for j in range(n):
            v_axial = (vel[3 * j] * directions[j, 0] + vel[3 * j + 1] * directions[j, 1]) \
                + vel[3 * j + 2] * directions[j, 2]
            bollard = k_beta * (pitch[j] - beta0)
            thrust[j] = efficiency[j] * (thrust_scale * (bollard - kj_nd * v_axial))
            k0 = math.sqrt(bollard * bollard + eps ** 2)
            scale = -md_scale * math.sqrt(k0 / math.pi)
            for i in range(3):
                drag[3 * j + i] = scale * (vel[3 * j + i] - v_axial * directions[j, i])
        spmv(sp_ptr, sp_idx, sp_val, thrust_matrix, 6, thrust, wrench)
        spmv(sp_ptr, sp_idx, sp_val, force_map, 6, drag, moment)
        for i in range(6):
            tau[i] += wrench[i] + moment[i]
    if use_external:
        for i in range(6):
            tau[i] += external[i]
    matvec(rot, nu[:3], out[:3])
    tt = math.tan(theta)
    p, q, r = nu[3], nu[4], nu[5]
    out[3] = (p + sf * tt * q) + cf * tt * r
    out[4] = (0.0 * p + cf * q) + (-sf) * r
    out[5] = (0.0 * p + sf / ct * q) + cf / ct * r
    accel = work[70 + 7 * n:76 + 7 * n]
    spmv(sp_ptr, sp_idx, sp_val, M_INV, 6, tau, accel)
    out[6:] = accel


@njit(**_JIT)
def _rk4_into(x, pitch0, command, tau_actuator, dt, current, use_current, external, use_external, thrusters_on,
              efficiency, sp_ptr, sp_idx, sp_val, h_axis, h_coef, h_signed, h_absolute, directions, scalars, curve_x, curve_y,
              new, pitch_end, buf):
    """integrator.rk4_step with the lagged pitch at the three stage times, into ``new`` and ``pitch_end``, with its
    scratch ``buf`` (:func:`rk4_scratch` floats) given."""
    n = pitch0.shape[0]
    p0, ph, p1 = buf[0:n], buf[n:2 * n], buf[2 * n:3 * n]
    b = 3 * n
    k1, k2, k3, k4, xs = buf[b:b + 12], buf[b + 12:b + 24], buf[b + 24:b + 36], buf[b + 36:b + 48], buf[b + 48:b + 60]
    work = buf[b + 60:]
    for j in range(n):
        if tau_actuator <= 0.0:
            p0[j] = command[j]
            ph[j] = command[j]
            p1[j] = command[j]
        else:
            gap = pitch0[j] - command[j]
            p0[j] = command[j] + gap * math.exp(-0.0 / tau_actuator)
            ph[j] = command[j] + gap * math.exp(-(0.5 * dt) / tau_actuator)
            p1[j] = command[j] + gap * math.exp(-dt / tau_actuator)
    half = 0.5 * dt
    rhs(x, p0, current, use_current, external, use_external, thrusters_on, efficiency, sp_ptr, sp_idx, sp_val,
        h_axis, h_coef, h_signed, h_absolute, directions, scalars, curve_x, curve_y, k1, work)
    for i in range(12):
        xs[i] = x[i] + half * k1[i]
    rhs(xs, ph, current, use_current, external, use_external, thrusters_on, efficiency, sp_ptr, sp_idx, sp_val,
        h_axis, h_coef, h_signed, h_absolute, directions, scalars, curve_x, curve_y, k2, work)
    for i in range(12):
        xs[i] = x[i] + half * k2[i]
    rhs(xs, ph, current, use_current, external, use_external, thrusters_on, efficiency, sp_ptr, sp_idx, sp_val,
        h_axis, h_coef, h_signed, h_absolute, directions, scalars, curve_x, curve_y, k3, work)
    for i in range(12):
        xs[i] = x[i] + dt * k3[i]
    rhs(xs, p1, current, use_current, external, use_external, thrusters_on, efficiency, sp_ptr, sp_idx, sp_val,
        h_axis, h_coef, h_signed, h_absolute, directions, scalars, curve_x, curve_y, k4, work)
    sixth = dt / 6.0
    for i in range(12):
        new[i] = x[i] + sixth * (((k1[i] + 2.0 * k2[i]) + 2.0 * k3[i]) + k4[i])
    for j in range(n):
        pitch_end[j] = p1[j]



@njit(**_JIT)
def rk4_checked(x, pitch0, command, tau_actuator, dt, current, use_current, external, use_external, thrusters_on,
                efficiency, sp_ptr, sp_idx, sp_val, h_axis, h_coef, h_signed, h_absolute, directions, scalars,
                curve_x, curve_y, envelope, new, pitch_end):
    """One physics step (:func:`_rk4_into`), then what :meth:`seapup_sim.integrator.VehicleIntegrator.step` does with the new state, in the
    same call: the envelope check (:func:`seapup_sim.integrator.divergence`: a non-finite value, or one beyond
    ``envelope``) and the roll and yaw wrap to [-pi, pi). Returns -1, or the index of the first state out of the
    envelope (``new`` then holds the step unwrapped, for the caller's message)."""
    _rk4_into(x, pitch0, command, tau_actuator, dt, current, use_current, external, use_external, thrusters_on,
              efficiency, sp_ptr, sp_idx, sp_val, h_axis, h_coef, h_signed, h_absolute, directions, scalars, curve_x,
              curve_y, new, pitch_end, np.empty(rk4_scratch(pitch0.shape[0])))
    for i in range(12):
        if not math.isfinite(new[i]) or abs(new[i]) > envelope[i]:
            return i
    new[3] = (new[3] + math.pi) % (2 * math.pi) - math.pi
    new[5] = (new[5] + math.pi) % (2 * math.pi) - math.pi
    return -1


@njit(**_JIT)
def rk4_period(x, pitch0, command, tau_actuator, dt, currents, use_current, external, use_external, thrusters_on,
               efficiency, sp_ptr, sp_idx, sp_val, h_axis, h_coef, h_signed, h_absolute, directions, scalars,
               curve_x, curve_y, envelope, states, pitches, accel):
    """A control period in one call: ``len(states)`` physics steps of :func:`rk4_checked` with the command held,
    the current of step i ``currents[i]`` (the Gauss-Markov current is independent of the vehicle: its values
    for the period are known before it), each step from the one before -- bit for bit the steps one call each
    (tested). ``states[i]``, ``pitches[i]``: after step i; ``accel``: d(u, v, w)/dt over the last step, as
    :meth:`seapup_sim.simulation.Simulation.advance` computes it. Returns -1, or ``12 i + j`` for state j out
    of the envelope at step i (``states[i]`` then holds that step unwrapped; the steps before it are good)."""
    buf = np.empty(rk4_scratch(pitch0.shape[0]))
    n = states.shape[0]
    for i in range(n):
        start = x if i == 0 else states[i - 1]
        pitch_start = pitch0 if i == 0 else pitches[i - 1]
        new, pitch_end = states[i], pitches[i]
        _rk4_into(start, pitch_start, command, tau_actuator, dt, currents[i], use_current, external, use_external,
                  thrusters_on, efficiency, sp_ptr, sp_idx, sp_val, h_axis, h_coef, h_signed, h_absolute, directions,
                  scalars, curve_x, curve_y, new, pitch_end, buf)
        for j in range(12):
            if not math.isfinite(new[j]) or abs(new[j]) > envelope[j]:
                return 12 * i + j
        new[3] = (new[3] + math.pi) % (2 * math.pi) - math.pi
        new[5] = (new[5] + math.pi) % (2 * math.pi) - math.pi
        if i == n - 1:
            for j in range(3):
                accel[j] = (new[6 + j] - start[6 + j]) / dt
    return -1


@njit(**_JIT)
def rk4_batch(states, pitches, commands, taus, dt, currents, use_current, externals, use_external, thrusters_on,
              efficiency, sp_ptr, sp_idx, sp_val, h_axis, h_coef, h_signed, h_absolute, directions, scalars, curve_x,
              curve_y, active, new, pitch_end):
    """The physics step (:func:`_rk4_into`) for each vehicle ``i`` of a batch (a leading axis on every argument but ``dt`` and the two
    flags) that is ``active``; the others keep their state and pitch. Vehicle i is stepped by the very kernel
    a single vehicle is, so it equals the single-vehicle step bit for bit. Releases the GIL: threads may step
    disjoint parts of a batch at once (:class:`seapup_sim.batch.BatchPlant`)."""
    buf = np.empty(rk4_scratch(pitches.shape[1]))
    for i in range(states.shape[0]):
        if not active[i]:
            new[i] = states[i]
            pitch_end[i] = pitches[i]
            continue
        _rk4_into(states[i], pitches[i], commands[i], taus[i], dt, currents[i], use_current, externals[i],
                  use_external, thrusters_on[i], efficiency[i], sp_ptr[i], sp_idx[i], sp_val[i], h_axis[i],
                  h_coef[i], h_signed[i], h_absolute[i], directions[i], scalars[i], curve_x[i], curve_y[i], new[i],
                  pitch_end[i], buf)


#: :func:`cable_solve`'s outcomes (``out[0]``)
CABLE_SOLVED, CABLE_SLOW_FLOW, CABLE_LIGHT_LOAD, CABLE_PARALLEL, CABLE_NEEDS_GUESS, CABLE_TOO_SHORT, \
    CABLE_NOT_CONVERGED = range(7)
#: ``out``'s layout: outcome, c0, lambda, tension, length, detail (the bypass's number, or the distance),
#: a, b (the end conditions), e1 (3), e2 (3), start (3), force on the vehicle (NED, 3), wrench on the vehicle
#: (body axes, 6), residual (2)
CABLE_OUT = 28


@njit(**_JIT)
def _cable_residual(c0, lam, a, b):
    cl = c0 - lam
    r0, rl = math.sqrt(1 + c0 * c0), math.sqrt(1 + cl * cl)
    return (r0 - rl - lam * a, math.asinh(c0) - math.asinh(cl) - lam * b, c0 / r0 - cl / rl, cl / rl - a,
            1 / r0 - 1 / rl, 1 / rl - b)


@njit(**_JIT)
def cable_solve(state, current, attachment, ship, fixed_length, length_ratio, k, weight, min_flow, max_ratio,
                c0, lam, has_guess, tol, max_iter, out):
    """umbilical.Umbilical.wrench's closed-form quasi-static cable (sec. 2.3.4, 3.8) from a warm start
    ``(c0, lam)``: the geometry, the bypass tests, damped Newton-Raphson on the two end conditions and the
    body wrench, into ``out`` (:data:`CABLE_OUT`). ``fixed_length`` NaN: the length follows the ends."""
    for i in range(CABLE_OUT):
        out[i] = 0.0
    rot = np.empty((3, 3))
    rotation(state[3], state[4], state[5], rot)
    w = state[9:12]
    spin = np.empty(3)
    spin[0] = state[6] + (w[1] * attachment[2] - w[2] * attachment[1])
    spin[1] = state[7] + (w[2] * attachment[0] - w[0] * attachment[2])
    spin[2] = state[8] + (w[0] * attachment[1] - w[1] * attachment[0])
    end = np.empty(3)
    flow = np.empty(3)
    chord = np.empty(3)
    for i in range(3):
        offset = 0.0
        velocity = 0.0
        for j in range(3):
            offset += rot[i, j] * attachment[j]
            velocity += rot[i, j] * spin[j]
        end[i] = state[i] + offset
        flow[i] = current[i] - velocity
    for i in range(3):
        chord[i] = ship[i] - end[i]
    dist = math.sqrt(chord[0] * chord[0] + chord[1] * chord[1] + chord[2] * chord[2])
    length = fixed_length if not math.isnan(fixed_length) else length_ratio * dist
    out[4] = length
    out[14:17] = end
    if length < dist * (1 - 1e-12):
        out[0] = CABLE_TOO_SHORT
        out[5] = dist
        return
    speed = math.sqrt(flow[0] * flow[0] + flow[1] * flow[1] + flow[2] * flow[2])
    if speed < min_flow:
        out[0] = CABLE_SLOW_FLOW
        out[5] = speed
        return
    load = k * speed * speed
    if weight > max_ratio * load:
        out[0] = CABLE_LIGHT_LOAD
        out[5] = weight / load
        return
    e1 = flow / speed
    along = chord[0] * e1[0] + chord[1] * e1[1] + chord[2] * e1[2]
    across = chord - along * e1
    across_norm = math.sqrt(across[0] * across[0] + across[1] * across[1] + across[2] * across[2])
    if across_norm < 1e-9 * max(dist, 1.0):
        out[0] = CABLE_PARALLEL
        return
    e2 = across / across_norm
    a, b = along / length, across_norm / length
    out[6], out[7] = a, b
    out[8:11] = e1
    out[11:14] = e2
    if not has_guess:
        out[0] = CABLE_NEEDS_GUESS
        return
    converged = False
    for _ in range(max_iter):
        g1, g2, j11, j12, j21, j22 = _cable_residual(c0, lam, a, b)
        if abs(g1) + abs(g2) < tol:
            converged = True
            break
        det = j11 * j22 - j12 * j21
        d_c0, d_lam = (-g1 * j22 + g2 * j12) / det, (-g2 * j11 + g1 * j21) / det
        t = 1.0
        while lam + t * d_lam <= 0:
            t *= 0.5
        c0, lam = c0 + t * d_c0, lam + t * d_lam
    if not converged:
        g1, g2, _, _, _, _ = _cable_residual(c0, lam, a, b)
        out[26], out[27] = g1, g2
        if not abs(g1) + abs(g2) < 1e-8:
            out[0] = CABLE_NOT_CONVERGED
            return
    tension = load * length / lam
    norm = math.sqrt(1 + c0 * c0)
    force = np.empty(3)
    for i in range(3):
        force[i] = tension * ((c0 * e1[i] + e2[i]) / norm)
    body = np.empty(3)
    for i in range(3):
        s = 0.0
        for j in range(3):
            s += rot[j, i] * force[j]
        body[i] = s
    out[0] = CABLE_SOLVED
    out[1], out[2], out[3] = c0, lam, tension
    out[17:20] = force
    out[20:23] = body
    out[23] = attachment[1] * body[2] - attachment[2] * body[1]
    out[24] = attachment[2] * body[0] - attachment[0] * body[2]
    out[25] = attachment[0] * body[1] - attachment[1] * body[0]


@njit(**_JIT)
def polar_to_ned(speed, direction, out):
    """(c cos alpha, c sin alpha, 0) per row (GaussMarkovCurrent.velocity_ned, with the same libm)."""
    for i in range(speed.shape[0]):
        out[i, 0] = speed[i] * math.cos(direction[i])
        out[i, 1] = speed[i] * math.sin(direction[i])
        out[i, 2] = 0.0


@njit(**_JIT)
def cos_product(a, b, out):
    """cos(a) cos(b) per element (the altimeter's tilt, sensors.SensorSuite, with the same libm)."""
    for i in range(a.shape[0]):
        out[i] = math.cos(a[i]) * math.cos(b[i])


def pack_batch(models) -> Packed:
    """:func:`pack` of each model, stacked on a leading axis; hydrodynamic tables of different lengths are
    padded with terms of coefficient zero on the constant factor (they add exactly 0.0), and the
    row-compressed non-zeros with entries no row reaches (each vehicle keeps its own row starts)."""
    packed: dict = {}   # a model shared by several vehicles is packed once
    packs = [packed[id(m)] if id(m) in packed else packed.setdefault(id(m), pack(m)) for m in models]
    terms = max(p.h_coef.shape[0] for p in packs)
    width = max(p.h_signed.shape[1] for p in packs)
    nnz = max(p.sp_idx.shape[0] for p in packs)

    def padded(p: Packed) -> Packed:
        n, w = p.h_coef.shape[0], p.h_signed.shape[1]
        signed = np.full((terms, width), 6, dtype=np.int64)
        absolute = np.full((terms, width), 6, dtype=np.int64)
        signed[:n, :w], absolute[:n, :w] = p.h_signed, p.h_absolute
        axis = np.zeros(terms, dtype=np.int64)
        axis[:n] = p.h_axis
        coef = np.zeros(terms)
        coef[:n] = p.h_coef
        idx, val = np.zeros(nnz, dtype=np.int64), np.zeros(nnz)
        idx[:p.sp_idx.shape[0]], val[:p.sp_val.shape[0]] = p.sp_idx, p.sp_val
        return p._replace(h_axis=axis, h_coef=coef, h_signed=signed, h_absolute=absolute, sp_idx=idx, sp_val=val)
    packs = [padded(p) for p in packs]
    return Packed(*(np.ascontiguousarray(np.stack([getattr(p, f) for p in packs])) for f in Packed._fields))


_NONE3 = np.zeros(3)
_NONE6 = np.zeros(6)


def derivatives(packed: Packed, efficiency, state, pitch, current_ned=None, external=None,
                thrusters_on: bool = True) -> np.ndarray:
    """x' (12,): :meth:`VehicleModel.derivatives` of the packed model, compiled."""
    out = np.empty(12)
    rhs(np.ascontiguousarray(state, dtype=np.float64), np.ascontiguousarray(pitch, dtype=np.float64),
        _NONE3 if current_ned is None else np.ascontiguousarray(current_ned, dtype=np.float64),
        current_ned is not None,
        _NONE6 if external is None else np.ascontiguousarray(external, dtype=np.float64), external is not None,
        bool(thrusters_on), np.ascontiguousarray(efficiency, dtype=np.float64), *packed, out,
        np.empty(work_size(packed.directions.shape[0])))
    return out


def warm() -> None:
    """Compile (or load from the cache) every kernel with the argument types the integrator uses.
    ``./seapup setup`` runs this after building seapup_sim, so no test or node compiles them itself."""
    from seapup_sim.vehicle import VehicleModel
    from seapup_sim.vehicle_config import load_vehicle_config
    model = VehicleModel(load_vehicle_config("baseline"))
    packed = pack(model)
    rk4_checked(np.zeros(12), np.zeros(4), np.zeros(4), 0.05, 0.1, _NONE3, False, _NONE6, False, True,
                model.thrusters.efficiency, *packed, np.ones(12), np.empty(12), np.empty(4))
    derivatives(packed, model.thrusters.efficiency, np.zeros(12), np.zeros(4))
    # and with a read-only command (a law's Command holds its pitches read-only): each is its own numba type
    frozen = np.zeros(4)
    frozen.setflags(write=False)
    for command in (np.zeros(4), frozen):
        rk4_period(np.zeros(12), np.zeros(4), command, 0.05, 0.1, np.zeros((2, 3)), False, _NONE6, False, True,
                   model.thrusters.efficiency, *packed, np.ones(12), np.empty((2, 12)), np.empty((2, 4)), np.empty(3))
    rk4_checked(np.zeros(12), np.zeros(4), frozen, 0.05, 0.1, _NONE3, False, _NONE6, False, True,
                model.thrusters.efficiency, *packed, np.ones(12), np.empty(12), np.empty(4))
    rov = VehicleModel(load_vehicle_config("bluerov2_heavy"))   # fixed-pitch thrusters: the curve's branch
    mixed = rov.inputs.to_actuators(np.zeros(4))   # the mixer's commands: a read-only array
    rk4_checked(np.zeros(12), np.zeros(8), mixed, 0.05, 0.1, _NONE3, False, _NONE6, False, True,
                rov.thrusters.efficiency, *pack(rov), np.ones(12), np.empty(12), np.empty(8))
    rk4_period(np.zeros(12), np.zeros(8), mixed, 0.05, 0.1, np.zeros((2, 3)), False, _NONE6, False, True,
               rov.thrusters.efficiency, *pack(rov), np.ones(12), np.empty((2, 12)), np.empty((2, 8)), np.empty(3))
    polar_to_ned(np.zeros(2), np.zeros(2), np.zeros((2, 3)))
    cos_product(np.zeros(2), np.zeros(2), np.zeros(2))
    two = pack_batch([model, model])   # BatchPlant.step's calls
    batch = (np.zeros((2, 12)), np.zeros((2, 4)), np.zeros((2, 4)), np.full(2, 0.05), 0.1, np.zeros((2, 3)), True,
             np.zeros((2, 6)), False, np.ones(2, dtype=np.bool_), np.ones((2, 4)), *two, np.ones(2, dtype=np.bool_),
             np.empty((2, 12)), np.empty((2, 4)))
    rk4_batch(*batch)


if __name__ == "__main__":
    warm()
