"""The executor a node runs under (``run_node``'s read-only parameter ``executor``, default ``$SEAPUP_EXECUTOR``).

Truth: the node itself -- a probe node started by ``run_node`` in a child process reports, from one of its own
timer callbacks, the class of the executor that called it (``Node.executor``, which rclpy sets when an
executor takes the node). Each choice, given by parameter or by environment, must be the one that runs the
callbacks, and a node under each must end with exit code 0 soon after SIGINT or SIGTERM (``run_node`` checks
its stop flag between ``spin_once`` calls of at most 0.1 s; the events executor's ``spin()`` never comes back to
Python, which is how it once hung here). A value that is not an executor stops the start, naming the choices.
"""
import os
import select
import signal
import subprocess
import sys
import time

import pytest

from seapup_common.processes import child_options

#: A node whose timer prints the class of the executor running it, started the way every seapup node is.
PROBE = """
import sys
import rclpy
from seapup_common.ros.node import run_node

def make():
    node = rclpy.create_node("executor_probe")
    def tick():
        executor = node.executor
        print(f"EXECUTOR {type(executor).__module__}.{type(executor).__name__} "
              f"{node.get_parameter('executor').value}", flush=True)
    node.create_timer(0.05, tick)
    return node

sys.exit(run_node(make))
"""
#: The classes behind each choice (the events executor is a pybind11 class made by a factory function).
CLASSES = {"single": "rclpy.executors.SingleThreadedExecutor", "events": "rclpy._rclpy_pybind11.EventsExecutor"}
#: How soon a node must be gone after a stop signal [s]: the 0.1 s spin step, destruction and rclpy's shutdown,
#: on a loaded 2-core machine (the watchdog's budget is 10 s; this is far inside it).
PROMPT = 3.0


def _start(env: dict, executor_param: str | None = None) -> subprocess.Popen:
    command = [sys.executable, "-c", PROBE]
    if executor_param is not None:
        command += ["--ros-args", "-p", f"executor:={executor_param}"]
    return subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            stdin=subprocess.DEVNULL, **child_options())


def _first_report(popen: subprocess.Popen, timeout: float = 30.0) -> str:
    """The first ``EXECUTOR ...`` line the probe prints (everything it printed, if it ends or times out)."""
    deadline, seen = time.monotonic() + timeout, b""
    fd = popen.stdout.fileno()
    while time.monotonic() < deadline:
        ready, _, _ = select.select([fd], [], [], 0.1)
        if ready:
            chunk = os.read(fd, 4096)
            if not chunk:
                break
            seen += chunk
            for line in seen.decode(errors="replace").splitlines():
                if line.startswith("EXECUTOR ") and seen.endswith(b"\n"):
                    return line
    return seen.decode(errors="replace")


def _stop(popen: subprocess.Popen, sig: int) -> tuple[int, float]:
    """Send ``sig`` to the probe's process group; its exit code and how long it took [s]."""
    t0 = time.monotonic()
    os.killpg(popen.pid, sig)
    try:
        code = popen.wait(timeout=15.0)
    finally:
        if popen.poll() is None:
            os.killpg(popen.pid, signal.SIGKILL)
            popen.wait()
    return code, time.monotonic() - t0


@pytest.mark.graph
@pytest.mark.parametrize("choice", ["single", "events"])
@pytest.mark.parametrize("given_by", ["parameter", "environment"])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_the_chosen_executor_runs_the_node_and_it_stops_promptly(ros_env, choice, given_by, sig):
    env = dict(ros_env)
    other = "events" if choice == "single" else "single"
    if given_by == "parameter":   # the parameter wins over the graph's environment
        env["SEAPUP_EXECUTOR"] = other
        popen = _start(env, choice)
    else:
        env["SEAPUP_EXECUTOR"] = choice
        popen = _start(env)
    report = _first_report(popen)
    assert report == f"EXECUTOR {CLASSES[choice]} {choice}", report
    code, took = _stop(popen, sig)
    assert code == 0 and took < PROMPT, (code, took, popen.stdout.read().decode(errors="replace")[-2000:])


@pytest.mark.graph
def test_the_default_is_the_documented_one(ros_env):
    from seapup_common.ros.node import DEFAULT_EXECUTOR
    env = dict(ros_env)
    env.pop("SEAPUP_EXECUTOR", None)
    popen = _start(env)
    report = _first_report(popen)
    assert report == f"EXECUTOR {CLASSES[DEFAULT_EXECUTOR]} {DEFAULT_EXECUTOR}", report
    assert _stop(popen, signal.SIGTERM)[0] == 0


@pytest.mark.graph
@pytest.mark.parametrize("given_by", ["parameter", "environment"])
def test_an_unknown_executor_stops_the_start_naming_the_choices(ros_env, given_by):
    env = dict(ros_env)
    if given_by == "parameter":
        popen = _start(env, "multi")
    else:
        env["SEAPUP_EXECUTOR"] = "multi"
        popen = _start(env)
    out = popen.communicate(timeout=30.0)[0].decode(errors="replace")
    assert popen.returncode == 1, out
    assert "'multi'" in out and "single, events" in out and "EXECUTOR " not in out, out


@pytest.mark.graph
def test_the_executor_cannot_be_changed_at_run_time(ros_context):
    import rclpy
    from rclpy.parameter import Parameter

    from seapup_common.ros.node import declare_executor
    node = rclpy.create_node("executor_read_only", context=ros_context)
    assert declare_executor(node) in ("single", "events")
    result = node.set_parameters([Parameter("executor", Parameter.Type.STRING, "events")])[0]
    assert not result.successful and "read-only" in result.reason


@pytest.mark.graph
def test_make_executor_builds_each_choice_and_refuses_others(ros_context):
    from seapup_common.ros.node import EXECUTORS, UnknownExecutorError, make_executor
    for choice in EXECUTORS:
        executor = make_executor(choice, context=ros_context)
        assert f"{type(executor).__module__}.{type(executor).__name__}" == CLASSES[choice]
        executor.shutdown(timeout_sec=1.0)
    with pytest.raises(UnknownExecutorError, match="single, events"):
        make_executor("multi", context=ros_context)


@pytest.mark.graph
def test_a_node_class_names_its_own_default_and_the_environment_still_wins(ros_context, monkeypatch):
    """The per-sample nodes (the demo's whole hierarchy: simulator, navigator, velocity controllers, manager,
    position and task controllers, self-test; ``open_loop``) run under the events executor by their class's
    ``EXECUTOR``; every other node (the recorder, the identifier, the live view, ...) under
    :data:`DEFAULT_EXECUTOR`; ``$SEAPUP_EXECUTOR`` overrides both (an A/B of a whole graph)."""
    import rclpy
    from rclpy.node import Node

    from seapup_common.ros.node import DEFAULT_EXECUTOR, declare_executor
    from seapup_control.controller_manager_node import ControllerManagerNode
    from seapup_control.navigator_node import NavigatorNode
    from seapup_control.open_loop_node import OpenLoopNode
    from seapup_control.position_controller_node import PositionControllerNode
    from seapup_control.self_test_node import SelfTestNode
    from seapup_control.task_controller_node import TaskControllerNode
    from seapup_control.velocity_controller_node import VelocityControllerNode
    from seapup_sim.simulator_node import SimulatorNode

    class Fast(Node):
        EXECUTOR = "events"

    monkeypatch.delenv("SEAPUP_EXECUTOR", raising=False)
    assert DEFAULT_EXECUTOR == "single"
    per_sample = [SimulatorNode, NavigatorNode, VelocityControllerNode, OpenLoopNode, ControllerManagerNode,
                  PositionControllerNode, TaskControllerNode, SelfTestNode]
    assert {cls.EXECUTOR for cls in per_sample} == {"events"}
    nodes = [Fast("fast", context=ros_context), rclpy.create_node("plain", context=ros_context)]
    assert [declare_executor(n) for n in nodes] == ["events", "single"]
    monkeypatch.setenv("SEAPUP_EXECUTOR", "single")
    assert declare_executor(Fast("fast_single", context=ros_context)) == "single"
    for node in nodes:
        node.destroy_node()


@pytest.mark.graph
def test_a_node_that_takes_message_info_runs_on_single_and_refuses_events(ros_context, monkeypatch, tmp_path):
    """rclpy 7.1's EventsExecutor cannot deliver the message info (next test): a node whose subscriptions take it
    -- the recorder, by its class's ``MESSAGE_INFO``, or any node with such a subscription -- runs on ``single``
    even when ``$SEAPUP_EXECUTOR`` asks the whole graph for ``events``, and ``-p executor:=events`` given to it
    is refused with the reason, before it spins."""
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from std_msgs.msg import String

    from seapup_common.recorder_node import RecorderNode
    from seapup_common.ros.node import declare_executor, takes_message_info

    monkeypatch.setenv("SEAPUP_EXECUTOR", "events")
    recorder = RecorderNode(context=ros_context, parameter_overrides=[
        Parameter("topics", value=["/chatter:std_msgs/msg/String"]), Parameter("bag_path", value=str(tmp_path / "bag"))])
    assert takes_message_info(recorder) and declare_executor(recorder) == "single"
    plain = Node("plain_events", context=ros_context)
    assert not takes_message_info(plain) and declare_executor(plain) == "events"   # the environment's choice
    with_info = Node("with_info", context=ros_context)
    with_info.create_subscription(String, "chatter", lambda msg, info: None, 10)
    assert takes_message_info(with_info) and declare_executor(with_info) == "single"
    asked = Node("asked_events", context=ros_context,
                 parameter_overrides=[Parameter("executor", value="events")])
    asked.create_subscription(String, "chatter", lambda msg, info: None, 10)
    with pytest.raises(ValueError, match="executor events refused: .*message info"):
        declare_executor(asked)


@pytest.mark.graph
def test_rclpy_events_executor_still_cannot_deliver_the_message_info(ros_context):
    """Why the recorder stays on ``single`` (``DEFAULT_EXECUTOR``'s note): a subscription whose callback takes the
    message info kills rclpy 7.1.6's EventsExecutor at its first message. When an rclpy upgrade mends it, this
    fails: then the recorder can join the events executor (its ~0.8 ms per sample in the hierarchy bench)."""
    from rclpy.experimental import EventsExecutor
    from rclpy.node import Node
    from std_msgs.msg import String

    node = Node("info_canary", context=ros_context)
    heard = []
    node.create_subscription(String, "canary", lambda msg, info: heard.append(info), 10)
    publisher = node.create_publisher(String, "canary", 10)
    executor = EventsExecutor(context=ros_context)
    executor.add_node(node)
    failure = None
    try:
        deadline = time.monotonic() + 10.0
        while not heard and failure is None and time.monotonic() < deadline:
            publisher.publish(String(data="x"))
            try:
                executor.spin_once(timeout_sec=0.05)
            except SystemError as exc:
                failure = exc
    finally:
        executor.shutdown(timeout_sec=1.0)
    assert failure is not None and "null argument" in str(failure), (
        f"rclpy's EventsExecutor delivered the message info ({heard[:1]}): the recorder may now run under it")
