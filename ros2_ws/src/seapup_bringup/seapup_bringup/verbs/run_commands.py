"""``./seapup fly SPEC`` and ``./seapup controllers``: runs and control laws as data on the command line.

fly          a run specification (YAML or JSON, :class:`seapup_runs.spec.RunSpec`'s keys) flown in
             this process or, with ``--graph``, through the ROS graph in lockstep; the result printed
             as a summary, written with ``--json`` in the run-result shape (``docs/run-result.md``)
             and plotted with ``--plots``. A mission document (``graph`` and ``mission`` keys,
             ``docs/missions.md``) is flown the same two ways, through the whole hierarchy
             (:func:`seapup_runs.mission_flight.run_mission`; on the graph
             :func:`seapup_bringup.graph.mission_graph.fly_mission`): the leg table printed, and with ``--out``
             the plots, ``summary.json`` and a page (on the graph also the bag). A new experiment is a
             new file, not a new verb.
controllers  the registered control laws (entry points ``seapup.velocity_controllers``) with their
             parameters and defaults.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from seapup_bringup.output import add_json_argument, emit_json, progress, text_stream

__all__ = ["fly", "controllers"]


def _load_spec(path: Path):
    """The run spec in ``path``: read bounded and parsed strictly (:mod:`seapup_common.input_files`: at most
    1 MiB, no duplicated key, no ``!!python`` tag), an empty or comment-only file refused, then checked
    (:meth:`RunSpec.from_dict`, whose messages are prefixed with the file)."""
    from seapup_common.input_files import load_yaml_file
    from seapup_runs.metrics import check_names
    from seapup_runs.spec import RunSpec, RunSpecError
    data = load_yaml_file(path, "spec")
    try:
        spec = RunSpec.from_dict(data)
        check_names(spec.metrics)   # before either transport flies it
        return spec
    except (RunSpecError, ValueError) as exc:
        raise RunSpecError(f"{path}: {exc}") from None


def _summary(result, text) -> None:
    spec, series = result.spec, result.series
    print(f"run {spec.name}: {spec.vehicle} ({spec.dynamics}), {spec.duration:g} s at {1 / spec.control_period:g} Hz, "
          f"{result.transport}; controllers: "
          + ", ".join(f"{c.type} from {t:g} s" for t, c in spec.controller_timeline()), file=text)
    end = {k: float(series.truth[k][-1]) for k in ("u", "v", "w", "x", "y", "z")}
    print("at the end (truth): " + ", ".join(f"{k} {v:.3f}" for k, v in end.items())
          + f", r {np.degrees(series.truth['r'][-1]):.2f} deg/s", file=text)
    if result.metrics.get("outputs"):
        for key, o in result.metrics["outputs"].items():
            cells = ", ".join(f"{name} {value:.3g}" for name, value in o.items()
                              if isinstance(value, (int, float)) and not isinstance(value, bool))
            cells += "" if o.get("settled", True) else " (not settled)"
            print(f"  {key}: {cells}", file=text)


def fly_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup fly`` (its usage line in ``./seapup help`` is generated from it)."""
    parser = argparse.ArgumentParser(prog="./seapup fly", description=__doc__.splitlines()[0])
    parser.add_argument("spec", type=Path, help="a run specification (YAML or JSON; see docs/run-result.md) or a "
                                                "mission (graph and mission keys; docs/missions.md)")
    parser.add_argument("--graph", action="store_true", help="fly it through the ROS graph in lockstep")
    parser.add_argument("--out", type=Path, help="the graph run's node logs and graph file (default: a temp dir); "
                                                 "a mission's plots, summary.json and page (and bag on the graph: "
                                                 "default bags/fly_<UTC time>)")
    parser.add_argument("--plots", type=Path, help="write a figure of the run into this directory")
    add_json_argument(parser)
    return parser


def fly(argv: list[str]) -> int:
    """``./seapup fly SPEC [--graph] [--out DIR] [--plots DIR] [--json [F]]``."""
    from seapup_bringup.graph.sil import SilError
    from seapup_common.controllers import ControllerRegistryError
    from seapup_runs.runner import DesignFailed, run
    from seapup_runs.spec import RunSpecError
    from seapup_sim.integrator import DivergenceError
    from seapup_sim.vehicle_config import ConfigError

    parser = fly_parser()
    args = parser.parse_args(argv)
    text = text_stream(args)
    mission = _mission_document(args.spec)
    if mission is not None:
        return _fly_mission(args, text, mission)
    try:
        spec = _load_spec(args.spec)
        if args.graph:
            from seapup_bringup.graph.graph_runner import run_on_graph
            result = run_on_graph(spec, out_dir=args.out, progress=lambda f: progress(spec.name, f))
        else:
            result = run(spec, progress=lambda f: progress(spec.name, f))
    except (RunSpecError, ControllerRegistryError, ConfigError, DesignFailed, ValueError, SilError,
            DivergenceError) as exc:
        print(f"seapup: error: {exc}", file=sys.stderr)
        return 1
    _summary(result, text)
    if args.plots:
        from seapup_runs.run_plots import plot_scenario
        print(f"wrote {plot_scenario(result, args.plots)}", file=text)
    emit_json(args, result.to_dict())
    return 0


def _mission_document(path: Path) -> dict | None:
    """The document in ``path`` if it is a mission (a mapping with ``mission``) rather than a run spec, else None.
    Read bounded, once; a file that cannot be read is left to the run spec's reader to refuse with its reason."""
    from seapup_common.input_files import InputFileError, load_yaml_file
    try:
        document = load_yaml_file(path, "spec")
    except InputFileError:
        return None
    return document if isinstance(document, dict) and "mission" in document else None


def _fly_mission(args, text, document: dict) -> int:
    """``./seapup fly MISSION [--graph] [--out DIR] [--json [F]]``: the mission in process or on the graph."""
    import os
    import time

    from seapup_bringup.graph.hierarchy_config import hierarchy_config
    from seapup_bringup.graph.mission_graph import fly_mission, mission_config
    from seapup_runs.mission_pages import report_mission
    from seapup_bringup.output import stopped_by_signal
    from seapup_common.ros.launch_graph import LaunchError
    from seapup_runs.mission import MissionError, MissionSpec
    from seapup_runs.mission_flight import MissionFlightError, run_mission
    try:
        config = mission_config(args.spec, document)
    except (MissionError, LaunchError) as exc:
        print(f"seapup: error: {exc}", file=sys.stderr)
        return 1
    config["source"] = str(args.spec)
    name = args.spec.stem
    out = args.out or args.plots
    if args.graph and out is None:
        out = Path(os.environ.get("SEAPUP_ROOT", ".")) / "bags" / time.strftime("fly_%Y%m%d_%H%M%S", time.gmtime())
    wall = time.monotonic()
    try:
        if args.graph:
            result = fly_mission(out, config, text)
        else:
            spec = MissionSpec.load({"graph": config["graph"], "mission": config["mission"]})
            result = run_mission(spec, hierarchy_config(spec.graph), lambda leg, f: progress(f"{name}: {leg}", f))
    except (MissionFlightError, RuntimeError, ValueError) as exc:
        if stopped_by_signal(exc):
            raise
        where = f"; node logs in {out}" if args.graph else ""
        print(f"seapup: error: mission {name} failed: {exc}{where}", file=sys.stderr)
        return 1
    result["wall_s"] = time.monotonic() - wall
    stopped = result.pop("stopped", None)
    result["interrupted"] = stopped is not None
    summary, code = report_mission(result, config, out, text, f"seapup fly {name}")
    emit_json(args, summary)
    if stopped is not None:
        raise stopped
    return code


def controllers_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup controllers`` (its usage line in ``./seapup help`` is generated from it)."""
    parser = argparse.ArgumentParser(prog="./seapup controllers", description="the registered velocity controllers")
    add_json_argument(parser)
    return parser


def controllers(argv: list[str]) -> int:
    """``./seapup controllers [--json [F]]``."""
    from seapup_common.controllers import ControllerRegistryError, available_controllers, controller_type

    parser = controllers_parser()
    args = parser.parse_args(argv)
    text = text_stream(args)
    listed, failed = {}, {}
    for name in available_controllers():
        try:
            kind = controller_type(name)
        except ControllerRegistryError as exc:  # a broken plugin is reported, not fatal
            failed[name] = str(exc)
            continue
        listed[name] = {"description": kind.description, "parameters": dict(kind.parameters),
                        "needs_document": kind.needs_document, "needs_applied": kind.needs_applied}
        print(f"{name:12} {kind.description}", file=text)
        for parameter, default in kind.parameters.items():
            print(f"{'':12}   {parameter} (default {default})", file=text)
        if kind.needs_document:
            print(f"{'':12}   + a design document (controller_file)", file=text)
    for name, why in failed.items():
        print(f"{name:12} NOT LOADED: {why}", file=text)
    emit_json(args, {"controllers": listed, "not_loaded": failed})
    return 1 if failed else 0
