"""The simulator's ``simulation_interfaces`` control surface, driven as a Gazebo user would.

A lockstep simulator in its own process, started held; this test's process is the graph's one answerer
(it commands the hover setting stamped with every ``/clock`` sample it hears, as a controller would) and
records ``/clock``, the commands and the truth. Every check is on messages (the samples and commands on the
topics, the answers of the services), bounded by timeouts on simulated work, never by sleeps. The entity
state conversions are checked against the simulator's own ``/odometry`` (ENU) conversion.
"""
from __future__ import annotations

import math
import subprocess

import numpy as np
import pytest
import rclpy
from nav_msgs.msg import Odometry
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from seapup_msgs.msg import BladePitch
from simulation_interfaces.action import SimulateSteps
from simulation_interfaces.msg import Result, SimulationState, SimulatorFeatures
from simulation_interfaces.srv import (GetEntities, GetEntityState, GetSimulationState, GetSimulatorFeatures,
                                       ResetSimulation, SetEntityState, SetSimulationState, StepSimulation)

from seapup_common import topics
from seapup_common.ros import messages as conv
from seapup_sim.simulator_services import entity_state_enu, state_from_enu

pytestmark = pytest.mark.graph

QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
T_NS = 200_000_000
START_DEPTH = 5.0
NAME = {key: name for key, (name, _) in topics.SIMULATION_CONTROL.items()}


def test_entity_state_conversions_invert_each_other_and_match_the_odometry():
    rng = np.random.default_rng(7)
    for _ in range(100):
        x = np.concatenate([rng.normal(size=3) * 5, rng.uniform(-1.2, 1.2, 2), rng.uniform(-3, 3, 1),
                            rng.normal(size=6)])
        e = entity_state_enu(x, np.zeros(3))
        assert np.allclose(state_from_enu(e["position"], e["orientation"], e["linear"], e["angular"]), x, atol=1e-9)
        odom = conv.odometry_enu(x, 0)     # the simulator's /odometry: ENU pose, FLU body twist
        q = odom.pose.pose.orientation
        assert np.allclose(e["orientation"], [q.x, q.y, q.z, q.w])
        assert np.allclose(e["position"], [odom.pose.pose.position.x, odom.pose.pose.position.y,
                                           odom.pose.pose.position.z])
        assert math.isclose(np.linalg.norm(e["linear"]), np.linalg.norm(x[6:9]))   # a rotation keeps speed


class Gazebo:
    """The test's node: the graph's answerer, and a user's client of the control surface."""

    def __init__(self, context, spin):
        self.node = rclpy.create_node("user", context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self._spin = spin
        self.clock, self.commands, self.truth = [], [], []
        self.answering = True
        self.pub = self.node.create_publisher(BladePitch, topics.COMMAND, QOS)
        self.node.create_subscription(Clock, topics.CLOCK, self._on_clock, QOS)
        self.node.create_subscription(BladePitch, topics.COMMAND, self.commands.append, QOS)
        self.node.create_subscription(Odometry, topics.TRUTH_ODOMETRY, self.truth.append, QOS)
        self.clients = {}

    def _on_clock(self, msg):
        t = conv.stamp_to_ns(msg.clock)
        self.clock.append(t)
        if self.answering and t not in self.answered:
            self.answered.add(t)
            msg = BladePitch(pitch=HOVER)
            msg.header.stamp = conv.ns_to_stamp(t)
            self.pub.publish(msg)

    answered: set = set()

    def spin(self, predicate, timeout=20.0):
        return self._spin(self.executor, predicate, timeout)

    def call(self, key, kind, request, timeout=30.0):
        client = self.clients.get(key) or self.clients.setdefault(key, self.node.create_client(kind, NAME[key]))
        assert self.spin(client.service_is_ready, 20.0), f"{NAME[key]} never came"
        future = client.call_async(request)
        assert self.spin(future.done, timeout), f"{NAME[key]} did not answer"
        return future.result()

    def state(self) -> int:
        return self.call("get_simulation_state", GetSimulationState, GetSimulationState.Request()).state.state

    def set_state(self, state: int) -> Result:
        return self.call("set_simulation_state", SetSimulationState,
                         SetSimulationState.Request(state=SimulationState(state=state))).result

    def step(self, n: int) -> Result:
        return self.call("step_simulation", StepSimulation, StepSimulation.Request(steps=n)).result

    def entity(self, name="seapup"):
        return self.call("get_entity_state", GetEntityState, GetEntityState.Request(entity=name))

    def commanded(self) -> list[int]:
        return [conv.stamp_to_ns(m.header.stamp) for m in self.commands]


def _hover() -> list[float]:
    """The hover setting (eq. 5.2) of the baseline vehicle [rad]: what the answerer commands."""
    from seapup_sim.analysis import hover_blade_pitch
    from seapup_sim.vehicle import VehicleModel
    from seapup_sim.vehicle_config import load_vehicle_config
    return [float(v) for v in hover_blade_pitch(VehicleModel(load_vehicle_config("baseline")))]


HOVER: list[float] = []


@pytest.fixture
def graph(ros_context, node_process, spin):
    HOVER[:] = HOVER or _hover()
    user = Gazebo(ros_context, spin)
    user.answered = set()
    node_process(package="seapup_sim", executable="simulator", args=[
        "--ros-args", "-p", "mode:=lockstep", "-p", "start_held:=true", "-p", f"start_depth:={START_DEPTH}",
        "-p", "lockstep_timeout:=5.0", "-p", "wait_for_subscribers:=['/clock']"])
    assert user.spin(lambda: user.clock and user.commanded()[-1:] == [0], 30.0), "t_0 never came or was answered"
    yield user
    user.executor.shutdown()


def held_at(user, t_ns):
    """The graph is held at t_ns with its command in (the user answered it)."""
    return user.spin(lambda: user.clock[-1:] == [t_ns] and t_ns in user.commanded(), 20.0)


def test_features_state_and_steps(graph):
    user = graph
    features = user.call("get_simulator_features", GetSimulatorFeatures, GetSimulatorFeatures.Request()).features
    F = SimulatorFeatures
    assert set(features.features) >= {F.SIMULATION_STATE_PAUSE, F.STEP_SIMULATION_ACTION, F.ENTITY_STATE_SETTING}
    assert F.SPAWNING not in features.features
    assert user.state() == SimulationState.STATE_PAUSED            # start_held
    # a step of 3: /clock advances exactly three periods, each stepped sample and the held one commanded
    result = user.step(3)
    assert result.result == Result.RESULT_OK, result.error_message
    assert user.clock[-1] == 3 * T_NS and sorted(set(user.clock)) == [0, T_NS, 2 * T_NS, 3 * T_NS]
    assert 3 * T_NS in user.commanded()                             # answered before the service answered
    user.spin(lambda: False, 0.5)                                   # held: nothing more comes
    assert user.clock[-1] == 3 * T_NS and user.state() == SimulationState.STATE_PAUSED
    assert user.step(1).result == Result.RESULT_OK and user.clock[-1] == 4 * T_NS
    # play, then pause: a step while playing is refused and changes nothing
    assert user.set_state(SimulationState.STATE_PLAYING).result == Result.RESULT_OK
    assert user.spin(lambda: user.clock[-1] >= 10 * T_NS, 20.0)
    refused = user.step(1)
    assert refused.result == Result.RESULT_OPERATION_FAILED and "pause" in refused.error_message
    again = user.set_state(SimulationState.STATE_PLAYING)
    assert again.result == SetSimulationState.Response.ALREADY_IN_TARGET_STATE
    assert user.set_state(SimulationState.STATE_PAUSED).result == Result.RESULT_OK
    assert user.state() == SimulationState.STATE_PAUSED
    at = user.clock[-1]
    assert user.step(1).result == Result.RESULT_OK and user.clock[-1] == at + T_NS
    # stopped: back at t_0, held; pausing a stopped simulation is an incorrect transition
    assert user.set_state(SimulationState.STATE_STOPPED).result == Result.RESULT_OK
    assert user.spin(lambda: user.clock[-1] == 0, 10.0) and user.state() == SimulationState.STATE_STOPPED
    refused = user.set_state(SimulationState.STATE_PAUSED)
    assert refused.result == SetSimulationState.Response.INCORRECT_TRANSITION and refused.error_message


def test_reset_and_entity_state(graph):
    user = graph
    start = user.entity()
    assert start.result.result == Result.RESULT_OK and start.state.header.frame_id == "odom"
    assert start.state.pose.position.z == pytest.approx(-START_DEPTH)           # ENU: depth down is -z
    names = user.call("get_entities", GetEntities, GetEntities.Request()).entities
    assert list(names) == ["seapup"]
    request = GetEntities.Request()
    request.filters.filter = "^rov"
    assert list(user.call("get_entities", GetEntities, request).entities) == []
    assert user.entity("nobody").result.result == Result.RESULT_NOT_FOUND
    # move the vehicle: 2 m east, 1 m north, yawed; GetEntityState and the next truth sample show it
    target = SetEntityState.Request(entity="seapup")
    target.state.header.frame_id = "odom"
    p = target.state.pose
    p.position.x, p.position.y, p.position.z = 2.0, 1.0, -4.0
    p.orientation.z, p.orientation.w = math.sin(0.25), math.cos(0.25)
    answer = user.call("set_entity_state", SetEntityState, target).result
    assert answer.result == Result.RESULT_OK, answer.error_message
    now = user.entity().state.pose
    assert (now.position.x, now.position.y, now.position.z) == pytest.approx((2.0, 1.0, -4.0))
    assert now.orientation.z == pytest.approx(math.sin(0.25))
    t = user.clock[-1]
    assert user.step(1).result == Result.RESULT_OK
    assert user.spin(lambda: any(conv.stamp_to_ns(m.header.stamp) == t + T_NS for m in user.truth), 10.0)
    truth = next(m for m in user.truth if conv.stamp_to_ns(m.header.stamp) == t + T_NS)   # NED
    assert truth.pose.pose.position.x == pytest.approx(1.0, abs=0.05)     # north, hovering for one period
    assert truth.pose.pose.position.y == pytest.approx(2.0, abs=0.05)
    # refusals: a bad quaternion, NaN, an unknown entity, a position beyond the limits; nothing changes
    for change, code in ((lambda s: setattr(s.pose.orientation, "w", 3.0), SetEntityState.Response.INVALID_POSE),
                         (lambda s: setattr(s.pose.position, "x", math.nan), SetEntityState.Response.INVALID_POSE),
                         (lambda s: setattr(s.twist.linear, "x", math.nan), Result.RESULT_OPERATION_FAILED),
                         (lambda s: setattr(s.pose.position, "z", 1e6), SetEntityState.Response.INVALID_POSE)):
        bad = SetEntityState.Request(entity="seapup")
        bad.state.pose.orientation.w = 1.0
        change(bad.state)
        refused = user.call("set_entity_state", SetEntityState, bad).result
        assert refused.result == code and refused.error_message and "\n" not in refused.error_message
    assert user.call("set_entity_state", SetEntityState,
                     SetEntityState.Request(entity="rov")).result.result == Result.RESULT_NOT_FOUND
    before = user.entity().state.pose.position
    assert user.entity().state.pose.position == before
    # reset: the start state and t = 0
    answer = user.call("reset_simulation", ResetSimulation, ResetSimulation.Request(scope=ResetSimulation.Request.SCOPE_ALL))
    assert answer.result.result == Result.RESULT_OK
    assert user.spin(lambda: user.clock[-1] == 0, 10.0)
    again = user.entity().state
    assert (again.pose.position.x, again.pose.position.y, again.pose.position.z) == pytest.approx((0, 0, -START_DEPTH))
    assert conv.stamp_to_ns(again.header.stamp) == 0
    assert user.call("reset_simulation", ResetSimulation,
                     ResetSimulation.Request(scope=ResetSimulation.Request.SCOPE_SPAWNED)).result.result == \
        Result.RESULT_FEATURE_UNSUPPORTED


def test_simulate_steps_feedback_and_cancel(graph):
    user = graph
    client = ActionClient(user.node, SimulateSteps, NAME["simulate_steps"])
    assert user.spin(client.server_is_ready, 20.0)
    feedback = []
    sent = client.send_goal_async(SimulateSteps.Goal(steps=4), feedback_callback=lambda f: feedback.append(
        (f.feedback.completed_steps, f.feedback.remaining_steps)))
    assert user.spin(sent.done, 10.0) and sent.result().accepted
    done = sent.result().get_result_async()
    assert user.spin(done.done, 30.0)
    assert done.result().result.result.result == Result.RESULT_OK
    assert feedback == [(1, 3), (2, 2), (3, 1), (4, 0)] and user.clock[-1] == 4 * T_NS
    # cancel: the user stops answering, so the step waits at its first sample; cancel holds it there
    user.answering = False
    sent = client.send_goal_async(SimulateSteps.Goal(steps=10))
    assert user.spin(sent.done, 10.0)
    goal = sent.result()
    assert user.spin(lambda: user.clock[-1] == 5 * T_NS, 10.0)
    cancel = goal.cancel_goal_async()
    assert user.spin(cancel.done, 10.0) and cancel.result().goals_canceling
    done = goal.get_result_async()
    assert user.spin(done.done, 10.0) and done.result().status == 5     # CANCELED
    user.spin(lambda: False, 0.5)
    assert user.clock[-1] == 5 * T_NS and user.state() == SimulationState.STATE_PAUSED


def test_the_ros2cli_substitute_steps_a_graph(graph, ros_env):
    user = graph
    import os
    from pathlib import Path
    seapup = str(Path(__file__).resolve().parents[1] / "seapup")
    env = {**os.environ, **ros_env}
    call = subprocess.Popen([seapup, "service", "call", NAME["step_simulation"], "simulation_interfaces/srv/StepSimulation",
                             "{steps: 3}"], env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert user.spin(lambda: call.poll() is not None, 60.0)
    out = call.stdout.read()
    assert call.returncode == 0 and "result: 1" in out, out   # RESULT_OK
    assert user.clock[-1] == 3 * T_NS
    send = subprocess.Popen([seapup, "action", "send_goal", NAME["simulate_steps"],
                             "simulation_interfaces/action/SimulateSteps", "{steps: 5}", "--feedback"],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert user.spin(lambda: send.poll() is not None, 60.0)
    out = send.stdout.read()
    assert send.returncode == 0 and "remaining_steps" in out and "SUCCEEDED" in out.upper(), out
    assert user.clock[-1] == 8 * T_NS
