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
