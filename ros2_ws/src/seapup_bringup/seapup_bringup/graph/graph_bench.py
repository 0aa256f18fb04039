"""Benchmarks of the ROS graph (rclpy; used by ``./seapup bench``).

- :func:`lockstep_rate`: the simulator in lockstep with the ``open_loop``
  controller in another process; simulated seconds per wall second, measured
  on ``/clock`` from a third process (this one).
- :func:`recording_memory`: the recorder's resident memory while it records
  everything a free-running simulator publishes (real_time_factor 0, the
  simulator's full rate), in simulated time, for minutes of wall time.
- :func:`dds_round_trip`: median time for a small message to go to another
  process and back (the floor of every lockstep step: the simulator publishes
  t_k, the controller answers).
- :func:`executor_ab`: the same graphs (simulator + ``open_loop``, simulator +
  ``mfol_velocity_controller``, the round trip) under each executor of
  ``run_node`` (``$SEAPUP_EXECUTOR``), in alternating blocks of one run,
  wall rate beside each process's CPU per sample.
- :func:`hierarchy_rate`: the demo's whole graph (``hierarchy.launch.yaml``:
  simulator, navigator, four velocity controllers under the manager, the
  position and task controllers, the self-test) with the demo's recorder,
  unpaced in lockstep, the fixed-gain controller active: simulated seconds per
  wall second and the CPU of every process per sample.
"""
from __future__ import annotations

import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from seapup_common.processes import DomainLease, NodeProcess, find_executable, ros_environment
from seapup_common.ros.node import EXECUTOR_ENV, EXECUTORS, make_executor
from seapup_common.topics import CLOCK

__all__ = ["lockstep_rate", "dds_round_trip", "recording_memory", "mfol_step_us", "mfol_lockstep_rate", "view_cost",
           "executor_ab", "executor_ab_lines", "hierarchy_rate"]

#: The echo of :func:`dds_round_trip`, spun as ``run_node`` spins a node: ``spin_once`` with a timeout, on the
#: executor ``$SEAPUP_EXECUTOR`` names (both ends of the round trip use the same one).
ECHO = """
import os
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from seapup_common.ros.node import make_executor
from seapup_msgs.msg import BladePitch
rclpy.init()
node = rclpy.create_node("bench_echo")
qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
pub = node.create_publisher(BladePitch, "/bench/pong", qos)
node.create_subscription(BladePitch, "/bench/ping", pub.publish, qos)
executor = make_executor(os.environ.get("SEAPUP_EXECUTOR") or "single")
executor.add_node(node)
try:
    while rclpy.ok():
        executor.spin_once(timeout_sec=0.1)
except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
    pass
"""


def _context(domain: int):
    import rclpy
    from rclpy.context import Context
    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain)
    return ctx


def lockstep_rate(control_period: float, sim_seconds: float = 60.0, log_dir="/tmp", controller=None,
                  view: bool = False, executor: str | None = None) -> dict:
    """Simulated seconds per wall second of simulator + a controller in lockstep.

    ``controller``: the controller's command line (default: ``open_loop``
    holding the mains at 0.6 rad). Beside the wall-clock rate, each process's
    CPU time per control step (user + system, from ``/proc``): what a step
    costs whatever else the machine is doing. ``view``: with the live view
    beside the graph and a viewer (:class:`_Viewer`) subscribed to all of its
    channels (its CPU per step as ``view_cpu_us_per_step``). ``executor``: the executor every node of the graph
    runs under (``$SEAPUP_EXECUTOR``; default: as this process's environment says). ``max_gap_s``: the
    longest wall time between two samples heard on ``/clock`` (a stall shows there: the simulator's
    lockstep timeout is 5 s).
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock

    physics = min(0.1, control_period)
    with DomainLease() as lease:
        env = ros_environment(lease.domain_id)
        if executor is not None:
            env[EXECUTOR_ENV] = executor
        simulator = NodeProcess([find_executable("seapup_sim", "simulator"), "--ros-args",
                           "-p", f"control_period:={control_period}", "-p", f"physics_step:={physics}",
                           "-p", "lockstep_timeout:=5.0", "-p", "watchdog_timeout:=1000.0"],
                          env, f"{log_dir}/bench_sim.log").start()
        ctx = _context(lease.domain_id)
        node = rclpy.create_node("bench_clock", context=ctx)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        stamps = []
        node.create_subscription(Clock, CLOCK, lambda m: stamps.append((time.perf_counter(),
                                 m.clock.sec + m.clock.nanosec * 1e-9)),
                                 QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
        ctl = watcher = live = None
        try:
            if view:
                port = _free_port()
                live = NodeProcess([find_executable("seapup_live_view", "live_view"), "--ros-args", "-p",
                                    f"port:={port}"], env, f"{log_dir}/bench_view.log").start()
                watcher = _Viewer(port).start()
            deadline = time.monotonic() + 30
            while not stamps and time.monotonic() < deadline:
                ex.spin_once(timeout_sec=0.05)
            command = controller or [str(find_executable("seapup_control", "open_loop")), "--ros-args",
                                     "-p", "lockstep:=true", "-p", "pitches:=[0.6, 0.6, 0.0, 0.0]"]
            ctl = NodeProcess(command, env, f"{log_dir}/bench_ctl.log").start()
            deadline = time.monotonic() + 120 + sim_seconds / 20.0   # a graph slower than 20x real time fails
            while time.monotonic() < deadline and (not stamps or stamps[-1][1] < 1.0):
                ex.spin_once(timeout_sec=0.05)
            if watcher is not None and not watcher.receiving.wait(30.0):
                raise RuntimeError("the benchmark's viewer received nothing from the live view")
            processes = [simulator, ctl, *([live] if live is not None else [])]
            first = len(stamps) - 1
            wall0, sim0 = stamps[-1]
            cpu0 = [_cpu_s(p.popen.pid) for p in processes]
            while time.monotonic() < deadline and stamps[-1][1] - sim0 < sim_seconds:
                ex.spin_once(timeout_sec=0.05)
            wall1, sim1 = stamps[-1]
            if sim1 - sim0 < sim_seconds:
                raise TimeoutError(f"the lockstep graph stalled at t = {sim1:.1f} s of {sim0 + sim_seconds:.1f} s")
            cpu1 = [_cpu_s(p.popen.pid) for p in processes]
        finally:
            if watcher is not None:
                watcher.stop()
            if live is not None:
                live.stop()
            if ctl is not None:
                ctl.stop()
            simulator.stop()
            ex.shutdown()
            node.destroy_node()
            ctx.try_shutdown()
    steps = (sim1 - sim0) / control_period
    out = {"rtf": (sim1 - sim0) / (wall1 - wall0), "steps_per_s": steps / (wall1 - wall0),
           "us_per_step": 1e6 * (wall1 - wall0) / steps, "control_period": control_period,
           "simulator_cpu_us_per_step": 1e6 * (cpu1[0] - cpu0[0]) / steps,
           "controller_cpu_us_per_step": 1e6 * (cpu1[1] - cpu0[1]) / steps,
           "max_gap_s": float(np.diff([w for w, _ in stamps[first:]]).max()), "samples": int(round(steps)),
           "executor": executor or os.environ.get(EXECUTOR_ENV) or "default"}
    if view:
        out["view_cpu_us_per_step"] = 1e6 * (cpu1[2] - cpu0[2]) / steps
    return out


def view_cost(blocks: int = 3, sim_seconds: float = 60.0, log_dir="/tmp") -> dict:
    """The live view's cost to a lockstep graph at 5 Hz: simulator + ``open_loop`` without and with the view
    (and a viewer subscribed to everything), in alternating blocks, the best of each; ``ratio`` = with / without
    (issue 27's target: >= 0.8)."""
    runs = {"without": [], "with": []}
    for _ in range(blocks):
        runs["without"].append(lockstep_rate(0.2, sim_seconds, log_dir))
        runs["with"].append(lockstep_rate(0.2, sim_seconds, log_dir, view=True))
    best = {key: max(values, key=lambda r: r["rtf"]) for key, values in runs.items()}
    return {"without": best["without"], "with": best["with"], "ratio": best["with"]["rtf"] / best["without"]["rtf"],
            "blocks": blocks}


def _free_port() -> int:
    import socket
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class _Viewer:
    """A Foxglove WebSocket client on a thread that subscribes to every channel the view advertises and reads
    everything (what a viewer makes the view do), for :func:`view_cost`."""

    def __init__(self, port: int):
        import threading
        self.port, self.frames = port, 0
        self.receiving = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self) -> "_Viewer":
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(5.0)

    def _run(self) -> None:
        import asyncio
        asyncio.run(self._watch())

    async def _watch(self) -> None:
        import asyncio
        import json
        from tornado.websocket import websocket_connect
        connection = None
        while connection is None and not self._stop.is_set():
            try:
                connection = await websocket_connect(f"ws://127.0.0.1:{self.port}", subprotocols=["foxglove.sdk.v1"])
            except OSError:
                await asyncio.sleep(0.2)
        subscribed = 0
        while connection is not None and not self._stop.is_set():
            try:
                frame = await asyncio.wait_for(connection.read_message(), 0.2)
            except asyncio.TimeoutError:
                continue
            if frame is None:
                break
            if isinstance(frame, str):
                op = json.loads(frame)
                if op.get("op") == "advertise":
                    subs = [{"id": subscribed + i, "channelId": c["id"]} for i, c in enumerate(op["channels"])]
                    subscribed += len(subs)
                    connection.write_message(json.dumps({"op": "subscribe", "subscriptions": subs}))
            elif frame[0] == 0x01:
                self.frames += 1
                self.receiving.set()
        if connection is not None:
            connection.close()


def dds_round_trip(n: int = 2000, log_dir="/tmp", executor: str | None = None) -> dict:
    """Round trip of a BladePitch to another process and back [us]; both ends spun by ``executor`` (one of
    ``EXECUTORS``; default ``$SEAPUP_EXECUTOR``, else ``single``) in ``spin_once`` steps, as ``run_node`` does."""
    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from seapup_msgs.msg import BladePitch

    executor = executor or os.environ.get(EXECUTOR_ENV) or "single"
    with DomainLease() as lease:
        env = ros_environment(lease.domain_id)
        env[EXECUTOR_ENV] = executor
        echo = NodeProcess([sys.executable, "-c", ECHO], env, f"{log_dir}/bench_echo.log").start()
        ctx = _context(lease.domain_id)
        node = rclpy.create_node("bench_ping", context=ctx)
        ex = make_executor(executor, context=ctx)
        ex.add_node(node)
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        pub = node.create_publisher(BladePitch, "/bench/ping", qos)
        echoed = set()   # the pings (by stamp) whose echo came back
        node.create_subscription(BladePitch, "/bench/pong", lambda m: echoed.add(m.header.stamp.sec), qos)
        try:
            deadline = time.monotonic() + 30
            while (pub.get_subscription_count() == 0 or node.count_publishers("/bench/pong") == 0) \
                    and time.monotonic() < deadline:
                ex.spin_once(timeout_sec=0.05)
            samples = []
            cpu0 = _cpu_s(echo.popen.pid)
            if echo.popen.poll() is not None:
                raise RuntimeError(f"the echo process ended: {echo.log_text()[-400:]}")
            for k in range(n + 50):
                msg = BladePitch()
                msg.header.stamp.sec = k
                t0 = sent = time.perf_counter()
                pub.publish(msg)
                while k not in echoed:
                    ex.spin_once(timeout_sec=0.1)
                    now = time.perf_counter()
                    # the 50 warm-up pings are said again every 0.5 s for up to 30 s: an echo whose writer had
                    # not yet matched this reader (discovery is seen from each side in its own time) sent its
                    # first pongs to nobody; a ping that is timed waits 5 s once
                    if k < 50 and now - sent > 0.5 and now - t0 < 30:
                        pub.publish(msg)
                        sent = now
                    elif now - t0 > (30 if k < 50 else 5):
                        raise TimeoutError(f"no echo of ping {k} within {30 if k < 50 else 5} s")
                if k >= 50:
                    samples.append(time.perf_counter() - t0)
            cpu = _cpu_s(echo.popen.pid) - cpu0
        finally:
            echo.stop()
            ex.shutdown()
            node.destroy_node()
            ctx.try_shutdown()
    s = np.array(samples) * 1e6
    return {"median_us": float(np.median(s)), "p99_us": float(np.percentile(s, 99)), "n": n,
            "echo_cpu_us_per_trip": 1e6 * cpu / (n + 50), "executor": executor}


def _cpu_s(pid: int) -> float:
    """User + system CPU time of a process so far [s] (Linux /proc)."""
    fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _rss_mb(pid: int) -> float:
    """Resident set size of a process [MiB] (Linux /proc)."""
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    raise OSError(f"no VmRSS for process {pid}")


def recording_memory(minutes: float = 10.0, period: float = 5.0, log_dir="/tmp", progress=None) -> dict:
    """Record ``--all`` from a free-running simulator for ``minutes`` of wall time; sample the recorder's RSS.

    Returns the RSS samples, the slope of a straight line through them after
    the first minute [MiB/min] (flat memory: ~0), the messages and bytes
    written and their rates. The bag goes to a temporary directory and is
    deleted afterwards.
    """
    import shutil
    import tempfile

    from seapup_common.bag import bag_info
    tmp = Path(tempfile.mkdtemp(prefix="seapup_bench_bag_"))
    bag_dir = tmp / "bag"
    samples = []
    with DomainLease() as lease:
        env = ros_environment(lease.domain_id)
        rec = NodeProcess([find_executable("seapup_common", "recorder"), "--ros-args", "-p", f"bag_path:={bag_dir}",
                           "-p", "all:=true", "-p", "use_sim_time:=true"], env, f"{log_dir}/bench_rec.log").start()
        simulator = NodeProcess([find_executable("seapup_sim", "simulator"), "--ros-args", "-p", "mode:=realtime",
                           "-p", "real_time_factor:=0.0", "-p", "watchdog_timeout:=1000.0",
                           "-p", "environment.current.enabled:=true"], env, f"{log_dir}/bench_sim.log").start()
        try:
            t0 = time.monotonic()
            while (elapsed := time.monotonic() - t0) < minutes * 60.0:
                if not (rec.running and simulator.running):
                    raise RuntimeError(f"a node died during the recording benchmark; see {log_dir}/bench_*.log")
                samples.append((elapsed, _rss_mb(rec.popen.pid)))
                if progress:
                    progress("recording", elapsed / (minutes * 60.0))
                time.sleep(min(period, max(minutes * 60.0 - elapsed, 0.0)) or 0.01)
            samples.append((time.monotonic() - t0, _rss_mb(rec.popen.pid)))
            wall = samples[-1][0]
        finally:
            simulator.stop()
            rec.stop()
        info = bag_info(bag_dir)
    shutil.rmtree(tmp, ignore_errors=True)
    t, rss = np.array(samples).T
    later = t >= min(60.0, t[-1] / 2)
    slope = float(np.polyfit(t[later] / 60.0, rss[later], 1)[0]) if later.sum() >= 2 else float("nan")
    return {"wall_s": wall, "sim_s": info["duration_s"], "messages": info["messages"],
            "messages_per_s": info["messages"] / wall, "bag_mb": info["bag_size_bytes"] / 2**20,
            "mb_per_s": info["bag_size_bytes"] / 2**20 / wall, "topics": len(info["topics"]),
            "rss_mb_start": float(rss[0]), "rss_mb_after_1min": float(rss[later][0]),
            "rss_mb_max": float(rss.max()), "rss_mb_end": float(rss[-1]), "rss_slope_mb_per_min": slope,
            "rss_samples": [[float(a), float(b)] for a, b in samples]}


def _controller_file(directory: Path, control_period: float) -> Path:
    """A controller file from a self-test flown in process (noise-free, zero speed)."""
    import yaml

    from seapup_runs.self_test_flight import fly_self_test
    from seapup_control.self_test import result_document
    run = fly_self_test("baseline", {"sample_period": control_period})
    path = directory / f"bench_controller_{int(round(1 / control_period))}hz.yaml"
    path.write_text(yaml.safe_dump(result_document(run.test), sort_keys=False))
    return path


def mfol_step_us(n: int = 20000) -> dict:
    """Cost of one sample of the MFOL law (scheduled over 0 and 0.7 m/s), measurement to command [us]."""
    from seapup_runs.self_test_flight import fly_self_test
    from seapup_common.contract import Command, Measurement, Reference
    from seapup_common.controllers import ControllerSpec, create_controller
    from seapup_control.self_test import result_document
    run = fly_self_test("baseline", {"operating_points": [0.0, 0.7]})
    controller = create_controller(ControllerSpec("mfol", {"schedule": True}, document=result_document(run.test)))
    controller.reset(Command(np.zeros(4)))
    measurement = Measurement.build(0.0, velocity=(0.35, 0.01, 0.0), rates=(0.0, 0.0, 0.01))
    reference = Reference([0.4, 0.0, 0.0, 0.0])
    t0 = time.perf_counter()
    for k in range(n):
        controller.update(k * 0.2, measurement, reference)
    law = (time.perf_counter() - t0) / n
    t0 = time.perf_counter()
    for k in range(n):
        controller.update(k * 0.2, Measurement.build(k * 0.2, velocity=(0.35, 0.01, 0.0), rates=(0.0, 0.0, 0.01)),
                          Reference([0.4, 0.0, 0.0, 0.0]))
    with_contract = (time.perf_counter() - t0) / n
    return {"law_us": law * 1e6, "with_measurement_and_reference_us": with_contract * 1e6, "n": n}


def _mfol_command(path: Path) -> list[str]:
    return [str(find_executable("seapup_control", "mfol_velocity_controller")), "--ros-args",
            "-p", f"controller_file:={path}", "-p", "autostart:=true"]


def mfol_lockstep_rate(control_period: float, sim_seconds: float, log_dir="/tmp", executor: str | None = None) -> dict:
    """SimulatorCore + mfol_velocity_controller (self-tested gains, autostart) in lockstep."""
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        path = _controller_file(Path(tmp), control_period)
        return lockstep_rate(control_period, sim_seconds, log_dir, controller=_mfol_command(path), executor=executor)


def executor_ab(sim_seconds: float = 60.0, blocks: int = 2, executors=EXECUTORS, round_trips: int = 2000,
                log_dir="/tmp") -> dict:
    """Each executor of ``run_node`` on the same graphs in one run: simulator + ``open_loop`` and simulator +
    ``mfol_velocity_controller`` in lockstep at 5 Hz, and the DDS round trip; the executors alternate in
    ``blocks`` (A B A B: a load that comes and goes on a shared machine falls on both), the best block of each
    kept (the least disturbed). Per graph and executor: x real time, wall us per sample, each process's CPU us
    per sample, the longest wall gap between two samples; and ``lockstep_over_round_trip``, the open-loop
    graph's wall time per sample over the same executor's round-trip median (issue 43's target: <= 2)."""
    import tempfile
    out: dict = {"open_loop_5hz": {}, "mfol_5hz": {}, "round_trip": {}, "blocks": blocks, "sim_seconds": sim_seconds}
    runs: dict = {key: {e: [] for e in executors} for key in ("open_loop_5hz", "mfol_5hz", "round_trip")}
    with tempfile.TemporaryDirectory() as tmp:
        path = _controller_file(Path(tmp), 0.2)
        for _ in range(blocks):
            for name in executors:
                runs["open_loop_5hz"][name].append(lockstep_rate(0.2, sim_seconds, log_dir, executor=name))
                runs["mfol_5hz"][name].append(lockstep_rate(0.2, sim_seconds, log_dir, controller=_mfol_command(path),
                                                            executor=name))
                runs["round_trip"][name].append(dds_round_trip(round_trips, log_dir, executor=name))
    for key in ("open_loop_5hz", "mfol_5hz"):
        for name, values in runs[key].items():
            out[key][name] = max(values, key=lambda r: r["rtf"])
    for name, values in runs["round_trip"].items():
        out["round_trip"][name] = min(values, key=lambda r: r["median_us"])
        out["open_loop_5hz"][name]["lockstep_over_round_trip"] = \
            out["open_loop_5hz"][name]["us_per_step"] / out["round_trip"][name]["median_us"]
    return out


#: Sec. 7.7: the extra PDP-11/73 time per 60 s simulated, fixed-gain : explicit : implicit [s]
THESIS_EXTRA_S = {"fixed": 35.0, "explicit": 88.0, "gmv": 133.0}


def _law_specs(document: dict) -> dict:
    from seapup_common.controllers import ControllerSpec
    return {"fixed": ControllerSpec("mfol", {"schedule": False}, document=document),
            "scheduled": ControllerSpec("mfol", {"schedule": True}, document=document),
            "explicit": ControllerSpec("explicit", {}, document=document),
            "gmv": ControllerSpec("gmv", {}, document=document)}


def law_step_costs(repeats: int = 10) -> dict:
    """Sec. 7.7's computing cost: each law's wall and CPU microseconds per control step, and their ratios to the
    fixed-gain law beside the thesis's 35 : 88 : 133.

    Each law is flown in closed loop on the ``square-inspection`` case (5 Hz, Kallstrom's instruments), so an
    adaptive law estimates and redesigns as it does in flight; only its own calls (``applied`` and
    ``update``) are timed, ``repeats`` runs each."""
    from seapup_runs import runner
    from seapup_runs.campaign import run_log
    from seapup_runs.scenarios import scenario_spec

    spec = runner.design(scenario_spec("square-inspection"))
    out = {}
    for name, law in _law_specs(spec.controller.document).items():
        timer = _CallTimer()
        with run_log() as lines:  # a self-tuner's jacket lines: counted, not printed over the benchmark's text
            for _ in range(repeats):
                runner.run(replace(spec, controller=law), wrap=timer.wrap)
        out[name] = {"wall_us": 1e6 * timer.wall / timer.steps, "cpu_us": 1e6 * timer.cpu / timer.steps,
                     "steps": timer.steps, "log_lines": len(lines)}
    base = out["fixed"]["cpu_us"]
    for name, value in out.items():
        value["cpu_ratio_to_fixed"] = value["cpu_us"] / base
        if name in THESIS_EXTRA_S:
            value["thesis_ratio_to_fixed"] = THESIS_EXTRA_S[name] / THESIS_EXTRA_S["fixed"]
    return out


class _CallTimer:
    """Wraps a controller so that its ``applied`` and ``update`` calls are timed (wall and CPU)."""

    def __init__(self):
        self.wall = self.cpu = 0.0
        self.steps = 0

    def wrap(self, controller):
        timer = self

        class Timed:
            def __getattr__(self, name):
                return getattr(controller, name)

            def applied(self, t, command):
                w, c = time.perf_counter(), time.process_time()
                controller.applied(t, command)
                timer.wall += time.perf_counter() - w
                timer.cpu += time.process_time() - c

            def update(self, t, measurement, reference):
                w, c = time.perf_counter(), time.process_time()
                command = controller.update(t, measurement, reference)
                timer.wall += time.perf_counter() - w
                timer.cpu += time.process_time() - c
                timer.steps += 1
                return command
        return Timed()


def law_lockstep_rate(law: str, control_period: float = 0.2, sim_seconds: float = 60.0, log_dir="/tmp") -> dict:
    """SimulatorCore + the generic velocity_controller flying ``law`` (self-tested gains, autostart) in lockstep."""
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        path = _controller_file(Path(tmp), control_period)
        command = [str(find_executable("seapup_control", "velocity_controller")), "--ros-args",
                   "-p", f"controller_type:={law}", "-p", f"controller_file:={path}", "-p", "autostart:=true"]
        return lockstep_rate(control_period, sim_seconds, log_dir, controller=command)


def executor_ab_lines(ab: dict) -> list[str]:
    """The lines ``./seapup bench`` prints for :func:`executor_ab`'s result: one per graph and executor."""
    lines = []
    for key, label in (("open_loop_5hz", "simulator + open_loop, 5 Hz"), ("mfol_5hz", "simulator + mfol, 5 Hz")):
        for name, g in ab[key].items():
            ratio = g.get("lockstep_over_round_trip")
            lines.append(f"executor {name:6s} {label}: {g['rtf']:.0f}x real time, {g['us_per_step']:.0f} us per sample "
                         f"wall; CPU per sample: simulator {g['simulator_cpu_us_per_step']:.0f} us, controller "
                         f"{g['controller_cpu_us_per_step']:.0f} us; longest gap {1e3 * g['max_gap_s']:.0f} ms"
                         + (f"; {ratio:.1f} round trips per sample" if ratio is not None else ""))
    for name, rt in ab["round_trip"].items():
        lines.append(f"executor {name:6s} DDS round trip: median {rt['median_us']:.0f} us, p99 {rt['p99_us']:.0f} us; "
                     f"echo CPU {rt['echo_cpu_us_per_trip']:.0f} us per trip")
    return lines


def hierarchy_rate(sim_seconds: float = 300.0, log_dir="/tmp") -> dict:
    """The demo's hierarchy graph with its recorder, unpaced in lockstep (issue 43's target: >= 60x real time).

    The graph runs on from t_0 (``end_time`` given: not held) with ``mfol_fixed`` active and no task goal (the
    vehicle holds its start); the rate is measured from the first sample the probe hears once the graph is
    ready to the sample ``sim_seconds`` later, on the probe's clock, with each node's CPU over that span.

    Returns
    -------
    dict
        ``rtf`` (simulated / wall), ``wall_s``, ``sim_s``, ``cpu_us_per_step`` per node, ``total_cpu_us_per_step``.
    """
    import tempfile

    from seapup_bringup.graph.graph_runner import GraphSpec, fly_graph
    from seapup_bringup.graph.mission_graph import RECORDED
    control_period = 0.2
    with tempfile.TemporaryDirectory(dir=log_dir) as tmp:
        path = _controller_file(Path(tmp), control_period)
        end = 5.0 + float(sim_seconds)
        arguments = {"controller_file": str(path), "end_time": repr(end), "lockstep_timeout": "10.0"}

        def flight(sil) -> tuple:
            sil.spin_until(lambda: sil.t >= 5.0, 300.0)
            t0, wall0 = sil.t, time.monotonic()
            cpu0 = {name: _cpu_s(p.popen.pid) for name, p in sil.processes.items() if p.running}
            if not sil.spin_until(lambda: sil.t >= end - 1e-6, max(600.0, 10.0 * sim_seconds)):
                raise RuntimeError(f"the hierarchy stopped at {sil.t:.1f} s of {end:g} s")
            wall = time.monotonic() - wall0
            steps = max(1, round((sil.t - t0) / control_period))
            cpu = {name: (_cpu_s(sil.processes[name].popen.pid) - c0) / steps * 1e6 for name, c0 in cpu0.items()
                   if sil.processes[name].running}
            return wall, steps, cpu, sil.t - t0
        spec = GraphSpec("hierarchy benchmark", arguments=arguments, record=tuple(RECORDED), ready_status="")
        wall, steps, cpu, sim = fly_graph(spec, Path(tmp) / "graph", flight, logs=False).outcome
    return {"rtf": sim / wall, "wall_s": wall, "sim_s": sim, "steps": steps, "cpu_us_per_step": cpu,
            "total_cpu_us_per_step": sum(cpu.values())}
