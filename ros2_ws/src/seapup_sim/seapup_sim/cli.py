"""``./seapup verify``, ``./seapup check-model`` and ``./seapup bench`` (no ROS).

verify       run the open-loop tests of Table 3.2 and the linear analyses,
             print simulated vs thesis values with PASS/FAIL, optionally write
             the JSON results and PNG plots. Exit 1 if a primary target fails.
check-model  report mass-matrix asymmetry, symmetry-breaking terms, negative
             dampers and instability over 0-1 m/s. Exit 1 on any finding.
bench        micro-benchmarks of the model (and later the environment and the
             ROS graph); JSON keys are stable for tracking.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from seapup_sim.integrator import VehicleIntegrator
from seapup_sim.model_check import check_model
from seapup_sim.report import format_rows, write_plots
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import ConfigError, available_configs, load_vehicle_config
from seapup_sim.verification import check_targets, verify

__all__ = ["main"]


def _model(name: str) -> VehicleModel:
    try:
        return VehicleModel(load_vehicle_config(name))
    except ConfigError as exc:
        raise SystemExit(f"seapup: {exc}")


def _jsonable(obj):
    if isinstance(obj, dict):
        return {k: _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def cmd_verify(args) -> int:
    model = _model(args.config)
    t0 = time.perf_counter()
    res, hist = verify(model)
    res["verify_seconds"] = time.perf_counter() - t0
    rows = check_targets(res, model.config_name)
    print(format_rows(rows, f"seapup verify: configuration '{model.config_name}' "
                            f"({res['verify_seconds']:.1f} s)"))
    b1 = np.array(res["step_gains_5hz"]["B1inv"])
    b0 = np.array(res["step_gains_5hz"]["B0inv"])
    print("\nstep gains from hover, 8 deg steps, T_s = 0.2 s (eq. 5.3; rows u v w [m/s] r [deg/s], "
          "columns main port, main stbd, vect stbd, vect port; per deg)")
    for name, m in (("B0inv", b0), ("B1inv", b1)):
        print(f"  {name}:")
        for row in m:
            print("   " + " ".join(f"{v:11.5f}" for v in row))
    ev = res["eigenvalues_quiescent"]
    print("\neigenvalues at hover [1/s]: " + ", ".join(
        f"{re:.4f}{im:+.4f}j" if abs(im) > 1e-9 else f"{re:.4f}" for re, im in ev))
    if args.json:
        res["checks"] = rows
        Path(args.json).write_text(json.dumps(_jsonable(res), indent=1))
        print(f"wrote {args.json}")
    if args.plots:
        for p in write_plots(res, hist, args.plots):
            print(f"wrote {p}")
    return 0 if all(r["pass"] for r in rows if r["primary"]) else 1


def cmd_check_model(args) -> int:
    model = _model(args.config)
    report = check_model(model)
    print(f"seapup check-model: configuration '{report.config}'")
    print(f"  mass {model.mass.mass:.2f} kg, buoyancy {model.mass.buoyancy_mass:.2f} kg, "
          f"CG {np.round(model.mass.cg, 4).tolist()} m, CB {np.round(model.mass.cb, 4).tolist()} m, "
          f"{len(model.hydro.terms)} hydrodynamic terms")
    for speed, worst in report.sweep:
        print(f"  u = {speed:4.2f} m/s: max Re(pole) = {worst:+.5f} 1/s")
    if report.ok:
        print("  no findings: mass matrices symmetric and positive definite, every term "
              "port/starboard-consistent and damping, stable over the speed range")
        return 0
    for f in report.findings:
        print(f"  [{f.kind}] {f.where}: {f.message}")
    print(f"  {len(report.findings)} finding(s)")
    return 1


def cmd_bench(args) -> int:
    model = _model(args.config)
    sim = VehicleIntegrator(model, dt=0.1)
    cmd = np.radians([20.0, 20.0, -10.0, -10.0])
    for _ in range(50):
        sim.step(cmd)
    n = args.steps
    t0 = time.perf_counter()
    for _ in range(n):
        sim.step(cmd)
    per_step = (time.perf_counter() - t0) / n
    out = {"model": {"step_us": per_step * 1e6, "rtf": 0.1 / per_step, "dt": 0.1,
                     "steps": n, "config": model.config_name}}
    # the same step with the quasi-static umbilical solved every step (sec. 3.8)
    from seapup_sim.simulation import load_environment, umbilical_from_environment
    x0 = np.zeros(12)
    x0[2] = 100.0
    cable = umbilical_from_environment(load_environment()["umbilical"], model.rho)
    sim = VehicleIntegrator(model, dt=0.1, state=x0)
    for _ in range(50):
        sim.step(cmd, external=cable.wrench(sim.state))
    t0 = time.perf_counter()
    for _ in range(n):
        sim.step(cmd, external=cable.wrench(sim.state))
    per_cable = (time.perf_counter() - t0) / n
    out["model_umbilical"] = {"step_us": per_cable * 1e6, "rtf": 0.1 / per_cable,
                              "extra_percent": 100.0 * (per_cable / per_step - 1.0)}
    t0 = time.perf_counter()
    verify(model)
    out["verify"] = {"seconds": time.perf_counter() - t0}
    if not args.no_graph:
        from seapup_sim import graph_bench
        print("graph: simulator + open_loop in lockstep (separate processes)...", flush=True)
        out["graph_lockstep_5hz"] = graph_bench.lockstep_rate(0.2, sim_seconds=120.0)
        out["graph_lockstep_20hz"] = graph_bench.lockstep_rate(0.05, sim_seconds=30.0)
        out["dds_round_trip_us"] = graph_bench.dds_round_trip()
        for key in ("graph_lockstep_5hz", "graph_lockstep_20hz"):
            g = out[key]
            print(f"{key}: {g['rtf']:.1f}x real time ({g['steps_per_s']:.0f} steps/s, "
                  f"{g['us_per_step']:.0f} us per step)")
        rt = out["dds_round_trip_us"]
        print(f"DDS round trip to another process: median {rt['median_us']:.0f} us, p99 {rt['p99_us']:.0f} us")
    print(f"model: {per_step * 1e6:.1f} us per RK4 step (dt 0.1 s) = {0.1 / per_step:.0f}x real time")
    print(f"model + umbilical: {per_cable * 1e6:.1f} us per step = {0.1 / per_cable:.0f}x real time "
          f"(+{out['model_umbilical']['extra_percent']:.0f} %; the thesis reports +30 %)")
    print(f"verify: {out['verify']['seconds']:.2f} s")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
        print(f"wrote {args.json}")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="seapup")
    sub = parser.add_subparsers(dest="command", required=True)
    configs = ", ".join(available_configs())
    p = sub.add_parser("verify", help="open-loop verification against the thesis")
    p.add_argument("--config", default="baseline", help=f"configuration ({configs})")
    p.add_argument("--json", help="write the results here")
    p.add_argument("--plots", help="write PNG plots into this directory")
    p.set_defaults(func=cmd_verify)
    p = sub.add_parser("check-model", help="model checker (thesis sec. 3.4-3.5)")
    p.add_argument("--config", default="baseline", help=f"configuration ({configs})")
    p.set_defaults(func=cmd_check_model)
    p = sub.add_parser("bench", help="benchmarks")
    p.add_argument("--config", default="baseline")
    p.add_argument("--steps", type=int, default=3000)
    p.add_argument("--no-graph", action="store_true", help="skip the ROS graph benchmarks")
    p.add_argument("--json", help="write the results here")
    p.set_defaults(func=cmd_bench)
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
