"""``./seapup selftest`` and ``./seapup closed-loop``: the Owens-Chotai autopilot on the simulated Seapup.

selftest     fly the self-test (sec. 4.5.2, 5.3) through the /seapup/self_test
             action with the simulator in lockstep, recording the run to a bag
             (or in this process, or refit a recorded run from its bag), and
             print B0^-1, B1^-1 and the designed gains per operating point
             beside eq. 5.3 / 5.7.
closed-loop  the closed-loop eigenvalues of the linearised vehicle under the
             self-tested controller over surge speed (sec. 5.4.1, figs 5.4-5.9):
             fixed or scheduled gains, 5 or 20 Hz.
"""
from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

import numpy as np

from seapup_common.topics import (APPLIED, CLOCK, COMMAND, DEPTH, IMU, SELF_TEST_ACTION, SELF_TEST_SAMPLES,
                                  TRUTH_ODOMETRY, VELOCITY, typed)
from seapup_bringup.output import add_json_argument, emit_json, progress, text_stream
from seapup_runs.closed_loop_analysis import MODES, analyse, plot_loci
from seapup_runs.self_test_flight import fly_self_test
from seapup_runs.targets import thesis_value
from seapup_control.self_test import SelfTestConfig
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import ConfigError, available_configs, load_vehicle_config

__all__ = ["selftest", "closed_loop_command", "SelfTestFailed"]


class SelfTestFailed(RuntimeError):
    """A self-test or closed-loop analysis that cannot go on: the reason says why (and where the logs are)."""

def _thesis_point(surge: float, mode: str, rate: float, config: str) -> dict | None:
    """The thesis's self-test result at an operating point (Tables 5.1, 5.2: the column of ``mode``'s
    quiescence, 5 Hz, the baseline vehicle) and its u0 (eq. 5.2; sec. 3.7's trim at 0.7 m/s), from the
    thesis targets file; None where the thesis reports none."""
    table = {0.0: "ch5.table5_1", 0.7: "ch5.table5_2"}.get(round(surge, 3))
    if table is None or rate != 5.0 or config != "baseline":
        return None
    u0 = (thesis_value("ch5.eq5_2.hover") if round(surge, 3) == 0.0 else
          [thesis_value("ch3.trim_0_7.mains")] * 2 + [thesis_value("ch3.trim_0_7.vectored")] * 2)
    return {"B0inv": thesis_value(f"{table}.{mode}.B0inv"), "B1inv": thesis_value(f"{table}.{mode}.B1inv"),
            "u0_deg": list(u0), "where": f"Table 5.{1 if table.endswith('1') else 2}, {mode} quiescence"}


def _model(name: str) -> VehicleModel:
    try:
        return VehicleModel(load_vehicle_config(name))
    except ConfigError as exc:
        raise SelfTestFailed(f"{exc}")


def _self_test_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config", default="baseline", help=f"vehicle configuration ({', '.join(available_configs())})")
    parser.add_argument("--rate", type=float, default=5.0, choices=(5.0, 20.0), help="sample rate [Hz]")
    parser.add_argument("--speeds", default="0,0.7", help="operating points [m/s], comma separated, from 0")
    parser.add_argument("--mode", choices=("realistic", "artificial"), default="realistic",
                        help="quiescence waited for, or the plant reset before each step (sec. 5.3.2)")


def _fly(args, text):
    """The self-test in this process (pure cores in lockstep with the simulation)."""
    speeds = _speeds(args)
    print(f"self-test: {args.config}, {args.rate:g} Hz, operating points {speeds} m/s, {args.mode} quiescence, "
          "in process", file=text, flush=True)
    run = fly_self_test(args.config, {"sample_period": 1.0 / args.rate, "operating_points": speeds,
                                      "mode": args.mode},
                        progress=lambda f: progress("self-test", f))
    if run.test.phase.value != "done":
        raise SelfTestFailed(f"the self-test {run.test.phase.value}: {run.test.reason}")
    return run


#: What a self-test run records (typed: subscribed before the publishers exist).
SELF_TEST_TOPICS = (CLOCK, COMMAND, APPLIED, VELOCITY, IMU, DEPTH, TRUTH_ODOMETRY, SELF_TEST_SAMPLES)


def _fly_graph(args, out: Path, bag: Path, text) -> dict:
    """The self-test through the ROS graph in lockstep (``seapup_bringup/launch/self_test.launch.yaml``: simulator
    and self_test action server) in the SIL harness, recorded to ``bag``; this process is the action client.

    Raises
    ------
    SelfTestFailed
        If the goal is refused or the self-test does not succeed; the harness's SilError if the graph
        does not come up.
    """
    from seapup_bringup.graph.sil import SilGraph
    from seapup_runs.spec import PHYSICS_STEP

    speeds = _speeds(args)
    period = 1.0 / args.rate
    # the first sample, command and self-test sample wait for every reader of them -- the recorder and the
    # probe included (the lockstep roster the harness fills): nothing of the run is lost
    arguments = {"vehicle": args.config, "control_period": period, "physics_step": min(PHYSICS_STEP, period),
                 "start_depth": 50.0, "result_dir": str(out.resolve())}
    with SilGraph("seapup_bringup self_test.launch.yaml", arguments, out_dir=out, record=typed(*SELF_TEST_TOPICS),
                  ready_status=None) as sil:
        print(f"self-test: {args.config}, {args.rate:g} Hz, operating points {speeds} m/s, through the ROS graph "
              f"(domain {sil.env['ROS_DOMAIN_ID']}); output in {out}", file=text, flush=True)
        result = sil.action(SELF_TEST_ACTION, "seapup_msgs/action/SelfTest",
                            {"sample_period": period, "operating_points": speeds}, timeout=3600.0, ready_timeout=60.0,
                            feedback=lambda f: progress(f"{f.phase} c{f.cycle} t{f.thruster}", f.progress))
        bag_dir = sil.bag
    if not result.success:
        raise SelfTestFailed(f"the self-test did not succeed: {result.message}; see {out}")
    if bag_dir != bag:
        shutil.move(str(bag_dir), str(bag))
    return {"result": result, "bag": bag}


def _speeds(args) -> list[float]:
    try:
        return [float(s) for s in args.speeds.split(",")]
    except ValueError:
        raise SelfTestFailed(f"--speeds must be numbers separated by commas, got {args.speeds!r}")


def _from_bag(bag_dir: Path) -> dict:
    """Refit a recorded run from its /seapup/self_test/samples and measure its space from the truth."""
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message
    from seapup_msgs.msg import SelfTestSample

    from seapup_common.bag import read_bag
    from seapup_control.mfol import DesignError
    from seapup_control.self_test import refit, tests_from_samples
    from seapup_control.step_identification import IdentificationError
    records, positions, stamps = [], [], []
    for m in read_bag(bag_dir, [SELF_TEST_SAMPLES, TRUTH_ODOMETRY]):
        if m.topic == TRUTH_ODOMETRY:
            odometry = deserialize_message(m.cdr, Odometry)
            p, stamp = odometry.pose.pose.position, odometry.header.stamp
            positions.append((stamp.sec + stamp.nanosec * 1e-9, p.x, p.y, p.z))
            continue
        s = deserialize_message(m.cdr, SelfTestSample)
        t = s.header.stamp.sec + s.header.stamp.nanosec * 1e-9
        stamps.append(t)
        records.append({"t": t, "test_index": s.test_index, "cycle": s.cycle, "surge": s.surge,
                        "thruster": s.thruster, "step": s.step, "quiescent_input": list(s.quiescent_input),
                        "equilibrium": list(s.equilibrium), "velocity": list(s.velocity),
                        "sample_period": s.sample_period, "phase": s.phase})
    if not records:
        raise SelfTestFailed(f"{bag_dir} has no {SELF_TEST_SAMPLES}: not a self-test bag")
    last = max(records, key=lambda r: r["t"])
    if last["phase"] not in ("done", "failed", "cancelled"):
        raise SelfTestFailed(f"{bag_dir}: its self-test record ends at t = {last['t']:.3f} s in phase "
                             f"{last['phase']!r}: the recording stopped before the self-test ended")
    try:
        config = SelfTestConfig.load({"sample_period": records[0]["sample_period"]})
        points = refit(tests_from_samples(records, config.sample_period), config.sample_period, config.poles,
                       config.max_condition)
    except (ConfigError, IdentificationError, DesignError) as exc:
        raise SelfTestFailed(f"{bag_dir}: {exc}") from None
    # the box of water of the run itself: truth from its first to its last sample
    position = np.array([p[1:] for p in positions if min(stamps) - 1e-9 <= p[0] <= max(stamps) + 1e-9]
                        or [(0.0, 0.0, 0.0)])
    return {"points": points, "duration": max(stamps) - min(stamps),
            "space": position.max(axis=0) - position.min(axis=0)}


def selftest_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup selftest`` (its usage line in ``./seapup help`` is generated from it)."""
    parser = argparse.ArgumentParser(prog="./seapup selftest", description=__doc__.splitlines()[0])
    _self_test_arguments(parser)
    parser.add_argument("--in-process", action="store_true",
                        help="fly it in this process (pure cores, no ROS; needed for --mode artificial)")
    parser.add_argument("--from-bag", type=Path, help="refit a recorded self-test run instead of flying one")
    parser.add_argument("--out", type=Path, help="output directory (default runs/selftest_<UTC time>)")
    parser.add_argument("--bag", type=Path, help="bag directory to create (default OUT/bag)")
    add_json_argument(parser)
    return parser


def _selftest(argv: list[str]) -> int:
    """``./seapup selftest``: the self-test through the ROS graph (or in process, or refitted from a bag)."""
    parser = selftest_parser()
    args = parser.parse_args(argv)
    text = text_stream(args)
    bag = None
    if args.from_bag:
        refitted = _from_bag(args.from_bag)
        points, duration, space, bag = refitted["points"], refitted["duration"], refitted["space"], args.from_bag
        print(f"refitted from {args.from_bag}", file=text)
    elif args.in_process or args.mode == "artificial":
        run = _fly(args, text)
        points, duration, space = run.test.points, run.test.duration, run.space
    else:
        import time
        out = args.out or Path("runs") / time.strftime("selftest_%Y%m%d_%H%M%S", time.gmtime())
        out.mkdir(parents=True, exist_ok=True)
        bag_dir = args.bag or out / "bag"
        if bag_dir.exists():
            parser.error(f"{bag_dir} exists: a bag is never overwritten")
        flown = _fly_graph(args, out, bag_dir, text)
        bag = flown["bag"]
        refitted = _from_bag(bag)  # the bag holds everything: the table and the space come from it
        points, duration, space = refitted["points"], flown["result"].duration, refitted["space"]
        live = np.reshape(flown["result"].b1_inverse, (-1, 4, 4))
        refitted_b1 = np.reshape([p.model.B1inv for p in points], (-1, 4, 4))
        if live.shape != refitted_b1.shape or not np.allclose(live, refitted_b1, rtol=1e-12, atol=1e-15):
            raise SelfTestFailed(f"the bag's refit ({len(refitted_b1)} operating points) differs from the live "
                                 f"result ({len(live)}): a sample was lost; see {bag}")
        print(f"bag {bag}; controller file {flown['result'].controller_file}", file=text)
    rows = _print_points(points, text, args)
    space_0, space_07 = thesis_value("ch5.self_test.space_0"), thesis_value("ch5.self_test.space_0_7")
    print(f"\ntime {duration:.1f} s, space {space[0]:.1f} x {space[1]:.1f} x {space[2]:.1f} m (X x Y x Z); "
          f"thesis: {thesis_value('ch5.self_test.time_0'):g} s and {' x '.join(f'{v:g}' for v in space_0)} m at 0 m/s, "
          f"+{thesis_value('ch5.self_test.time_0_7'):g} s and {' x '.join(f'{v:g}' for v in space_07)} m with 0.7 m/s "
          "(sec. 5.3.3)", file=text)
    emit_json(args, {"config": args.config, "rate_hz": args.rate, "mode": args.mode, "operating_points": rows,
                     "duration_s": duration, "space_m": space, "bag": str(bag) if bag else None})
    return 0


def _print_points(points, text, args) -> list[dict]:
    rows = []
    for point in points:
        b0, b1 = point.model.in_thesis_units()
        rows.append({"surge": point.surge, "B0inv": b0, "B1inv": b1, "u0_deg": np.degrees(point.model.u0),
                     "Kp": point.gains.K_err, "Ki": point.gains.K_int, "cycle": point.cycle})
        thesis = _thesis_point(point.surge, args.mode, args.rate, args.config)
        print(f"\noperating point {point.surge:g} m/s (outputs u, v, w [m/s], r [deg/s] per degree of pitch;"
              + (f" thesis {thesis['where']} in brackets)" if thesis else ")"), file=text)
        for name, key, ours in (("B0^-1", "B0inv", b0), ("B1^-1", "B1inv", b1)):
            print(f"  {name}", file=text)
            for i, row in enumerate(ours):
                theirs = thesis[key][i] if thesis else [None] * 4
                print("   " + " ".join(f"{v:10.5f}" + (f" ({t:9.5f})" if t is not None else "")
                                       for v, t in zip(row, theirs)), file=text)
        u0 = np.degrees(point.model.u0)
        print("  u0 [deg] " + " ".join(f"{v:7.3f}" for v in u0)
              + (f"   (thesis {' '.join(f'{v:7.3f}' for v in thesis['u0_deg'])})" if thesis else ""), file=text)
    return rows


def closed_loop_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup closed-loop`` (its usage line in ``./seapup help`` is generated from it)."""
    parser = argparse.ArgumentParser(prog="./seapup closed-loop", description=__doc__.splitlines()[0])
    _self_test_arguments(parser)
    parser.add_argument("--schedule", action="store_true", help="gains scheduled on surge speed (else fixed at 0)")
    parser.add_argument("--plots", type=Path, help="write s-plane loci per mode (figs 5.4-5.9) into this directory")
    add_json_argument(parser)
    return parser


def _closed_loop_command(argv: list[str]) -> int:
    """``./seapup closed-loop``: closed-loop eigenvalues over surge speed (sec. 5.4.1)."""
    parser = closed_loop_parser()
    args = parser.parse_args(argv)
    text = text_stream(args)
    run = _fly(args, text)
    schedule = run.test.schedule()
    speeds = [round(0.1 * k, 1) for k in range(11)]
    rows = analyse(_model(args.config), schedule, speeds, args.schedule)
    designed = run.test.config.poles
    print(f"\nclosed loop, {args.rate:g} Hz, {'scheduled' if args.schedule else 'fixed'} gains; designed s-plane "
          "poles (u, v, w, r): " + ", ".join(f"{s.real:.2f}" for s in designed.continuous()[0]), file=text)
    print(f"{'surge':>6} {'stable':>7} {'maxRe s':>8}  " + "  ".join(f"{m:>17}" for m in MODES if m != "position"),
          file=text)
    for row in rows:
        if "error" in row:
            print(f"{row['surge']:6.1f}  no trim: {row['error']}", file=text)
            continue
        cells = []
        for mode in MODES:
            if mode == "position":
                continue
            poles = sorted(row["modes"].get(mode, []), key=lambda p: -p[0])
            cells.append(f"{poles[0][0]:8.2f}{poles[0][1]:+8.2f}j" if poles else f"{'-':>17}")
        print(f"{row['surge']:6.1f} {str(row['stable']):>7} {row['max_re_s']:8.3f}  " + "  ".join(cells),
              file=text)
    print("(per mode: its least damped pole, s = ln(z) / T [1/s]; stable: all but the four position "
          "integrations, s = 0, decay)", file=text)
    result = {"config": args.config, "rate_hz": args.rate, "scheduled": args.schedule,
              "designed_s": [[float(s.real), float(s.imag)] for s in designed.continuous()[0]], "speeds": rows}
    if args.plots:
        for path in plot_loci(result, args.plots):
            print(f"wrote {path}", file=text)
    emit_json(args, result)
    return 0


def _one_line(verb: str, body, argv: list[str]) -> int:
    """Run a verb; what stops it is one line on standard error and exit 1, never a traceback."""
    from seapup_bringup.graph.sil import SilError
    try:
        return body(argv)
    except (SelfTestFailed, SilError, ConfigError, OSError) as exc:
        print(f"seapup {verb}: error: {exc}", file=sys.stderr)
        return 1


def selftest(argv: list[str]) -> int:
    """``./seapup selftest``: the self-test through the ROS graph (or in process, or refitted from a bag)."""
    return _one_line("selftest", _selftest, argv)


def closed_loop_command(argv: list[str]) -> int:
    """``./seapup closed-loop``: closed-loop eigenvalues over surge speed under the self-tested controller."""
    return _one_line("closed-loop", _closed_loop_command, argv)
