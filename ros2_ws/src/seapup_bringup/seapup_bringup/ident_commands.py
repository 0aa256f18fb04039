"""``./seapup ident``: identification experiments and fits from bags or CSV files (thesis ch. 6).

- ``experiment``: the open-loop PRBS experiment of sec. 6.5.1-6.5.4 in SIL (graph
  ``seapup_bringup/launch/identification.yaml``: simulator in lockstep, ``open_loop`` holding a
  PRBS of +-amplitude about the hover setting on every thruster, clock 10 samples at 5 Hz, and
  the ``identifier`` node estimating online), recorded to a bag under ``bags/`` next to the
  identifier's own run bag;
- ``fit SOURCE``: a model from a bag (velocity, IMU and applied blade-pitch topics) or a CSV file,
  as JSON {"method", "orders", "A", "B", "C", "d", "loss", "aic", ...};
- ``orders SOURCE``: loss, AIC and F per output and order (Tables 6.1, 6.2, 6.6);
- ``compare SOURCE``: AIC of LS, ELS and RPEM (Tables 6.3-6.5, 6.7).

The computations are :mod:`seapup_ident.identify`; this module reads the data and prints.
"""
from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

import numpy as np

from seapup_bringup.cli import add_json_argument, emit_json, progress, text_stream
from seapup_common.blade_pitch import THRUSTER_NAMES

__all__ = ["main", "bag_data", "load_source", "OUTPUT_SETS"]

#: Output sets: ch. 6 (surge, sway, heave, yaw velocities, roll, pitch) and ch. 7 (u, v, w, r).
OUTPUT_SETS = {"ch6": ("u", "v", "w", "r", "roll", "pitch"), "ch7": ("u", "v", "w", "r")}


def bag_data(path, outputs=OUTPUT_SETS["ch6"]):
    """IdentificationData from a bag: outputs from ``/seapup/sensors/velocity`` (u, v, w, r) and
    ``/seapup/sensors/imu`` (roll, pitch), inputs the applied blade pitches, joined on the sample
    stamps. A sample missing from any topic becomes a NaN row (reported as a gap, never used)."""
    from geometry_msgs.msg import TwistWithCovarianceStamped
    from rclpy.serialization import deserialize_message
    from seapup_msgs.msg import BladePitch
    from sensor_msgs.msg import Imu

    from seapup_common.bag import read_bag
    from seapup_common.ros.messages import attitude_from_imu, stamp_to_ns, velocity_from_msg
    from seapup_ident.identify import IdentificationData

    unknown = set(outputs) - set(OUTPUT_SETS["ch6"])
    if unknown:
        raise ValueError(f"unknown output(s) {sorted(unknown)}; choose from {', '.join(OUTPUT_SETS['ch6'])}")
    kinds = {"/seapup/sensors/velocity": TwistWithCovarianceStamped, "/seapup/sensors/imu": Imu,
             "/seapup/thrusters/applied": BladePitch}
    found = {topic: {} for topic in kinds}
    for message in read_bag(path, list(kinds)):
        msg = deserialize_message(message.cdr, kinds[message.topic])
        found[message.topic][stamp_to_ns(msg.header.stamp)] = msg
    empty = [topic for topic, values in found.items() if not values and
             (topic != "/seapup/sensors/imu" or {"roll", "pitch"} & set(outputs))]
    if empty:
        raise ValueError(f"{path}: no messages on {', '.join(empty)} (record them: ./seapup ident experiment)")
    stamps = sorted(set(found["/seapup/sensors/velocity"]) | set(found["/seapup/thrusters/applied"]))
    y = np.full((len(stamps), len(outputs)), np.nan)
    u = np.full((len(stamps), 4), np.nan)
    for k, stamp in enumerate(stamps):
        row = {}
        if stamp in found["/seapup/sensors/velocity"]:
            velocity, rates = velocity_from_msg(found["/seapup/sensors/velocity"][stamp])
            if velocity.valid and rates.valid:
                row.update(zip(("u", "v", "w"), velocity.value))
                row["r"] = rates.value[2]
        if stamp in found["/seapup/sensors/imu"]:
            attitude = attitude_from_imu(found["/seapup/sensors/imu"][stamp])
            if attitude.valid:
                row.update(roll=attitude.value[0], pitch=attitude.value[1])
        y[k] = [row.get(name, math.nan) for name in outputs]
        if stamp in found["/seapup/thrusters/applied"]:
            u[k] = found["/seapup/thrusters/applied"][stamp].pitch
    return IdentificationData(y, u, np.array(stamps) * 1e-9, tuple(outputs), THRUSTER_NAMES)


def load_source(source: str, outputs: str | None, inputs: str | None, output_set: str):
    """A bag directory (metadata.yaml) or a CSV file."""
    from seapup_ident.identify import read_csv
    path = Path(source)
    if path.is_dir():
        names = tuple(outputs.split(",")) if outputs else OUTPUT_SETS[output_set]
        return bag_data(path, names)
    if path.suffix.lower() == ".csv":
        return read_csv(path, outputs.split(",") if outputs else None, inputs.split(",") if inputs else None)
    raise ValueError(f"{source}: neither a bag directory nor a .csv file")


def _forgetting(args):
    from seapup_ident.recursive import Forgetting
    if args.forgetting is not None:
        return lambda: Forgetting(args.forgetting)
    return lambda: Forgetting.schedule(args.lambda0, args.alpha)


def _common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("source", help="a bag directory or a CSV file (header: y... outputs, u... inputs, t)")
    parser.add_argument("--outputs", help="comma-separated output names (bag: u,v,w,r,roll,pitch; CSV: columns)")
    parser.add_argument("--inputs", help="CSV: comma-separated input columns (default u...)")
    parser.add_argument("--set", dest="output_set", choices=sorted(OUTPUT_SETS), default="ch6",
                        help="bag outputs: ch6 = u,v,w,r,roll,pitch (default), ch7 = u,v,w,r")
    parser.add_argument("--lambda0", type=float, default=0.6, help="eq. 6.15's lambda(0) (default 0.6)")
    parser.add_argument("--alpha", type=float, default=0.9, help="eq. 6.15's alpha (default 0.9)")
    parser.add_argument("--forgetting", type=float, help="a fixed forgetting factor instead of eq. 6.15")
    parser.add_argument("--p0", type=float, default=100.0, help="P(0) = p0 I (default 100, sec. 6.5.1)")
    parser.add_argument("--passes", type=int, default=1, help="times the record is replayed (sec. 6.5.1)")
    add_json_argument(parser)


def _fit(args, text) -> dict:
    from seapup_ident.armax import ArmaxOrders
    from seapup_ident.identify import fit, model_document
    data = load_source(args.source, args.outputs, args.inputs, args.output_set)
    na, nb, nc = (int(v) for v in args.orders.split(","))
    if args.method == "ls" and nc:
        raise ValueError("least squares has no noise model: use --orders na,nb,0 or --method els|rpem")
    result = fit(data, ArmaxOrders(data.y.shape[1], data.u.shape[1], na, nb, nc), args.method,
                 forgetting=_forgetting(args)(), p0=args.p0, passes=args.passes)
    doc = model_document(result, data, source=str(args.source))
    print(f"ident fit: {args.method} orders ({na}, {nb}, {nc}) on {result.report.usable} of "
          f"{result.report.samples} samples ({result.report.non_finite} non-finite, {result.report.gaps} gaps), "
          f"{args.passes} pass(es)", file=text)
    print(f"{'output':<10}{'loss V_N':>14}{'AIC':>12}", file=text)
    for name, v, a in zip(data.outputs, result.loss, result.aic):
        print(f"{name:<10}{v:>14.4e}{a:>12.1f}", file=text)
    if args.plots:
        doc["plots"] = [_plot_fit(data, result, Path(args.plots))]
    return doc


def _plot_fit(data, result, out: Path) -> str:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(len(data.outputs), 1, figsize=(10, 2 * len(data.outputs)), sharex=True, squeeze=False)
    for ax, i in zip(axes[:, 0], range(len(data.outputs))):
        ax.plot(data.t, data.y[:, i], lw=0.8, label="data")
        ax.plot(data.t, result.predictions[:, i], lw=0.8, label="model (one step ahead, last pass)")
        ax.set_ylabel(data.outputs[i])
    axes[0, 0].legend(), axes[-1, 0].set_xlabel("t [s]")
    fig.tight_layout()
    path = out / f"ident_fit_{result.method}.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return str(path)


def _orders(args, text) -> dict:
    from seapup_ident.identify import order_table
    data = load_source(args.source, args.outputs, args.inputs, args.output_set)
    table = order_table(data, args.max_order, args.method, alpha=args.risk, forgetting_factory=_forgetting(args),
                        p0=args.p0, passes=args.passes)
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
    return table


def _compare(args, text) -> dict:
    from seapup_ident.identify import compare_methods
    data = load_source(args.source, args.outputs, args.inputs, args.output_set)
    table = compare_methods(data, args.order, forgetting_factory=_forgetting(args), p0=args.p0, passes=args.passes)
    print(f"ident compare: AIC at order {args.order}, {args.passes} pass(es) ({len(data.t)} samples)", file=text)
    print(f"{'method':<8}" + "".join(f"{n:>12}" for n in data.outputs), file=text)
    for method, values in table["methods"].items():
        print(f"{method:<8}" + "".join(f"{v:>12.1f}" for v in values["aic"]), file=text)
    return table


def _experiment(args, text) -> dict:
    from seapup_common.topics import typed
    from seapup_control.ros.sil import SilGraph
    from seapup_ident.prbs import prbs
    from seapup_sim.analysis import hover_blade_pitch
    from seapup_sim.vehicle import VehicleModel
    from seapup_sim.vehicle_config import load_vehicle_config

    period = 0.2
    samples = int(round(args.duration / period))
    hover = hover_blade_pitch(VehicleModel(load_vehicle_config(args.vehicle)))
    signal = prbs(samples, clock=args.clock, amplitude=math.radians(args.amplitude), n_inputs=4, offset=hover)
    switches = np.flatnonzero(np.r_[True, np.any(np.diff(signal, axis=0) != 0, axis=1)])
    times = [round(float(k) * period, 6) for k in switches]
    pitches = [float(v) for k in switches for v in signal[k]]
    root = Path(os.environ.get("SEAPUP_ROOT", "."))
    out = Path(args.out) if args.out else root / "bags" / time.strftime("ident_%Y%m%d_%H%M%S", time.gmtime())
    arguments = {"times": str(times), "pitches": str(pitches), "vehicle": args.vehicle, "seed": args.seed,
                 "current": args.current, "sensors": args.sensors, "method": args.method,
                 "orders": str([int(v) for v in args.orders.split(",")]), "identifier_bag": out / "identifier"}
    record = typed("/clock", "/seapup/thrusters/command", "/seapup/thrusters/applied", "/seapup/sensors/velocity",
                   "/seapup/sensors/imu", "/seapup/sensors/depth", "/seapup/truth/odometry")
    with SilGraph("seapup_bringup identification.yaml", arguments, out_dir=out, record=record,
                  ready_status=None) as sil:
        print(f"ident experiment: PRBS +-{args.amplitude:g} deg about hover, clock {args.clock} samples, "
              f"{args.duration:g} s; ROS domain {sil.env['ROS_DOMAIN_ID']}, output in {out}", file=text)
        start = sil.t
        while sil.t < start + args.duration:
            sil.run_for(min(5.0, start + args.duration - sil.t))
            progress("experiment", (sil.t - start) / args.duration)
        bag = sil.bag
    print(f"ident experiment: bag {bag}; the identifier's run (readings used, model after each sample) in "
          f"{out / 'identifier'}", file=text)
    return {"bag": str(bag), "identifier_bag": str(out / "identifier"), "method": args.method,
            "orders": [int(v) for v in args.orders.split(",")], "duration": args.duration, "clock": args.clock, "amplitude_deg": args.amplitude,
            "current": args.current, "sensors": args.sensors, "switches": len(times)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="./seapup ident", description=__doc__.splitlines()[0],
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
    exp_p = sub.add_parser("experiment", help="the open-loop PRBS experiment in SIL, recorded (sec. 6.5.1-6.5.4)")
    exp_p.add_argument("--duration", type=float, default=60.0, help="simulated seconds (default 60, sec. 6.5.1)")
    exp_p.add_argument("--clock", type=int, default=10, help="PRBS clock period in samples (default 10)")
    exp_p.add_argument("--amplitude", type=float, default=10.0, help="PRBS amplitude [deg] (default 10)")
    exp_p.add_argument("--current", action="store_true", help="the Gauss-Markov current of sec. 6.5.4")
    exp_p.add_argument("--sensors", default="baseline", help="sensor profile (default baseline: Kallstrom's)")
    exp_p.add_argument("--vehicle", default="baseline")
    exp_p.add_argument("--seed", type=int, default=0)
    exp_p.add_argument("--out", help="output directory (default bags/ident_<UTC time>)")
    exp_p.add_argument("--method", choices=("ls", "els", "rpem"), default="ls", help="the online identifier's method")
    exp_p.add_argument("--orders", default="2,2,0", help="the online identifier's na,nb,nc (default 2,2,0)")
    add_json_argument(exp_p)
    args = parser.parse_args(argv)
    text = text_stream(args)
    handlers = {"fit": _fit, "orders": _orders, "compare": _compare, "experiment": _experiment}
    try:
        result = handlers[args.command](args, text)
    except (ValueError, OSError) as exc:
        print(f"seapup ident {args.command}: error: {exc}", file=text)
        return 1
    emit_json(args, result)
    return 0
