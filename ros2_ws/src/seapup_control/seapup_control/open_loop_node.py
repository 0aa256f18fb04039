"""The ``open_loop`` node: publishes a blade-pitch schedule at the sample rate.

A thin shell over :class:`seapup_control.profiles.PitchProfile`, publishing on
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
from seapup_msgs.msg import BladePitch

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_common.contract import Measurement, Reference
from seapup_common.ros.messages import command_to_msg
from seapup_common.ros.node import STREAM_QOS, declare_from_package_file, run_node
from seapup_common.topics import NAMESPACE
from seapup_control.ros.sample_publisher import SamplePublisher, sample_publisher_events
from seapup_control.profiles import OpenLoop, PitchProfile

__all__ = ["OpenLoopNode", "main"]


class OpenLoopNode(Node):
    """rclpy shell around a :class:`PitchProfile` (see module docstring)."""

    #: Spun by rclpy's EventsExecutor unless told otherwise (seapup_common.ros.node.DEFAULT_EXECUTOR: measured
    #: faster, soaked and hostile-tested for this node).
    EXECUTOR = "events"

    def __init__(self, **kwargs):
        super().__init__("open_loop", namespace=NAMESPACE, **kwargs)
        p = declare_from_package_file(self, "seapup_control", "open_loop.yaml", {
            "sample_period": ParameterDescriptor(
                description="controller sample period [s]", read_only=True,
                floating_point_range=[FloatingPointRange(from_value=0.01, to_value=10.0)]),
            "blade_pitch_limit": ParameterDescriptor(
                description="blade-pitch limit [rad] the schedule must respect", read_only=True,
                floating_point_range=[FloatingPointRange(from_value=0.01, to_value=BLADE_PITCH_LIMIT)]),
        }, defaults={"blade_pitch_limit": BLADE_PITCH_LIMIT}, section="open_loop",
            ranges={"times": (0.0, 1e9), "pitches": (-BLADE_PITCH_LIMIT, BLADE_PITCH_LIMIT),
                    "wait_for_command_subscribers": (0, 100)})
        self.schedule = PitchProfile(p["times"], p["pitches"], p["blade_pitch_limit"])
        self.controller = OpenLoop(self.schedule, p["sample_period"])
        self.publisher = self.create_publisher(BladePitch, "thrusters/command", STREAM_QOS,
            event_callbacks=sample_publisher_events(self, lambda: getattr(self, "sampler", None)))
        # answer nothing until the plant (and e.g. a recorder) listens: no command is lost at start
        self.sampler = SamplePublisher(self, self.publisher, self._command, lockstep=p["lockstep"],
                                       sample_period=p["sample_period"],
                                       wait_for_subscribers=p["wait_for_command_subscribers"])
        self.get_logger().info(
            f"open-loop schedule: {len(self.schedule.times)} segment(s), last switch at "
            f"{self.schedule.duration:.1f} s, period {p['sample_period']:.3f} s")

    def _command(self, t_ns: int, elapsed: float):
        return command_to_msg(self.controller.update(elapsed, Measurement(elapsed), Reference()), t_ns)

    def destroy_node(self) -> None:
        if getattr(self, "sampler", None) is not None:
            self.get_logger().info(self.sampler.summary())
        super().destroy_node()


def main(args=None) -> int:
    return run_node(OpenLoopNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
