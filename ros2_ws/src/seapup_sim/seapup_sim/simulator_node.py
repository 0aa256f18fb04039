"""The ``simulator`` node: the Seapup plant on the ROS graph.

A shell over :class:`seapup_sim.simulator_core.SimulatorCore` (all computation is
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

With ``end_time`` > 0 the simulator stops stepping once it has published the
sample t_k >= end_time (in either mode): commands are still taken and counted,
/clock stays at t_k, diagnostics say it is at its end. A recorded experiment
then ends at exactly end_time in graph time, however late its driver stops the
graph. With ``start_held`` it holds so at its first sample t_0 until ``end_time``
is set. ``end_time`` can be set at run time: a later value resumes a held
graph (in lockstep with the command for t_k if it came while held, else the
sample is published again, the same messages, for a node that joined while
the graph was held, and waits for its command as usual), so a driver can hold the whole graph at an
exact sample, act (send a goal, switch a controller) and go on -- what it
does then takes effect at the same sample however busy the machine is
(:class:`seapup_bringup.sil.SilGraph` drives a hierarchy like that).

After the messages of each sample the simulator publishes its manifest,
``sensors/sample`` (seapup_msgs/SampleManifest: the stamp t_k and the topics
published for it -- the acoustic fix only at some samples), so a node that needs a sample's readings together knows which to
wait for whatever order they arrive in (the navigator).

Every environment setting is a read-only parameter ``environment.<section>.<key>``
(defaults from ``environment/default.yaml``, overridden by the YAML file named
in ``environment_file``, then by ``-p``/``--params-file``); services change
the current, sensors, configuration and fouling at run time.

Commands are subscribed raw: a message that does not decode, or whose
re-encoding differs in length (a wrong array length), is counted and dropped
without touching the simulation.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import yaml
import rclpy.parameter
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import (PoseWithCovarianceStamped, TwistWithCovarianceStamped,
                               Vector3Stamped, WrenchStamped)
from nav_msgs.msg import Odometry
from nav_msgs.msg import Path as PathMessage
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType,
                                SetParametersResult)
from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, Range
from seapup_msgs.msg import BladePitch, Depth, SampleManifest
from seapup_msgs.srv import Reset, SetConfiguration, SetCurrent, SetSensorProfile, SetThrusterEfficiency
from tf2_msgs.msg import TFMessage

from seapup_common import frames
from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_common.config import load_yaml, merge
from seapup_common.contract import ContractError
from seapup_common.lockstep import Pacer
from seapup_common.ros import messages as conv
from seapup_common.ros.graph import SubscriberGate
from seapup_common.ros.sample_bytes import SampleEncoder
from seapup_common.ros.node import (COMMAND_QOS, QUIET_PUBLISHER, QUIET_SUBSCRIPTION, RELIABLE_QOS, STREAM_QOS,
                                    SERVICE_QOS, TF_QOS, TF_STATIC_QOS, QosWatch, declare_from_package_file, declare_guarded,
                                    flatten, one_of, run_node, text, topic_names)
from seapup_common.topics import CLOCK, DIAGNOSTICS, NAMESPACE, TF, TF_STATIC
from seapup_sim.current import CurrentParams
from seapup_sim.environment_config import default_environment_mapping, load_environment
from seapup_sim.sensors import sensor_profiles
from seapup_sim.simulator_core import SimulatorCore, SimulatorConfig
from seapup_sim.linearised import DYNAMICS
from seapup_sim.vehicle_config import available_configs

__all__ = ["SimulatorNode", "main"]

NED, FRD = frames.FRAME_NED, frames.FRAME_FRD


def _float_range(lo, hi, description, read_only=False):
    return ParameterDescriptor(description=description, read_only=read_only,
                               floating_point_range=[FloatingPointRange(from_value=lo, to_value=hi)])


#: The allowed range of each numeric ``environment.*`` parameter (read-only: given at start). The environment's
#: own validation (:func:`~seapup_sim.environment_config.load_environment`, ``environment/limits.yaml``) is the
#: finer check; these bound what it is given and show in ``./seapup param describe``.
ENVIRONMENT_RANGES = {
    "current.mean_speed": (0.0, 3.0), "current.speed_std": (0.0, 3.0),        # limits.yaml current.speed_max
    "current.mean_direction": (-2 * math.pi, 2 * math.pi), "current.direction_std": (0.0, math.pi),
    "current.break_time": (0.1, 1e5),                                          # limits.yaml current.break_time
    "umbilical.ship_ned": (-1e4, 1e4),            # [m] limits.yaml start_state.horizontal_max
    "umbilical.diameter": (1e-3, 1.0),            # [m] a cable, not a riser
    "umbilical.still_water_drag_coefficient": (0.0, 10.0), "umbilical.strumming_factor": (1.0, 10.0),
    "umbilical.weight_per_length": (-1e3, 1e3),   # [N/m] in water, buoyant (negative) or heavy
    "umbilical.length_ratio": (1.0, 10.0),        # a cable at least as long as the straight line
    "umbilical.attachment": (-10.0, 10.0),        # [m] body axes: on the vehicle (about 1 m long)
    "umbilical.min_flow": (1e-6, 1.0), "umbilical.max_gravity_ratio": (0.0, 1.0),
    "seabed.depth": (0.0, 11000.0),               # [m] the deepest ocean
    "seabed.gradient": (-10.0, 10.0), "seabed.direction": (-2 * math.pi, 2 * math.pi),
    "seabed.points": (-1e5, 1e5),                 # [m] distance and depth pairs
}


def _environment_overrides(node) -> dict:
    """Declare ``environment_file`` and every ``environment.*`` leaf (read-only, ranged, strings with their
    allowed values); return the environment mapping they give (validated by :func:`load_environment`)."""
    declare_guarded(node, {"environment_file": ""}, {"environment_file": ParameterDescriptor(
        description="YAML of environment overrides merged over environment/default.yaml", read_only=True)},
        allowed={"environment_file": text("a YAML file of environment overrides, or empty",
                                          lambda v: "" if not v or Path(v).is_file() else "no such file")})
    defaults = default_environment_mapping()
    path = node.get_parameter("environment_file").value
    if path:
        defaults = merge(defaults, load_yaml(path), strict=f"{Path(path).name} over environment/default.yaml")
    flat = flatten(defaults)
    descriptors = {name: ParameterDescriptor(read_only=True, description="environment (see environment/default.yaml);"
                                             " services change the current and sensors at run time")
                   for name in flat}
    if not flat.get("seabed.points"):
        descriptors["seabed.points"].type = ParameterType.PARAMETER_DOUBLE_ARRAY
    allowed = {"seabed.kind": one_of("flat", "slope", "polyline"), "sensors": one_of(*sensor_profiles())}
    declared = declare_guarded(node, {f"environment.{k}": v for k, v in flat.items()},
                               {f"environment.{k}": d for k, d in descriptors.items()},
                               {f"environment.{k}": r for k, r in ENVIRONMENT_RANGES.items() if k in flat},
                               {f"environment.{k}": a for k, a in allowed.items() if k in flat},
                               where="environment")
    out: dict = {}
    for name, value in declared.items():
        *parents, leaf = name.split(".")[1:]
        level = out
        for key in parents:
            level = level.setdefault(key, {})
        level[leaf] = value
    return out


def _events_problem(value: str) -> str:
    try:
        _events_parameter(value)
    except ValueError as exc:
        return str(exc).splitlines()[0]
    return ""


def _events_parameter(text: str) -> list:
    """The ``events`` parameter (YAML text) as plain data; checked by the simulator's configuration."""
    try:
        events = yaml.safe_load(text) if text else []
    except yaml.YAMLError as exc:
        raise ValueError(f"events is not YAML: {exc}") from None
    return [] if events is None else events

class SimulatorNode(Node):
    """rclpy shell around :class:`SimulatorCore` (see module docstring)."""

    def __init__(self, **kwargs):
        super().__init__("simulator", namespace=NAMESPACE, **kwargs)
        ro = dict(read_only=True)
        p = declare_from_package_file(self, "seapup_sim", "simulator.yaml", {
            "mode": ParameterDescriptor(description="lockstep | realtime", **ro),
            "real_time_factor": _float_range(0.0, 1e4, "realtime speed-up (0 = as fast as possible)"),
            "lockstep_timeout": _float_range(0.001, 60.0, "wall seconds to wait for the t_k command"),
            "lockstep_pace": _float_range(0.0, 1e4, "lockstep: publish no faster than this many times real time, "
                                                    "to be watched (0: as fast as the graph answers; settable at "
                                                    "run time; simulated results are the same at any pace)"),
            "control_period": _float_range(0.01, 10.0, "controller sample period T [s]", **ro),
            "physics_step": _float_range(0.001, 1.0, "integration step [s]", **ro),
            "vehicle": ParameterDescriptor(description="vehicle configuration (~/set_configuration "
                                                       "changes it)", **ro),
            "dynamics": ParameterDescriptor(description="nonlinear (ch. 2) | linearised (eq. 3.2 about hover)",
                                            **ro),
            "seed": ParameterDescriptor(description="random seed (~/reset changes it)", read_only=True,
                                        integer_range=[IntegerRange(from_value=0, to_value=2**31 - 1)]),
            "blade_pitch_limit": _float_range(0.01, BLADE_PITCH_LIMIT, "blade-pitch limit [rad]", **ro),
            "watchdog_timeout": _float_range(0.01, 3600.0, "sim seconds without a valid command"),
            "watchdog_action": ParameterDescriptor(description="hover | neutral"),
            "start_depth": _float_range(0.0, 6000.0, "initial depth [m]", **ro),
            "publish_clock": ParameterDescriptor(description="publish /clock (the simulator owns time)", **ro),
            "publish_tf": ParameterDescriptor(description="publish /tf (REP-105 odom -> base_link, each sample) "
                                                          "and /tf_static (odom -> odom_ned, base_link -> "
                                                          "base_link_frd)", **ro),
            "diagnostics_period": _float_range(0.05, 60.0, "diagnostics period [s wall]", **ro),
            "end_time": _float_range(0.0, 1e9, "the last sample [s sim]: no step past it; 0 = run on (settable at "
                                               "run time: a later value resumes a held graph)"),
            "start_held": ParameterDescriptor(description="hold at the first sample t_0 until end_time is set "
                                                          "at run time (to a later sample; 0: run on)", **ro),
            "wait_for_subscribers": ParameterDescriptor(
                type=ParameterType.PARAMETER_STRING_ARRAY, read_only=True,
                description="published topics that need a matched subscriber (e.g. a recorder's) before "
                            "the first sample is published; a topic listed k times needs k"),
            "discovery_grace": _float_range(0.0, 10.0, "wall seconds the awaited subscribers must stay matched "
                                                       "before the first sample", **ro),
            "events": ParameterDescriptor(description="scheduled changes, YAML list of {time, kind, detail} "
                                                      "(configuration, thruster_efficiency, current)", **ro),
        }, defaults={"blade_pitch_limit": BLADE_PITCH_LIMIT}, section="simulator", allowed={
            "mode": one_of("lockstep", "realtime"), "vehicle": one_of(*available_configs()),
            "dynamics": one_of(*DYNAMICS), "watchdog_action": one_of("hover", "neutral"),
            "wait_for_subscribers": topic_names(), "events": text("YAML text: a list of {time, kind, detail}",
                                                                   _events_problem)})
        if p["mode"] not in ("lockstep", "realtime"):
            raise ValueError(f"mode must be lockstep or realtime, got {p['mode']!r}")
        self.mode = p["mode"]
        if self.get_parameter("use_sim_time").value:
            self.set_parameters([rclpy.parameter.Parameter("use_sim_time", value=False)])
            self.get_logger().error("use_sim_time refused: the simulator is the clock source (it publishes "
                                    "/clock); running on its own time")
        environment = _environment_overrides(self)
        load_environment(environment)  # refuse a bad environment before anything starts
        self.config = SimulatorConfig(p["vehicle"], p["seed"], p["physics_step"], p["control_period"],
                                      p["blade_pitch_limit"], p["watchdog_timeout"], p["watchdog_action"],
                                      environment=environment, dynamics=p["dynamics"],
                                      events=_events_parameter(p["events"]))
        self.start_state = np.zeros(12)
        self.start_state[2] = p["start_depth"]
        self.simulator = SimulatorCore(self.config, self.start_state)
        self.simulator.limits.check_state(self.start_state)
        self.simulator.limits.check_real_time_factor(p["real_time_factor"], self.config.control_period)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._create_interfaces(p["publish_clock"], p["publish_tf"])
        self._gate = self._subscriber_gate(p["wait_for_subscribers"])

        self._wall_start = time.monotonic()
        self._waiting_since = None
        self._last_warn = 0.0
        self._outputs = None
        self._halted = ""  # set when the plant diverged: stop stepping until ~/reset
        self._unanswered = 0  # lockstep samples in a row that timed out (the controller is silent)
        self._handshake = True  # lockstep: until the first command, re-publish t_0 (discovery races)
        self._last_republish = time.monotonic()
        self._started = False  # the first sample is published once the subscriber gate is open
        self._samples_published = 0  # samples t_k published (each data topic once per sample)
        self._last_gate_log = 0.0
        self._end_ns = int(round(p["end_time"] * 1e9))  # 0: no end
        self._held_at_start = bool(p["start_held"])  # until end_time is set at run time
        self._answered_ns: int | None = None  # lockstep: the sample whose command has come
        self._encoder = SampleEncoder()
        self.ack_budget = 3.0   # at its stop, wait this long for readers (a recorder) to acknowledge the last samples
        self._pacer = Pacer(p["lockstep_pace"])
        self._pace_timer = None  # a paced sample waiting for its wall time
        self._sent: list = []  # the current sample's (publisher, message or its bytes) pairs, for a republish
        self._catch_up = False  # resumed at an unanswered sample: republish it to readers that match late
        self._readers: list[int] = []  # matched readers per publisher of _sent at its last (re)publish
        if self.mode == "lockstep":
            self._start_when_ready()
            self.create_timer(0.01, self._lockstep_watch)
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

    def _start_when_ready(self) -> bool:
        """Publish the first sample once every awaited subscriber is matched."""
        if self._started:
            return True
        if not self._gate.ready():
            now = time.monotonic()
            if now - self._last_gate_log > 5.0:
                self._last_gate_log = now
                self.get_logger().info("waiting for subscribers: " + ", ".join(self._gate.missing()))
            return False
        self._started = True
        self._publish_outputs()
        self._waiting_since = time.monotonic()
        return True

    # -- parameters --------------------------------------------------------------
    def _realtime_period(self) -> float:
        rtf = self.get_parameter("real_time_factor").value
        return 0.0 if rtf == 0 else self.config.control_period / rtf

    def _refuse_parameter(self, prm) -> str:
        """Why ``prm`` cannot be set ('' if it can)."""
        if prm.name == "use_sim_time" and prm.value:
            return "use_sim_time refused: the simulator is the clock source (it publishes /clock)"
        if prm.name == "watchdog_action" and prm.value not in ("hover", "neutral"):
            return "watchdog_action must be hover or neutral"
        if prm.name == "real_time_factor":
            try:
                self.simulator.limits.check_real_time_factor(prm.value, self.config.control_period)
            except (TypeError, ValueError) as exc:
                return str(exc)
        return ""

    def _on_set_parameters(self, params) -> SetParametersResult:
        for prm in params:
            reason = self._refuse_parameter(prm)
            if reason:
                self.get_logger().warn(f"parameter refused: {reason}")
                return SetParametersResult(successful=False, reason=reason)
        for prm in params:
            if prm.name == "end_time":
                self._set_end(float(prm.value))
            elif prm.name == "lockstep_pace":
                self._pacer.rate = float(prm.value)
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
            self.simulator.reject_malformed(f"malformed command: {exc}")
            self._warn(self.simulator.last_error)
            return
        stamp = conv.stamp_to_ns(msg.header.stamp)
        lockstep = self.mode == "lockstep"
        if lockstep and not self._started:
            self.simulator.reject("rejected_future", "command before the first sample was published")
            return
        ok, reason = self.simulator.submit(np.array(msg.pitch, float), stamp, lockstep)
        if not ok or reason == "saturated":
            self._warn(f"command {'rejected' if not ok else 'saturated'}: {reason if not ok else ''}".strip())
        if ok and lockstep and stamp == self.simulator.t_ns:
            self._unanswered = 0
            self._answered_ns = stamp
            self._advance_paced()

    def _set_end(self, end_time: float) -> None:
        """A new ``end_time`` [s]: resumes a graph held at its end when it lies beyond the held sample."""
        held = self._at_end()
        self._end_ns = int(round(end_time * 1e9))
        self._held_at_start = False
        if not held or self._at_end() or self._halted:
            return
        if self.mode == "lockstep" and self._started:
            if self._answered_ns == self.simulator.t_ns:
                self._advance_paced()  # the command for the held sample came meanwhile
            else:
                # a node that joined while the graph was held (a controller configured and activated
                # there) never heard the sample it is to answer: say it again, every topic, same messages,
                # and again whenever a reader matches later (discovery may lag) until it is answered
                self._catch_up = True
                self._republish()
                self._waiting_since = time.monotonic()  # its lockstep_timeout counts from now
    def _at_end(self) -> bool:
        """The sample of ``end_time`` (or a later one) is published, or t_0 with ``start_held``: step no
        further."""
        return 0 < self._end_ns <= self.simulator.t_ns or self._held_at_start

    def _advance(self) -> None:
        if self._halted or self._at_end():
            return
        try:
            self.simulator.step()
            self._publish_outputs()
        except (FloatingPointError, ContractError) as exc:  # DivergenceError or a non-finite output
            self._halted = str(exc)
            self.get_logger().error(f"simulation halted: {exc}; call ~/reset to continue")
            return
        self._waiting_since = time.monotonic()
        self._catch_up = False

    def _advance_paced(self) -> None:
        """Step on now, or when :class:`~seapup_common.lockstep.Pacer` says the next sample is due (a one-shot
        timer: the executor never sleeps, and no lockstep time-out runs meanwhile)."""
        if self._pace_timer is not None:
            return
        delay = self._pacer.delay(self.simulator.t + self.config.control_period, time.monotonic())
        if delay <= 0.0:
            self._advance()
            return
        self._waiting_since = None
        self._pace_timer = self.create_timer(delay, self._paced_due)

    def _paced_due(self) -> None:
        self.destroy_timer(self._pace_timer)
        self._pace_timer = None
        self._advance()

    def _lockstep_watch(self) -> None:
        if self._halted or not self._start_when_ready() or self._at_end() or self._pace_timer is not None:
            return
        now = time.monotonic()
        if self._catch_up and now - self._last_republish > 0.05:
            self._last_republish = now
            if any(n > seen for n, seen in zip(self._reader_counts(), self._readers)):
                self._republish()
        if self._handshake:
            if self.simulator.counters["accepted"]:
                self._handshake = False
            elif now - self._last_republish > 0.2:
                self._last_republish = now
                self._publish_outputs(resend=True)  # no controller has answered yet: say t_k again
        timeout = self.get_parameter("lockstep_timeout").value
        if self._waiting_since is not None and now - self._waiting_since > timeout:
            self._unanswered += 1
            self.simulator.lockstep_timeout()
            self._warn(f"no command stamped t = {self.simulator.t:.3f} s within {timeout} s: holding the last one")
            self._advance_paced()

    def _realtime_tick(self) -> None:
        if self._start_when_ready():
            self._advance()

    # -- outputs -----------------------------------------------------------------
    def _publish_outputs(self, resend: bool = False) -> None:
        t_ns = self.simulator.t_ns
        if not resend:
            out = self._outputs = self.simulator.outputs()
            self.simulator.check_finite(out)
        if self.pub_clock is not None:
            self.pub_clock.publish(self._encoder.clock(t_ns))
        if resend:
            return  # handshake: say t_k again on /clock only (no duplicate data for recorders)
        self._samples_published += 1
        sample, m = out["sample"], out["sample"].measurement
        prof = self.simulator.sensor_profile
        encode = self._encoder  # serialised bytes: the messages of seapup_common.ros.messages, packed
        messages = [
            (self.pub_applied, encode.applied(out["applied_blade_pitch"], t_ns)),
            (self.pub_velocity, encode.velocity(m.velocity, m.rates, t_ns)),
            (self.pub_imu, encode.imu(m.attitude, m.rates, sample.specific_force, t_ns)),
            *([(self.pub_position, encode.position(m.position, t_ns))] if m.position.valid else []),
            (self.pub_depth, encode.depth(m.depth, t_ns)),
            (self.pub_altitude, encode.altitude(  # every sample: +inf when invalid (REP-117)
                m.altitude, t_ns, field_of_view=prof.altimeter_field_of_view, min_range=prof.altimeter_min_range,
                max_range=prof.altimeter_max_range)),
            (self.pub_truth, encode.odometry_ned(sample.state, t_ns)),
            (self.pub_odom, encode.odometry_enu(sample.state, t_ns)),
            (self.pub_current, encode.vector3_stamped(sample.current_ned, t_ns, NED)),
            (self.pub_wrench, encode.wrench_stamped(sample.umbilical_body, t_ns, FRD)),
            *([(self.pub_tf, encode.transforms_enu(sample.state, t_ns))] if self.pub_tf is not None else [])]
        cable = self.simulator.cable_shape()
        if cable is not None:   # a simulation with an umbilical: its shape, to be drawn
            messages.append((self.pub_cable, encode.path_ned(cable, t_ns)))
        # last: what this sample holds (the acoustic fix comes only at some samples)
        manifest = encode.manifest([publisher.topic_name for publisher, _ in messages], t_ns)
        self._sent = messages + [(self.pub_manifest, manifest)]
        for publisher, msg in self._sent:
            publisher.publish(msg)

    def _republish(self) -> None:
        """The current sample's messages once more, unchanged (a reader takes a sample once)."""
        if self.pub_clock is not None:
            self.pub_clock.publish(self._encoder.clock(self.simulator.t_ns))
        for publisher, msg in self._sent:
            publisher.publish(msg)
        self._readers = self._reader_counts()

    def _reader_counts(self) -> list[int]:
        return [publisher.get_subscription_count() for publisher, _ in self._sent]

    def _publish_diagnostics(self) -> None:
        c = self.simulator.counters
        elapsed = time.monotonic() - self._wall_start
        rejected = sum(v for k, v in c.items() if k.startswith("rejected"))
        level = DiagnosticStatus.OK
        message = f"{self.mode}, t = {self.simulator.t:.1f} s"
        problems = self._graph_problems()
        if self._halted:
            level, message = DiagnosticStatus.ERROR, message + f", halted: {self._halted}"
        elif problems:
            level, message = DiagnosticStatus.WARN, message + ", " + "; ".join(problems)
        elif self.simulator.watchdog_active:
            level, message = DiagnosticStatus.WARN, message + ", watchdog active (no valid command)"
        if self._held_at_start and self._started:
            message += ", held at t_0 (start_held)"
        elif self._at_end():
            message += f", at end_time {self._end_ns * 1e-9:g} s (holding)"
        elif rejected:
            level, message = DiagnosticStatus.WARN, message + f", last rejection: {self.simulator.last_error}"
        values = {**c, "samples_published": self._samples_published, "sim_time": f"{self.simulator.t:.3f}",
                  "real_time_factor_measured": f"{self.simulator.t / elapsed:.2f}" if elapsed > 0 else "0",
                  "control_steps_per_wall_second": f"{c['steps'] / elapsed:.1f}" if elapsed > 0 else "0",
                  "watchdog_active": str(self.simulator.watchdog_active), "at_end": str(self._at_end()),
                  "vehicle": self.config.vehicle,
                  "sensor_profile": self.simulator.sensor_profile.name}
        status = DiagnosticStatus(level=level, name="seapup/simulator", hardware_id="seapup_sim",
                                  message=message, values=[KeyValue(key=k, value=str(v)) for k, v in values.items()])
        arr = DiagnosticArray(status=[status])
        arr.header.stamp = conv.ns_to_stamp(self.simulator.t_ns)  # the graph's time: the simulator owns it
        self.pub_diag.publish(arr)

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
        if self.mode == "lockstep" and self._unanswered:
            problems.append(f"the controller has not answered {self._unanswered} sample(s) in a row "
                            "(holding the last command)")
        return problems

    # -- services ----------------------------------------------------------------
    def _answer(self, response, action, success_text):
        """Run ``action``; anything it raises is a refusal with its reason (never a crash)."""
        try:
            action()
        except (ValueError, TypeError, KeyError) as exc:
            response.success, response.message = False, str(exc)[:500]
            self.get_logger().warn(f"service refused: {response.message}")
        except Exception as exc:  # noqa: BLE001 - the boundary: nothing may escape into the executor
            response.success = False
            response.message = f"internal error, request refused: {type(exc).__name__}: {str(exc)[:300]}"
            self.get_logger().error(response.message)
        else:
            response.success, response.message = True, success_text()
            self.get_logger().info(response.message)
        return response

    def _srv_reset(self, request, response):
        def act():
            state = np.array(request.state, float) if request.use_state else self.start_state
            self.simulator.reset(request.seed, state)  # validated against environment/limits.yaml, atomic
            self._halted = ""
            self._answered_ns, self._unanswered, self._catch_up = None, 0, False  # the commands were for before
            if self._pace_timer is not None:   # a paced step of the old run is not taken
                self.destroy_timer(self._pace_timer)
                self._pace_timer = None
            self._pacer.restart()   # the schedule starts again at t = 0
            self._publish_outputs()
            self._waiting_since = time.monotonic()
        return self._answer(response, act, lambda: f"reset: t = 0, seed {request.seed}")

    def _srv_configuration(self, request, response):
        def act():
            if request.name not in available_configs():
                raise ValueError(f"no configuration {request.name[:80]!r} "
                                 f"(available: {', '.join(available_configs())})")
            self.simulator.set_configuration(request.name)
        return self._answer(response, act, lambda: f"configuration {request.name} at t = {self.simulator.t:.2f} s")

    def _srv_efficiency(self, request, response):
        return self._answer(response, lambda: self.simulator.set_thruster_efficiency(np.array(request.efficiency)),
                            lambda: "thruster efficiency " + ", ".join(f"{e:.3f}" for e in request.efficiency))

    def _srv_current(self, request, response):
        def act():
            if not (math.isfinite(request.at) and request.at >= 0.0):
                raise ValueError(f"at must be a finite time >= 0 s, got {request.at!r}")
            params = None
            if request.enabled:
                tc = request.break_time or self.simulator.current_params().break_time  # 0: keep the present T_c
                params = CurrentParams(request.mean_speed, request.speed_std, request.mean_direction,
                                       request.direction_std, tc)
            if request.at > self.simulator.t:
                self.simulator.schedule_current(params, request.at)
            else:
                self.simulator.set_current(params)

        def said():
            when = f" at t = {request.at:g} s" if request.at > self.simulator.t else ""
            return "current " + ("set" if request.enabled else "off") + when
        return self._answer(response, act, said)

    def _srv_sensor_profile(self, request, response):
        def act():
            if request.name not in sensor_profiles():
                raise ValueError(f"no sensor profile {request.name[:80]!r} (available: {', '.join(sensor_profiles())})")
            self.simulator.set_sensor_profile(request.name)
        return self._answer(response, act, lambda: f"sensor profile {request.name}")


def main(args=None) -> int:
    return run_node(SimulatorNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
