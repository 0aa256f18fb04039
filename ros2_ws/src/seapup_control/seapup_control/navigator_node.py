"""The ``navigator`` node: the Kalman-filter navigation of :mod:`seapup_control.navigation` on the graph.

Subscribes (namespace ``/seapup``) to ``sensors/velocity`` (doppler log and
gyros), ``sensors/imu`` (attitude), ``sensors/depth`` and ``sensors/position``
(acoustic fix) and publishes ``navigation/odometry`` (nav_msgs/Odometry,
``odom_ned`` -> ``base_link_frd``, stamped with the sample time, position
covariance from the filter) once per sample t_k. A sample is processed when
the readings of ``sample_topics`` stamped t_k have all arrived (the
simulator publishes them together), or when a later velocity reading comes
first. Non-finite or malformed readings are rejected and counted, never
fused; ``/diagnostics`` (``seapup/navigator``) carries the counts and the
estimate's standard deviation.
"""
from __future__ import annotations

import math

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseWithCovarianceStamped, TwistWithCovarianceStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from sensor_msgs.msg import Imu
from seapup_msgs.msg import Depth

from seapup_common.contract import ContractError
from seapup_common.lockstep import StampGate
from seapup_common.ros.messages import MeasurementCollector, diagnostic_array, estimate_to_odometry, stamp_to_ns
from seapup_common.ros.node import COMMAND_QOS, RELIABLE_QOS, declare_from_package_file, run_node
from seapup_common.topics import DIAGNOSTICS, NAMESPACE
from seapup_control.navigation import Navigator, NavigatorParams

__all__ = ["NavigatorNode", "main"]

_TOPICS = {"velocity": ("sensors/velocity", TwistWithCovarianceStamped), "imu": ("sensors/imu", Imu),
           "depth": ("sensors/depth", Depth), "position": ("sensors/position", PoseWithCovarianceStamped)}


class NavigatorNode(Node):
    """rclpy shell around :class:`Navigator` (see the module docstring)."""

    def __init__(self, **kwargs):
        super().__init__("navigator", namespace=NAMESPACE, **kwargs)
        p = declare_from_package_file(self, "seapup_control", "navigator.yaml", section="navigator", ranges={
            "q_walk": (0.0, 1e3), "velocity_std": (1e-6, 10.0), "fix_std": (1e-3, 1e3), "depth_std": (1e-4, 1e3),
            "initial_std": (1e-3, 1e4), "gate_probability": (0.5, 1.0 - 1e-12), "coast_inflation": (1.0, 1e6),
            "max_speed": (0.01, 100.0), "depth_range": (-1e3, 1.2e4), "reacquire_after": (0, 10**6)})
        self.sample_topics = set(p.pop("sample_topics"))
        unknown = self.sample_topics - set(_TOPICS)
        if unknown or "velocity" not in self.sample_topics:
            raise ValueError(f"sample_topics {sorted(self.sample_topics)}: must include velocity and only "
                             f"{', '.join(_TOPICS)}")
        self.navigator = Navigator(NavigatorParams.from_mapping(p))
        self.collector = MeasurementCollector()
        self.rejected = 0
        self._arrived: dict[int, set] = {}  # sample stamp -> topics heard for it
        self._processed_ns: int | None = None
        self.stamps = StampGate()
        self.publisher = self.create_publisher(Odometry, "navigation/odometry", RELIABLE_QOS)
        self.diagnostics = self.create_publisher(DiagnosticArray, DIAGNOSTICS, RELIABLE_QOS)
        for name, (topic, kind) in _TOPICS.items():
            self.create_subscription(kind, topic, lambda msg, name=name: self._on_reading(name, msg), COMMAND_QOS)
        self.create_timer(1.0, self._diagnose)

    def _on_reading(self, name: str, msg) -> None:
        stamp = stamp_to_ns(msg.header.stamp)
        if not self.stamps.accept(stamp):  # one far-future stamp would make every real sample "late"
            self.rejected += 1
            self.get_logger().warn(f"{name} reading rejected: {self.stamps.why(stamp)}", throttle_duration_sec=2.0)
            return
        if not self.collector.add(msg):
            self.rejected += 1
            self.get_logger().warn(f"{name} reading rejected: {self.collector.last_error}", throttle_duration_sec=2.0)
            return
        t_ns = stamp_to_ns(msg.header.stamp)
        if self._processed_ns is not None and t_ns <= self._processed_ns:
            return  # a late reading of a processed sample: kept for the next one
        if name == "velocity":
            for earlier in sorted(k for k in self._arrived if k < t_ns):
                self._process(earlier)  # a sample whose other readings never came
        self._arrived.setdefault(t_ns, set()).add(name)
        if name == "velocity" or t_ns in self._arrived and "velocity" in self._arrived[t_ns]:
            if self.sample_topics <= self._arrived[t_ns]:
                self._process(t_ns)

    def _process(self, t_ns: int) -> None:
        for stamp in [k for k in self._arrived if k <= t_ns]:
            del self._arrived[stamp]
        if "velocity" not in self.collector.latest:
            return
        self._processed_ns = t_ns
        try:
            estimate = self.navigator.update(self.collector.measurement(t_ns * 1e-9))
        except ContractError as exc:
            self.rejected += 1
            self.get_logger().warn(f"sample rejected: {exc}", throttle_duration_sec=2.0)
            return
        if estimate is not None:
            self.publisher.publish(estimate_to_odometry(estimate, t_ns))

    def _diagnose(self) -> None:
        estimate = self.navigator.estimate()
        values = {**self.navigator.counts, "rejected_readings": self.rejected,
                  "horizontal_std": estimate.horizontal_std if estimate else math.nan,
                  "depth_std": math.sqrt(estimate.position_cov[2, 2]) if estimate else math.nan}
        level = DiagnosticStatus.OK if estimate is not None else DiagnosticStatus.WARN
        self.diagnostics.publish(diagnostic_array("seapup/navigator", level,
                                                  "tracking" if estimate is not None else "waiting for a position fix", values, int(self.navigator.t * 1e9) if self.navigator.t is not None else 0))


def main(args=None) -> int:
    return run_node(NavigatorNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
