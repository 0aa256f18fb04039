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
- :func:`rhs` is inlined into the step and keeps the reference's small vectors (R, nu_r, the Coriolis terms,
  each thruster's flow) as scalars, its few arrays as offsets in one scratch array: no array views made per
  evaluation (each costs numba a reference count), the same operations in the same order -- the same bits
  as the evaluation it replaced, and about 1.8x faster (issue 42; ``./seapup bench``).
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

__all__ = ["Packed", "pack", "Flat", "flatten", "BatchFlat", "pack_batch", "derivatives", "rk4_checked", "rk4_batch", "rhs",
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

#: The header of a :class:`Flat` model's integers, entry by entry: the number of thrusters, of hydrodynamic terms and
#: their width (factors per term); where the row starts, the columns, the first term of each axis (7 entries: the
#: terms grouped by axis, the last the end) and the terms' signed and absolute factor indices (rows of ``width``)
#: begin in the integers; where the non-zeros, the term coefficients, the thrust
#: axes (rows of 3), the scalars and the two curve tables begin in the floats, each table with its length.
(I_THRUSTERS, I_TERMS, I_WIDTH, I_PTR, I_IDX, I_AXIS, I_SIGNED, I_ABSOLUTE, I_VAL, I_COEF, I_DIRECTIONS, I_SCALARS,
 I_CURVE_X, I_CURVE_X_SIZE, I_CURVE_Y, I_CURVE_Y_SIZE, HEADER) = range(17)


class Flat(NamedTuple):
    """A :class:`Packed` model as the kernels take it: all its integers in one array, its floats in another, placed
    by the integers' header (:data:`HEADER` entries: ``I_*``). Two arguments where there were eleven: a kernel
    call's cost is mostly its arguments' unboxing (about 70 ns an array), which the single vehicle pays every
    step. A batch's models are rows of two such arrays (:class:`BatchFlat`)."""

    ints: np.ndarray     # int64
    floats: np.ndarray   # float64


def flatten(packed: Packed) -> Flat:
    """``packed``'s arrays laid end to end (:class:`Flat`), the same numbers."""
    terms, width = packed.h_signed.shape
    # the hydrodynamic terms grouped by axis, in their order within each (a stable sort): each axis's force is then
    # a running sum of its terms alone, the same additions in the same order as the table's
    order = np.argsort(packed.h_axis, kind="stable")
    axis_starts = np.searchsorted(packed.h_axis[order], np.arange(7), side="left")
    int_parts = [packed.sp_ptr, packed.sp_idx, axis_starts, packed.h_signed[order].reshape(-1),
                 packed.h_absolute[order].reshape(-1)]
    float_parts = [packed.sp_val, packed.h_coef[order], packed.directions.reshape(-1), packed.scalars, packed.curve_x,
                   packed.curve_y]
    int_starts = HEADER + np.concatenate(([0], np.cumsum([a.size for a in int_parts])))
    float_starts = np.concatenate(([0], np.cumsum([a.size for a in float_parts])))
    header = np.zeros(HEADER, dtype=np.int64)
    header[[I_THRUSTERS, I_TERMS, I_WIDTH]] = packed.directions.shape[0], terms, width
    header[[I_PTR, I_IDX, I_AXIS, I_SIGNED, I_ABSOLUTE]] = int_starts[:5]
    header[[I_VAL, I_COEF, I_DIRECTIONS, I_SCALARS, I_CURVE_X, I_CURVE_Y]] = float_starts[:6]
    header[[I_CURVE_X_SIZE, I_CURVE_Y_SIZE]] = packed.curve_x.size, packed.curve_y.size
    ints = np.concatenate([header] + [np.asarray(a, dtype=np.int64) for a in int_parts])
    floats = np.concatenate([np.asarray(a, dtype=np.float64) for a in float_parts])
    return Flat(np.ascontiguousarray(ints), np.ascontiguousarray(floats))


@njit(inline="always", **_JIT)
def thrust_rows(n):
    """(first row of the thrust matrix, of the force map) in the row-compressed block, for n thrusters."""
    return POINT_MAP + 3 * n, POINT_MAP + 3 * n + 6


@njit(inline="always", **_JIT)
def work_size(n):
    """Scratch floats :func:`rhs` needs for n thrusters."""
    return _W_THRUST + 4 * n


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
def rotation_entries(cf, sf, ct, st, cp, sp):
    """R's nine entries by rows, from the cosines and sines of roll, pitch and yaw (eq. 2.1, z-y-x Euler angles;
    frames.rotation_body_to_ned): v_ned = R v_body."""
    return (cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf,
            sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf,
            -st, ct * sf, ct * cf)


@njit(inline="always", **_JIT)
def rotation(phi, theta, psi, rot):
    """R with v_ned = R v_body (:func:`rotation_entries`) into ``rot``."""
    entries = rotation_entries(math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta), math.cos(psi),
                               math.sin(psi))
    for k in range(9):
        rot[k // 3, k % 3] = entries[k]


@njit(inline="always", **_JIT)
def dot3(a0, a1, a2, b0, b1, b2):
    """a . b as the reference's products sum it: begun at +0.0, term by term."""
    s = 0.0
    s += a0 * b0
    s += a1 * b1
    s += a2 * b2
    return s


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


@njit(inline="always", **_JIT)
def row_dot(ints, floats, ptr, idx, val, row, x, offset):
    """Row ``row`` of the row-compressed block (:class:`Packed`; in ``ints`` and ``floats`` from ``ptr``, ``idx`` and
    ``val``: :class:`Flat`) times the vector at ``x[offset:]``: its non-zeros in order, the sum begun at +0.0."""
    s = 0.0
    for k in range(ints[ptr + row], ints[ptr + row + 1]):
        s += floats[val + k] * x[offset + ints[idx + k]]
    return s


@njit(inline="always", **_JIT)
def kirchhoff(ints, floats, ptr, idx, val, first, x, offset, u, v, w, p, q, r):
    """``-[w x p_v ; w x p_w + v x p_v]`` with p = M nu (vehicle.kirchhoff_coriolis) as six floats, M the block's
    rows from ``first``, nu = (u, v, w, p, q, r) also at ``x[offset:]``."""
    a = row_dot(ints, floats, ptr, idx, val, first, x, offset)
    b = row_dot(ints, floats, ptr, idx, val, first + 1, x, offset)
    c = row_dot(ints, floats, ptr, idx, val, first + 2, x, offset)
    d = row_dot(ints, floats, ptr, idx, val, first + 3, x, offset)
    e = row_dot(ints, floats, ptr, idx, val, first + 4, x, offset)
    f = row_dot(ints, floats, ptr, idx, val, first + 5, x, offset)
    return (-(q * c - r * b), -(r * a - p * c), -(p * b - q * a), -(q * f - r * e) - (v * c - w * b),
            -(r * d - p * f) - (w * a - u * c), -(p * e - q * d) - (u * b - v * a))


#: Where :func:`rhs` keeps its vectors in ``work``: nu_r and the constant 1 (the hydrodynamic terms' factors), the
#: hydrodynamic forces, tau, then the thrusts and the momentum drags (N and 3N)
_W_EXT, _W_HYDRO, _W_TAU, _W_THRUST = 0, 7, 13, 19


@njit(inline="always", **_JIT)
def rhs(x, pitch, current, use_current, external, use_external, thrusters_on, efficiency, ints, floats, out,
        work):
    """x' (eq. 2.1-2.3) into ``out`` (12,); VehicleModel.derivatives term by term, for N thrusters of either
    kind (``pitch``: the Seapup's blade pitches, or fixed-pitch thrusters' lagged commands). ``work``: at least
    :func:`work_size` (N) floats of scratch (no allocation in the kernel). Scalars where the reference has small
    vectors, and each product's terms in the reference's order, so the same bits. ``ints``, ``floats``: the model
    (:func:`flatten`)."""
    n, width = ints[I_THRUSTERS], ints[I_WIDTH]
    o_axis, o_signed, o_absolute = ints[I_AXIS], ints[I_SIGNED], ints[I_ABSOLUTE]
    f_coef, f_dir, f_sc = ints[I_COEF], ints[I_DIRECTIONS], ints[I_SCALARS]
    ptr, idx, val = ints[I_PTR], ints[I_IDX], ints[I_VAL]
    cf, sf = math.cos(x[3]), math.sin(x[3])
    ct, st = math.cos(x[4]), math.sin(x[4])
    cp, sp = math.cos(x[5]), math.sin(x[5])
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rotation_entries(cf, sf, ct, st, cp, sp)
    u, v, w, p, q, r = x[6], x[7], x[8], x[9], x[10], x[11]
    ur, vr, wr = u, v, w
    if use_current:   # nu_r = nu - R^T v_c
        c0, c1, c2 = current[0], current[1], current[2]
        ur -= dot3(r00, r10, r20, c0, c1, c2)
        vr -= dot3(r01, r11, r21, c0, c1, c2)
        wr -= dot3(r02, r12, r22, c0, c1, c2)
    e = _W_EXT
    work[e], work[e + 1], work[e + 2], work[e + 3], work[e + 4], work[e + 5], work[e + 6] = ur, vr, wr, p, q, r, 1.0
    # -[w x p_v ; w x p_w + v x p_v], p = M nu, for the rigid body (nu) and the added mass (nu_r)
    rigid0, rigid1, rigid2, rigid3, rigid4, rigid5 = kirchhoff(ints, floats, ptr, idx, val, M_RIGID, x, 6, u, v, w,
                                                                p, q, r)
    added0, added1, added2, added3, added4, added5 = kirchhoff(ints, floats, ptr, idx, val, M_ADDED, work, e, ur, vr,
                                                               wr, p, q, r)
    h = _W_HYDRO
    for axis in range(6):   # each axis's terms (flatten: grouped by axis, in the table's order)
        force = 0.0
        for k in range(ints[o_axis + axis], ints[o_axis + axis + 1]):
            if width == 2:   # the shipped tables' width, unrolled: the same products
                first, second = o_signed + 2 * k, o_absolute + 2 * k
                signed = 1.0 * work[e + ints[first]] * work[e + ints[first + 1]]
                absolute = 1.0 * abs(work[e + ints[second]]) * abs(work[e + ints[second + 1]])
            else:
                signed = 1.0
                for i in range(width):
                    signed *= work[e + ints[o_signed + k * width + i]]
                absolute = 1.0
                for i in range(width):
                    absolute *= abs(work[e + ints[o_absolute + k * width + i]])
            force += floats[f_coef + k] * signed * absolute
        work[h + axis] = force
    net, ax, ay, az = floats[f_sc + 6], floats[f_sc + 7], floats[f_sc + 8], floats[f_sc + 9]
    t = _W_TAU   # tau: Coriolis, hydrodynamic, hydrostatic (eq. 2.1-2.3, sec. 2.3.2)
    work[t] = rigid0 + added0 + work[h] + net * r20
    work[t + 1] = rigid1 + added1 + work[h + 1] + net * r21
    work[t + 2] = rigid2 + added2 + work[h + 2] + net * r22
    work[t + 3] = rigid3 + added3 + work[h + 3] + (ay * r22 - az * r21)
    work[t + 4] = rigid4 + added4 + work[h + 4] + (az * r20 - ax * r22)
    work[t + 5] = rigid5 + added5 + work[h + 5] + (ax * r21 - ay * r20)
    thrust_matrix, force_map = thrust_rows(n)
    th, dr = _W_THRUST, _W_THRUST + n
    if thrusters_on and floats[f_sc + 10] == KIND_FIXED_PITCH:   # FixedPitchThrusters.wrench: B (eff * T(c))
        f_x, f_y = ints[I_CURVE_X], ints[I_CURVE_Y]
        curve_x, curve_y = floats[f_x:f_x + ints[I_CURVE_X_SIZE]], floats[f_y:f_y + ints[I_CURVE_Y_SIZE]]
        for j in range(n):
            work[th + j] = efficiency[j] * fixed_pitch_thrust(pitch[j], floats[f_sc + 11], floats[f_sc + 12], curve_x,
                                                              curve_y)
        for i in range(6):
            work[t + i] += row_dot(ints, floats, ptr, idx, val, thrust_matrix + i, work, th)
    elif thrusters_on:
        k_beta, beta0, thrust_scale, kj_nd, md_scale, eps = (floats[f_sc], floats[f_sc + 1], floats[f_sc + 2],
                                                            floats[f_sc + 3], floats[f_sc + 4], floats[f_sc + 5])
        eps2 = eps ** 2
        for j in range(n):
            v0 = row_dot(ints, floats, ptr, idx, val, POINT_MAP + 3 * j, work, e)
            v1 = row_dot(ints, floats, ptr, idx, val, POINT_MAP + 3 * j + 1, work, e)
            v2 = row_dot(ints, floats, ptr, idx, val, POINT_MAP + 3 * j + 2, work, e)
            d0, d1, d2 = floats[f_dir + 3 * j], floats[f_dir + 3 * j + 1], floats[f_dir + 3 * j + 2]
            v_axial = (v0 * d0 + v1 * d1) + v2 * d2
            bollard = k_beta * (pitch[j] - beta0)
            work[th + j] = efficiency[j] * (thrust_scale * (bollard - kj_nd * v_axial))
            k0 = math.sqrt(bollard * bollard + eps2)
            scale = -md_scale * math.sqrt(k0 / math.pi)
            work[dr + 3 * j] = scale * (v0 - v_axial * d0)
            work[dr + 3 * j + 1] = scale * (v1 - v_axial * d1)
            work[dr + 3 * j + 2] = scale * (v2 - v_axial * d2)
        for i in range(6):
            work[t + i] += row_dot(ints, floats, ptr, idx, val, thrust_matrix + i, work, th) \
                + row_dot(ints, floats, ptr, idx, val, force_map + i, work, dr)
    if use_external:
        for i in range(6):
            work[t + i] += external[i]
    out[0] = dot3(r00, r01, r02, u, v, w)   # R nu_v
    out[1] = dot3(r10, r11, r12, u, v, w)
    out[2] = dot3(r20, r21, r22, u, v, w)
    tt = math.tan(x[4])
    out[3] = (p + sf * tt * q) + cf * tt * r
    out[4] = (0.0 * p + cf * q) + (-sf) * r
    out[5] = (0.0 * p + sf / ct * q) + cf / ct * r
    for i in range(6):
        out[6 + i] = row_dot(ints, floats, ptr, idx, val, M_INV + i, work, t)


@njit(**_JIT)
def _rk4_into(x, pitch0, command, tau_actuator, dt, current, use_current, external, use_external, thrusters_on,
              efficiency, ints, floats, new, pitch_end, buf):
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
    rhs(x, p0, current, use_current, external, use_external, thrusters_on, efficiency, ints, floats, k1, work)
    for i in range(12):
        xs[i] = x[i] + half * k1[i]
    rhs(xs, ph, current, use_current, external, use_external, thrusters_on, efficiency, ints, floats, k2, work)
    for i in range(12):
        xs[i] = x[i] + half * k2[i]
    rhs(xs, ph, current, use_current, external, use_external, thrusters_on, efficiency, ints, floats, k3, work)
    for i in range(12):
        xs[i] = x[i] + dt * k3[i]
    rhs(xs, p1, current, use_current, external, use_external, thrusters_on, efficiency, ints, floats, k4, work)
    sixth = dt / 6.0
    for i in range(12):
        new[i] = x[i] + sixth * (((k1[i] + 2.0 * k2[i]) + 2.0 * k3[i]) + k4[i])
    for j in range(n):
        pitch_end[j] = p1[j]



@njit(**_JIT)
def rk4_checked(x, pitch0, command, tau_actuator, dt, current, use_current, external, use_external, thrusters_on,
                efficiency, ints, floats, envelope, new, pitch_end):
    """One physics step (:func:`_rk4_into`), then what :meth:`seapup_sim.integrator.VehicleIntegrator.step` does with the new state, in the
    same call: the envelope check (:func:`seapup_sim.integrator.divergence`: a non-finite value, or one beyond
    ``envelope``) and the roll and yaw wrap to [-pi, pi). Returns -1, or the index of the first state out of the
    envelope (``new`` then holds the step unwrapped, for the caller's message)."""
    _rk4_into(x, pitch0, command, tau_actuator, dt, current, use_current, external, use_external, thrusters_on,
              efficiency, ints, floats, new, pitch_end, np.empty(rk4_scratch(pitch0.shape[0])))
    for i in range(12):
        if not math.isfinite(new[i]) or abs(new[i]) > envelope[i]:
            return i
    new[3] = (new[3] + math.pi) % (2 * math.pi) - math.pi
    new[5] = (new[5] + math.pi) % (2 * math.pi) - math.pi
    return -1


@njit(**_JIT)
def rk4_period(x, pitch0, command, tau_actuator, dt, currents, use_current, external, use_external, thrusters_on,
               efficiency, ints, floats, envelope, states, pitches, accel):
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
                  thrusters_on, efficiency, ints, floats, new, pitch_end, buf)
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
              efficiency, ints, floats, which, envelope, active, new, pitch_end, status):
    """The physics step for each vehicle ``i`` of a batch (a leading axis on every argument but ``dt``, the two
    flags, the models ``ints`` and ``floats`` -- vehicle i flies row ``which[i]``, :class:`BatchFlat` -- and
    ``envelope``) that is ``active``: :func:`rk4_checked`'s step, check and wrap into ``new[i]`` and
    ``pitch_end[i]``, ``status[i]`` -1 or the index of its first state out of the envelope (``new[i]`` then holds
    the step unwrapped). An inactive vehicle keeps its state and pitch (status -1). Vehicle i is stepped by the
    very kernel a single vehicle is, so it equals the single-vehicle step bit for bit. Releases the GIL: threads
    may step disjoint parts of a batch at once (:class:`seapup_sim.batch.BatchPlant`)."""
    buf = np.empty(rk4_scratch(pitches.shape[1]))
    for i in range(states.shape[0]):
        status[i] = -1
        if not active[i]:
            new[i] = states[i]
            pitch_end[i] = pitches[i]
            continue
        out = new[i]
        _rk4_into(states[i], pitches[i], commands[i], taus[i], dt, currents[i], use_current, externals[i],
                  use_external, thrusters_on[i], efficiency[i], ints[which[i]], floats[which[i]], out, pitch_end[i],
                  buf)
        for j in range(12):
            if not math.isfinite(out[j]) or abs(out[j]) > envelope[j]:
                status[i] = j
                break
        if status[i] < 0:
            out[3] = (out[3] + math.pi) % (2 * math.pi) - math.pi
            out[5] = (out[5] + math.pi) % (2 * math.pi) - math.pi


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


class BatchFlat(NamedTuple):
    """The models of a batch (:func:`pack_batch`): each distinct model once, a row of ``ints`` and of ``floats``
    (:class:`Flat`; shorter rows padded with zeros no kernel reads), and ``which`` row each vehicle flies. A
    campaign's thousands of vehicles share a few models: the kernel reads them from a few rows that stay in the
    cache, not from a copy per vehicle."""

    ints: np.ndarray     # (models, width) int64
    floats: np.ndarray   # (models, width) float64
    which: np.ndarray    # (N,) int64: vehicle i flies row which[i]


def pack_batch(models) -> BatchFlat:
    """:func:`flatten` (:func:`pack`) of each distinct model of ``models`` (one per vehicle; the same object may
    appear more than once) and which each vehicle flies (:class:`BatchFlat`)."""
    rows: dict = {}   # id(model) -> its row
    flats, which = [], []
    for m in models:
        if id(m) not in rows:
            rows[id(m)] = len(flats)
            flats.append(flatten(pack(m)))
        which.append(rows[id(m)])
    out = []
    for field in Flat._fields:
        arrays = [getattr(f, field) for f in flats]
        stacked = np.zeros((len(arrays), max(a.size for a in arrays)), dtype=arrays[0].dtype)
        for i, a in enumerate(arrays):
            stacked[i, :a.size] = a
        out.append(stacked)
    return BatchFlat(*out, np.array(which, dtype=np.int64))


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
        bool(thrusters_on), np.ascontiguousarray(efficiency, dtype=np.float64), *flatten(packed), out,
        np.empty(work_size(packed.directions.shape[0])))
    return out


def warm() -> None:
    """Compile (or load from the cache) every kernel with the argument types the integrator uses.
    ``./seapup setup`` runs this after building seapup_sim, so no test or node compiles them itself."""
    from seapup_sim.vehicle import VehicleModel
    from seapup_sim.vehicle_config import load_vehicle_config
    model = VehicleModel(load_vehicle_config("baseline"))
    packed = pack(model)
    flat = flatten(packed)
    rk4_checked(np.zeros(12), np.zeros(4), np.zeros(4), 0.05, 0.1, _NONE3, False, _NONE6, False, True,
                model.thrusters.efficiency, *flat, np.ones(12), np.empty(12), np.empty(4))
    derivatives(packed, model.thrusters.efficiency, np.zeros(12), np.zeros(4))
    # and with a read-only command (a law's Command holds its pitches read-only): each is its own numba type
    frozen = np.zeros(4)
    frozen.setflags(write=False)
    for command in (np.zeros(4), frozen):
        rk4_period(np.zeros(12), np.zeros(4), command, 0.05, 0.1, np.zeros((2, 3)), False, _NONE6, False, True,
                   model.thrusters.efficiency, *flat, np.ones(12), np.empty((2, 12)), np.empty((2, 4)), np.empty(3))
    rk4_checked(np.zeros(12), np.zeros(4), frozen, 0.05, 0.1, _NONE3, False, _NONE6, False, True,
                model.thrusters.efficiency, *flat, np.ones(12), np.empty(12), np.empty(4))
    rov = VehicleModel(load_vehicle_config("bluerov2_heavy"))   # fixed-pitch thrusters: the curve's branch
    mixed = rov.inputs.to_actuators(np.zeros(4))   # the mixer's commands: a read-only array
    rk4_checked(np.zeros(12), np.zeros(8), mixed, 0.05, 0.1, _NONE3, False, _NONE6, False, True,
                rov.thrusters.efficiency, *flatten(pack(rov)), np.ones(12), np.empty(12), np.empty(8))
    rk4_period(np.zeros(12), np.zeros(8), mixed, 0.05, 0.1, np.zeros((2, 3)), False, _NONE6, False, True,
               rov.thrusters.efficiency, *flatten(pack(rov)), np.ones(12), np.empty((2, 12)), np.empty((2, 8)), np.empty(3))
    polar_to_ned(np.zeros(2), np.zeros(2), np.zeros((2, 3)))
    cos_product(np.zeros(2), np.zeros(2), np.zeros(2))
    two = pack_batch([model, model])   # BatchPlant.step's calls
    batch = (np.zeros((2, 12)), np.zeros((2, 4)), np.zeros((2, 4)), np.full(2, 0.05), 0.1, np.zeros((2, 3)), True,
             np.zeros((2, 6)), False, np.ones(2, dtype=np.bool_), np.ones((2, 4)), *two, np.ones(12),
             np.ones(2, dtype=np.bool_), np.empty((2, 12)), np.empty((2, 4)), np.empty(2, dtype=np.int64))
    rk4_batch(*batch)


if __name__ == "__main__":
    warm()
