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
import sys
from pathlib import Path

import numpy as np

from seapup_bringup.graph.self_test_graph import SelfTestFailed, fly_self_test_graph, self_test_from_bag
from seapup_bringup.output import add_json_argument, emit_json, progress, text_stream
from seapup_runs.closed_loop_analysis import MODES, analyse, plot_loci
from seapup_control.self_test import FITS
from seapup_runs.self_test_flight import fly_self_test
from seapup_runs.targets import thesis_value
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import ConfigError, available_configs, load_vehicle_config

__all__ = ["selftest", "closed_loop_command", "SelfTestFailed"]


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
    parser.add_argument("--fit", choices=FITS,
                        help="each step's lag fitted to the deviations from the operating point (eq. 5.5) or to "
                             "the raw outputs, as the thesis's Table 5.2 reads at 0.7 m/s (default: the self-test "
                             "settings' fit, deviation)")


def _fly(args, text):
    """The self-test in this process (pure cores in lockstep with the simulation)."""
    speeds = _speeds(args)
    print(f"self-test: {args.config}, {args.rate:g} Hz, operating points {speeds} m/s, {args.mode} quiescence, "
          "in process", file=text, flush=True)
    run = fly_self_test(args.config, {"sample_period": 1.0 / args.rate, "operating_points": speeds,
                                      "mode": args.mode, **({"fit": args.fit} if args.fit else {})},
                        progress=lambda f: progress("self-test", f))
    if run.test.phase.value != "done":
        raise SelfTestFailed(f"the self-test {run.test.phase.value}: {run.test.reason}")
    return run


def _speeds(args) -> list[float]:
    try:
        return [float(s) for s in args.speeds.split(",")]
    except ValueError:
        raise SelfTestFailed(f"--speeds must be numbers separated by commas, got {args.speeds!r}")


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
        refitted = self_test_from_bag(args.from_bag, args.fit)
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
        flown = fly_self_test_graph(args.config, args.rate, _speeds(args), out, bag_dir, text)
        bag = flown["bag"]
        refitted = self_test_from_bag(bag)  # the bag holds everything: the table and the space come from it
        points, duration, space = refitted["points"], flown["result"].duration, refitted["space"]
        live = np.reshape(flown["result"].b1_inverse, (-1, 4, 4))
        refitted_b1 = np.reshape([p.model.B1inv for p in points], (-1, 4, 4))
        if live.shape != refitted_b1.shape or not np.allclose(live, refitted_b1, rtol=1e-12, atol=1e-15):
            raise SelfTestFailed(f"the bag's refit ({len(refitted_b1)} operating points) differs from the live "
                                 f"result ({len(live)}): a sample was lost; see {bag}")
        print(f"bag {bag}; controller file {flown['result'].controller_file}", file=text)
        if args.fit:   # the node flew and designed with the settings' fit; the table is the bag's refit
            points = self_test_from_bag(bag, args.fit)["points"]
            print(f"the table below: the bag refitted with --fit {args.fit} (the controller file keeps the "
                  "node's own fit)", file=text)
    rows = _print_points(points, text, args)
    space_0, space_07 = thesis_value("ch5.self_test.space_0"), thesis_value("ch5.self_test.space_0_7")
    print(f"\ntime {duration:.1f} s, space {space[0]:.1f} x {space[1]:.1f} x {space[2]:.1f} m (X x Y x Z); "
          f"thesis: {thesis_value('ch5.self_test.time_0'):g} s and {' x '.join(f'{v:g}' for v in space_0)} m at 0 m/s, "
          f"+{thesis_value('ch5.self_test.time_0_7'):g} s and {' x '.join(f'{v:g}' for v in space_07)} m with 0.7 m/s "
          "(sec. 5.3.3)", file=text)
    emit_json(args, {"config": args.config, "rate_hz": args.rate, "mode": args.mode, "fit": args.fit or "settings",
                     "operating_points": rows,
                     "duration_s": duration, "space_m": space, "bag": str(bag) if bag else None})
    return 0


def _print_points(points, text, args) -> list[dict]:
    from seapup_sim.vehicle import VehicleModel
    from seapup_sim.vehicle_config import load_vehicle_config
    inputs = VehicleModel(load_vehicle_config(args.config)).inputs
    virtual = inputs.kind == "virtual"   # per unit of a virtual input (its full scale), not per degree of pitch
    rows = []
    for point in points:
        b0, b1 = (point.model.B0inv, point.model.B1inv) if virtual else point.model.in_thesis_units()
        rows.append({"surge": point.surge, "B0inv": b0, "B1inv": b1, "u0": point.model.u0,
                     **({} if virtual else {"u0_deg": np.degrees(point.model.u0)}),
                     "Kp": point.gains.K_err, "Ki": point.gains.K_int, "cycle": point.cycle,
                     "inputs": list(inputs.names)})
        thesis = None if virtual else _thesis_point(point.surge, args.mode, args.rate, args.config)
        units = (f"r [rad/s] per unit of the virtual inputs {', '.join(inputs.names)}" if virtual
                 else "r [deg/s] per degree of pitch")
        print(f"\noperating point {point.surge:g} m/s (outputs u, v, w [m/s], {units};"
              + (f" thesis {thesis['where']} in brackets)" if thesis else ")"), file=text)
        for name, key, ours in (("B0^-1", "B0inv", b0), ("B1^-1", "B1inv", b1)):
            print(f"  {name}", file=text)
            for i, row in enumerate(ours):
                theirs = thesis[key][i] if thesis else [None] * 4
                print("   " + " ".join(f"{v:10.5f}" + (f" ({t:9.5f})" if t is not None else "")
                                       for v, t in zip(row, theirs)), file=text)
        u0 = point.model.u0 if virtual else np.degrees(point.model.u0)
        print(("  u0       " if virtual else "  u0 [deg] ") + " ".join(f"{v:7.3f}" for v in u0)
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
    result = {"config": args.config, "rate_hz": args.rate, "scheduled": args.schedule, "fit": run.test.config.fit,
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
