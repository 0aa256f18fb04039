"""The ``navigator`` node: the Kalman-filter navigation of :mod:`seapup_control.navigation` on the graph.

Subscribes (namespace ``/seapup``) to ``sensors/velocity`` (doppler log and
gyros), ``sensors/imu`` (attitude), ``sensors/depth`` and ``sensors/position``
(acoustic fix) and publishes ``navigation/odometry`` (nav_msgs/Odometry,
``odom_ned`` -> ``base_link_frd``, stamped with the sample time, position
covariance from the filter) once per sample t_k.

When is a sample complete? With the simulator's manifest (``sensors/sample``,
seapup_msgs/SampleManifest: the topics it published for t_k), when every
reading it lists that the navigator subscribes to has arrived -- the acoustic
fix of t_k included, however the deliveries of the topics interleave (it
came after the depth reading, and was then fused a sample late, depending
on timing). A later sample complete while an earlier one still waits for a
reading that never comes is taken after ``manifest_patience`` complete
samples, the earlier ones first. Without a manifest (a vehicle's
instruments): when the readings of ``sample_topics`` stamped t_k have all
arrived, or when a later velocity reading comes first. Non-finite or
malformed readings, and readings in another frame than their instrument's (``base_link_frd`` for the
velocity and IMU, ``odom_ned`` for the fix and the depth: :mod:`seapup_common.ros.messages`), are rejected
and counted, never fused (a rejected reading
has arrived, for completeness); ``/diagnostics`` (``seapup/navigator``)
carries the counts, the estimate's standard deviation and the estimate publisher's
matched readers (``subscribers:/seapup/navigation/odometry``).

A reader that matches late (discovery lags on a loaded machine) would miss the
estimates sent before -- and in a lockstep graph held at a sample by its driver
no newer one comes: the position controller would wait for ever. So whenever
the publisher's matched readers grow, the newest estimate is published again,
unchanged (its consumers take an estimate stamp once: a repeat is ignored).
The matched-reader count in ``/diagnostics`` is the one the newest estimate has
reached, so a driver that waits for it knows every reader has that estimate.
"""
from __future__ import annotations

import math

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseWithCovarianceStamped, TwistWithCovarianceStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from sensor_msgs.msg import Imu
from seapup_msgs.msg import Depth, SampleManifest

from seapup_common.contract import ContractError
from seapup_common.lockstep import StampGate
from seapup_common.ros.messages import MeasurementCollector, diagnostic_array, estimate_to_odometry, stamp_to_ns
from seapup_common.ros.node import (COMMAND_QOS, RELIABLE_QOS, STREAM_QOS, declare_from_package_file, each_one_of,
                                    run_node)
from seapup_common.topics import DIAGNOSTICS, NAMESPACE
from seapup_control.navigation import SHELL_PARAMETERS, Navigator, NavigatorParams

__all__ = ["NavigatorNode", "main"]

_TOPICS = {"velocity": ("sensors/velocity", TwistWithCovarianceStamped), "imu": ("sensors/imu", Imu),
           "depth": ("sensors/depth", Depth), "position": ("sensors/position", PoseWithCovarianceStamped)}


class NavigatorNode(Node):
    """rclpy shell around :class:`Navigator` (see the module docstring)."""

    #: Spun by rclpy's EventsExecutor unless told otherwise (seapup_common.ros.node.DEFAULT_EXECUTOR): plain
    #: subscriptions and publishers, none replaced while spinning; the hierarchy's third-busiest process.
    EXECUTOR = "events"

    def __init__(self, **kwargs):
        super().__init__("navigator", namespace=NAMESPACE, **kwargs)
        p = declare_from_package_file(self, "seapup_control", "navigator.yaml", section="navigator", ranges={
            "q_walk": (0.0, 1e3), "velocity_std": (1e-6, 10.0), "fix_std": (1e-3, 1e3), "depth_std": (1e-4, 1e3),
            "initial_std": (1e-3, 1e4), "gate_probability": (0.5, 1.0 - 1e-12), "coast_inflation": (1.0, 1e6),
            "max_speed": (0.01, 100.0), "depth_range": (-1e3, 1.2e4), "reacquire_after": (0, 10**6),
            "manifest_patience": (1, 1000)},
            allowed={"sample_topics": each_one_of(*_TOPICS, empty=False, unique=True)})
        shell = {key: p.pop(key) for key in SHELL_PARAMETERS}   # the rest is the filter's
        self.sample_topics = set(shell["sample_topics"])
        self.manifest_patience = int(shell["manifest_patience"])
        unknown = self.sample_topics - set(_TOPICS)
        if unknown or "velocity" not in self.sample_topics:
            raise ValueError(f"sample_topics {sorted(self.sample_topics)}: must include velocity and only "
                             f"{', '.join(_TOPICS)}")
        self.navigator = Navigator(NavigatorParams.from_mapping(p))
        self.collector = MeasurementCollector()
        self.rejected = 0                       # sensor readings refused (stamp, frame, finite, unit quaternion)
        self.rejected_manifests = 0             # manifests refused (stamp far from the graph's time)
        self._arrived: dict[int, set] = {}  # sample stamp -> topics heard for it
        self._processed_ns: int | None = None
        self._manifests: dict[int, set] = {}  # sample stamp -> the readings the simulator published for it
        self._manifested = False                # samples complete by the manifest (_by_manifest)
        self._held: dict[int, dict] = {}        # sample stamp -> topic -> its readings, waiting for it
        self._manifest_topic = self.resolve_topic_name("sensors/sample")
        self.forced_samples = 0                 # processed before a listed reading came (manifest_patience)
        self._topic_names = {self.resolve_topic_name(topic): name for name, (topic, _) in _TOPICS.items()}
        self.stamps = StampGate()
        self.publisher = self.create_publisher(Odometry, "navigation/odometry", STREAM_QOS)
        self._newest: Odometry | None = None   # the newest estimate sent, for readers that match late
        self._readers = 0                       # the publisher's matched readers when it was last sent
        self.repeated = 0                       # estimates sent again to readers that matched late
        self.diagnostics = self.create_publisher(DiagnosticArray, DIAGNOSTICS, RELIABLE_QOS)
        for name, (topic, kind) in _TOPICS.items():
            self.create_subscription(kind, topic, lambda msg, name=name: self._on_reading(name, msg), COMMAND_QOS)
        self.create_subscription(SampleManifest, "sensors/sample", self._on_manifest, COMMAND_QOS)
        self.create_timer(1.0, self._diagnose)
        self.create_timer(0.05, self._check_readers)

    def _on_reading(self, name: str, msg) -> None:
        stamp = stamp_to_ns(msg.header.stamp)
        if not self.stamps.accept(stamp):  # one far-future stamp would make every real sample "late"
            self.rejected += 1
            self.get_logger().warn(f"{name} reading rejected: {self.stamps.why(stamp)}", throttle_duration_sec=2.0)
            return
        if self._by_manifest():
            self._hold(name, stamp, msg)
            return
        if not self.collector.add(msg):
            self.rejected += 1
            self.get_logger().warn(f"{name} reading rejected: {self.collector.last_error}", throttle_duration_sec=2.0)
            return
        t_ns = stamp
        if self._processed_ns is not None and t_ns <= self._processed_ns:
            return  # a late reading of a processed sample: kept for the next one
        if name == "velocity":
            for earlier in sorted(k for k in self._arrived if k < t_ns):
                self._process(earlier)  # a sample whose other readings never came
        self._arrived.setdefault(t_ns, set()).add(name)
        if name == "velocity" or t_ns in self._arrived and "velocity" in self._arrived[t_ns]:
            if self.sample_topics <= self._arrived[t_ns]:
                self._process(t_ns)

    def _by_manifest(self) -> bool:
        """Samples complete by the simulator's manifest: one was heard, or its publisher is on the graph
        (so the first sample waits for it too)."""
        if not self._manifested and self.count_publishers(self._manifest_topic) > 0:
            self._manifested = True
        return self._manifested

    def _hold(self, name: str, t_ns: int, msg) -> None:
        """Keep a reading for its sample (the collector takes it when the sample is processed: a later
        sample's reading arriving first must not replace it)."""
        try:   # converted and checked now, once; the collector keeps the readings when the sample is processed
            readings = MeasurementCollector.readings(msg)
        except (ContractError, ValueError) as exc:   # counted whether or not its sample is still open
            self.rejected += 1
            self.get_logger().warn(f"{name} reading rejected: {exc}", throttle_duration_sec=2.0)
            readings = None
        if self._processed_ns is not None and t_ns <= self._processed_ns:
            return  # late: its sample was processed without it
        if readings is not None:
            self._held.setdefault(t_ns, {})[name] = readings
        self._arrived.setdefault(t_ns, set()).add(name)   # a rejected reading came too: no waiting for it
        self._complete()

    def _on_manifest(self, msg: SampleManifest) -> None:
        t_ns = stamp_to_ns(msg.header.stamp)
        if not self.stamps.accept(t_ns):
            self.rejected_manifests += 1
            self.get_logger().warn(f"manifest rejected: {self.stamps.why(t_ns)}", throttle_duration_sec=2.0)
            return
        if self._processed_ns is not None and t_ns <= self._processed_ns:
            return
        self._manifested = True
        self._manifests[t_ns] = {self._topic_names[t] for t in msg.topics if t in self._topic_names}
        self._complete()

    def _complete(self) -> None:
        """Process, in stamp order, every manifested sample whose listed readings have all arrived; one
        still waiting goes first once ``manifest_patience`` later samples are complete (a lost reading)."""
        while self._manifests:
            first = min(self._manifests)
            if self._manifests[first] <= self._arrived.get(first, set()):
                del self._manifests[first]
                self._process(first)
                continue
            ready = [t for t, need in self._manifests.items() if t != first and need <= self._arrived.get(t, set())]
            if len(ready) < self.manifest_patience:
                return
            missing = sorted(self._manifests.pop(first) - self._arrived.get(first, set()))
            self.forced_samples += 1
            self.get_logger().warn(f"sample t = {first * 1e-9:.3f} s processed without its {', '.join(missing)} "
                                   f"reading ({len(ready)} later samples complete)", throttle_duration_sec=2.0)
            self._process(first)

    def _process(self, t_ns: int) -> None:
        for stamp in [k for k in self._arrived if k <= t_ns]:
            del self._arrived[stamp]
        for stamp in sorted(k for k in self._held if k <= t_ns):  # held readings, in sample and topic order
            held = self._held.pop(stamp)
            for name in _TOPICS:
                for field, reading in held.get(name, ()):
                    self.collector.keep(field, reading)
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
            self._check_readers()  # a reader that matched since the newest was sent gets that one first
            self._newest = estimate_to_odometry(estimate, t_ns)
            self.publisher.publish(self._newest)

    def _check_readers(self) -> None:
        """The newest estimate again if readers matched since it was sent (see the module docstring)."""
        readers = self.publisher.get_subscription_count()
        if readers > self._readers and self._newest is not None:
            self.publisher.publish(self._newest)
            self.repeated += 1
        self._readers = readers

    def _diagnose(self) -> None:
        self._check_readers()  # the count reported is the one the newest estimate has reached
        estimate = self.navigator.estimate()
        values = {**self.navigator.counts, "rejected_readings": self.rejected,
                  "rejected_manifests": self.rejected_manifests, "forced_samples": self.forced_samples,
                  "samples_by": "manifest" if self._manifested else "sample_topics", "repeated_estimates": self.repeated,
                  f"subscribers:{self.publisher.topic_name}": self._readers,
                  "horizontal_std": estimate.horizontal_std if estimate else math.nan,
                  "depth_std": math.sqrt(estimate.position_cov[2, 2]) if estimate else math.nan}
        level = DiagnosticStatus.OK if estimate is not None else DiagnosticStatus.WARN
        self.diagnostics.publish(diagnostic_array("seapup/navigator", level,
                                                  "tracking" if estimate is not None else "waiting for a position fix", values, int(self.navigator.t * 1e9) if self.navigator.t is not None else 0))


def main(args=None) -> int:
    return run_node(NavigatorNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
