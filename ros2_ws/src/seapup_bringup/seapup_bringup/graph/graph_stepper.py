"""Hold and step a lockstep graph through the simulator's ``simulation_interfaces`` control surface.

The simulator (``seapup_sim.simulator_node``) offers the ROS 2 standard
simulation control under the names of
:data:`seapup_common.topics.SIMULATION_CONTROL`; its rules are those of
:class:`seapup_common.lockstep.server.LockstepServer`. A step of n samples is
allowed only while the graph is held (PAUSED: paused, ``start_held`` at t_0, or
at its ``end_time``); it is answered once the graph is held at t_k+n *and*
the command stamped t_k+n has come or the lockstep time-out passed for it --
every answerer has answered the held sample. So a driver that steps, acts
(a goal, a controller switch) and steps again acts at the same sample however
busy the machine is.

:class:`GraphStepper` is the one client of that surface a driver needs:

- :meth:`GraphStepper.step`: ``SimulateSteps`` (the action): feedback counts
  the samples done; with ``give_up`` it is cancelled -- the graph stays held
  at the present sample -- once ``give_up()`` holds and no sample has been done
  for ``stall`` wall seconds (nobody answers: the graph waits for its driver);
- :meth:`GraphStepper.step_call`: ``StepSimulation`` (the service), the same
  without feedback or cancel;
- :meth:`GraphStepper.state`, :meth:`GraphStepper.wait_paused`, :meth:`GraphStepper.pause`,
  :meth:`GraphStepper.play`, :meth:`GraphStepper.period`.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

from seapup_common import topics
from seapup_common.topics import SIMULATION_CONTROL

__all__ = ["GraphStepper", "Stepped", "StepFailed", "PLAYING", "PAUSED", "STOPPED"]

#: simulation_interfaces/msg/SimulationState values
STOPPED, PLAYING, PAUSED = 0, 1, 2
_OK = 1                      # simulation_interfaces/msg/Result RESULT_OK
_SUCCEEDED, _CANCELED, _ABORTED = 4, 5, 6  # action_msgs/msg/GoalStatus


class StepFailed(RuntimeError):
    """The simulator refused a step or state change, or did not finish a step in time."""


@dataclass(frozen=True)
class Stepped:
    """How a step request ended: ``completed`` samples of ``requested``; ``canceled`` (given up: the graph
    is held at the sample ``completed`` samples after the start)."""

    requested: int
    completed: int
    canceled: bool


def _import(kind: str):
    package, group, name = kind.split("/")
    module = __import__(f"{package}.{group}", fromlist=[name])
    return getattr(module, name)


class GraphStepper:
    """A client of a simulator's control surface on a driver's node (see the module docstring).

    Parameters
    ----------
    node, executor
        The driver's rclpy node and the executor that spins it.
    names : dict
        name -> (service or action, type) of the surface (default :data:`SIMULATION_CONTROL`).
    """

    def __init__(self, node, executor, names: dict = SIMULATION_CONTROL):
        from rclpy.action import ActionClient
        self.node, self.executor = node, executor
        self._names = dict(names)
        self._action_type = _import(names["simulate_steps"][1])
        self._action = ActionClient(node, self._action_type, names["simulate_steps"][0])
        self._clients = {name: node.create_client(_import(kind), service) for name, (service, kind)
                         in names.items() if name in ("step_simulation", "get_simulation_state",
                                                      "set_simulation_state")}

    def destroy(self) -> None:
        """Destroy the clients (the node stays)."""
        self._action.destroy()
        for client in self._clients.values():
            self.node.destroy_client(client)
        self._clients = {}

    def _spin_until(self, predicate, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not predicate() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)
        return bool(predicate())

    def wait_ready(self, timeout: float) -> None:
        """Wait until the simulator offers the action and the services.

        Raises
        ------
        StepFailed
            If they are not there within ``timeout`` wall seconds.
        """
        if not self._spin_until(lambda: self._action.server_is_ready()
                                and all(c.service_is_ready() for c in self._clients.values()), timeout):
            raise StepFailed(f"the simulator's control surface ({self._names['simulate_steps'][0]} and its "
                             f"services) is not available within {timeout:g} s")

    def _call(self, name: str, request, timeout: float):
        """Call a service of the surface once more if its answer is lost (only for calls that may repeat)."""
        from seapup_common.ros.graph import ServiceNotAnswered, call_idempotent
        try:
            return call_idempotent(self.executor, self._clients[name], request, ready_timeout=timeout,
                                   response_timeout=min(5.0, timeout), attempts=3)
        except ServiceNotAnswered as exc:
            raise StepFailed(str(exc)) from None

    def state(self, timeout: float = 10.0) -> int:
        """The simulation state (:data:`PLAYING`, :data:`PAUSED`, :data:`STOPPED`)."""
        kind = self._clients["get_simulation_state"].srv_type
        return int(self._call("get_simulation_state", kind.Request(), timeout).state.state)

    def wait_paused(self, timeout: float) -> None:
        """Wait until the simulator says :data:`PAUSED` (held: paused, ``start_held``, its ``end_time``).

        Raises
        ------
        StepFailed
            If it does not within ``timeout`` wall seconds.
        """
        if not self._spin_until(lambda: self.state() == PAUSED, timeout):
            raise StepFailed(f"the simulator did not say PAUSED within {timeout:g} s")

    def _set_state(self, state: int, timeout: float) -> None:
        kind = self._clients["set_simulation_state"].srv_type
        request = kind.Request()
        request.state.state = state
        answer = self._call("set_simulation_state", request, timeout).result
        if answer.result not in (_OK, kind.Response.ALREADY_IN_TARGET_STATE):
            raise StepFailed(f"the simulator refused state {state}: {answer.error_message}")

    def pause(self, timeout: float = 10.0) -> None:
        """Hold the graph at its present sample."""
        self._set_state(PAUSED, timeout)

    def play(self, timeout: float = 10.0) -> None:
        """Let the graph run on (an ``end_time`` reached still holds it)."""
        self._set_state(PLAYING, timeout)

    def period(self, timeout: float = 10.0) -> float:
        """The simulator's control period T [s] (its ``control_period`` parameter)."""
        from rcl_interfaces.srv import GetParameters
        service = topics.SIMULATOR_PARAMETERS_SERVICE.rsplit("/", 1)[0] + "/get_parameters"
        client = self.node.create_client(GetParameters, service)
        try:
            from seapup_common.ros.graph import ServiceNotAnswered, call_idempotent
            try:
                answer = call_idempotent(self.executor, client, GetParameters.Request(names=["control_period"]),
                                         ready_timeout=timeout, response_timeout=min(5.0, timeout), attempts=3)
            except ServiceNotAnswered as exc:
                raise StepFailed(str(exc)) from None
        finally:
            self.node.destroy_client(client)
        period = answer.values[0].double_value if answer.values else 0.0
        if not period > 0:
            raise StepFailed(f"the simulator's control_period is {period!r}")
        return float(period)

    def step_call(self, n: int, timeout: float = 600.0) -> None:
        """Step ``n`` samples with ``StepSimulation`` and wait for the answer (the graph held at t_k+n,
        answered).

        Raises
        ------
        StepFailed
            If the simulator refuses (not paused, n < 1) or does not answer within ``timeout`` s.
        """
        client = self._clients["step_simulation"]
        if not self._spin_until(client.service_is_ready, min(timeout, 30.0)):
            raise StepFailed(f"no service {client.srv_name!r}")
        future = client.call_async(client.srv_type.Request(steps=int(n)))
        if not self._spin_until(future.done, timeout):
            client.remove_pending_request(future)
            raise StepFailed(f"a step of {n} samples was not answered within {timeout:g} s")
        answer = future.result().result
        if answer.result != _OK:
            raise StepFailed(f"the simulator refused a step of {n} samples: {answer.error_message}")

    def step(self, n: int, *, give_up=None, stall: float = 2.0, timeout: float = 600.0, progress=None) -> Stepped:
        """Step ``n`` samples with ``SimulateSteps`` and wait for its end (the graph held at t_k+n, answered).

        Parameters
        ----------
        n : int
            Samples to step (>= 1).
        give_up : callable, optional
            Once it returns True and no sample has been done for ``stall`` wall seconds, the step is
            cancelled: the graph stays held at the present sample.
        timeout : float
            Wall seconds for the whole step.
        progress : callable, optional
            Called with the samples completed so far at each feedback.

        Raises
        ------
        StepFailed
            If the simulator refuses the step or it does not end within ``timeout`` s (then it is cancelled).
        """
        from seapup_common.ros.graph import GoalNotAnswered, send_goal
        done = {"n": 0, "at": time.monotonic()}

        def on_feedback(msg):
            if msg.feedback.completed_steps != done["n"]:
                done["n"], done["at"] = int(msg.feedback.completed_steps), time.monotonic()
                if progress is not None:
                    progress(done["n"])
        try:
            handle = send_goal(self.executor, self._action, self._action_type.Goal(steps=int(n)), on_feedback,
                               ready_timeout=min(timeout, 30.0))
        except GoalNotAnswered as exc:
            raise StepFailed(str(exc)) from None
        if not handle.accepted:
            raise StepFailed(f"the simulator refused a step of {n} samples (is the graph held?)")
        done["at"] = time.monotonic()
        future, canceled = handle.get_result_async(), False
        deadline = time.monotonic() + timeout

        def stalled() -> bool:
            return give_up is not None and time.monotonic() - done["at"] > stall and give_up()
        self._spin_until(lambda: future.done() or stalled(), max(0.0, deadline - time.monotonic()))
        if not future.done():
            canceled = True
            timed_out = not stalled()
            self._spin_until(handle.cancel_goal_async().done, 10.0)
            self._spin_until(future.done, 10.0)
            if timed_out:
                raise StepFailed(f"a step of {n} samples did not end within {timeout:g} s "
                                 f"({done['n']} done); cancelled")
        if not future.done():
            raise StepFailed(f"a step of {n} samples was cancelled but never ended")
        response = future.result()
        if response.status == _SUCCEEDED and response.result.result.result == _OK:
            return Stepped(int(n), int(n), False)
        if canceled and response.status in (_CANCELED, _ABORTED):   # ended by the cancel asked for
            return Stepped(int(n), done["n"], True)
        raise StepFailed(f"a step of {n} samples ended with status {response.status}: "
                         f"{response.result.result.error_message}")
