"""Software-in-the-loop harness: fly a graph of nodes on a private ROS domain and get the logs as arrays.

A test (or a script) describes the graph with a graph file (the format of
``./seapup launch``; default: ``seapup_bringup hierarchy.launch.yaml``, the whole
supervisory hierarchy in lockstep), then drives it with goals and service
calls; every node runs in its own process, exactly as on a vehicle::

    from seapup_bringup.sil import SilGraph

    with SilGraph(arguments={"controller_file": "ctrl.yaml"}, out_dir=tmp_path) as sil:
        result = sil.goal("goto", x=5.0, y=3.0, z=31.0, yaw=1.0)
        assert result["status"] == "succeeded"
        logs = sil.logs()          # numpy arrays: truth, estimate, references, commands
        sil.switch(activate=["mfol_scheduled"], deactivate=["mfol_fixed"])

**Paced driving.** A lockstep graph that declares
an ``end_time`` argument for its simulator (``hierarchy.launch.yaml`` does) is
*held*: the simulator stops at the first sample at or after ``start_at``
and the harness lets it run on in chunks of ``chunk`` simulated seconds,
holding it at each chunk's end (the simulator's run-time ``end_time``).
Every goal, cancel, controller switch and service call is made while the
graph is held, once every node has answered the held sample, so it takes
effect at the same sample however busy the machine is; a goal's result is
acted on at the first chunk boundary a whole chunk after the graph's own
end time (the result's ``end_time``), so when the harness hears it does not
matter either. A lockstep graph whose every node is waited for then flies
the same trajectory on a quiet and on a loaded machine
(``tests/test_hierarchy.py`` checks it with a CPU burner per core).

The harness leases a ``ROS_DOMAIN_ID`` of its own (machine-wide lock, so
parallel runs never hear each other), keeps DDS on loopback, starts each
node in its own process group (stopped with SIGINT, SIGTERM, SIGKILL at the
end, also when the test fails), optionally records topics to an MCAP bag
with the ``recorder`` node, and listens in with a probe node of its own on a
private rclpy Context. ``tests/test_sil_example.py`` is a complete example to
copy for your own velocity controller: put your node in the graph file (or
pass your own file) and register it with the controller manager.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from seapup_bringup.output import stopped_by_signal
from seapup_common import topics
from seapup_common.topics import TOPIC_TYPES

__all__ = ["SilGraph", "SilError", "TOPICS", "INSTRUMENTS"]

#: What the probe logs: name -> (topic, message type as a Python path).
TOPICS = {name: (topic, TOPIC_TYPES[topic].replace("/", ".")) for name, topic in {
    "truth": topics.TRUTH_ODOMETRY,
    "estimate": topics.NAVIGATION_ODOMETRY,
    "reference": topics.VELOCITY_REFERENCE,
    "setpoint": topics.POSITION_REFERENCE,
    "command": topics.COMMAND,
    "applied": topics.APPLIED,
    "altitude": topics.ALTITUDE,
    "velocity": topics.VELOCITY,
    "imu": topics.IMU,
    "depth": topics.DEPTH,
    "position": topics.POSITION,
    "rejections": topics.TASK_REJECTIONS,
    "diagnostics": topics.DIAGNOSTICS,
}.items()}
#: The instruments' topics, logged only when asked (``instruments=True``): a graph whose simulator waits
#: for a subscriber of one of them (the identification graphs wait for the recorder's) must not be
#: started by the probe's subscription.
INSTRUMENTS = ("velocity", "imu", "depth", "position")
#: The logged topics a graph publishes once per control sample: :meth:`SilGraph.catch_up` waits until
#: each has reached the same time.
SAMPLED = ("truth", "estimate", "reference", "setpoint", "command", "applied")
#: The instruments published at every sample (the acoustic fixes come at some samples only): caught up
#: with :data:`SAMPLED` when instruments are logged (a command heard before its sample's velocity was seen).
SAMPLED_INSTRUMENTS = ("velocity", "imu", "depth")
#: The simulator's per-sample topics: published at a sample before any node answers it, so a log that has
#: heard an answer to sample k (:data:`_ANSWERS`, stamped with the sample's stamp) must have them at k too
#: (caught up exactly, not within the slack).
_SIMULATOR_SAMPLED = ("truth", "applied") + SAMPLED_INSTRUMENTS
_ANSWERS = ("command", "estimate")

_ACTIONS = {"hover": "Hover", "goto": "Goto", "follow_seabed": "FollowSeabed"}
#: The logged topics the simulator publishes: a sample it publishes again (to a node that joined while the
#: graph was held) is logged once.
# topics whose publisher may say a sample again, to a reader that matched late: the simulator (resumed at an
# unanswered sample) and the navigator (its newest estimate)
_SAID_AGAIN = ("truth", "applied", "altitude", "velocity", "imu", "depth", "position", "estimate")


def _once_per_stamp(msgs: list) -> list:
    """The messages without repeats of the next one's stamp (the last kept: after a simulator reset, t_0
    is a new sample)."""
    out = []
    for msg in msgs:
        if out and (out[-1].header.stamp.sec, out[-1].header.stamp.nanosec) == (msg.header.stamp.sec,
                                                                                msg.header.stamp.nanosec):
            out[-1] = msg
        else:
            out.append(msg)
    return out


class SilError(RuntimeError):
    """The graph did not come up, a node died, or a goal was never answered."""


def _import(path: str):
    module, name = path.rsplit(".", 1)
    return getattr(__import__(module, fromlist=[name]), name)


class SilGraph:
    """A graph started in SIL (see the module docstring); use it as a context manager.

    Parameters
    ----------
    graph : str or Path
        ``"PACKAGE FILE"`` (a graph in the package's ``launch`` directory) or a path.
    arguments : dict
        The graph file's arguments (``name: value``).
    out_dir : Path
        Where node logs (and the bag) go.
    record : list of str, optional
        Topics the ``recorder`` writes to ``out_dir/bag`` (``/t`` or ``/t:pkg/msg/Type``). Typed ones
        are subscribed before the graph starts, so nothing of them is lost; untyped ones only once
        a publisher has told the recorder their type.
    ready_timeout : float
        Wall seconds for the first navigation estimate (a start on a loaded machine: ten-odd Python nodes
        importing rclpy beside CPU burners took most of a minute).
    start_at, chunk : float
        Paced driving (module docstring) [s simulated]: the first hold, and the run between holds.
        ``start_at`` 0: the first sample (held there by the graph's ``start_held`` argument), for a graph
        in which nobody answers a sample before the
        harness acts (the demo's: its first leg, the self-test, answers t_0).
        Used when the graph declares an ``end_time`` argument and runs in lockstep (``paced`` says
        whether it is); pass ``end_time`` in ``arguments`` to drive the graph unpaced.
    instruments : bool
        Also log the instruments (velocity, IMU, depth, position fixes: :data:`INSTRUMENTS`). Off by
        default. The probe's subscriptions, and the recorder's typed ones, are extra listeners of the graph's
        lockstep roster: the simulator's first sample and each commander's first message wait for them.
    ready_status : str or tuple of str, optional
        The graph is ready once the latest ``/diagnostics`` statuses of these names say OK
        (default ``seapup/task_controller``: it hears the navigator and a position controller
        listens to its setpoints, and ``seapup/position_controller``: active, hearing the
        navigator and matched to the setpoint publisher, so a goal is accepted and flown at once)
        and each publisher they report (``subscribers:<topic>``) has matched every subscription
        of its topic this probe sees. The simulator starts once *its* subscribers are
        there; the rest of the graph discovers itself meanwhile (in lockstep tens of simulated
        seconds can pass). "" waits only for the first estimate, None only for the first truth
        sample (a graph without a navigator). With a navigator, also until its newest estimate
        has reached every reader of ``navigation/odometry`` this probe sees (its ``/diagnostics``
        count; it says that estimate again to a reader that matches late), so no reader -- the
        recorder, a controller, the probe -- lacks the estimate of the sample the graph is held at.
    extra_nodes : list of NodeSpec
        Nodes started with the graph's own (the live view of ``./seapup demo --view``).
    """

    def __init__(self, graph="seapup_bringup hierarchy.launch.yaml", arguments: dict | None = None, *,
                 out_dir, record: list[str] | None = None, ready_timeout: float = 120.0,
                 ready_status: str | tuple[str, ...] | None = ("seapup/task_controller",
                                                                "seapup/position_controller"),
                 instruments: bool = False, start_at: float = 10.0, chunk: float = 1.0, extra_nodes=()):
        if not (math.isfinite(start_at) and start_at >= 0 and math.isfinite(chunk) and chunk > 0):
            raise ValueError(f"start_at must be finite and >= 0 s, chunk > 0 s, got {start_at!r}, {chunk!r}")
        self.start_at, self.chunk = float(start_at), float(chunk)
        self.paced = False      # set at start: the graph is held between the harness's actions
        self.held: float | None = None  # paced: the sample [s] the graph is held at
        self.late_results = 0   # paced: results heard too late to be acted on at their chunk boundary
        self.graph = str(graph)
        self.extra_nodes = list(extra_nodes)   # NodeSpecs started with the graph's own (the live view)
        self.instruments = bool(instruments)
        self.arguments = {k: (str(v).lower() if isinstance(v, bool) else str(v)) for k, v in (arguments or {}).items()}
        self.out_dir = Path(out_dir)
        self.record = list(record or [])
        self.ready_timeout = float(ready_timeout)
        self.ready_status = ready_status
        self.processes: dict = {}
        self.log: dict[str, list] = {name: [] for name in TOPICS}
        self.feedback: list = []
        self._lease = self._context = self._node = self._executor = None

    # -- start and stop --------------------------------------------------------------------------
    def __enter__(self) -> "SilGraph":
        try:
            self._start()
        except BaseException as exc:
            self.close(hurry=stopped_by_signal(exc))
            raise
        return self

    def __exit__(self, exc_type, exc, traceback) -> None:
        self.close(hurry=exc is not None and stopped_by_signal(exc))

    def _start(self) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor

        from seapup_common.processes import DomainLease, NodeProcess, find_executable, ros_environment
        from seapup_common.ros.launch_graph import command_line, find_graph, graph_arguments, load_graph

        self.out_dir.mkdir(parents=True, exist_ok=True)
        self._lease = DomainLease()
        domain = self._lease.acquire()
        self.env = ros_environment(domain)
        graph_file = find_graph(self.graph) if Path(self.graph).is_file() else find_graph(*self.graph.split())
        declared = graph_arguments(graph_file)
        self.paced = ("end_time" in declared and "end_time" not in self.arguments
                      and str(self.arguments.get("mode", declared.get("mode", "lockstep"))) == "lockstep")
        if self.paced:
            if self.start_at > 0:
                self.arguments["end_time"] = repr(self.start_at)
            elif "start_held" in declared:  # held at t_0 itself (end_time 0 means "run on")
                self.arguments["start_held"] = "true"
        specs = self._with_roster(load_graph(graph_file, self.arguments))
        self._context = Context()
        rclpy.init(context=self._context, domain_id=domain)
        self._node = rclpy.create_node("sil_probe", context=self._context)
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self._node)
        for name, (topic, kind) in TOPICS.items():
            if name in INSTRUMENTS and not self.instruments:
                continue  # a graph may use these subscriptions as its start signal (the recorder's, say)
            self._node.create_subscription(_import(kind), topic, self.log[name].append, 10000)
        if self.record:
            self.bag = self.out_dir / "bag"
            self.processes["recorder"] = NodeProcess(
                [str(find_executable("seapup_common", "recorder")), "--ros-args", "-p", f"bag_path:={self.bag}",
                 "-p", "use_sim_time:=true", "-p", f"topics:={self.record}"],
                self.env, self.out_dir / "recorder.log", "recorder").start()
            self._wait_for_recorder()
        for spec in specs:
            self.processes[spec.label] = NodeProcess(command_line(spec), self.env,
                                                     self.out_dir / f"{spec.label}.log", spec.label).start()
        names = (self.ready_status,) if isinstance(self.ready_status, str) else tuple(self.ready_status or ())
        names = tuple(name for name in names if name)
        # a graph with a navigator: its estimate has reached every reader this probe sees (whatever its level:
        # t_0 may lack an acoustic fix), so a reader that matched late -- the recorder, a controller, this
        # probe -- has the estimate of the sample the graph is held at (the navigator says its newest again)
        matched_only = () if self.ready_status is None else ("seapup/navigator",)

        def matched_all(status) -> bool:
            # a status may report its publishers' matched readers ("subscribers:<topic>": n, the writer's
            # side, which decides delivery): ready once each has matched every reader this probe sees
            return all(int(kv.value) >= self._node.count_subscribers(kv.key.split(":", 1)[1])
                       for kv in status.values if kv.key.startswith("subscribers:"))

        def latest():
            found = {}
            for array in self.log["diagnostics"][-40:]:
                for status in array.status:
                    found[status.name] = status
            return found

        def ready():
            found = latest()
            return (all(name in found and found[name].level in (0, b"\x00") and matched_all(found[name])
                        for name in names)
                    and all(name in found and matched_all(found[name]) for name in matched_only))
        # an estimate first, unless held at t_0: the navigator's first comes with its first acoustic fix,
        # which t_0 may lack (a dropout), and the graph goes on only once the harness acts
        navigation = self.ready_status is not None and not (self.paced and self.start_at == 0)
        if not self.spin_until(lambda: self.log["truth"] and (not navigation or self.log["estimate"])
                               and (self.ready_status is None or ready()), self.ready_timeout):
            found = latest()
            seen = "; ".join(f"{name}: " + (f"{found[name].message!r} (matched readers: "
                                            f"{[kv.value for kv in found[name].values if kv.key.startswith('subscribers:')]}"
                                            f" of {[self._node.count_subscribers(kv.key.split(':', 1)[1]) for kv in found[name].values if kv.key.startswith('subscribers:')]})"
                                            if name in found else "no status") for name in names + matched_only)
            raise SilError(f"no navigation estimate ({len(self.log['estimate'])} heard, {len(self.log['truth'])} "
                           f"samples) or no OK {self.ready_status!r} within {self.ready_timeout:g} s [{seen}]; "
                           f"node logs in {self.out_dir}" + self._dead())
        if self.paced:
            from rcl_interfaces.srv import SetParameters
            self._end_client = self._node.create_client(SetParameters, topics.SIMULATOR_PARAMETERS_SERVICE)
            if not self.spin_until(self._end_client.service_is_ready, self.ready_timeout):
                raise SilError("the simulator's set_parameters service is not available" + self._dead())
            if self._settle(self.start_at, self.ready_timeout) != "held":
                raise SilError(f"the graph was not held at its start ({self.start_at:g} s) within "
                               f"{self.ready_timeout:g} s; node logs in {self.out_dir}" + self._dead())

    def _with_roster(self, specs: list) -> list:
        """The graph's nodes and the extra ones with the lockstep handshake's counts filled
        (:func:`seapup_bringup.launch.with_roster`): this harness's probe and recorder are extra listeners,
        so a first sample or command waits for them as for the graph's own nodes -- the bag and the logs miss
        nothing from t_0 on."""
        from seapup_bringup.launch import with_roster
        from seapup_common.lockstep.roster import Listener
        probe = Listener("sil_probe", tuple(topic for name, (topic, _) in TOPICS.items()
                                            if self.instruments or name not in INSTRUMENTS))
        listeners = [probe] + ([Listener.recorder("recorder", self.record)] if self.record else [])
        return with_roster([*specs, *self.extra_nodes], listeners)

    def _wait_for_recorder(self, timeout: float = 30.0) -> None:
        """Before the graph starts: the recorder subscribes to every typed topic (``/t:pkg/msg/Type``) at
        once, so wait for those subscriptions -- a lockstep simulator can fly a minute in a second
        and would otherwise run ahead of the recorder's discovery."""
        own = {topic for name, (topic, _) in TOPICS.items() if self.instruments or name not in INSTRUMENTS}
        typed = [entry.split(":")[0] for entry in self.record if ":" in entry]

        recorder = self.processes["recorder"]

        def subscribed():   # or it has exited (a bag that exists already, say): say so at once
            return not recorder.running or all(self._node.count_subscribers(topic) >= 1 + (topic in own)
                                               for topic in typed)
        if typed and (not self.spin_until(subscribed, timeout) or not recorder.running):
            if not recorder.running:
                raise SilError(f"the recorder exited: {recorder.log_text().strip().splitlines()[-1:]}; "
                               f"its log is {self.out_dir / 'recorder.log'}")
            missing = [t for t in typed if self._node.count_subscribers(t) < 1 + (t in own)]
            raise SilError(f"the recorder did not subscribe to {', '.join(missing)} within {timeout:g} s; "
                           f"its log is {self.out_dir / 'recorder.log'}" + self._dead())

    def _dead(self) -> str:
        dead = [f"{name} (exit {p.returncode})" for name, p in self.processes.items() if not p.running]
        return f"; exited: {', '.join(dead)}" if dead else ""

    def close(self, hurry: bool = False) -> None:
        """Stop every node (the recorder last, so it has everything), the probe and the lease. ``hurry`` (the
        command was interrupted): the graph's nodes get SIGTERM, a prompt stop, instead of SIGINT."""
        from seapup_common.processes import stop_process_groups
        # the graph's nodes together (each takes a moment to shut down; one after another added up to seconds
        # per run), then the recorder, so it has everything
        nodes = [p for name, p in self.processes.items() if name != "recorder" and p.popen is not None]
        # interrupted (hurry): SIGTERM, and SIGKILL for what is still running a second later -- a node inside a
        # long callback (seen: 2 s) must not hold up a user's Ctrl-C
        stop_process_groups([p.popen for p in nodes], 5.0, 1.0 if hurry else 2.0, hurry=hurry)
        for process in nodes:
            process.popen.wait()
        if "recorder" in self.processes:
            self.processes["recorder"].stop(grace=10.0)
        # the probe's DDS participant must go with the graph: alive, it keeps announcing itself on a
        # domain the next lease holder reuses (seen: '/sil_probe' in a later test's node list)
        if self._executor is not None:
            self._executor.shutdown(timeout_sec=1.0)
            self._executor = None
        if self._node is not None:
            self._node.destroy_node()
            self._node = None
        if self._context is not None:
            self._context.try_shutdown()
            self._context.destroy()
            self._context = None
        if self._lease is not None:
            self._lease.release()
            self._lease = None

    def kill(self, name: str) -> None:
        """Kill one node's process at once (SIGKILL: a crash)."""
        import os
        import signal
        process = self.processes[name]
        os.killpg(process.popen.pid, signal.SIGKILL)
        process.popen.wait(5.0)

    # -- driving ---------------------------------------------------------------------------------
    def spin_until(self, predicate, timeout: float) -> bool:
        """Spin the probe until ``predicate()`` holds or ``timeout`` wall seconds pass."""
        deadline = time.monotonic() + timeout
        while not predicate() and time.monotonic() < deadline:
            self._executor.spin_once(timeout_sec=0.02)
        return bool(predicate())

    def catch_up(self, target: float | None = None, stall: float = 2.0, slack: float = 0.25) -> None:
        """Spin until every per-sample topic heard so far (:data:`SAMPLED`, and :data:`SAMPLED_INSTRUMENTS`
        when the instruments are logged) has reached ``target`` [s simulated] within ``slack`` (default
        target: the newest stamp heard on any of them), and the simulator's own topics, exactly, every
        sample a node has been heard answering (a command or an estimate).

        The probe is not waited for by the graph: on a loaded machine it takes its messages seconds of
        simulated time behind the nodes, one topic further behind than another (seen: setpoints at
        48 s, estimates at 35 s). Logs read without this would end early or disagree with each other.
        Gives up when no log has grown for ``stall`` wall seconds (the graph stopped)."""
        def last(name):
            return self._stamp(self.log[name][-1])
        sampled = SAMPLED + (SAMPLED_INSTRUMENTS if self.instruments else ())
        live = [name for name in sampled if self.log[name]]
        if not live:
            return
        if target is None:
            target = max(last(name) for name in live)
        sizes, moved = None, time.monotonic()
        answered = [last(name) for name in _ANSWERS if name in live]
        answered_to = min(target, max(answered)) if answered else -math.inf

        def behind(name):
            return last(name) < target - slack or (name in _SIMULATOR_SAMPLED and last(name) < answered_to - 1e-6)
        while any(behind(name) for name in live):
            now = [len(self.log[name]) for name in live]
            if now != sizes:
                sizes, moved = now, time.monotonic()
            elif time.monotonic() - moved > stall:
                return
            self._executor.spin_once(timeout_sec=0.02)

    @property
    def t(self) -> float:
        """Latest simulated time heard [s] (from the truth)."""
        return self.log["truth"][-1].header.stamp.sec + 1e-9 * self.log["truth"][-1].header.stamp.nanosec \
            if self.log["truth"] else 0.0

    def estimate(self) -> tuple[float, np.ndarray, np.ndarray]:
        """The latest navigation estimate: time [s], position (x, y, z odom_ned) [m], attitude (phi, theta, psi)."""
        from seapup_common import frames
        if not self.log["estimate"]:
            raise SilError("no navigation estimate heard yet")
        msg = self.log["estimate"][-1]
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        return (msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec, np.array([p.x, p.y, p.z]),
                np.asarray(frames.quaternion_to_euler([q.x, q.y, q.z, q.w]), dtype=float))

    # -- paced driving (module docstring) -------------------------------------------------------
    def _set_end(self, end_time: float) -> None:
        from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
        from rcl_interfaces.srv import SetParameters

        from seapup_common.ros.graph import ServiceNotAnswered, call_idempotent
        request = SetParameters.Request(parameters=[Parameter(name="end_time", value=ParameterValue(
            type=ParameterType.PARAMETER_DOUBLE, double_value=float(end_time)))])
        try:   # a set: asked again if its answer is lost
            answer = call_idempotent(self._executor, self._end_client, request, ready_timeout=10.0,
                                     response_timeout=4.0, attempts=3)
        except ServiceNotAnswered:
            answer = None
        if answer is None or not answer.results[0].successful:
            raise SilError(f"the simulator did not take end_time {end_time:g} s{self._dead()}")

    def _settle(self, until: float, timeout: float, done=None, stall: float = 2.0) -> str:
        """Wait until the graph is held at the first sample at or after ``until`` and every per-sample
        topic still flowing has reached it (so every node has answered it; one stopped short of it is
        waited for ``stall`` wall seconds): "held". "blocked" when ``done()`` holds and simulated time
        stopped short of ``until`` for ``stall`` wall seconds (nobody answers a sample: the graph waits
        for the driver, e.g. after a self-test with no controller active)."""
        previous = self.held if self.held is not None else 0.0

        def last(name):
            return self._stamp(self.log[name][-1])
        deadline, moved, size = time.monotonic() + timeout, time.monotonic(), len(self.log["truth"])
        while True:
            if self.t >= until - 1e-6:
                flowing = [n for n in SAMPLED if self.log[n] and last(n) >= previous - 1e-6]
                if all(last(n) >= self.t - 1e-6 for n in flowing):
                    self.held = self.t
                    return "held"
            if len(self.log["truth"]) != size:
                size, moved = len(self.log["truth"]), time.monotonic()
            elif time.monotonic() - moved > stall:
                if self.t >= until - 1e-6:  # held there, but a topic stopped short of it
                    self.held = self.t
                    return "held"
                if done is not None and done():
                    self.held = self.t
                    return "blocked"
            if time.monotonic() > deadline:
                raise SilError(f"simulated time stuck at {self.t:.1f} s (wanted {until:.1f} s){self._dead()}")
            self._executor.spin_once(timeout_sec=0.01)

    def _next_boundary(self, t: float) -> float:
        """The first chunk boundary after ``t`` by at least a whole chunk [s]."""
        return math.ceil((t + self.chunk) / self.chunk - 1e-9) * self.chunk

    def _advance(self, until: float | None, done=None, end_time=None, timeout: float = 600.0) -> str:
        """Paced: run the graph chunk by chunk and hold it at ``until``, or (``done()`` true) at the first
        chunk boundary a whole chunk after ``end_time()`` (the graph time of what ``done`` waited for);
        when the graph blocks waiting for the driver once ``done()`` holds, right there. "held" or
        "blocked"."""
        deadline = time.monotonic() + timeout
        target = None
        while True:
            if done is not None and target is None and done():
                end = end_time() if end_time is not None else None
                target = self.held if end is None else self._next_boundary(end)
                if target < self.held - 1e-6:
                    self.late_results += 1  # heard more than a chunk after its end: acted on late
                    target = self.held
            goal = target if target is not None else until
            if goal is not None and self.held >= goal - 1e-6:
                return "held"
            step = self.held + self.chunk if done is not None and target is None else math.inf
            nxt = min(goal if goal is not None else math.inf, step)
            if not math.isfinite(nxt):
                nxt = self.held + self.chunk
            self._set_end(nxt)
            if self._settle(nxt, max(1.0, deadline - time.monotonic()), done) == "blocked":
                # held right here (no lockstep time-out), however long the driver takes to act: a controller
                # activated now answers this very sample on a quiet and on a loaded machine alike (not at t_0,
                # where end_time 0 would mean "run on")
                if self.held > 0:
                    self._set_end(self.held)
                return "blocked"

    def run_for(self, seconds: float, timeout: float | None = None) -> None:
        """Let simulated time advance by ``seconds`` (paced: and hold the graph there)."""
        if self.paced:
            self._advance(self.held + seconds, timeout=timeout or max(60.0, 2 * seconds))
            return
        end = self.t + seconds
        if not self.spin_until(lambda: self.t >= end - 1e-9, timeout or max(30.0, 2 * seconds)):
            raise SilError(f"simulated time stuck at {self.t:.1f} s (wanted {end:.1f} s){self._dead()}")

    def goal(self, kind: str, *, timeout: float = 300.0, cancel_after: float | None = None,
             during: tuple | None = None, **fields) -> dict:
        """Send a task goal and wait for its end; ``{"status", "accepted", "rejection", "accepted_t", "end_t",
        <result fields>}`` (``accepted_t``, ``end_t``: simulated times at which the probe heard it accepted and
        ended -- on a loaded machine later than the graph's; the result's ``end_time`` is the graph's own).

        ``cancel_after`` [s simulated]: cancel the goal that long after it was accepted.
        ``during = (seconds, function)``: call ``function()`` once, that many simulated seconds
        after the goal was accepted (e.g. a controller switch mid-manoeuvre); its return value is
        in the result as ``during``. Rejected goals return ``accepted: False`` and the reason the
        task controller published.
        """
        from rclpy.action import ActionClient

        from seapup_common.ros.graph import send_goal

        action = _import(f"seapup_msgs.action.{_ACTIONS[kind]}")
        client = ActionClient(self._node, action, topics.task_action(kind))
        try:
            goal = action.Goal(**fields)
            if self.paced:
                self._task_controller_at_hold()
            rejections = len(self.log["rejections"])
            handle = send_goal(self._executor, client, goal, lambda fb: self.feedback.append((kind, fb.feedback)))
            if not handle.accepted:
                self.spin_until(lambda: len(self.log["rejections"]) > rejections, 5.0)
                reason = self.log["rejections"][-1].data if len(self.log["rejections"]) > rejections else ""
                return {"status": "rejected", "accepted": False, "rejection": reason}
            accepted_t = self.t
            future = handle.get_result_async()
            during_result = None
            if self.paced:
                self._paced_goal(future, handle, during, cancel_after, timeout)
                during_result = self._during_result
            else:
                if during is not None:
                    start = self.t
                    self.spin_until(lambda: self.t >= start + during[0] or future.done(), timeout)
                    during_result = during[1]()
                if cancel_after is not None:
                    start = self.t
                    self.spin_until(lambda: self.t >= start + cancel_after or future.done(), timeout)
                    if not future.done():
                        cancel = handle.cancel_goal_async()
                        self.spin_until(cancel.done, 10.0)
            if not self.spin_until(future.done, timeout):
                raise SilError(f"{kind} goal not finished within {timeout:g} s{self._dead()}")
            response = future.result()
            status = {4: "succeeded", 5: "canceled", 6: "aborted"}.get(response.status, str(response.status))
            result = response.result
            out = {name: getattr(result, name) for name in result.get_fields_and_field_types()}
            self.catch_up(out.get("end_time") or None)  # the logs hold the task's whole flight
            return {"status": status, "accepted": True, "rejection": "", "during": during_result,
                    "accepted_t": accepted_t, "end_t": self.t, **out}
        finally:
            client.destroy()

    @staticmethod
    def _end_time(future):
        """The graph time a finished action's result says it ended at (None: it does not say)."""
        if not future.done():
            return None
        end = getattr(future.result().result, "end_time", 0.0)
        return float(end) if end else None

    def _task_controller_at_hold(self, wait: float = 5.0) -> None:
        """Paced: wait until the task controller has handled the held sample's estimate (its status is stamped
        with the newest estimate it handled). Its answer is a setpoint for the *next* sample, so the graph
        does not wait for it before holding: a goal or cancel that overtook the estimate would act on the
        sample before (a goal built from the older estimate)."""
        held = self.held

        def handled():
            return any(status.name == "seapup/task_controller" and self._stamp(array) >= held - 1e-6
                       for array in self.log["diagnostics"][-40:] for status in array.status)
        self.spin_until(handled, wait)

    def _paced_goal(self, future, handle, during, cancel_after, timeout: float) -> None:
        """A task goal accepted while the graph is held: its ``during`` call and cancel made at holds, and
        the graph held again after its end (module docstring)."""
        held = self.held
        # the task controller starts its setpoint stream at the acceptance (stamped for the next sample):
        # heard here, the position controller has it too before the graph goes on
        self.spin_until(lambda: self.log["setpoint"] and self._stamp(self.log["setpoint"][-1]) > held + 1e-6, 5.0)
        if not self.log["reference"]:
            # the run's first velocity reference (the position controller's answer to the next estimate, for
            # reference_delay samples later): one sample on, held until it is heard, so a velocity controller
            # has it in time (it waits for references only once one has come)
            self._advance(held + 1e-3, timeout=timeout)
            self.spin_until(lambda: self.log["reference"], 5.0)
            self.spin_until(lambda: False, 0.5)  # heard here: on its way to the velocity controllers too
        self._during_result = None
        end = lambda: self._end_time(future)  # noqa: E731
        if during is not None:
            self._advance(held + during[0], done=future.done, end_time=end, timeout=timeout)
            self._during_result = during[1]()
        if cancel_after is not None:
            self._advance(held + cancel_after, done=future.done, end_time=end, timeout=timeout)
            if not future.done():
                self._task_controller_at_hold()
                cancel = handle.cancel_goal_async()
                self.spin_until(cancel.done, 10.0)
        self._advance(None, done=future.done, end_time=end, timeout=timeout)

    @staticmethod
    def _stamp(msg) -> float:
        return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec

    def _refusal_reason(self, wait: float = 2.0) -> str:
        """``": <why>"`` from the newest "goal refused: ..." line a node logged (its log files), or ""."""
        import re
        deadline = time.monotonic() + wait  # the node's log line may land a moment after its answer
        while True:
            found = []
            for process in self.processes.values():
                found += re.findall(r"goal refused: (.*)", process.log_text())
            if found or time.monotonic() >= deadline:
                return f": {found[-1].strip()}" if found else ""
            time.sleep(0.1)

    def action(self, name: str, action_type: str, fields: dict | None = None, timeout: float = 600.0,
               feedback=None, ready_timeout: float = 30.0):
        """Send a goal (``action_type`` like ``seapup_msgs/action/SelfTest``, its fields) to action server
        ``name`` and wait for the end; the result message. ``feedback(msg)`` is called with each
        feedback message; ``ready_timeout`` [s wall] is how long the server may take to appear."""
        from rclpy.action import ActionClient

        from seapup_common.ros.graph import GoalNotAnswered, send_goal
        package, _, kind_name = action_type.split("/")
        kind = _import(f"{package}.action.{kind_name}")
        client = ActionClient(self._node, kind, name)
        try:
            try:
                handle = send_goal(self._executor, client, kind.Goal(**(fields or {})),
                                   (lambda msg: feedback(msg.feedback)) if feedback else None,
                                   ready_timeout=ready_timeout)
            except GoalNotAnswered as exc:
                raise SilError(f"{exc}{self._dead()}") from None
            if not handle.accepted:
                raise SilError(f"{name} refused the goal" + self._refusal_reason())
            future = handle.get_result_async()
            if self.paced:
                self._advance(None, done=future.done, end_time=lambda: self._end_time(future), timeout=timeout)
            if not self.spin_until(future.done, timeout):
                raise SilError(f"{name} did not finish within {timeout:g} s{self._dead()}")
            return future.result().result
        finally:
            client.destroy()

    def call(self, service: str, srv_type: str, fields: dict | None = None, timeout: float = 10.0):
        """Call a service (``srv_type`` like ``seapup_msgs/srv/SwitchController``); the response."""
        package, _, name = srv_type.split("/")
        kind = _import(f"{package}.srv.{name}")
        client = self._node.create_client(kind, service)
        try:
            if not self.spin_until(client.service_is_ready, timeout):
                raise SilError(f"service {service} not available{self._dead()}")
            future = client.call_async(kind.Request(**(fields or {})))
            if not self.spin_until(future.done, timeout):
                raise SilError(f"service {service} did not answer within {timeout:g} s")
            return future.result()
        finally:
            self._node.destroy_client(client)

    def switch(self, activate=(), deactivate=(), strict: bool = True, timeout: float = 10.0):
        """The controller manager's switch_controller; the response (``ok``, ``message``)."""
        return self.call(topics.SWITCH_CONTROLLER_SERVICE, "seapup_msgs/srv/SwitchController",
                         {"activate_controllers": list(activate), "deactivate_controllers": list(deactivate),
                          "strictness": 2 if strict else 1, "timeout": float(timeout)}, timeout=timeout + 5.0)

    # -- logs ------------------------------------------------------------------------------------
    def logs(self) -> dict[str, np.ndarray]:
        """Everything heard so far as arrays (times in s, SI units, NED/FRD).

        ``truth_t``, ``truth_position`` (N, 3), ``truth_attitude`` (N, 3), ``truth_velocity`` (N, 6);
        ``estimate_t``, ``estimate_position``, ``estimate_horizontal_std`` [m]; ``reference_t``, ``reference`` (N, 4: u, v, w, r);
        ``command_t``, ``command`` (N, 4 blade pitches); ``applied_t``, ``applied``;
        ``setpoint_t``, ``setpoint`` (N, 4: x, y, z, yaw); ``altitude_t``, ``altitude`` (NaN out of range);
        the instruments: ``velocity_t``, ``velocity`` (N, 6: u, v, w, p, q, r), ``imu_t``, ``attitude``
        (N, 3), ``depth_t``, ``depth``, ``position_t``, ``position`` (N, 3: acoustic fixes).
        """
        from seapup_common import frames

        self.catch_up()

        def stamp(msg):
            return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec

        def xyz(v):
            return [v.x, v.y, v.z]

        def quat(q):
            return frames.quaternion_to_euler([q.x, q.y, q.z, q.w])
        log = {name: _once_per_stamp(msgs) if name in _SAID_AGAIN else msgs for name, msgs in self.log.items()}
        out = {}
        for name in ("truth", "estimate"):
            msgs = log[name]
            out[f"{name}_t"] = np.array([stamp(m) for m in msgs])
            out[f"{name}_position"] = np.array([xyz(m.pose.pose.position) for m in msgs]).reshape(-1, 3)
            out[f"{name}_attitude"] = np.array([quat(m.pose.pose.orientation) for m in msgs]).reshape(-1, 3)
            out[f"{name}_velocity"] = np.array([xyz(m.twist.twist.linear) + xyz(m.twist.twist.angular)
                                                for m in msgs]).reshape(-1, 6)
        # the navigator's stated horizontal uncertainty [m]: the larger of its x, y standard deviations
        out["estimate_horizontal_std"] = np.array([math.sqrt(max(m.pose.covariance[0], m.pose.covariance[7], 0.0))
                                                   for m in log["estimate"]])
        out["reference_t"] = np.array([stamp(m) for m in log["reference"]])
        out["reference"] = np.array([xyz(m.twist.linear) + [m.twist.angular.z] for m in log["reference"]]
                                    ).reshape(-1, 4)
        for name in ("command", "applied"):
            out[f"{name}_t"] = np.array([stamp(m) for m in log[name]])
            out[name] = np.array([list(m.pitch) for m in log[name]]).reshape(-1, 4)
        out["setpoint_t"] = np.array([stamp(m) for m in log["setpoint"]])
        out["setpoint"] = np.array([xyz(m.pose.position) + [quat(m.pose.orientation)[2]]
                                    for m in log["setpoint"]]).reshape(-1, 4)
        out["velocity_t"] = np.array([stamp(m) for m in log["velocity"]])
        out["velocity"] = np.array([xyz(m.twist.twist.linear) + xyz(m.twist.twist.angular)
                                    for m in log["velocity"]]).reshape(-1, 6)
        out["imu_t"] = np.array([stamp(m) for m in log["imu"]])
        out["attitude"] = np.array([quat(m.orientation) for m in log["imu"]]).reshape(-1, 3)
        out["depth_t"] = np.array([stamp(m) for m in log["depth"]])
        out["depth"] = np.array([m.depth for m in log["depth"]])
        out["position_t"] = np.array([stamp(m) for m in log["position"]])
        out["position"] = np.array([xyz(m.pose.pose.position) for m in log["position"]]).reshape(-1, 3)
        out["altitude_t"] = np.array([stamp(m) for m in log["altitude"]])
        out["altitude"] = np.array([m.range if m.min_range <= m.range <= m.max_range else math.nan
                                    for m in log["altitude"]])
        return out
