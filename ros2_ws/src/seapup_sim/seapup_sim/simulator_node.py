"""The ``simulator`` node: the Seapup plant on the ROS graph.

A shell over :class:`seapup_sim.simulator_core.SimulatorCore` (all computation is
there) and :class:`seapup_common.lockstep.server.LockstepServer` (every rule of
the lockstep protocol is there: start gate, handshake, time-outs, pace, holds
at ``end_time`` / ``start_held``, catch-up republishing, reset): this node feeds
them events and executes the actions they return. Namespace ``/seapup``; topics,
services and parameters are listed in the README. Times are simulated time:
every message is stamped t_k and, with ``publish_clock``, ``/clock`` carries t_k
so other nodes can run with ``use_sim_time``.

Modes:
- ``lockstep``: publish the outputs of t_k (and /clock), wait for the command
  stamped t_k, integrate to t_k + T with it held (fig. 5.1); after
  ``lockstep_timeout`` wall seconds hold the previous command and go on. No
  polling: a one-shot timer wakes the node at the server's next deadline.
- ``realtime``: integrate one control period per wall-timer tick of
  T / real_time_factor (0: as fast as the executor allows) with the latest
  valid command.

``end_time`` > 0 holds the graph at the sample t_k >= end_time (either mode);
``start_held`` holds it at t_0 until ``end_time`` is set; a later ``end_time``
set at run time resumes it (see the server's rules). After the messages of
each sample the simulator publishes its manifest, ``sensors/sample``
(:func:`~seapup_sim.ros.simulator_messages.sample_messages`); a message is packed only for a topic with a
matched subscriber (nobody else could hear it). Every environment
setting is a read-only parameter ``environment.<section>.<key>``
(:mod:`seapup_sim.ros.simulator_parameters`); services change the current,
sensors, configuration and fouling at run time. The standard ``simulation_interfaces`` control surface
(state, steps, reset, the vehicle's entity state) is :mod:`seapup_sim.ros.simulation_control`.

Commands are subscribed raw: a message that does not decode, or whose
re-encoding differs in length (a wrong array length), is counted and dropped
without touching the simulation.
"""
from __future__ import annotations

import time

import numpy as np
import rclpy.parameter
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import (PoseWithCovarianceStamped, TwistWithCovarianceStamped,
                               Vector3Stamped, WrenchStamped)
from nav_msgs.msg import Odometry
from nav_msgs.msg import Path as PathMessage
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, Range
from seapup_msgs.msg import BladePitch, Depth, SampleManifest
from seapup_msgs.srv import Reset, SetConfiguration, SetCurrent, SetSensorProfile, SetThrusterEfficiency
from tf2_msgs.msg import TFMessage

from seapup_common.contract import ContractError
from seapup_common.lockstep.server import (POLL_READERS, PUBLISH, REPUBLISH, RESEND_CLOCK, RESET, STEP, STEP_DONE,
                                           STEP_PROGRESS, TIME_OUT, WAKE_AT, LockstepServer)
from seapup_common.ros import messages as conv
from seapup_common.ros.graph import SubscriberGate
from seapup_common.ros.sample_bytes import SampleEncoder, blade_pitch_values
from seapup_common.ros.node import (COMMAND_QOS, QUIET_PUBLISHER, QUIET_SUBSCRIPTION, STREAM_QOS, SERVICE_QOS,
                                    TF_QOS, TF_STATIC_QOS, QosWatch, run_node)
from seapup_common.topics import CLOCK, DIAGNOSTICS, NAMESPACE, TF, TF_STATIC
from seapup_sim.environment_config import load_environment
from seapup_sim.sensors import sensor_profiles
from seapup_sim.simulator_core import SimulatorCore, SimulatorConfig
from seapup_sim.ros.simulation_control import SimulationControl
from seapup_sim.ros.simulator_messages import diagnostics_of, sample_messages
from seapup_sim.ros.simulator_parameters import (declare_simulator_parameters, environment_overrides,
                                                 events_parameter, refusal)
from seapup_sim.simulator_services import answer, apply_current, current_said
from seapup_sim.vehicle_config import available_configs

__all__ = ["SimulatorNode", "main"]


class SimulatorNode(Node):
    """rclpy shell around :class:`SimulatorCore` and :class:`LockstepServer` (see module docstring)."""

    #: Spun by rclpy's EventsExecutor unless told otherwise (seapup_common.ros.node.DEFAULT_EXECUTOR; its
    #: coroutine services through :func:`~seapup_sim.ros.simulation_control.deferred_service`).
    EXECUTOR = "events"

    def __init__(self, **kwargs):
        super().__init__("simulator", namespace=NAMESPACE, **kwargs)
        p = declare_simulator_parameters(self)
        if p["mode"] not in ("lockstep", "realtime"):
            raise ValueError(f"mode must be lockstep or realtime, got {p['mode']!r}")
        self.mode = p["mode"]
        if self.get_parameter("use_sim_time").value:
            self.set_parameters([rclpy.parameter.Parameter("use_sim_time", value=False)])
            self.get_logger().error("use_sim_time refused: the simulator is the clock source (it publishes "
                                    "/clock); running on its own time")
        environment = environment_overrides(self)
        load_environment(environment)  # refuse a bad environment before anything starts
        self.config = SimulatorConfig(p["vehicle"], p["seed"], p["physics_step"], p["control_period"],
                                      p["blade_pitch_limit"], p["watchdog_timeout"], p["watchdog_action"],
                                      environment=environment, dynamics=p["dynamics"],
                                      events=events_parameter(p["events"]))
        self.start_state = np.zeros(12)
        self.start_state[2] = p["start_depth"]
        self.simulator = SimulatorCore(self.config, self.start_state)
        self.simulator.limits.check_state(self.start_state)
        self.simulator.limits.check_real_time_factor(p["real_time_factor"], self.config.control_period)
        self.server = LockstepServer(self.config.control_period, lockstep=self.mode == "lockstep",
                                     timeout=p["lockstep_timeout"], pace=p["lockstep_pace"], end_time=p["end_time"],
                                     start_held=p["start_held"])
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._create_interfaces(p["publish_clock"], p["publish_tf"])
        self._gate = self._subscriber_gate(p["wait_for_subscribers"])
        self._wall_start = time.monotonic()
        self._last_warn = self._last_gate_log = 0.0
        self._samples_published = 0  # samples t_k published (each data topic once per sample)
        self._encoder = SampleEncoder()
        self._sent: list = []  # the current sample's (publisher, packed message) pairs, for a republish
        self._armed_at: float | None = None   # when the wake timer fires (None: not armed)
        self._wake_timer = self.create_timer(1.0, self._on_wake, autostart=False)
        if self.mode == "lockstep":
            self._on_wake()
        else:
            self._realtime_timer = self.create_timer(self._realtime_period(), self._realtime_tick)
        self.create_timer(p["diagnostics_period"], self._publish_diagnostics)
        self.get_logger().info(
            f"simulator ready: {self.mode}, vehicle {self.config.vehicle} ({self.config.dynamics}), sensors "
            f"{self.simulator.sensor_profile.name}, T = {self.config.control_period} s, dt = "
            f"{self.config.physics_step} s, seed {self.config.seed}")

    def _create_interfaces(self, publish_clock: bool, publish_tf: bool) -> None:
        def pub(kind, topic, qos):  # no per-publisher event handlers on the executor's path: QosWatch instead
            return self.create_publisher(kind, topic, qos, event_callbacks=QUIET_PUBLISHER)
        self._qos_watch = QosWatch(self)
        self.pub_applied = pub(BladePitch, "thrusters/applied", STREAM_QOS)
        self.pub_velocity = pub(TwistWithCovarianceStamped, "sensors/velocity", STREAM_QOS)
        self.pub_imu = pub(Imu, "sensors/imu", STREAM_QOS)
        self.pub_position = pub(PoseWithCovarianceStamped, "sensors/position", STREAM_QOS)
        self.pub_depth = pub(Depth, "sensors/depth", STREAM_QOS)
        self.pub_altitude = pub(Range, "sensors/altitude", STREAM_QOS)
        self.pub_truth = pub(Odometry, "truth/odometry", STREAM_QOS)
        self.pub_odom = pub(Odometry, "odometry", STREAM_QOS)
        self.pub_current = pub(Vector3Stamped, "environment/current", STREAM_QOS)
        self.pub_wrench = pub(WrenchStamped, "umbilical/wrench", STREAM_QOS)
        self.pub_cable = pub(PathMessage, "umbilical/shape", STREAM_QOS)
        self.pub_manifest = pub(SampleManifest, "sensors/sample", STREAM_QOS)
        self.pub_clock = pub(Clock, CLOCK, STREAM_QOS) if publish_clock else None
        self.pub_tf = pub(TFMessage, TF, TF_QOS) if publish_tf else None
        if publish_tf:   # latched: a viewer that joins later still gets the fixed frames
            self._pub_tf_static = pub(TFMessage, TF_STATIC, TF_STATIC_QOS)
            self._pub_tf_static.publish(conv.static_transforms(0))
        self.pub_diag = pub(DiagnosticArray, DIAGNOSTICS, 10)
        self.create_subscription(BladePitch, "thrusters/command", self._on_command, COMMAND_QOS, raw=True,
                                 event_callbacks=QUIET_SUBSCRIPTION)
        def srv(kind, name, callback):
            self.create_service(kind, name, callback, qos_profile=SERVICE_QOS)
        srv(Reset, "~/reset", self._srv_reset)
        srv(SetConfiguration, "~/set_configuration", self._srv_configuration)
        srv(SetThrusterEfficiency, "~/set_thruster_efficiency", self._srv_efficiency)
        srv(SetCurrent, "~/set_current", self._srv_current)
        srv(SetSensorProfile, "~/set_sensor_profile", self._srv_sensor_profile)
        self.control = SimulationControl(self)   # simulation_interfaces: state, steps, reset, the entity

    def _subscriber_gate(self, topics) -> SubscriberGate:
        """A topic listed k times needs k matched subscribers (e.g. two controllers and a probe)."""
        by_topic = {pub.topic_name: pub for pub in self.publishers}
        counts: dict[str, int] = {}
        for topic in topics:
            if not topic:
                continue
            name = self.resolve_topic_name(topic)
            if name not in by_topic:
                raise ValueError(f"wait_for_subscribers: {topic[:80]!r} is not a topic this node publishes "
                                 f"({', '.join(sorted(by_topic))})")
            counts[name] = counts.get(name, 0) + 1
        requirements = [(by_topic[name], count) for name, count in counts.items()]
        return SubscriberGate(requirements, grace=float(self.get_parameter("discovery_grace").value))

    def _gate_open(self) -> bool:
        """Whether every awaited subscriber is matched (logged every 5 s while not)."""
        if self._gate.ready():
            return True
        now = time.monotonic()
        if now - self._last_gate_log > 5.0:
            self._last_gate_log = now
            self.get_logger().info("waiting for subscribers: " + ", ".join(self._gate.missing()))
        return False

    # -- the lockstep server's actions ---------------------------------------------
    def _run(self, actions) -> None:
        """Execute the server's actions in order (a plant that diverges halts it and ends the list)."""
        for action in actions:
            kind = action.kind
            if kind in (STEP, PUBLISH):
                try:
                    self.simulator.step() if kind == STEP else self._publish_outputs()
                except (FloatingPointError, ContractError) as exc:  # DivergenceError or a non-finite output
                    self.get_logger().error(f"simulation halted: {exc}; call ~/reset to continue")
                    self._run(self.server.halt(str(exc), time.monotonic()))
                    return
            elif kind == WAKE_AT:
                self._arm(action.at)
            elif kind == TIME_OUT:
                self.simulator.lockstep_timeout()
                self._warn(f"no command stamped t = {self.simulator.t:.3f} s within {self.server.timeout} s: "
                           "holding the last one")
                self._publish_diagnostics()  # said at once (seapup_common.lockstep.ENDED_WAITS)
            elif kind == REPUBLISH:   # the current sample's messages once more, unchanged
                self._publish_clock()
                self._send(self._sent)
            elif kind == RESEND_CLOCK:   # handshake: /clock only (no duplicate data for recorders)
                self._publish_clock()
            elif kind == POLL_READERS:
                counts = {publisher.topic_name: publisher.get_subscription_count() for publisher, _ in self._sent}
                self._run(self.server.readers(counts, time.monotonic()))
            elif kind == RESET:
                self.simulator.reset(self.config.seed, self.start_state)
            elif kind in (STEP_PROGRESS, STEP_DONE):
                self.control.step_event(action)

    def _arm(self, at: float | None) -> None:
        """Wake at ``at`` [s monotonic]; a timer armed earlier stays (its tick is harmless and re-arms)."""
        if at is None or (self._armed_at is not None and self._armed_at <= at):
            return
        self._armed_at = at
        self._wake_timer.timer_period_ns = max(1, int((at - time.monotonic()) * 1e9))
        self._wake_timer.reset()

    def _on_wake(self) -> None:
        self._wake_timer.cancel()   # one-shot
        self._armed_at = None
        now = time.monotonic()
        if not self.server.started and self._gate_open():
            self._run(self.server.gate_ready(now))
        self._run(self.server.tick(now))

    def _realtime_tick(self) -> None:
        if not self.server.started:
            if not self._gate_open():
                return
            self._run(self.server.gate_ready(time.monotonic()))
        self._run(self.server.period(time.monotonic()))

    # -- parameters --------------------------------------------------------------
    def _realtime_period(self) -> float:
        rtf = self.get_parameter("real_time_factor").value
        return 0.0 if rtf == 0 else self.config.control_period / rtf

    def _on_set_parameters(self, params) -> SetParametersResult:
        for prm in params:
            reason = refusal(prm.name, prm.value, self.simulator, self.config.control_period)
            if reason:
                self.get_logger().warn(f"parameter refused: {reason}")
                return SetParametersResult(successful=False, reason=reason)
        for prm in params:
            if prm.name == "end_time":
                self._run(self.server.set_end_time(float(prm.value), time.monotonic()))
            elif prm.name == "lockstep_pace":
                self._run(self.server.set_pace(float(prm.value), time.monotonic()))
            elif prm.name == "lockstep_timeout":
                self._run(self.server.set_timeout(float(prm.value), time.monotonic()))
            elif prm.name == "watchdog_timeout":
                self.config.watchdog_timeout = float(prm.value)
            elif prm.name == "watchdog_action":
                self.config.watchdog_action = prm.value
            elif prm.name == "real_time_factor" and self.mode == "realtime":
                # at once, whatever wait the old timer had scheduled
                self.destroy_timer(self._realtime_timer)
                rtf = float(prm.value)
                self._realtime_timer = self.create_timer(
                    0.0 if rtf == 0 else self.config.control_period / rtf, self._realtime_tick)
        return SetParametersResult(successful=True)

    # -- commands ----------------------------------------------------------------
    def _warn(self, text: str) -> None:
        now = time.monotonic()
        if now - self._last_warn >= 1.0:  # at most once per second
            self._last_warn = now
            self.get_logger().warn(text)

    def _on_command(self, raw: bytes) -> None:
        decoded = blade_pitch_values(raw)   # a command in base_link_frd or no frame; else the typed path
        if decoded is not None:
            stamp, pitch = decoded
        else:
            try:
                msg = deserialize_message(raw, BladePitch)
                if len(serialize_message(msg)) != len(raw):
                    raise ValueError(f"{len(raw)} bytes do not encode a BladePitch (wrong array length?)")
            except Exception as exc:  # noqa: BLE001 - any decoding failure is bad input
                self.simulator.reject_malformed(f"malformed command: {exc}")
                self._warn(self.simulator.last_error)
                return
            stamp, pitch = conv.stamp_to_ns(msg.header.stamp), msg.pitch
        if not self.server.takes_commands:
            self.simulator.reject("rejected_future", "command before the first sample was published")
            return
        ok, reason = self.simulator.submit(np.array(pitch, float), stamp, self.mode == "lockstep")
        if not ok or reason == "saturated":
            self._warn(f"command {'rejected' if not ok else 'saturated'}: {reason if not ok else ''}".strip())
        self._run(self.server.command(stamp, ok, time.monotonic()))

    # -- outputs -----------------------------------------------------------------
    def _publish_clock(self) -> None:
        if self.pub_clock is not None:
            self.pub_clock.publish(self._encoder.clock(self.simulator.t_ns))

    def _publish_outputs(self) -> None:
        out = self.simulator.outputs()
        self.simulator.check_finite(out)
        self._publish_clock()
        self._samples_published += 1
        self._sent = sample_messages(self._encoder, self, out, self.simulator.t_ns, self.simulator.sensor_profile,
                                     self.simulator.cable_shape())
        self._send(self._sent)

    @staticmethod
    def _send(messages) -> None:
        """Publish each message that has a matched subscriber (packed only then; nobody else could hear it)."""
        for publisher, packed in messages:
            if publisher.get_subscription_count():
                publisher.publish(packed())

    def _publish_diagnostics(self) -> None:
        self.pub_diag.publish(diagnostics_of(self.mode, self.simulator, self.server, self._graph_problems(),
                                             self._samples_published, time.monotonic() - self._wall_start))

    def _graph_problems(self) -> list[str]:
        """What is wrong around the simulator on the graph (for WARN diagnostics)."""
        problems = self._qos_watch.problems()
        if self.pub_clock is not None and self.count_publishers(CLOCK) > 1:
            problems.append(f"{self.count_publishers(CLOCK)} publishers on {CLOCK}: another clock source "
                            "(a second simulator?) interleaves its time with ours")
        command_topic = self.resolve_topic_name("thrusters/command")
        types = dict(self.get_topic_names_and_types()).get(command_topic, [])
        others = [t for t in types if t != "seapup_msgs/msg/BladePitch"]
        if others:
            problems.append(f"{command_topic} also carries {', '.join(others)}: those messages never arrive")
        if self.mode == "lockstep" and self.server.unanswered:
            problems.append(f"the controller has not answered {self.server.unanswered} sample(s) in a row "
                            "(holding the last command)")
        return problems

    # -- services ----------------------------------------------------------------
    def _srv_reset(self, request, response):
        def act():
            state = np.array(request.state, float) if request.use_state else self.start_state
            self.simulator.reset(request.seed, state)  # validated against environment/limits.yaml, atomic
            self._run(self.server.reset(time.monotonic()))   # the commands were for before; t_0 published
        return answer(response, act, lambda: f"reset: t = 0, seed {request.seed}", self.get_logger())

    def _srv_configuration(self, request, response):
        def act():
            if request.name not in available_configs():
                raise ValueError(f"no configuration {request.name[:80]!r} "
                                 f"(available: {', '.join(available_configs())})")
            self.simulator.set_configuration(request.name)
        return answer(response, act, lambda: f"configuration {request.name} at t = {self.simulator.t:.2f} s",
                      self.get_logger())

    def _srv_efficiency(self, request, response):
        return answer(response, lambda: self.simulator.set_thruster_efficiency(np.array(request.efficiency)),
                      lambda: "thruster efficiency " + ", ".join(f"{e:.3f}" for e in request.efficiency),
                      self.get_logger())

    def _srv_current(self, request, response):
        return answer(response, lambda: apply_current(self.simulator, request),
                      lambda: current_said(self.simulator, request), self.get_logger())

    def _srv_sensor_profile(self, request, response):
        def act():
            if request.name not in sensor_profiles():
                raise ValueError(f"no sensor profile {request.name[:80]!r} (available: {', '.join(sensor_profiles())})")
            self.simulator.set_sensor_profile(request.name)
        return answer(response, act, lambda: f"sensor profile {request.name}", self.get_logger())


def main(args=None) -> int:
    return run_node(SimulatorNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
