"""The mfol_velocity_controller lifecycle node flying the simulator in lockstep.

Independent truth: the same controller (from the same controller file) flown
by the pure loop (Simulation.run): lockstep makes the graph the same
computation, so the trajectories agree to rounding.
"""
import math

import numpy as np
import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TwistStamped
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
from nav_msgs.msg import Odometry
from rclpy.executors import SingleThreadedExecutor
from seapup_msgs.msg import BladePitch

from seapup_runs.self_test_flight import fly_self_test
from seapup_common.contract import Reference
from seapup_control.mfol_controller import GainSchedule, MFOLController
from seapup_control.self_test import result_document
from seapup_sim.analysis import hover_blade_pitch
from seapup_sim.simulation import Simulation
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config
from tests.test_simulator_node import start_simulator

HOVER = hover_blade_pitch(VehicleModel(load_vehicle_config("baseline")))
NAME = "/seapup/mfol_velocity_controller"


def controller_file(tmp_path):
    run = fly_self_test("baseline", {"operating_points": [0.0, 0.7]})
    path = tmp_path / "controller.yaml"
    path.write_text(yaml.safe_dump(result_document(run.test), sort_keys=False))
    return path


class Probe:
    def __init__(self, context, spin):
        self.node = rclpy.create_node("mfol_probe", context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.odometry, self.commands = [], []
        self.node.create_subscription(Odometry, "/seapup/truth/odometry", self.odometry.append, 1000)
        self.node.create_subscription(BladePitch, "/seapup/thrusters/command", self.commands.append, 1000)
        self.diagnostics = []
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self.diagnostics.append, 1000)
        self.reference = self.node.create_publisher(TwistStamped, "/seapup/velocity_controller/reference", 10)
        self.change = self.node.create_client(ChangeState, f"{NAME}/change_state")
        self.get_state = self.node.create_client(GetState, f"{NAME}/get_state")
        self._spin = spin

    def spin(self, predicate, timeout):
        return self._spin(self.executor, predicate, timeout)

    def state(self) -> int:
        from seapup_common.ros.graph import call_idempotent
        return call_idempotent(self.executor, self.get_state, GetState.Request()).current_state.id

    def transition(self, transition_id, attempts: int = 4):
        """The node's answer to a transition request. A lifecycle request is not idempotent, and the server may
        drop its answer while it has not yet matched our response reader (rmw "failed to send response
        (timeout)", seen on a fresh clone; :func:`seapup_common.ros.graph.call_idempotent`): unanswered, the
        node's state tells -- changed from before the request: the transition was made; unchanged: nothing
        happened (a refusal or a lost request), and it is asked again."""
        assert self.spin(self.change.service_is_ready, 20.0)
        before = self.state()
        for _ in range(attempts):
            future = self.change.call_async(ChangeState.Request(transition=Transition(id=transition_id)))
            if self.spin(future.done, 20.0):
                return future.result().success
            self.change.remove_pending_request(future)
            now = self.state()
            if now != before and now < 10:   # a primary state other than the one it was in (10+: transitioning)
                return True
        raise AssertionError(f"transition {transition_id} unanswered {attempts} times (state {self.state()})")

    def activate_and_sample(self, t_ns: int) -> None:
        """Configure and activate the controller, then publish one velocity sample stamped ``t_ns``."""
        from geometry_msgs.msg import TwistWithCovarianceStamped
        from seapup_common.contract import Reading
        from seapup_common.ros.messages import velocity_to_msg
        velocity = self.node.create_publisher(TwistWithCovarianceStamped, "/seapup/sensors/velocity", 10)
        assert self.transition(Transition.TRANSITION_CONFIGURE)
        assert self.transition(Transition.TRANSITION_ACTIVATE)
        assert self.spin(lambda: velocity.get_subscription_count() > 0, 20.0)
        self.spin(lambda: False, 0.3)
        velocity.publish(velocity_to_msg(Reading(np.zeros(3), t_ns * 1e-9), Reading(np.zeros(3), t_ns * 1e-9), t_ns))

    def send_reference(self, u, v=0.0, w=0.0, r=0.0, at_ns=0):
        msg = TwistStamped()
        msg.header.frame_id = "base_link_frd"
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(at_ns, 10**9)
        msg.twist.linear.x, msg.twist.linear.y, msg.twist.linear.z, msg.twist.angular.z = u, v, w, r
        assert self.spin(lambda: self.reference.get_subscription_count() > 0, 20.0)
        self.reference.publish(msg)
        self.spin(lambda: False, 0.3)


def test_lifecycle_node_flies_the_simulator_as_the_pure_loop_does(ros_context, node_process, spin, tmp_path):
    path = controller_file(tmp_path)
    start_simulator(node_process, "mode:=lockstep", "lockstep_timeout:=60.0", "start_depth:=50.0",
                    "environment.sensors:=ideal",
                    "wait_for_subscribers:=['/seapup/sensors/velocity', '/seapup/truth/odometry']")
    node_process(package="seapup_control", executable="mfol_velocity_controller",
                 args=["--ros-args", "-p", f"controller_file:={path}"])
    probe = Probe(ros_context, spin)
    assert probe.transition(Transition.TRANSITION_CONFIGURE)  # subscriptions exist from now on
    probe.send_reference(0.3)
    probe.send_reference(0.5, v=0.1, at_ns=20 * 10**9)  # takes effect exactly at the sample t = 20 s
    assert probe.transition(Transition.TRANSITION_ACTIVATE)
    assert not probe.transition(Transition.TRANSITION_ACTIVATE)  # a second activate is refused, not fatal
    def stamp_ns(o):
        return o.header.stamp.sec * 10**9 + o.header.stamp.nanosec
    assert probe.spin(lambda: probe.odometry and stamp_ns(probe.odometry[-1]) >= 30 * 10**9, 60.0)
    # the same controller in the pure loop, from the same start (bumpless from the applied hover
    # setting, which the node waits for in lockstep), compared sample by sample at every stamp this
    # process received (on a loaded machine its subscription may match after the first ones)
    schedule = GainSchedule.from_document(yaml.safe_load(path.read_text()))
    simulation = Simulation.from_config("baseline", {"sensors": "ideal"}, state=np.r_[0, 0, 50.0, np.zeros(9)],
                                        pitch=HOVER)
    log = simulation.run(MFOLController(schedule), 30.0,
                         reference=lambda t: Reference([0.3, 0, 0, 0] if t < 20.0 - 1e-9 else [0.5, 0.1, 0, 0]))
    received = {round(stamp_ns(o) / 2e8): (o.pose.pose.position.x, o.twist.twist.linear.x)
                for o in probe.odometry if stamp_ns(o) <= 30 * 10**9}
    assert len(received) >= 100 and 100 in received and 150 in received
    k = sorted(received)
    graph = np.array([received[i] for i in k])
    np.testing.assert_allclose(graph, log.state[k][:, [0, 6]], rtol=1e-9, atol=1e-12)
    assert abs(received[100][1] - 0.3) < 0.01 and abs(received[150][1] - 0.5) < 0.02  # tracking the references
    # a non-finite reference is rejected: the vehicle keeps flying the last good one
    probe.send_reference(math.nan)
    probe.send_reference(0.2, at_ns=1_795_000_000 * 10**9)  # a wall-clock stamp on sim time: refused, not queued
    count = len(probe.odometry)
    assert probe.spin(lambda: len(probe.odometry) > count + 50, 30.0)
    assert abs(probe.odometry[-1].twist.twist.linear.x - 0.5) < 0.01

    def counts():
        found = [dict((kv.key, kv.value) for kv in status.values) for array in probe.diagnostics
                 for status in array.status if status.name == "seapup/mfol_velocity_controller"]
        return found[-1] if found else {}
    # its next status says so (published every diagnostics_every samples: on a loaded machine later)
    assert probe.spin(lambda: counts().get("rejected_references") == "2", 30.0), counts()
    assert counts()["references_waiting"] == "0"
    # deactivated, it stops commanding (the lockstep simulator then waits); commands already sent may still be
    # on their way to this probe on a loaded machine: wait until none has come for a second, then for another
    assert probe.transition(Transition.TRANSITION_DEACTIVATE)
    count = -1
    for _ in range(30):
        if len(probe.commands) == count:
            break
        count = len(probe.commands)
        probe.spin(lambda: False, 1.0)
    probe.spin(lambda: False, 1.0)
    assert len(probe.commands) == count


def test_configure_fails_cleanly_on_a_bad_controller_file(ros_context, node_process, spin, tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("kind: something_else\n")
    node = node_process(package="seapup_control", executable="mfol_velocity_controller",
                        args=["--ros-args", "-p", f"controller_file:={bad}"])
    probe = Probe(ros_context, spin)
    assert not probe.transition(Transition.TRANSITION_CONFIGURE)
    assert "configure failed" in node.log_text() and "not a seapup MFOL controller" in node.log_text()
    assert node.running


def test_a_sample_whose_applied_pitch_was_missed_is_answered_after_applied_wait(ros_context, node_process, spin,
                                                                               tmp_path):
    """Configured at a sample boundary (the demo re-configures the controller after the self-test), the
    node may subscribe after the simulator published that sample's applied pitch; in lockstep nothing
    else comes until the sample is answered. It must start from u0 after ``applied_wait``, not hang
    until the simulator's lockstep timeout."""
    path = controller_file(tmp_path)
    node_process(package="seapup_control", executable="mfol_velocity_controller",
                 args=["--ros-args", "-p", f"controller_file:={path}", "-p", "applied_wait:=0.5"])
    probe = Probe(ros_context, spin)
    t_ns = 12 * 10**9
    probe.activate_and_sample(t_ns)
    assert probe.spin(lambda: probe.commands, 5.0), "the sample was never answered"
    command = probe.commands[0]
    assert command.header.stamp.sec == 12 and command.header.stamp.nanosec == 0
    u0 = GainSchedule.from_document(yaml.safe_load(path.read_text())).offset_at(0.0)
    np.testing.assert_allclose(command.pitch, u0, atol=np.radians(2.0))   # from u0, one PI step on zero error


def test_the_first_command_waits_for_every_awaited_subscriber(ros_context, node_process, spin, tmp_path):
    """``wait_for_command_subscribers`` n: a lockstep sample is not answered until n subscriptions have matched
    the command publisher (a run's probe and recorder hear every command); then it is, with its stamp."""
    node = node_process(package="seapup_control", executable="velocity_controller",
                        args=["--ros-args", "-p", "controller_type:=hold", "-p", "blade_pitch:=[0.1, 0.1, 0.2, 0.2]",
                              "-p", "sample_period:=0.2", "-p", "wait_for_command_subscribers:=2", "-p", "applied_wait:=0.2",
                              "-r", "__node:=mfol_velocity_controller"])
    probe = Probe(ros_context, spin)  # one subscription to the commands
    probe.activate_and_sample(3 * 10**9)
    probe.spin(lambda: False, 2.0)
    assert probe.commands == [], "answered with one of two awaited subscribers"
    assert probe.spin(lambda: "waiting for subscribers of /seapup/thrusters/command (1/2)" in node.log_text(), 5.0)
    second = []
    probe.node.create_subscription(BladePitch, "/seapup/thrusters/command", second.append, 10)
    assert probe.spin(lambda: probe.commands and second, 20.0), "the held sample was never answered"
    for heard in (probe.commands, second):
        assert len(heard) == 1 and heard[0].header.stamp.sec == 3 and heard[0].header.stamp.nanosec == 0
        np.testing.assert_allclose(heard[0].pitch, [0.1, 0.1, 0.2, 0.2])


def test_every_numeric_parameter_is_range_checked_at_start_and_on_every_change(ros_context, node_process, spin):
    """``reference_wait`` inf, NaN, 1e300 or -1 once killed the controller at its next sample: now a bad
    value is refused at start (exit 1, the parameter named) and by ``param set`` (the node flies on)."""
    from rcl_interfaces.srv import GetParameters, SetParameters
    from rclpy.parameter import Parameter

    from seapup_common.ros.graph import call_idempotent
    bad = node_process(package="seapup_control", executable="velocity_controller",
                       args=["--ros-args", "-p", "reference_wait:=.nan", "-r", "__node:=bad"])
    assert bad.popen.wait(60) == 1, bad.log_text()[-800:]
    assert "fatal" in bad.log_text() and "reference_wait" in bad.log_text() and "nan" in bad.log_text()
    node_process(package="seapup_control", executable="velocity_controller",
                 args=["--ros-args", "-p", "controller_type:=hold", "-p", "sample_period:=0.2",
                       "-r", "__node:=mfol_velocity_controller"])
    probe = Probe(ros_context, spin)
    setter = probe.node.create_client(SetParameters, f"{NAME}/set_parameters")
    getter = probe.node.create_client(GetParameters, f"{NAME}/get_parameters")

    def set_wait(value):   # a set may be asked again: a loaded server once dropped its answer (call_idempotent)
        request = SetParameters.Request(parameters=[Parameter("reference_wait", value=value).to_parameter_msg()])
        return call_idempotent(probe.executor, setter, request, ready_timeout=30.0, response_timeout=10.0).results[0]
    for value in (math.inf, math.nan, 1e300, -1.0):
        result = set_wait(value)
        assert not result.successful and "reference_wait" in result.reason, (value, result)
    assert set_wait(0.5).successful
    answer = call_idempotent(probe.executor, getter, GetParameters.Request(names=["reference_wait"]),
                             ready_timeout=30.0, response_timeout=10.0)
    assert answer.values[0].double_value == 0.5
