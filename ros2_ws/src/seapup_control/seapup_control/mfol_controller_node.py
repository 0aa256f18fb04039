"""The ``mfol_velocity_controller`` node: Owens and Chotai's velocity controller as a lifecycle node.

A thin shell over :class:`seapup_control.mfol_controller.MFOLController`,
managed like a ros2_control controller (configure, activate, deactivate), so
a controller manager can swap it at run time:

- **configure** loads the gains from ``controller_file`` (the YAML a
  self-test writes, :func:`~seapup_control.self_test.result_document`):
  every operating point as a gain schedule on surge speed, or only the
  zero-speed point with ``schedule: false``;
- **activate** starts it bumpless from the blade pitches the vehicle applies
  (``/seapup/thrusters/applied``; in lockstep, when none has been heard yet,
  a sample waits up to ``applied_wait`` wall seconds for the one
  the simulator publishes with it, then falls back to the file's zero-speed
  offset u0; a sample that arrived before activation is answered at once),
  then every sample it reads
  ``/seapup/sensors/velocity`` and the reference in force on
  ``/seapup/velocity_controller/reference`` (``geometry_msgs/TwistStamped``:
  linear x, y, z = u, v, w [m/s], angular z = r [rad/s], ``base_link_frd``;
  a reference takes effect at its header stamp — at once when the stamp is
  zero or past — so a stamped setpoint lands exactly on its sample:
  :class:`~seapup_common.contract.ReferenceSchedule`)
  and publishes ``/seapup/thrusters/command`` stamped with the sample time
  (``lockstep``: each sensor sample t_k of a lockstep simulator, or its
  repeated ``/clock`` t_k, is answered once; otherwise a timer). In lockstep,
  while stamped references stream in (the newest two stamped within
  ``reference_stream`` s of each other and of the sample), sample t_k waits
  up to ``reference_wait`` wall seconds for the reference stamped t_k (then
  goes on with the one in force, counted as ``late_references``): the simulator then waits for the whole
  hierarchy, not only this loop, and the outer loops keep their designed
  delay however fast the simulation runs (without it they fell up to 5 s
  behind in the demo mission). With ``first_reference_wait`` > 0 the first
  sample also waits (that long at most) for the first reference, so a
  reference schedule started after the simulator still sets the first sample's;
- **deactivate** stops commanding.

Non-finite or malformed references and sensor messages are rejected,
counted and logged, never integrated. ``/diagnostics`` carries the loop's
state: errors, integrator states, commands before saturation, saturated
thrusters and the counts.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import yaml
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import TwistStamped, TwistWithCovarianceStamped
from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn
from rclpy.clock import Clock as SteadyClock, ClockType
from rosgraph_msgs.msg import Clock
from seapup_msgs.msg import BladePitch

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_common.contract import Command, ContractError, ReferenceSchedule
from seapup_common.ros.messages import (LockstepSampler, MeasurementCollector, command_to_msg, diagnostic_array,
                                        reference_from_msg, stamp_to_ns)
from seapup_common.ros.node import (COMMAND_QOS, RELIABLE_QOS, declare_from_package_file, refuse_invalid_transitions,
                                    run_node)
from seapup_control.mfol import DesignError
from seapup_control.mfol_controller import GainSchedule, MFOLController

__all__ = ["MFOLControllerNode", "main"]


class MFOLControllerNode(LifecycleNode):
    """rclpy lifecycle shell around :class:`MFOLController` (see the module docstring)."""

    def __init__(self, **kwargs):
        super().__init__("mfol_velocity_controller", namespace="/seapup", **kwargs)
        self.p = declare_from_package_file(self, "seapup_control", "mfol_velocity_controller.yaml",
                                           defaults={"blade_pitch_limit": BLADE_PITCH_LIMIT},
                                           section="mfol_velocity_controller")
        self.controller: MFOLController | None = None
        self.active = False
        self.counts = {"samples": 0, "rejected_references": 0, "rejected_measurements": 0, "skipped_samples": 0,
                       "late_references": 0}
        self._newest_reference: float | None = None   # latest reference stamp heard [s]
        self._previous_reference: float | None = None  # the one before it (a stream has both, close)
        self._reference_waiting: tuple[int, float] | None = None  # (sample, wall time) waiting for its reference
        self._heard_reference = False  # any reference accepted (first_reference_wait)
        self._first_wait_since: float | None = None  # when a sample first waited for the first reference
        self.references = ReferenceSchedule()
        self.applied: np.ndarray | None = None
        self._start_pending = False  # lockstep: active, waiting for the applied pitch to start from
        self._sample_waiting_since: float | None = None  # when a sample first waited for it
        self._interfaces = []
        refuse_invalid_transitions(self)  # e.g. a second activate: refused, not fatal
        if self.p["autostart"]:
            self.trigger_configure()
            self.trigger_activate()

    # -- life cycle ------------------------------------------------------------------
    def on_configure(self, state) -> TransitionCallbackReturn:
        path = Path(self.get_parameter("controller_file").value or "")
        try:
            document = yaml.safe_load(path.read_text())
            schedule = GainSchedule.from_document(document)
            if not self.get_parameter("schedule").value:
                schedule = GainSchedule([(schedule.speeds[0], schedule.gains[0])])
            self.controller = MFOLController(schedule, limit=float(self.get_parameter("blade_pitch_limit").value))
        except (OSError, yaml.YAMLError, DesignError) as exc:
            self.get_logger().error(f"configure failed: controller_file {str(path)!r}: {exc}")
            return TransitionCallbackReturn.FAILURE
        self.collector = MeasurementCollector()
        self.sampler = LockstepSampler(self.collector, bool(self.get_parameter("lockstep").value))
        self.publisher = self.create_lifecycle_publisher(BladePitch, "thrusters/command", RELIABLE_QOS)
        self.diagnostics = self.create_publisher(DiagnosticArray, "/diagnostics", RELIABLE_QOS)
        self._interfaces = [
            self.create_subscription(TwistWithCovarianceStamped, "sensors/velocity", self._on_velocity, COMMAND_QOS),
            self.create_subscription(TwistStamped, "velocity_controller/reference", self._on_reference, COMMAND_QOS),
            self.create_subscription(BladePitch, "thrusters/applied", self._on_applied, RELIABLE_QOS)]
        if self.get_parameter("lockstep").value:
            self._interfaces.append(self.create_subscription(Clock, "/clock", self._on_clock, RELIABLE_QOS))
        else:
            self._interfaces.append(self.create_timer(self.controller.sample_period, self._on_timer))
        speeds = ", ".join(f"{s:g}" for s in self.controller.schedule.speeds)
        self.get_logger().info(f"configured from {path}: operating points {speeds} m/s, "
                               f"T = {self.controller.sample_period:g} s")
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state) -> TransitionCallbackReturn:
        self.active = True
        if self.applied is None and self.get_parameter("lockstep").value:
            # the simulator publishes the applied pitch with every sample: start from it, not from u0
            self._start_pending, self._sample_waiting_since = True, None
            self.get_logger().info("active: waiting for the applied blade pitch to start bumpless")
        else:
            self._start(self.applied, "the applied blade pitch")
        result = super().on_activate(state)
        if self.get_parameter("lockstep").value and self.sampler.latest_ns is not None:
            self._answer(self.sampler.latest_ns)  # a sample that arrived before activation waits for its answer
        return result

    def _start(self, applied, source: str) -> None:
        if applied is None:
            applied, source = self.controller.schedule.offset_at(0.0), "the zero-speed offset u0 (no applied pitch heard)"
        self.controller.reset(Command(applied))  # bumpless: from what the vehicle holds now
        self._start_pending = False
        self.get_logger().info(f"starting from {source}: "
                               + ", ".join(f"{np.degrees(a):.2f}" for a in applied) + " deg")

    def on_deactivate(self, state) -> TransitionCallbackReturn:
        self.active = False
        self._start_pending = False
        return super().on_deactivate(state)

    def on_cleanup(self, state) -> TransitionCallbackReturn:
        for item in self._interfaces:
            (self.destroy_timer if hasattr(item, "timer_period_ns") else self.destroy_subscription)(item)
        self._interfaces = []
        self.destroy_lifecycle_publisher(self.publisher)
        self.destroy_publisher(self.diagnostics)
        self.controller = None
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state) -> TransitionCallbackReturn:
        self.active = False
        return TransitionCallbackReturn.SUCCESS

    # -- inputs ----------------------------------------------------------------------
    def _on_reference(self, msg: TwistStamped) -> None:
        try:
            reference = reference_from_msg(msg)
            stamp_ns = stamp_to_ns(msg.header.stamp)
            at = None if stamp_ns == 0 else stamp_ns * 1e-9
            latest = self.sampler.latest_ns
            horizon = float(self.get_parameter("reference_horizon").value)
            if at is not None and latest is not None and at > latest * 1e-9 + horizon:
                raise ContractError(f"stamped {at - latest * 1e-9:.3g} s after the latest sample (more than "
                                    f"reference_horizon {horizon:g} s): a wall-clock stamp on a sim-time graph?")
            self.references.add(reference, at)
            first, self._heard_reference = not self._heard_reference, True
            if first and self.active and self._first_wait_since is not None and self.sampler.latest_ns is not None:
                self._answer(self.sampler.latest_ns)  # the sample that waited for the first reference
            if at is not None and (self._newest_reference is None or at > self._newest_reference):
                self._previous_reference, self._newest_reference = self._newest_reference, at
                if self.active and self._reference_waiting is not None and self.sampler.latest_ns is not None:
                    self._answer(self.sampler.latest_ns)  # the sample that waited for it
        except ContractError as exc:
            self.counts["rejected_references"] += 1
            self.get_logger().warn(f"reference rejected: {exc}", throttle_duration_sec=2.0)

    def _on_applied(self, msg: BladePitch) -> None:
        pitch = np.array(msg.pitch, dtype=float)
        if pitch.shape == (4,) and np.all(np.isfinite(pitch)):
            self.applied = pitch
            if self.active and self._start_pending and self.sampler.latest_ns is not None:
                self._answer(self.sampler.latest_ns)  # a sample that waited for it

    def _on_velocity(self, msg: TwistWithCovarianceStamped) -> None:
        refused = self.collector.rejected
        t_ns = self.sampler.on_velocity(msg)
        if self.collector.rejected > refused:  # non-finite or malformed: counted, never used
            self.counts["rejected_measurements"] += 1
            self.get_logger().warn(f"sensor message rejected: {self.collector.last_error}",
                                   throttle_duration_sec=2.0)
        elif t_ns is not None:
            self._answer(t_ns)

    def _on_clock(self, msg: Clock) -> None:
        t_ns = self.sampler.on_clock(msg)
        if t_ns is not None:
            self._answer(t_ns)

    def _on_timer(self) -> None:
        self._answer(self.get_clock().now().nanoseconds)

    # -- the loop --------------------------------------------------------------------
    def _answer(self, t_ns: int) -> None:
        if not self.active:
            # an inactive controller keeps the reference in force up to date (the position level
            # streams one per sample: waiting ones would pile up to the schedule's capacity and the
            # newest be refused), so when it is switched in it uses the present reference
            self.references.at(t_ns * 1e-9)
            return
        if self.sampler.pending(t_ns) is None:
            return
        if self._start_pending:
            if self._sample_waiting_since is None:
                self._sample_waiting_since = time.monotonic()
                # the applied pitch of this sample may have been published before this node (re)subscribed
                # (configured at a sample boundary): do not wait for the next one, which never comes
                self._wake_after(float(self.get_parameter("applied_wait").value))
            waited = time.monotonic() - self._sample_waiting_since
            if self.applied is None and waited < float(self.get_parameter("applied_wait").value):
                return  # the applied pitch of this sample, or the simulator's /clock repeats, bring it back
            self._start(self.applied, "the applied blade pitch")
        if self._awaiting_reference(t_ns):
            return
        t = t_ns * 1e-9
        try:
            command = self.controller.update(t, self.collector.measurement(t), self.references.at(t))
        except ContractError as exc:  # no fresh velocity: nothing is integrated, the vehicle holds
            self.counts["skipped_samples"] += 1
            self.get_logger().warn(f"sample t = {t:.3f} s skipped: {exc}", throttle_duration_sec=2.0)
            return
        self.sampler.answered(t_ns)
        self.counts["samples"] += 1
        self.publisher.publish(command_to_msg(command, t_ns))
        if self.counts["samples"] % max(1, int(self.get_parameter("diagnostics_every").value)) == 0:
            self._diagnose(t_ns)

    def _awaiting_reference(self, t_ns: int) -> bool:
        """Lockstep: hold sample t_k while the reference stream is live and its reference for t_k is not here."""
        t = t_ns * 1e-9
        first_wait = float(self.get_parameter("first_reference_wait").value)
        if self.get_parameter("lockstep").value and not self._heard_reference and first_wait > 0:
            if self._first_wait_since is None:
                self._first_wait_since = time.monotonic()
                self._wake_after(first_wait)
            if time.monotonic() - self._first_wait_since < first_wait:
                return True  # the first reference, or the retry timer, brings it back
            self.counts["late_references"] += 1
            self._heard_reference = True  # waited once: go on with the reference in force
            return False
        newest, previous = self._newest_reference, self._previous_reference
        stream = float(self.get_parameter("reference_stream").value)
        if (not self.get_parameter("lockstep").value or newest is None or previous is None
                or newest - previous > stream or newest >= t - 1e-9 or newest < t - stream):
            self._reference_waiting = None
            return False
        wait = float(self.get_parameter("reference_wait").value)
        if self._reference_waiting is None or self._reference_waiting[0] != t_ns:
            self._reference_waiting = (t_ns, time.monotonic())
            self._wake_after(wait)
        if time.monotonic() - self._reference_waiting[1] < wait:
            return True  # the reference's arrival, or the retry timer, brings it back
        self._reference_waiting = None
        self.counts["late_references"] += 1
        return False

    def _wake_after(self, after: float) -> None:
        """Answer the latest sample again after ``after`` wall seconds (sim time stands still while a
        lockstep sample waits): a sample waiting for its reference, the first reference or the applied
        pitch then goes on even if what it waits for never comes."""
        def fire():
            timer.cancel()
            self.destroy_timer(timer)
            if self.active and self.sampler.latest_ns is not None:
                self._answer(self.sampler.latest_ns)
        timer = self.create_timer(after + 1e-3, fire, clock=SteadyClock(clock_type=ClockType.STEADY_TIME))

    def _diagnose(self, t_ns: int) -> None:
        state = self.controller.state
        values = {**self.counts, "error": state.error.tolist(), "integrator": state.integrator.tolist(),
                  "command_unsaturated": state.command_unsaturated.tolist(),
                  "saturated": [bool(s) for s in state.saturated],
                  "saturated_samples": self.controller.saturated_samples.tolist(),
                  "reference": self.references.current.velocity.tolist(),
                  "references_waiting": self.references.waiting}
        rejected = self.counts["rejected_references"] + self.counts["rejected_measurements"]
        level = DiagnosticStatus.WARN if (rejected or any(state.saturated)) else DiagnosticStatus.OK
        self.diagnostics.publish(diagnostic_array(f"seapup/{self.get_name()}", level,
                                                  "saturated" if any(state.saturated) else "tracking", values, t_ns))


def main(args=None) -> int:
    return run_node(MFOLControllerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
