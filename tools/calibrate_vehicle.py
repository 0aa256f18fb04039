#!/usr/bin/env python3
"""Calibrate the Seapup model's free parameters to the thesis (developer tool).

How the numbers in ``seapup_sim/vehicles/baseline.yaml`` marked "calibrated"
were obtained: scipy.optimize.least_squares over the parameters in FREE,
minimising the misfit to the targets of ``seapup_sim.verification.TARGETS``
(each residual = (value - thesis) / tolerance, secondary targets weighted
0.3). The vectored thrusters' heave installation coefficient is not free: it
is solved so that hovering needs exactly -13.098 deg (eq. 5.2).

Usage (inside ``eval "$(./seapup env)"``):
    python tools/calibrate_vehicle.py [--iterations N] [--only P1,P2,...] [--write]
--write stores the result into baseline.yaml (values only; comments kept);
--only frees just those parameters (the others stay at baseline.yaml's values).

Round 2 (issue 11) added the large-amplitude yaw of App. A.3 (full push-pull
of the mains from rest: 53.3 / 50.0 deg/s) and the non-minimum-phase crossover
of sec. 3.7 (the pitch transmission-zero pair on the imaginary axis at
0.7 m/s) as targets, and the heave-pitch added-mass coupling
``added_mass[2][4] = [4][2]`` (-Z_qdot = -M_wdot, kg m) as a free parameter:
    python tools/calibrate_vehicle.py --only "hydrodynamics.N_r,hydrodynamics.N_r|r|,added_mass.2.4" --write
takes about 2 minutes on 2 cores.

Round 3 (issue 41) added sec. 3.8's umbilical trials (the surge test with the cable at 50, 100 and 200 m:
top speed and F_x, as ``./seapup verify`` scores them; ``--no-umbilical`` leaves them out, about 17 times
cheaper) and ``--base`` (a candidate vehicle file to start from, e.g. sec. 3.1's geometry) and ``--bound``
(free a parameter that FREE lacks, or change a bound: ``--bound "hydrodynamics.N_v=-20,20"``).
"""
from __future__ import annotations

import argparse
import copy
import math
import sys
import time
from pathlib import Path

import numpy as np
import scipy.optimize

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "ros2_ws/src/seapup_sim"))

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT  # noqa: E402
from seapup_sim.analysis import TrimError, linearise, system_zeros, trim  # noqa: E402
from seapup_sim.vehicle import VehicleModel  # noqa: E402
from seapup_sim.vehicle_config import load_vehicle_config  # noqa: E402
from seapup_sim.verification import oscillatory_mode, output_matrix, run_open_loop, verify_umbilical  # noqa: E402

D = math.radians
YAML = ROOT / "ros2_ws/src/seapup_sim/seapup_sim/vehicles/baseline.yaml"

# (path in the config, lower, upper)
FREE = {
    "hydrodynamics.X_u|u|": (-400.0, -5.0),
    "hydrodynamics.X_u": (-60.0, 0.0),
    "hydrodynamics.M_u|u|": (0.0, 200.0),
    "hydrodynamics.Z_uu": (-300.0, 0.0),
    "hydrodynamics.M_|u|q": (-200.0, 0.0),
    "hydrodynamics.M_q": (-60.0, 0.0),
    "hydrodynamics.Z_w|w|": (-3000.0, -50.0),
    "hydrodynamics.Z_ww": (-1500.0, 1500.0),
    "hydrodynamics.Z_w": (-300.0, 0.0),
    "hydrodynamics.Y_v|v|": (-3000.0, -50.0),
    "hydrodynamics.K_v|v|": (-200.0, 200.0),
    "hydrodynamics.K_p": (-30.0, 0.0),
    "hydrodynamics.K_p|p|": (-30.0, 0.0),
    "hydrodynamics.N_r|r|": (-100.0, 0.0),
    "hydrodynamics.N_r": (-60.0, 0.0),
    "thrusters.k_beta": (0.05, 0.6),
    "thrusters.k_j": (0.0, 1.5),
    "thrusters.installation.0.0": (0.1, 1.0),   # X, mains (both kept equal)
    "thrusters.installation.1.2": (0.1, 1.0),   # Y, vectored (both kept equal)
    "thrusters.positions.2.2": (-0.4, 0.0),     # vectored thrusters' height (roll arm)
    # a bluff open frame displacing ~0.1 m^3 has surge added mass of tens of kg
    "added_mass.0.0": (30.0, 150.0),
    "added_mass.4.4": (2.0, 40.0),
    "rigid_body.inertia_cg.1.1": (5.0, 30.0),
    # heave-pitch added-mass coupling (fore-aft asymmetric frame): -x of the heave added mass's centre
    # times the heave added mass; bounded well inside positive definiteness of the mass matrix
    "added_mass.2.4": (-40.0, 40.0),
}
TIED = {"thrusters.installation.0.0": ["thrusters.installation.0.1"],
        "thrusters.installation.1.2": ["thrusters.installation.1.3"],
        "thrusters.positions.2.2": ["thrusters.positions.3.2"],
        "added_mass.2.4": ["added_mass.4.2"]}


def get(cfg, path):
    node = cfg
    for part in path.split("."):
        node = node[int(part)] if isinstance(node, list) else node[part]
    return node


def put(cfg, path, value):
    *head, last = path.split(".")
    node = cfg
    for part in head:
        node = node[int(part)] if isinstance(node, list) else node[part]
    if isinstance(node, list):
        node[int(last)] = float(value)
    else:
        node[last] = float(value)


def apply(base, z, free=None):
    cfg = copy.deepcopy(base)
    for path, value in zip(free or FREE, z):
        put(cfg, path, value)
        for other in TIED.get(path, []):
            put(cfg, other, value)
    solve_hover(cfg)
    return cfg


def solve_hover(cfg):
    """Vectored heave installation coefficient so that hover is at -13.098 deg."""
    model = VehicleModel(cfg)
    th = model.thrusters
    t_hover = th.bollard_thrust(D(-13.098))
    net_weight = model.weight - model.buoyancy
    c = net_weight / (2 * abs(t_hover) * th.open_water[2, 2])
    for j in (2, 3):
        put(cfg, f"thrusters.installation.2.{j}", c)


def pitch_zero_real(model, speed):
    """Largest real part of the transmission zeros at ``speed`` (sec. 3.7): 0 where the model turns
    non-minimum phase."""
    guess = None
    for s in np.linspace(0.0, speed, 8):  # warm-started trims up to the speed
        tr = trim(model, float(s), guess, enforce_limits=False)
        guess = tr.unknowns
    a, b = linearise(model, tr.state, tr.blade_pitch)
    zs = [z.value for z in system_zeros(a, b, output_matrix()) if z.kind == "transmission"]
    return max(z.real for z in zs)


def measure(cfg, umbilical: bool = True):
    """The calibrated quantities, cheaply (dt 0.1 s, shorter runs); with ``umbilical``, sec. 3.8's trials as
    verify flies them."""
    model = VehicleModel(cfg)
    lim = BLADE_PITCH_LIMIT
    out = {}
    t, x, _ = run_open_loop(model, np.array([lim, lim, 0, 0]), 25.0)
    u = x[:, 6]
    out["max_u"] = u.max()
    out["steady_pitch"] = math.degrees(x[-1, 4])
    out["max_pitch"] = math.degrees(x[:, 4].max())
    out["max_pitch_rate"] = math.degrees(x[:, 10].max())
    above = np.flatnonzero(u >= 0.95 * u[-1])
    out["rise95"] = t[above[0]] if above.size else 25.0
    t, x, _ = run_open_loop(model, np.array([0, 0, lim, -lim]), 25.0)
    out["max_v"] = np.abs(x[:, 7]).max()
    out["max_roll"] = math.degrees(np.abs(x[:, 3]).max())
    out["max_roll_rate"] = math.degrees(np.abs(x[:, 9]).max())
    _, x, _ = run_open_loop(model, np.array([0, 0, lim, lim]), 20.0)
    out["w_down"] = x[:, 8].max()
    _, x, _ = run_open_loop(model, np.array([0, 0, -lim, -lim]), 20.0)
    out["w_up"] = (-x[:, 8]).max()
    a, _ = linearise(model, np.zeros(12), np.zeros(4), thrusters_on=False)
    roll, pitch = oscillatory_mode(a, 3), oscillatory_mode(a, 4)
    out["roll_re"], out["roll_im"] = roll.real, roll.imag
    out["pitch_re"], out["pitch_im"] = pitch.real, pitch.imag
    hover = trim(model, 0.0)
    try:
        t07 = trim(model, 0.7, [0.1, 0.2, -0.1])
        out["trim_pitch"] = math.degrees(t07.pitch_angle)
        out["trim_main"] = math.degrees(t07.blade_pitch[0])
        out["trim_vect"] = math.degrees(t07.blade_pitch[2])
    except TrimError:
        out["trim_pitch"], out["trim_main"], out["trim_vect"] = 40.0, 40.0, 40.0
    for key, cmd, sign in (("yaw_stbd", [lim, -lim, 0, 0], 1.0), ("yaw_port", [-lim, lim, 0, 0], -1.0)):
        _, x, _ = run_open_loop(model, np.array(cmd), 20.0)
        out[key] = math.degrees((sign * x[:, 11]).max())
    out["zero_re_0_7"] = pitch_zero_real(model, 0.7)
    t10 = trim(model, 1.0, [0.3, 0.6, 0.1], enforce_limits=False)
    out["trim1_main"] = math.degrees(t10.blade_pitch[0])
    for j, key in ((0, "main"), (2, "vect")):
        cmd = hover.blade_pitch.copy()
        cmd[j] += D(8.0)
        _, x, _ = run_open_loop(model, cmd, 10.0, pitch0=hover.blade_pitch)
        out[f"b1_{key}"] = x[-1, [6, 7, 8, 11]] / 8.0 * np.array([1, 1, 1, 180 / math.pi])
        out[f"b0_{key}"] = x[2, [6, 7, 8, 11]] / 8.0 * np.array([1, 1, 1, 180 / math.pi])
    if umbilical:
        for depth, trial in verify_umbilical(model)[0].items():
            out[f"umbilical_{depth}_u"], out[f"umbilical_{depth}_Fx"] = trial["max_u"], trial["Fx"]
    return out


# (quantity, thesis value, tolerance, weight)
OBJECTIVE = [
    ("max_u", 0.98, 0.049, 1.0), ("steady_pitch", 27.4, 3.0, 1.0),
    ("max_v", 0.34, 0.034, 1.0), ("max_roll", 24.8, 3.0, 1.0),
    ("w_down", 0.33, 0.033, 1.0), ("w_up", 0.17, 0.05, 1.0),
    ("roll_re", -0.185, 0.06, 1.0), ("roll_im", 2.56, 0.2, 1.0),
    ("pitch_re", -0.167, 0.05, 1.0), ("pitch_im", 1.46, 0.12, 1.0),
    ("max_pitch", 32.5, 3.0, 0.3), ("max_pitch_rate", 23.2, 4.6, 0.3),
    ("max_roll_rate", 32.7, 6.5, 0.3), ("rise95", 2.2, 0.55, 1.0),
    ("trim_pitch", 10.0, 3.0, 0.3), ("trim_main", 14.6, 3.0, 0.3), ("trim_vect", -5.9, 3.0, 0.3),
    # round 2 (issue 11): App. A.3's zero-radius turn; sec. 3.7's crossover at 0.7 m/s
    ("yaw_stbd", 53.3, 8.0, 1.0), ("yaw_port", 50.0, 7.5, 1.0), ("zero_re_0_7", 0.0, 0.05, 1.0),
]
#: Round 3 (issue 41): sec. 3.8's surge trials with the umbilical (primaries of verify: the speeds within
#: 10 %, F_x within 15 %, thesis_targets.yaml's cable_speed and cable_force bands)
UMBILICAL = [(f"umbilical_{d}_u", u, 0.10 * u, 1.0) for d, u in (("50", 0.474), ("100", 0.354), ("200", 0.259))] + [
    (f"umbilical_{d}_Fx", f, 0.15 * abs(f), 1.0) for d, f in (("50", -148.0), ("100", -163.0), ("200", -172.0))]


def residuals(z, base, verbose=False, free=None, umbilical=True):
    cfg = apply(base, z, free)
    objective = OBJECTIVE + (UMBILICAL if umbilical else [])
    try:
        m = measure(cfg, umbilical)
    except Exception as exc:  # a diverged trial: large, finite misfit
        if verbose:
            print("diverged:", exc)
        return np.full(len(objective) + 11, 50.0)
    res = [w * (m[k] - v) / tol for k, v, tol, w in objective]
    # trim must exist up to 1 m/s within the blade limits (primary)
    res.append(max(0.0, m["trim1_main"] - 33.0) / 2.0)
    b1m, b1v = m["b1_main"], m["b1_vect"]
    res += [0.3 * (b1m[0] - 0.0246) / 0.0123, 0.3 * (b1m[3] - 1.96) / 0.98,
            0.3 * (b1v[2] - 0.004875) / 0.0025, 0.3 * (b1v[1] + 0.00766) / 0.0038,
            0.3 * (b1m[2] + 0.0006) / 0.0006,
            0.3 * (m["b0_main"][0] - 0.0026) / 0.0013, 0.3 * (m["b0_main"][3] - 0.2629) / 0.13,
            0.3 * (m["b0_vect"][2] - 0.000525) / 0.00026,
            # round 3: eq. 5.3b's small vectored entries, whose sign verify checks (surge; the yaw that a
            # vectored thruster abreast of the CG barely makes)
            0.3 * (b1v[0] - 0.00064) / 0.0013, 0.3 * (b1v[3] + 0.0499) / 0.1]
    if verbose:
        for k, v, tol, w in objective:
            print(f"  {k:<16} {m[k]:10.4f}  thesis {v}")
        print(f"  trim 1.0 main   {m['trim1_main']:.2f}")
        print(f"  B1 main {np.round(b1m, 5)}  vect {np.round(b1v, 5)}")
        print(f"  B0 main {np.round(m['b0_main'], 5)}  vect {np.round(m['b0_vect'], 5)}")
    return np.array(res)


def write_yaml(cfg, free=FREE, target=YAML):
    """Store the fitted values (``free``'s and those tied to them) in ``target`` (baseline.yaml, or the file
    ``--base`` named), keeping its comments (ruamel.yaml)."""
    from ruamel.yaml import YAML as RoundTrip
    rt = RoundTrip()
    rt.width = 120
    doc = rt.load(Path(target).read_text())
    for path in list(free) + [p for key in free for p in TIED.get(key, [])] + [
            "thrusters.installation.2.2", "thrusters.installation.2.3"]:
        put(doc, path, float(f"{get(cfg, path):.6g}"))
    with open(target, "w") as f:
        rt.dump(doc, f)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--iterations", type=int, default=30)
    ap.add_argument("--write", action="store_true")
    ap.add_argument("--start", help="start from a .npy vector of FREE values")
    ap.add_argument("--only", help="comma-separated parameters of FREE to fit (default: all)")
    ap.add_argument("--base", default="baseline", help="the vehicle (shipped name or file) to start from")
    ap.add_argument("--bound", action="append", default=[], metavar="PATH=LO,HI",
                    help="free PATH within [LO, HI] (a parameter FREE lacks, or another bound); repeatable")
    ap.add_argument("--no-umbilical", action="store_true", help="leave sec. 3.8's umbilical trials out")
    args = ap.parse_args()
    base = load_vehicle_config(args.base)
    bounds = dict(FREE)
    for text in args.bound:
        path, _, pair = text.partition("=")
        lo, hi = (float(v) for v in pair.split(","))
        bounds[path] = (lo, hi)
    free = {p: bounds[p] for p in args.only.split(",")} if args.only else bounds
    umbilical = not args.no_umbilical
    z0 = np.array([get(base, p) for p in free])
    lo = np.array([b[0] for b in free.values()])
    hi = np.array([b[1] for b in free.values()])
    if args.start:
        z0 = np.load(args.start)
    z0 = np.clip(z0, lo + 1e-9, hi - 1e-9)
    t0 = time.perf_counter()
    print("start cost", 0.5 * np.sum(residuals(z0, base, free=free, umbilical=umbilical) ** 2))
    sol = scipy.optimize.least_squares(residuals, z0, args=(base, False, free, umbilical), bounds=(lo, hi),
                                       x_scale=np.abs(hi - lo) / 10, diff_step=1e-3,
                                       max_nfev=args.iterations, verbose=1)
    print(f"final cost {sol.cost:.4g} after {time.perf_counter() - t0:.0f} s")
    residuals(sol.x, base, verbose=True, free=free, umbilical=umbilical)
    np.save(ROOT / "tools" / ".calibration_last.npy", sol.x)
    cfg = apply(base, sol.x, free)
    for path in free:
        print(f"{path:<36} {get(cfg, path):.6g}")
    print("vectored Z installation", get(cfg, "thrusters.installation.2.2"))
    if args.write:
        write_yaml(cfg, free, YAML if args.base == "baseline" else args.base)


if __name__ == "__main__":
    main()
