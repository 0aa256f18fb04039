"""The ``simulator`` node: the Seapup plant on the ROS graph.

A shell over :class:`seapup_sim.simulator.Simulator` (all computation is
there). Namespace ``/seapup``; topics, services and parameters are listed in
the README. Times are simulated time: every message is stamped t_k and, with
``publish_clock``, ``/clock`` carries t_k so other nodes can run with
``use_sim_time``.

Modes:
- ``lockstep``: publish the outputs of t_k (and /clock), wait for the command
  stamped t_k, integrate to t_k + T with it held (fig. 5.1). If it does not
  come within ``lockstep_timeout`` wall seconds, log, count, hold the previous
  command and go on.
- ``realtime``: integrate one control period per wall-timer tick of
  T / real_time_factor (0: as fast as the executor allows) with the latest
  valid command.

Commands are subscribed raw: a message that does not decode, or whose
re-encoding differs in length (a wrong array length), is counted and dropped
without touching the simulation.
"""
from __future__ import annotations

import math
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import (PoseWithCovarianceStamped, TwistWithCovarianceStamped,
                               Vector3Stamped, WrenchStamped)
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, Range
from seapup_msgs.msg import BladePitch, Depth
from seapup_msgs.srv import Reset, SetConfiguration, SetCurrent, SetSensorProfile, SetThrusterEfficiency

from seapup_sim import frames
from seapup_sim.current import CurrentParams
from seapup_sim.node_main import declare_from_package_file, run_node
from seapup_sim.sensors import sensor_profiles
from seapup_sim.simulator import Simulator, SimulatorConfig
from seapup_sim.vehicle_config import available_configs

__all__ = ["SimulatorNode", "main"]

QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
# commands queue deeper: every one, good or bad, must be seen and counted
COMMAND_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
NED, FRD = frames.FRAME_NED, frames.FRAME_FRD


def _stamp(msg_header, t_ns: int) -> None:
    msg_header.stamp.sec, msg_header.stamp.nanosec = divmod(int(t_ns), 1_000_000_000)


def _float_range(lo, hi, description, read_only=False):
    return ParameterDescriptor(description=description, read_only=read_only,
                               floating_point_range=[FloatingPointRange(from_value=lo, to_value=hi)])


class SimulatorNode(Node):
    """rclpy shell around :class:`Simulator` (see module docstring)."""

    def __init__(self, **kwargs):
        super().__init__("simulator", namespace="/seapup", **kwargs)
        ro = dict(read_only=True)
        p = declare_from_package_file(self, "seapup_sim", "simulator.yaml", {
            "mode": ParameterDescriptor(description="lockstep | realtime", **ro),
            "real_time_factor": _float_range(0.0, 1e4, "realtime speed-up (0 = as fast as possible)"),
            "lockstep_timeout": _float_range(0.001, 60.0, "wall seconds to wait for the t_k command"),
            "control_period": _float_range(0.01, 10.0, "controller sample period T [s]", **ro),
            "physics_step": _float_range(0.001, 1.0, "integration step [s]", **ro),
            "vehicle": ParameterDescriptor(description="vehicle configuration (~/set_configuration "
                                                       "changes it)", **ro),
            "sensor_profile": ParameterDescriptor(description="sensor profile (~/set_sensor_profile)", **ro),
            "seed": ParameterDescriptor(description="random seed (~/reset changes it)", read_only=True,
                                        integer_range=[IntegerRange(from_value=0, to_value=2**31 - 1)]),
            "blade_pitch_limit": _float_range(0.01, math.radians(35.0), "blade-pitch limit [rad]", **ro),
            "watchdog_timeout": _float_range(0.01, 3600.0, "sim seconds without a valid command"),
            "watchdog_action": ParameterDescriptor(description="hover | neutral"),
            "start_depth": _float_range(0.0, 6000.0, "initial depth [m]", **ro),
            "diagnostics_period": _float_range(0.05, 60.0, "diagnostics period [s wall]", **ro),
        })
        if p["mode"] not in ("lockstep", "realtime"):
            raise ValueError(f"mode must be lockstep or realtime, got {p['mode']!r}")
        self.mode = p["mode"]
        env = {"current": {"enabled": p["current_enabled"], "mean_speed": p["current_mean_speed"],
                           "mean_direction": p["current_mean_direction"], "speed_std": p["current_speed_std"],
                           "direction_std": p["current_direction_std"], "break_time": p["current_break_time"]},
               "umbilical": {"enabled": p["umbilical_enabled"]}}
        self.config = SimulatorConfig(p["vehicle"], p["sensor_profile"], p["seed"], p["physics_step"],
                                      p["control_period"], p["blade_pitch_limit"], p["watchdog_timeout"],
                                      p["watchdog_action"], environment=env)
        self.start_state = np.zeros(12)
        self.start_state[2] = p["start_depth"]
        self.core = Simulator(self.config, self.start_state)
        self.add_on_set_parameters_callback(self._on_set_parameters)

        pub = self.create_publisher
        self.pub_applied = pub(BladePitch, "thrusters/applied", QOS)
        self.pub_velocity = pub(TwistWithCovarianceStamped, "sensors/velocity", QOS)
        self.pub_imu = pub(Imu, "sensors/imu", QOS)
        self.pub_position = pub(PoseWithCovarianceStamped, "sensors/position", QOS)
        self.pub_depth = pub(Depth, "sensors/depth", QOS)
        self.pub_altitude = pub(Range, "sensors/altitude", QOS)
        self.pub_truth = pub(Odometry, "truth/odometry", QOS)
        self.pub_odom = pub(Odometry, "odometry", QOS)
        self.pub_current = pub(Vector3Stamped, "environment/current", QOS)
        self.pub_wrench = pub(WrenchStamped, "umbilical/wrench", QOS)
        self.pub_clock = pub(Clock, "/clock", QOS) if p["publish_clock"] else None
        self.pub_diag = pub(DiagnosticArray, "/diagnostics", 10)
        self.create_subscription(BladePitch, "thrusters/command", self._on_command, COMMAND_QOS, raw=True)

        srv = self.create_service
        srv(Reset, "~/reset", self._srv_reset)
        srv(SetConfiguration, "~/set_configuration", self._srv_configuration)
        srv(SetThrusterEfficiency, "~/set_thruster_efficiency", self._srv_efficiency)
        srv(SetCurrent, "~/set_current", self._srv_current)
        srv(SetSensorProfile, "~/set_sensor_profile", self._srv_sensor_profile)

        self._wall_start = time.monotonic()
        self._sim_start = 0.0
        self._waiting_since = None
        self._last_warn = 0.0
        self._outputs = None
        self._halted = ""  # set when the plant diverged: stop stepping until ~/reset
        self._handshake = True  # lockstep: until the first command, re-publish t_0 (discovery races)
        self._last_republish = time.monotonic()
        if self.mode == "lockstep":
            self._publish_outputs()
            self._waiting_since = time.monotonic()
            self.create_timer(0.01, self._lockstep_watch)
        else:
            self._realtime_timer = self.create_timer(self._realtime_period(), self._realtime_tick)
        self.create_timer(p["diagnostics_period"], self._publish_diagnostics)
        self.get_logger().info(
            f"simulator ready: {self.mode}, vehicle {self.config.vehicle}, sensors "
            f"{self.config.sensor_profile}, T = {self.config.control_period} s, dt = "
            f"{self.config.physics_step} s, seed {self.config.seed}")

    # -- parameters --------------------------------------------------------------
    def _realtime_period(self) -> float:
        rtf = self.get_parameter("real_time_factor").value
        return 0.0 if rtf == 0 else self.config.control_period / rtf

    def _on_set_parameters(self, params) -> SetParametersResult:
        for prm in params:
            if prm.name == "watchdog_action" and prm.value not in ("hover", "neutral"):
                return SetParametersResult(successful=False, reason="watchdog_action must be hover or neutral")
        for prm in params:
            if prm.name == "watchdog_timeout":
                self.config.watchdog_timeout = float(prm.value)
            elif prm.name == "watchdog_action":
                self.config.watchdog_action = prm.value
            elif prm.name == "real_time_factor" and self.mode == "realtime":
                rtf = float(prm.value)
                self._realtime_timer.timer_period_ns = int(
                    0 if rtf == 0 else self.config.control_period / rtf * 1e9)
        return SetParametersResult(successful=True)

    # -- commands and stepping ---------------------------------------------------
    def _warn(self, text: str) -> None:
        now = time.monotonic()
        if now - self._last_warn >= 1.0:  # at most once per second
            self._last_warn = now
            self.get_logger().warn(text)

    def _on_command(self, raw: bytes) -> None:
        try:
            msg = deserialize_message(raw, BladePitch)
            if len(serialize_message(msg)) != len(raw):
                raise ValueError(f"{len(raw)} bytes do not encode a BladePitch (wrong array length?)")
        except Exception as exc:  # noqa: BLE001 - any decoding failure is bad input
            self.core.reject_malformed(f"malformed command: {exc}")
            self._warn(self.core.last_error)
            return
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        lockstep = self.mode == "lockstep"
        ok, reason = self.core.submit(np.array(msg.pitch, float), stamp, lockstep)
        if not ok or reason == "saturated":
            self._warn(f"command {'rejected' if not ok else 'saturated'}: {reason if not ok else ''}".strip())
        if ok and lockstep and stamp == self.core.t_ns:
            self._advance()

    def _advance(self) -> None:
        if self._halted:
            return
        try:
            self.core.step()
            self._publish_outputs()
        except FloatingPointError as exc:  # DivergenceError or a non-finite output
            self._halted = str(exc)
            self.get_logger().error(f"simulation halted: {exc}; call ~/reset to continue")
            return
        self._waiting_since = time.monotonic()

    def _lockstep_watch(self) -> None:
        if self._halted:
            return
        now = time.monotonic()
        if self._handshake:
            if self.core.counters["accepted"]:
                self._handshake = False
            elif now - self._last_republish > 0.2:
                self._last_republish = now
                self._publish_outputs(resend=True)  # no controller has answered yet: say t_k again
        timeout = self.get_parameter("lockstep_timeout").value
        if self._waiting_since is not None and now - self._waiting_since > timeout:
            self.core.lockstep_timeout()
            self._warn(f"no command stamped t = {self.core.t:.3f} s within {timeout} s: holding the last one")
            self._advance()

    def _realtime_tick(self) -> None:
        self._advance()

    # -- outputs -----------------------------------------------------------------
    def _publish_outputs(self, resend: bool = False) -> None:
        if resend and self._outputs is not None:
            out = self._outputs  # the same sample again: no new sensor noise drawn
        else:
            out = self._outputs = self.core.outputs()
            self.core.check_finite(out)
        t_ns = self.core.t_ns
        if self.pub_clock is not None:
            clk = Clock()
            clk.clock.sec, clk.clock.nanosec = divmod(t_ns, 1_000_000_000)
            self.pub_clock.publish(clk)

        applied = BladePitch()
        _stamp(applied.header, t_ns)
        applied.header.frame_id = FRD
        applied.pitch = out["applied_pitch"]
        self.pub_applied.publish(applied)

        tw = TwistWithCovarianceStamped()
        _stamp(tw.header, t_ns)
        tw.header.frame_id = FRD
        (tw.twist.twist.linear.x, tw.twist.twist.linear.y, tw.twist.twist.linear.z) = out["velocity"]
        (tw.twist.twist.angular.x, tw.twist.twist.angular.y, tw.twist.twist.angular.z) = out["rates"]
        tw.twist.covariance = np.diag(np.concatenate([out["velocity_var"], out["rates_var"]])).ravel()
        self.pub_velocity.publish(tw)

        imu = Imu()
        _stamp(imu.header, t_ns)
        imu.header.frame_id = FRD
        q = out["attitude_quaternion"]  # base_link_frd relative to odom_ned
        imu.orientation.x, imu.orientation.y, imu.orientation.z, imu.orientation.w = q
        imu.orientation_covariance = np.diag(out["attitude_var"]).ravel()
        imu.angular_velocity.x, imu.angular_velocity.y, imu.angular_velocity.z = out["rates"]
        imu.angular_velocity_covariance = np.diag(out["rates_var"]).ravel()
        f = out["specific_force"]
        imu.linear_acceleration.x, imu.linear_acceleration.y, imu.linear_acceleration.z = f
        # REP-145: unknown covariance -> zeros (the accelerometer is noise-free here)
        self.pub_imu.publish(imu)

        if out["position"] is not None:
            pose = PoseWithCovarianceStamped()
            _stamp(pose.header, t_ns)
            pose.header.frame_id = NED
            pos = out["position"]
            pose.pose.pose.position.x, pose.pose.pose.position.y, pose.pose.pose.position.z = pos
            pose.pose.pose.orientation.w = 1.0
            # acoustic fixes give no orientation: a huge variance says so
            pose.pose.covariance = np.diag([out["position_var"]] * 3 + [1e9] * 3).ravel()
            self.pub_position.publish(pose)

        depth = Depth()
        _stamp(depth.header, t_ns)
        depth.header.frame_id = NED
        depth.depth, depth.variance = out["depth"], out["depth_var"]
        self.pub_depth.publish(depth)

        if out["altitude"] is not None:
            rng = Range()
            _stamp(rng.header, t_ns)
            rng.header.frame_id = FRD
            rng.radiation_type = Range.ULTRASOUND
            rng.field_of_view = math.radians(10.0)
            rng.min_range, rng.max_range = 0.3, 200.0
            rng.range = float(out["altitude"])
            rng.variance = out["altitude_var"]
            self.pub_altitude.publish(rng)

        x = out["state"]
        truth = Odometry()
        _stamp(truth.header, t_ns)
        truth.header.frame_id, truth.child_frame_id = NED, FRD
        truth.pose.pose.position.x, truth.pose.pose.position.y, truth.pose.pose.position.z = x[:3]
        qt = out["quaternion_truth"]
        (truth.pose.pose.orientation.x, truth.pose.pose.orientation.y,
         truth.pose.pose.orientation.z, truth.pose.pose.orientation.w) = qt
        truth.twist.twist.linear.x, truth.twist.twist.linear.y, truth.twist.twist.linear.z = x[6:9]
        truth.twist.twist.angular.x, truth.twist.twist.angular.y, truth.twist.twist.angular.z = x[9:12]
        self.pub_truth.publish(truth)

        odom = Odometry()
        odom.header.stamp = truth.header.stamp
        odom.header.frame_id, odom.child_frame_id = frames.FRAME_ENU, frames.FRAME_FLU
        pe = frames.ned_to_enu(x[:3])
        odom.pose.pose.position.x, odom.pose.pose.position.y, odom.pose.pose.position.z = pe
        qe = frames.orientation_ned_frd_to_enu_flu(qt)
        (odom.pose.pose.orientation.x, odom.pose.pose.orientation.y,
         odom.pose.pose.orientation.z, odom.pose.pose.orientation.w) = qe
        odom.twist.twist.linear.x, odom.twist.twist.linear.y, odom.twist.twist.linear.z = frames.frd_to_flu(x[6:9])
        (odom.twist.twist.angular.x, odom.twist.twist.angular.y,
         odom.twist.twist.angular.z) = frames.frd_to_flu(x[9:12])
        self.pub_odom.publish(odom)

        cur = Vector3Stamped()
        _stamp(cur.header, t_ns)
        cur.header.frame_id = NED
        cur.vector.x, cur.vector.y, cur.vector.z = out["current_ned"]
        self.pub_current.publish(cur)

        wr = WrenchStamped()
        _stamp(wr.header, t_ns)
        wr.header.frame_id = FRD
        wr.wrench.force.x, wr.wrench.force.y, wr.wrench.force.z = out["umbilical_body"][:3]
        wr.wrench.torque.x, wr.wrench.torque.y, wr.wrench.torque.z = out["umbilical_body"][3:]
        self.pub_wrench.publish(wr)

    def _publish_diagnostics(self) -> None:
        c = self.core.counters
        elapsed = time.monotonic() - self._wall_start
        rejected = sum(v for k, v in c.items() if k.startswith("rejected"))
        level = DiagnosticStatus.OK
        message = f"{self.mode}, t = {self.core.t:.1f} s"
        if self._halted:
            level, message = DiagnosticStatus.ERROR, message + f", halted: {self._halted}"
        elif self.core.watchdog_active:
            level, message = DiagnosticStatus.WARN, message + ", watchdog active (no valid command)"
        elif rejected:
            level, message = DiagnosticStatus.WARN, message + f", last rejection: {self.core.last_error}"
        values = {**c, "sim_time": f"{self.core.t:.3f}",
                  "real_time_factor_measured": f"{self.core.t / elapsed:.2f}" if elapsed > 0 else "0",
                  "control_steps_per_wall_second": f"{c['steps'] / elapsed:.1f}" if elapsed > 0 else "0",
                  "watchdog_active": str(self.core.watchdog_active), "vehicle": self.config.vehicle,
                  "sensor_profile": self.config.sensor_profile}
        status = DiagnosticStatus(level=level, name="seapup/simulator", hardware_id="seapup_sim",
                                  message=message, values=[KeyValue(key=k, value=str(v)) for k, v in values.items()])
        arr = DiagnosticArray(status=[status])
        arr.header.stamp = self.get_clock().now().to_msg()
        self.pub_diag.publish(arr)

    # -- services ----------------------------------------------------------------
    def _answer(self, response, action, success_text):
        try:
            action()
        except (ValueError, TypeError, KeyError) as exc:
            response.success, response.message = False, str(exc)
            self.get_logger().warn(f"service refused: {exc}")
        else:
            response.success, response.message = True, success_text
            self.get_logger().info(success_text)
        return response

    def _srv_reset(self, request, response):
        def act():
            state = np.array(request.state, float) if request.use_state else self.start_state
            if not np.all(np.isfinite(state)):
                raise ValueError("reset state must be finite")
            if not 0 <= request.seed < 2**31:
                raise ValueError(f"seed must be in [0, 2^31), got {request.seed}")
            self.core.reset(request.seed, state)
            self._halted = ""
            self._publish_outputs()
            self._waiting_since = time.monotonic()
        return self._answer(response, act, f"reset: t = 0, seed {request.seed}")

    def _srv_configuration(self, request, response):
        def act():
            if request.name not in available_configs():
                raise ValueError(f"no configuration {request.name!r} (available: {', '.join(available_configs())})")
            self.core.set_configuration(request.name)
        return self._answer(response, act, f"configuration {request.name} at t = {self.core.t:.2f} s")

    def _srv_efficiency(self, request, response):
        return self._answer(response, lambda: self.core.set_thruster_efficiency(np.array(request.efficiency)),
                            f"thruster efficiency {list(np.round(request.efficiency, 3))}")

    def _srv_current(self, request, response):
        def act():
            if not request.enabled:
                self.core.set_current(None)
                return
            tc = request.break_time or self.get_parameter("current_break_time").value
            self.core.set_current(CurrentParams(request.mean_speed, request.speed_std, request.mean_direction,
                                                request.direction_std, tc))
        return self._answer(response, act, "current " + ("set" if request.enabled else "off"))

    def _srv_sensor_profile(self, request, response):
        def act():
            if request.name not in sensor_profiles():
                raise ValueError(f"no sensor profile {request.name!r} (available: {', '.join(sensor_profiles())})")
            self.core.set_sensor_profile(request.name)
        return self._answer(response, act, f"sensor profile {request.name}")


def main(args=None) -> int:
    return run_node(SimulatorNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
