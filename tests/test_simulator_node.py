"""The simulator node in its own process, driven from this test's process.

A real cross-process test: the node is started from its installed executable
(what ``ros2 run`` / ``./seapup run`` start) on the test's own domain; this
process publishes commands and subscribes to what the node publishes.
"""
import math
import os
from pathlib import Path

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from seapup_msgs.msg import BladePitch

LIMIT = math.radians(35.0)
QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
REPO = Path(__file__).resolve().parents[1]


def graph_has_node(node, name, namespace):
    return (name, namespace) in node.get_node_names_and_namespaces()


def make_probe(ros_context):
    node = rclpy.create_node("probe", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    return node, executor


def test_simulator_gates_commands_across_processes(ros_context, node_process, spin):
    sim = node_process(package="seapup_sim", executable="simulator",
                       args=["--ros-args", "-p", "heartbeat_period:=0.2"])
    node, executor = make_probe(ros_context)
    applied, diags = [], []
    node.create_subscription(BladePitch, "/seapup/thrusters/applied", applied.append, QOS)
    node.create_subscription(DiagnosticArray, "/diagnostics", diags.append, 10)
    pub = node.create_publisher(BladePitch, "/seapup/thrusters/command", QOS)
    assert spin(executor, lambda: pub.get_subscription_count() > 0 and len(diags) > 0, 15.0), sim.log_text()

    commands = [[0.1, 0.1, -0.2, -0.2], [1.0, -1.0, 0.0, 0.0], [math.nan, 0, 0, 0], [0, math.inf, 0, 0]]
    for i, pitch in enumerate(commands):
        msg = BladePitch()
        msg.header.stamp.sec = i
        msg.pitch = pitch
        pub.publish(msg)

    def counters():
        if not diags:
            return {}
        return {kv.key: int(kv.value) for kv in diags[-1].status[0].values}

    assert spin(executor, lambda: counters().get("rejected") == 2 and len(applied) == 2, 10.0), sim.log_text()
    assert counters() == {"accepted": 2, "rejected": 2, "saturated": 2}
    assert [m.header.stamp.sec for m in applied] == [0, 1]
    assert list(applied[0].pitch) == commands[0]
    assert list(applied[1].pitch) == [LIMIT, -LIMIT, 0.0, 0.0]
    assert all(math.isfinite(p) for m in applied for p in m.pitch)
    assert diags[-1].status[0].level == b"\x01"  # WARN after rejections
    assert "not finite" in diags[-1].status[0].message
    assert sim.running, "the node must survive bad input"
    executor.shutdown()
    node.destroy_node()


def test_seapup_run_starts_a_node_another_process_can_see(ros_context, node_process, ros_env, spin):
    env = dict(ros_env)
    for key in ("PYTHONPATH", "AMENT_PREFIX_PATH", "_ROS_WHEELS_BOOTSTRAP_COMPLETE"):
        env.pop(key, None)  # as a user's shell would be: ./seapup sets these up itself
    env["PATH"] = os.defpath
    sim = node_process([str(REPO / "seapup"), "run", "seapup_sim", "simulator"], env=env, name="seapup-run")
    node, executor = make_probe(ros_context)
    assert spin(executor, lambda: graph_has_node(node, "simulator", "/seapup"), 30.0), sim.log_text()
    assert sim.stop() == 0, sim.log_text()
    executor.shutdown()
    node.destroy_node()


def test_open_loop_drives_the_simulator_in_another_process(ros_context, node_process, spin):
    hover = [-0.058992, -0.058992, -0.228638, -0.228638]
    node_process(package="seapup_sim", executable="simulator")
    node_process(package="seapup_control", executable="open_loop",
                 args=["--ros-args", "-p", "sample_period:=0.05"])
    node, executor = make_probe(ros_context)
    applied = []
    node.create_subscription(BladePitch, "/seapup/thrusters/applied", applied.append, QOS)
    assert spin(executor, lambda: len(applied) >= 10, 20.0)
    assert all(list(m.pitch) == hover for m in applied)
    stamps = [m.header.stamp.sec * 1e9 + m.header.stamp.nanosec for m in applied]
    assert stamps == sorted(stamps)
    executor.shutdown()
    node.destroy_node()
