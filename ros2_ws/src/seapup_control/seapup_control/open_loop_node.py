"""The ``open_loop`` node: publishes a blade-pitch schedule at the sample rate.

A thin shell over :class:`seapup_control.schedule.PitchSchedule`, publishing on
``/seapup/thrusters/command``. With ``lockstep`` false it publishes every
``sample_period`` the pitches for the time elapsed since the node started
(node clock, so ``use_sim_time`` works). With ``lockstep`` true it answers
every ``/clock`` sample t_k of a lockstep simulator with the command for t_k,
stamped t_k. This is how the thesis's open-loop tests (Table 3.2) are flown
through the ROS graph.
"""
from __future__ import annotations

from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from seapup_msgs.msg import BladePitch

from seapup_control.schedule import PitchSchedule
from seapup_sim.node_main import declare_from_package_file, run_node

__all__ = ["OpenLoopNode", "main"]


class OpenLoopNode(Node):
    """rclpy shell around a :class:`PitchSchedule` (see module docstring)."""

    def __init__(self, **kwargs):
        super().__init__("open_loop", namespace="/seapup", **kwargs)
        declare_from_package_file(self, "seapup_control", "open_loop.yaml", {
            "sample_period": ParameterDescriptor(
                description="controller sample period [s]", read_only=True,
                floating_point_range=[FloatingPointRange(from_value=0.01, to_value=10.0)]),
        })
        value = self.get_parameter
        self.schedule = PitchSchedule(value("times").value, value("pitches").value,
                                      value("blade_pitch_limit").value)
        self.publisher = self.create_publisher(
            BladePitch, "thrusters/command", QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
        self.start = self.get_clock().now()
        self.sent = 0
        self._last_clock = None
        if value("lockstep").value:
            self.create_subscription(Clock, "/clock", self._on_clock,
                                     QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
        else:
            self.create_timer(value("sample_period").value, self._tick)
        self.get_logger().info(
            f"open-loop schedule: {len(self.schedule.times)} segment(s), last switch at "
            f"{self.schedule.duration:.1f} s, period {value('sample_period').value:.3f} s")

    def _on_clock(self, msg: Clock) -> None:
        t_ns = msg.clock.sec * 1_000_000_000 + msg.clock.nanosec
        if t_ns == self._last_clock:
            return  # the simulator repeats t_k until someone answers: answer once
        self._last_clock = t_ns
        out = BladePitch()
        out.header.stamp = msg.clock
        out.pitch = self.schedule.at(t_ns * 1e-9)
        self.publisher.publish(out)
        self.sent += 1

    def _tick(self) -> None:
        now = self.get_clock().now()
        elapsed = max((now - self.start).nanoseconds * 1e-9, 0.0)
        msg = BladePitch()
        msg.header.stamp = now.to_msg()
        msg.pitch = self.schedule.at(elapsed)
        self.publisher.publish(msg)
        self.sent += 1


def main(args=None) -> int:
    return run_node(OpenLoopNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
