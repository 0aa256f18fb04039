"""The simulator node in its own process, driven from this test's process.

Real cross-process tests: the node is started from its installed executable
(what ``ros2 run`` / ``./seapup run`` start) on the test's own domain; this
process publishes commands (typed and raw bytes), calls services and
subscribes to what the node publishes.
"""
import math
import os
import time
from pathlib import Path

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import TwistWithCovarianceStamped, Vector3Stamped, WrenchStamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import Imu
from seapup_msgs.msg import BladePitch, Depth
from seapup_msgs.srv import Reset, SetConfiguration, SetSensorProfile, SetThrusterEfficiency
from tf2_msgs.msg import TFMessage

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT as LIMIT
from seapup_common.ros.graph import call_idempotent
from seapup_control.profiles import OpenLoop, PitchProfile
from seapup_sim.analysis import hover_blade_pitch
from seapup_sim.simulation import Simulation
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config

HOVER = hover_blade_pitch(VehicleModel(load_vehicle_config("baseline")))
QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
REPO = Path(__file__).resolve().parents[1]


class Probe:
    """A node in the test process that records topics and talks to the simulator."""

    def __init__(self, context, spin):
        self.node = rclpy.create_node("probe", context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self._spin = spin
        self.msgs, self.info, self.matches, self.lost, self.subscriptions, self.types = {}, {}, {}, {}, {}, {}
        self.cmd = self.node.create_publisher(BladePitch, "/seapup/thrusters/command", QOS)

    def record(self, topic, msg_type):
        """Record ``topic`` into a new list ``self.msgs[topic]``, from a new subscription (one recording it
        before is destroyed: what it still had queued -- a stopped simulator's last samples, taken late on a
        loaded machine -- is not heard as new). Per topic also what DDS reported lost, every change of the
        publishers matched (wall time, count), and each message's (reception wall time, publication sequence
        number)."""
        from rclpy.event_handler import SubscriptionEventCallbacks
        if topic in self.subscriptions:
            self.node.destroy_subscription(self.subscriptions.pop(topic))
        msgs, info, matches = [], [], []
        self.msgs[topic], self.info[topic], self.matches[topic], self.lost[topic] = msgs, info, matches, 0

        def take(msg, message_info):
            msgs.append(msg)
            info.append((time.monotonic(), message_info["publication_sequence_number"]))

        def lost(status, topic=topic):
            self.lost[topic] += int(status.total_count_change)
        events = SubscriptionEventCallbacks(
            message_lost=lost, matched=lambda status: matches.append((round(time.monotonic(), 2), status.current_count)))
        self.subscriptions[topic] = self.node.create_subscription(msg_type, topic, take, QOS, event_callbacks=events)
        self.types[topic] = msg_type

    def renew(self):
        """Record every recorded topic afresh (:meth:`record`)."""
        for topic, msg_type in list(self.types.items()):
            self.record(topic, msg_type)

    def spin(self, predicate, timeout):
        return self._spin(self.executor, predicate, timeout)

    def counters(self):
        diags = self.msgs.get("/diagnostics") or []
        for d in reversed(diags):
            for st in d.status:
                if st.name == "seapup/simulator":
                    return {kv.key: kv.value for kv in st.values}
        return {}

    def call(self, srv_type, name, request, timeout=10.0):
        client = self.node.create_client(srv_type, name)   # (the services called here are sets and queries)
        return call_idempotent(self.executor, client, request, ready_timeout=timeout, response_timeout=timeout)

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()


def command(pitch, stamp_ns=0):
    msg = BladePitch()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(stamp_ns), 1_000_000_000)
    msg.pitch = pitch
    return msg


def start_simulator(node_process, *params):
    args = ["--ros-args", "-p", "diagnostics_period:=0.1"]
    for p in params:
        args += ["-p", p]
    return node_process(package="seapup_sim", executable="simulator", args=args)


def finite(msg):
    """Every float in a message (recursively) is finite."""
    if isinstance(msg, float):
        return math.isfinite(msg)
    if isinstance(msg, (list, tuple, np.ndarray)):
        return all(finite(float(v)) if np.isscalar(v) else finite(v) for v in msg)
    if hasattr(msg, "get_fields_and_field_types"):
        return all(finite(getattr(msg, f)) for f in msg.get_fields_and_field_types())
    return True


def test_hostile_commands_are_counted_and_never_reach_the_outputs(ros_context, node_process, spin):
    sim = start_simulator(node_process, "mode:=realtime", "real_time_factor:=5.0", "watchdog_timeout:=1000.0")
    probe = Probe(ros_context, spin)
    for topic, t in (("/seapup/thrusters/applied", BladePitch), ("/seapup/truth/odometry", Odometry),
                     ("/seapup/sensors/velocity", TwistWithCovarianceStamped), ("/seapup/sensors/imu", Imu),
                     ("/diagnostics", DiagnosticArray)):
        probe.record(topic, t)
    assert probe.spin(lambda: probe.cmd.get_subscription_count() > 0 and probe.counters(), 20.0), sim.log_text()

    good = serialize_message(command([0.1, 0.1, -0.2, -0.2]))
    padded = serialize_message(command([0.1, 0.2, 0.3, 0.4])) + b"\0" * 8   # a fifth float64
    n = 300
    kinds = [("nan", command([math.nan, 0, 0, 0])), ("inf", command([0, -math.inf, 0, 0])),
             ("huge", command([1e300, -1e300, 0, 0])), ("future", command([0.1] * 4, 10**15)),
             ("truncated", good[:-8]), ("padded", padded), ("valid", command([0.2, 0.2, 0.0, 0.0]))]
    def counted():  # each message lands in exactly one of these (a saturated one is also accepted)
        c = probe.counters()
        return sum(int(c.get(k, 0)) for k in ("rejected_invalid", "rejected_future", "rejected_malformed",
                                               "accepted"))
    for i in range(n):
        for _, msg in kinds:
            probe.cmd.publish(msg)
        if i % 5 == 4:  # let the node drain its queue (however busy the machine): nothing may be lost
            assert probe.spin(lambda: counted() >= (i + 1) * len(kinds), 30.0), (i, probe.counters())
    expected = {"rejected_invalid": 2 * n, "rejected_future": n, "rejected_malformed": 2 * n,
                "accepted": 2 * n, "saturated": 2 * n}
    assert probe.spin(lambda: all(int(probe.counters().get(k, -1)) == v for k, v in expected.items()), 30.0), \
        (probe.counters(), sim.log_text()[-2000:])
    assert sim.running, "the node must survive hostile input"
    for topic, msgs in probe.msgs.items():
        assert msgs, topic
        assert all(finite(m) for m in msgs), f"non-finite value on {topic}"
    applied = np.array([m.pitch for m in probe.msgs["/seapup/thrusters/applied"]])
    assert np.abs(applied).max() <= LIMIT + 1e-12
    probe.close()


def test_lockstep_rejects_commands_from_the_past(ros_context, node_process, spin):
    sim = start_simulator(node_process, "lockstep_timeout:=0.05")
    probe = Probe(ros_context, spin)
    probe.record("/diagnostics", DiagnosticArray)
    probe.record("/clock", Clock)
    assert probe.spin(lambda: float(probe.counters().get("sim_time", 0)) > 1.0, 20.0), sim.log_text()
    for _ in range(50):
        probe.cmd.publish(command([0.1] * 4, 0))  # t = 0 is long gone
    assert probe.spin(lambda: int(probe.counters().get("rejected_stale", 0)) == 50, 10.0), probe.counters()
    assert int(probe.counters()["lockstep_timeouts"]) > 0  # nobody answered: it held and went on
    assert float(probe.counters()["control_steps_per_wall_second"]) > 0
    probe.close()


def test_watchdog_returns_to_hover(ros_context, node_process, spin):
    sim = start_simulator(node_process, "mode:=realtime", "real_time_factor:=10.0", "watchdog_timeout:=1.0")
    probe = Probe(ros_context, spin)
    probe.record("/seapup/thrusters/applied", BladePitch)
    probe.record("/diagnostics", DiagnosticArray)
    assert probe.spin(lambda: probe.cmd.get_subscription_count() > 0 and probe.counters(), 20.0)
    probe.cmd.publish(command([LIMIT, LIMIT, 0.0, 0.0]))
    applied = probe.msgs["/seapup/thrusters/applied"]
    assert probe.spin(lambda: any(abs(m.pitch[0] - LIMIT) < 1e-3 for m in applied), 10.0), sim.log_text()
    assert probe.spin(lambda: probe.counters().get("watchdog_active") == "True", 10.0)
    assert probe.spin(lambda: np.allclose(applied[-1].pitch, HOVER, atol=1e-4), 10.0)
    assert int(probe.counters()["watchdog_trips"]) == 1
    probe.close()


SCHEDULE_TIMES = [0.0, 4.0]
SCHEDULE_PITCHES = [0.6, 0.6, 0.0, 0.0, 0.3, -0.1, 0.4, -0.4]


def _processes_on_domain(domain: int) -> list[str]:
    """Every process on this machine whose environment says ``ROS_DOMAIN_ID=domain``: pid, parent, command."""
    found = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            env = (proc / "environ").read_bytes().split(b"\0")
            if f"ROS_DOMAIN_ID={domain}".encode() not in env:
                continue
            ppid = (proc / "stat").read_text().rsplit(")", 1)[1].split()[1]
            command = (proc / "cmdline").read_bytes().replace(b"\0", b" ")[:200].decode(errors="replace")
            found.append(f"{proc.name} (parent {ppid}): {command}")
        except OSError:
            continue
    return found


def _assert_own_samples(probe, truth, nodes):
    """The truth heard is this run's simulator's alone, sample after sample from t_0 (twice, under load, a run
    heard another simulator's truth on its own leased domain): if not, fail naming every publisher of the topic
    and every process on the domain, to tell whose it was."""
    stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in truth]
    if stamps == [k * 200_000_000 for k in range(len(stamps))]:
        return
    domain = probe.node.context.get_domain_id()
    publishers = [(i.node_name, i.node_namespace, bytes(i.endpoint_gid).hex())
                  for i in probe.node.get_publishers_info_by_topic("/seapup/truth/odometry")]
    odd = [(s * 1e-9, round(m.pose.pose.position.x, 2), round(m.pose.pose.position.z, 2))
           for s, m in zip(stamps, truth) if s % 200_000_000 or s > 200_000_000 * len(stamps)]
    topic = "/seapup/truth/odometry"
    heard = [(round(t, 2), seq, m.header.stamp.sec + m.header.stamp.nanosec * 1e-9)
             for (t, seq), m in zip(probe.info[topic], probe.msgs[topic])]
    raise AssertionError(
        f"domain {domain} (this process {os.getpid()}, its nodes {[p.popen.pid for p in nodes]}) heard truth that "
        f"is not its simulator's: stamps {[round(s * 1e-9, 1) for s in stamps]}; odd samples (t, x, z) {odd[:5]}; "
        f"publishers {publishers}; processes on the domain {_processes_on_domain(domain)}; DDS reported "
        f"{probe.lost[topic]} lost; matches {probe.matches[topic]}; controller started {probe.started:.2f}, now "
        f"{time.monotonic():.2f}; heard (wall, "
        f"sequence number, stamp) {heard[:60]}")


def run_lockstep_with_open_loop(node_process, probe, seed, duration, pace=0.0):
    """One lockstep run (simulator + open_loop in their own processes, the simulator paced at ``pace`` x real
    time); returns the truth and measured-velocity histories and the wall seconds from the controller's start
    to the last sample, and stops both nodes."""
    probe.renew()   # not clear(): the last run's simulator went on after its probe had heard enough, and what
    # its subscriptions still held would be taken into this run's lists (seen under load: t = 19.2 s before t_0)
    sim = node_process(package="seapup_sim", executable="simulator",
                       args=["--ros-args", "-p", "lockstep_timeout:=30.0", "-p", f"seed:={seed}",
                             "-p", "environment.current.enabled:=true", "-p", "environment.sensors:=baseline",
                             "-p", "wait_for_subscribers:=['truth/odometry', 'sensors/velocity']",
                             "-p", f"lockstep_pace:={float(pace)}"],
                       name="sim")
    # the simulator holds t_0 (re-sending it) until a controller answers: start
    # the controller only once this probe hears t_0, so it records from the start
    odom = probe.msgs["/seapup/truth/odometry"]

    def heard_t0(msgs):
        return any(m.header.stamp.sec == 0 and m.header.stamp.nanosec == 0 for m in msgs)

    assert probe.spin(lambda: heard_t0(odom) and heard_t0(probe.msgs["/seapup/sensors/velocity"]), 30.0), \
        sim.log_text()
    ctl = node_process(package="seapup_control", executable="open_loop",
                       args=["--ros-args", "-p", "lockstep:=true", "-p", f"times:={SCHEDULE_TIMES}",
                             "-p", f"pitches:={SCHEDULE_PITCHES}"], name="open_loop")
    started = probe.started = time.monotonic()
    n = int(round(duration / 0.2)) + 1

    def first_per_stamp(msgs):  # t_0 may have been re-sent while waiting
        out = {}
        for m in msgs:
            out.setdefault(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec, m)
        return [out[k] for k in sorted(out)]

    assert probe.spin(lambda: len(first_per_stamp(odom)) >= n
                      and len(first_per_stamp(probe.msgs["/seapup/sensors/velocity"])) >= n, 60.0), sim.log_text()
    wall = time.monotonic() - started
    _assert_own_samples(probe, first_per_stamp(odom)[:n], [sim, ctl])
    ctl.stop()
    sim.stop()
    probe.spin(lambda: False, 0.5)  # drain what was still in flight
    truth = np.array([(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec, m.pose.pose.position.x,
                       m.pose.pose.position.z, m.twist.twist.linear.x, m.twist.twist.linear.y,
                       m.twist.twist.angular.z) for m in first_per_stamp(odom)[:n]])
    vel = np.array([(m.twist.twist.linear.x, m.twist.twist.linear.y)
                    for m in first_per_stamp(probe.msgs["/seapup/sensors/velocity"])[:n]])
    return truth, vel, wall


def test_lockstep_is_deterministic_and_equals_the_pure_core_loop(ros_context, node_process, spin):
    probe = Probe(ros_context, spin)
    probe.record("/seapup/truth/odometry", Odometry)
    probe.record("/seapup/sensors/velocity", TwistWithCovarianceStamped)
    truth1, vel1, _ = run_lockstep_with_open_loop(node_process, probe, seed=7, duration=10.0)
    # paced to 4x real time (to be watched): the same run, bit for bit, no faster than the pace
    truth2, vel2, wall = run_lockstep_with_open_loop(node_process, probe, seed=7, duration=10.0, pace=4.0)
    np.testing.assert_array_equal(truth1, truth2)
    np.testing.assert_array_equal(vel1, vel2)
    assert wall >= 10.0 / 4.0 - 0.2 - 0.05, wall   # the first sample sets the schedule
    # the same scenario through the pure core (no ROS), sample by sample
    schedule = PitchProfile(SCHEDULE_TIMES, SCHEDULE_PITCHES, LIMIT)
    core = Simulation.from_config("baseline", {"current": {"enabled": True}, "sensors": "baseline"}, seed=7,
                                  pitch=HOVER)
    log = core.run(OpenLoop(schedule, 0.2), 10.0)
    np.testing.assert_array_equal(truth1[:, 0].astype(np.int64), np.round(log.t * 1e9).astype(np.int64))
    ref = np.column_stack([log.state[:, 0], log.state[:, 2], log.state[:, 6], log.state[:, 7], log.state[:, 11]])
    np.testing.assert_array_equal(truth1[:, 1:], ref)
    np.testing.assert_array_equal(vel1, log.measured["velocity"][:, :2])
    assert np.abs(ref[:, 3]).max() > 0.05  # it did move sideways with the current
    probe.close()


def test_frames_units_and_enu_conversion(ros_context, node_process, spin):
    start_simulator(node_process, "mode:=realtime", "real_time_factor:=5.0", "start_depth:=20.0",
                    "watchdog_timeout:=1000.0")
    probe = Probe(ros_context, spin)
    topics = {"/seapup/truth/odometry": Odometry, "/seapup/odometry": Odometry,
              "/seapup/sensors/velocity": TwistWithCovarianceStamped, "/seapup/sensors/imu": Imu,
              "/seapup/sensors/depth": Depth, "/seapup/environment/current": Vector3Stamped,
              "/seapup/umbilical/wrench": WrenchStamped, "/seapup/thrusters/applied": BladePitch}
    for topic, t in topics.items():
        probe.record(topic, t)
    assert probe.spin(lambda: all(len(v) > 5 for v in probe.msgs.values()), 20.0)
    probe.cmd.publish(command([0.5, 0.3, 0.2, -0.3]))
    assert probe.spin(lambda: abs(probe.msgs["/seapup/truth/odometry"][-1].twist.twist.angular.z) > 0.05, 20.0)
    frame = {t: probe.msgs[t][-1].header.frame_id for t in topics}
    assert frame["/seapup/truth/odometry"] == "odom_ned"
    assert probe.msgs["/seapup/truth/odometry"][-1].child_frame_id == "base_link_frd"
    assert frame["/seapup/odometry"] == "odom" and probe.msgs["/seapup/odometry"][-1].child_frame_id == "base_link"
    for t in ("/seapup/sensors/velocity", "/seapup/sensors/imu", "/seapup/umbilical/wrench",
              "/seapup/thrusters/applied"):
        assert frame[t] == "base_link_frd", t
    assert frame["/seapup/sensors/depth"] == "odom_ned" and frame["/seapup/environment/current"] == "odom_ned"
    # same stamp, same physical pose in both conventions
    ned = {(m.header.stamp.sec, m.header.stamp.nanosec): m for m in probe.msgs["/seapup/truth/odometry"]}
    enu = next(m for m in reversed(probe.msgs["/seapup/odometry"])
               if (m.header.stamp.sec, m.header.stamp.nanosec) in ned)
    n = ned[(enu.header.stamp.sec, enu.header.stamp.nanosec)]
    p = n.pose.pose.position
    assert (enu.pose.pose.position.x, enu.pose.pose.position.y, enu.pose.pose.position.z) == (p.y, p.x, -p.z)
    assert p.z > 19.0  # metres, positive down
    qn, qe = n.pose.pose.orientation, enu.pose.pose.orientation
    fwd_ned = Rotation.from_quat([qn.x, qn.y, qn.z, qn.w]).apply([1, 0, 0])
    fwd_enu = Rotation.from_quat([qe.x, qe.y, qe.z, qe.w]).apply([1, 0, 0])
    np.testing.assert_allclose(fwd_enu, [fwd_ned[1], fwd_ned[0], -fwd_ned[2]], atol=1e-9)
    assert enu.twist.twist.angular.z == -n.twist.twist.angular.z   # yaw rate: FRD z down, FLU z up
    # radians: the applied blade pitch settles on the command (0.05 s lag) in rad
    applied = probe.msgs["/seapup/thrusters/applied"]
    assert probe.spin(lambda: abs(applied[-1].pitch[0] - 0.5) < 1e-9, 5.0), applied[-1].pitch
    depth = next(m for m in reversed(probe.msgs["/seapup/sensors/depth"])
                 if (m.header.stamp.sec, m.header.stamp.nanosec) in ned)
    assert abs(depth.depth - ned[(depth.header.stamp.sec, depth.header.stamp.nanosec)].pose.pose.position.z) < 0.5
    _check_tf(probe)
    probe.close()


def _check_tf(probe):
    """/tf carries odom -> base_link at each sample, the ENU odometry's pose; /tf_static, subscribed late as
    tf2 listeners do (transient local), the two fixed frames."""
    tf = []
    probe.node.create_subscription(TFMessage, "/tf", tf.append, QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))
    static = []
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    probe.node.create_subscription(TFMessage, "/tf_static", static.append, latched)
    truth = probe.msgs["/seapup/truth/odometry"]
    assert probe.spin(lambda: static and len(tf) > 3 and _stamp(tf[-3].transforms[0]) <= _stamp(truth[-1]), 20.0)
    ned = {_stamp(m): m for m in truth}
    assert {(t.header.frame_id, t.child_frame_id) for t in static[0].transforms} == \
        {("odom", "odom_ned"), ("base_link", "base_link_frd")}
    compared = 0
    for msg in tf:
        (transform,) = msg.transforms
        assert (transform.header.frame_id, transform.child_frame_id) == ("odom", "base_link")
        if _stamp(transform) in ned:
            p, q = ned[_stamp(transform)].pose.pose.position, transform.transform
            assert (q.translation.x, q.translation.y, q.translation.z) == (p.y, p.x, -p.z)
            compared += 1
    assert compared >= 3


def _stamp(msg):
    return msg.header.stamp.sec, msg.header.stamp.nanosec


def param(name, value):
    v = ParameterValue()
    if isinstance(value, float):
        v.type, v.double_value = ParameterType.PARAMETER_DOUBLE, value
    else:
        v.type, v.string_value = ParameterType.PARAMETER_STRING, value
    return ParameterMsg(name=name, value=v)


def test_services_and_parameter_validation(ros_context, node_process, spin):
    start_simulator(node_process, "mode:=realtime", "real_time_factor:=5.0")
    probe = Probe(ros_context, spin)
    probe.record("/diagnostics", DiagnosticArray)
    probe.record("/seapup/truth/odometry", Odometry)
    probe.record("/seapup/sensors/velocity", TwistWithCovarianceStamped)
    assert probe.spin(lambda: float(probe.counters().get("sim_time", 0)) > 1.0, 20.0)

    r = probe.call(SetConfiguration, "/seapup/simulator/set_configuration", SetConfiguration.Request(name="camera"))
    assert r.success, r.message
    assert probe.spin(lambda: probe.counters().get("vehicle") == "camera", 5.0)
    r = probe.call(SetConfiguration, "/seapup/simulator/set_configuration", SetConfiguration.Request(name="boat"))
    assert not r.success and "no configuration 'boat'" in r.message
    req = SetThrusterEfficiency.Request()
    req.efficiency = [2.0, 1.0, 1.0, 1.0]
    r = probe.call(SetThrusterEfficiency, "/seapup/simulator/set_thruster_efficiency", req)
    assert not r.success and "[0, 1.5]" in r.message
    req.efficiency = [0.5, 1.0, 1.0, 1.0]
    assert probe.call(SetThrusterEfficiency, "/seapup/simulator/set_thruster_efficiency", req).success
    r = probe.call(SetSensorProfile, "/seapup/simulator/set_sensor_profile", SetSensorProfile.Request(name="haslar"))
    assert r.success and probe.spin(lambda: probe.counters().get("sensor_profile") == "haslar", 5.0)
    # what it changes: the published velocity covariance is Haslar's sigma^2 (0.0172 m/s, App. A)
    vel = probe.msgs["/seapup/sensors/velocity"]
    assert probe.spin(lambda: vel and abs(vel[-1].twist.covariance[0] - 0.0172 ** 2) < 1e-12, 5.0)
    assert vel[-1].twist.covariance[7] == vel[-1].twist.covariance[0]
    r = probe.call(SetSensorProfile, "/seapup/simulator/set_sensor_profile", SetSensorProfile.Request(name="x" * 10**5))
    assert not r.success and len(r.message) < 300

    reset = Reset.Request(seed=5, use_state=True)
    reset.state = [0.0, 0.0, 33.0] + [0.0] * 9
    assert probe.call(Reset, "/seapup/simulator/reset", reset).success
    odom = probe.msgs["/seapup/truth/odometry"]
    assert probe.spin(lambda: odom and odom[-1].header.stamp.sec == 0 and abs(odom[-1].pose.pose.position.z - 33.0) < 0.1, 5.0)
    bad = Reset.Request(seed=1, use_state=True)
    bad.state = [math.nan] + [0.0] * 11
    r = probe.call(Reset, "/seapup/simulator/reset", bad)
    assert not r.success and "finite" in r.message

    # a legal state that leaves the valid envelope within a step: the plant halts
    # with an ERROR diagnostic instead of the node dying, until the next reset
    steep = Reset.Request(seed=1, use_state=True)
    steep.state = [0.0, 0.0, 10.0, 0.0, 1.45, 0.0, 0.0, 0.0, 0.0, 0.0, 3.0, 0.0]
    r = probe.call(Reset, "/seapup/simulator/reset", steep)
    assert not r.success and "theta = 1.45" in r.message  # beyond environment/limits.yaml: refused
    steep.state = [0.0, 0.0, 10.0, 0.0, 1.39, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0]  # legal, but pitching over
    assert probe.call(Reset, "/seapup/simulator/reset", steep).success
    diags = probe.msgs["/diagnostics"]

    def simulator_status():
        return next((st for d in reversed(diags) for st in d.status if st.name == "seapup/simulator"), None)

    assert probe.spin(lambda: simulator_status() is not None and "halted" in simulator_status().message, 10.0)
    assert simulator_status().level == b"\x02"  # ERROR
    assert probe.call(Reset, "/seapup/simulator/reset", Reset.Request(seed=2)).success
    assert probe.spin(lambda: "halted" not in simulator_status().message
                      and float(probe.counters()["sim_time"]) > 1.0, 10.0)

    client = probe.node.create_client(SetParameters, "/seapup/simulator/set_parameters")
    def set_params(*ps):   # asked again if a loaded server drops its answer (call_idempotent)
        request = SetParameters.Request(parameters=list(ps))
        return call_idempotent(probe.executor, client, request, ready_timeout=10.0, response_timeout=10.0).results[0]
    res = set_params(param("real_time_factor", -1.0))
    assert not res.successful and res.reason
    res = set_params(param("mode", "realtime"))
    assert not res.successful and "read-only" in res.reason
    res = set_params(param("watchdog_action", "panic"))
    assert not res.successful and "hover or neutral" in res.reason
    assert set_params(param("real_time_factor", 2.0)).successful
    probe.close()


def test_seapup_run_starts_a_node_another_process_can_see(ros_context, node_process, ros_env, spin):
    env = dict(ros_env)
    for key in ("PYTHONPATH", "AMENT_PREFIX_PATH", "_ROS_WHEELS_BOOTSTRAP_COMPLETE"):
        env.pop(key, None)  # as a user's shell would be: ./seapup sets these up itself
    env["PATH"] = os.defpath
    sim = node_process([str(REPO / "seapup"), "run", "seapup_sim", "simulator"], env=env, name="seapup-run")
    probe = Probe(ros_context, spin)
    assert probe.spin(lambda: ("simulator", "/seapup") in probe.node.get_node_names_and_namespaces(), 30.0), \
        sim.log_text()
    assert sim.stop() == 0, sim.log_text()
    probe.close()


def test_lockstep_at_20_hz(ros_context, node_process, spin):
    probe = Probe(ros_context, spin)
    probe.record("/clock", Clock)
    node_process(package="seapup_sim", executable="simulator",
                 args=["--ros-args", "-p", "control_period:=0.05", "-p", "physics_step:=0.05",
                       "-p", "lockstep_timeout:=30.0"], name="sim")
    clocks = probe.msgs["/clock"]
    assert probe.spin(lambda: len(clocks) > 0, 30.0)
    node_process(package="seapup_control", executable="open_loop",
                 args=["--ros-args", "-p", "lockstep:=true"], name="open_loop")
    assert probe.spin(lambda: clocks and clocks[-1].clock.sec >= 5, 60.0)
    stamps = sorted({c.clock.sec * 10**9 + c.clock.nanosec for c in clocks})
    assert set(np.diff(stamps)) == {50_000_000}  # every 50 ms sample, none skipped
    probe.close()


def test_a_held_graph_resumes_and_says_its_sample_again_to_nodes_that_joined_meanwhile(ros_context, node_process,
                                                                                     spin):
    """end_time set at run time (SilGraph's paced driving): the lockstep simulator holds at the first sample
    at or after it, publishing nothing more (no lockstep time-out while held); a later end_time resumes it.
    A node that joined while it was held (a controller configured there) hears the held sample again, the
    same bytes, and a command for the held sample that came while held is the one applied."""
    probe = Probe(ros_context, spin)
    probe.record("/diagnostics", DiagnosticArray)
    probe.record("/seapup/sensors/velocity", TwistWithCovarianceStamped)
    probe.record("/seapup/thrusters/applied", BladePitch)
    # a sample nobody answers goes on after lockstep_timeout: long enough for the simulator to match a reader
    # that joined while it was held (discovery lags on a loaded machine; with 0.05 s the held sample was once
    # gone before the simulator had seen the new reader, so it was never said to it)
    start_simulator(node_process, "mode:=lockstep", "lockstep_timeout:=1.0", "start_held:=true",
                    "wait_for_subscribers:=['sensors/velocity', 'thrusters/applied']")
    velocity, applied = probe.msgs["/seapup/sensors/velocity"], probe.msgs["/seapup/thrusters/applied"]

    def stamps(msgs):
        return [round(m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec, 6) for m in msgs]

    def holding(at=1.0):
        text = "held at t_0 (start_held)" if at == 0 else f"at end_time {at:g} s (holding)"
        return any(st.name == "seapup/simulator" and text in st.message
                   for d in probe.msgs["/diagnostics"][-3:] for st in d.status)
    client = probe.node.create_client(SetParameters, "/seapup/simulator/set_parameters")

    def set_end(value):   # asked again if a loaded server drops its answer (call_idempotent)
        request = SetParameters.Request(parameters=[param("end_time", value)])
        assert call_idempotent(probe.executor, client, request, ready_timeout=10.0,
                               response_timeout=10.0).results[0].successful
    # start_held: t_0 is published and held, with no lockstep time-out however long nobody answers it
    assert probe.spin(lambda: holding(0), 20.0)
    probe.spin(lambda: False, 1.0)
    assert stamps(velocity) == [0.0] and int(probe.counters()["lockstep_timeouts"]) == 0
    set_end(1.0)
    assert probe.spin(holding, 20.0)
    probe.spin(lambda: False, 1.0)  # held: nothing more, and no time-out while held
    # t_0 unanswered at the resume, but nobody joined during the hold: not said again (no sample twice in a bag)
    assert stamps(velocity) == [0.0, 0.2, 0.4, 0.6, 0.8, 1.0]
    assert int(probe.counters()["lockstep_timeouts"]) == 5  # nobody answers: 0 to 0.8 s went on without
    late = []
    joined = probe.node.create_subscription(TwistWithCovarianceStamped, "/seapup/sensors/velocity", late.append, QOS)
    assert probe.spin(lambda: joined.get_publisher_count() > 0, 10.0)
    set_end(1.4)
    assert probe.spin(lambda: stamps(late)[-1:] == [1.4] and stamps(velocity)[-1:] == [1.4], 10.0), stamps(late)
    # said again on the resume, and again if the simulator matched the new reader only after that
    assert sorted(set(stamps(late))) == [1.0, 1.2, 1.4] and stamps(late)[-2:] == [1.2, 1.4]
    # the same reading, said again: every field equal (not the bytes: the serializer leaves CDR's alignment
    # padding uninitialised -- after the frame id, at byte 33 -- so equal messages need not be equal bytes)
    assert late[0] == velocity[5]
    assert stamps(velocity)[5] == 1.0 and stamps(velocity)[-2:] == [1.2, 1.4] and set(stamps(velocity)[5:-2]) == {1.0}
    assert len(stamps(velocity)[5:-2]) >= 2
    # a command for the held sample, sent while held, is applied when the graph goes on (no time-out)
    assert probe.spin(lambda: holding(1.4), 10.0)
    timeouts = int(probe.counters()["lockstep_timeouts"])
    assert timeouts == 7  # 1.0 (said again) and 1.2 went on without
    probe.cmd.publish(command([0.2, 0.1, -0.1, 0.05], int(1.4e9)))
    assert probe.spin(lambda: int(probe.counters().get("accepted", 0)) == 1, 5.0)
    set_end(1.6)
    assert probe.spin(lambda: applied and stamps(applied)[-1] == 1.6, 10.0)
    wanted = np.array([0.2, 0.1, -0.1, 0.05])  # reached through the blade-pitch servos' lag
    held = applied[stamps(applied).index(1.4)].pitch
    assert np.abs(held - wanted).max() > 0.05 and np.allclose(applied[-1].pitch, wanted, atol=0.02)
    assert stamps(velocity).count(1.4) == 1
    assert int(probe.counters()["lockstep_timeouts"]) == timeouts
    probe.close()


def test_a_subscriber_with_an_incompatible_qos_is_reported_once_in_the_log_and_in_diagnostics(
        ros_context, node_process, spin):
    """The simulator's publishers carry no per-endpoint event handlers (speed): the incompatible-QoS warning
    rclpy's default handler would log comes from the diagnostics check instead -- once in the log, and as a
    WARN naming the topic and the subscriber for as long as it is there."""
    from rclpy.qos import DurabilityPolicy

    sim = start_simulator(node_process, "mode:=realtime", "real_time_factor:=5.0", "watchdog_timeout:=1000.0")
    probe = Probe(ros_context, spin)
    probe.record("/diagnostics", DiagnosticArray)
    depth = []
    greedy = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)  # the publisher offers volatile
    probe.node.create_subscription(Depth, "/seapup/sensors/depth", depth.append, greedy)

    def warned():
        for d in probe.msgs["/diagnostics"][-3:]:
            for st in d.status:
                if st.name == "seapup/simulator" and "incompatible QoS" in st.message:
                    return st
        return None
    assert probe.spin(warned, 20.0), sim.log_text()[-2000:]
    status = warned()
    assert status.level == DiagnosticStatus.WARN
    assert "/seapup/sensors/depth: subscription /probe has an incompatible QoS" in status.message
    assert "transient local" in status.message.lower()
    assert status.message.count("incompatible QoS") == 1, "compatible endpoints (the probe's own) are not reported"
    assert not depth, "nothing passes between incompatible endpoints"
    n_diagnostics = len(probe.msgs["/diagnostics"])
    assert probe.spin(lambda: len(probe.msgs["/diagnostics"]) > n_diagnostics + 10, 20.0)
    assert sim.log_text().count("/seapup/sensors/depth: subscription /probe has an incompatible QoS") == 1
    probe.close()
