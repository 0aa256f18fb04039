"""The simulator's standard control surface: ``simulation_interfaces`` services and action (rclpy shell).

A Gazebo user's tools drive the lockstep graph through these, named in
:data:`seapup_common.topics.SIMULATION_CONTROL` (under ``/seapup/simulator/``):
``get_simulator_features``, ``get_simulation_state`` / ``set_simulation_state``
(stopped = rewound to t_0 and held, paused = held at the present sample, playing),
``step_simulation`` (service) and ``simulate_steps`` (action: feedback per sample,
cancel holds at the present sample), ``reset_simulation``, ``get_entities``,
``get_entity_state`` / ``set_entity_state`` (the vehicle, entity ``seapup``, in
``odom``: REP-103 ENU). Every rule of WHEN (which state allows what, when a step
is done) is :class:`~seapup_common.lockstep.server.LockstepServer`'s; the numbers
are :mod:`seapup_sim.simulator_services`'; this module only converts messages.
Every refusal is a ``Result`` with a one-line ``error_message`` and changes nothing.

A step is answered once the graph is held at t_k+n with the command stamped t_k+n
taken (the server's ``STEP_DONE``): the service callback is a coroutine awaiting
an rclpy Future that action completes. It runs in its own reentrant callback group
(in the node's default, mutually exclusive group it would keep every other callback
of the node -- the command subscription included -- from running until it is done),
and :func:`deferred_service` makes it work under rclpy's EventsExecutor too, whose
service dispatch (rclpy 7.1) does not await a coroutine.

A set entity state takes effect at once: the plant is in it from the present sample
t_k on (the next step integrates from it; :meth:`GetEntityState` shows it now).
The held sample t_k, already published, is not said again: the record keeps one
sample per stamp, and the next sample shows the change.
"""
from __future__ import annotations

import inspect
import time

import numpy as np
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.task import Future
from simulation_interfaces.action import SimulateSteps
from simulation_interfaces.msg import Result, SimulatorFeatures
from simulation_interfaces.srv import (GetEntities, GetEntityState, GetSimulationState, GetSimulatorFeatures,
                                       ResetSimulation, SetEntityState, SetSimulationState, StepSimulation)

from seapup_common import frames
from seapup_common.lockstep import server as lockstep
from seapup_common.ros import messages as conv
from seapup_common.topics import SIMULATION_CONTROL
from seapup_sim.simulator_services import (ENTITY, InvalidPose, entity_state_enu, matching_entities, reset_scope,
                                           set_plant_state, state_from_enu)

__all__ = ["SimulationControl", "deferred_service", "FEATURES"]

F = SimulatorFeatures
#: [s wall] How long a ``simulate_steps`` goal waits for its feedback topic's subscription before stepping.
FEEDBACK_WAIT = 2.0
#: What this simulator supports (GetSimulatorFeatures).
FEATURES = [F.SIMULATION_STATE_GETTING, F.SIMULATION_STATE_SETTING, F.SIMULATION_STATE_PAUSE,
            F.STEP_SIMULATION_SINGLE, F.STEP_SIMULATION_MULTIPLE, F.STEP_SIMULATION_ACTION,
            F.SIMULATION_RESET, F.SIMULATION_RESET_TIME, F.SIMULATION_RESET_STATE,
            F.ENTITY_STATE_GETTING, F.ENTITY_STATE_SETTING]
#: The server's refusal kinds -> Result codes (SetSimulationState's own codes 101-103 included).
_CODES = {lockstep.ALREADY: SetSimulationState.Response.ALREADY_IN_TARGET_STATE,
          lockstep.INCORRECT: SetSimulationState.Response.INCORRECT_TRANSITION,
          lockstep.FAILED: SetSimulationState.Response.STATE_TRANSITION_ERROR,
          lockstep.UNSUPPORTED: Result.RESULT_FEATURE_UNSUPPORTED,
          lockstep.NOT_PAUSED: Result.RESULT_OPERATION_FAILED,   # StepSimulation's comment: not paused
          lockstep.INVALID: Result.RESULT_OPERATION_FAILED,
          lockstep.BUSY: Result.RESULT_INCORRECT_STATE, lockstep.HALTED: Result.RESULT_INCORRECT_STATE,
          lockstep.NOT_STARTED: Result.RESULT_INCORRECT_STATE}
#: The world frames a state may be given in ('' is the world: odom).
_WORLD = ("", frames.FRAME_ENU)


def _result(code: int = Result.RESULT_OK, message: str = "") -> Result:
    return Result(result=code, error_message=message.splitlines()[0][:300] if message else "")


def deferred_service(node, srv_type, name: str, callback):
    """A service whose ``callback`` is a coroutine (answered when it returns), under any rclpy executor.

    The SingleThreadedExecutor awaits a coroutine callback itself; the EventsExecutor of rclpy 7.1 passes the
    coroutine to ``send_response``: here it becomes a task of the node's executor, whose result is sent."""
    service = node.create_service(srv_type, name, callback, callback_group=ReentrantCallbackGroup())
    send = service.send_response

    def send_response(response, header):
        if inspect.iscoroutine(response):
            task = node.executor.create_task(response)
            task.add_done_callback(lambda done: send(done.result(), header))
        else:
            send(response, header)
    service.send_response = send_response
    return service


class SimulationControl:
    """The ``simulation_interfaces`` services and action of a simulator node (see the module docstring).

    Parameters
    ----------
    node : seapup_sim.simulator_node.SimulatorNode
        Has ``server`` (the lockstep server), ``simulator`` (the core), ``config``, ``start_state`` and
        ``_run(actions)`` (executes the server's actions; :data:`STEP_PROGRESS` / :data:`STEP_DONE` come back
        here through :meth:`step_event`).
    """

    def __init__(self, node):
        self.node = node
        self._steps: dict[int, list] = {}   # id(StepRecord) -> [done future, goal or None, samples reported]
        group = self._group = ReentrantCallbackGroup()
        plain = {"get_simulator_features": (GetSimulatorFeatures, self._features),
                 "get_simulation_state": (GetSimulationState, self._get_state),
                 "set_simulation_state": (SetSimulationState, self._set_state),
                 "reset_simulation": (ResetSimulation, self._reset),
                 "get_entities": (GetEntities, self._entities),
                 "get_entity_state": (GetEntityState, self._get_entity),
                 "set_entity_state": (SetEntityState, self._set_entity)}
        for key, (kind, callback) in plain.items():
            node.create_service(kind, SIMULATION_CONTROL[key][0], callback)
        deferred_service(node, StepSimulation, SIMULATION_CONTROL["step_simulation"][0], self._step)
        self._action = ActionServer(node, SimulateSteps, SIMULATION_CONTROL["simulate_steps"][0],
                                    execute_callback=self._simulate, goal_callback=lambda goal: GoalResponse.ACCEPT,
                                    cancel_callback=self._cancel, callback_group=group)

    # -- the server's step events ------------------------------------------------------------------
    def step_event(self, action) -> None:
        """:data:`STEP_PROGRESS`: feedback to an action's goal; :data:`STEP_DONE`: the step's answer."""
        entry = self._steps.get(id(action.step))
        if entry is None:
            return
        future, goal, reported = entry
        record = action.step
        if action.kind == lockstep.STEP_DONE:
            del self._steps[id(record)]
            future.set_result(record)
        elif goal is not None and record.done > reported:   # once per sample
            entry[2] = record.done
            goal.publish_feedback(SimulateSteps.Feedback(completed_steps=record.done,
                                                         remaining_steps=record.requested - record.done))

    def _start_step(self, n: int, goal=None) -> tuple[Future | None, Result]:
        """Ask the server for ``n`` samples: (the future of its end, OK) or (None, the refusal)."""
        server, now = self.node.server, time.monotonic()
        try:
            actions = server.step(int(n), now)
        except lockstep.StepRefused as exc:
            return None, _result(_CODES[exc.kind], str(exc))
        future = Future()
        self._steps[id(server.stepping)] = [future, goal, 0]
        self.node._run(actions)
        return future, _result()

    @staticmethod
    def _outcome(record) -> Result:
        if record.outcome == "completed":
            return _result()
        return _result(Result.RESULT_OPERATION_FAILED,
                       f"the step ended {record.outcome} after {record.done} of {record.requested} sample(s)")

    # -- services ----------------------------------------------------------------------------------
    def _features(self, request, response):
        response.features.features = FEATURES
        response.features.custom_info = ("seapup lockstep simulator: one entity 'seapup' (the vehicle), states in "
                                         "odom (REP-103 ENU); a step is one control period")
        return response

    def _get_state(self, request, response):
        response.state.state = self.node.server.state
        response.result = _result()
        return response

    def _set_state(self, request, response):
        try:
            self.node._run(self.node.server.set_state(request.state.state, time.monotonic()))
        except lockstep.TransitionRefused as exc:
            response.result = _result(_CODES[exc.kind], str(exc))
            return response
        response.result = _result()
        return response

    async def _step(self, request, response):
        future, response.result = self._start_step(request.steps)
        if future is not None:
            response.result = self._outcome(await future)
        return response

    def _reset(self, request, response):
        try:
            reset_time, reset_state = reset_scope(request.scope)
            node = self.node
            if reset_time:   # t = 0: the start state, or (TIME alone) the present one
                state = node.start_state if reset_state else node.simulator.simulation.state
                node.simulator.reset(node.config.seed, state)   # validated, atomic
                node._run(node.server.reset(time.monotonic()))
            else:
                set_plant_state(node.simulator, node.start_state)
        except ValueError as exc:
            code = Result.RESULT_FEATURE_UNSUPPORTED if "scope" in str(exc) else Result.RESULT_OPERATION_FAILED
            response.result = _result(code, str(exc))
            return response
        response.result = _result()
        return response

    def _entities(self, request, response):
        f = request.filters
        if f.categories or f.tags.tags or f.bounds.type or f.bounds.points:
            response.result = _result(Result.RESULT_FEATURE_UNSUPPORTED,
                                      "only the name filter is supported (no categories, tags or bounds)")
            return response
        try:
            response.entities = matching_entities(f.filter)
        except ValueError as exc:
            response.result = _result(Result.RESULT_OPERATION_FAILED, str(exc))
            return response
        response.result = _result()
        return response

    def _unknown(self, entity: str) -> Result | None:
        if entity != ENTITY:
            return _result(Result.RESULT_NOT_FOUND, f"no entity {entity[:80]!r} (the one entity is {ENTITY!r})")
        return None

    def _get_entity(self, request, response):
        if (refused := self._unknown(request.entity)) is not None:
            response.result = refused
            return response
        simulation = self.node.simulator.simulation
        e = entity_state_enu(simulation.state, simulation.acceleration)
        s = response.state
        s.header.stamp, s.header.frame_id = conv.ns_to_stamp(self.node.simulator.t_ns), frames.FRAME_ENU
        p, q = s.pose.position, s.pose.orientation
        p.x, p.y, p.z = (float(v) for v in e["position"])
        q.x, q.y, q.z, q.w = (float(v) for v in e["orientation"])
        for target, values in ((s.twist.linear, e["linear"]), (s.twist.angular, e["angular"]),
                               (s.acceleration.linear, e["linear_acceleration"])):
            target.x, target.y, target.z = (float(v) for v in values)
        response.result = _result()
        return response

    def _set_entity(self, request, response):
        if (refused := self._unknown(request.entity)) is not None:
            response.result = refused
            return response
        s = request.state
        if s.header.frame_id not in _WORLD:
            response.result = _result(Result.RESULT_OPERATION_FAILED, f"frame {s.header.frame_id[:80]!r} is not "
                                      f"supported: give the state in {frames.FRAME_ENU!r} (or '': the world)")
            return response
        if reason := self.node.server.entity_refusal():
            response.result = _result(Result.RESULT_INCORRECT_STATE, reason)
            return response

        def xyz(v):
            return [v.x, v.y, v.z]
        try:
            state = state_from_enu(xyz(s.pose.position), [*xyz(s.pose.orientation), s.pose.orientation.w],
                                   xyz(s.twist.linear), xyz(s.twist.angular))
            set_plant_state(self.node.simulator, state)
        except InvalidPose as exc:
            response.result = _result(SetEntityState.Response.INVALID_POSE, str(exc))
            return response
        except ValueError as exc:
            response.result = _result(Result.RESULT_OPERATION_FAILED, str(exc))
            return response
        self.node.get_logger().info(f"entity {ENTITY} set at t = {self.node.simulator.t:.3f} s: "
                                    f"{np.array2string(state, precision=3)}")
        response.result = _result()
        return response

    # -- the action --------------------------------------------------------------------------------
    def _feedback_listened(self, timeout: float = FEEDBACK_WAIT) -> Future:
        """A future done once this server knows a subscription of its feedback topic, or after ``timeout``
        wall seconds. A client learns the action server's services first (``server_is_ready``), and the
        feedback topic is discovered on its own: a goal sent at once was stepped before the feedback
        writer had matched its reader, and the first feedback was lost (seen under load). The graph is held
        meanwhile, so the wait changes no sample."""
        done, deadline = Future(), time.monotonic() + timeout
        topic = SIMULATION_CONTROL["simulate_steps"][0] + "/_action/feedback"

        def check() -> None:
            if done.done():
                return
            if self.node.count_subscribers(topic) > 0 or time.monotonic() >= deadline:
                done.set_result(None)
                timer.cancel()
                self.node.destroy_timer(timer)
        timer = self.node.create_timer(0.01, check, callback_group=self._group)
        check()
        return done

    async def _simulate(self, goal):
        await self._feedback_listened()
        future, result = self._start_step(goal.request.steps, goal)
        if future is not None:
            record = await future
            result = self._outcome(record)
            if record.outcome == "canceled" and goal.is_cancel_requested:
                goal.canceled()
                return SimulateSteps.Result(result=result)
        (goal.succeed if result.result == Result.RESULT_OK else goal.abort)()
        return SimulateSteps.Result(result=result)

    def _cancel(self, goal) -> CancelResponse:
        """Cancel the goal's step: held at the present sample (the goal ends canceled)."""
        running = self.node.server.stepping
        if running is None or self._steps.get(id(running), [None, None])[1] is not goal:
            return CancelResponse.REJECT
        self.node._run(self.node.server.cancel_step(time.monotonic()))
        return CancelResponse.ACCEPT
