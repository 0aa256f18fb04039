"""A mission flown in one process: the supervisory hierarchy's cores (thesis sec. 4.2, fig. 4.3) in lockstep,
sample for sample as the ROS graph flies it, without ROS.

:func:`run_mission` takes a :class:`~seapup_runs.mission.MissionSpec` -- the graph's arguments (vehicle,
seed, sensors, seabed, start depth) and the legs -- and flies it through the same pure cores the nodes of
``seapup_bringup/launch/hierarchy.launch.yaml`` wrap, with their parameter files:
:class:`~seapup_sim.simulator_core.SimulatorCore` (the plant, its sensors and command gate), the
:class:`~seapup_control.navigation.Navigator`, the tasks of :mod:`seapup_control.tasks`, the
:class:`~seapup_control.position_control.PositionController`, the velocity laws the launch document names
(:func:`seapup_common.controllers.create_controller`, configured from the self-test's result) under one
active at a time, and the :class:`~seapup_control.self_test.SelfTest` (sec. 4.5.2). The result is what
``./seapup demo`` computes from the graph's probe: the legs (status, the task's numbers, ``t0``/``t1``) and
the logs of :mod:`seapup_runs.mission_metrics` -- the same shape, so the same table, page and metrics.

The graph's timing, which this module reproduces (``docs/missions.md``; the SIL harness holds the
graph at a sample while it acts, so every act falls on one sample):

* at each sample t_k the simulator publishes the sample (one draw of the sensors' noise); the navigator
  makes the estimate of t_k from the latest valid readings no older than their age limits
  (:class:`~seapup_common.ros.messages.MeasurementCollector`'s rule); the task steps at it and its setpoint
  is stamped t_k + T; the position controller takes the setpoints due by t_k and its velocity reference is
  stamped t_k + ``reference_delay`` T; the active velocity law answers t_k with the reference in force; the
  plant integrates that command to t_{k+1};
* a goal is accepted while the graph is held at sample h, built from the estimate of t_h, and first steps
  at t_{h+1}; the first goal of a run also starts the setpoint stream with a hold stamped t_{h+1};
* a goal that ends at t_e (its result's ``end_time``) leaves the graph held at the first whole second at
  least a second after it (:func:`next_boundary`): the leg's ``t1`` and the next leg's hold;
* an act ``after`` s into a goal (a controller switch, a fouling) is made while held at the first sample at
  or after ``accepted + after``, that sample answered by the outgoing controller (at every hold the held
  sample is answered before the harness acts); a switch's incoming law answers the next sample, started
  bumpless from the blade pitch applied then; a service (current, thruster efficiency) changes the plant
  from the step out of the held sample;
* the self-test answers t_0 onwards and stops commanding at its last sample t_f; the graph is held at
  t_{f+1}, unanswered, where the controllers are configured from its result and the first one activated
  (it answers t_{f+1}).

What crosses the graph as a message crosses here as the same numbers: stamps are k T in whole
nanoseconds (read as the nodes read them, ``ns * 1e-9``: a task's clock, an arrival's settle time; the logs
as a listener reads them, ``sec + 1e-9 nanosec``), attitudes go through the quaternions the messages carry (:mod:`seapup_common.frames`), the
altimeter's range through the single precision of ``sensor_msgs/Range``. Flown so, the demo's mission gives
the graph's commands bit for bit (all 3 176 of them equal; ``tests/test_mission_flight.py`` allows 1e-9 rad).
"""
from __future__ import annotations

import dataclasses
import math
import time
from collections import deque
from typing import Callable

import numpy as np

from seapup_common import frames
from seapup_common.contract import (Command, ContractError, LatestReadings, Measurement, NavigationEstimate, Reading,
                                     StampedReferences)
from seapup_common.controllers import (ControllerRegistryError, ControllerSpec, at_input_limit, controller_type,
                                       create_controller)
from seapup_common.kernels import numba_installed
from seapup_runs.mission import (PILOT_PERIOD, fouling_creep, fouling_result, leg_goal, leg_numbers_of, manual_result,
                                 pilot_sends)

__all__ = ["run_mission", "MissionFlightError", "next_boundary", "HOLD_CHUNK", "MissionFlight", "HierarchyConfig",
           "MAX_MISSION_SECONDS"]

#: [s simulated] the SIL harness runs a lockstep graph between holds in chunks of this much, and holds it
#: after a goal's end at the first chunk boundary at least a chunk later (seapup_bringup.graph.sil's ``chunk``).
HOLD_CHUNK = 1.0
#: [s simulated] the longest mission flown in process: a day, 432 000 samples at 5 Hz (about 100 MB of logs);
#: a mission that would run longer (a goal that never ends) stops with the reason.
MAX_MISSION_SECONDS = 86_400.0


class MissionFlightError(RuntimeError):
    """A leg that cannot be flown (a goal refused, a switch to no controller): the message says which and why."""


def next_boundary(t: float, chunk: float = HOLD_CHUNK) -> float:
    """The first multiple of ``chunk`` at least a whole chunk after ``t`` [s] (where the graph is held after a
    goal that ended at ``t``).

    Examples
    --------
    >>> next_boundary(12.0), next_boundary(12.2)
    (13.0, 14.0)
    """
    return math.ceil((t + chunk) / chunk - 1e-9) * chunk


@dataclasses.dataclass(frozen=True)
class HierarchyConfig:
    """The hierarchy's nodes as plain data: what a launch document and the nodes' parameter files say
    (``seapup_bringup.graph.hierarchy_config`` reads them; picklable, so a campaign ships it to its workers).

    Parameters
    ----------
    simulator : dict
        ``vehicle``, ``seed``, ``start_depth`` [m] and ``environment`` (overrides of
        ``environment/default.yaml``: sensors, current, seabed); optionally ``physics_step``,
        ``control_period`` [s], ``dynamics``, ``watchdog_timeout`` [s], ``watchdog_action``.
    navigator, task_controller, position_controller : dict
        The ``ros__parameters`` of each node.
    velocity_controllers : dict
        Name -> (registered type, the law's parameters, sample period [s] or None: the design's).
    designs : dict, optional
        Name -> the design document (a self-test result) a velocity controller node is given (its
        ``controller_file``'s content, carried so that no file is needed where the mission flies); none:
        configured only by a mission's self-test.
    initial : str, optional
        The controller manager's ``initial``: with it, every controller that has a design is configured
        from it at the start and this one is active from the first sample (as the manager does on the graph).
    """

    simulator: dict
    navigator: dict
    task_controller: dict
    position_controller: dict
    velocity_controllers: dict
    designs: dict = dataclasses.field(default_factory=dict)
    initial: str = ""

    @staticmethod
    def controller(given: dict) -> tuple:
        """(type, law parameters, period) of a velocity_controller node's parameters, as the node configures
        its law: each parameter its type declares, from ``given`` or the type's default."""
        kind = controller_type(str(given["controller_type"]))
        parameters = {name: given.get(name, default) for name, default in kind.parameters.items()}
        # as the node: its input_limit (the vehicle's; 0: the law's own) is the law's blade_pitch_limit
        parameters = at_input_limit(kind, parameters, float(given.get("input_limit", 0.0) or 0.0))
        return kind.name, parameters, float(given.get("sample_period", 0.0) or 0.0) or None


def _round_trip():
    """:func:`seapup_common.frames.euler_through_quaternion` (phi, theta, psi, normalise): compiled
    (:mod:`seapup_common.compiled_frames`, the same bits) where numba is installed."""
    if numba_installed():
        from seapup_common.compiled_frames import euler_through_quaternion
        return euler_through_quaternion
    return lambda phi, theta, psi, normalise: frames.euler_through_quaternion(phi, theta, psi, normalise=normalise)


def _through_quaternions(attitudes: list) -> np.ndarray:
    """Each row of ``attitudes`` (Euler angles) as a message carries it (:func:`_via_quaternion`), (n, 3)."""
    angles = np.asarray(attitudes, float).reshape(-1, 3)
    if numba_installed():
        from seapup_common.compiled_frames import rows
        return rows(np.ascontiguousarray(angles), True)
    return np.array([frames.euler_through_quaternion(*row) for row in angles.tolist()]).reshape(-1, 3)


def _via_quaternion(attitude, round_trip) -> np.ndarray:
    """Euler angles as a message carries them: to a quaternion and back (an IMU's normalised on receipt), by
    ``round_trip`` (:func:`_round_trip`)."""
    phi, theta, psi = attitude.tolist()
    return np.array(round_trip(phi, theta, psi, True))


class _Collector(LatestReadings):
    """A node's collector of ``fields`` (:class:`~seapup_common.contract.LatestReadings`), fed the simulator's
    sample as the node hears its messages: stamped with the sample, the attitude through a quaternion."""

    def __init__(self, fields):
        super().__init__()
        self.fields = tuple(fields)
        self._round_trip = _round_trip()

    def add(self, measurement: Measurement, t: float) -> None:
        latest = self.latest
        for name in self.fields:
            reading = getattr(measurement, name)
            if reading.value is not None:   # valid: kept (LatestReadings.keep)
                if name == "attitude":
                    latest[name] = Reading(_via_quaternion(reading.value, self._round_trip), t, reading.variance)
                elif reading.stamp == t:    # stamped as the node stamps it already: the same reading
                    latest[name] = reading
                else:
                    latest[name] = Reading(reading.value, t, reading.variance)


@dataclasses.dataclass
class _Goal:
    """An action goal's fields (zero: the task controller's default), as ``seapup_msgs/action`` defines them."""

    hold_current: bool = False
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    yaw: float = 0.0
    duration: float = 0.0
    speed: float = 0.0
    tolerance: float = 0.0
    yaw_tolerance: float = 0.0
    timeout: float = 0.0
    altitude: float = 0.0
    follow: bool = False


def _stamp(ns: int) -> float:
    """A time [s] as a header stamp of it reads (``sec + 1e-9 nanosec``)."""
    return ns // 10**9 + 1e-9 * (ns % 10**9)


class MissionFlight:
    """The hierarchy of the launch document flying one mission in one process (module docstring).

    Use :func:`run_mission`; this class is its state: the plant, the cores, the active law, the logs.
    """

    def __init__(self, hierarchy: HierarchyConfig, max_seconds: float = MAX_MISSION_SECONDS):
        from seapup_control.navigation import SHELL_PARAMETERS, Navigator, NavigatorParams
        from seapup_control.position_control import PositionController, PositionControllerParams
        from seapup_control.tasks import TaskLimits
        from seapup_sim.simulator_core import SimulatorConfig, SimulatorCore

        simulator = hierarchy.simulator
        config = SimulatorConfig(str(simulator["vehicle"]), int(simulator["seed"]),
                                 physics_step=float(simulator.get("physics_step", 0.1)),
                                 control_period=float(simulator.get("control_period", 0.2)),
                                 watchdog_timeout=float(simulator.get("watchdog_timeout", 1.0)),
                                 watchdog_action=str(simulator.get("watchdog_action", "hover")),
                                 environment=dict(simulator["environment"]),
                                 dynamics=str(simulator.get("dynamics", "nonlinear")))
        start = np.zeros(12)
        start[2] = float(simulator["start_depth"])
        self.core = SimulatorCore(config, start)
        self.core.limits.check_state(start)
        self.period = config.control_period
        self.period_ns = int(round(self.period * 1e9))
        self.k = 0
        self._round_trip = _round_trip()
        self.max_samples = int(max_seconds / self.period)
        navigator = hierarchy.navigator
        self.navigator = Navigator(NavigatorParams.from_mapping({k: v for k, v in navigator.items()
                                                                 if k not in SHELL_PARAMETERS}))
        self.navigation_readings = _Collector(("velocity", "rates", "attitude", "depth", "position"))
        task = hierarchy.task_controller
        self.limits = TaskLimits.from_mapping(task["limits"])
        self.navigation_timeout = float(task["navigation_timeout"])
        self.altitudes: deque = deque(maxlen=100)
        position = hierarchy.position_controller
        self.position = PositionController(PositionControllerParams.from_mapping(
            {k: position[k] for k in ("gains", "yaw_gain", "speed_limits", "max_yaw_rate", "acceleration_limits",
                                      "feedforward")}), float(position["sample_period"]))
        self.reference_delay = int(position["reference_delay"]) * self.position.sample_period
        self.setpoints = StampedReferences(initial=None)    # the position controller's queue of stamped setpoints
        self.references = StampedReferences()              # the velocity controllers' queue of references
        self.law_readings = _Collector(("velocity", "rates"))
        self.laws = dict(hierarchy.velocity_controllers)
        self.configured: dict = {}
        self.active: str | None = None
        self.starting = False          # the active law starts (bumpless) at the next sample it answers
        if hierarchy.initial:          # the manager's initial controller: every one with a design configured first
            for name in self.laws:
                if hierarchy.designs.get(name):
                    self._configure(name, hierarchy.designs[name])
            if hierarchy.initial in self.configured:
                self.active, self.starting = hierarchy.initial, True
        self.self_test = None          # a SelfTest while one runs
        self.estimate: NavigationEstimate | None = None
        self.task = None
        self.task_result: dict | None = None
        self.cancel_requested = False  # the running task is cancelled at the next estimate
        self.setpoint = None           # the task controller's setpoint (PoseReference), None before the first goal
        self._setpoint_yaw = (math.nan, math.nan)   # (a setpoint's yaw, as its message carries it)
        self.answered = False          # the present sample has its command
        self.skipped = 0               # samples nobody could answer (no fresh velocity): the plant held its command
        self.logs = {name: [] for name in ("command_t", "command", "truth_t", "truth_state",
                                           "setpoint_t", "setpoint", "reference_t", "reference", "estimate_t",
                                           "estimate_position", "estimate_horizontal_std")}
        self._publish()

    # -- time -------------------------------------------------------------------------------------------
    @property
    def t(self) -> float:
        """The present sample's time [s] as a listener reads a stamp (``sec + 1e-9 nanosec``: the logs, the legs)."""
        return _stamp(self.k * self.period_ns)

    @property
    def now(self) -> float:
        """The present sample's time [s] as the nodes compute with it (``nanoseconds * 1e-9``)."""
        return self.k * self.period_ns * 1e-9

    def _t_ns(self, t: float) -> int:
        return int(round(t * 1e9))

    # -- one sample ---------------------------------------------------------------------------------------
    def _publish(self) -> None:
        """Sample t_k published and heard by every node but the velocity level (which answers it)."""
        out = self.core.outputs()
        sample, t, stamp = out["sample"], self.now, self.t
        self.applied = out["applied_blade_pitch"]   # outputs() hands out copies: the sample's state is its own
        self.answered = False
        logs = self.logs
        logs["truth_t"].append(stamp)
        logs["truth_state"].append(sample.state)   # split at finish(), the attitude through a quaternion
        measurement = sample.measurement
        self.law_readings.add(measurement, t)
        altitude = measurement.altitude
        if altitude.valid:   # sensor_msgs/Range carries it in single precision
            self.altitudes.append(Reading(float(np.float32(altitude.value)), t, float(np.float32(altitude.variance))))
        self.navigation_readings.add(measurement, t)
        if "velocity" not in self.navigation_readings.latest:
            return
        estimate = self.navigator.update(self.navigation_readings.measurement(t))
        if estimate is None:
            return
        # as the navigator's odometry carries it: the attitude through a quaternion (the estimate's arrays are
        # the navigator's copies, Navigator.estimate)
        phi, theta, psi = estimate.attitude.tolist()
        attitude = np.array(self._round_trip(phi, theta, psi, False))
        estimate = NavigationEstimate(t, estimate.position, estimate.position_cov, attitude, estimate.velocity,
                                      estimate.rates)
        logs["estimate_t"].append(stamp)
        logs["estimate_position"].append(estimate.position)
        logs["estimate_horizontal_std"].append(math.sqrt(max(estimate.position_cov[0, 0],
                                                             estimate.position_cov[1, 1], 0.0)))
        self._task_step(estimate)
        self._track(estimate)

    def _task_step(self, estimate: NavigationEstimate) -> None:
        """The task controller at estimate t_k: the task steps; the setpoint goes out stamped t_k + T."""
        self.estimate = estimate
        if self.task is not None and self.task_result is None and self.cancel_requested:
            # as the task controller's node: a cancelled task hovers where the vehicle is
            self.setpoint = self.task.hold(estimate, estimate.t)
            self.task_result = {"status": "canceled", "message": "cancelled: hovering where it is",
                                "end_time": estimate.t}
            self.cancel_requested = False
        elif self.task is not None and self.task_result is None:
            step = self.task.step(estimate.t, estimate, self._altitude_at(estimate.t))
            self.setpoint = step.setpoint
            if step.done:
                self.task_result = {"status": "succeeded" if step.success else "aborted", "message": step.message,
                                    **{k: float(v) for k, v in step.result.items()}, "end_time": estimate.t}
        if self.setpoint is not None:
            self._send_setpoint(self.setpoint, estimate.t + self.period)

    def _send_setpoint(self, setpoint, stamp: float) -> None:
        t_ns = self._t_ns(stamp)
        if self._setpoint_yaw[0] != setpoint.yaw:   # a held setpoint's yaw crosses as the same quaternion each sample
            self._setpoint_yaw = (setpoint.yaw,
                                  frames.euler_through_quaternion(0.0, 0.0, setpoint.yaw, normalise=False)[2])
        yaw = self._setpoint_yaw[1]
        from seapup_control.position_control import PoseReference
        self.setpoints.add(PoseReference(np.array(setpoint.position, float), yaw, t_ns * 1e-9), t_ns * 1e-9)
        self.logs["setpoint_t"].append(_stamp(t_ns))
        self.logs["setpoint"].append([*setpoint.position, yaw])

    def _altitude_at(self, t: float):
        """The task controller's altimeter reading for ``t``: the newest valid one at or before it, at most 1 s old."""
        for reading in reversed(self.altitudes):
            if reading.stamp <= t + 1e-9:
                return reading if t - reading.stamp <= 1.0 else None
        return None

    def _track(self, estimate: NavigationEstimate) -> None:
        """The position controller at estimate t_k: the reference for t_k + reference_delay."""
        for setpoint in self.setpoints.due(estimate.t):
            self.position.set_reference(setpoint)
        if self.position.reference is None:
            return
        reference = self.position.update(estimate.position, estimate.attitude)
        at_ns = self._t_ns(estimate.t + self.reference_delay)
        self.references.add(reference, at_ns * 1e-9)
        self.logs["reference_t"].append(_stamp(at_ns))
        self.logs["reference"].append(np.asarray(reference.velocity, float).copy())

    def answer(self) -> bool:
        """The velocity level answers the present sample (the self-test or the active law); False if nobody does."""
        if self.answered:
            return True
        t = self.now
        reference = self.references.at(t)    # every configured controller keeps the reference in force current
        if self.self_test is not None and not self.self_test.finished:
            try:
                command = self.self_test.update(t, self.law_readings.measurement(t)).blade_pitch
            except ContractError:   # no fresh velocity: the sample is skipped
                return False
        elif self.active is not None:
            law = self.configured[self.active]
            applied = Command(self.applied, t)
            if self.starting:
                law.reset(Command(self.applied, stamp=t))
                self.starting = False
            law.applied(t, applied)
            try:
                command = law.update(t, self.law_readings.measurement(t), reference).blade_pitch
            except ContractError:
                return False
        else:
            return False
        accepted, reason = self.core.submit(np.asarray(command, float), self.k * self.period_ns, lockstep=True)
        if not accepted:
            raise MissionFlightError(f"the simulator refused the command of t = {t:.1f} s: {reason}")
        self.logs["command_t"].append(self.t)
        self.logs["command"].append(np.asarray(command, float).copy())
        self.answered = True
        return True

    def step(self) -> None:
        """Answer the present sample (or let the plant hold its command, as a lockstep time-out does), integrate
        to the next and publish it."""
        if not self.answer():
            self.core.lockstep_timeout()
            self.skipped += 1
        if self.k >= self.max_samples:
            raise MissionFlightError(f"the mission has flown {self.t:g} s simulated, the most one may "
                                     f"({self.max_samples * self.period:g} s): stopped")
        self.core.step()
        self.k += 1
        self._publish()

    def run_to(self, t: float) -> None:
        """Fly until held at the first sample at or after ``t`` [s], that sample answered (a held graph's
        sample is answered before the harness acts on it)."""
        while self.t < t - 1e-6:
            self.step()
        self.answer()

    # -- acts made while held ----------------------------------------------------------------------------
    def configure(self, document: dict) -> None:
        """Every velocity controller of the launch document configured from a self-test result."""
        for name in self.laws:
            self._configure(name, document)

    def _configure(self, name: str, document: dict) -> None:
        """Velocity controller ``name`` configured from a design ``document``, as its node configures."""
        kind, parameters, period = self.laws[name]
        try:
            self.configured[name] = create_controller(ControllerSpec(kind, parameters, document=document), period)
        except ControllerRegistryError as exc:
            raise MissionFlightError(f"velocity controller {name}: {exc}") from None

    def switch(self, activate=(), deactivate=()) -> None:
        """The controller manager's switch while held: the incoming law answers the next sample."""
        for name in [*activate, *deactivate]:
            if name not in self.configured:
                raise MissionFlightError(f"switch: {name!r} is not a configured velocity controller "
                                         f"({', '.join(self.laws) or 'none'})")
        if self.active in deactivate:
            self.active = None
        if activate:
            self.active = activate[0]
            self.starting = True

    def set_current(self, detail: dict) -> None:
        """The simulator's SetCurrent (fields of ``seapup_msgs/srv/SetCurrent``), now."""
        from seapup_sim.current import CurrentParams
        params = None
        if detail.get("enabled"):
            tc = float(detail.get("break_time", 0.0)) or self.core.current_params().break_time
            params = CurrentParams(float(detail.get("mean_speed", 0.0)), float(detail.get("speed_std", 0.0)),
                                   float(detail.get("mean_direction", 0.0)), float(detail.get("direction_std", 0.0)), tc)
        self.core.set_current(params)

    def goal(self, kind: str, fields: dict, during: tuple | None = None, timeout: float = 3600.0, acts=(),
             cancel_after: float | None = None) -> dict:
        """A task goal accepted at the present hold, flown to its end; the graph held after it (module
        docstring). ``during = (after, act)``: ``act()`` at the hold ``after`` s in; ``acts``: more such pairs in
        rising time, none after the task's end; ``cancel_after``: cancelled at the hold that long in (the task
        controller then hovers where the vehicle is at the next estimate), as
        :meth:`seapup_bringup.graph.sil.SilGraph.goal` does on the graph."""
        from seapup_control.tasks import FollowSeabed, Goto, Hover, TaskRejected
        goal = _Goal(**fields)
        estimate = self.estimate if (self.estimate is not None
                                     and self.now - self.estimate.t <= self.navigation_timeout) else None
        try:
            if kind == "hover":
                task = Hover(self.limits, estimate, hold_current=goal.hold_current,
                             pose=(goal.x, goal.y, goal.z, goal.yaw), duration=goal.duration, follow=goal.follow)
            elif kind == "goto":
                task = Goto(self.limits, estimate, (goal.x, goal.y, goal.z), goal.yaw, speed=goal.speed,
                            tolerance=goal.tolerance, yaw_tolerance=goal.yaw_tolerance, timeout=goal.timeout)
            else:
                altitude = self._altitude_at(estimate.t) if estimate is not None else None
                task = FollowSeabed(self.limits, estimate, altitude, height=goal.altitude, yaw=goal.yaw,
                                    speed=goal.speed, duration=goal.duration)
        except TaskRejected as exc:
            raise MissionFlightError(f"{kind} goal rejected: {exc}") from None
        accepted = self.t
        self.task, self.task_result = task, None
        if self.setpoint is None and self.estimate is not None:   # the first task starts the setpoint stream
            self.setpoint = task.hold(self.estimate, self.estimate.t)
            self._send_setpoint(self.setpoint, self.estimate.t + self.period)
        acted = None
        end = accepted + timeout
        for after, act in acts:
            while self.task_result is None and self.t < accepted + after - 1e-6 and self.t < end:
                self.step()
            if self.task_result is not None:
                break
            self.answer()        # held there, the sample answered by the controller in force
            act()
        if during is not None:
            while self.task_result is None and self.t < accepted + during[0] - 1e-6 and self.t < end:
                self.step()
            if self.task_result is not None:
                self.run_to(next_boundary(self.task_result["end_time"]))
            self.answer()        # held there, the sample answered by the controller in force
            acted = during[1]()
        if cancel_after is not None:
            while self.task_result is None and self.t < accepted + cancel_after - 1e-6 and self.t < end:
                self.step()
            self.answer()
            self.cancel_requested = self.task_result is None
        while self.task_result is None:
            if self.t >= end:
                raise MissionFlightError(f"{kind} goal not finished within {timeout:g} s simulated")
            self.step()
        result = self.task_result
        self.task = None
        self.run_to(next_boundary(result["end_time"]))
        return {"accepted": True, "rejection": "", "success": result["status"] == "succeeded", **result,
                "accepted_t": accepted, "end_t": self.t, "during": acted}

    def pilot(self, controller: str, demand) -> None:
        """A pilot's stick (x, y, z, yaw of a REP-103 ``Twist``) heard now by manual velocity controller
        ``controller``, as its node hears the teleop tool's message while the graph is held
        (:func:`seapup_bringup.graph.sil.send_pilot`)."""
        law = self.configured.get(controller)
        if law is None or not callable(getattr(law, "pilot", None)):
            raise MissionFlightError(f"{controller!r} is not a configured manual velocity controller")
        law.pilot(self.now, tuple(demand[:3]), (0.0, 0.0, float(demand[3])))

    def fly_self_test(self, goal: dict) -> dict:
        """The self-test action from the present hold to its end; held at the sample after its last."""
        from seapup_control.self_test import SelfTest, SelfTestConfig, goal_overrides, result_document
        # as the self-test node: the goal's settings over the defaults, within the vehicle's input limit (the
        # launch's input_limit)
        test = SelfTest(SelfTestConfig.load(goal_overrides(goal), limit=self.core.simulation.model.pitch_limit))
        self.self_test = test
        t0 = self.t
        while not test.finished:
            self.step()
        self.self_test = None
        if test.phase.value != "done":
            raise MissionFlightError(f"self-test failed: {test.reason}")
        return {"status": "succeeded", "t0": t0, "t1": self.t, "document": result_document(test),
                "controller_file": "", "self_test_duration": float(test.duration)}

    def finish(self) -> dict:
        """The logs as arrays: the true states as the simulator's odometry carries them (``truth_position``,
        ``truth_attitude`` through a quaternion, ``truth_velocity``)."""
        logs = {name: np.asarray(values, float) for name, values in self.logs.items() if name != "truth_state"}
        states = np.asarray(self.logs["truth_state"], float).reshape(-1, 12)
        logs.update(truth_position=states[:, :3].copy(), truth_attitude=_through_quaternions(states[:, 3:6]),
                    truth_velocity=states[:, 6:12].copy())
        return logs


def run_mission(spec, hierarchy: HierarchyConfig, progress: Callable[[str, float], None] | None = None,
                max_seconds: float = MAX_MISSION_SECONDS) -> dict:
    """Fly a mission in one process: ``{"legs": [...], "logs": {...}, "held": t}`` as ``./seapup demo`` gets
    them from the graph (its legs' numbers by :func:`seapup_runs.mission_metrics.mission_numbers`).

    Parameters
    ----------
    spec : MissionSpec
        The mission (:mod:`seapup_runs.mission`); its ``graph`` arguments are already in ``hierarchy``.
    hierarchy : HierarchyConfig
        The nodes' parameters (``seapup_bringup.graph.hierarchy_config.hierarchy_config(spec.graph)``).
    progress : callable, optional
        ``progress(leg name, fraction of the mission's expected time)``.
    max_seconds : float
        [s simulated] the most the mission may fly (:data:`MAX_MISSION_SECONDS`): bounds its logs.

    Raises
    ------
    MissionFlightError
        A leg that cannot be flown (its goal refused, the self-test failed): which and why.
    """
    from seapup_runs.mission_metrics import mission_numbers
    plan = [dict(leg, index=i) for i, leg in enumerate(spec.to_dict()["mission"])]
    check_manual_legs(plan, hierarchy)
    flight = MissionFlight(hierarchy, max_seconds)
    total, done = sum(leg.get("expected", 60.0) for leg in plan), 0.0
    legs, swap = [], {}
    for leg in plan:
        if progress is not None:
            progress(leg["name"], done / total)
        wall = time.monotonic()
        numbers = _fly_leg(flight, leg, swap)
        done += leg.get("expected", 60.0)
        legs.append({"name": leg["name"], "kind": leg["kind"], "goal": leg.get("goal", {}),
                     "hold_from": float(leg.get("hold_from", 0.0)), "wall_s": time.monotonic() - wall, **numbers})
    if progress is not None:
        progress("mission", 1.0)
    logs = flight.finish()
    legs = mission_numbers(legs, logs, hierarchy.simulator["environment"]["seabed"], swap,
                           flight.core.simulation.model.pitch_limit)
    return {"transport": "process", "legs": legs, "logs": logs,
            "held": flight.t,
            "skipped_samples": flight.skipped,
            "ended_waits": {}}   # one process waits for nothing on a wall clock (the graph's: mission_graph)


def _fly_leg(flight: MissionFlight, leg: dict, swap: dict, during: tuple | None = None) -> dict:
    """One leg as ``seapup_bringup.graph.mission_graph`` flies it on the graph (its numbers: status, t0, t1, the task's)."""
    kind = leg["kind"]
    if kind == "fouling":
        return _fly_fouling(flight, leg, swap)
    if kind == "manual":
        return _fly_manual(flight, leg)
    if kind == "self_test":
        out = flight.fly_self_test(leg.get("goal", {}))
        flight.configure(out.pop("document"))
        flight.switch(activate=[leg["activate"]])
        return out
    if kind == "current":
        flight.set_current(leg["current"])
    estimate = flight.estimate
    if estimate is None:
        raise MissionFlightError(f"{leg['name']}: no navigation estimate yet")
    kind, goal, target = leg_goal(leg, estimate.position, float(estimate.attitude[2]))
    if "switch" in leg:
        def do_switch():
            swap["t"] = flight.t
            flight.switch(**leg["switch"]["request"])
            return True
        during = (leg["switch"]["after"], do_switch)
    result = flight.goal(kind, goal, during)
    if "switch" in leg:
        swap["leg"] = leg["index"]
        result["switch_ok"] = bool(result["during"])
    return leg_numbers_of(result, target, goal)


def _fly_fouling(flight: MissionFlight, leg: dict, swap: dict) -> dict:
    """sec. 7.4.4's leg: a creep fouled ``foul.after`` s in, then the switch and a second creep."""
    marks = {}
    if "current" in leg:
        flight.set_current(leg["current"])

    def foul():
        marks["foul_t"] = flight.t
        flight.core.set_thruster_efficiency([float(v) for v in leg["foul"]["efficiency"]])
        return True
    fixed = _fly_leg(flight, fouling_creep(leg, leg["fouled_seconds"]), swap, during=(leg["foul"]["after"], foul))
    marks["switch_t"] = flight.t
    flight.switch(**leg["switch"])
    adaptive = _fly_leg(flight, fouling_creep(leg, leg["adaptive_seconds"]), swap)
    return fouling_result(leg, fixed, adaptive, marks)


def _fly_manual(flight: MissionFlight, leg: dict) -> dict:
    """A manual leg (:mod:`seapup_runs.mission`): the pilot's controller in (from whichever law flies), its stick
    sent every :data:`~seapup_runs.mission.PILOT_PERIOD` s while the task controller follows the vehicle, then the
    hand-back -- at ``seconds``, or at once should the following end earlier -- and a hover where the vehicle is
    (as ``seapup_bringup.graph.mission_graph`` flies it on the graph)."""
    marks = {"take_t": flight.t}
    if flight.active != leg["controller"]:
        flight.switch(activate=[leg["controller"]], deactivate=[flight.active] if flight.active else [])
    sends = pilot_sends(leg)
    if sends and sends[0][0] == 0.0:   # the first stick at the hold the pilot takes over at
        flight.pilot(leg["controller"], sends.pop(0)[1])

    def hand_back():
        marks["hand_back_t"] = flight.t
        if flight.active != leg["hand_back"]:
            flight.switch(activate=[leg["hand_back"]], deactivate=[flight.active] if flight.active else [])
    acts = [*((after, lambda demand=demand: flight.pilot(leg["controller"], demand)) for after, demand in sends),
            (float(leg["seconds"]), hand_back)]
    piloted = leg_numbers_of(flight.goal("hover", {"follow": True}, acts=acts, cancel_after=float(leg["seconds"])),
                             None, {})
    if "hand_back_t" not in marks:   # the following ended before its time: handed back where it ended
        hand_back()
    held = leg_numbers_of(flight.goal("hover", {"hold_current": True, "duration": float(leg["goal"]["duration"])}),
                          None, {})
    return manual_result(leg, piloted, held, marks)


def check_manual_legs(legs, hierarchy: HierarchyConfig) -> None:
    """Before anything flies: each manual leg's controller is a manual one of the hierarchy whose
    ``silence_timeout`` outlasts the gap between the stick's sends -- every
    :data:`~seapup_runs.mission.PILOT_PERIOD` s, each on the first sample at or after its time, so up to that
    period rounded up to whole control periods -- or :class:`MissionFlightError` says why not."""
    laws = hierarchy.velocity_controllers
    period = float(hierarchy.simulator.get("control_period", 0.2))
    gap = math.ceil(PILOT_PERIOD / period - 1e-9) * period
    for leg in legs:
        if leg["kind"] != "manual":
            continue
        name = leg["controller"]
        if name not in laws or laws[name][0] != "manual":
            raise MissionFlightError(f"{leg['name']}: {name!r} is not a manual velocity controller of the hierarchy "
                                     f"({', '.join(n for n, law in laws.items() if law[0] == 'manual') or 'none'}; "
                                     "the launch argument manual:=true adds one)")
        timeout = float(laws[name][1]["silence_timeout"])
        if timeout <= gap + 1e-9:
            raise MissionFlightError(f"{leg['name']}: {name}'s silence_timeout {timeout:g} s is not longer than the "
                                     f"{gap:g} s between the pilot's sends: the stick would go silent between them")

