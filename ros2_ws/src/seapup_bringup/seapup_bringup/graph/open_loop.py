"""``./seapup open-loop``: fly the Seapup open-loop through the ROS graph.

The thesis's open-loop manoeuvres (Table 3.2 style) with the full plant, as
separate processes on a private ROS domain in the SIL harness
(:class:`seapup_bringup.graph.sil.SilGraph`): the ``simulator`` (seapup_sim) in
lockstep with a Gauss-Markov current and the baseline sensors, ending at the
flight's duration, ``open_loop`` (seapup_control) answering every sample with
a blade-pitch schedule -- hover (eq. 5.2), surge (both mains +35 deg), sway
(vectored push-pull), hover -- and the harness's ``recorder`` writing
commands, truth, sensors and diagnostics into a rosbag2/MCAP bag, which the
command reads back and summarises per manoeuvre, checking that every message
the simulator counted is in it.
"""
from __future__ import annotations

import argparse
import math
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message

from seapup_bringup.output import add_json_argument, emit_json, progress, text_stream
from seapup_common import frames
from seapup_common.bag import read_bag
from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_common.ros.messages import stamp_to_ns
from seapup_common.topics import APPLIED, CLOCK, COMMAND, DEPTH, DIAGNOSTICS, IMU, TRUTH_ODOMETRY, VELOCITY, typed
from seapup_sim.analysis import hover_blade_pitch
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config



def demo_config() -> dict:
    """The demo's graph parameters (``seapup_bringup/config/demo.yaml``)."""
    from ament_index_python.packages import get_package_share_directory
    return yaml.safe_load((Path(get_package_share_directory("seapup_bringup")) / "config" / "demo.yaml").read_text())


def manoeuvres() -> list[tuple[str, np.ndarray]]:
    """Hover (the trim of eq. 5.2), surge (Table 3.2 no. 3), sway (no. 4a), hover [rad]."""
    hover = hover_blade_pitch(VehicleModel(load_vehicle_config(demo_config()["simulator"]["vehicle"])))
    lim = BLADE_PITCH_LIMIT
    return [("hover", hover), ("surge", np.array([lim, lim, 0.0, 0.0])),
            ("sway", np.array([0.0, 0.0, lim, -lim])), ("hover", hover)]


#: What the demo records: (topic, published by the simulator once per sample); types from TOPIC_TYPES.
RECORDED = [(CLOCK, False), (COMMAND, False), (APPLIED, True), (TRUTH_ODOMETRY, True), (VELOCITY, True), (IMU, True),
            (DEPTH, True), (DIAGNOSTICS, False)]
TOPICS = [t for t, _ in RECORDED]


def schedule_times(duration: float, plan) -> list[float]:
    """Switching times [s]: the manoeuvres share the flight equally."""
    return [round(k * duration / len(plan), 6) for k in range(len(plan))]


def schedule_args(duration: float, plan) -> list[str]:
    """The ``open_loop`` node's ``-p`` arguments for ``plan`` flown over ``duration`` (lockstep)."""
    pitches = [float(x) for _, row in plan for x in row]
    return ["-p", "lockstep:=true", "-p", f"times:={schedule_times(duration, plan)}", "-p", f"pitches:={pitches}"]


def graph_document(duration: float, plan) -> dict:
    """The open-loop graph (launch-file format): the simulator with ``config/demo.yaml``'s parameters, in
    lockstep, ending at ``duration``, and ``open_loop`` holding ``plan``. Each first message waits for
    every reader of it (the launcher's lockstep roster: the harness's recorder and probe are its extra
    listeners) -- nothing published is missed by the bag."""
    simulator = {**demo_config()["simulator"], "mode": "lockstep", "end_time": float(duration)}
    pitches = [float(x) for _, row in plan for x in row]
    schedule = {"lockstep": True, "times": schedule_times(duration, plan), "pitches": pitches}
    from seapup_common.launch_format import launch_document
    return launch_document([{"package": "seapup_sim", "executable": "simulator", "required": True,
                             "parameters": [simulator]},
                            {"package": "seapup_control", "executable": "open_loop", "required": True,
                             "parameters": [schedule]}])


def _simulator_status(diags: list) -> dict:
    for d in reversed(diags):
        for st in d.status:
            if st.name == "seapup/simulator":
                return {"message": st.message, **{kv.key: kv.value for kv in st.values}}
    return {}


def _fly(args, out: Path, bag_dir: Path, plan, text) -> dict | None:
    """Fly ``args.duration`` simulated seconds through the graph in the SIL harness, recorded; the run's
    numbers, or None if the graph failed (the reason printed)."""
    from seapup_bringup.graph.graph_runner import GraphSpec, fly_graph
    from seapup_bringup.graph.sil import SilError

    graph = out / "graph.launch.yaml"
    graph.write_text(yaml.safe_dump(graph_document(args.duration, plan), sort_keys=False))
    steady = {"real_time_factor_measured", "control_steps_per_wall_second"}

    def counters(diags) -> dict:
        return {k: v for k, v in _simulator_status(diags).items() if k not in steady}

    def flight(sil) -> dict | None:
        wall0 = time.monotonic()
        flown = sil.spin_until(lambda: progress("flying", sil.t / args.duration) or sil.t >= args.duration - 1e-6,
                               600.0)
        wall = time.monotonic() - wall0
        if not flown:
            print(f"seapup open-loop: the graph stopped at {sil.t:.1f} s; see the logs in {out}", file=text)
            return None
        # the simulator holds at its end: two successive reports with the same counters, nothing in flight
        seen = len(sil.log["diagnostics"])
        sil.spin_until(lambda: len(sil.log["diagnostics"]) >= seen + 3
                       and counters(sil.log["diagnostics"][-1:]) == counters(sil.log["diagnostics"][-2:-1]), 10.0)
        return {"final": _simulator_status(sil.log["diagnostics"]), "sim_seconds": sil.t, "wall": wall}
    try:
        flown = fly_graph(GraphSpec("open-loop run", graph, record=tuple(typed(*TOPICS)),
                                    banner="seapup open-loop: ROS domain {domain} (loopback only), output in {out}"),
                          out, flight, logs=False, text=text)
    except SilError as exc:
        print(f"seapup open-loop: {exc}", file=text)
        return None
    if flown.outcome is None:
        return None
    final, sim_seconds, wall, bag_written = (flown.outcome["final"], flown.outcome["sim_seconds"],
                                             flown.outcome["wall"], flown.bag)
    if bag_written != bag_dir:
        shutil.move(str(bag_written), str(bag_dir))
    per_sample = [t for t, each in RECORDED if each]
    published = {t: int(final.get("samples_published", -1)) for t in per_sample}
    # every command the simulator received, good or refused (each is in the bag too)
    published[COMMAND] = sum(int(final.get(k, -1)) for k in (
        "accepted", "rejected_invalid", "rejected_stale", "rejected_future", "rejected_malformed"))
    return {"sim_seconds": sim_seconds, "wall_seconds": wall, "published": published}


def open_loop_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup open-loop`` (its usage line in ``./seapup help`` is generated from it)."""
    parser = argparse.ArgumentParser(prog="./seapup open-loop", description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=float(demo_config()["duration"]),
                        help="simulated seconds (default from config/demo.yaml; lockstep runs faster than real time)")
    parser.add_argument("--out", type=Path, default=None, help="output directory (default runs/demo_<UTC time>)")
    parser.add_argument("--bag", type=Path, default=None, help="bag directory to create (default OUT/bag)")
    add_json_argument(parser)
    return parser


def main(argv=None) -> int:
    parser = open_loop_parser()
    args = parser.parse_args(argv)
    if not (math.isfinite(args.duration) and 4.0 <= args.duration <= 3600.0):
        parser.error(f"--duration must be between 4 and 3600 s, got {args.duration}")
    text = text_stream(args)
    out = args.out or Path("runs") / time.strftime("demo_%Y%m%d_%H%M%S", time.gmtime())
    out.mkdir(parents=True, exist_ok=True)
    bag_dir = args.bag or out / "bag"
    if bag_dir.exists():
        parser.error(f"{bag_dir} exists: a bag is never overwritten")
    plan = manoeuvres()
    flown = _fly(args, out, bag_dir, plan, text)
    if flown is None:
        return 1
    print(f"flew {flown['sim_seconds']:.1f} s of simulated time in {flown['wall_seconds']:.1f} s "
          f"({flown['sim_seconds'] / max(flown['wall_seconds'], 1e-9):.0f}x real time)", file=text)
    summary = summarise(bag_dir, args.duration, plan)
    summary.update({"bag": str(bag_dir), **flown})
    summary["missed"] = {t: n - summary["counts"].get(t, 0) for t, n in flown["published"].items()
                         if n != summary["counts"].get(t, 0)}
    print_summary(summary, text)
    emit_json(args, summary)
    return 0 if summary["segments"] and not summary["missed"] else 1


def _truth_rows(bag_dir: Path) -> tuple[np.ndarray, dict, list]:
    truth, diags, counts = [], [], {t: 0 for t in TOPICS}
    for m in read_bag(bag_dir):
        counts[m.topic] += 1
        if m.topic == TRUTH_ODOMETRY:
            o = deserialize_message(m.cdr, Odometry)
            q = o.pose.pose.orientation
            roll, pitch, _ = frames.quaternion_to_euler([q.x, q.y, q.z, q.w])
            tw = o.twist.twist
            truth.append((stamp_to_ns(o.header.stamp) * 1e-9, tw.linear.x, tw.linear.y, tw.linear.z,
                          math.degrees(roll), math.degrees(pitch), o.pose.pose.position.z))
        elif m.topic == DIAGNOSTICS:
            diags.append(deserialize_message(m.cdr, DiagnosticArray))
    return np.array(sorted(set(truth))).reshape(-1, 7), counts, diags


def summarise(bag_dir: Path, duration: float, plan) -> dict:
    """Per manoeuvre: what the vehicle did (from the recorded truth), and the simulator's counters."""
    x, counts, diags = _truth_rows(bag_dir)
    seg = duration / len(plan)
    segments = []
    for k, (name, _) in enumerate(plan):
        rows = x[(x[:, 0] >= k * seg) & (x[:, 0] < (k + 1) * seg)]
        if len(rows):
            segments.append({"manoeuvre": name, "from_s": k * seg, "u_max": rows[:, 1].max(),
                             "v_abs_max": np.abs(rows[:, 2]).max(), "w_end": rows[-1, 3],
                             "roll_abs_max_deg": np.abs(rows[:, 4]).max(), "pitch_end_deg": rows[-1, 5],
                             "depth_end": rows[-1, 6]})
    simulator = {}
    for d in reversed(diags):
        st = next((s for s in d.status if s.name == "seapup/simulator"), None)
        if st is not None:
            simulator = {"message": st.message, **{kv.key: kv.value for kv in st.values}}
            break
    return {"counts": counts, "segments": segments, "simulator": simulator}


def print_summary(summary: dict, text=sys.stdout) -> None:
    print(f"\nbag {summary['bag']}: " + ", ".join(f"{t} {n}" for t, n in summary["counts"].items()), file=text)
    if summary.get("missed"):
        print("seapup open-loop: the bag misses messages that were published: " +
              ", ".join(f"{t} {n}" for t, n in summary["missed"].items()), file=text)
    else:
        print("every published sample and command is in the bag", file=text)
    if not summary["segments"]:
        print("seapup open-loop: no vehicle data was recorded; see the logs", file=text)
        return
    print(f"\n{'manoeuvre':<8} {'from':>6} {'u max':>7} {'|v| max':>8} {'w end':>7} {'|roll| max':>10} "
          f"{'pitch end':>10} {'depth end':>10}", file=text)
    print(f"{'':<8} {'[s]':>6} {'[m/s]':>7} {'[m/s]':>8} {'[m/s]':>7} {'[deg]':>10} {'[deg]':>10} {'[m]':>10}",
          file=text)
    for r in summary["segments"]:
        print(f"{r['manoeuvre']:<8} {r['from_s']:6.1f} {r['u_max']:7.3f} {r['v_abs_max']:8.3f} "
              f"{r['w_end']:7.3f} {r['roll_abs_max_deg']:10.1f} {r['pitch_end_deg']:10.1f} "
              f"{r['depth_end']:10.1f}", file=text)
    counts = summary["simulator"]
    if counts:
        rejected = sum(int(v) for k, v in counts.items() if k.startswith("rejected"))
        print(f"\nsimulator: {counts['message']}; steps {counts.get('steps')}, commands accepted "
              f"{counts.get('accepted')}, rejected {rejected}, lockstep timeouts {counts.get('lockstep_timeouts')}",
              file=text)
    print("Thesis, no current: surge top speed 0.98 m/s with 27.4 deg bow-up; sway 0.34 m/s, "
          "max roll 24.8 deg (sec. 3.5).", file=text)


if __name__ == "__main__":
    raise SystemExit(main())
