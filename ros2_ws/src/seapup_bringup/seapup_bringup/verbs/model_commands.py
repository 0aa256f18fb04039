"""``./seapup verify``, ``./seapup check-model`` and ``./seapup bench``.

verify       run the open-loop tests of Table 3.2 and the linear analyses,
             print simulated vs thesis values with PASS/FAIL, optionally write
             the JSON results and PNG plots. Exit 1 if a primary target fails.
check-model  report mass-matrix asymmetry, symmetry-breaking terms, negative
             dampers and instability over 0-1 m/s. Exit 1 on any finding.
bench        micro-benchmarks of the model, the umbilical, verify and the ROS
             graph; JSON keys are stable for tracking.

Each is registered in :mod:`seapup_bringup.cli` and takes its own arguments.
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from seapup_bringup.output import add_json_argument, emit_json, progress, text_stream
from seapup_sim.environment_config import load_environment
from seapup_sim.integrator import VehicleIntegrator
from seapup_sim.model_check import check_model as run_model_check
from seapup_runs.targets import verify_rows, verify_summary
from seapup_sim.verification_report import format_rows, write_plots
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import ConfigError, available_configs, load_vehicle_config
from seapup_sim.verification import verify as run_verify

__all__ = ["verify", "check_model", "bench"]


def _model(name: str) -> VehicleModel:
    try:
        return VehicleModel(load_vehicle_config(name))
    except ConfigError as exc:
        raise SystemExit(f"seapup: {exc}")


def _parser(name: str, description: str, config: bool = True) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=f"./seapup {name}", description=description)
    if config:
        parser.add_argument("--config", default="baseline",
                            help=f"a shipped configuration ({', '.join(available_configs())}) or a vehicle file (.yaml)")
    add_json_argument(parser)
    return parser


def verify_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup verify`` (its usage line in ``./seapup help`` is generated from it)."""
    parser = _parser("verify", "open-loop verification of the vehicle model against the thesis")
    parser.add_argument("--plots", help="write PNG plots into this directory")
    return parser


def check_model_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup check-model`` (its usage line in ``./seapup help`` is generated from it)."""
    return _parser("check-model", "model checker (thesis sec. 3.4-3.5)")


def bench_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup bench`` (its usage line in ``./seapup help`` is generated from it)."""
    parser = _parser("bench", "benchmarks")
    parser.add_argument("--steps", type=int, default=3000)
    parser.add_argument("--no-graph", action="store_true", help="skip the ROS graph benchmarks")
    parser.add_argument("--no-campaign", action="store_true", help="skip the Dask campaign throughput benchmark")
    parser.add_argument("--no-report", action="store_true", help="skip the reproduction report's cold/warm timing")
    parser.add_argument("--recording-minutes", type=float, default=10.0,
                        help="wall minutes of the recorder memory benchmark (0 skips it; default 10)")
    parser.add_argument("--plots", help="write the cost curves (against N, threads and workers) as PNGs here")
    return parser


def verify(argv: list[str]) -> int:
    """``./seapup verify``: Table 3.2 and the analyses against the thesis; exit 1 if a primary target fails."""
    args = verify_parser().parse_args(argv)
    out = text_stream(args)
    model = _model(args.config)
    if model.inputs.kind != "direct":   # not a blade-pitch Seapup: Table 3.2 does not apply
        return _verify_against_reference(args, model, out)
    t0 = time.perf_counter()
    res, hist = run_verify(model)
    res["verify_seconds"] = time.perf_counter() - t0
    rows = verify_rows(res, model.config_name)
    table = format_rows(rows, f"seapup verify: configuration '{model.config_name}' ({res['verify_seconds']:.1f} s)",
                        verify_summary(rows))
    *body, summary_line = table.splitlines()
    print("\n".join(body), file=out)
    b1 = np.array(res["step_gains_5hz"]["B1inv"])
    b0 = np.array(res["step_gains_5hz"]["B0inv"])
    print("\nstep gains from hover, 8 deg steps, T_s = 0.2 s (eq. 5.3; rows u v w [m/s] r [deg/s], "
          "columns main port, main stbd, vect stbd, vect port; per deg)", file=out)
    for name, m in (("B0inv", b0), ("B1inv", b1)):
        print(f"  {name}:", file=out)
        for row in m:
            print("   " + " ".join(f"{v:11.5f}" for v in row), file=out)
    ev = res["eigenvalues_quiescent"]
    print("\neigenvalues at hover [1/s]: " + ", ".join(
        f"{re:.4f}{im:+.4f}j" if abs(im) > 1e-9 else f"{re:.4f}" for re, im in ev), file=out)
    res["checks"] = rows
    res["summary"] = verify_summary(rows)
    emit_json(args, res)
    if args.plots:
        for p in write_plots(res, hist, args.plots):
            print(f"wrote {p}", file=out)
    print("\n" + summary_line, file=out)  # last: what decides the exit status
    return 0 if res["summary"]["ok"] else 1


def _verify_against_reference(args, model: VehicleModel, out) -> int:
    """``./seapup verify`` for a vehicle with virtual inputs: its open-loop responses against the paper's own
    model that its description was written from (:mod:`seapup_sim.fossen`), or a one-line refusal without one."""
    from seapup_sim.fossen import available_references, reference_for, verify_fossen
    reference = reference_for(model.config_name)
    if reference is None:
        print(f"seapup verify: error: configuration '{model.config_name}' has virtual inputs and no published "
              f"reference model to verify it against (the thesis's Table 3.2 is the Seapup's; references: "
              f"{', '.join(available_references())}); check-model and a self-test are its checks "
              "(docs/vehicles.md)", file=sys.stderr)
        return 1
    t0 = time.perf_counter()
    rows, hist = verify_fossen(model, reference)
    seconds = time.perf_counter() - t0
    print(f"seapup verify: configuration '{model.config_name}' against {reference.name}'s own equations "
          f"({seconds:.1f} s): open loop from rest, the same thruster commands (sway, heave and yaw at full scale, surge "
          "at 0.3 of it: below the model's heave-pitch instability)", file=out)
    print(f"  {'response':18s} {'unit':6s} {'description':>12s} {'paper':>10s} {'balance':>10s} "
          f"{'rise 90 % [s]':>15s}  ok", file=out)
    for r in rows:
        print(f"  {r['test']:18s} {r['unit']:6s} {r['description']:12.4f} {r['reference']:10.4f} "
              f"{r['balance']:10.4f} {r['rise_description_s']:7.1f} / {r['rise_reference_s']:<5.1f}  "
              f"{'yes' if r['ok'] else 'NO'}", file=out)
    passed = sum(r["ok"] for r in rows)
    summary = {"ok": passed == len(rows), "passed": passed, "checks": len(rows)}
    emit_json(args, {"config": model.config_name, "reference": reference.name, "checks": rows, "summary": summary,
                     "verify_seconds": seconds})
    if args.plots:
        from seapup_sim.verification_report import write_reference_plot
        print(f"wrote {write_reference_plot(hist, rows, args.plots)}", file=out)
    print(f"\nseapup verify: {passed}/{len(rows)} responses within the reference's (steady speed within 1 %, "
          "90 % rise within 0.1 s; 'balance': damping against force alone, which a surge or sway that also pitches "
          "or rolls does not reach)", file=out)
    return 0 if summary["ok"] else 1


def check_model(argv: list[str]) -> int:
    """``./seapup check-model``: exit 1 on any finding."""
    args = check_model_parser().parse_args(argv)
    out = text_stream(args)
    model = _model(args.config)
    report = run_model_check(model)
    emit_json(args, {"config": report.config, "ok": report.ok,
                     "sweep": [{"surge_speed": u, "max_real_pole": w} for u, w in report.sweep],
                     "findings": [{"kind": f.kind, "where": f.where, "message": f.message}
                                  for f in report.findings], "notes": list(report.notes)})
    print(f"seapup check-model: configuration '{report.config}'", file=out)
    print(f"  mass {model.mass_properties.mass:.2f} kg, buoyancy {model.mass_properties.buoyancy_mass:.2f} kg, "
          f"CG {np.round(model.mass_properties.cg, 4).tolist()} m, CB {np.round(model.mass_properties.cb, 4).tolist()} m, "
          f"{len(model.hydro.terms)} hydrodynamic terms", file=out)
    for speed, worst in report.sweep:
        print(f"  u = {speed:4.2f} m/s: max Re(pole) = {worst:+.5f} 1/s", file=out)
    for note in report.notes:
        print(f"  note: {note}", file=out)
    if report.ok:
        print("  no findings: mass matrices symmetric and positive definite, every term "
              "port/starboard-consistent and damping, stable over the speed range"
              + (" but for the modes noted" if any(n.startswith("open-loop") for n in report.notes) else ""), file=out)
        return 0
    for f in report.findings:
        print(f"  [{f.kind}] {f.where}: {f.message}", file=out)
    print(f"  {len(report.findings)} finding(s)", file=out)
    return 1


def _plant_step(model, backend: str, command, steps: int, cable=None) -> dict:
    """Wall and CPU time of one physics step (dt 0.1 s) of ``model`` stepped by ``backend``, after 50
    warm-up steps (which also load the compiled kernels); with ``cable`` the umbilical's wrench is solved
    every step (sec. 3.8) from 100 m depth."""
    x0 = np.zeros(12)
    x0[2] = 100.0 if cable is not None else 0.0
    plant = VehicleIntegrator(model, dt=0.1, state=x0, backend=backend)

    def step():
        plant.step(command, external=cable.wrench(plant.state) if cable is not None else None)
    for _ in range(50):
        step()
    wall, cpu = time.perf_counter(), time.process_time()
    for _ in range(steps):
        step()
    wall, cpu = (time.perf_counter() - wall) / steps, (time.process_time() - cpu) / steps
    return {"backend": plant.backend if plant.compiled or backend == "numpy" else "numpy", "step_us": wall * 1e6,
            "cpu_us": cpu * 1e6, "rtf": 0.1 / wall, "steps": steps}


def _batch_step(model, vehicles: int, command, steps: int, threads: int = 1) -> dict:
    """Vehicle-steps per second (wall and CPU) of the batch plant stepping ``vehicles`` copies of ``model``
    in a current on ``threads`` threads, after one warm-up step."""
    from seapup_sim.batch import BatchPlant
    batch = BatchPlant([model] * vehicles, dt=0.1, threads=threads)
    commands, currents = np.tile(command, (vehicles, 1)), np.tile([0.2, 0.1, 0.0], (vehicles, 1))
    batch.step(commands, currents)
    wall, cpu = time.perf_counter(), time.process_time()
    for _ in range(steps):
        batch.step(commands, currents)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    done = vehicles * steps
    return {"vehicles": vehicles, "steps": steps, "threads": threads, "vehicle_steps_per_s": done / wall,
            "cpu_vehicle_steps_per_s": done / cpu, "cpu_us_per_vehicle_step": cpu / done * 1e6,
            "rtf_per_vehicle": 0.1 * done / cpu}


#: The bench's campaign: runs, and runs per task. A campaign is thousands of runs; at 1024 its time is the runs', not
#: the fixed cost of starting and gathering the tasks (about 0.1 s, which 256 runs of 0.15 s a task would count as
#: a third of a 2-worker flight).
CAMPAIGN_RUNS, CAMPAIGN_TASK = 1024, 128


def bench_plots(out: dict, directory) -> list:
    """The cost curves of a bench: the batch plant's CPU per vehicle-step and vehicle-steps/s against N on one and
    two threads (``bench_batch.png``), and, with the campaign, its runs/s against Dask workers
    (``bench_workers.png``); the paths written."""
    import textwrap
    from pathlib import Path
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    folder = Path(directory)
    folder.mkdir(parents=True, exist_ok=True)
    sweep = out["batch_threads"]
    sizes = [int(n) for n in sweep]
    fig, (cost, rate) = plt.subplots(1, 2, figsize=(10, 3.6))
    for threads in ("1", "2"):
        cost.plot(sizes, [sweep[str(n)][threads]["cpu_us_per_vehicle_step"] for n in sizes], "o-",
                  label=f"{threads} thread{'s' if threads != '1' else ''}")
        rate.plot(sizes, [sweep[str(n)][threads]["vehicle_steps_per_s"] for n in sizes], "o-",
                  label=f"{threads} thread{'s' if threads != '1' else ''}")
    for ax, label in ((cost, "CPU us per vehicle-step"), (rate, "vehicle-steps/s (wall)")):
        ax.set_xscale("log")
        ax.set_xlabel("vehicles in the batch, N")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        ax.legend()
    cost.set_yscale("log")
    fig.suptitle(textwrap.fill(f"batch plant: {out['batch_plant']['workload']}", 110), fontsize=8)
    fig.tight_layout()
    paths = [folder / "bench_batch.png"]
    fig.savefig(paths[0], dpi=90)
    plt.close(fig)
    if "campaign" in out:
        c = out["campaign"]
        workers = sorted(int(k.split("_")[3]) for k in c if k.startswith("runs_per_s_"))
        rates = [c[f"runs_per_s_{w}_worker{'s' if w > 1 else ''}"] for w in workers]
        fig, ax = plt.subplots(figsize=(5, 3.6))
        ax.plot(workers, rates, "o-", label="measured")
        ax.plot(workers, [rates[0] * w for w in workers], ":", color="0.5", label="linear from 1 worker")
        ax.set_xlabel("Dask workers (LocalCluster processes)")
        ax.set_ylabel("runs/s")
        ax.set_xticks(workers)
        ax.grid(True, alpha=0.3)
        ax.legend()
        ax.set_title(textwrap.fill(f"campaign: {c['runs']} runs of {c['workload']}", 60), fontsize=7)
        fig.tight_layout()
        paths.append(folder / "bench_workers.png")
        fig.savefig(paths[-1], dpi=90)
        plt.close(fig)
    return paths


def bench(argv: list[str]) -> int:
    """``./seapup bench``: speed of the model, the batch plant, campaigns, the umbilical, verify and the ROS
    graph."""
    args = bench_parser().parse_args(argv)
    out_text = text_stream(args)
    model = _model(args.config)
    n = args.steps
    cmd = np.radians([20.0, 20.0, -10.0, -10.0])
    # the plant step: compiled kernels (the default) and the NumPy reference, in this run
    out = {"model": {**_plant_step(model, "compiled", cmd, n), "dt": 0.1, "steps": n, "config": model.config_name}}
    out["model_numpy"] = _plant_step(model, "numpy", cmd, max(300, n // 10))
    out["model"]["speedup_vs_numpy"] = out["model_numpy"]["cpu_us"] / out["model"]["cpu_us"]
    per_step = out["model"]["step_us"] * 1e-6
    out["batch_plant"] = _batch_step(model, 1000, cmd, 300)
    # vehicle-steps/s against N, on one thread and on two (the 2-core figure: target 1M at N = 1000), each size
    # timed over at least 300 000 vehicle-steps (about half a second on one thread)
    sweep = {str(n): {str(k): _batch_step(model, n, cmd, max(3, 300_000 // n), threads=k) for k in (1, 2)}
             for n in (1, 10, 100, 1000, 10_000, 100_000)}
    out["batch"] = {n: max(v["1"]["vehicle_steps_per_s"], v["2"]["vehicle_steps_per_s"]) for n, v in sweep.items()}
    out["batch_threads"] = sweep
    # the same step with the quasi-static umbilical solved every step (sec. 3.8)
    cable = load_environment(rho=model.rho).umbilical.build()
    out["model_umbilical"] = _plant_step(model, "compiled", cmd, n, cable)
    per_cable = out["model_umbilical"]["step_us"] * 1e-6
    out["model_umbilical"]["extra_percent"] = 100.0 * (per_cable / per_step - 1.0)
    if not args.no_campaign:
        from seapup_bringup.campaign_runner import campaign_rates
        print(f"campaign: {CAMPAIGN_RUNS} fixed-gain runs in tasks of {CAMPAIGN_TASK} on a LocalCluster of 1, then 2 "
              "worker processes...", file=out_text, flush=True)
        out["campaign"] = campaign_rates(CAMPAIGN_RUNS, per_task=CAMPAIGN_TASK)
        from seapup_bringup.campaign_runner import tuner_campaign_rate
        print("campaign: adaptive-500's self-tuner runs on a LocalCluster of 2 worker processes...", file=out_text,
              flush=True)
        tc = out["tuner_campaign"] = tuner_campaign_rate()
        print(f"tuner_campaign ({tc['workload']}): {tc['samples_per_s']:.0f} closed-loop vehicle-samples/s on "
              f"{tc['workers']} workers ({tc['runs']} runs, {tc['samples']} samples in {tc['wall_s']:.1f} s wall, "
              f"{tc['run_cpu_s']:.1f} s CPU in the runs; target >= 50 000)", file=out_text)
        from seapup_bringup.campaign_runner import mission_campaign_rate
        print("campaign: 8 missions of demo-mission-robustness on a LocalCluster of 2 worker processes...",
              file=out_text, flush=True)
        mc = out["mission_campaign"] = mission_campaign_rate()
        print(f"mission_campaign: {mc['missions_per_min']:.1f} missions per minute on {mc['workers']} workers "
              f"({mc['wall_s']:.1f} s wall, {mc['mission_cpu_s']:.1f} s CPU in the missions; target >= 50)",
              file=out_text)
    t0 = time.perf_counter()
    run_verify(model)
    out["verify"] = {"seconds": time.perf_counter() - t0}
    from seapup_bringup.graph.graph_bench import mfol_step_us
    out["mfol_law"] = mfol_step_us()
    out["estimator"] = _estimator_step_us()
    print("mission: the demo's mission flown in process (the hierarchy's cores, sample for sample)...", file=out_text,
          flush=True)
    m = out["mission_in_process"] = _mission_rate()
    print(f"mission_in_process: {m['rtf']:.0f}x real time, the median of flights 2-{m['flights']} "
          f"({m['simulated_s']:.0f} s simulated in {m['wall_s']:.2f} s wall, {m['cpu_s']:.2f} s CPU; target >= 2000x); "
          f"the process's first flight {m['first_rtf']:.0f}x ({m['first_wall_s']:.2f} s wall, "
          f"{m['first_cpu_s']:.2f} s CPU)", file=out_text)
    from seapup_bringup.graph.graph_bench import law_step_costs
    print("control laws: each flown on square-inspection, its own calls timed (sec. 7.7)...", file=out_text, flush=True)
    out["control_laws"] = law_step_costs()
    if not args.no_report:
        print("report: every run of the thesis targets from a cold cache, then again warm...", file=out_text, flush=True)
        out["report"] = _report_times()
        r = out["report"]
        print(f"report: cold {r['cold']['wall_s']:.1f} s wall ({r['cold']['cpu_s']:.1f} s CPU, {r['jobs']} jobs; target "
              f"<= 600 s), warm {r['warm']['wall_s']:.1f} s wall ({r['warm']['cpu_s']:.1f} s CPU; target <= 30 s)",
              file=out_text)
    if not args.no_graph:
        from seapup_bringup.graph import graph_bench
        print("graph: simulator + open_loop in lockstep (separate processes)...", file=out_text, flush=True)
        out["graph_lockstep_5hz"] = graph_bench.lockstep_rate(0.2, sim_seconds=120.0)
        out["graph_lockstep_20hz"] = graph_bench.lockstep_rate(0.05, sim_seconds=30.0)
        out["dds_round_trip_us"] = graph_bench.dds_round_trip()
        print("graph: simulator + mfol_velocity_controller in lockstep...", file=out_text, flush=True)
        out["graph_mfol_lockstep_5hz"] = graph_bench.mfol_lockstep_rate(0.2, sim_seconds=120.0)
        out["graph_mfol_lockstep_20hz"] = graph_bench.mfol_lockstep_rate(0.05, sim_seconds=30.0)
        for law in ("explicit", "gmv"):
            print(f"graph: simulator + velocity_controller ({law}) in lockstep...", file=out_text, flush=True)
            out[f"graph_{law}_lockstep_5hz"] = graph_bench.law_lockstep_rate(law, 0.2, sim_seconds=60.0)
        for key in ("graph_lockstep_5hz", "graph_lockstep_20hz", "graph_mfol_lockstep_5hz", "graph_mfol_lockstep_20hz",
                    "graph_explicit_lockstep_5hz", "graph_gmv_lockstep_5hz"):
            g = out[key]
            print(f"{key}: {g['rtf']:.1f}x real time ({g['steps_per_s']:.0f} steps/s, "
                  f"{g['us_per_step']:.0f} us per step; CPU per step: simulator {g['simulator_cpu_us_per_step']:.0f} "
                  f"us, controller {g['controller_cpu_us_per_step']:.0f} us)", file=out_text)
        print("graph: each executor of run_node (single, events) on the same graphs, in alternating blocks...",
              file=out_text, flush=True)
        out["graph_executor_ab"] = graph_bench.executor_ab()
        for line in graph_bench.executor_ab_lines(out["graph_executor_ab"]):
            print(line, file=out_text)
        print("graph: the demo's hierarchy with its recorder, unpaced in lockstep...", file=out_text, flush=True)
        h = out["graph_hierarchy_5hz"] = graph_bench.hierarchy_rate()
        print(f"graph_hierarchy_5hz: {h['rtf']:.1f}x real time (target >= 60x; CPU per sample over all "
              f"{len(h['cpu_us_per_step'])} processes {h['total_cpu_us_per_step']:.0f} us)", file=out_text)
        print("graph: the live view's cost (simulator + open_loop at 5 Hz without and with it)...", file=out_text,
              flush=True)
        cost = out["graph_view_cost_5hz"] = graph_bench.view_cost()
        print(f"graph_view_cost_5hz: {cost['with']['rtf']:.1f}x real time with the view (a viewer subscribed to "
              f"everything; view CPU {cost['with']['view_cpu_us_per_step']:.0f} us per step) against "
              f"{cost['without']['rtf']:.1f}x without: ratio {cost['ratio']:.2f} (target >= 0.8)", file=out_text)
        rt = out["dds_round_trip_us"]
        # a lockstep sample holds at least one round trip (t_k out, its command back): the graph's ceiling
        rt["lockstep_ceiling_5hz"] = 0.2 / (rt["median_us"] * 1e-6)
        print(f"DDS round trip to another process: median {rt['median_us']:.0f} us, p99 {rt['p99_us']:.0f} us "
              f"(so no lockstep graph of two processes exceeds {rt['lockstep_ceiling_5hz']:.0f}x real time at 5 Hz "
              "here)", file=out_text)
        if args.recording_minutes > 0:
            print(f"recorder memory: {args.recording_minutes:g} min recording everything a free-running "
                  "simulator publishes...", file=out_text, flush=True)
            r = out["recording"] = graph_bench.recording_memory(args.recording_minutes, progress=progress)
            print(f"recording: {r['messages']} messages ({r['messages_per_s']:.0f}/s, {r['mb_per_s']:.2f} MB/s, "
                  f"{r['sim_s']:.0f} s simulated) in {r['wall_s']:.0f} s; recorder RSS {r['rss_mb_start']:.1f} MB "
                  f"at start, {r['rss_mb_after_1min']:.1f} after 1 min, {r['rss_mb_end']:.1f} at the end "
                  f"(max {r['rss_mb_max']:.1f}); slope {r['rss_slope_mb_per_min']:+.3f} MB/min", file=out_text)
    m, ref = out["model"], out["model_numpy"]
    # the workloads, written beside their figures
    pitches = ", ".join(f"{v:g}" for v in np.degrees(cmd).round(1))
    m["workload"] = (f"{model.config_name}, the nonlinear plant in open loop (no law, no sensors), inputs held at "
                     f"({pitches}) deg, still water, dt 0.1 s, one vehicle stepped a physics step a call")
    out["batch_plant"]["workload"] = (f"N x {model.config_name} in open loop (no law, no sensors), inputs held at "
                                      f"({pitches}) deg, a 0.22 m/s current, dt 0.1 s, all N stepped a physics step "
                                      "a call")
    print(f"model ({m['workload']}): {m['step_us']:.1f} us per RK4 step ({m['cpu_us']:.1f} us CPU) = "
          f"{m['rtf']:.0f}x real time, compiled; the NumPy reference {ref['step_us']:.0f} us ({ref['cpu_us']:.0f} us "
          f"CPU) = {ref['rtf']:.0f}x: {m['speedup_vs_numpy']:.0f} times faster in CPU time", file=out_text)
    b = out["batch_plant"]
    print(f"batch plant ({b['workload']}): N = {b['vehicles']}, {b['vehicle_steps_per_s']:.0f} vehicle-steps/s wall "
          f"({b['cpu_us_per_vehicle_step']:.1f} us CPU per vehicle-step, one core)", file=out_text)
    for n, by_threads in out["batch_threads"].items():
        one, two = by_threads["1"], by_threads["2"]
        print(f"batch plant, N = {n:>5}: {one['vehicle_steps_per_s']:9.0f} vehicle-steps/s on 1 thread, "
              f"{two['vehicle_steps_per_s']:9.0f} on 2 ({one['cpu_us_per_vehicle_step']:.2f} / "
              f"{two['cpu_us_per_vehicle_step']:.2f} us CPU per vehicle-step)", file=out_text)
    if "campaign" in out:
        c = out["campaign"]
        print(f"campaign ({c['runs']} runs of {c['workload']}; {c['samples']} samples): "
              f"{c['runs_per_s_1_worker']:.2f} runs/s "
              f"on 1 worker, {c['runs_per_s_2_workers']:.2f} on 2 ({c['scaling']:.2f}x; target >= 1.8x; "
              f"{c['overhead_s_per_task']:.3f} s a task beyond its runs' CPU on 1 worker); "
              f"{c['closed_loop_samples_per_s']:.0f} closed-loop vehicle-samples/s on 2 workers; all {c['runs']} as one "
              f"batch in one process: {c['batch_samples_per_cpu_s']:.0f} per CPU second (set-up, flight and metrics; "
              "target 100 000 on 2 cores)", file=out_text)
    print(f"model + umbilical: {per_cable * 1e6:.1f} us per step = {0.1 / per_cable:.0f}x real time "
          f"(+{out['model_umbilical']['extra_percent']:.0f} %; the thesis reports +30 %)", file=out_text)
    print(f"verify: {out['verify']['seconds']:.2f} s", file=out_text)
    law = out["mfol_law"]
    print(f"MFOL law (scheduled, eq. 5.6): {law['law_us']:.1f} us per sample; with building the measurement and "
          f"reference {law['with_measurement_and_reference_us']:.1f} us", file=out_text)
    for method, value in out["estimator"].items():
        print(f"estimator {method} (4 outputs, 4 inputs, orders {value['orders']}, offset; ch. 7): "
              f"{value['step_us']:.1f} us per step (target <= 100 us)", file=out_text)
    if args.plots:
        for path in bench_plots(out, args.plots):
            print(f"wrote {path}", file=out_text)
    for name, value in out["control_laws"].items():
        thesis = value.get("thesis_ratio_to_fixed")
        print(f"control law {name}: {value['cpu_us']:.0f} us CPU ({value['wall_us']:.0f} us wall) per step, "
              f"{value['cpu_ratio_to_fixed']:.1f}x the fixed-gain law"
              + (f" (thesis, PDP-11/73: {thesis:.1f}x)" if thesis is not None else ""), file=out_text)
    emit_json(args, out)
    return 0


def _report_times() -> dict:
    """``./seapup report`` from a cold cache and again from the warm one, each as its own process (as a user
    runs it): wall and CPU seconds (it and its run workers), with as many jobs as CPUs."""
    import os
    import subprocess
    import tempfile
    from pathlib import Path

    from seapup_common.processes import spawn
    jobs = os.cpu_count() or 1
    out = {"jobs": jobs}
    with tempfile.TemporaryDirectory() as tmp:
        for label in ("cold", "warm"):
            before, wall = os.times(), time.perf_counter()
            child = spawn([sys.executable, "-m", "seapup_bringup.cli", "report", "--out", str(Path(tmp) / label),
                           "--cache", str(Path(tmp) / "cache"), "--jobs", str(jobs)],
                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            code = child.wait()
            after = os.times()
            cpu = sum(getattr(after, k) - getattr(before, k) for k in ("user", "system", "children_user", "children_system"))
            out[label] = {"wall_s": time.perf_counter() - wall, "cpu_s": cpu, "exit": code}
    return out

def _mission_rate(flights: int = 4) -> dict:
    """The shipped mission (``seapup_bringup/config/mission.yaml``) flown in process ``flights`` times
    (:func:`seapup_runs.mission_flight.run_mission`): simulated seconds per wall second, CPU beside wall, of the
    first flight (it pays the process's first use of the cores: imports, compiled-kernel dispatch) and the median
    of the others (what each further mission of a campaign's worker costs)."""
    from seapup_bringup.graph.hierarchy_config import hierarchy_config
    from seapup_bringup.graph.mission_graph import mission_path
    from seapup_runs.mission import load_mission
    from seapup_runs.mission_flight import run_mission
    spec = load_mission(mission_path())
    hierarchy = hierarchy_config(spec.graph)
    times = []
    for _ in range(max(2, flights)):
        wall, cpu = time.perf_counter(), time.process_time()
        result = run_mission(spec, hierarchy)
        times.append((time.perf_counter() - wall, time.process_time() - cpu))
    (first_wall, first_cpu), rest = times[0], sorted(times[1:])
    wall, cpu = rest[len(rest) // 2]
    return {"simulated_s": result["held"], "wall_s": wall, "cpu_s": cpu, "rtf": result["held"] / wall,
            "first_wall_s": first_wall, "first_cpu_s": first_cpu, "first_rtf": result["held"] / first_wall,
            "flights": len(times), "samples": len(result["logs"]["command_t"])}


def _estimator_step_us(samples: int = 2000) -> dict:
    """us per recursive-estimator step for the 4-output, 4-input model of ch. 7 (orders 1, 1, and nc 1 for
    els / rpem), on a PRBS-driven known first-order plant."""
    from seapup_ident.armax import ArmaxOrders
    from seapup_ident.prbs import prbs
    from seapup_ident.recursive import Forgetting, RecursiveArmax
    rng = np.random.default_rng(0)
    u = prbs(samples, clock=10, amplitude=0.17, n_inputs=4)
    phi, delta = np.diag([0.88, 0.93, 0.8, 0.82]), 0.05 * rng.normal(size=(4, 4)) + 0.2 * np.eye(4)
    y = np.zeros((samples, 4))
    for t in range(1, samples):
        y[t] = phi @ y[t - 1] + delta @ u[t - 1] + 0.003 * rng.normal(size=4)
    out = {}
    for method, nc in (("ls", 0), ("els", 1), ("rpem", 1)):
        estimator = RecursiveArmax(ArmaxOrders(4, 4, 1, 1, nc), method, forgetting=Forgetting(0.99), p0=100.0)
        t0 = time.perf_counter()
        for t in range(samples):
            estimator.step(y[t], u[t])
        out[method] = {"step_us": (time.perf_counter() - t0) / samples * 1e6, "orders": [1, 1, nc]}
    return out
