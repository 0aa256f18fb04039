"""The ``reference_schedule`` node: a velocity-reference schedule for the velocity controller.

A thin shell over :class:`seapup_control.profiles.ReferenceProfile`, publishing body-velocity
references (u, v, w, r; geometry_msgs/TwistStamped in ``base_link_frd``) on
``/seapup/velocity_controller/reference`` -- what the position controller publishes in the
hierarchy, here from a fixed, optionally repeating schedule: the square-wave reference of thesis
sec. 6.5.5's closed-loop identification, or any test reference. With ``lockstep`` true it answers
every ``/clock`` sample t_k with the reference for t_k, stamped t_k (the velocity controller
waits for the reference stamped for its sample); otherwise it publishes on a timer every
``sample_period`` for the time since it started.
"""
from __future__ import annotations

from geometry_msgs.msg import TwistStamped
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.node import Node

from seapup_common.ros.messages import reference_to_msg
from seapup_common.ros.node import STREAM_QOS, declare_from_package_file, run_node
from seapup_common.topics import NAMESPACE
from seapup_control.ros.sample_publisher import SamplePublisher, sample_publisher_events
from seapup_control.profiles import ReferenceProfile

__all__ = ["ReferenceScheduleNode", "main"]


class ReferenceScheduleNode(Node):
    """rclpy shell around a :class:`ReferenceProfile` (see module docstring)."""

    def __init__(self, **kwargs):
        super().__init__("reference_schedule", namespace=NAMESPACE, **kwargs)
        p = declare_from_package_file(self, "seapup_control", "reference_schedule.yaml", {
            "sample_period": ParameterDescriptor(
                description="controller sample period [s]", read_only=True,
                floating_point_range=[FloatingPointRange(from_value=0.01, to_value=10.0)]),
        }, section="reference_schedule",
            ranges={"times": (0.0, 1e9), "references": (-10.0, 10.0),  # [m/s], [rad/s]
                    "period": (0.0, 1e9), "wait_for_reference_subscribers": (0, 100)})
        self.schedule = ReferenceProfile(p["times"], p["references"], p["period"])
        self.publisher = self.create_publisher(TwistStamped, "velocity_controller/reference", STREAM_QOS,
            event_callbacks=sample_publisher_events(self, lambda: getattr(self, "sampler", None)))
        self.sampler = SamplePublisher(self, self.publisher, self._reference, lockstep=p["lockstep"],
                                       sample_period=p["sample_period"],
                                       wait_for_subscribers=p["wait_for_reference_subscribers"])
        self.get_logger().info(f"reference schedule: {len(self.schedule.times)} row(s)"
                               + (f", repeating every {self.schedule.period:g} s" if self.schedule.period else ""))

    def _reference(self, t_ns: int, elapsed: float) -> TwistStamped:
        return reference_to_msg(self.schedule.at(elapsed), t_ns)

    def destroy_node(self) -> None:
        if getattr(self, "sampler", None) is not None:
            self.get_logger().info(self.sampler.summary())
        super().destroy_node()


def main(args=None) -> int:
    return run_node(ReferenceScheduleNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
