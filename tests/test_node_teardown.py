"""A node destroys its action servers and clients with itself.

rclpy's ``Node.destroy_node`` leaves waitables to the garbage collector, which finalised an action server
after its node's clock and crashed the process (SIGSEGV in ``rcl_clock_remove_jump_callback``; 1 in 4 runs
of the task controller's tests, and a CI run). Truth: the node's waitables before and after.
"""
import pytest
from rclpy.action import ActionClient, ActionServer
from rclpy.exceptions import InvalidHandle
from rclpy.node import Node
from seapup_msgs.action import SelfTest

from seapup_common.ros.node import destroy_actions


def _actions(node):
    return [w for w in node.waitables if isinstance(w, (ActionServer, ActionClient))]


@pytest.mark.graph
@pytest.mark.parametrize("module, cls, servers", [("seapup_control.task_controller_node", "TaskControllerNode", 3),
                                                  ("seapup_control.self_test_node", "SelfTestNode", 1)])
def test_a_node_with_action_servers_destroys_them(ros_context, module, cls, servers):
    import importlib
    node = getattr(importlib.import_module(module), cls)(context=ros_context)
    made = _actions(node)
    assert len(made) == servers and all(isinstance(s, ActionServer) for s in made)
    for server in made:
        with server._handle:  # live
            pass
    node.destroy_node()
    assert _actions(node) == []
    for server in made:  # the handle is gone, not only unlisted
        with pytest.raises(InvalidHandle):
            with server._handle:
                pass


@pytest.mark.graph
def test_destroy_actions_takes_servers_and_clients_and_leaves_the_rest(ros_context):
    node = Node("teardown_probe", context=ros_context)
    ActionServer(node, SelfTest, "self_test", execute_callback=lambda goal: None)
    ActionClient(node, SelfTest, "self_test")
    publisher = node.create_publisher(SelfTest.Feedback, "x", 1)
    assert len(_actions(node)) == 2
    destroy_actions(node)
    assert _actions(node) == [] and publisher in node.publishers
    node.destroy_node()


class _Queued:
    """An executor that is not rclpy's SingleThreadedExecutor: each step runs the next queued callback -- a
    message received before the stop, a timer's that takes none -- and, once they are done, a message of a
    graph that keeps publishing (``live``: received now), as :func:`seapup_common.ros.node._spin_step` drives it."""

    def __init__(self, node, queue, live=False):
        self.node, self.queue, self.live, self.backlog_taken = node, list(queue), live, 0

    def spin_until_future_complete(self, until, timeout_sec):
        import time
        if self.queue:
            if self.queue.pop(0) == "message":
                self.node.received += 1
                self.node.last_received_ns = 1   # long before the stop
                self.backlog_taken += 1
        elif self.live:
            self.node.received += 1
            self.node.last_received_ns = time.time_ns()
            time.sleep(0.001)


def test_a_draining_recorder_takes_every_queued_message_and_no_more():
    """A stopping recorder drains what it received before the stop (run_node's ``_drain``): a step that runs
    a timer's callback (the flush) takes no message and must not end the drain while messages still wait --
    under load a bag lost the last 12 s of a self-test that way -- and a graph that keeps publishing must not
    keep it draining to its budget (a recorder SIGKILLed at its stop): it ends ``idle`` seconds after the
    last message received before the stop, or with nothing queued."""
    import time
    from types import SimpleNamespace

    from seapup_common.ros.node import _drain
    queue = ["message"] * 3 + ["timer"] + ["message"] * 50 + ["timer", "timer"] + ["message"] * 7
    for live in (False, True):
        node = SimpleNamespace(received=0, last_received_ns=0)
        executor = _Queued(node, queue, live)
        t0 = time.monotonic()
        _drain(executor, node, budget=5.0, idle=0.05)
        assert executor.backlog_taken == 60 and time.monotonic() - t0 < 1.0, (live, executor.backlog_taken)
    node = SimpleNamespace(received=0, last_received_ns=0)
    t0 = time.monotonic()
    _drain(_Queued(node, []), node, budget=5.0, idle=0.05)
    assert node.received == 0 and time.monotonic() - t0 < 1.0
