"""The ``simulator`` node: the plant every other seapup node talks to.

Current scope (foundation): the node gates blade-pitch commands through
:class:`seapup_sim.blade_pitch.CommandGate` and republishes what the thrusters
would apply, and reports its health on ``/diagnostics``. The vehicle model
(thesis ch. 2-3) and the sensor topics come with later issues; the heartbeat
says so rather than pretending.

Topics (node namespace ``/seapup`` by default):

- sub ``thrusters/command`` (seapup_msgs/BladePitch, rad)
- pub ``thrusters/applied`` (seapup_msgs/BladePitch, rad, after the blade limits)
- pub ``/diagnostics`` (diagnostic_msgs/DiagnosticArray), every ``heartbeat_period``
"""
from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, SetParametersResult
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from seapup_msgs.msg import BladePitch

from seapup_sim.blade_pitch import CommandGate
from seapup_sim.node_main import declare_from_package_file, run_node

__all__ = ["SimulatorNode", "main"]

COMMAND_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


class SimulatorNode(Node):
    """rclpy shell around the command gate (see module docstring)."""

    def __init__(self, **kwargs):
        super().__init__("simulator", namespace="/seapup", **kwargs)
        declare_from_package_file(self, "seapup_sim", "simulator.yaml", {
            "blade_pitch_limit": ParameterDescriptor(
                description="symmetric blade-pitch limit [rad]",
                floating_point_range=[FloatingPointRange(from_value=0.01, to_value=1.0)]),
            "heartbeat_period": ParameterDescriptor(
                description="period of the /diagnostics heartbeat [s]",
                floating_point_range=[FloatingPointRange(from_value=0.05, to_value=60.0)]),
        })
        self.gate = CommandGate(limit=self.get_parameter("blade_pitch_limit").value)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.applied_pub = self.create_publisher(BladePitch, "thrusters/applied", COMMAND_QOS)
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_subscription(BladePitch, "thrusters/command", self._on_command, COMMAND_QOS)
        self.heartbeat = self.create_timer(self.get_parameter("heartbeat_period").value,
                                           self._publish_diagnostics)
        self.get_logger().info(
            f"simulator ready: blade-pitch limit {self.gate.limit:.4f} rad; "
            "vehicle model not yet loaded (commands are gated and echoed on thrusters/applied)")

    def _on_set_parameters(self, params) -> SetParametersResult:
        for p in params:
            if p.name == "blade_pitch_limit":
                self.gate.limit = float(p.value)
            elif p.name == "heartbeat_period":
                self.heartbeat.timer_period_ns = int(float(p.value) * 1e9)
        return SetParametersResult(successful=True)

    def _on_command(self, msg: BladePitch) -> None:
        clipped_before = self.gate.saturated
        applied = self.gate.submit(msg.pitch)
        if applied is None:
            self.get_logger().warn(f"rejected command: {self.gate.last_error}",
                                   throttle_duration_sec=1.0)
            return
        if self.gate.saturated > clipped_before:
            self.get_logger().warn(
                f"blade pitch saturated at +/-{self.gate.limit:.4f} rad "
                f"({self.gate.saturated} pitches so far)", throttle_duration_sec=1.0)
        out = BladePitch()
        out.header = msg.header
        out.pitch = applied
        self.applied_pub.publish(out)

    def _publish_diagnostics(self) -> None:
        status = DiagnosticStatus(
            level=DiagnosticStatus.WARN if self.gate.rejected else DiagnosticStatus.OK,
            name=f"{self.get_namespace().strip('/')}/{self.get_name()}: commands",
            hardware_id="seapup_sim",
            message=(f"last rejection: {self.gate.last_error}" if self.gate.rejected
                     else "commands OK; vehicle model not yet loaded"),
            values=[KeyValue(key=k, value=str(v)) for k, v in self.gate.counters().items()])
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self.diag_pub.publish(array)


def main(args=None) -> int:
    return run_node(SimulatorNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
