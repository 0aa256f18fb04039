"""Software-in-the-loop harness: fly a graph of nodes on a private ROS domain and get the logs as arrays.

A test (or a script) describes the graph with a graph file (the format of
``./seapup launch``; default: ``seapup_bringup hierarchy.launch.yaml``, the whole
supervisory hierarchy in lockstep), then drives it with goals and service
calls; every node runs in its own process, exactly as on a vehicle::

    from seapup_bringup.graph.sil import SilGraph

    with SilGraph(arguments={"controller_file": "ctrl.yaml"}, out_dir=tmp_path) as sil:
        result = sil.goal("goto", x=5.0, y=3.0, z=31.0, yaw=1.0)
        assert result["status"] == "succeeded"
        logs = sil.logs()          # numpy arrays: truth, estimate, references, commands
        sil.switch(activate=["mfol_scheduled"], deactivate=["mfol_fixed"])

**Paced driving.** A lockstep graph that declares an ``end_time`` argument
for its simulator (``hierarchy.launch.yaml`` does) is *held*: it starts held
at the first sample at or after ``start_at`` (its ``end_time``; at t_0:
``start_held``) and the harness steps it on through the simulator's
``simulation_interfaces`` control surface
(:class:`seapup_bringup.graph.graph_stepper.GraphStepper`, ``SimulateSteps``) in
chunks of ``chunk`` simulated seconds (:class:`seapup_bringup.graph.paced.PacedGraph`).
A step is answered once the graph is held at its last sample and every node
has answered that sample, so every goal, cancel, controller switch and
service call is made while the graph is held at a sample every node has
answered: it takes effect at the same sample however busy the machine is. A
goal's result is acted on at the first chunk boundary a whole chunk after the
graph's own end time (the result's ``end_time``), so when the harness hears
it does not matter either. A lockstep graph whose every node is waited for
then flies the same trajectory on a quiet and on a loaded machine
(``tests/test_hierarchy.py`` checks it with a CPU burner per core).

The harness leases a ``ROS_DOMAIN_ID`` of its own (machine-wide lock, so
parallel runs never hear each other), keeps DDS on loopback, starts each
node in its own process group (stopped with SIGINT, SIGTERM, SIGKILL at the
end, also when the test fails), optionally records topics to an MCAP bag
with the ``recorder`` node, and listens in with a probe node of its own on a
private rclpy Context (:mod:`seapup_bringup.graph.sil_probe`). ``tests/test_sil_example.py`` is a complete example to
copy for your own velocity controller: put your node in the graph file (or
pass your own file) and register it with the controller manager.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from seapup_bringup.graph import readiness
from seapup_bringup.output import stopped_by_signal
from seapup_bringup.graph.paced import result_end_time, task_settle
from seapup_bringup.graph.sil_processes import SilError
from seapup_bringup.graph.sil_probe import INSTRUMENTS, SAMPLED, TOPICS, SilProbe, import_path, log_arrays, stamp_s
from seapup_common import topics

__all__ = ["SilGraph", "SilError", "TOPICS", "INSTRUMENTS", "SAMPLED"]

_ACTIONS = {"hover": "Hover", "goto": "Goto", "follow_seabed": "FollowSeabed"}


#: [s wall] How long the harness waits, the graph held, for what it must hear before it resumes the graph (a
#: held graph stands still, so a long bound costs nothing unless what it waits for never comes).
HARNESS_WAIT = 30.0


def _harness_wait(sil, predicate, what: str, wait: float = HARNESS_WAIT) -> None:
    """Spin until ``predicate()`` (``wait`` s wall at most); a wait the bound ended is counted under ``what`` in
    ``sil.harness_waits_ended`` (:meth:`SilGraph.ended_waits` names it: the run may be the machine's)."""
    if not sil.spin_until(predicate, wait):
        ended = sil.__dict__.setdefault("harness_waits_ended", {})
        ended[what] = ended.get(what, 0) + 1


def _acts(advance, done, acts, during):
    """A goal's acts in time order, each made where ``advance(seconds after the acceptance)`` left the graph
    (paced: held there): ``acts`` while the goal runs, none after its end; then ``during``'s, whose result is
    returned (None without one), even when the goal ended first (:meth:`SilGraph.goal`)."""
    for after, act in acts:
        advance(after)
        if done():
            break
        act()
    if during is None:
        return None
    advance(during[0])
    return during[1]()


def send_pilot(sil, demand, controller: str | None = None) -> None:
    """A pilot's stick (x, y, z [m/s], yaw [rad/s] of a REP-103 ``Twist``) sent from the harness's node as a
    teleop tool sends it, on :data:`seapup_common.topics.PILOT`. With ``controller`` (a manual velocity
    controller) the first waits until a subscriber has matched (a message sent before discovery would be lost)
    and, on a paced graph, the harness then waits until that controller says it has this one (its diagnostics'
    ``pilot_received`` count moved on since the harness last heard it), so the stick is in force from the held
    sample whatever the load."""
    from geometry_msgs.msg import Twist
    from seapup_common.ros.node import COMMAND_QOS
    sent = sil.__dict__.setdefault("_pilot_sent", {"publisher": None})
    if sent["publisher"] is None:
        sent["publisher"] = sil.probe.node.create_publisher(Twist, topics.PILOT, COMMAND_QOS)
        if controller is not None:
            _harness_wait(sil, lambda: sent["publisher"].get_subscription_count() > 0, "pilot subscriber")
    msg = Twist()
    msg.linear.x, msg.linear.y, msg.linear.z = (float(v) for v in demand[:3])
    msg.angular.z = float(demand[3])
    name, log = f"seapup/{controller}", sil.log["diagnostics"]
    seen, before = len(log), readiness.status_value(log, name, "pilot_received")   # its count until now
    sent["publisher"].publish(msg)
    if controller is not None and sil.paced:   # its count moved on (or began again): it has this stick
        _harness_wait(sil, lambda: readiness.said_otherwise(log, seen, name, "pilot_received", before),
                      "pilot's stick")


def _stream_acknowledged(sil, key: str, node: str, value: str = "stream_start") -> None:
    """Wait until ``node`` said (status ``value``: :func:`~seapup_bringup.graph.readiness.stream_started`) that the
    stream the probe logs as ``key`` started at the first message heard: acknowledged by every reader, or had."""
    if sil.log[key]:
        start = stamp_s(sil.log[key][0])
        _harness_wait(sil, lambda: readiness.stream_started(sil.log["diagnostics"], node, start, 400, value),
                      f"{key} stream start")   # said once, maybe before this wait: a wide window


def _first_reference_heard(sil) -> None:
    """Wait until every reader acknowledged the position controller's first reference and the active velocity
    controller (the manager's status) said it has it (``reference_stream_start``)."""
    _stream_acknowledged(sil, "reference", "seapup/position_controller")
    active = readiness.latest_statuses(sil.log["diagnostics"], window=len(sil.log["diagnostics"])).get(
        "seapup/controller_manager")
    name = next((kv.value for kv in (active.values if active else ()) if kv.key == "active"), "")
    if name:
        _stream_acknowledged(sil, "reference", f"seapup/{name}", "reference_stream_start")


def _with_roster(specs: list, probe_topics, record: list) -> list:
    """The nodes with their lockstep rosters (:func:`seapup_bringup.ros2cli.launch.with_roster`): the SIL probe
    and the recorder (if ``record``) are extra listeners, waited for as the graph's own nodes."""
    from seapup_bringup.ros2cli.launch import with_roster
    from seapup_common.lockstep.roster import Listener
    listeners = [Listener("sil_probe", probe_topics)]
    listeners += [Listener.recorder("recorder", record)] if record else []
    return with_roster(specs, listeners)


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
        are subscribed before the graph starts, so nothing of them is lost.
    ready_timeout : float
        Wall seconds for the graph to come up (ten-odd Python nodes beside CPU burners: most of a minute).
    start_at, chunk : float
        Paced driving (module docstring) [s simulated]: the first hold, and the run between holds. Used when
        the graph declares an ``end_time`` argument, runs in lockstep and gets no ``end_time`` (``paced``).
        ``start_at`` 0: held at t_0 (``start_held``), for a graph in which nobody answers t_0 before the
        harness acts.
    instruments : bool
        Also log the instruments (:data:`INSTRUMENTS`); extra listeners of the graph's lockstep roster.
    ready_status : str or tuple of str, optional
        The graph is ready once the latest ``/diagnostics`` statuses of these names say OK and matched
        (:mod:`seapup_bringup.graph.readiness`; default :data:`~seapup_bringup.graph.readiness.DEFAULT_READY`); "" waits
        only for the first estimate (and the navigator matched), None only for the first truth sample.
    extra_nodes : list of NodeSpec
        Nodes started with the graph's own (the live view of ``./seapup demo --view``).
    """

    def __init__(self, graph="seapup_bringup hierarchy.launch.yaml", arguments: dict | None = None, *,
                 out_dir, record: list[str] | None = None, ready_timeout: float = 120.0,
                 ready_status: str | tuple[str, ...] | None = readiness.DEFAULT_READY,
                 instruments: bool = False, start_at: float = 10.0, chunk: float = 1.0, extra_nodes=()):
        if not (math.isfinite(start_at) and start_at >= 0 and math.isfinite(chunk) and chunk > 0):
            raise ValueError(f"start_at must be finite and >= 0 s, chunk > 0 s, got {start_at!r}, {chunk!r}")
        self.start_at, self.chunk = float(start_at), float(chunk)
        self.paced = False      # set at start: the graph is held between the harness's actions
        self.graph, self.extra_nodes, self.instruments = str(graph), list(extra_nodes), bool(instruments)
        self.arguments = {k: (str(v).lower() if isinstance(v, bool) else str(v)) for k, v in (arguments or {}).items()}
        self.out_dir, self.record = Path(out_dir), list(record or [])
        self.ready_timeout, self.ready_status = float(ready_timeout), ready_status
        self.processes: dict = {}
        self.feedback: list = []
        self.probe = SilProbe(self.instruments)
        self.log = self.probe.log
        self._lease = self._stepper = self._pacing = self._node = self._executor = None

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
        from seapup_bringup.graph.sil_processes import GraphProcesses
        from seapup_common.processes import DomainLease, ros_environment
        from seapup_common.ros.launch_graph import command_line, find_graph, graph_arguments, load_graph

        self.out_dir.mkdir(parents=True, exist_ok=True)
        self._lease = DomainLease()
        domain = self._lease.acquire()
        self.env = ros_environment(domain)
        self.processes = GraphProcesses(self.env, self.out_dir)
        graph_file = find_graph(self.graph) if Path(self.graph).is_file() else find_graph(*self.graph.split())
        declared = graph_arguments(graph_file)
        self.paced = ("end_time" in declared and "end_time" not in self.arguments
                      and str(self.arguments.get("mode", declared.get("mode", "lockstep"))) == "lockstep")
        if self.paced and self.start_at > 0:   # held at start_at (end_time: a PAUSED state a step overrides)
            self.arguments["end_time"] = repr(self.start_at)
        elif self.paced and "start_held" in declared:   # held at t_0 itself (end_time 0 means "run on")
            self.arguments["start_held"] = "true"
        specs = _with_roster([*load_graph(graph_file, self.arguments), *self.extra_nodes], self.probe.topics,
                             self.record)
        self._node, self._executor = self.probe.open(domain).node, self.probe.executor
        if self.record:   # typed topics: each subscribed by the recorder (and this probe) before the graph starts
            self.bag, own = self.out_dir / "bag", set(self.probe.topics)
            typed = [entry.split(":")[0] for entry in self.record if ":" in entry]
            self.processes.start_recorder(self.bag, self.record, lambda: [
                t for t in typed if self._node.count_subscribers(t) < 1 + (t in own)], self.spin_until)
        for spec in specs:
            self.processes.start(spec.label, command_line(spec))
        if self.paced:
            self._hold_at_start()
        self._wait_ready()

    def _hold_at_start(self) -> None:
        """Paced: wait until the simulator says PAUSED at its first hold (``start_at``: its ``end_time``, or
        t_0: ``start_held``) and the probe has heard every node answer that sample."""
        from seapup_bringup.graph.graph_stepper import GraphStepper, StepFailed
        from seapup_bringup.graph.paced import PacedGraph, samples_to
        self._stepper, deadline = GraphStepper(self._node, self._executor), time.monotonic() + self.ready_timeout
        try:
            self._stepper.wait_ready(self.ready_timeout)
            period = self._stepper.period()
            self._stepper.wait_paused(max(1.0, deadline - time.monotonic()))
        except StepFailed as exc:
            raise SilError(f"the graph was not held at its start ({self.start_at:g} s): {exc}; node logs in "
                           f"{self.out_dir}{self._dead()}") from None
        k = samples_to(self.start_at, 0, round(period * 1e9)) if self.start_at > 0 else 0
        self._pacing = PacedGraph(self._stepper, period, self.chunk,
                                  lambda t, since, answered: self.probe.hear(t, since, answered), k)
        self.probe.hear(self.held, None, answered=self.start_at > 0)   # t_0: nobody answers before the harness

    def _wait_ready(self) -> None:
        """Spin until the graph is ready (``ready_status``, :mod:`seapup_bringup.graph.readiness`)."""
        names, matched_only = readiness.required(self.ready_status)
        count = self._node.count_subscribers

        def ready():
            found = readiness.latest_statuses(self.log["diagnostics"])
            return readiness.graph_ready(found, names, matched_only, count)
        # an estimate first, unless held at t_0: the navigator's first comes with its first acoustic fix,
        # which t_0 may lack (a dropout), and the graph goes on only once the harness acts
        navigation = self.ready_status is not None and not (self.paced and self.start_at == 0)
        if not self.spin_until(lambda: self.log["truth"] and (not navigation or self.log["estimate"])
                               and (self.ready_status is None or ready()), self.ready_timeout):
            seen = readiness.not_ready_report(readiness.latest_statuses(self.log["diagnostics"]),
                                              names + matched_only, count)
            raise SilError(f"no navigation estimate ({len(self.log['estimate'])} heard, {len(self.log['truth'])} "
                           f"samples) or no OK {self.ready_status!r} within {self.ready_timeout:g} s [{seen}]; "
                           f"node logs in {self.out_dir}" + self._dead())

    def _dead(self) -> str:
        return self.processes.dead() if self.processes else ""

    def close(self, hurry: bool = False) -> None:
        """Stop every node (:meth:`GraphProcesses.stop`: the recorder last), the probe and the lease.
        ``hurry`` (interrupted): SIGTERM, then SIGKILL a second later, instead of SIGINT."""
        if self.processes:
            self.processes.stop(hurry)
        if self._stepper is not None:
            self._stepper.destroy()
            self._stepper = None
        self.probe.close()
        if self._lease is not None:
            self._lease.release()
            self._lease = None

    def kill(self, name: str) -> None:
        """Kill one node's process at once (SIGKILL: a crash)."""
        self.processes.kill(name)

    # -- logs ------------------------------------------------------------------------------------
    def spin_until(self, predicate, timeout: float) -> bool:
        """Spin the probe until ``predicate()`` holds or ``timeout`` wall seconds pass."""
        return self.probe.spin_until(predicate, timeout)

    def catch_up(self, target: float | None = None, stall: float = 2.0, slack: float = 0.25) -> None:
        """Let the probe's logs reach ``target`` [s simulated] (:meth:`SilProbe.catch_up`)."""
        self.probe.catch_up(target, stall, slack)

    @property
    def t(self) -> float:
        """Latest simulated time heard [s] (from the truth)."""
        return self.probe.t

    def estimate(self, wait: float = 10.0) -> tuple[float, np.ndarray, np.ndarray]:
        """The estimate of the sample the graph is at (``t``; at t_0 it may still be on its way: waited for up to
        ``wait`` wall s, else the latest): time [s], position (x, y, z odom_ned) [m], attitude (phi, theta, psi)."""
        self.spin_until(lambda: (e := self.probe.estimate()) is not None and e[0] >= self.t - 1e-9, wait)
        if (found := self.probe.estimate()) is None:
            raise SilError(f"no navigation estimate heard within {wait:g} s (is the navigator running?)")
        return found

    def logs(self) -> dict[str, np.ndarray]:
        """Everything heard so far as arrays (:func:`seapup_bringup.graph.sil_probe.log_arrays`), caught up."""
        self.catch_up()
        return log_arrays(self.log)

    # -- paced driving (module docstring) -------------------------------------------------------
    @property
    def held(self) -> float | None:
        """Paced: the sample [s] the graph is held at (None: not paced)."""
        return self._pacing.held if self._pacing is not None else None

    def ended_waits(self) -> dict[str, dict[str, int]]:
        """Which nodes went on without what a lockstep wait waited for, a wall-clock limit having ended it
        (:func:`~seapup_bringup.graph.readiness.ended_waits`), and ``"harness"``: this harness's own waits before
        it resumed a held graph (:data:`HARNESS_WAIT`); empty when the run is deterministic."""
        harness = getattr(self, "harness_waits_ended", {})
        return {**readiness.ended_waits(self.log["diagnostics"]), **({"harness": dict(harness)} if harness else {})}

    @property
    def late_results(self) -> int:
        """Paced: results heard too late to be acted on at their chunk boundary."""
        return self._pacing.late_results if self._pacing is not None else 0

    def _advance(self, until: float | None, done=None, end_time=None, timeout: float = 600.0, settle=None) -> str:
        """Paced: :meth:`PacedGraph.advance` (hold at ``until`` or after what ``done`` waited for)."""
        from seapup_bringup.graph.graph_stepper import StepFailed
        try:
            return self._pacing.advance(until, done, end_time, timeout, settle)
        except StepFailed as exc:
            raise SilError(f"simulated time stuck at {self.t:.1f} s: {exc}{self._dead()}") from None

    def run_for(self, seconds: float, timeout: float | None = None) -> None:
        """Let simulated time advance by ``seconds`` (paced: and hold the graph there)."""
        if self.paced:
            self._advance(self.held + seconds, timeout=timeout or max(60.0, 2 * seconds))
            return
        end = self.t + seconds
        if not self.spin_until(lambda: self.t >= end - 1e-9, timeout or max(30.0, 2 * seconds)):
            raise SilError(f"simulated time stuck at {self.t:.1f} s (wanted {end:.1f} s){self._dead()}")

    # -- goals, actions, services ------------------------------------------------------------------
    def goal(self, kind: str, *, timeout: float = 300.0, cancel_after: float | None = None,
             during: tuple | None = None, acts=(), **fields) -> dict:
        """Send a task goal and wait for its end; ``{"status", "accepted", "rejection", "accepted_t", "end_t",
        <result fields>}`` (``accepted_t``, ``end_t``: simulated times the probe heard it accepted and ended).

        ``cancel_after`` [s simulated]: cancel the goal that long after its acceptance. ``during = (seconds,
        function)``: call ``function()`` that long after it (its return value: ``during``). ``acts``: more
        ``(seconds, function)`` pairs in rising time, each called (paced: held there) that long after the
        acceptance while the goal runs, none after its end (a manual leg's pilot). A rejected goal:
        ``accepted: False`` and the reason the task controller published."""
        from rclpy.action import ActionClient

        from seapup_common.ros.graph import send_goal

        action = import_path(f"seapup_msgs.action.{_ACTIONS[kind]}")
        client = ActionClient(self._node, action, topics.task_action(kind))
        try:
            goal = action.Goal(**fields)
            if self.paced:
                self._task_controller_at_hold()
            rejections, heard, setpoints = len(self.log["rejections"]), len(self.feedback), len(self.log["setpoint"])
            handle = send_goal(self._executor, client, goal, lambda fb: self.feedback.append((kind, fb.feedback)))
            if not handle.accepted:
                self.spin_until(lambda: len(self.log["rejections"]) > rejections, 5.0)
                reason = self.log["rejections"][-1].data if len(self.log["rejections"]) > rejections else ""
                return {"status": "rejected", "accepted": False, "rejection": reason}
            accepted_t, future = self.t, handle.get_result_async()
            if self.paced:
                during_result = self._paced_goal(future, handle, during, cancel_after, timeout, heard, setpoints == 0,
                                                 acts)
            else:
                during_result = self._unpaced_goal(future, handle, during, cancel_after, timeout, acts)
            if not self.spin_until(future.done, timeout):
                raise SilError(f"{kind} goal not finished within {timeout:g} s{self._dead()}")
            response = future.result()
            status = {4: "succeeded", 5: "canceled", 6: "aborted"}.get(response.status, str(response.status))
            out = {name: getattr(response.result, name) for name in response.result.get_fields_and_field_types()}
            self.catch_up(out.get("end_time") or None)  # the logs hold the task's whole flight
            return {"status": status, "accepted": True, "rejection": "", "during": during_result,
                    "accepted_t": accepted_t, "end_t": self.t, **out}
        finally:
            client.destroy()

    def _unpaced_goal(self, future, handle, during, cancel_after, timeout: float, acts=()):
        """A goal's ``during`` call, ``acts`` and cancel by the simulated time heard; the ``during`` result."""
        start = self.t
        during_result = _acts(lambda after: self.spin_until(lambda: self.t >= start + after or future.done(), timeout),
                              future.done, acts, during)
        if cancel_after is not None:   # that long after the acceptance, as paced
            self.spin_until(lambda: self.t >= start + cancel_after or future.done(), timeout)
            if not future.done():
                self.spin_until(handle.cancel_goal_async().done, 10.0)
        return during_result

    def _task_controller_at_hold(self) -> None:
        """Paced: wait until the task controller handled the held sample's estimate (a goal or cancel overtaking
        it would act a sample early; its answer, for the *next* sample, is not waited for)."""
        held = self.held
        _harness_wait(self, lambda: readiness.handled_since(self.log["diagnostics"], "seapup/task_controller", held),
                      "task controller at the hold")

    def _paced_goal(self, future, handle, during, cancel_after, timeout: float, heard: int, first: bool, acts=()):
        """A task goal accepted while the graph is held: its ``during`` call and cancel made at holds, and the graph
        held again after its end (module docstring); the ``during`` result. ``first``: it starts the setpoints."""
        held = self.held
        # the setpoint sent at the acceptance (for the next sample); the first goal's, had by the position controller
        _harness_wait(self, lambda: self.log["setpoint"] and stamp_s(self.log["setpoint"][-1]) > held + 1e-6, "goal")
        if first:
            _stream_acknowledged(self, "setpoint", "seapup/position_controller", "setpoint_stream_start")
        if not self.log["reference"]:
            # the first velocity reference (answering the next estimate), acknowledged by every reader
            self._advance(held + 1e-3, timeout=timeout)
            _harness_wait(self, lambda: self.log["reference"], "first reference")
            _first_reference_heard(self)
        end = lambda: result_end_time(future)   # noqa: E731
        settle = task_settle(self.spin_until, future.done, lambda: [fb.elapsed for _, fb in self.feedback[heard:]],
                             held, self._pacing.period_ns * 1e-9)   # feedback since the goal was sent
        during_result = _acts(lambda after: self._advance(held + after, done=future.done, end_time=end,
                                                          timeout=timeout, settle=settle), future.done, acts, during)
        if cancel_after is not None:
            self._advance(held + cancel_after, done=future.done, end_time=end, timeout=timeout, settle=settle)
            if not future.done():
                self._task_controller_at_hold()
                self.spin_until(handle.cancel_goal_async().done, 10.0)
        self._advance(None, done=future.done, end_time=end, timeout=timeout, settle=settle)
        return during_result

    def action(self, name: str, action_type: str, fields: dict | None = None, timeout: float = 600.0,
               feedback=None, ready_timeout: float = 30.0):
        """Send a goal (``action_type`` like ``seapup_msgs/action/SelfTest``, its fields) to action server
        ``name`` and wait for the end; the result message. ``feedback(msg)`` is called with each
        feedback message; ``ready_timeout`` [s wall] is how long the server may take to appear."""
        from rclpy.action import ActionClient

        from seapup_common.ros.graph import GoalNotAnswered, send_goal
        package, _, kind_name = action_type.split("/")
        kind = import_path(f"{package}.action.{kind_name}")
        client = ActionClient(self._node, kind, name)
        try:
            try:
                handle = send_goal(self._executor, client, kind.Goal(**(fields or {})),
                                   (lambda msg: feedback(msg.feedback)) if feedback else None,
                                   ready_timeout=ready_timeout)
            except GoalNotAnswered as exc:
                raise SilError(f"{exc}{self._dead()}") from None
            if not handle.accepted:
                raise SilError(f"{name} refused the goal" + self.processes.refusal_reason())
            future = handle.get_result_async()
            if self.paced:
                self._advance(None, done=future.done, end_time=lambda: result_end_time(future), timeout=timeout)
            if not self.spin_until(future.done, timeout):
                raise SilError(f"{name} did not finish within {timeout:g} s{self._dead()}")
            return future.result().result
        finally:
            client.destroy()

    def call(self, service: str, srv_type: str, fields: dict | None = None, timeout: float = 10.0):
        """Call a service (``srv_type`` like ``seapup_msgs/srv/SwitchController``); the response."""
        package, _, name = srv_type.split("/")
        kind = import_path(f"{package}.srv.{name}")
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
