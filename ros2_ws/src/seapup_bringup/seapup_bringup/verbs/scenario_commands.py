"""``./seapup scenario NAME``: a closed-loop case of the thesis (sec. 5.4.2-5.4.3, figs 5.10-5.24; sec. 7.4,
7.6, figs 7.3-7.25).

The case (``seapup_runs/data/scenarios.yaml``) becomes a run spec
(:func:`seapup_runs.scenarios.scenario_spec`: a registered velocity controller
-- ``--controller mfol|explicit|gmv``, settings by ``--param key=value`` --
designed or commissioned by the self-test on the baseline vehicle, sec. 5.5)
flown in this process
(:func:`seapup_runs.runner.run`) or through the ROS graph in lockstep
(:func:`seapup_bringup.graph.graph_runner.run_on_graph`); both give the same
:class:`~seapup_runs.result.RunResult`, printed beside the thesis's numbers,
plotted, and written with ``--json`` in the run-result shape
(``docs/run-result.md``).
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from seapup_bringup.output import add_json_argument, emit_json, progress, text_stream
from seapup_common.controllers import ControllerRegistryError
from seapup_bringup.graph.sil import SilError
from seapup_runs.result import RunResult
from seapup_runs.run_plots import plot_scenario
from seapup_runs.runner import DesignFailed, run
from seapup_runs.scenarios import scenario_spec, scenarios
from seapup_runs.targets import thesis_by_metric
from seapup_runs.spec import RunSpecError
from seapup_runs.thesis_designs import DESIGNS
from seapup_control.self_test import FITS
from seapup_sim.vehicle_config import ConfigError, available_configs

__all__ = ["scenario_command", "print_scenario"]


def print_scenario(result: RunResult, text) -> None:
    """The case's figures of merit, the thesis's in brackets where it reports one."""
    spec, metrics = result.spec, result.metrics
    scheduled = any(c.parameters.get("schedule") for _, c in spec.controller_timeline() if c.type == "mfol")
    kind = spec.controller_timeline()[-1][1].type
    # the thesis's numbers (metric path -> value) are for the baseline vehicle with fixed gains
    thesis = thesis_by_metric(f"scenario:{spec.name}:{1.0 / spec.control_period:g}") \
        if spec.vehicle == "baseline" and not scheduled and kind in ("mfol", "hold") else {}
    law = ("scheduled" if scheduled else "fixed") + " gains" if kind == "mfol" else f"the {kind} controller"
    document = spec.controller.document or {}
    if document.get("phase") == "thesis":   # designed from the thesis's own matrices (seapup_runs.thesis_designs)
        law += f" designed from {document.get('reason', 'the thesis')}"
    if kind == "mfol" and spec.controller.parameters.get("anti_windup") is False:
        law += ", no anti-windup (the thesis's law)"
    print(f"\nscenario {spec.name}: {spec.vehicle}, {1.0 / spec.control_period:g} Hz, "
          f"{law}, {result.transport} (thesis in brackets where it reports one)", file=text)
    print(f"{'output':>6} {'reference':>10} {'final':>9} {'rise95 [s]':>14} {'overshoot [%]':>16} "
          f"{'max interaction':>16}", file=text)
    for key, o in metrics["outputs"].items():
        def cell(name, width, fmt):
            value = o.get(name)
            ref = thesis.get(f"outputs.{key}.{name}")
            body = "-" if value is None else (fmt.format(value) if math.isfinite(value) else "never")
            return f"{body + (f' ({ref:g})' if ref is not None else ''):>{width}}"
        print(f"{key:>6} {o['reference']:10.3f} {cell('final', 9, '{:.3f}')} {cell('rise95_s', 14, '{:.2f}')} "
              f"{cell('overshoot_pct', 16, '{:.1f}')} {cell('max_interaction', 16, '{:.3f}')}", file=text)
    window = metrics["pitch_deg"]["window_s"]
    print(f"units: m/s, r in deg/s; final = mean over the last {window:g} s; saturation [s] per thruster: "
          + ", ".join(f"{s:.1f}" for s in metrics["saturation_s"]), file=text)
    unsettled = [f"{key} {o['range'][0]:.3f} to {o['range'][1]:.3f} {'deg/s' if key == 'r' else 'm/s'}"
                 for key, o in metrics["outputs"].items() if not o["settled"]]
    if unsettled:
        print(f"not settled over the last {window:g} s: " + "; ".join(unsettled), file=text)
    lc = metrics["limit_cycle"]
    pitch = metrics["pitch_deg"]
    print(f"pitch peak {pitch['peak']:.1f} deg"
          + (f" ({thesis['pitch_deg.peak']:g})" if "pitch_deg.peak" in thesis else "")
          + f", final {pitch['final']:.1f} deg"
          + (f" ({thesis['pitch_deg.final']:g})" if "pitch_deg.final" in thesis else "")
          + ("" if pitch["settled"] else f" (not settled: {pitch['range'][0]:.1f} to {pitch['range'][1]:.1f} deg "
                                         f"over the last {pitch['window_s']:g} s)")
          + f"; roll peak {metrics['roll_deg']['peak']:.1f} deg; sway limit cycle: "
          + (f"period {lc['period_s']:.1f} s, {lc['amplitude']:.3f} m/s peak to peak" if lc["detected"] else "none")
          + (f" ({thesis['limit_cycle.period_s']:g} s)" if "limit_cycle.period_s" in thesis else ""), file=text)
    if "station_keep" in metrics:
        sk = metrics["station_keep"]
        print("station keeping after the controller is on: "
              + ", ".join(f"{k} {v:.2f}" + (f" ({thesis[f'station_keep.{k}']:g})" if f"station_keep.{k}" in thesis else "")
                          for k, v in sk.items()), file=text)
    if "jacket" in metrics:
        j = metrics["jacket"]
        print(f"self-tuner: {j.get('adaptive', 0)} samples adaptive, {j.get('fallback', 0)} on the fixed gains "
              f"({j.get('engagements', 0)} fallbacks), estimation frozen {j.get('frozen_at_set_point', 0)} samples "
              f"at the set point and {j.get('frozen_no_excitation', 0)} without excitation", file=text)
    if "u_peak_after_current" in metrics:
        print(f"current step: u peak {metrics['u_peak_after_current']:.4f} m/s"
              + (f" ({thesis['u_peak_after_current']:g})" if "u_peak_after_current" in thesis else "")
              + f", back within 5 % after {metrics['recovery_5pct_s']:.1f} s"
              + (f" ({thesis['recovery_5pct_s']:g})" if "recovery_5pct_s" in thesis else ""), file=text)


def scenario_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup scenario`` (its usage line in ``./seapup help`` is generated from it)."""
    parser = argparse.ArgumentParser(prog="./seapup scenario", description=__doc__.splitlines()[0])
    parser.add_argument("name", nargs="?", help="scenario (--list shows them)")
    parser.add_argument("--list", action="store_true", help="list the scenarios")
    parser.add_argument("--rate", type=float, default=5.0, choices=(5.0, 20.0))
    parser.add_argument("--config", default="baseline", help=f"vehicle flown ({', '.join(available_configs())})")
    parser.add_argument("--schedule", action="store_true", default=None, help="gain-scheduled controller")
    parser.add_argument("--seed", type=int, default=0, help="seed of the run's random streams")
    parser.add_argument("--controller", default="mfol",
                        help="velocity controller by registered name (./seapup controllers lists them; default mfol)")
    parser.add_argument("--param", action="append", default=[], metavar="KEY=VALUE",
                        help="a controller setting, e.g. forgetting=0.95, lambda=0.1, order=1 (repeatable)")
    parser.add_argument("--sensors", help="sensor profile instead of the case's (baseline, haslar, ideal)")
    parser.add_argument("--design", default="self-test", choices=("self-test", *DESIGNS),
                        help="what designs the controller: our self-test (default), or the thesis's own matrices "
                             "(eq. 5.3's velocity log, Table 5.1's realistic self-test; 5 Hz)")
    parser.add_argument("--fit", choices=FITS, default="deviation",
                        help="how the designing self-test fits its steps: deviations from the operating point "
                             "(eq. 5.5, the default) or the raw outputs, as the thesis's Table 5.2 reads at 0.7 m/s")
    parser.add_argument("--plots", type=Path, help="write a figure like figs 5.10-5.24 into this directory")
    parser.add_argument("--graph", action="store_true",
                        help="fly it through the ROS graph in lockstep (simulator and controller nodes)")
    add_json_argument(parser)
    return parser


def scenario_command(argv: list[str]) -> int:
    """``./seapup scenario NAME``: one of the thesis's closed-loop cases, measured and compared."""
    parser = scenario_parser()
    args = parser.parse_args(argv)
    text = text_stream(args)
    if args.list or not args.name:
        for name, case in scenarios().items():
            print(f"{name:14} {case['duration']:5.0f} s  reference {case['reference']}", file=text)
        return 0 if args.list else 2
    try:
        spec = scenario_spec(args.name, args.config, args.rate, args.schedule, args.seed, args.controller,
                             _parameters(args.param), args.sensors, args.design, args.fit)
        if args.graph:
            from seapup_bringup.graph.graph_runner import run_on_graph
            result = run_on_graph(spec, progress=lambda f: progress(args.name, f))
        else:
            result = run(spec, progress=lambda f: progress(args.name, f))
    except (KeyError, ValueError, ConfigError, RunSpecError, ControllerRegistryError, DesignFailed, SilError) as exc:
        reason = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc   # a KeyError's str() is quoted
        print(f"seapup: error: {reason}", file=sys.stderr)
        return 1
    print_scenario(result, text)
    if args.plots:
        print(f"wrote {plot_scenario(result, args.plots)}", file=text)
    emit_json(args, result.to_dict())
    return 0


def _parameters(items: list[str]) -> dict:
    """``--param key=value`` as a mapping, each value read as strict YAML (0.95, true, [1, 2]:
    :func:`seapup_common.input_files.parse_yaml`, safe tags only, bounded depth); a key given twice is refused.
    The controller type checks names and types when the run is made."""
    from seapup_common.input_files import InputFileError, parse_yaml
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ValueError(f"--param needs KEY=VALUE, got {item[:80]!r}")
        if key in out:
            raise ValueError(f"--param {key[:80]} is given twice")
        try:
            out[key] = parse_yaml(value, f"--param {key[:80]}")
        except InputFileError as exc:
            raise ValueError(str(exc)) from None
    return out
