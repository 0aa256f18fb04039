"""The ``controller_manager`` node: runtime swaps and failover of the velocity controller (ros2_control's semantics).

A thin shell over :class:`seapup_control.controller_manager.ControllerManagerCore`.
The managed velocity controllers are lifecycle nodes in ``/seapup``, each
publishing its blade pitches on a topic of its own (``command_topic``); the
manager forwards the active one's commands to ``/seapup/thrusters/command``,
at most one per sample, so exactly one controller commands the thrusters.

Services (``/seapup/controller_manager/...``):

- ``list_controllers`` (seapup_msgs/srv/ListControllers): each controller's
  lifecycle state (asked of the node), type, counters; the active one.
- ``switch_controller`` (seapup_msgs/srv/SwitchController): deactivate, then
  activate, through each node's ``change_state`` service; an unconfigured
  controller is configured first. From the moment the outgoing controller is
  told to stop, the samples not yet forwarded belong to the incoming one, so
  the switch falls on a tick boundary; the incoming one starts from the
  applied blade pitch (bumpless). If it fails to activate, the outgoing one
  is activated again (rollback) and the reply says why.

Failover: when the vehicle's sample t_k (``thrusters/applied``) has waited
``command_deadline`` wall seconds without a command from the active
controller, the manager asks that controller its lifecycle state
(``liveness_timeout``). One that does not answer, or is no longer active,
has failed (its process died, it hangs): the manager activates the
``fallback`` controller, which answers that sample; reported at ERROR on
``/diagnostics`` (``seapup/controller_manager``) and in the log. One that
answers "active" is alive and only slow -- a loaded machine, where in
lockstep simulated time waits for it -- and keeps the thrusters (counted as
``slow_answers``), so no failover depends on how busy the machine is;
``liveness_timeout: 0`` fails over on the deadline alone (hard real time).
A transition that times out may still have happened: the manager then asks
the controller's state before it decides, and a rollback is given the
node's ``switch_timeout`` at least, whatever the request's timeout.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from seapup_msgs.msg import BladePitch, ControllerState
from seapup_msgs.srv import ListControllers, SwitchController

from seapup_common.ros.messages import diagnostic_array, stamp_to_ns
from seapup_common.ros.graph import SubscriberGate
from seapup_common.controllers import available_controllers
from seapup_common.ros.node import (COMMAND_QOS, RELIABLE_QOS, STREAM_QOS, SERVICE_QOS, declare_from_package_file,
                                    run_node, stop_requested, text, topic_names)
from seapup_common.topics import DIAGNOSTICS, FORWARDED_COMMAND, NAMESPACE
from seapup_control.controller_manager import ControllerManagerCore, SwitchError

#: [s] the switch timeouts a request may give (0: the node's ``switch_timeout``): a lifecycle
#: transition through the graph takes milliseconds at best.
MIN_SWITCH_TIMEOUT, MAX_SWITCH_TIMEOUT = 0.1, 120.0

__all__ = ["ControllerManagerNode", "main"]


@dataclass(frozen=True)
class _TransitionProblem:
    """Why a lifecycle transition did not succeed: refused, or not answered in time (``unanswered``: the
    controller may still have made it)."""

    message: str
    unanswered: bool

    def __str__(self) -> str:
        return self.message


def _node_names(value) -> str:
    from rclpy.exceptions import InvalidNodeNameException
    from rclpy.validate_node_name import validate_node_name
    for name in [value] if isinstance(value, str) else list(value):
        if name == "":
            continue
        try:
            validate_node_name(name)
        except InvalidNodeNameException:
            return f"{name!r} is not a node name (letters, digits and _, not starting with a digit)"
    return ""


def _command_topic(value: str) -> str:
    if "{name}" not in value:
        return "it must contain {name} (each controller's node name)"
    return topic_names().test(value.replace("{name}", "x"))


#: The allowed values of the manager's string parameters: node names (the managed controllers, the fallback,
#: the initial one; "" for none), registered law types, and the command topic pattern.
ALLOWED = {"controllers": text("velocity_controller node names in /seapup", _node_names),
           "types": text("registered controller types (./seapup controllers), one per controller, or none",
                         lambda v: next((f"{t!r} is not a registered type ({', '.join(available_controllers())})"
                                         for t in v if t not in available_controllers()), "")),
           "command_topic": text("a topic name containing {name}", _command_topic),
           "fallback": text("one of controllers", _node_names),
           "initial": text("one of controllers, or empty (none until a switch)", _node_names)}


class ControllerManagerNode(Node):
    """rclpy shell around :class:`ControllerManagerCore` (see the module docstring)."""

    #: Spun by rclpy's EventsExecutor unless told otherwise (seapup_common.ros.node.DEFAULT_EXECUTOR).
    EXECUTOR = "events"

    def __init__(self, **kwargs):
        super().__init__("controller_manager", namespace=NAMESPACE, **kwargs)
        p = declare_from_package_file(self, "seapup_control", "controller_manager.yaml", section="controller_manager",
                                      ranges={"command_deadline": (0.01, 60.0), "switch_timeout": (0.1, 120.0),
                                              "liveness_timeout": (0.0, 60.0),
                                              "wait_for_command_subscribers": (0, 100)}, allowed=ALLOWED)
        names, types = list(p["controllers"]), list(p["types"])
        if types and len(types) != len(names):
            raise ValueError(f"types: {len(types)} given for {len(names)} controllers")
        self.core = ControllerManagerCore(names, p["fallback"], dict(zip(names, types)))
        self.deadline = float(p["command_deadline"])
        self.switch_timeout = float(p["switch_timeout"])
        self.liveness_timeout = float(p["liveness_timeout"])
        self.slow_answers = 0
        self.topics = {n: p["command_topic"].format(name=n) for n in names}
        self.publisher = self.create_publisher(BladePitch, "thrusters/command", STREAM_QOS)
        self.forwarded = self.create_publisher(BladePitch, FORWARDED_COMMAND, RELIABLE_QOS)  # a copy of each
        # the first forwarded command waits for every awaited subscriber (the vehicle, a recorder): a
        # bag once lacked the first 2-8 s of commands
        self.gate = SubscriberGate([(self.publisher, int(p["wait_for_command_subscribers"]))])
        self._held: BladePitch | None = None
        self.create_timer(0.05, self._release_held)
        self.diagnostics = self.create_publisher(DiagnosticArray, DIAGNOSTICS, RELIABLE_QOS)
        for name in names:
            self.create_subscription(BladePitch, self.topics[name],
                                     lambda msg, name=name: self._on_command(name, msg), COMMAND_QOS)
        self.create_subscription(BladePitch, "thrusters/applied", self._on_applied, RELIABLE_QOS)
        self._client_node = rclpy.create_node("controller_manager_lifecycle_client", namespace=NAMESPACE,
                                              context=self.context)
        self._client_executor = SingleThreadedExecutor(context=self.context)
        self._client_executor.add_node(self._client_node)
        self.change = {n: self._client_node.create_client(ChangeState, f"{NAMESPACE}/{n}/change_state") for n in names}
        self.get_state = {n: self._client_node.create_client(GetState, f"{NAMESPACE}/{n}/get_state") for n in names}
        self.create_service(ListControllers, "~/list_controllers", self._list, qos_profile=SERVICE_QOS)
        self.create_service(SwitchController, "~/switch_controller", self._switch, qos_profile=SERVICE_QOS)
        self.latest_sample_ns: int | None = None
        self._unanswered_since: float | None = None
        self.invalid_commands = 0
        self.failover_message = ""
        self.create_timer(0.02, self._watch)
        self.create_timer(1.0, self._diagnose)
        self._initial = p["initial"]
        if self._initial:
            if self._initial not in self.core.controllers:
                raise ValueError(f"initial controller {self._initial!r} is not one of {names}")
            self._initial_since: float | None = None
            self._initial_timer = self.create_timer(0.1, self._start_initial)

    # -- lifecycle calls -----------------------------------------------------------------------
    # The calls block inside a service or timer callback: they go through a private client node
    # spun by an executor of its own (coroutine callbacks that await futures stall Jazzy's
    # SingleThreadedExecutor here). Meanwhile nothing is forwarded, which in lockstep only makes
    # the simulator wait; a transition takes a few milliseconds.
    def _call(self, client, request, timeout: float):
        """The service's response, or None after ``timeout`` wall seconds or once the node is asked to
        stop (a SIGINT must not wait out a transition: it took 2.6 s to exit under load)."""
        if not client.wait_for_service(timeout_sec=min(timeout, 1.0)):
            return None
        future = client.call_async(request)
        deadline = time.monotonic() + timeout
        while not future.done() and not stop_requested() and time.monotonic() < deadline:
            self._client_executor.spin_until_future_complete(future, timeout_sec=min(0.05, deadline - time.monotonic()))
        return future.result() if future.done() else None

    def _state(self, name: str, timeout: float) -> str:
        response = self._call(self.get_state[name], GetState.Request(), timeout)
        label = response.current_state.label if response is not None else "unknown"
        self.core.controllers[name].state = label
        return label

    def _transition(self, name: str, transition: int, timeout: float) -> _TransitionProblem | None:
        """Run one lifecycle transition; None on success, else why not."""
        request = ChangeState.Request()
        request.transition.id = transition
        response = self._call(self.change[name], request, timeout)
        if response is None:
            return _TransitionProblem(f"{name} did not answer transition {transition} within {timeout:g} s "
                                      "(is it running?)", unanswered=True)
        if not response.success:
            return _TransitionProblem(f"{name} refused transition {transition} (see its log)", unanswered=False)
        return None

    def _activate(self, name: str, timeout: float) -> str | None:
        state = self._state(name, timeout)
        if state == "unconfigured":
            problem = self._transition(name, Transition.TRANSITION_CONFIGURE, timeout)
            if problem:
                return f"configure: {problem}"
        self.core.handover(name)  # its answer to the pending sample is the first forwarded
        problem = self._transition(name, Transition.TRANSITION_ACTIVATE, timeout)
        if problem and problem.unanswered and self._state(name, timeout) == "active":
            problem = None  # the answer came late (a loaded machine): it is active, and already forwarded
        if problem:
            self.core.handover(None)
            return f"activate: {problem}"
        self.core.set_state(name, "active")
        return None

    def _deactivate(self, name: str, timeout: float) -> _TransitionProblem | None:
        self.core.handover(None)  # from now on nothing of it is forwarded
        problem = self._transition(name, Transition.TRANSITION_DEACTIVATE, timeout)
        self.core.set_state(name, "inactive" if problem is None else "unknown")
        return problem

    def _start_initial(self) -> None:
        # every managed controller up first (or 30 s gone): all are configured now, so an inactive one
        # hears every sample before a switch activates it (configured only at its switch, it had missed
        # that sample and waited out the simulator's lockstep timeout, 10 s, under load)
        if self._initial_since is None:
            self._initial_since = time.monotonic()
        everyone = all(client.service_is_ready() for client in self.change.values())
        if not self.change[self._initial].service_is_ready() or \
                (not everyone and time.monotonic() - self._initial_since < 30.0):
            return  # the controller nodes are not up yet: try again at the next tick
        self.destroy_timer(self._initial_timer)
        # a node still starting on a loaded machine may not answer in time: ask again (a graph whose
        # simulator waits for every controller's subscriptions waited for ever on one left unconfigured)
        self._configure_all(self.switch_timeout, attempts=4)
        problem = self._activate(self._initial, self.switch_timeout)
        if problem:
            self.get_logger().error(f"initial controller {self._initial}: {problem}")
        else:
            self.get_logger().info(f"initial controller {self._initial} active")

    # -- services ------------------------------------------------------------------------------
    def _list(self, request, response):
        for name, controller in self.core.controllers.items():
            state = self._state(name, 1.0)
            response.controller.append(ControllerState(
                name=name, state=state, type=controller.type, fallback=name == self.core.fallback,
                command_topic=self.topics[name], commands_forwarded=controller.commands_forwarded,
                commands_dropped=controller.commands_dropped))
        response.active = self.core.active or ""
        return response

    def _switch(self, request, response):
        timeout = request.timeout if request.timeout != 0 else self.switch_timeout
        if not MIN_SWITCH_TIMEOUT <= timeout <= MAX_SWITCH_TIMEOUT:  # NaN too: nothing is changed
            response.ok = False
            response.message = (f"timeout {request.timeout!r} s refused: give 0 (the node's switch_timeout, "
                                f"{self.switch_timeout:g} s) or {MIN_SWITCH_TIMEOUT:g}-{MAX_SWITCH_TIMEOUT:g} s; "
                                "a shorter one could only leave no controller active")
            self.get_logger().warn(f"switch refused: {response.message}")
            return response
        try:
            plan = self.core.plan_switch(list(request.activate_controllers), list(request.deactivate_controllers),
                                         request.strictness)
        except SwitchError as exc:
            response.ok, response.message = False, str(exc)
            self.get_logger().warn(f"switch refused: {exc}")
            return response
        response.ok, response.message = self._run_plan(plan, timeout)
        # one call site per severity: rclpy refuses a call site whose severity changes between calls
        if response.ok:
            self.get_logger().info(f"switch: {response.message}")
        else:
            self.get_logger().error(f"switch: {response.message}")
        self._diagnose()
        return response

    def _configure_all(self, timeout: float, attempts: int = 1) -> None:
        """Configure every unconfigured controller (as ros2_control loads controllers before switching):
        an inactive controller already hears the applied blade pitch, so it starts bumpless. A controller
        whose state or configuration went unanswered is asked again, up to ``attempts`` times in all (one
        that refuses its configuration is not: its log says why)."""
        pending = [name for name in self.core.controllers if name != self.core.active]
        for attempt in range(max(1, int(attempts))):
            unanswered = []
            for name in pending:
                state = self._state(name, timeout)
                if state == "unknown":
                    unanswered.append(name)
                elif state == "unconfigured":
                    problem = self._transition(name, Transition.TRANSITION_CONFIGURE, timeout)
                    if problem and problem.unanswered and self._state(name, timeout) != "inactive":
                        unanswered.append(name)
                    elif problem and problem.unanswered is False:
                        self.get_logger().warn(f"configure {name}: {problem}")
            if not unanswered:
                return
            pending = unanswered
        self.get_logger().warn(f"configure: {', '.join(pending)} did not answer in {attempts} attempts of "
                               f"{timeout:g} s (configured when a switch activates them)")

    def _run_plan(self, plan, timeout: float) -> tuple[bool, str]:
        self._configure_all(timeout)
        outgoing = plan.deactivate[0] if plan.deactivate else None
        for name in plan.deactivate:
            problem = self._deactivate(name, timeout)
            if problem:
                return False, f"deactivate: {problem}"
        for name in plan.activate:
            problem = self._activate(name, timeout)
            if problem:
                if outgoing is not None:  # rollback: the outgoing controller takes over again (a short
                    # timeout that made the switch fail must not leave the thrusters to nobody)
                    back = self._activate(outgoing, max(timeout, self.switch_timeout))
                    return False, f"{problem}; rolled back to {outgoing}" + (f" (failed too: {back})" if back else "")
                return False, problem
        done = [f"deactivated {', '.join(plan.deactivate)}"] if plan.deactivate else []
        done += [f"activated {', '.join(plan.activate)}"] if plan.activate else []
        return True, "; ".join(done + plan.skipped) or "nothing to do"

    # -- forwarding and failover -------------------------------------------------------------
    def _on_command(self, name: str, msg: BladePitch) -> None:
        pitch = np.asarray(msg.pitch, dtype=float)
        if pitch.shape != (4,) or not np.all(np.isfinite(pitch)):
            self.invalid_commands += 1
            self.get_logger().warn(f"invalid command from {name} dropped", throttle_duration_sec=2.0)
            return
        stamp_ns = stamp_to_ns(msg.header.stamp)
        if self.core.accept_command(name, stamp_ns):
            if self.gate.ready():
                self.publisher.publish(msg)
                self.forwarded.publish(msg)
            else:
                self._held = msg  # the newest: sent once the awaited subscribers have matched
            if self.latest_sample_ns is None or stamp_ns >= self.latest_sample_ns:
                self._unanswered_since = None

    def _release_held(self) -> None:
        if self._held is not None and self.gate.ready():
            self.publisher.publish(self._held)
            self.forwarded.publish(self._held)
            self._held = None

    def _on_applied(self, msg: BladePitch) -> None:
        stamp_ns = stamp_to_ns(msg.header.stamp)
        if self.latest_sample_ns is not None and stamp_ns <= self.latest_sample_ns:
            return
        self.latest_sample_ns = stamp_ns
        answered = self.core.last_forwarded_ns is not None and self.core.last_forwarded_ns >= stamp_ns
        if not answered and self._unanswered_since is None:
            self._unanswered_since = time.monotonic()

    def _watch(self) -> None:
        if self._unanswered_since is None:
            return
        waited = time.monotonic() - self._unanswered_since
        if self.core.overdue(self.latest_sample_ns, waited, self.deadline):
            if self._alive_but_slow():
                self._unanswered_since = time.monotonic()  # wait for it another deadline
                return
            self._failover()

    def _alive_but_slow(self) -> bool:
        """The silent active controller still answers, and is active (see the module docstring)."""
        name = self.core.active
        if self.liveness_timeout <= 0 or name is None:
            return False
        if self._state(name, self.liveness_timeout) != "active":
            return False
        self.slow_answers += 1
        self.get_logger().warn(f"{name} is {self.deadline:g} s late with sample t = {self.latest_sample_ns * 1e-9:.3f} s "
                               f"but alive and active: it keeps the thrusters ({self.slow_answers} slow answers)",
                               throttle_duration_sec=5.0)
        return True

    def _failover(self) -> None:
        failed, fallback, sample = self.core.active, self.core.fallback, self.latest_sample_ns
        reason = (f"{failed} did not answer sample t = {sample * 1e-9:.3f} s within {self.deadline:g} s "
                  f"(process dead or deadline missed)")
        self._unanswered_since = None  # one failover per unanswered stretch
        if failed == fallback:
            self.failover_message = f"{reason}; it is the fallback: nothing to fail over to"
            self.get_logger().error(self.failover_message, throttle_duration_sec=5.0)
            return
        self.core.set_state(failed, "unknown")
        self.core.record_failover(failed, sample, reason)
        self._transition_quietly(failed)
        problem = self._activate(fallback, self.switch_timeout)
        self.failover_message = f"failover: {reason}; " + (f"{fallback} failed too: {problem}" if problem
                                                          else f"{fallback} active")
        self.get_logger().error(self.failover_message)
        self._diagnose()

    def _transition_quietly(self, name: str) -> None:
        """Ask a failed controller to deactivate (it may be dead: nobody waits for the answer)."""
        if self.change[name].service_is_ready():
            request = ChangeState.Request()
            request.transition.id = Transition.TRANSITION_DEACTIVATE
            self.change[name].call_async(request)

    def destroy_node(self):
        self._client_executor.shutdown()
        self._client_node.destroy_node()
        return super().destroy_node()

    def _diagnose(self) -> None:
        values = {"active": self.core.active or "", "fallback": self.core.fallback,
                  "failovers": len(self.core.failovers), "invalid_commands": self.invalid_commands,
                  "slow_answers": self.slow_answers,
                  "last_failover": self.failover_message}
        for name, c in self.core.controllers.items():
            values[f"{name}.forwarded"] = c.commands_forwarded
            values[f"{name}.dropped"] = c.commands_dropped
        level = DiagnosticStatus.ERROR if self.core.failovers else DiagnosticStatus.OK
        message = self.failover_message or (f"{self.core.active} active" if self.core.active else "no controller active")
        self.diagnostics.publish(diagnostic_array("seapup/controller_manager", level,
                                                  message, values, self.latest_sample_ns or 0))


def main(args=None) -> int:
    return run_node(ControllerManagerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
