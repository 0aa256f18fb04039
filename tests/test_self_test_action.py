"""The /seapup/self_test action through the ROS graph, with the simulator in lockstep.

Independent truth: the same self-test flown in one process on the same
simulation (seapup_runs.self_test_flight): lockstep makes the ROS run the
same computation, so the results must agree to rounding.
"""
import math

import numpy as np
import yaml
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from seapup_msgs.action import SelfTest
from seapup_msgs.msg import BladePitch
from seapup_msgs.srv import SetThrusterEfficiency

import rclpy
from action_msgs.msg import GoalStatus
from seapup_runs.self_test_flight import fly_self_test
from seapup_common.ros.graph import call_idempotent, send_goal
from seapup_control.mfol_controller import GainSchedule
from seapup_sim.analysis import hover_blade_pitch
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config
from tests.test_simulator_node import start_simulator

HOVER = hover_blade_pitch(VehicleModel(load_vehicle_config("baseline")))


class Client:
    def __init__(self, context, spin):
        self.node = rclpy.create_node("self_test_client", context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.client = ActionClient(self.node, SelfTest, "/seapup/self_test")
        self.feedback = []
        self.commands = []
        self.node.create_subscription(BladePitch, "/seapup/thrusters/command", self.commands.append, 1000)
        self._spin = spin

    def spin(self, predicate, timeout):
        return self._spin(self.executor, predicate, timeout)

    def send(self, goal):
        return send_goal(self.executor, self.client, goal, lambda f: self.feedback.append(f.feedback))

    def result(self, handle, timeout=180.0):
        future = handle.get_result_async()
        assert self.spin(future.done, timeout), "no result"
        return future.result()


def start_graph(node_process, *simulator_params, self_test_params=()):
    start_simulator(node_process, "mode:=lockstep", "lockstep_timeout:=60.0", "start_depth:=50.0",
                    "environment.sensors:=ideal", "wait_for_subscribers:=['/seapup/sensors/velocity']",
                    *simulator_params)
    args = ["--ros-args"] + [a for p in self_test_params for a in ("-p", p)]
    return node_process(package="seapup_control", executable="self_test", args=args)


def test_self_test_through_ros_equals_the_in_process_run(ros_context, node_process, spin, tmp_path):
    start_graph(node_process, self_test_params=[f"result_dir:={tmp_path}", "wait_for_command_subscribers:=2"])
    client = Client(ros_context, spin)
    goal = SelfTest.Goal()
    goal.operating_points = [0.0]
    handle = client.send(goal)
    assert handle.accepted
    # rclpy drops feedback that comes after the result: take the last ("done") first (the server keeps
    # the result until asked; under load the result once overtook it)
    assert client.spin(lambda: client.feedback and client.feedback[-1].phase == "done", 180.0)
    answer = client.result(handle)
    assert answer.status == GoalStatus.STATUS_SUCCEEDED, answer.result.message
    result = answer.result
    local = fly_self_test("baseline", {}, start_pitch=HOVER)
    (point,) = local.test.points
    np.testing.assert_allclose(np.reshape(result.b0_inverse, (4, 4)), point.model.B0inv, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(np.reshape(result.b1_inverse, (4, 4)), point.model.B1inv, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(np.reshape(result.k_int, (4, 4)), point.gains.K_int, rtol=1e-9)
    np.testing.assert_allclose(result.u0, point.model.u0, atol=1e-12)
    assert result.duration == local.test.duration and list(result.surge_speeds) == [0.0]
    # feedback: every phase seen, progress monotone to 1, live velocities
    phases = {f.phase for f in client.feedback}
    assert {"drift", "quiesce", "step", "done"} <= phases
    progress = [f.progress for f in client.feedback]
    assert progress == sorted(progress) and progress[-1] == 1.0
    assert all(math.isfinite(v) for v in client.feedback[-1].velocity)
    # the controller file loads as a gain schedule
    schedule = GainSchedule.from_document(yaml.safe_load(open(result.controller_file)))
    np.testing.assert_allclose(schedule.gains_at(0.0)[0], point.gains.K_int, rtol=1e-9)
    # every command stamped with its sample (lockstep), one per sample
    stamps = [c.header.stamp.sec * 10**9 + c.header.stamp.nanosec for c in client.commands]
    # contiguous from the first one this process heard (its subscription may match late under load)
    assert stamps[:50] == [stamps[0] + k * 200_000_000 for k in range(50)]
    # after success it keeps flying the controller at zero reference: the simulator keeps stepping
    count = len(client.commands)
    assert client.spin(lambda: len(client.commands) > count + 20, 20.0)


def test_cancel_leaves_the_vehicle_hovering_under_the_best_controller(ros_context, node_process, spin, tmp_path):
    # paced (at most 20x real time: a sample every 10 ms of wall time) so that the cancel, sent when cycle 2's
    # feedback is heard, reaches a test still in cycle 2: unpaced, the whole test can end before it arrives
    start_graph(node_process, "lockstep_pace:=20.0", self_test_params=[f"result_dir:={tmp_path}"])
    client = Client(ros_context, spin)
    handle = client.send(SelfTest.Goal())
    assert client.spin(lambda: client.feedback and client.feedback[-1].cycle == 2, 120.0)
    cancel = handle.cancel_goal_async()
    assert client.spin(cancel.done, 10.0)
    answer = client.result(handle)
    assert answer.status == GoalStatus.STATUS_CANCELED and "cancel" in answer.result.message
    assert not answer.result.success and len(answer.result.surge_speeds) == 1  # cycle 1's controller
    count = len(client.commands)

    def hovering():   # the newest ten commands hold hover (this client reads its queue behind a lockstep graph:
        # under load, what it takes first after the result can be steps commanded before the cancel)
        last = np.array([c.pitch for c in client.commands[-10:]])
        return np.allclose(last.mean(axis=0), HOVER, atol=np.radians(3.0))
    assert client.spin(lambda: len(client.commands) > count + 50 and hovering(), 60.0), \
        np.degrees([c.pitch for c in client.commands[-10:]])
    stamps = [c.header.stamp.sec + 1e-9 * c.header.stamp.nanosec for c in client.commands[count:]]
    assert np.all(np.diff(stamps) > 0)   # still answering, sample after sample
    later = len(client.commands)
    assert client.spin(lambda: len(client.commands) > later + 20, 20.0) and hovering()   # and it stays there


def test_failures_abort_with_the_reason(ros_context, node_process, spin, tmp_path):
    # a step that would pass the blade limit at 0.95 m/s (the mains hold 29 deg there)
    start_graph(node_process, self_test_params=[f"result_dir:={tmp_path}"])
    client = Client(ros_context, spin)
    goal = SelfTest.Goal()
    goal.operating_points = [0.0, 0.95]
    answer = client.result(client.send(goal))
    assert answer.status == GoalStatus.STATUS_ABORTED and "saturate" in answer.result.message
    assert list(answer.result.surge_speeds) == [0.0]  # the zero-speed result is still reported
    # a goal the settings refuse is rejected at once
    bad = SelfTest.Goal()
    bad.operating_points = [0.7]
    assert not client.send(bad).accepted


def test_a_dead_thruster_aborts_with_b0_singular(ros_context, node_process, spin, tmp_path):
    """Eq. 4.9 needs |B0| != 0: the port main switched off through the simulator's service
    (efficiency 0) leaves cycle 1 a model that is singular to the test's resolution."""
    start_graph(node_process, self_test_params=[f"result_dir:={tmp_path}"])
    client = Client(ros_context, spin)
    request = SetThrusterEfficiency.Request(efficiency=[0.0, 1.0, 1.0, 1.0])
    service = client.node.create_client(SetThrusterEfficiency, "/seapup/simulator/set_thruster_efficiency")
    answer = call_idempotent(client.executor, service, request)   # (its answer may be lost under load: asked again)
    assert answer.success, answer.message
    answer = client.result(client.send(SelfTest.Goal()))
    assert answer.status == GoalStatus.STATUS_ABORTED
    assert "singular" in answer.result.message and "main_port" in answer.result.message, answer.result.message
    assert not answer.result.success and list(answer.result.surge_speeds) == []  # no controller was designed
    assert not any(f.cycle == 2 and f.phase == "step" for f in client.feedback)  # failed at cycle 1's end


def test_no_velocity_data_aborts_the_goal(ros_context, node_process, spin, tmp_path):
    node_process(package="seapup_control", executable="self_test",
                 args=["--ros-args", "-p", "no_data_timeout:=1.0", "-p", f"result_dir:={tmp_path}"])
    client = Client(ros_context, spin)
    answer = client.result(client.send(SelfTest.Goal()), timeout=30.0)
    assert answer.status == GoalStatus.STATUS_ABORTED and "no velocity data" in answer.result.message
    assert client.commands == []  # nothing was commanded without data


class _AcceptedHandle:
    """What rclpy's action server hands its ``handle_accepted_callback``."""

    is_cancel_requested = False

    def __init__(self, request):
        self.request, self.executed, self.feedback = request, 0, []

    def execute(self):
        self.executed += 1

    def publish_feedback(self, feedback):
        self.feedback.append(feedback)


def test_a_goal_answers_the_held_sample_heard_before_it(ros_context):
    """Issue 43 (about one graph self-test start in six stalled, "no velocity data for 10.0 s"): a lockstep
    graph held at t_0 has delivered t_0's velocity before the goal is sent, and nothing asks for t_0 again
    once the graph is held. Accepting the goal (rclpy's accepted callback, run right after the goal response)
    must answer t_0 at once, with no later sample or /clock. Truth: one command, stamped t_0, before the
    execute callback has run."""
    from rclpy.action import GoalResponse
    from rclpy.serialization import deserialize_message, serialize_message
    from geometry_msgs.msg import TwistWithCovarianceStamped
    from seapup_common import frames
    from seapup_common.ros.graph import SubscriberGate
    from seapup_control.self_test_node import SelfTestNode
    node = SelfTestNode(context=ros_context)
    node.gate = SubscriberGate([], grace=0.0)     # the plant listens (tested elsewhere: the gate itself)
    commands = []
    node.publisher.publish = lambda data: commands.append(deserialize_message(data, BladePitch))
    sample = TwistWithCovarianceStamped()
    sample.header.frame_id = frames.FRAME_FRD
    node._on_velocity(serialize_message(sample))  # t_0, heard while no goal runs: nothing answers it
    assert commands == [] and node.policy.latest_ns == 0
    goal = SelfTest.Goal()
    assert node._accept(goal) == GoalResponse.ACCEPT
    handle = _AcceptedHandle(goal)
    node.server._handle_accepted_callback(handle)   # the server's own wiring
    assert handle.executed == 1 and len(commands) == 1
    assert (commands[0].header.stamp.sec, commands[0].header.stamp.nanosec) == (0, 0)
    assert np.all(np.isfinite(commands[0].pitch)) and len(handle.feedback) == 1
    node._on_velocity(serialize_message(sample))  # t_0 again (the simulator's repeat): answered once only
    assert len(commands) == 1
    node.destroy_node()
