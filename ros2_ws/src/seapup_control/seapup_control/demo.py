"""``./seapup demo``: fly a short open-loop scenario through the ROS graph.

Until the vehicle model and the autopilots land, the demo shows the graph
itself working end to end, as separate processes on a private ROS domain:
``open_loop`` (seapup_control) publishes a Table 3.2-style blade-pitch schedule
-- hover (eq. 5.2), then both main thrusters at +35 deg (surge test), then
hover -- the ``simulator`` (seapup_sim) gates it and republishes what the
thrusters apply, and ``recorder`` (seapup_ident) writes both topics and the
diagnostics into a rosbag2/MCAP bag, which the demo then reads back and
summarises.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.serialization import deserialize_message
from seapup_msgs.msg import BladePitch

from seapup_ident.bag import read_bag
from seapup_sim.node_processes import DomainLease, NodeProcess, find_executable, ros_environment

HOVER_DEG = (-3.38, -3.38, -13.10, -13.10)      # eq. 5.2
SURGE_DEG = (35.0, 35.0, -13.10, -13.10)        # Table 3.2 test 1: mains full ahead
TOPICS = ["/seapup/thrusters/command", "/seapup/thrusters/applied", "/diagnostics"]
TYPES = ["seapup_msgs/msg/BladePitch", "seapup_msgs/msg/BladePitch", "diagnostic_msgs/msg/DiagnosticArray"]


def schedule_args(duration: float) -> list[str]:
    times = [0.0, duration / 3, 2 * duration / 3]
    rows = [HOVER_DEG, SURGE_DEG, HOVER_DEG]
    pitches = [round(math.radians(d), 6) for row in rows for d in row]
    return ["-p", f"times:={times}", "-p", f"pitches:={pitches}"]


def progress(label: str, fraction: float, width: int = 30) -> None:
    """A progress bar on a terminal; a line per 10% otherwise (logs, CI)."""
    done = int(width * fraction)
    bar = f"  {label:<12} [{'#' * done}{'.' * (width - done)}] {100 * fraction:5.1f}%"
    if sys.stdout.isatty():
        sys.stdout.write("\r" + bar)
    elif int(100 * fraction) % 10 == 0 and int(100 * fraction) != getattr(progress, "last", -1):
        progress.last = int(100 * fraction)
        sys.stdout.write(bar + "\n")
    sys.stdout.flush()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="./seapup demo", description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=6.0, help="scenario length [s] (default 6)")
    parser.add_argument("--out", type=Path, default=None,
                        help="output directory (default runs/demo_<UTC time>)")
    args = parser.parse_args(argv)
    if not (math.isfinite(args.duration) and 1.0 <= args.duration <= 600.0):
        parser.error(f"--duration must be between 1 and 600 s, got {args.duration}")
    out = args.out or Path("runs") / time.strftime("demo_%Y%m%d_%H%M%S", time.gmtime())
    out.mkdir(parents=True, exist_ok=True)
    bag_dir = out / "bag"

    with DomainLease() as lease:
        env = ros_environment(lease.domain_id)
        print(f"seapup demo: ROS domain {lease.domain_id} (loopback only), output in {out}")
        procs = [
            NodeProcess([find_executable("seapup_ident", "recorder"), "--ros-args",
                         "-p", f"bag_path:={bag_dir}",
                         "-p", f"topics:={[f'{t}:{m}' for t, m in zip(TOPICS, TYPES)]}"], env,
                        out / "recorder.log", "recorder"),
            NodeProcess([find_executable("seapup_sim", "simulator"), "--ros-args",
                         "-p", "heartbeat_period:=0.5"], env, out / "simulator.log", "simulator"),
        ]
        try:
            for p in procs:
                p.start()
            deadline = time.monotonic() + 20.0
            while time.monotonic() < deadline and not ("simulator ready" in procs[1].log_text()
                                                       and "recording /diagnostics [" in procs[0].log_text()):
                time.sleep(0.05)
            source = NodeProcess([find_executable("seapup_control", "open_loop"), "--ros-args",
                                  *schedule_args(args.duration)], env, out / "open_loop.log", "open_loop")
            procs.insert(0, source.start())
            t0 = time.monotonic()
            while (elapsed := time.monotonic() - t0) < args.duration:
                progress("flying", elapsed / args.duration)
                time.sleep(0.1)
            progress("flying", 1.0)
            if sys.stdout.isatty():
                print()
        finally:
            for p in procs:  # source first, recorder last, so the bag sees everything
                p.stop()
        dead = [p.name for p in procs if p.returncode not in (0, -2)]
        if dead:
            print(f"seapup demo: {', '.join(dead)} exited abnormally; see the logs in {out}")
            return 1

    return summarise(bag_dir)


def summarise(bag_dir: Path) -> int:
    per_topic: dict[str, list] = {t: [] for t in TOPICS}
    for m in read_bag(bag_dir):
        cls = DiagnosticArray if m.topic == "/diagnostics" else BladePitch
        per_topic[m.topic].append((m.t_ns, deserialize_message(m.cdr, cls)))
    commands, applied = per_topic[TOPICS[0]], per_topic[TOPICS[1]]
    print(f"\nbag {bag_dir}: " + ", ".join(f"{t} {len(v)}" for t, v in per_topic.items()))
    if not commands or not applied:
        print("seapup demo: no commands reached the simulator; see the logs")
        return 1
    pitches = np.array([m.pitch for _, m in applied])
    print("\nblade-pitch segments applied by the simulator (deg):")
    print(f"  {'main port':>10} {'main stbd':>10} {'vect stbd':>10} {'vect port':>10}  samples")
    start = 0
    for i in range(1, len(pitches) + 1):
        if i == len(pitches) or not np.array_equal(pitches[i], pitches[start]):
            row = "".join(f"{d:>11.2f}" for d in np.degrees(pitches[start]))
            print(f" {row}  {i - start}")
            start = i
    rates = len(commands) / max((commands[-1][0] - commands[0][0]) * 1e-9, 1e-9)
    print(f"\ncommand rate {rates:.2f} Hz (5 Hz expected); {len(commands)} commands recorded, "
          f"{len(applied)} applied")
    if per_topic["/diagnostics"]:
        status = per_topic["/diagnostics"][-1][1].status[0]
        print(f"simulator diagnostics: {status.message}; "
              + ", ".join(f"{kv.key}={kv.value}" for kv in status.values))
    print("\nThe vehicle model (thesis ch. 2-3) is not in the simulator yet: "
          "this demo shows the ROS graph, command gating and recording.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
