"""The ``self_test`` node: the ``/seapup/self_test`` action server (thesis sec. 4.5.2, 5.3).

A thin shell over :class:`seapup_control.self_test.SelfTest`. It listens to
``/seapup/sensors/velocity`` (u, v, w and the gyro rates: the four outputs of
the velocity loop) and, while a goal runs, answers every sample with a
blade-pitch command on ``/seapup/thrusters/command``:

- ``lockstep`` (default): each sensor sample t_k of a lockstep simulator is
  answered once with a command stamped t_k, triggered by the sample or by the
  simulator's repeated ``/clock`` t_k (its graph-ready handshake);
- otherwise on a timer of the node clock every ``sample_period``.

A goal's test starts at its acceptance, in the callback that sends the goal
response (rclpy's ``handle_accepted_callback``, with no other callback in
between), and at once answers the newest sample heard if it is still
pending: a lockstep graph held at t_0 when the goal is sent has already
delivered t_0, and answering it only when a later callback (the execute
callback, scheduled by rclpy) first saw a sample left the graph waiting for
a command nobody would send whenever t_0's repeat came in between (about
one graph self-test start in six stalled: "no velocity data for 10.0 s").

Feedback (phase, cycle, thruster, operating point, progress, velocities)
goes out every sample. Cancel is honoured at the next sample: the test stops
and, as after success or failure, the node keeps flying the best controller
it found at zero reference (hover) when ``hover_after`` is set. The result
carries B0^-1, B1^-1, u0 and the gains of every operating point and the path
of a controller file (YAML, :func:`~seapup_control.self_test.result_document`).

Artificial quiescence (a plant reset before every step) needs the plant to
be moved, which a vehicle cannot do: it is only offered in process
(``./seapup selftest --mode artificial``).
"""
from __future__ import annotations

import math
import os
import time
from pathlib import Path

from geometry_msgs.msg import TwistWithCovarianceStamped
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.clock import Clock as SteadyClock, ClockType
from rclpy.node import Node
from rclpy.task import Future
from rosgraph_msgs.msg import Clock
from seapup_msgs.action import SelfTest as SelfTestAction
from seapup_msgs.msg import BladePitch, SelfTestSample

from seapup_common.config import ConfigError
from seapup_common.contract import ContractError
from seapup_common.lockstep import SamplePolicy
from seapup_common.ros.messages import MeasurementCollector, SampleFeed, ns_to_stamp
from seapup_common.ros.sample_bytes import command_bytes
from seapup_common.ros.graph import SubscriberGate
from seapup_common.blade_pitch import BLADE_PITCH_LIMIT, VIRTUAL_INPUT_LIMIT
from seapup_common.ros.node import (COMMAND_QOS, RELIABLE_QOS, STREAM_QOS, SERVICE_QOS, declare_from_package_file,
                                    destroy_actions, path_or_empty, run_node)
from seapup_common.topics import CLOCK, NAMESPACE
from seapup_control.mfol import DesignError
from seapup_control.ros.sample_inputs import RawSampleFeed
from seapup_control.self_test import (Phase, SelfTest, SelfTestConfig, goal_overrides, result_document,
                                      write_result_file)

__all__ = ["SelfTestNode", "main"]



class SelfTestNode(Node):
    """rclpy shell around :class:`SelfTest` (see the module docstring)."""

    #: Spun by rclpy's EventsExecutor unless told otherwise (seapup_common.ros.node.DEFAULT_EXECUTOR).
    EXECUTOR = "events"

    def __init__(self, **kwargs):
        super().__init__("self_test", namespace=NAMESPACE, **kwargs)
        p = declare_from_package_file(self, "seapup_control", "self_test.yaml", section="self_test", ranges={
            "no_data_timeout": (0.1, 3600.0), "wait_for_command_subscribers": (0, 100),
            "input_limit": (0.0, VIRTUAL_INPUT_LIMIT),
            "wait_for_sample_subscribers": (0, 100)},
            allowed={"result_dir": path_or_empty("the directory the result files are written into")})
        self.lockstep = bool(p["lockstep"])
        self.hover_after = bool(p["hover_after"])
        root = Path(os.environ.get("SEAPUP_ROOT", "."))
        self.result_dir = Path(p["result_dir"]) if p["result_dir"] else root / "runs" / "self_test"
        self.no_data_timeout = float(p["no_data_timeout"])
        self.input_limit = float(p["input_limit"]) or BLADE_PITCH_LIMIT   # 0: the Seapup's blade pitch
        self._last_sample_wall = 0.0
        self.collector = MeasurementCollector()
        self.policy = SamplePolicy(self.lockstep)  # which sample is pending (the self-test never waits)
        self.policy.activate(heard_applied=True)
        self.feed = SampleFeed(self.collector, self.policy, self._rejected)
        self.publisher = self.create_publisher(BladePitch, "thrusters/command", STREAM_QOS)
        self.samples = self.create_publisher(SelfTestSample, "self_test/samples", COMMAND_QOS)
        # answer nothing until the plant (and a recorder) listen: no command or sample record is lost
        self.gate = SubscriberGate([(self.publisher, p["wait_for_command_subscribers"]),
                                    (self.samples, p["wait_for_sample_subscribers"])])
        # bytes read straight (sample_inputs: what the typed path gives, its refusals for anything else)
        self.raw_feed = RawSampleFeed(self.feed)
        self.create_subscription(TwistWithCovarianceStamped, "sensors/velocity", self._on_velocity, COMMAND_QOS,
                                 raw=True)
        self.test: SelfTest | None = None      # the run in progress, or the last one (hovering)
        self._goal = None
        self._done: Future | None = None
        self.rejected = 0
        if self.lockstep:
            self.create_subscription(Clock, CLOCK, self._on_clock, RELIABLE_QOS, raw=True)
        self._timer = None
        self._retry_timer = None  # a sample to decide again once the subscriber gate opens
        self.server = ActionServer(self, SelfTestAction, "self_test", execute_callback=self._execute,
                                   goal_callback=self._accept, cancel_callback=lambda _: CancelResponse.ACCEPT,
                                   goal_service_qos_profile=SERVICE_QOS, result_service_qos_profile=SERVICE_QOS,
                                   cancel_service_qos_profile=SERVICE_QOS,  # a request storm gets every answer
                                   handle_accepted_callback=self._start)
        self._watchdog = None
        self.get_logger().info(f"self-test action server ready ({'lockstep' if self.lockstep else 'timer'})")

    def destroy_node(self):
        destroy_actions(self)  # before the node's clock goes: see destroy_actions
        return super().destroy_node()

    # -- the action ------------------------------------------------------------------
    def _config(self, goal) -> SelfTestConfig:
        """The goal's settings over the defaults, within the vehicle's input limit (``input_limit``)."""
        return SelfTestConfig.load(goal_overrides(goal), limit=self.input_limit)

    def _accept(self, goal) -> GoalResponse:
        if self._goal is not None:
            self.get_logger().warn("self-test goal refused: one is running")
            return GoalResponse.REJECT
        try:
            self._config(goal)
        except (ConfigError, DesignError, ValueError) as exc:
            self.get_logger().warn(f"self-test goal refused: {exc}")
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def _start(self, goal_handle) -> None:
        """The goal was accepted (its response just sent: module docstring): the test starts now, answering the
        held sample if nobody has, then the execute callback awaits its end."""
        config = self._config(goal_handle.request)
        self.test = SelfTest(config)
        self._goal = goal_handle
        self._done = Future()
        if not self.lockstep:
            if self._timer is not None:
                self.destroy_timer(self._timer)
            self._timer = self.create_timer(config.sample_period, self._on_timer)
        self._last_sample_wall = time.monotonic()
        self._watchdog = self.create_timer(0.5, self._watch_data)
        self.get_logger().info(f"self-test started: operating points {list(config.operating_points)} m/s, "
                               f"T = {config.sample_period:g} s")
        goal_handle.execute()
        if self.lockstep and self.policy.latest_ns is not None:
            self._answer(self.policy.latest_ns)  # the sample heard before the goal (a held graph's t_0) waits

    async def _execute(self, goal_handle):
        await self._done
        self.destroy_timer(self._watchdog)
        test = self.test
        self._goal = None
        result = self._result(test)
        if test.phase == Phase.CANCELLED:
            goal_handle.canceled()
        elif test.phase == Phase.DONE:
            goal_handle.succeed()
        else:
            goal_handle.abort()
        self.get_logger().info(f"self-test {test.phase.value}: {result.message or 'ok'}")
        return result

    def _result(self, test: SelfTest):
        result = SelfTestAction.Result()
        result.success = test.phase == Phase.DONE
        result.message = test.reason
        result.duration = float(test.duration)
        for point in test.points:
            result.surge_speeds.append(point.surge)
            result.b0_inverse.extend(point.model.B0inv.ravel().tolist())
            result.b1_inverse.extend(point.model.B1inv.ravel().tolist())
            result.u0.extend(point.model.u0.tolist())
            result.k_int.extend(point.gains.K_int.ravel().tolist())
            result.k_err.extend(point.gains.K_err.ravel().tolist())
        if test.points:
            result.controller_file = str(write_result_file(self.result_dir, result_document(test)).resolve())
        return result

    def _watch_data(self) -> None:
        """Fail a goal whose samples stopped coming (no simulator, a dead sensor): it ends, with the reason."""
        idle = time.monotonic() - self._last_sample_wall
        if self._goal is not None and idle > self.no_data_timeout and not self._done.done():
            why = (f"no velocity data for {idle:.1f} s (is /seapup/sensors/velocity published?)"
                   if not self.gate.missing()
                   else f"still waiting for subscribers after {idle:.1f} s: {', '.join(self.gate.missing())}")
            self.test.abort(why)
            self._done.set_result(True)

    # -- sampling --------------------------------------------------------------------
    def _rejected(self, reason: str) -> None:  # a non-finite or malformed sensor message: counted, never used
        self.rejected += 1
        self.get_logger().warn(f"sensor message rejected: {reason}", throttle_duration_sec=5.0)

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

    def _answer(self, t_ns: int) -> None:
        test = self.test
        if test is None or self.policy.pending(t_ns) is None or (test.finished and not self.hover_after):
            return
        if not self.gate.ready():
            # the first command waits until every awaited subscriber has matched (and stayed matched for the
            # gate's grace): decided again shortly, since in lockstep no new sample comes meanwhile
            self.get_logger().info(f"waiting for subscribers: {', '.join(self.gate.missing()) or '(settling)'}",
                                   throttle_duration_sec=5.0)
            self._retry(t_ns)
            return
        if test.finished and test.controller is None:
            return  # nothing better than what the plant does by itself
        t = t_ns * 1e-9
        try:
            command = test.update(t, self.collector.measurement(t))
        except ContractError as exc:  # no fresh velocity: skip this sample (counted), never integrate it
            self.rejected += 1
            self.get_logger().warn(f"sample t = {t:.3f} s skipped: {exc}", throttle_duration_sec=5.0)
            return
        self.policy.answered(t_ns)
        self._last_sample_wall = time.monotonic()
        self.publisher.publish(command_bytes(command.blade_pitch, t_ns))  # serialised: a fraction of the cost
        if self._goal is not None:
            for msg in self._sample_msgs(test, t_ns):
                self.samples.publish(msg)
        if self._goal is not None:
            self._feedback(test)
            if self._goal.is_cancel_requested and not test.finished:
                test.cancel("cancelled by the client")
            if test.finished and not self._done.done():
                self._done.set_result(True)

    def _retry(self, t_ns: int, after: float = 0.05) -> None:
        """Answer sample ``t_ns`` again ``after`` wall seconds from now (a steady timer: a held or waiting
        lockstep graph's time stands still)."""
        if self._retry_timer is not None:
            return

        def fire():
            self.destroy_timer(self._retry_timer)
            self._retry_timer = None
            self._answer(t_ns)
        self._retry_timer = self.create_timer(after, fire, clock=SteadyClock(clock_type=ClockType.STEADY_TIME))

    def _sample_msgs(self, test: SelfTest, t_ns: int) -> list[SelfTestSample]:
        """What this sample was used for, with the velocities used: one message per step test it was
        logged into (two when one test ends and the next starts with it; one with test_index -1 if none)."""
        cycle, surge, thruster = test.test_in_progress
        messages = []
        for index in test.last_logged or [-1]:
            msg = SelfTestSample()
            msg.header.stamp = ns_to_stamp(t_ns)
            msg.header.frame_id = "base_link_frd"
            msg.phase, msg.cycle, msg.thruster, msg.surge = test.phase.value, cycle, thruster, float(surge)
            msg.progress, msg.sample_period = float(test.progress), float(test.sample_period)
            msg.test_index = index
            if index < 0:
                msg.quiescent_input = msg.equilibrium = msg.velocity = [math.nan] * 4
            else:
                logged = test.tests[index]
                msg.cycle, msg.thruster, msg.surge = logged.cycle, logged.thruster, float(logged.surge)
                msg.step = float(logged.step)
                msg.quiescent_input = logged.quiescent_input.tolist()
                msg.equilibrium = logged.equilibrium.tolist()
                msg.velocity = logged.outputs[-1].tolist()
            messages.append(msg)
        return messages

    def _feedback(self, test: SelfTest) -> None:
        cycle, surge, thruster = test.test_in_progress
        feedback = SelfTestAction.Feedback()
        feedback.phase = test.phase.value
        feedback.cycle, feedback.thruster, feedback.surge = cycle, thruster, float(surge)
        feedback.progress = float(test.progress)
        velocity = self.collector.latest.get("velocity")
        rates = self.collector.latest.get("rates")
        if velocity is not None and rates is not None:
            feedback.velocity = [*map(float, velocity.value), float(rates.value[2])]
        else:
            feedback.velocity = [math.nan] * 4
        self._goal.publish_feedback(feedback)


def main(args=None) -> int:
    return run_node(SelfTestNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
