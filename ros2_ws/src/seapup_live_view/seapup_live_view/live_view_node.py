"""The ``live_view`` node: the graph in Foxglove (or Lichtblick) through a WebSocket on localhost.

A shell over :mod:`seapup_live_view.view_scene` (the geometry) and the ``foxglove-sdk`` server (its own
threads: nothing here waits for a viewer). It subscribes to the graph's topics and, at each sample of the
simulator's truth, logs to the server, stamped with the sample's (sim) time, which the server also
broadcasts as its clock (at a display's rate: every sample while the graph runs at up to 10x real time):

- ``/tf`` (foxglove.FrameTransforms): ``odom`` -> ``base_link`` and the fixed ``odom_ned``, ``base_link_frd``;
- ``/scene/vehicle`` (foxglove.SceneUpdate, in ``base_link_frd``): the frame, the thrusters with their thrust
  arrows (full length at the +-35 deg blade-pitch limit, or at a fixed-pitch thruster's full thrust: a
  BlueROV2's eight through its mixer), the payloads (the bow camera when fitted);
- ``/scene/world`` (in ``odom_ned``): the track flown, the umbilical (the simulator's cable solution), the
  current's arrow, the position set point, the
  navigator's estimate (a sphere of its 2-sigma horizontal uncertainty) and the acoustic fixes as they come;
- ``/scene/seabed``: the environment's seabed around the vehicle (re-sent every few seconds: the server keeps
  nothing for a client that subscribes later);
- ``/plot`` (JSON): the true body velocities against the references, the inputs applied and their limit
  (the Seapup's blade pitches [deg]; a virtual-input vehicle's in % of full scale: ``view_scene.plot_inputs``).

Services through the server (JSON requests): ``switch_controller`` (``{"activate": "gmv"}`` -> the controller
manager's switch), ``set_current`` (``{"enabled": true, "mean_speed": 0.26, ...}`` -> the simulator's),
``set_sensor_profile`` (``{"name": "haslar"}``) and ``goto`` (``{"x": 10, "y": 0, "z": 30}`` -> a goal of the
task controller). Parameters: ``lockstep_pace`` (the simulator's) and ``controller`` (setting it switches).
Every payload and parameter value is checked first (:mod:`seapup_live_view.view_requests`); a refusal is one line,
said on ``/events`` with the count of refusals so far, and nothing reaches the graph. A parameter set never holds
the server's thread: it is checked there, carried out on the view's own worker (one at a time), and its new value
published to the viewers subscribed to it; at most :data:`MAX_CALLS_IN_FLIGHT` service calls wait on the graph
at once.

The port is served through :class:`seapup_live_view.view_relay.Relay`, so clients offering ``foxglove.sdk.v1`` and
clients offering only ``foxglove.websocket.v1`` (Lichtblick) are both served.

A message is built only when a viewer subscribes to its channel (``has_sinks``), the scenes at a display's rate
(:data:`DISPLAY_PERIOD`, :data:`VEHICLE_PERIOD`, :data:`WORLD_PERIOD`; the per-sample topics are taken as bytes
and read only when shown); the server's per-client
queues are bounded and drop the oldest, so a slow or vanished viewer costs the graph nothing.
"""
from __future__ import annotations

import collections
import concurrent.futures
import json
import logging
import math
import threading
import time

import numpy as np
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, Twist, TwistStamped, \
    Vector3Stamped
from nav_msgs.msg import Odometry
from nav_msgs.msg import Path as PathMessage
from rcl_interfaces.msg import IntegerRange, ParameterDescriptor, ParameterType
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from diagnostic_msgs.msg import DiagnosticArray
from foxglove.websocket import ServerListener
from seapup_msgs.msg import BladePitch, ControllerEstimate
from seapup_msgs.action import Goto
from seapup_msgs.srv import SetCurrent, SetSensorProfile, SwitchController

from seapup_common import frames
from seapup_common.ros import messages as conv
from seapup_common.ros.node import (QUIET_SUBSCRIPTION, RELIABLE_QOS, STREAM_QOS, declare_guarded, one_of,
                                     path_or_empty, run_node)
from seapup_common.topics import (APPLIED, CURRENT, DIAGNOSTICS, NAMESPACE, NAVIGATION_ODOMETRY, PILOT, POSITION,
                                  POSITION_REFERENCE, SET_CURRENT_SERVICE, SIMULATOR_PARAMETERS_SERVICE,
                                  SWITCH_CONTROLLER_SERVICE, TRUTH_ODOMETRY, UMBILICAL_SHAPE, VELOCITY_REFERENCE,
                                  task_action)
from seapup_live_view import view_scene
from seapup_live_view.view_requests import GOTO_KEYS, VIEW_PARAMETERS, ViewRequestError
from seapup_live_view import view_requests

__all__ = ["LiveViewNode", "main", "PLOT_SCHEMA", "SCENE_TOPICS", "PLOT_TOPIC", "TF_TOPIC", "SERVICES",
           "VIEW_PARAMETERS", "EVENTS_TOPIC", "ESTIMATE_TOPIC", "MAX_CALLS_IN_FLIGHT"]

#: The server's channels: the scene (SceneUpdate), the plot (JSON), the frames (FrameTransforms).
SCENE_TOPICS = ("/scene/vehicle", "/scene/world", "/scene/seabed")
PLOT_TOPIC, TF_TOPIC = "/plot", "/tf"
#: The server's services.
SERVICES = ("switch_controller", "set_current", "set_sensor_profile", "goto")
#: Viewer service calls waiting on the graph at once (each waits at most 5 s, a goto 10 s); the next is refused.
MAX_CALLS_IN_FLIGHT = 4
#: The server's other channels: controller switches and refusals (foxglove.Log), the self-tuners' estimates.
EVENTS_TOPIC, ESTIMATE_TOPIC = "/events", "/estimate"

#: The /plot channel's JSON schema (what a plot panel's paths name).
PLOT_SCHEMA = {"title": "seapup.Plot", "type": "object", "properties": {
    "t": {"type": "number"}, "velocity": {"type": "array"}, "reference": {"type": "array"},
    "inputs": {"type": "array"}, "input_limit": {"type": "number"}, "input_unit": {"type": "string"},
    "input_names": {"type": "array"}, "blade_pitch_deg": {"type": "array"}, "pitch_limit_deg": {"type": "number"},
    "controller": {"type": "string"}}}

_SEABED_PERIOD_NS = 5_000_000_000
#: Wall seconds between two samples shown (frames, plot, server time: every sample of a graph at up to 10x real time
#: at 5 Hz), two ``/scene/vehicle`` updates and two ``/scene/world`` updates (the track's thousands of points): a
#: display's rates, whatever the lockstep graph's speed (it can run at hundreds of times real time).
DISPLAY_PERIOD, VEHICLE_PERIOD, WORLD_PERIOD = 0.02, 0.05, 0.2
_SEABED_KEYS = ("kind", "depth", "gradient", "direction")   # and "points" for a polyline (an empty list is no
_SIMULATOR_GET_PARAMETERS = f"{NAMESPACE}/simulator/get_parameters"
_SEABED_PARAMETERS = tuple(f"environment.seabed.{key}" for key in _SEABED_KEYS)   # parameter at all)


def _state_from_truth(msg: Odometry) -> np.ndarray:
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    angles = frames.quaternion_to_euler([q.x, q.y, q.z, q.w])
    v, w = msg.twist.twist.linear, msg.twist.twist.angular
    return np.array([p.x, p.y, p.z, *angles, v.x, v.y, v.z, w.x, w.y, w.z], float)


class LiveViewNode(Node):
    def __init__(self, **kwargs):
        # no parameter services of its own: every service and client is one more entity that rclpy's executor
        # visits at each turn, and the view's turns come at the graph's sample rate
        super().__init__("live_view", start_parameter_services=False, **kwargs)
        from seapup_sim.vehicle_config import available_configs
        declare_guarded(self, {"port": 8765, "vehicle": "baseline", "environment_file": ""}, descriptors={
            "port": ParameterDescriptor(
                description="the WebSocket server's port on 127.0.0.1 (0: any free port, logged)", read_only=True,
                integer_range=[IntegerRange(from_value=0, to_value=65535)]),
            "vehicle": ParameterDescriptor(
                description="vehicle configuration drawn until the simulator's own is read", read_only=True),
            "environment_file": ParameterDescriptor(
                type=ParameterType.PARAMETER_STRING, read_only=True,
                description="environment overrides (YAML; '' or empty = the default environment): the seabed "
                            "drawn until the simulator's own is read")},
            allowed={"vehicle": one_of(*available_configs()),
                     "environment_file": path_or_empty("an environment file (YAML) read at start")})
        import foxglove
        from foxglove.channels import FrameTransformsChannel, SceneUpdateChannel
        from foxglove.websocket import Capability
        from seapup_sim.environment_config import load_environment
        from seapup_sim.linearised import vehicle_model
        from seapup_sim.vehicle_config import load_vehicle_config

        logging.getLogger("foxglove").setLevel(logging.ERROR)   # a dropped client is not the graph's problem
        self.shape = view_scene.vehicle_shape(vehicle_model(load_vehicle_config(self.get_parameter("vehicle").value)))
        env_file = self.get_parameter("environment_file").value
        self.seabed = load_environment(env_file or None).seabed
        # what the graph's simulator flies (its read-only parameters), once it is on the graph
        self._service_clients: dict = {}   # ROS service clients, made at their first use (see __init__'s note)
        self._service_clients_lock = threading.Lock()
        self._asked = None
        self._pace = 0.0
        self._goto_client = None
        self.refusals = 0   # viewer requests refused (said on /events with this count)
        self._refusals_lock = threading.Lock()
        self._calls = threading.BoundedSemaphore(MAX_CALLS_IN_FLIGHT)   # viewer service calls waiting on the graph
        # parameter sets are carried out here, one at a time, never on the server's thread
        self._parameter_worker = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="view-parameters")
        self._parameter_change = None
        self._parameter_lock = threading.Lock()
        self._ask_timer = self.create_timer(1.0, self._ask_simulator)
        self.trail = view_scene.Trail()
        self._latest: dict = {}
        self._fixes = collections.deque(maxlen=50)   # the newest acoustic fixes
        self._seabed_sent_ns = -_SEABED_PERIOD_NS
        # a viewer's stick (Foxglove's Teleop panel) goes to the graph as a pilot's Twist (seapup_control.manual)
        self.pilot_publisher = self.create_publisher(Twist, PILOT, RELIABLE_QOS)
        self._pilot_channels: set = set()   # (client id, client channel id) taken as the pilot's
        self.server = foxglove.start_server(   # on a private port: viewers come through the relay
            name="seapup", host="127.0.0.1", port=0,
            capabilities=[Capability.Time, Capability.Parameters, Capability.ClientPublish],
            services=self._viewer_services(foxglove),
            supported_encodings=["json"], server_listener=_Listener(self))
        from seapup_live_view.view_relay import Relay
        port = int(self.get_parameter("port").value)
        try:
            self.relay = Relay(port, self.server.port).start()
        except OSError as exc:
            self.server.stop()
            self._parameter_worker.shutdown(wait=False)
            raise RuntimeError(f"port {port} on 127.0.0.1 cannot be served ({exc.strerror or exc}): "
                               f"another view? choose another port") from None
        self.port = self.relay.port
        self.tf_channel = FrameTransformsChannel(TF_TOPIC)
        self.vehicle_channel, self.world_channel, self.seabed_channel = (SceneUpdateChannel(t) for t in SCENE_TOPICS)
        self.plot_channel = foxglove.Channel(PLOT_TOPIC, schema=PLOT_SCHEMA)
        from foxglove.channels import LogChannel
        self.events_channel = LogChannel(EVENTS_TOPIC)
        self.estimate_channel = foxglove.Channel(ESTIMATE_TOPIC, schema={"title": "seapup.Estimate", "type": "object"})
        self.active_controller = ""
        self._estimates: set[str] = set()   # estimate topics subscribed (found on the graph: their names vary)
        self._t_ns = 0
        self._world_sent = self._vehicle_sent = -math.inf
        self.samples = 0
        # the per-sample topics are taken as bytes and read only when shown (at most every DISPLAY_PERIOD)
        self._types = {TRUTH_ODOMETRY: Odometry, APPLIED: BladePitch, CURRENT: Vector3Stamped,
                       VELOCITY_REFERENCE: TwistStamped,
                       NAVIGATION_ODOMETRY: Odometry, POSITION_REFERENCE: PoseStamped, UMBILICAL_SHAPE: PathMessage}
        self._raw: dict = {}
        self._shown_raw = None        # the truth sample last shown
        self._shown_at = -math.inf
        for topic, kind in self._types.items():
            callback = self._on_truth if topic == TRUTH_ODOMETRY else (lambda raw, t=topic: self._raw.__setitem__(t, raw))
            self.create_subscription(kind, topic, callback, STREAM_QOS, raw=True, event_callbacks=QUIET_SUBSCRIPTION)
        self.create_timer(DISPLAY_PERIOD, self._show_pending)
        self._subscribe(PoseWithCovarianceStamped, POSITION, self._on_fix, STREAM_QOS)
        self._subscribe(DiagnosticArray, DIAGNOSTICS, self._on_diagnostics, RELIABLE_QOS)
        self.create_timer(2.0, self._find_estimates)
        from urllib.parse import quote
        app_url = (self.server.app_url() or "").replace(quote(f"ws://127.0.0.1:{self.server.port}", safe=""),
                                                         quote(f"ws://127.0.0.1:{self.port}", safe=""))
        self.get_logger().info(f"live view: ws://127.0.0.1:{self.port} (open it in Foxglove or Lichtblick: "
                               f"{app_url})")

    # -- the graph -> the viewer -------------------------------------------------------------
    def _subscribe(self, kind, topic, callback, qos):
        """A subscription without rclpy's per-subscription event handlers (visited on every executor turn:
        half of a small node's spin cost, measured for the simulator)."""
        return self.create_subscription(kind, topic, callback, qos, event_callbacks=QUIET_SUBSCRIPTION)

    def _ask_simulator(self) -> None:
        getter = self._client(GetParameters, _SIMULATOR_GET_PARAMETERS)
        if self._asked is not None or not getter.service_is_ready():
            return
        getter.call_async(GetParameters.Request(names=["lockstep_pace"])).add_done_callback(self._on_pace)
        self._asked = getter.call_async(GetParameters.Request(names=["vehicle", *_SEABED_PARAMETERS]))
        self._asked.add_done_callback(self._on_simulator_parameters)

    def _on_pace(self, future) -> None:
        from rclpy.parameter import parameter_value_to_python
        values = future.result().values if future.result() is not None else []
        if len(values) == 1:
            self._pace = float(parameter_value_to_python(values[0]) or 0.0)

    def _on_points(self, future, vehicle: str, seabed: dict) -> None:
        from rclpy.parameter import parameter_value_to_python
        try:
            (points,) = [parameter_value_to_python(v) for v in future.result().values]
            self._draw(vehicle, {**seabed, "points": points})
        except Exception as exc:  # noqa: BLE001 - as in _on_simulator_parameters
            self.destroy_timer(self._ask_timer)
            self.get_logger().warn(f"could not read the simulator's seabed polyline ({exc})")

    def _draw(self, vehicle: str, seabed: dict) -> None:
        from seapup_sim.linearised import vehicle_model
        from seapup_sim.seabed import Seabed
        from seapup_sim.vehicle_config import load_vehicle_config
        self.shape = view_scene.vehicle_shape(vehicle_model(load_vehicle_config(vehicle)))
        self.seabed = Seabed.from_config(seabed)
        self._seabed_sent_ns = -_SEABED_PERIOD_NS
        self.destroy_timer(self._ask_timer)
        self.get_logger().info(f"drawing the simulator's vehicle ({vehicle}) and seabed ({seabed['kind']})")

    def _on_simulator_parameters(self, future) -> None:
        from rclpy.parameter import parameter_value_to_python
        try:
            values = [parameter_value_to_python(v) for v in future.result().values]
            if len(values) != 1 + len(_SEABED_KEYS):
                raise ValueError(f"{len(values)} of {1 + len(_SEABED_KEYS)} parameters answered")
            vehicle, seabed = values[0], dict(zip(_SEABED_KEYS, values[1:]))
            if seabed["kind"] == "polyline":
                self._client(GetParameters, _SIMULATOR_GET_PARAMETERS).call_async(
                    GetParameters.Request(names=["environment.seabed.points"])).add_done_callback(
                    lambda f: self._on_points(f, vehicle, seabed))
                return
            self._draw(vehicle, seabed)
        except Exception as exc:  # noqa: BLE001 - a foreign simulator: keep drawing the defaults
            self.destroy_timer(self._ask_timer)
            self.get_logger().warn(f"could not read the simulator's vehicle and seabed ({exc}): drawing the "
                                   f"node's own vehicle and environment_file")

    def _on_fix(self, msg: PoseWithCovarianceStamped) -> None:
        p = msg.pose.pose.position
        self._fixes.append((p.x, p.y, p.z))

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name != "seapup/controller_manager":
                continue
            active = next((kv.value for kv in status.values if kv.key == "active"), self.active_controller)
            if active != self.active_controller:
                if self.events_channel.has_sinks():
                    from seapup_live_view import live_view_messages as fm
                    self.events_channel.log(fm.event(f"controller {self.active_controller or '(none)'} -> "
                                                     f"{active or '(none)'}", self._t_ns), log_time=self._t_ns)
                self.active_controller = active

    def _find_estimates(self) -> None:
        """Subscribe to every self-tuner's estimate on the graph (``<controller>/estimate``)."""
        for topic, types in self.get_topic_names_and_types():
            if topic not in self._estimates and "seapup_msgs/msg/ControllerEstimate" in types:
                self._estimates.add(topic)
                self._subscribe(ControllerEstimate, topic, self._on_estimate, STREAM_QOS)

    def _on_estimate(self, msg: ControllerEstimate) -> None:
        if (self.active_controller and msg.controller != self.active_controller) or not self.estimate_channel.has_sinks():
            return   # (a graph without a controller manager: whichever self-tuner estimates)
        t_ns = conv.stamp_to_ns(msg.header.stamp)
        self.estimate_channel.log({"t": t_ns * 1e-9, "controller": msg.controller, "mode": msg.mode,
                                   "frozen": msg.frozen, **{name: value for name, value in zip(msg.names, msg.values)
                                                            if np.isfinite(value)}}, log_time=t_ns)

    def _decoded(self, topic: str):
        """The newest message of ``topic`` (None before the first), read from its bytes once."""
        raw = self._raw.get(topic)
        if raw is None:
            return None
        cached = self._latest.get(topic)
        if cached is None or cached[0] is not raw:
            try:
                cached = (raw, deserialize_message(raw, self._types[topic]))
            except Exception:  # noqa: BLE001 - a malformed message from a foreign publisher: not drawn
                return None
            self._latest[topic] = cached
        return cached[1]

    def _on_truth(self, raw: bytes) -> None:
        """A sample: shown now if the display is due (the graph may run far faster than a display redraws)."""
        self._raw[TRUTH_ODOMETRY] = raw
        self.samples += 1
        if time.monotonic() - self._shown_at >= DISPLAY_PERIOD:
            self._show()

    def _show_pending(self) -> None:
        """The newest sample once the graph paused (held, or ended) before it was shown."""
        if self._raw.get(TRUTH_ODOMETRY) is not None and self._raw[TRUTH_ODOMETRY] is not self._shown_raw:
            self._show()

    def _show(self) -> None:
        self._shown_at = time.monotonic()
        self._shown_raw = self._raw[TRUTH_ODOMETRY]
        msg = self._decoded(TRUTH_ODOMETRY)
        if msg is None:
            return
        t_ns = conv.stamp_to_ns(msg.header.stamp)
        self._t_ns = t_ns
        state = _state_from_truth(msg)
        if not np.all(np.isfinite(state)):
            return
        self.trail.add(state[:3])
        self.server.broadcast_time(t_ns)
        from seapup_live_view import live_view_messages as fm
        if self.tf_channel.has_sinks():
            self.tf_channel.log(fm.frame_transforms(view_scene.frame_transforms(state), t_ns), log_time=t_ns)
        applied = self._decoded(APPLIED)
        pitch = np.asarray(applied.pitch, float) if applied is not None else np.zeros(4)
        now = time.monotonic()
        if self.vehicle_channel.has_sinks() and now - self._vehicle_sent >= VEHICLE_PERIOD:
            self._vehicle_sent = now
            self.vehicle_channel.log(fm.vehicle(self.shape, view_scene.thrust_arrows(self.shape, pitch), t_ns),
                                     log_time=t_ns)
        if self.world_channel.has_sinks() and now - self._world_sent >= WORLD_PERIOD:
            self._world_sent = now   # the track's thousands of points: at a display's rate, not the graph's
            self.world_channel.log(fm.world(self._world(t_ns)), log_time=t_ns)
        if self.seabed_channel.has_sinks() and t_ns - self._seabed_sent_ns >= _SEABED_PERIOD_NS:
            self._seabed_sent_ns = t_ns
            self.seabed_channel.log(fm.seabed(*view_scene.seabed_grid(self.seabed, state[:3]), t_ns), log_time=t_ns)
        if self.plot_channel.has_sinks():
            self.plot_channel.log(self._plot(t_ns, pitch, state), log_time=t_ns)

    def _world(self, t_ns: int) -> dict:
        world = {"t_ns": t_ns, "trail": self.trail.points(), "fixes": list(self._fixes)}
        current = self._decoded(CURRENT)
        if current is not None:
            world["current"] = view_scene.current_arrow([current.vector.x, current.vector.y, current.vector.z])
        cable = self._decoded(UMBILICAL_SHAPE)
        if cable is not None and len(cable.poses) >= 2:
            world["cable"] = np.array([[p.pose.position.x, p.pose.position.y, p.pose.position.z] for p in cable.poses])
        goal = self._decoded(POSITION_REFERENCE)
        if goal is not None:
            world["goal"] = np.array([goal.pose.position.x, goal.pose.position.y, goal.pose.position.z])
        estimate = self._decoded(NAVIGATION_ODOMETRY)
        if estimate is not None:
            e = conv.estimate_from_odometry(estimate)
            world["estimate"] = (np.asarray(e.position, float),
                                 2.0 * float(np.sqrt(np.max(np.diag(e.position_cov)[:2]))))
        return world

    def _plot(self, t_ns: int, pitch: np.ndarray, state: np.ndarray) -> dict:
        """The plot sample: the true body velocities (u, v, w, r: what the vehicle does, from the truth already
        read, so no instrument topic costs the graph a reader) against the velocity controllers' reference."""
        plot = {"t": t_ns * 1e-9, **view_scene.plot_inputs(self.shape, pitch), "controller": self.active_controller,
                "velocity": [float(state[6]), float(state[7]), float(state[8]), float(state[11])]}
        reference = self._decoded(VELOCITY_REFERENCE)
        if reference is not None:
            v, w = reference.twist.linear, reference.twist.angular
            plot["reference"] = [v.x, v.y, v.z, w.z]
        return plot

    # -- the viewer -> the graph ---------------------------------------------------------------
    def _viewer_services(self, foxglove) -> list:
        def schema(name, properties):
            return foxglove.MessageSchema(encoding="json", schema=foxglove.Schema(
                name=name, encoding="jsonschema", data=json.dumps({"type": "object", "properties": properties,
                                                                   "additionalProperties": False}).encode()))
        result = schema("seapup.Result", {"ok": {"type": "boolean"}, "message": {"type": "string"}})
        name = {"type": "string", "minLength": 1, "maxLength": view_requests.MAX_NAME_LENGTH}
        return [
            foxglove.Service(SERVICES[0], schema=foxglove.ServiceSchema(
                "seapup.SwitchController", request=schema("seapup.Switch", {"activate": name}),
                response=result), handler=self._served(SERVICES[0], self._switch)),
            foxglove.Service(SERVICES[1], schema=foxglove.ServiceSchema(
                "seapup.SetCurrent", request=schema("seapup.Current", {
                    k: {"type": "number"} for k in view_requests.CURRENT_KEYS[1:]} | {"enabled": {"type": "boolean"}}),
                response=result), handler=self._served(SERVICES[1], self._set_current)),
            foxglove.Service(SERVICES[2], schema=foxglove.ServiceSchema(
                "seapup.SetSensorProfile", request=schema("seapup.Profile", {"name": name}),
                response=result), handler=self._served(SERVICES[2], self._set_profile)),
            foxglove.Service(SERVICES[3], schema=foxglove.ServiceSchema(
                "seapup.Goto", request=schema("seapup.GotoGoal", {k: {"type": "boolean" if k == "preempt" else "number"}
                                                                  for k in GOTO_KEYS}),
                response=result), handler=self._served(SERVICES[3], self._goto))]

    def _served(self, service: str, handler):
        """``handler`` as the server calls it (on its threads): the payload checked first, at most
        :data:`MAX_CALLS_IN_FLIGHT` calls waiting on the graph; any refusal said and counted, and answered with
        its one line (the app shows it as the call's failure)."""
        def serve(request) -> bytes:
            try:
                if not self._calls.acquire(blocking=False):
                    raise ViewRequestError(f"{service}: busy ({MAX_CALLS_IN_FLIGHT} viewer requests already wait on "
                                           f"the graph): try again")
                try:
                    return handler(request.payload)
                finally:
                    self._calls.release()
            except Exception as exc:  # noqa: BLE001 - refused (bad payload, or the graph said no): one line
                text = _one_line(exc)
                self.refused(text)
                raise _Refused(text) from None
        return serve

    def _switch(self, payload: bytes) -> bytes:
        response = self._switch_to(view_requests.switch_request(payload))
        return json.dumps({"ok": bool(response.ok), "message": response.message}).encode()

    def _switch_to(self, name: str):
        """The manager's switch (strict) to ``name`` from the controller flying (view_requests.switch_lists)."""
        activate, deactivate = view_requests.switch_lists(name, self.active_controller)
        return self._call(self._client(SwitchController, SWITCH_CONTROLLER_SERVICE), SwitchController.Request(
            activate_controllers=activate, deactivate_controllers=deactivate,
            strictness=SwitchController.Request.STRICT))

    def _set_current(self, payload: bytes) -> bytes:
        ros = SetCurrent.Request(**view_requests.current_request(payload))
        response = self._call(self._client(SetCurrent, SET_CURRENT_SERVICE), ros)
        return json.dumps({"ok": bool(response.success), "message": response.message}).encode()

    def _set_profile(self, payload: bytes) -> bytes:
        name = view_requests.profile_request(payload)
        response = self._call(self._client(SetSensorProfile, f"{NAMESPACE}/simulator/set_sensor_profile"),
                              SetSensorProfile.Request(name=name))
        return json.dumps({"ok": bool(response.success), "message": response.message}).encode()

    def _goto(self, payload: bytes) -> bytes:
        """Send the task controller a goto goal (odom_ned, metres, radians); the answer says whether it was
        accepted (the task then flies; its progress is the view's track and ``/events``)."""
        from rclpy.action import ActionClient
        goal = Goto.Goal(**view_requests.goto_request(payload))
        with self._service_clients_lock:   # made at its first use, from any of the server's threads
            if self._goto_client is None:
                self._goto_client = ActionClient(self, Goto, task_action("goto"))
        if not self._goto_client.wait_for_server(timeout_sec=5.0):
            raise RuntimeError(f"{task_action('goto')} is not on the graph (no task controller)")
        done = threading.Event()
        future = self._goto_client.send_goal_async(goal)
        future.add_done_callback(lambda _: done.set())
        if not done.wait(5.0):
            raise RuntimeError("the task controller did not answer the goal in 5 s")
        accepted = bool(future.result().accepted)
        return json.dumps({"ok": accepted, "message": "goal accepted" if accepted else "goal refused"}).encode()

    def viewer_parameters(self) -> dict:
        """The server's parameters: the simulator's pace (as last read) and the active controller."""
        return {"lockstep_pace": float(self._pace), "controller": self.active_controller}

    def request_parameters(self, parameters: list) -> None:
        """A viewer's checked parameter set (:func:`view_requests.parameter_request`), handed to the view's worker;
        returns at once (it is called on the server's thread, which serves every viewer).

        Raises
        ------
        ViewRequestError
            A parameter set is still being carried out (one at a time: a viewer cannot queue up work).
        """
        with self._parameter_lock:
            if self._parameter_change is not None and not self._parameter_change.done():
                raise ViewRequestError("setParameters: a parameter change is still being carried out: try again")
            self._parameter_change = self._parameter_worker.submit(self._apply_parameters, parameters)

    def _apply_parameters(self, parameters: list) -> None:
        """On the worker: each parameter carried out in the graph (a refusal said, the value kept); then the values
        published to the viewers subscribed to them."""
        for name, value in parameters:
            try:
                self.set_viewer_parameter(name, value)
            except Exception as exc:  # noqa: BLE001 - refused by the graph: said, nothing changed
                self.refused(f"{name}: {_one_line(exc)}")
        from foxglove import Parameter
        values = self.viewer_parameters()
        self.server.publish_parameter_values([Parameter(name, value=values[name]) for name, _ in parameters])

    def set_viewer_parameter(self, name: str, value) -> None:
        """A checked parameter value carried out in the graph (raises with one line if the graph refuses)."""
        if name == "lockstep_pace":
            from rclpy.parameter import Parameter
            request = SetParameters.Request(parameters=[Parameter("lockstep_pace", value=float(value)).to_parameter_msg()])
            response = self._call(self._client(SetParameters, SIMULATOR_PARAMETERS_SERVICE), request)
            if not response.results[0].successful:
                raise RuntimeError(f"the simulator refused lockstep_pace: {response.results[0].reason}")
            self._pace = float(value)
        elif name == "controller":
            response = self._switch_to(value)
            if not response.ok:
                raise RuntimeError(f"switch to {value} refused: {response.message}")
            self.active_controller = value
        else:
            raise ViewRequestError(f"no parameter {name!r} (parameters: {', '.join(VIEW_PARAMETERS)})")

    def _client(self, kind, name: str):
        """The service client of ``name``, made at its first use (from any thread)."""
        with self._service_clients_lock:
            if name not in self._service_clients:
                self._service_clients[name] = self.create_client(kind, name)
            return self._service_clients[name]

    def _call(self, client, request, timeout: float = 5.0):
        """A ROS service call from a server or worker thread: the node's executor completes it."""
        if not client.wait_for_service(timeout_sec=timeout):
            raise RuntimeError(f"{client.srv_name} is not on the graph")
        done = threading.Event()
        future = client.call_async(request)
        future.add_done_callback(lambda _: done.set())
        if not done.wait(timeout):
            raise RuntimeError(f"{client.srv_name} did not answer in {timeout:g} s")
        return future.result()

    def refused(self, text: str) -> None:
        """A viewer's request the view or the graph did not take: counted, logged, and said on ``/events``."""
        with self._refusals_lock:
            self.refusals += 1
            count = self.refusals
        self.get_logger().warn(f"viewer request refused ({count} so far): {text}")
        from seapup_live_view import live_view_messages as fm
        self.events_channel.log(fm.event(f"refused ({count} so far): {text}", self._t_ns, error=True),
                                log_time=self._t_ns)

    def destroy_node(self):
        self.relay.stop()
        self.server.stop()
        self._parameter_worker.shutdown(wait=False, cancel_futures=True)
        return super().destroy_node()


class _Listener(ServerListener):
    """The server's parameter requests (on the server's thread, which serves every viewer: nothing here waits).
    A set is checked here and carried out by the node's worker; its answer carries the values before the change,
    and the new values follow as a parameter update. A refusal is said on ``/events`` and changes nothing."""

    def __init__(self, node: "LiveViewNode"):
        self.node = node

    def _parameters(self, names):
        from foxglove import Parameter
        values = self.node.viewer_parameters()
        wanted = set(names) & set(VIEW_PARAMETERS) if names else set(VIEW_PARAMETERS)
        return [Parameter(name, value=values[name]) for name in VIEW_PARAMETERS if name in wanted]

    def on_client_advertise(self, client, channel):
        try:
            view_requests.pilot_channel(channel.topic, channel.encoding, channel.schema_name, PILOT)
        except ViewRequestError as exc:   # refused: said, nothing published
            self.node.refused(str(exc))
            return
        self.node._pilot_channels.add((client.id, channel.id))

    def on_client_unadvertise(self, client, client_channel_id):
        self.node._pilot_channels.discard((client.id, client_channel_id))

    def on_message_data(self, client, client_channel_id, data):
        """A viewer's pilot message, checked and published on the pilot's topic (a thread-safe publish)."""
        if (client.id, client_channel_id) not in self.node._pilot_channels:
            return
        try:
            linear, angular = view_requests.pilot_twist(data)
        except ViewRequestError as exc:
            self.node.refused(str(exc))
            return
        msg = Twist()
        msg.linear.x, msg.linear.y, msg.linear.z = linear
        msg.angular.x, msg.angular.y, msg.angular.z = angular
        self.node.pilot_publisher.publish(msg)

    def on_get_parameters(self, client, param_names, request_id=None):
        return self._parameters(param_names)

    def on_set_parameters(self, client, parameters, request_id=None):
        try:
            checked = view_requests.parameter_request(
                parameters if len(parameters) > view_requests.MAX_PARAMETERS_PER_REQUEST
                else [(p.name, p.get_value()) for p in parameters])
            self.node.request_parameters(checked)
        except ViewRequestError as exc:   # refused: said, nothing changed
            self.node.refused(str(exc))
        except Exception as exc:  # noqa: BLE001 - a value the server could not convert: refused, one line
            self.node.refused(f"setParameters: {_one_line(exc)}")
        return self._parameters([p.name for p in parameters] if len(parameters) <= len(VIEW_PARAMETERS)
                                else VIEW_PARAMETERS)


class _Refused(ValueError):
    """A service call's failure as the viewer reads it: the SDK writes ``<__qualname__>: <message>``, so
    ``refused: <the reason>`` rather than an exception's name."""


_Refused.__qualname__ = "refused"


def _one_line(exc: BaseException) -> str:
    """An exception as the one line a viewer reads: its message (its type's name only when it has none)."""
    text = " ".join(str(exc).split())
    return text[:300] if text else type(exc).__name__


def main(args=None) -> int:
    import sys
    from seapup_live_view.attach import ros_arguments
    return run_node(LiveViewNode, ros_arguments(list(sys.argv if args is None else args)))


if __name__ == "__main__":
    raise SystemExit(main())
