"""The ``velocity_controller`` node: any registered velocity controller as a lifecycle node.

A thin shell over a :class:`~seapup_common.contract.VelocityController` made
by :func:`seapup_common.controllers.create_controller` from the parameter
``controller_type`` (a registered type name: ``mfol``, ``hold`` or a
package's own) with its design document ``controller_file`` and the law's own
parameters (declared by name once the type is known: ``schedule`` and
``blade_pitch_limit`` for ``mfol``), managed like a ros2_control controller
(configure, activate, deactivate), so a controller manager can swap it at run
time. The executable ``mfol_velocity_controller`` is this node named
``mfol_velocity_controller`` with ``controller_type: mfol`` (launch files of
the MFOL-only era keep working).

- **configure** builds the law (an unknown type, unknown parameters or an
  unusable file fail the transition with the reason in the log);
- **activate** starts it bumpless from the blade pitch the vehicle applies
  (``/seapup/thrusters/applied``; when none has been heard yet in lockstep, a
  sample waits ``applied_wait`` for it, then starts from the law's
  ``fallback_command()`` where it has one, else zero pitch); activated while
  the graph is held at a sample the controller manager already forwarded an
  answer to (``/seapup/controller_manager/forwarded``), it leaves that sample
  to the outgoing controller and starts at the next, from the pitch applied
  up to it;
- every sample it reads ``/seapup/sensors/velocity``, tells the law the
  applied pitch stamped with the sample (:meth:`VelocityController.applied`),
  takes the reference in force on ``/seapup/velocity_controller/reference``
  (``geometry_msgs/TwistStamped``: linear x, y, z = u, v, w [m/s], angular z =
  r [rad/s], ``base_link_frd``, taking effect at its header stamp, at once when
  the stamp is zero: :class:`~seapup_common.contract.StampedReferences`) and
  publishes ``/seapup/thrusters/command`` stamped with the sample time;
- **deactivate** stops commanding.

With ``wait_for_command_subscribers`` n > 0 the first command is held until n
subscriptions have matched the command publisher
(:class:`~seapup_common.ros.graph.SubscriberGate`): in lockstep, simulated
time stands still meanwhile, so a run's probe or recorder hears every
command.

With ``start_at``/``stop_at`` (lockstep) the node answers only the samples of
that window of simulated time and starts at ``start_at`` from the applied pitch
stamped with that sample: a run's scheduled controller switch falls on one
sample whatever the wall-clock timing.

When a lockstep sample is answered and how long it waits for its reference,
the first reference or the applied pitch is
:class:`seapup_common.lockstep.SamplePolicy` (pure and unit-tested); this
file only feeds it the events and arms a wall-clock timer for the time it
says to come back. Non-finite or malformed references and sensor messages are
rejected, counted and logged, never integrated. ``/diagnostics`` carries the
law's :meth:`~VelocityController.diagnostics` and the node's counts (WARN
with the reason while a self-tuner has fallen back to its fixed gains). A law
with an estimate (the self-tuners of ch. 7: ``estimate_matrix()`` and
``named_estimate()``) also publishes ``~/estimate``
(``seapup_msgs/ControllerEstimate``: Theta, the named traces, the mode, the
jacket's reason and counts) after every sample it answers; the status on
``/diagnostics`` comes every ``diagnostics_every`` samples, in lockstep no
more often than real time would give
(:class:`~seapup_control.ros.diagnostics_pace.DiagnosticsPace`), and at once when the node (configured)
hears its first stamped reference (``reference_stream_start``, its stamp [s]): a harness holding the graph
resumes it only once the active controller has it.

The per-sample inputs (velocity, applied pitch, reference, ``/clock``) are
subscribed as bytes and read without message objects
(:mod:`seapup_control.ros.sample_inputs`: the typed conversions' results and
refusals, bit for bit; bytes rclpy cannot read are refused and counted with
the rest); the command is published as bytes.
"""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Twist, TwistStamped, TwistWithCovarianceStamped
from rclpy.clock import Clock as SteadyClock, ClockType
from rclpy.exceptions import ParameterUninitializedException
from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn
from rosgraph_msgs.msg import Clock
from seapup_msgs.msg import BladePitch, ControllerEstimate

from seapup_common.blade_pitch import VIRTUAL_INPUT_LIMIT
from seapup_common.contract import Command, ContractError, StampedReferences
from seapup_common.controllers import (ControllerRegistryError, ControllerSpec, available_controllers,
                                       at_input_limit, controller_type, create_controller)
from seapup_common.lockstep import ANSWER, SKIP, WAIT, SamplePolicy, WaitSettings
from seapup_common.ros.messages import MeasurementCollector, SampleFeed, diagnostic_array, ns_to_stamp, stamp_to_ns
from seapup_common.ros.graph import SubscriberGate
from seapup_common.ros.node import (COMMAND_QOS, QUIET_PUBLISHER, QUIET_SUBSCRIPTION, RELIABLE_QOS, STREAM_QOS,
                                    QosWatch, declare_from_package_file, declare_guarded, one_of,
                                    graph_time_ns, refuse_invalid_transitions, run_node, text)
from seapup_common.ros.sample_bytes import command_bytes
from seapup_common.topics import CLOCK, DIAGNOSTICS, FORWARDED_COMMAND, NAMESPACE
from seapup_control.ros.diagnostics_pace import DiagnosticsPace
from seapup_control.ros.sample_inputs import RawSampleFeed, command_of, reference_of

__all__ = ["VelocityControllerNode", "main", "main_mfol", "RANGES"]

#: Allowed values of the node's numeric parameters ([s] wall or simulated, counts): anything else,
#: NaN and inf included, is refused at start and by ``param set``.
RANGES = {"sample_period": (0.0, 10.0), "applied_wait": (0.0, 600.0), "reference_wait": (0.0, 600.0),
          "reference_stream": (0.0, 3600.0), "first_reference_wait": (0.0, 600.0), "start_at": (0.0, 1e9),
          "stop_at": (0.0, 1e9), "reference_horizon": (0.0, 1e9), "wait_for_command_subscribers": (0, 100),
          "diagnostics_every": (1, 10**6), "input_limit": (0.0, VIRTUAL_INPUT_LIMIT)}


def allowed_values() -> dict:
    """The allowed values of the node's string parameters (:class:`~seapup_common.ros.node.Allowed`)."""
    def readable(path: str) -> str:
        return "" if not path or Path(path).is_file() else "no such file (a self-test's controller file, or empty)"
    return {"controller_type": one_of(*available_controllers()),
            "controller_file": text("a controller file (YAML, read on configure), or empty", readable)}


def law_ranges(kind) -> dict:
    """The range of each numeric parameter of a law: its declared one (:class:`~seapup_common.controllers.Ranged`),
    else (a package's law that declares none) any finite number."""
    return {name: kind.ranges.get(name, (-math.inf, math.inf)) for name, default in kind.parameters.items()
            if isinstance(default, (int, float, list, tuple)) and not isinstance(default, bool)}


def law_descriptors(kind) -> dict:
    """A descriptor per law parameter: its range's source as the description."""
    from rcl_interfaces.msg import ParameterDescriptor, ParameterType
    out = {}
    for name, default in kind.parameters.items():
        source = kind.sources.get(name, "a parameter of the law")
        out[name] = ParameterDescriptor(description=f"{kind.name}: {source}")
        if isinstance(default, (list, tuple)) and not default:
            out[name].type = ParameterType.PARAMETER_DOUBLE_ARRAY
    return out


class VelocityControllerNode(LifecycleNode):
    """rclpy lifecycle shell around a registered velocity controller (see the module docstring).

    Parameters
    ----------
    name : str
        Node name (``velocity_controller``; the MFOL alias passes ``mfol_velocity_controller``).
    default_type : str
        ``controller_type`` when none is given.
    """

    #: Spun by rclpy's EventsExecutor unless told otherwise (seapup_common.ros.node.DEFAULT_EXECUTOR: measured
    #: faster, soaked and hostile-tested for this node).
    EXECUTOR = "events"

    def __init__(self, name: str = "velocity_controller", default_type: str = "mfol", **kwargs):
        super().__init__(name, namespace=NAMESPACE, **kwargs)
        self.p = declare_from_package_file(self, "seapup_control", "velocity_controller.yaml",
                                           section="velocity_controller", ranges=RANGES, allowed=allowed_values())
        if default_type != self.p["controller_type"] and not self._overridden("controller_type"):
            self.set_parameters([self._parameter("controller_type", default_type)])
        self.kind = controller_type(self.get_parameter("controller_type").value)  # unknown: the node refuses to start
        clash = sorted(set(self.kind.parameters) & set(self.p))
        if clash:
            raise ControllerRegistryError(f"controller type {self.kind.name!r} parameters {clash} clash with the "
                                          "node's own")
        self.add_on_set_parameters_callback(self._law_is_fixed)
        self.law_parameters = declare_guarded(self, dict(self.kind.parameters), law_descriptors(self.kind),
                                              law_ranges(self.kind), where=f"controller type {self.kind.name!r}")
        self.controller = None
        self.counts = {"samples": 0, "rejected_references": 0, "rejected_measurements": 0, "rejected_applied": 0,
                       "skipped_samples": 0, "late_references": 0, "late_applied": 0}
        self.references = StampedReferences()
        self._reference_stream_start: float | None = None   # [s] the first stamped reference heard
        self.applied: np.ndarray | None = None      # the latest applied blade pitch heard
        self._applied_at: dict[int, Command] = {}  # applied pitch by sample stamp (the last few)
        self._interfaces = []
        self._timer = None
        refuse_invalid_transitions(self)  # e.g. a second activate: refused, not fatal
        if self.p["autostart"]:
            if self.trigger_configure() == TransitionCallbackReturn.SUCCESS:
                self.trigger_activate()
            else:
                self.get_logger().error("autostart: not activated, the configuration failed (see above)")

    def _law_is_fixed(self, parameters):
        """``controller_type`` is read once, at start: another law needs another node."""
        from rcl_interfaces.msg import SetParametersResult
        for parameter in parameters:
            if parameter.name == "controller_type" and parameter.value != self.kind.name:
                return SetParametersResult(successful=False, reason=(
                    f"controller_type = {parameter.value!r} refused: it is fixed at start ({self.kind.name}); "
                    "start another velocity_controller for another law"))
        return SetParametersResult(successful=True)

    def _overridden(self, name: str) -> bool:
        return name in self._parameter_overrides

    @staticmethod
    def _parameter(name, value):
        from rclpy.parameter import Parameter
        return Parameter(name, value=value)

    def _value(self, name: str):
        try:
            return self.get_parameter(name).value
        except ParameterUninitializedException:  # an empty list given on the command line has no type
            return []

    # -- life cycle ------------------------------------------------------------------
    def on_configure(self, state) -> TransitionCallbackReturn:
        parameters = {}
        for name, default in self.kind.parameters.items():
            value = self._value(name)
            parameters[name] = list(value) if isinstance(default, (list, tuple)) else value
        parameters = at_input_limit(self.kind, parameters, float(self._value("input_limit")))
        period = float(self._value("sample_period")) or None
        spec = ControllerSpec(self.kind.name, parameters, self._value("controller_file") or None)
        try:
            self.controller = create_controller(spec, period)
        except ControllerRegistryError as exc:
            self.get_logger().error(f"configure failed: {exc}")
            return TransitionCallbackReturn.FAILURE
        lockstep = bool(self._value("lockstep"))
        self.collector = MeasurementCollector()
        self.policy = SamplePolicy(lockstep, WaitSettings(
            applied_wait=float(self._value("applied_wait")), reference_wait=float(self._value("reference_wait")),
            reference_stream=float(self._value("reference_stream")),
            first_reference_wait=float(self._value("first_reference_wait")), needs_applied=self.kind.needs_applied,
            reference_every_sample=bool(self._value("reference_every_sample")),
            start_at=float(self._value("start_at")), stop_at=float(self._value("stop_at"))))
        self.feed = SampleFeed(self.collector, self.policy, self._rejected)
        self.raw_feed = RawSampleFeed(self.feed)
        self.pace = DiagnosticsPace(self.controller.sample_period, lockstep)
        self.publisher = self.create_lifecycle_publisher(BladePitch, "thrusters/command", STREAM_QOS,
                                                         event_callbacks=QUIET_PUBLISHER)
        self.gate = SubscriberGate([(self.publisher, int(self._value("wait_for_command_subscribers")))])
        self.diagnostics = self.create_publisher(DiagnosticArray, DIAGNOSTICS, RELIABLE_QOS,
                                                 event_callbacks=QUIET_PUBLISHER)
        # a self-tuner (ch. 7) says its estimate and jacket state after every sample it answers
        self.estimates = (self.create_lifecycle_publisher(ControllerEstimate, "~/estimate", STREAM_QOS,
                                                          event_callbacks=QUIET_PUBLISHER)
                          if callable(getattr(self.controller, "estimate_matrix", None)) else None)
        def subscribe(kind, topic, callback, qos, raw=False):  # no event handlers on the executor's path: QosWatch
            return self.create_subscription(kind, topic, callback, qos, event_callbacks=QUIET_SUBSCRIPTION, raw=raw)
        self._interfaces = [   # the per-sample inputs as bytes (sample_inputs)
            subscribe(TwistWithCovarianceStamped, "sensors/velocity", self._on_velocity, COMMAND_QOS, raw=True),
            subscribe(TwistStamped, "velocity_controller/reference", self._on_reference, COMMAND_QOS, raw=True),
            subscribe(BladePitch, "thrusters/applied", self._on_applied, RELIABLE_QOS, raw=True),
            # a controller manager's copy of what reached the vehicle: activated while the graph is held at a
            # sample the outgoing controller answered, this one starts at the next (SamplePolicy)
            subscribe(BladePitch, FORWARDED_COMMAND,
                      lambda msg: self.policy.on_vehicle_command(stamp_to_ns(msg.header.stamp)), RELIABLE_QOS)]
        if callable(getattr(self.controller, "pilot", None)):   # manual flight: the pilot's stick (REP-103 Twist)
            self._pilot_said = None   # the sample whose stick diagnostics last said (_on_pilot)
            self._interfaces.append(subscribe(Twist, "pilot/cmd_vel", self._on_pilot, COMMAND_QOS))
        self._qos_watch = QosWatch(self)
        if lockstep:
            self._interfaces.append(subscribe(Clock, CLOCK, self._on_clock, RELIABLE_QOS, raw=True))
        else:
            self._interfaces.append(self.create_timer(self.controller.sample_period, self._on_timer))
        self.get_logger().info(f"configured {self.kind.name} ({spec.file or 'no file'}; "
                               + ", ".join(f"{k} {v}" for k, v in parameters.items())
                               + f"), T = {self.controller.sample_period:g} s")
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state) -> TransitionCallbackReturn:
        if self.policy.activate(heard_applied=self.applied is not None):
            self._start()
        else:
            self.get_logger().info("active: waiting for the applied blade pitch to start bumpless")
        result = super().on_activate(state)
        if self.policy.lockstep and self.policy.latest_ns is not None:
            self._answer(self.policy.latest_ns)  # a sample that arrived before activation waits for its answer
        return result

    def _start(self, t_ns: int | None = None) -> None:
        at = self._applied_at.get(t_ns)
        applied, source = self.applied if at is None else at.blade_pitch, "the applied blade pitch"
        if applied is None:
            fallback = getattr(self.controller, "fallback_command", None)
            applied = np.asarray(fallback(), float) if fallback is not None else np.zeros(4)
            source = "the law's fallback setting (no applied pitch heard)"
        t_ns = t_ns if t_ns is not None else (self.policy.latest_ns or 0)
        self.controller.reset(Command(applied, stamp=t_ns * 1e-9))  # bumpless: from what the vehicle holds now
        self.get_logger().info(f"starting from {source}: " + ", ".join(f"{np.degrees(a):.2f}" for a in applied)
                               + " deg")

    def on_deactivate(self, state) -> TransitionCallbackReturn:
        self.policy.deactivate()
        return super().on_deactivate(state)

    def on_cleanup(self, state) -> TransitionCallbackReturn:
        for item in self._interfaces:
            (self.destroy_timer if hasattr(item, "timer_period_ns") else self.destroy_subscription)(item)
        self._interfaces = []
        self.destroy_lifecycle_publisher(self.publisher)
        self.destroy_publisher(self.diagnostics)
        if self.estimates is not None:
            self.destroy_lifecycle_publisher(self.estimates)
            self.estimates = None
        self.controller = None
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state) -> TransitionCallbackReturn:
        if self.controller is not None:
            self.policy.deactivate()
        return TransitionCallbackReturn.SUCCESS

    # -- inputs ----------------------------------------------------------------------
    def _on_reference(self, data: bytes) -> None:
        try:
            reference, stamp_ns = reference_of(data)
            at = None if stamp_ns == 0 else stamp_ns * 1e-9
            latest = self.policy.latest_ns
            horizon = float(self._value("reference_horizon"))
            if at is not None and latest is not None and at > latest * 1e-9 + horizon:
                raise ContractError(f"stamped {at - latest * 1e-9:.3g} s after the latest sample (more than "
                                    f"reference_horizon {horizon:g} s): a wall-clock stamp on a sim-time graph?")
            self.references.add(reference, at)
        except ContractError as exc:
            self.counts["rejected_references"] += 1
            self.get_logger().warn(f"reference rejected: {exc}", throttle_duration_sec=2.0)
            return
        first = at is not None and self._reference_stream_start is None
        if first:
            self._reference_stream_start = at
        if self.policy.on_reference(at) and self.policy.latest_ns is not None:
            self._answer(self.policy.latest_ns)  # the sample that waited for it
        if first and self.controller is not None:
            self._diagnose(self.policy.latest_ns or 0)   # said at once (module docstring)

    def _on_applied(self, data: bytes) -> None:
        try:
            command, t_ns = command_of(data)
        except ValueError as exc:  # the simulator never publishes such: counted, nothing to start from
            self.counts["rejected_applied"] += 1
            self.get_logger().warn(f"applied blade pitch rejected: {exc}", throttle_duration_sec=2.0)
            return
        self.applied = command.blade_pitch
        self._applied_at[t_ns] = command   # stamped t_ns: what the law is told at that sample
        while len(self._applied_at) > 8:
            self._applied_at.pop(next(iter(self._applied_at)))
        if self.controller is not None and self.policy.on_applied(t_ns) and self.policy.latest_ns is not None:
            self._answer(self.policy.latest_ns)  # a sample that waited for it

    def _rejected(self, reason: str) -> None:  # a non-finite or malformed sensor message: counted, never used
        self.counts["rejected_measurements"] += 1
        self.get_logger().warn(f"sensor message rejected: {reason}", throttle_duration_sec=2.0)

    def _on_pilot(self, msg) -> None:
        """The pilot's demand, timed by the graph's time as the node knows it (its clock under ``use_sim_time``,
        else the newest sample: :func:`~seapup_common.ros.node.graph_time_ns`; the wall clock would make a
        stick on a simulated-time graph never silent); a malformed one counted. Said in diagnostics
        (``pilot_received``) at once, but once a sample at most (a teleop panel sends at 10-50 Hz): a harness
        holding the graph waits for its stick there."""
        t_ns = graph_time_ns(self, self.policy.latest_ns)
        try:
            self.controller.pilot(t_ns * 1e-9, (msg.linear.x, msg.linear.y, msg.linear.z),
                                  (msg.angular.x, msg.angular.y, msg.angular.z))
        except ContractError as exc:   # a non-finite stick: counted in diagnostics, never flown
            self.counts["rejected_pilot"] = self.counts.get("rejected_pilot", 0) + 1
            self.get_logger().warn(f"pilot message rejected: {exc}", throttle_duration_sec=2.0)
        if t_ns != self._pilot_said:
            self._pilot_said = t_ns
            self._diagnose(t_ns)

    def _on_velocity(self, data: bytes) -> None:
        t_ns = self.raw_feed.velocity(data)
        if t_ns is not None:
            self._answer(t_ns)

    def _on_clock(self, data: bytes) -> None:
        t_ns = self.raw_feed.clock(data, self.get_logger())
        if t_ns is not None:
            self._answer(t_ns)

    def _on_timer(self) -> None:
        self._answer(self.get_clock().now().nanoseconds)

    # -- the loop --------------------------------------------------------------------
    def _answer(self, t_ns: int) -> None:
        if (self.policy.active and self.policy.pending(t_ns) is not None and self.policy.in_window(t_ns)
                and not self.gate.ready()):
            # the first command waits until every awaited subscriber (the simulator, a run's probe or
            # recorder) has matched the publisher: simulated time stands still meanwhile
            self.get_logger().info("holding the first command: waiting for subscribers of "
                                   + ", ".join(self.gate.missing()), throttle_duration_sec=5.0)
            self._wake_at(time.monotonic() + 0.05)
            return
        decision = self.policy.decide(t_ns, time.monotonic())
        if decision.action == SKIP:
            # not this node's sample (inactive, outside its window, answered): it keeps the reference in
            # force up to date (the position level streams one per sample: waiting ones would pile up to
            # the schedule's capacity and the newest be refused), so when it takes over it uses the
            # present reference
            self.references.at(t_ns * 1e-9)
            return
        if decision.start:
            self._start(t_ns)
        for what in decision.late:
            self.counts["late_references" if what == "reference" else "late_applied"] += 1
        if decision.action == WAIT:
            self._wake_at(decision.wake_at)
            return
        if decision.action != ANSWER:
            return
        t = t_ns * 1e-9
        if t_ns in self._applied_at:
            self.controller.applied(t, self._applied_at[t_ns])   # stamped t: checked once, when heard
        try:
            command = self.controller.update(t, self.collector.measurement(t), self.references.at(t))
        except ContractError as exc:  # no fresh velocity: nothing is integrated, the vehicle holds
            self.counts["skipped_samples"] += 1
            self.get_logger().warn(f"sample t = {t:.3f} s skipped: {exc}", throttle_duration_sec=2.0)
            return
        self.policy.answered(t_ns)
        self.counts["samples"] += 1
        self.publisher.publish(command_bytes(command.blade_pitch, t_ns))  # serialised: a fraction of the cost
        if self.estimates is not None:
            self.estimates.publish(self._estimate(t_ns))
        # a wall-clock limit that ended a wait (seapup_common.lockstep.ENDED_WAITS) is said at once
        if decision.late or self.pace.due(self.counts["samples"], max(1, int(self._value("diagnostics_every"))),
                                          time.monotonic()):
            self._diagnose(t_ns)

    def _wake_at(self, wake_at: float) -> None:
        """Decide the latest sample again at ``wake_at`` (monotonic wall time): simulated time stands still
        while a lockstep sample waits, so it must go on even if what it waits for never comes."""
        if self._timer is not None:
            self.destroy_timer(self._timer)

        def fire():
            self.destroy_timer(timer)
            if self._timer is timer:
                self._timer = None
            if self.policy.active and self.policy.latest_ns is not None:
                self._answer(self.policy.latest_ns)
        timer = self.create_timer(max(wake_at - time.monotonic(), 0.0) + 1e-3, fire,
                                  clock=SteadyClock(clock_type=ClockType.STEADY_TIME))
        self._timer = timer

    def _estimate(self, t_ns: int) -> ControllerEstimate:
        """The self-tuner's estimate after this sample (``seapup_msgs/ControllerEstimate``)."""
        law = self.controller
        theta = law.estimate_matrix()
        named = law.named_estimate()
        counts = dict(getattr(law, "counts", {}))
        msg = ControllerEstimate(controller=self.get_name(), type=self.kind.name, mode=str(getattr(law, "mode", "")),
                                 reason=str(getattr(law, "reason", "")), frozen=str(getattr(law, "frozen", "")),
                                 names=list(named), values=[float(v) for v in named.values()],
                                 rows=theta.shape[0], cols=theta.shape[1] if theta.ndim > 1 else 1,
                                 theta=theta.ravel().tolist(), counters=list(counts),
                                 counts=[int(v) for v in counts.values()])
        msg.header.stamp = ns_to_stamp(t_ns)
        msg.header.frame_id = "base_link_frd"
        return msg

    def _diagnose(self, t_ns: int) -> None:
        law = self.controller.diagnostics()
        values = {"controller_type": self.kind.name, **self.counts, **law,
                  "reference": self.references.current.velocity.tolist(),
                  "references_waiting": self.references.waiting,
                  "reference_stream_start": self._reference_stream_start}
        rejected = (self.counts["rejected_references"] + self.counts["rejected_measurements"]
                    + self.counts["rejected_applied"])
        saturated = any(law.get("saturated", ()))
        fallen_back = law.get("mode") == "fallback"   # a self-tuner's jacket refused its estimate (ch. 7)
        qos = self._qos_watch.problems()
        level = DiagnosticStatus.WARN if (rejected or saturated or fallen_back or qos) else DiagnosticStatus.OK
        message = (f"fallback: {law.get('reason', '')}" if fallen_back else "saturated" if saturated else "tracking")
        message += "".join(f"; {problem}" for problem in qos)
        self.diagnostics.publish(diagnostic_array(f"seapup/{self.get_name()}", level, message, values, t_ns))


def main(args=None) -> int:
    """``velocity_controller``: the law named by ``controller_type``."""
    return run_node(VelocityControllerNode, args)


def main_mfol(args=None) -> int:
    """``mfol_velocity_controller``: the same node, named so, flying ``mfol`` unless told otherwise."""
    return run_node(lambda: VelocityControllerNode("mfol_velocity_controller", "mfol"), args)


if __name__ == "__main__":
    sys.exit(main())
