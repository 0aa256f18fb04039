"""The ``position_controller`` lifecycle node: the global position controller (thesis sec. 4.2) on the graph.

A thin shell over :class:`seapup_control.position_control.PositionController`.
Subscribes (namespace ``/seapup``) to ``position_controller/reference``
(geometry_msgs/PoseStamped in ``odom_ned``: x, y, z and yaw; a setpoint takes
effect at its header stamp, at once when the stamp is zero) and
``navigation/odometry`` (the navigator's estimate); at every estimate t_k it
publishes ``velocity_controller/reference`` (geometry_msgs/TwistStamped in
``base_link_frd``: u, v, w, r) stamped t_k + ``reference_delay`` x T, the
sample it is meant for. Without a setpoint it publishes nothing (the
velocity controller holds its last reference).

While stamped setpoints stream in (the task controller sends one per
sample, stamped t_k + T at its estimate t_k), the estimate t_k waits up to
``setpoint_wait`` wall seconds for the setpoint stamped t_k before it is
used (then goes on with the one in force, counted as ``late_setpoints``):
on a loaded machine the task controller can fall a sample behind, and the
reference must not depend on that. Non-finite or wrong-frame
setpoints are rejected, counted and logged. Inactive, it publishes nothing.
An estimate stamped as the one before it (the navigator says its newest
again to readers that match late) is ignored and counted
(``repeated_estimates``): tracking it twice would step the law twice.

The first setpoint of a stream (none heard before, or none for more than a sample) is said at once on
``/diagnostics`` (``setpoint_stream_start``, its stamp [s]), once this node has it: a harness holding the graph
resumes it only then, so the next estimate is tracked with it whatever the delivery order or the load (the
task controller's acknowledged send alone was not enough: beside two burners a mission's first estimate after
the goal was once tracked without its setpoint).
The first reference of a stream (the first estimate tracked after none was, for one sample or more) is
waited on until every reader has acknowledged it, and said at once on ``/diagnostics`` (``stream_start``, its
stamp [s]; :func:`seapup_common.ros.node.acknowledge_stream_start`): a harness holding the graph resumes it
only once the velocity controllers have it (they wait for every sample's reference only once one was heard).

``/diagnostics`` (``seapup/position_controller``): while tracking, the setpoint,
the reference and the limits once a wall second; otherwise once a wall second
whether it could track -- OK "idle" when active, hearing the navigator and
matched to a setpoint publisher (a goal's setpoints would be flown at once),
else WARN with the reason -- so a graph is known ready before a goal is sent.
"""
from __future__ import annotations

import math
import time
from collections import deque

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn
from rosgraph_msgs.msg import Clock

from seapup_common.contract import ContractError, StampedReferences
from seapup_common.ros.messages import (diagnostic_array, estimate_from_odometry, pose_setpoint_from_msg,
                                        reference_to_msg, stamp_to_ns)
from seapup_common.ros.node import (COMMAND_QOS, RELIABLE_QOS, STREAM_QOS, acknowledge_stream_start,
                                    declare_from_package_file, graph_time_ns, refuse_invalid_transitions, run_node)
from seapup_common.topics import CLOCK, DIAGNOSTICS, NAMESPACE
from seapup_control.position_control import PoseReference, PositionController, PositionControllerParams

__all__ = ["PositionControllerNode", "main"]

_LAW = ("gains", "yaw_gain", "speed_limits", "max_yaw_rate", "acceleration_limits", "feedforward")


class PositionControllerNode(LifecycleNode):
    """rclpy lifecycle shell around :class:`PositionController` (see the module docstring)."""

    #: Spun by rclpy's EventsExecutor unless told otherwise (seapup_common.ros.node.DEFAULT_EXECUTOR).
    EXECUTOR = "events"

    def __init__(self, **kwargs):
        super().__init__("position_controller", namespace=NAMESPACE, **kwargs)
        self.p = declare_from_package_file(self, "seapup_control", "position_controller.yaml",
                                           section="position_controller", ranges={
                                               "sample_period": (0.01, 10.0), "reference_delay": (0, 100),
                                               "gains": (0.0, 10.0), "yaw_gain": (0.0, 10.0),
                                               "speed_limits": (0.0, 5.0), "max_yaw_rate": (0.0, 5.0),
                                               "acceleration_limits": (1e-4, 10.0),
                                               "setpoint_wait": (0.0, 600.0)})
        self.controller: PositionController | None = None
        self.active = False
        self.counts = {"estimates": 0, "references": 0, "rejected_setpoints": 0, "rejected_estimates": 0,
                       "limited_samples": 0, "late_setpoints": 0, "unacknowledged_stream_starts": 0,
                       "repeated_estimates": 0}
        self._interfaces = []
        refuse_invalid_transitions(self)
        if self.p["autostart"]:
            self.trigger_configure()
            self.trigger_activate()

    def on_configure(self, state) -> TransitionCallbackReturn:
        try:
            params = PositionControllerParams.from_mapping({k: self.get_parameter(k).value for k in _LAW})
            self.controller = PositionController(params, float(self.get_parameter("sample_period").value))
        except ValueError as exc:
            self.get_logger().error(f"configure failed: {exc}")
            return TransitionCallbackReturn.FAILURE
        self.setpoints = StampedReferences(initial=None)
        self.delay = int(self.get_parameter("reference_delay").value) * self.controller.sample_period
        self.publisher = self.create_lifecycle_publisher(TwistStamped, "velocity_controller/reference", STREAM_QOS)
        self.diagnostics = self.create_publisher(DiagnosticArray, DIAGNOSTICS, RELIABLE_QOS)
        self._interfaces = [
            self.create_subscription(PoseStamped, "position_controller/reference", self._on_setpoint, COMMAND_QOS),
            self.create_subscription(Odometry, "navigation/odometry", self._on_estimate, COMMAND_QOS),
            self.create_subscription(Clock, CLOCK, self._on_clock, RELIABLE_QOS)]
        self._clock_ns: int | None = None
        self._last_diag = 0.0
        self._estimate_wall: float | None = None
        self._estimate_ns: int | None = None
        self._idle_timer = self.create_timer(1.0, self._diagnose_idle)
        self._newest_setpoint: float | None = None   # [s] stamp of the newest stamped setpoint
        self._last_reference_ns: int | None = None   # the newest reference's stamp
        self._stream_start: float | None = None      # [s] the stamp of the reference stream's first message
        self._setpoint_stream_start: float | None = None   # [s] and of the setpoint stream's, as heard here
        # estimates not yet tracked, in order: the first waits (until its wall deadline) for its setpoint, the
        # rest behind it (the graph need not wait for this node's answer to one estimate before the next: its
        # reference is for reference_delay samples later), so none is tracked with a setpoint that came late
        self._waiting: deque = deque()               # [estimate, wall deadline]
        self._wait_timer = self.create_timer(0.01, self._check_wait)
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state) -> TransitionCallbackReturn:
        self.controller.reset()
        self.active = True
        return super().on_activate(state)

    def on_deactivate(self, state) -> TransitionCallbackReturn:
        self.active = False
        self._waiting.clear()
        return super().on_deactivate(state)

    def on_cleanup(self, state) -> TransitionCallbackReturn:
        for sub in self._interfaces:
            self.destroy_subscription(sub)
        self._interfaces = []
        self.destroy_timer(self._idle_timer)
        self.destroy_timer(self._wait_timer)
        self.destroy_lifecycle_publisher(self.publisher)
        self.destroy_publisher(self.diagnostics)
        self.controller = None
        return TransitionCallbackReturn.SUCCESS

    def _on_clock(self, msg: Clock) -> None:
        self._clock_ns = stamp_to_ns(msg.clock)

    def _on_setpoint(self, msg: PoseStamped) -> None:
        try:
            position, yaw, stamp_ns = pose_setpoint_from_msg(msg)
            self.setpoints.add(PoseReference(position, yaw, stamp_ns * 1e-9), None if stamp_ns == 0 else stamp_ns * 1e-9)
        except ContractError as exc:
            self.counts["rejected_setpoints"] += 1
            self.get_logger().warn(f"setpoint rejected: {exc}", throttle_duration_sec=2.0)
            return
        if stamp_ns:
            previous = self._newest_setpoint
            self._newest_setpoint = max(previous or 0.0, stamp_ns * 1e-9)
            if previous is None or stamp_ns * 1e-9 > previous + 1.5 * self.controller.sample_period:
                self._setpoint_stream_start = stamp_ns * 1e-9   # a stream starts: said at once (module docstring)
                self._last_diag = -math.inf
                self._diagnose_idle()
        self._drain()

    def _on_estimate(self, msg: Odometry) -> None:
        stamp_ns = stamp_to_ns(msg.header.stamp)
        if stamp_ns == self._estimate_ns:  # the navigator's newest again, for a reader that matched late
            self.counts["repeated_estimates"] += 1
            return
        self._estimate_ns = stamp_ns  # the graph's time, for the idle status
        self._estimate_wall = time.monotonic()  # heard (an estimate before activation counts)
        if not self.active:
            return
        try:
            estimate = estimate_from_odometry(msg)
        except ContractError as exc:
            self.counts["rejected_estimates"] += 1
            self.get_logger().warn(f"estimate rejected: {exc}", throttle_duration_sec=2.0)
            return
        self.counts["estimates"] += 1
        self._waiting.append([estimate, time.monotonic() + float(self.get_parameter("setpoint_wait").value)])
        self._drain()

    def _needs_setpoint(self, estimate) -> bool:
        """While stamped setpoints stream (one per estimate), is the one for ``estimate`` still to come?"""
        newest = self._newest_setpoint
        streaming = newest is not None and newest >= estimate.t - 1.5 * self.controller.sample_period
        return streaming and newest < estimate.t - 1e-6 and float(self.get_parameter("setpoint_wait").value) > 0

    def _drain(self) -> None:
        """Track the waiting estimates in order, each once its setpoint is here or its wait is over."""
        while self._waiting:
            estimate, deadline = self._waiting[0]
            if self._needs_setpoint(estimate):
                if time.monotonic() <= deadline:
                    return
                self.counts["late_setpoints"] += 1
                self._last_diag = -math.inf  # said at once, with this estimate's reference (ENDED_WAITS)
                self.get_logger().warn(f"no setpoint for t = {estimate.t:.3f} s within the setpoint_wait: going "
                                       "on with the one in force", throttle_duration_sec=5.0)
            self._waiting.popleft()
            if self._waiting:  # the next one's wait starts now
                self._waiting[0][1] = max(self._waiting[0][1], time.monotonic()
                                          + float(self.get_parameter("setpoint_wait").value))
            self._track(estimate)

    def _check_wait(self) -> None:
        self._drain()

    def _track(self, estimate) -> None:
        """The reference for the sample after ``estimate`` (reference_delay samples ahead)."""
        if not self.active:
            return
        for setpoint in self.setpoints.due(estimate.t):
            self.controller.set_reference(setpoint)
        if self.controller.reference is None:
            return
        reference = self.controller.update(estimate.position, estimate.attitude)
        self.counts["limited_samples"] += int(bool(self.controller.limited.any()))
        self.counts["references"] += 1
        t_ns = int(round((estimate.t + self.delay) * 1e9))
        self.publisher.publish(reference_to_msg(reference, t_ns))
        previous, self._last_reference_ns = self._last_reference_ns, t_ns
        if previous is None or t_ns - previous > 1.5e9 * self.controller.sample_period:  # a stream starts
            self._stream_start = t_ns * 1e-9
            if not acknowledge_stream_start(self.publisher):
                self.counts["unacknowledged_stream_starts"] += 1
            self._last_diag = -math.inf  # said at once (module docstring)
        if time.monotonic() - self._last_diag > 1.0:
            self._diagnose(t_ns, reference)

    def _diagnose(self, t_ns: int, reference) -> None:
        self._last_diag = time.monotonic()
        setpoint = self.controller.reference
        values = {**self.counts, "setpoint": [*setpoint.position.tolist(), setpoint.yaw],
                  "velocity_reference": reference.velocity.tolist(),
                  "limited": [bool(x) for x in self.controller.limited], "stream_start": self._stream_start,
                  "setpoint_stream_start": self._setpoint_stream_start}
        level = DiagnosticStatus.WARN if self.counts["rejected_setpoints"] else DiagnosticStatus.OK
        self.diagnostics.publish(diagnostic_array(f"seapup/{self.get_name()}", level,
                                                  "tracking", values, t_ns))


    def _diagnose_idle(self) -> None:
        """Once a wall second while not tracking: can a setpoint be flown now?"""
        if time.monotonic() - self._last_diag <= 1.0:
            return
        # the estimate is current by the graph's time when there is a /clock (a lockstep graph held at a sample
        # by its driver stands still: the newest estimate is that sample's), else by its wall-clock age
        heard = self._estimate_wall is not None and (
            time.monotonic() - self._estimate_wall <= 2.0
            or (self._clock_ns is not None and self._estimate_ns is not None
                and self._clock_ns - self._estimate_ns <= 2_000_000_000))
        setpoint_source = self._interfaces[0].get_publisher_count() > 0
        ready = self.active and heard and setpoint_source
        level = DiagnosticStatus.OK if ready else DiagnosticStatus.WARN
        message = "idle" if ready else "inactive" if not self.active else \
            "no navigation estimate" if not heard else "no setpoint publisher (task controller) matched"
        values = {**self.counts, f"subscribers:{self.publisher.topic_name}": self.publisher.get_subscription_count(),
                  "setpoint_stream_start": self._setpoint_stream_start}
        self.diagnostics.publish(diagnostic_array(f"seapup/{self.get_name()}", level, message, values,
                                                  graph_time_ns(self, self._estimate_ns)))


def main(args=None) -> int:
    return run_node(PositionControllerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
