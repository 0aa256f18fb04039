"""Identification experiments on the graph and fits from bags or CSV files (thesis ch. 6): ``./seapup ident``.

- ``experiment``: the identification experiments of sec. 6.5 in SIL, recorded to a bag under
  ``bags/`` next to the identifier's own run bag: open loop (sec. 6.5.1-6.5.4, graph
  ``seapup_bringup/launch/identification.launch.yaml``: simulator in lockstep, nonlinear or linearised,
  ``open_loop`` holding a PRBS of +-amplitude about the hover setting on every thruster, clock 10
  samples at 5 Hz, optionally the current) or closed loop (sec. 6.5.5,
  ``identification_closed_loop.launch.yaml``: the fixed-gain self-tested controller following a
  square-wave reference from ``reference_schedule``), the ``identifier`` node estimating online; with
  ``--in-process`` the same experiment's run spec (:mod:`seapup_runs.identification_experiment`) flown in this
  process instead, its record ``OUT/run.json`` equal to the graph's bag sample for sample (tested), in a
  fraction of a second;
- ``fit SOURCE``: a model from a bag (velocity, IMU and applied blade-pitch topics), a run result (``.json``)
  or a CSV file, as JSON {"method", "orders", "A", "B", "C", "d", "loss", "aic", ...};
- ``orders SOURCE``: loss, AIC and F per output and order (Tables 6.1, 6.2, 6.6);
- ``compare SOURCE``: AIC of LS, ELS and RPEM (Tables 6.3-6.5, 6.7), with plots of each model
  against the data (figs 6.3, 6.5-6.11, 6.13-6.14);
- ``residuals SOURCE``: the whiteness test of a fitted model's residuals (sec. 6.3, fig. 6.2).

An experiment of ``--duration`` D s at period T ends at exactly t = D in graph time (the simulator's
``end_time``): its bag holds the D / T + 1 samples t = 0, T, ..., D, and the identification data
read from it the D / T samples t = 0 .. D - T, each with the input held over [t_k, t_k + T] (the
sample at t = D has no interval left). The experiment's request is kept in ``experiment.json``
next to the bag. Every fit reports the samples and times it scored (``scope`` in JSON) and takes
``--duration`` (score the first D s; default: what the experiment asked for, when the record says)
and ``--points``; a record longer than its experiment asked for is said so in one line.

The computations are :mod:`seapup_ident.identify`; this module reads the data, flies the experiment on the
graph and prints; ``./seapup ident`` (:mod:`seapup_bringup.verbs.ident_commands`) parses and writes JSON.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

import numpy as np

from seapup_bringup.output import add_json_argument, progress
from seapup_common.blade_pitch import THRUSTER_NAMES
from seapup_common.topics import (APPLIED, CLOCK, COMMAND, DEPTH, IMU, TRUTH_ODOMETRY, VELOCITY, VELOCITY_REFERENCE,
                                  typed)
from seapup_runs.identification_experiment import EXPERIMENT_PERIOD, OUTPUT_SETS, experiment_samples

__all__ = ["handle", "identify", "ident_parser", "bag_data", "load_source", "experiment_record", "scope", "OUTPUT_SETS",
           "EXPERIMENT_RECORD", "experiment_samples"]

#: The experiment's request, written next to its record (``OUT/bag``, or ``OUT/run.json`` in process) by
#: ``ident experiment``.
EXPERIMENT_RECORD = "experiment.json"
#: An in-process experiment's record: its run result (``seapup/run_result``, docs/run-result.md).
RUN_RECORD = "run.json"


def bag_data(path, outputs=OUTPUT_SETS["ch6"]):
    """IdentificationData from a bag: outputs from ``/seapup/sensors/velocity`` (u, v, w, r) and
    ``/seapup/sensors/imu`` (roll, pitch) joined on the sample stamps; the input u(t_k) is the
    applied blade pitch read at the next sample, the pitch held over [t_k, t_k+1]
    (:func:`seapup_ident.online.held_inputs`, as the identifier node joins them). A sample missing
    from any topic becomes a NaN row (reported, never used); the last samples, whose interval the
    record does not cover, are left out."""
    from geometry_msgs.msg import TwistWithCovarianceStamped
    from rclpy.serialization import deserialize_message
    from seapup_msgs.msg import BladePitch
    from sensor_msgs.msg import Imu

    from seapup_common.bag import read_bag
    from seapup_common.ros.messages import attitude_from_imu, stamp_to_ns, velocity_from_msg
    from seapup_ident.identify import IdentificationData
    from seapup_ident.online import held_inputs

    unknown = set(outputs) - set(OUTPUT_SETS["ch6"])
    if unknown:
        raise ValueError(f"unknown output(s) {sorted(unknown)}; choose from {', '.join(OUTPUT_SETS['ch6'])}")
    kinds = {VELOCITY: TwistWithCovarianceStamped, IMU: Imu, APPLIED: BladePitch}
    found = {topic: {} for topic in kinds}
    for message in read_bag(path, list(kinds)):
        msg = deserialize_message(message.cdr, kinds[message.topic])
        found[message.topic][stamp_to_ns(msg.header.stamp)] = msg
    empty = [topic for topic, values in found.items() if not values and
             (topic != IMU or {"roll", "pitch"} & set(outputs))]
    if empty:
        raise ValueError(f"{path}: no messages on {', '.join(empty)} (record them: ./seapup ident experiment)")
    applied = {stamp: np.asarray(msg.pitch, float) for stamp, msg in found[APPLIED].items()}
    output_topics = [VELOCITY] + ([IMU] if {"roll", "pitch"} & set(outputs) else [])
    stamps = sorted(set().union(*(found[topic] for topic in output_topics)))
    period = float(np.median(np.diff(sorted(applied)))) * 1e-9 if len(applied) > 1 else 0.0
    u = held_inputs(stamps, applied, period)
    covered = np.flatnonzero(np.all(np.isfinite(u), axis=1))
    if not len(covered):
        raise ValueError(f"{path}: no sample has an applied blade pitch read after it (one sample period later)")
    stamps, u = stamps[:covered[-1] + 1], u[:covered[-1] + 1]
    y = np.full((len(stamps), len(outputs)), np.nan)
    for k, stamp in enumerate(stamps):
        row = {}
        if stamp in found[VELOCITY]:
            velocity, rates = velocity_from_msg(found[VELOCITY][stamp])
            if velocity.valid and rates.valid:
                row.update(zip(("u", "v", "w"), velocity.value))
                row["r"] = rates.value[2]
        if stamp in found[IMU]:
            attitude = attitude_from_imu(found[IMU][stamp])
            if attitude.valid:
                row.update(roll=attitude.value[0], pitch=attitude.value[1])
        y[k] = [row.get(name, math.nan) for name in outputs]
    return IdentificationData(y, u, np.array(stamps) * 1e-9, tuple(outputs), THRUSTER_NAMES)


#: The most cells (rows x columns) a CSV record may have: parsing holds each cell as a string before it becomes
#: a float, about 60 bytes a cell, so 4 x 10^6 cells are ~0.25 GB at most. A thesis experiment (60 s at 20 Hz,
#: a dozen columns) is ~1.4 x 10^4 cells; the cap is over 4 hours of such a record.
MAX_CSV_CELLS = 4 * 10**6


def load_source(source: str, outputs: str | None, inputs: str | None, output_set: str):
    """A bag directory (metadata.yaml), a run result (``.json``: an in-process experiment's ``run.json``, or any
    run's ``--json``; :func:`seapup_runs.identification_experiment.identification_data`) or a CSV file (read
    bounded: :mod:`seapup_common.input_files`' data limit, at most :data:`MAX_CSV_CELLS` cells, no row longer
    than the header)."""
    from seapup_ident.identify import read_csv
    path = Path(source)
    names = tuple(outputs.split(",")) if outputs else OUTPUT_SETS.get(output_set, ())
    if path.is_dir():
        return bag_data(path, names)
    if path.suffix.lower() == ".json":
        from seapup_runs.identification_experiment import identification_data
        from seapup_runs.result import RunResult, RunResultError
        if inputs:
            raise ValueError("--inputs names CSV columns; a run result's inputs are its four applied blade pitches")
        try:
            result = RunResult.from_json(path)   # bounded: the data limit (docs/limits.md)
        except RunResultError as exc:
            raise ValueError(f"{source}: {exc}") from None
        return identification_data(result, names)
    if path.suffix.lower() == ".csv":
        _check_csv(path)
        return read_csv(path, outputs.split(",") if outputs else None, inputs.split(",") if inputs else None)
    raise ValueError(f"{source}: neither a bag directory, a run result (.json) nor a .csv file")


def _check_csv(path: Path) -> None:
    """Refuse a CSV file that is too large, not text, has too many cells or a row longer than its header, in one
    line, before :func:`seapup_ident.identify.read_csv` builds anything from it."""
    import csv
    import io

    from seapup_common.input_files import read_text
    text = read_text(path, "data")   # InputFileError (a ValueError): too large, not UTF-8, a NUL byte
    cells = text.count(",") + text.count("\n") + (not text.endswith("\n"))   # a line has one cell more than commas
    if cells > MAX_CSV_CELLS:
        raise ValueError(f"{path}: about {cells:,} cells, more than the {MAX_CSV_CELLS:,} a CSV record may have "
                         "(docs/limits.md)")
    try:
        reader = csv.reader(io.StringIO(text, newline=""))
        width = None
        for line, row in enumerate(reader, 1):
            width = len(row) if width is None else width
            if len(row) > width:
                raise ValueError(f"{path}: row {line} has {len(row)} cells, more than the header's {width}")
    except csv.Error as exc:
        raise ValueError(f"{path}: not CSV ({exc})") from None


def experiment_record(source) -> dict | None:
    """The request of the experiment that recorded ``source`` (``experiment.json`` in its parent directory
    naming it as its bag, its identifier's bag or its in-process record), or None."""
    path = Path(source)
    record = path.parent / EXPERIMENT_RECORD
    if not (path.exists() and record.is_file()):
        return None
    from seapup_common.input_files import read_text
    try:
        doc = json.loads(read_text(record, "data"))   # InputFileError is a ValueError
    except (ValueError, RecursionError):
        return None
    if not isinstance(doc, dict):
        return None
    named = [Path(doc[key]).resolve() for key in ("bag", "identifier_bag", "record") if isinstance(doc.get(key), str)]
    return doc if path.resolve() in named and isinstance(doc.get("duration"), (int, float)) else None


def _seconds(value: float) -> str:
    return f"{value:.6g}"


def scope(data, duration: float | None = None, asked: float | None = None):
    """The part of a record to score, what it covers, and the lines that say so.

    Parameters
    ----------
    data : IdentificationData
    duration : float, optional
        Score the first ``duration`` seconds (``--duration``; ``math.inf``: all of it).
    asked : float, optional
        The seconds the experiment that recorded it asked for (``experiment.json``): the default
        ``duration``, and a record longer than this is said so.

    Returns
    -------
    (IdentificationData, dict, list of str)
        The data scored; ``{"samples", "t", "sample_period", "seconds"}`` of it plus
        ``"record"`` (the same of the whole record), ``"duration_s"`` (the limit applied, or None),
        ``"asked_s"`` and ``"trimmed"``; the lines to print.
    """
    whole = data.span()
    period = whole["sample_period"]
    limit = asked if duration is None else duration
    limit = None if limit is None or math.isinf(limit) else float(limit)
    trimmed = limit is not None and whole["seconds"] > limit + 0.5 * period
    scored = data.first(limit) if trimmed else data
    span = scored.span()
    lines = []
    if asked is not None and whole["seconds"] > asked + 0.5 * period:
        what = (f"scoring the first {_seconds(limit)} s" if trimmed else "scoring all of it") + (
            " (--duration all scores all of it)" if trimmed and duration is None else "")
        lines.append(f"note: the record holds {whole['samples']} samples ({_seconds(whole['seconds'])} s), longer "
                     f"than the {_seconds(asked)} s its experiment asked for; {what}")
    t = span["t"]
    lines.append(f"data: {span['samples']} samples, t = {t[0]:.6g} .. {t[1]:.6g} s (T = {period:.6g} s, "
                 f"{_seconds(span['seconds'])} s of inputs)"
                 + (f", the first {_seconds(limit)} s of a {whole['samples']}-sample record" if trimmed else ""))
    return scored, {**span, "record": whole, "duration_s": limit, "asked_s": asked, "trimmed": trimmed}, lines


def _scoped_source(args, text):
    """``load_source`` for the common options, cut to ``--duration`` (or the experiment's), said in ``text``."""
    data = load_source(args.source, args.outputs, args.inputs, args.output_set)
    record = experiment_record(args.source)
    scored, doc, lines = scope(data, args.duration, float(record["duration"]) if record else None)
    for line in lines:
        print(line, file=text)
    return scored, doc


def _duration(text: str) -> float:
    """``--duration``: seconds > 0, or ``all``."""
    if text.strip().lower() == "all":
        return math.inf
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"--duration must be seconds > 0 or 'all', got {text!r}")
    return value


def _forgetting(args):
    from seapup_ident.recursive import Forgetting
    if args.forgetting is not None:
        return lambda: Forgetting(args.forgetting)
    return lambda: Forgetting.schedule(args.lambda0, args.alpha)


def _parse_orders(text: str) -> tuple[int, int, int]:
    try:
        na, nb, nc = (int(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"--orders needs three integers na,nb,nc, got {text!r}") from None
    return na, nb, nc


def _points(args) -> int | None:
    if args.points is not None and args.passes != 1:
        raise ValueError("give --passes or --points, not both")
    return args.points


def _rpem_filter(args) -> tuple[float, float] | None:
    if args.rpem_k0 is None:
        return None
    if not (0.0 < args.rpem_k0 <= 1.0 and 0.0 <= args.rpem_gamma < 1.0):
        raise ValueError(f"--rpem-k0 must be in (0, 1] and --rpem-gamma in [0, 1), got {args.rpem_k0}, "
                         f"{args.rpem_gamma}")
    return args.rpem_k0, args.rpem_gamma


def _common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("source", help="a bag directory, a run result (.json, e.g. an in-process experiment's "
                                       "run.json) or a CSV file (header: y... outputs, u... inputs, t)")
    parser.add_argument("--outputs", help="comma-separated output names (bag: u,v,w,r,roll,pitch; CSV: columns)")
    parser.add_argument("--inputs", help="CSV: comma-separated input columns (default u...)")
    parser.add_argument("--set", dest="output_set", choices=sorted(OUTPUT_SETS), default="ch6",
                        help="bag outputs: ch6 = u,v,w,r,roll,pitch (default), ch7 = u,v,w,r")
    parser.add_argument("--lambda0", type=float, default=0.6, help="eq. 6.15's lambda(0) (default 0.6)")
    parser.add_argument("--alpha", type=float, default=0.9, help="eq. 6.15's alpha (default 0.9)")
    parser.add_argument("--forgetting", type=float, help="a fixed forgetting factor instead of eq. 6.15")
    parser.add_argument("--p0", type=float, default=100.0, help="P(0) = p0 I (default 100, sec. 6.5.1)")
    parser.add_argument("--score", choices=("posterior", "prior"), default="posterior",
                        help="V_N and AIC from the a posteriori equation errors (eq. 6.20, default) or the "
                             "one-step prediction errors (eq. 6.11)")
    parser.add_argument("--rpem-k0", type=float, help="RPEM: weaken the gradient filter at first, K(0) "
                                                      "(Tables 6.3-6.7: 0.1); default none")
    parser.add_argument("--rpem-gamma", type=float, default=0.98, help="RPEM: the weakening's gamma (default 0.98)")
    parser.add_argument("--passes", type=int, default=1,
                        help="times the record is replayed, scoring the last pass (sec. 6.5.1)")
    parser.add_argument("--points", type=int, help="replay until this many samples were examined, scoring them "
                                                   "all (the thesis's 2000-point runs); instead of --passes")
    parser.add_argument("--duration", type=_duration,
                        help="score the first DURATION seconds of the record ('all': the whole record; default: "
                             "the duration its experiment asked for, when experiment.json says, else all)")
    add_json_argument(parser)


def _fit_model(args, data, orders: tuple[int, int, int]):
    """The fit ``ident fit`` and ``ident residuals`` share, from the common options."""
    from seapup_ident.armax import ArmaxOrders
    from seapup_ident.identify import fit
    return fit(data, ArmaxOrders(data.y.shape[1], data.u.shape[1], *orders), args.method,
               forgetting=_forgetting(args)(), p0=args.p0, passes=args.passes, points=_points(args),
               filter_weakening=_rpem_filter(args) if args.method == "rpem" else None, score=args.score)


def _fit(args, text) -> dict:
    from seapup_ident.identify import model_document
    na, nb, nc = _parse_orders(args.orders)
    if args.method == "ls" and nc:
        raise ValueError("least squares has no noise model: use --orders na,nb,0 or --method els|rpem")
    data, span = _scoped_source(args, text)
    result = _fit_model(args, data, (na, nb, nc))
    doc = model_document(result, data, source=str(args.source), scope=span)
    print(f"ident fit: {args.method} orders ({na}, {nb}, {nc}) on {result.report.usable} of "
          f"{result.report.samples} samples ({result.report.non_finite} non-finite, {result.report.gaps} gaps), "
          f"{result.examined} examined in {result.passes} pass(es), {result.scored} scored", file=text)
    print(f"{'output':<10}{'loss V_N':>14}{'AIC':>12}", file=text)
    for name, v, a in zip(data.outputs, result.loss, result.aic):
        print(f"{name:<10}{v:>14.4e}{a:>12.1f}", file=text)
    if args.plots:
        doc["plots"] = [_plot_model(data, result, Path(args.plots), f"{args.source}: {args.method} ({na}, {nb}, {nc})")]
    return doc


def _plot_model(data, result, out: Path, title: str) -> str:
    """Figs 6.3, 6.5-6.11, 6.13-6.14: per output the data against the adapting model's one-step
    predictions during the first pass (the transient) and against the final model's."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from seapup_ident.identify import predict

    final = predict(result.model, data)
    out.mkdir(parents=True, exist_ok=True)
    ny = len(data.outputs)
    fig, axes = plt.subplots(ny, 2, figsize=(13, 1.9 * ny), sharex=True, squeeze=False)
    for i, name in enumerate(data.outputs):
        for ax, prediction, label in ((axes[i, 0], result.transient, "adapting model (first pass)"),
                                      (axes[i, 1], final, "final model")):
            error = data.y[:, i] - prediction[:, i]
            rms = float(np.sqrt(np.nanmean(error ** 2)))
            ax.plot(data.t, data.y[:, i], lw=0.9, color="k", label="data")
            ax.plot(data.t, prediction[:, i], lw=0.8, color="tab:red", label=label)
            ax.plot(data.t, error, lw=0.6, color="tab:blue", label="error")
            ax.set_title(f"{name}: rms error {rms:.3g}", fontsize=8, loc="left")
            ax.tick_params(labelsize=7)
    axes[0, 0].legend(fontsize=7), axes[0, 1].legend(fontsize=7)
    axes[-1, 0].set_xlabel("t [s]"), axes[-1, 1].set_xlabel("t [s]")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    path = out / f"ident_{result.method}_{'_'.join(map(str, (result.orders.na, result.orders.nb, result.orders.nc)))}.png"
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return str(path)


def _plot_residuals(table: dict, out: Path, title: str, name: str) -> str:
    """Fig. 6.2: the residuals' normalised autocorrelation per output with the 95 % band."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    ny = len(table["outputs"])
    fig, axes = plt.subplots((ny + 1) // 2, 2, figsize=(11, 2.2 * ((ny + 1) // 2)), squeeze=False)
    for ax, output, r, white in zip(axes.ravel(), table["outputs"], table["autocorrelation"], table["white"]):
        ax.vlines(table["lags"], 0, r, color="k")
        ax.axhline(table["band"], ls="--", color="tab:red"), ax.axhline(-table["band"], ls="--", color="tab:red")
        ax.set_title(f"{output}: {'white' if white else 'correlated'}", fontsize=8, loc="left")
        ax.set_ylim(-max(0.3, 2 * table["band"]), 1.05)
        ax.tick_params(labelsize=7)
    for ax in axes.ravel()[ny:]:
        ax.set_visible(False)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    path = out / name
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return str(path)


def _orders(args, text) -> dict:
    from seapup_ident.identify import order_table
    data, span = _scoped_source(args, text)
    table = order_table(data, args.max_order, args.method, alpha=args.risk, forgetting_factory=_forgetting(args),
                        p0=args.p0, passes=args.passes, points=_points(args), score=args.score)
    names = data.outputs
    print(f"ident orders: {args.method}, orders (n, n{', n' if args.method != 'ls' else ''}), risk {args.risk:g}",
          file=text)
    for key, label in (("loss", "V_n"), ("aic", "AIC_n"), ("f", "F")):
        print(f"{label:<8}" + "".join(f"{n:>12}" for n in names), file=text)
        for row in table["rows"]:
            if key in row:
                print(f"  n = {row['order']:<3}" + "".join(f"{v:>12.4g}" for v in row[key]), file=text)
    print(f"order by AIC {table['aic_order']}, by F {table['f_order']}: system order {table['system_order']}",
          file=text)
    table["scope"] = span
    return table


def _compare(args, text) -> dict:
    from seapup_ident.identify import compare_methods
    data, span = _scoped_source(args, text)
    table = compare_methods(data, args.order, tuple(args.methods.split(",")), forgetting_factory=_forgetting(args),
                            p0=args.p0, passes=args.passes, points=_points(args), rpem_filter=_rpem_filter(args),
                            score=args.score)
    scope = f"{args.points} points examined" if args.points else f"{args.passes} pass(es), the last scored"
    print(f"ident compare: AIC at order {args.order}, {scope} ({len(data.t)} samples)"
          + (f", RPEM filter K(0) = {args.rpem_k0:g}, gamma = {args.rpem_gamma:g}" if _rpem_filter(args) else ""),
          file=text)
    print(f"{'method':<8}" + "".join(f"{n:>12}" for n in data.outputs), file=text)
    for method, values in table["methods"].items():
        print(f"{method:<8}" + "".join(f"{v:>12.1f}" for v in values["aic"]), file=text)
    if args.plots:
        table["plots"] = [_plot_model(data, result, Path(args.plots), f"{args.source}: {method}, {scope}")
                          for method, result in table.pop("results").items()]
        for path in table["plots"]:
            print(f"plot {path}", file=text)
    else:
        table.pop("results")
    table["scope"] = span
    return table


def _residuals(args, text) -> dict:
    from seapup_ident.identify import residual_whiteness
    data, span = _scoped_source(args, text)
    na, nb, nc = _parse_orders(args.orders)
    result = _fit_model(args, data, (na, nb, nc))
    table = residual_whiteness(result.model, data, args.lags, args.risk)
    print(f"ident residuals: {args.method} ({na}, {nb}, {nc}), the final model's one-step errors over "
          f"{table['samples']} samples; band +-{table['band']:.3f} (95 %), Ljung-Box at risk {args.risk:g}",
          file=text)
    print(f"{'output':<10}{'inside band':>12}{'max |R(k)|':>12}{'Q':>10}{'p':>10}  verdict", file=text)
    for i, name in enumerate(table["outputs"]):
        print(f"{name:<10}{table['inside'][i]:>12.0%}{table['max_abs'][i]:>12.3f}{table['ljung_box_q'][i]:>10.1f}"
              f"{table['p_value'][i]:>10.3g}  {'white' if table['white'][i] else 'correlated'}", file=text)
    table.update(method=args.method, orders=[na, nb, nc], scope=span)
    if args.plots:
        table["plots"] = [_plot_residuals(table, Path(args.plots), f"{args.source}: residuals of {args.method} "
                                          f"({na}, {nb}, {nc})", f"ident_residuals_{args.method}.png")]
        print(f"plot {table['plots'][0]}", file=text)
    return table


def _experiment(args, text) -> dict:
    root = Path(os.environ.get("SEAPUP_ROOT", "."))
    out = Path(args.out) if args.out else root / "bags" / time.strftime("ident_%Y%m%d_%H%M%S", time.gmtime())
    orders = list(_parse_orders(args.orders))
    samples = experiment_samples(args.duration, EXPERIMENT_PERIOD)
    excitation = _closed_loop_excitation(args, out, text) if args.closed_loop else _prbs_excitation(args)
    request = {"method": args.method, "orders": orders, "duration": args.duration,
               "sample_period": EXPERIMENT_PERIOD, "samples": samples + 1, "dynamics": args.dynamics,
               "current": args.current, "sensors": args.sensors}
    if args.in_process:
        return _experiment_in_process(args, out, excitation, request, text)
    from seapup_bringup.graph.graph_runner import GraphSpec, fly_graph
    arguments = {"vehicle": args.vehicle, "dynamics": args.dynamics, "seed": args.seed, "current": args.current,
                 "sensors": args.sensors, "method": args.method, "orders": str(orders),
                 "identifier_bag": out / "identifier", "end_time": repr(samples * EXPERIMENT_PERIOD)}
    graph = ("seapup_bringup identification_closed_loop.launch.yaml" if args.closed_loop
             else "seapup_bringup identification.launch.yaml")
    arguments.update(excitation.pop("arguments"))
    excitation.pop("spec")
    # the first sample and the first command wait for every reader of them (the lockstep roster the harness
    # fills: the graph's own -- the identifier once started after a loaded run had ended, and estimated
    # nothing -- the recorder and the probe): a run that ends at end_time never says them again to a late reader
    record = typed(CLOCK, COMMAND, APPLIED, VELOCITY, IMU, DEPTH, TRUTH_ODOMETRY,
                   *([VELOCITY_REFERENCE] if args.closed_loop else []))
    spec = GraphSpec("identification experiment", graph, arguments, record=tuple(record),
                     banner=f"ident experiment: {excitation['description']}, {args.dynamics} model, "
                            f"{args.duration:g} s; ROS domain {{domain}}, output in {{out}}")
    flown = fly_graph(spec, out, lambda sil: _fly_to_end(sil, args.duration), logs=False, text=text)
    bag = flown.bag
    expected = [round(k * EXPERIMENT_PERIOD * 1e9) for k in range(samples + 1)]
    for topic, stamps in _recorded_samples(bag).items():   # every per-sample topic whole, not the truth alone
        if stamps != expected:
            raise ValueError(f"{bag}: {topic} holds {len(stamps)} samples"
                             + (f", t = {stamps[0] * 1e-9:g} .. {stamps[-1] * 1e-9:g} s" if stamps else "")
                             + f"; the experiment asked for the {samples + 1} samples t = 0 .. {args.duration:g} s "
                             f"(missing or extra samples: the recorder's log is {out / 'recorder.log'})")
    # a lockstep wait that ran out (a loaded machine) leaves a record the in-process flight need not repeat
    doc = {"bag": str(bag), "identifier_bag": str(out / "identifier"), **request, **excitation,
           "ended_waits": flown.ended_waits}
    if flown.ended_waits:
        print(f"ident experiment: warning: lockstep waits ended by their wall-clock limit: {flown.ended_waits} "
              "(the record is not the deterministic one)", file=text)
    (out / EXPERIMENT_RECORD).write_text(json.dumps(doc, indent=1) + "\n")
    print(f"ident experiment: bag {bag}: {samples + 1} samples, t = 0 .. {args.duration:g} s (the identification "
          f"data: the {samples} with an input interval); the identifier's run (readings used, model after each "
          f"sample) in {out / 'identifier'}; the request in {out / EXPERIMENT_RECORD}", file=text)
    return doc


def _experiment_in_process(args, out: Path, excitation: dict, request: dict, text) -> dict:
    """The same experiment flown in this process (:func:`seapup_runs.runner.run` of its run spec, sample for
    sample the record the graph gives): its run result in ``OUT/run.json``, a source for ``fit``, ``orders``,
    ``compare`` and ``residuals`` as the graph's bag is. No identifier runs online (``fit`` does it offline)."""
    from seapup_runs.runner import run
    spec = excitation.pop("spec")
    excitation.pop("arguments")
    print(f"ident experiment: {excitation['description']}, {args.dynamics} model, {args.duration:g} s, in this "
          f"process; output in {out}", file=text)
    result = run(spec, progress=lambda f: progress("experiment", f))
    out.mkdir(parents=True, exist_ok=True)
    record = out / RUN_RECORD
    result.to_json(record)
    online = ("method", "orders")   # the online identifier's settings: none runs in process
    doc = {"record": str(record), "transport": result.transport,
           **{k: v for k, v in request.items() if k not in online}, **excitation}
    (out / EXPERIMENT_RECORD).write_text(json.dumps(doc, indent=1) + "\n")
    print(f"ident experiment: record {record}: {len(result.series.t)} samples, t = 0 .. {args.duration:g} s "
          f"(the identification data: the {len(result.series.t) - 1} with an input interval); the request in "
          f"{out / EXPERIMENT_RECORD}", file=text)
    return doc


def _fly_to_end(sil, duration: float) -> None:
    """Until the simulator has published its last sample (t = duration: it steps no further, its
    ``end_time``) and the answer to it was heard, so the recorder has every message of t <= duration."""
    while sil.t < duration - 1e-9:
        sil.run_for(min(5.0, duration - sil.t))
        progress("experiment", sil.t / duration)
    sil.spin_until(lambda: sil.log["command"] and _stamp(sil.log["command"][-1]) >= duration - 1e-9, 10.0)
    sil.spin_until(lambda: False, 0.5)  # the recorder takes the last messages as the probe did (nothing new comes)


def _stamp(msg) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


#: The simulator's topics an identification bag must hold at every sample (what ``orders``/``compare`` read).
PER_SAMPLE = (TRUTH_ODOMETRY, VELOCITY, IMU, DEPTH, APPLIED)


def _recorded_samples(bag) -> dict[str, list[int]]:
    """Each of :data:`PER_SAMPLE`'s sample stamps in a bag [ns], in the order recorded."""
    from seapup_common.bag import header_stamp_ns, read_bag
    stamps: dict[str, list[int]] = {topic: [] for topic in PER_SAMPLE}
    for message in read_bag(bag, list(PER_SAMPLE)):
        stamps[message.topic].append(header_stamp_ns(message.cdr))
    return stamps


def _prbs_excitation(args) -> dict:
    """Open loop (sec. 6.5.1-6.5.4): a PRBS of +-amplitude about the hover setting on each thruster
    (:func:`seapup_runs.identification_experiment.prbs_schedule`): the run spec, the nodes' arguments and
    what the record says of it."""
    from seapup_runs.identification_experiment import experiment_spec, prbs_schedule
    schedule = prbs_schedule(args.vehicle, args.duration, args.clock, args.amplitude)
    return {"excitation": "prbs", "clock": args.clock, "amplitude_deg": args.amplitude,
            "switches": schedule["switches"],
            "description": f"open loop, PRBS +-{args.amplitude:g} deg about hover, clock {args.clock} samples",
            "arguments": {"times": str(schedule["times"]), "pitches": str(schedule["pitches"])},
            "spec": experiment_spec(**_plant(args), schedule=schedule)}


def _plant(args) -> dict:
    return {"vehicle": args.vehicle, "dynamics": args.dynamics, "seed": args.seed, "current": args.current,
            "sensors": args.sensors, "duration": args.duration}


def _closed_loop_excitation(args, out: Path, text) -> dict:
    """Closed loop (sec. 6.5.5): the fixed-gain self-tested controller following a square wave."""
    import yaml

    from seapup_runs.identification_experiment import experiment_spec, square_wave
    try:
        rows = [[float(v) for v in row.split(",")] for row in args.references.split(";")]
    except ValueError:
        rows = []
    if len(rows) != 2 or any(len(row) != 4 or not all(map(math.isfinite, row)) for row in rows):
        raise ValueError(f"--references needs two rows of four finite values 'u,v,w,r;u,v,w,r' "
                         f"(m/s and deg/s), got {args.references!r}")
    if not (math.isfinite(args.half_period) and args.half_period > 0):
        raise ValueError(f"--half-period must be > 0 s, got {args.half_period}")
    levels = [row[:3] + [math.radians(row[3])] for row in rows]
    wave = square_wave(levels, args.half_period, args.duration)   # bounded before the self-test is flown
    controller = Path(args.controller) if args.controller else None
    if controller is None:
        from seapup_runs.self_test_flight import fly_self_test
        from seapup_control.self_test import result_document
        print("ident experiment: self-testing the fixed-gain controller at 0 m/s (in process, sec. 5.3)", file=text)
        run = fly_self_test(args.vehicle, {"operating_points": [0.0]}, progress=lambda f: progress("self-test", f))
        if run.test.phase.value != "done":
            raise ValueError(f"the self-test {run.test.phase.value}: {run.test.reason}")
        out.mkdir(parents=True, exist_ok=True)
        controller = out / "controller.yaml"
        controller.write_text(yaml.safe_dump(result_document(run.test)))
    elif not controller.is_file():
        raise ValueError(f"--controller {controller}: no such file")
    references = [v for level in levels for v in level]
    return {"excitation": "closed_loop", "controller_file": str(controller), "half_period": args.half_period,
            "references": levels,
            "description": f"closed loop under the fixed-gain controller, square wave of half-period "
                           f"{args.half_period:g} s between {rows[0]} and {rows[1]} (u, v, w m/s, r deg/s)",
            "arguments": {"controller_file": controller, "times": str([0.0, args.half_period]),
                          "references": str(references), "period": 2 * args.half_period},
            "spec": experiment_spec(**_plant(args), controller_file=str(controller), reference=wave)}


def ident_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup ident`` (its usage line in ``./seapup help`` is generated from it)."""
    parser = argparse.ArgumentParser(prog="./seapup ident", description="``./seapup ident``: identification experiments and fits from bags or CSV files (thesis ch. 6).",
                                     epilog="Every subcommand takes --json [FILE]: its result as JSON to FILE "
                                            "(stdout without FILE; text then goes to stderr).")
    sub = parser.add_subparsers(dest="command", required=True)
    fit_p = sub.add_parser("fit", help="a model from a bag or CSV file")
    _common(fit_p)
    fit_p.add_argument("--method", choices=("ls", "els", "rpem"), default="ls")
    fit_p.add_argument("--orders", default="2,2,0", help="na,nb,nc (default 2,2,0)")
    fit_p.add_argument("--plots", help="directory for a PNG of the model's predictions against the data")
    orders_p = sub.add_parser("orders", help="loss, AIC and F per output and order (Tables 6.1, 6.2, 6.6)")
    _common(orders_p)
    orders_p.add_argument("--method", choices=("ls", "els", "rpem"), default="ls")
    orders_p.add_argument("--max-order", type=int, default=3)
    orders_p.add_argument("--risk", type=float, default=0.05, help="the F-test's risk alpha (eq. 6.18)")
    compare_p = sub.add_parser("compare", help="AIC of LS, ELS and RPEM (Tables 6.3-6.5, 6.7)")
    _common(compare_p)
    compare_p.add_argument("--order", type=int, default=2)
    compare_p.add_argument("--methods", default="ls,els,rpem", help="comma-separated (default ls,els,rpem)")
    compare_p.add_argument("--plots", help="directory for a PNG per method: data against the adapting and the "
                                           "final model (figs 6.3, 6.5-6.11, 6.13-6.14)")
    resid_p = sub.add_parser("residuals", help="whiteness of a fitted model's residuals (sec. 6.3, fig. 6.2)")
    _common(resid_p)
    resid_p.add_argument("--method", choices=("ls", "els", "rpem"), default="ls")
    resid_p.add_argument("--orders", default="2,2,0", help="na,nb,nc (default 2,2,0)")
    resid_p.add_argument("--lags", type=int, default=20, help="autocorrelation lags (default 20)")
    resid_p.add_argument("--risk", type=float, default=0.05, help="the Ljung-Box test's risk (default 0.05)")
    resid_p.add_argument("--plots", help="directory for the autocorrelation plot")
    exp_p = sub.add_parser("experiment", help="an identification experiment in SIL, recorded: open-loop PRBS "
                                              "(sec. 6.5.1-6.5.4) or closed loop (sec. 6.5.5)")
    exp_p.add_argument("--duration", type=float, default=60.0,
                       help="simulated seconds, a whole number of 0.2 s samples (default 60, sec. 6.5.1): the bag "
                            "holds t = 0 .. DURATION, DURATION / 0.2 + 1 samples")
    exp_p.add_argument("--clock", type=int, default=10, help="PRBS clock period in samples (default 10)")
    exp_p.add_argument("--amplitude", type=float, default=10.0, help="PRBS amplitude [deg] (default 10)")
    exp_p.add_argument("--closed-loop", action="store_true",
                       help="fly the fixed-gain self-tested controller on a square-wave reference (sec. 6.5.5) "
                            "instead of the open-loop PRBS")
    exp_p.add_argument("--controller", help="closed loop: a self-test result YAML (default: self-test at 0 m/s "
                                            "in process first, written to OUT/controller.yaml)")
    exp_p.add_argument("--references", default="0.2,0,0,15;0,0.1,-0.1,0",
                       help="closed loop: the square wave's two levels 'u,v,w,r;u,v,w,r' [m/s, deg/s] "
                            "(default sec. 6.5.5's)")
    exp_p.add_argument("--half-period", type=float, default=10.0, help="closed loop: half-period [s] (default 10)")
    exp_p.add_argument("--dynamics", choices=("nonlinear", "linearised"), default="nonlinear",
                       help="the plant: the nonlinear model (default) or eq. 3.2 linearised about hover (sec. 6.5.1)")
    exp_p.add_argument("--current", action="store_true", help="the Gauss-Markov current of sec. 6.5.4")
    exp_p.add_argument("--sensors", default="baseline", help="sensor profile (default baseline: Kallstrom's)")
    exp_p.add_argument("--vehicle", default="baseline")
    exp_p.add_argument("--seed", type=int, default=0)
    exp_p.add_argument("--out", help="output directory (default bags/ident_<UTC time>)")
    exp_p.add_argument("--method", choices=("ls", "els", "rpem"), default="ls", help="the online identifier's method")
    exp_p.add_argument("--orders", default="2,2,0", help="the online identifier's na,nb,nc (default 2,2,0)")
    exp_p.add_argument("--in-process", action="store_true",
                       help="fly the same experiment in this process (the record equals the graph's sample for "
                            "sample), written as OUT/run.json; no identifier runs online")
    add_json_argument(exp_p)
    return parser


def handle(args, text) -> dict:
    """The ``ident`` request ``args`` (parsed by :func:`ident_parser`) carried out; its result. Lines of progress
    go to ``text``.

    Raises
    ------
    ValueError, OSError, seapup_bringup.graph.sil.SilError
        What stops it, in one line.
    """
    handlers = {"fit": _fit, "orders": _orders, "compare": _compare, "residuals": _residuals,
                "experiment": _experiment}
    return handlers[args.command](args, text)


def identify(argv: list, text=None) -> dict:
    """``./seapup ident ARGV`` in this process (the reproduction report's identification runs): the result
    :func:`handle` gives as ``--json`` writes it (plain lists and numbers), its lines to ``text`` (default:
    dropped). Raises as :func:`handle` does, and
    ValueError for arguments the parser refuses."""
    import contextlib
    import io
    stream = io.StringIO()
    try:
        with contextlib.redirect_stderr(stream):
            args = ident_parser().parse_args([str(a) for a in argv])
    except SystemExit:   # the parser's one line (usage, then "error: ...")
        lines = stream.getvalue().strip().splitlines()
        raise ValueError(lines[-1] if lines else f"ident {' '.join(map(str, argv))}: refused") from None
    from seapup_common.jsondata import jsonable
    return jsonable(handle(args, text if text is not None else io.StringIO()))   # as --json writes it
