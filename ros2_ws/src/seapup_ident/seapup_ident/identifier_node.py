"""The ``identifier`` node: online multivariable recursive identification (thesis ch. 6, 7).

A thin shell over :class:`seapup_ident.online.OnlineIdentifier`: it subscribes to
``/seapup/sensors/velocity`` (u, v, w, r), ``/seapup/sensors/imu`` (roll, pitch) and
``/seapup/thrusters/applied`` (the blade pitches at each sample; the next sample's reading is
the input u(t_k) held over the interval, see :mod:`seapup_ident.online`),
runs the estimator chosen by its parameters (``config/identifier.yaml``) on every complete
sample, publishes the model on ``/seapup/identifier/model`` (``seapup_msgs/IdentifiedModel``) and
records the run -- the readings it used and each published model -- into an MCAP bag, so
``./seapup ident fit BAG`` with the same settings gives the same model. Non-finite readings, readings in
another frame than their instrument's and non-unit quaternions are refused, counted and logged; the estimate
never sees them. The model's ``rejected`` and ``/diagnostics`` (``seapup/identifier``, every second) count
every refused reading: by its message's checks here and by the core.
"""
from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import TwistWithCovarianceStamped
from rclpy.node import Node
from rclpy.serialization import serialize_message
from seapup_msgs.msg import BladePitch, IdentifiedModel
from sensor_msgs.msg import Imu

from seapup_common.bag import BagWriter, make_typestore
from seapup_common.blade_pitch import THRUSTER_NAMES
from seapup_common.recorder_node import project_msg_files
from seapup_common.contract import ContractError
from seapup_common.ros.messages import attitude_from_imu, diagnostic_array, stamp_to_ns, velocity_from_msg
from seapup_common.ros.node import (COMMAND_QOS, RELIABLE_QOS, STREAM_QOS, declare_from_package_file, each_one_of,
                                    one_of, path_or_empty, run_node)
from seapup_common.topics import APPLIED, DIAGNOSTICS, IDENTIFIED_MODEL, IMU, NAMESPACE, TOPIC_TYPES, VELOCITY
from seapup_ident.armax import ArmaxOrders
from seapup_ident.online import OUTPUTS, OnlineIdentifier
from seapup_ident.recursive import METHODS, DataError, Forgetting

__all__ = ["IdentifierNode", "main"]

_TOPICS = {"velocity": (VELOCITY, TwistWithCovarianceStamped), "attitude": (IMU, Imu), "applied": (APPLIED, BladePitch)}


class IdentifierNode(Node):
    """rclpy shell around :class:`OnlineIdentifier` (see the module docstring)."""

    #: Its readings' callbacks take the message info (the middleware's reception time, for the drain at the
    #: stop): spun by the SingleThreadedExecutor (seapup_common.ros.node.DEFAULT_EXECUTOR).
    MESSAGE_INFO = True

    def __init__(self, **kwargs):
        super().__init__("identifier", namespace=NAMESPACE, **kwargs)
        p = declare_from_package_file(self, "seapup_ident", "identifier.yaml", section="identifier", ranges={
            "orders": (0, 20), "lambda0": (0.0, 1.0), "alpha": (0.0, 1.0), "forgetting": (0.0, 1.0),
            "p0": (1e-6, 1e12), "rpem_filter_k0": (0.0, 1.0), "rpem_filter_gamma": (0.0, 1.0),
            "sample_period": (0.01, 10.0)}, allowed={
            "method": one_of(*METHODS), "outputs": each_one_of(*OUTPUTS, empty=False, unique=True),
            "bag_path": path_or_empty("the bag directory to create (must not exist); 'none': no bag")})
        outputs = list(p["outputs"])
        na, nb, nc = (int(v) for v in p["orders"])
        forgetting = Forgetting(float(p["forgetting"])) if p["forgetting"] > 0 else \
            Forgetting.schedule(float(p["lambda0"]), float(p["alpha"]))
        weakening = (float(p["rpem_filter_k0"]), float(p["rpem_filter_gamma"])) \
            if p["method"] == "rpem" and p["rpem_filter_k0"] > 0 else None
        self.core = OnlineIdentifier(ArmaxOrders(len(outputs), 4, na, nb, nc), p["method"], outputs,
                                     forgetting=forgetting, p0=float(p["p0"]), sample_period=float(p["sample_period"]),
                                     filter_weakening=weakening)
        self.publisher = self.create_publisher(IdentifiedModel, IDENTIFIED_MODEL, STREAM_QOS)
        self.refused = 0                   # readings refused by their message's checks (the core counts its own)
        self._latest_ns = 0                # the newest sample used: the diagnostics' stamp (the graph's time)
        self.diagnostics = self.create_publisher(DiagnosticArray, DIAGNOSTICS, RELIABLE_QOS)
        self.create_timer(1.0, self._diagnose)
        self.bag = self._open_bag(p["bag_path"])
        self._held: dict[int, dict] = {}   # readings (as CDR) of samples not complete yet, for the bag
        # run_node takes the readings received before the stop (behind a fast graph on a loaded machine, dozens of
        # samples were still queued when the graph stopped at its end_time, and their models went unestimated):
        # it counts them, and when the middleware received the newest (seapup_common.ros.node._drain)
        self.drain_on_shutdown = True
        self.drain_budget = 8.0
        self.received, self.last_received_ns = 0, 0
        for kind, (topic, msg_type) in _TOPICS.items():
            if kind in self.core.kinds:
                self.create_subscription(msg_type, topic, lambda msg, info, kind=kind: self._on_reading(kind, msg, info),
                                         COMMAND_QOS)
        self.get_logger().info(f"identifying {outputs} with {p['method']} orders ({na}, {nb}, {nc})"
                               + (f"; recording into {self.bag.path}" if self.bag else ""))

    def _open_bag(self, bag_path: str):
        if bag_path == "none":
            return None
        root = Path(os.environ.get("SEAPUP_ROOT", "."))
        path = bag_path or str(root / "bags" / time.strftime("identifier_%Y%m%d_%H%M%S", time.gmtime()))
        bag = BagWriter(path, make_typestore(project_msg_files())).open()
        for kind, (topic, _) in _TOPICS.items():
            if kind in self.core.kinds:
                bag.add_topic(topic, TOPIC_TYPES[topic])
        bag.add_topic(IDENTIFIED_MODEL, TOPIC_TYPES[IDENTIFIED_MODEL])
        return bag

    def _on_reading(self, kind: str, msg, info=None) -> None:
        self.received += 1
        self.last_received_ns = int((info or {}).get("received_timestamp", 0)) or time.time_ns()
        stamp = stamp_to_ns(msg.header.stamp)
        try:   # the message's own checks (frame, finite, unit quaternion): refused here, counted here
            values = self._values(kind, msg)
        except (ContractError, DataError, ValueError) as exc:
            self.refused += 1
            self.get_logger().warn(f"{kind} reading refused: {exc}", throttle_duration_sec=2.0)
            return
        try:
            used = self.core.add(kind, stamp, values)   # the core counts what it refuses (counts["rejected"])
        except (DataError, ValueError) as exc:
            self.get_logger().warn(f"{kind} reading refused: {exc}", throttle_duration_sec=2.0)
            return
        if self.bag is not None:  # only a reading the core took (a refused one never replaces a good one)
            self._held.setdefault(stamp, {})[kind] = serialize_message(msg)
        for sample in used:
            self._publish(sample)

    @staticmethod
    def _values(kind: str, msg) -> list:
        if kind == "velocity":
            velocity, rates = velocity_from_msg(msg)
            if not (velocity.valid and rates.valid):
                raise DataError("invalid velocity or rate reading")
            return [*velocity.value, rates.value[2]]
        if kind == "attitude":
            attitude = attitude_from_imu(msg)
            if not attitude.valid:
                raise DataError("invalid attitude reading")
            return list(attitude.value[:2])
        return list(msg.pitch)

    def rejected(self) -> int:
        """Every reading refused: by its message's checks here, and by the core."""
        return self.refused + self.core.counts["rejected"]

    def _diagnose(self) -> None:
        counts = {**self.core.counts, "refused_messages": self.refused, "rejected_readings": self.rejected()}
        level = DiagnosticStatus.WARN if self.rejected() else DiagnosticStatus.OK
        self.diagnostics.publish(diagnostic_array("seapup/identifier", level, "identifying", counts,
                                                  self._latest_ns, hardware_id="seapup_ident"))

    def _publish(self, used) -> None:
        o, est = self.core.orders, self.core.estimator
        model = est.model
        msg = IdentifiedModel(method=est.method, ny=o.ny, nu=o.nu, na=o.na, nb=o.nb, nc=o.nc,
                              outputs=list(self.core.outputs), inputs=list(THRUSTER_NAMES))
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(used.stamp_ns, 10**9)
        msg.a, msg.b, msg.c = (np.ravel(m).tolist() for m in (model.A, model.B, model.C))
        msg.d = model.d.tolist()
        msg.covariance_trace = est.trace.tolist()
        msg.prediction_error = used.prediction_error.tolist()
        msg.forgetting = float(est.forgetting.value)
        msg.samples, msg.rejected = self.core.counts["used"], self.rejected()
        self._latest_ns = max(self._latest_ns, used.stamp_ns)
        self.publisher.publish(msg)
        if self.bag is not None:
            for stamp in [s for s in self._held if s < used.stamp_ns]:
                del self._held[stamp]   # readings of samples never completed: not used, not recorded
            for kind, cdr in self._held.pop(used.stamp_ns, {}).items():
                if kind != "applied":   # the pitch at t_k measured the interval before it
                    self.bag.write(_TOPICS[kind][0], cdr, used.stamp_ns)
            self.bag.write(_TOPICS["applied"][0], self._held[used.input_stamp_ns]["applied"], used.input_stamp_ns)
            self.bag.write(IDENTIFIED_MODEL, serialize_message(msg), used.stamp_ns)

    def destroy_node(self):
        if self.bag is not None:
            self.bag.close()
            self.bag = None
        return super().destroy_node()


def main(args=None) -> int:
    return run_node(IdentifierNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
