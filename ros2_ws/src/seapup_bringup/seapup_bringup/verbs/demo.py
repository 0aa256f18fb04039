"""``./seapup demo``: the mission -- the thesis's supervisory hierarchy (sec. 4.2, fig. 4.3) flying the Seapup.

Starts the whole graph (``seapup_bringup/launch/hierarchy.launch.yaml`` in lockstep,
faster than real time, every node its own process, plus the recorder) with
:class:`seapup_bringup.graph.sil.SilGraph`, then flies, through ROS only:

1. the self-test (sec. 4.5.2) through its action; both velocity controllers
   are configured from its result and the fixed-gain one is activated;
2. hover, swapping the velocity controller (fixed gain -> gain scheduled)
   half way through;
3. a goto of ~10 m with a 90 deg heading change;
4. the inspection manoeuvre (sec. 5.4.2: body velocities 0.2, 0.1, 0.1 m/s,
   "a diagonal creeping motion"), as a goto along that diagonal at its speed;
5. seabed following at a set height up the slope;
6. station keeping in the thesis's 0.26 m/s Gauss-Markov current (sec. 3.9);
7. a fouled thruster (sec. 7.4.4): on an inspection creep the main-port thruster's
   efficiency is halved under the self-tested gains, then the controller manager
   switches to a self-tuner of ch. 7 (GMV), which re-tunes while the creep goes on;
   the leg reports the velocity-tracking RMS (truth against the reference) before
   the fouling, fouled under the fixed gains, and under the self-tuner after it
   tuned in.

Everything is recorded to an MCAP bag (``<out>/bag``); the demo prints a table
per leg (duration, tracking errors, position-hold RMS and max from the truth,
thruster saturation, the swap's command step), writes PNG plots next to the
bag, the numbers as JSON (``summary.json``, ``--json``) and ``index.html``: one page with the legs
(units, pass criteria and verdicts), the plots, the seed and the configuration flown.
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

from seapup_bringup.graph.mission_graph import fly_mission, mission_config, mission_path
from seapup_runs.mission_pages import report_mission
from seapup_bringup.output import add_json_argument, emit_json, stopped_by_signal, text_stream

__all__ = ["main", "demo_parser"]


def demo_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup demo`` (its usage line in ``./seapup help`` is generated from it)."""
    from seapup_live_view.attach import add_view_arguments
    parser = argparse.ArgumentParser(prog="./seapup demo", description=__doc__.splitlines()[0])
    parser.add_argument("--out", help="output directory: the bag (OUT/bag), plots, summary.json and node logs "
                                      "(default bags/demo_<UTC time> under the checkout)")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    parser.add_argument("--mission", type=Path, help="a mission file to fly instead of the shipped one "
                                                     "(seapup_bringup/config/mission.yaml; keys: docs/missions.md)")
    parser.add_argument("--vehicle", default="baseline",
                        help="fly the mission shipped for this vehicle (baseline: the Seapup's; bluerov2_heavy: "
                             "seapup_bringup/config/mission_bluerov2_heavy.yaml; docs/vehicles.md)")
    add_view_arguments(parser, "fly at this many times real time (the lockstep graph paced; default: as fast as "
                               "it answers, or 1 with --view); the summary is the same at any rate")
    add_json_argument(parser)
    return parser


def main(argv=None) -> int:
    from seapup_live_view.attach import check_port, view_node, view_url
    parser = demo_parser()
    args = parser.parse_args(argv)
    rate = args.rate if args.rate is not None else (1.0 if args.view else 0.0)
    if not (rate >= 0 and rate < 1e4):
        parser.error(f"--rate must be >= 0 (0: unpaced) and < 10000, got {args.rate}")
    if args.view:
        try:
            check_port(args.view_port)
        except ValueError as exc:
            parser.error(str(exc))
    text = text_stream(args)
    root = Path(os.environ.get("SEAPUP_ROOT", "."))
    out = Path(args.out) if args.out else root / "bags" / time.strftime("demo_%Y%m%d_%H%M%S", time.gmtime())
    from seapup_runs.mission import MissionError
    if args.mission and args.vehicle != "baseline":
        parser.error("--mission and --vehicle: a mission file names its own vehicle (graph.vehicle)")
    try:
        path = args.mission or mission_path(args.vehicle)
        config = mission_config(path)
    except MissionError as exc:
        parser.error(str(exc))
    config["source"] = str(args.mission) if args.mission else f"seapup_bringup/config/{path.name}"
    if rate:
        config["graph"]["lockstep_pace"] = rate
    extra = [view_node(args.view_port)] if args.view else []
    if args.view:
        print(f"seapup demo: live view at {view_url(args.view_port)}", file=text)
    wall = time.monotonic()
    try:
        result = fly_mission(out, config, text, extra)
    except Exception as exc:  # a failed leg or graph: say which, point at the logs
        if stopped_by_signal(exc):
            raise
        print(f"seapup demo: failed: {exc}; node logs in {out}", file=text)
        return 1
    result["wall_s"] = time.monotonic() - wall
    stopped = result.pop("stopped")
    result["interrupted"] = stopped is not None
    summary, code = report_mission(result, config, out, text, "seapup demo", plots=not args.no_plots)
    emit_json(args, summary)
    if stopped is not None:
        raise stopped  # ./seapup: "interrupted", exit 128 + the signal
    return code

if __name__ == "__main__":
    raise SystemExit(main())
