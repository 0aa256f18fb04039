"""A wall-clock limit that ends a lockstep wait is said on ``/diagnostics`` at once, and the SIL harness names it.

A lockstep graph flies the same trajectory on a quiet and a loaded machine only while every node waits for what
it waits for; a node that goes on without it (a limit in wall seconds ran out) makes the run the machine's.
Each such node counts it (``seapup_common.lockstep.ENDED_WAITS``) and publishes its status at once, so a run's
harness can say which node went on without what (``SilGraph.ended_waits``). Truth: the test decides the order and
the absence of every input, and the node's published status is read back.
"""
import time

import pytest
from rclpy.serialization import serialize_message

from seapup_common import frames
from seapup_common.ros.messages import ns_to_stamp

T_NS = 200_000_000


def _stamped(msg, k):
    msg.header.stamp, msg.header.frame_id = ns_to_stamp(T_NS * k), frames.FRAME_FRD
    return msg


def _velocity(k):
    from geometry_msgs.msg import TwistWithCovarianceStamped
    msg = _stamped(TwistWithCovarianceStamped(), k)
    msg.twist.twist.linear.x = 0.1
    return serialize_message(msg)


def _reference(k):
    from geometry_msgs.msg import TwistStamped
    msg = _stamped(TwistStamped(), k)
    msg.twist.linear.x = 0.2
    return serialize_message(msg)


def _applied(k):
    from seapup_msgs.msg import BladePitch
    msg = _stamped(BladePitch(), k)
    msg.pitch = [0.0, 0.0, 0.0, 0.0]
    return serialize_message(msg)


def _clock(k):
    from rosgraph_msgs.msg import Clock
    return serialize_message(Clock(clock=ns_to_stamp(T_NS * k)))


@pytest.mark.graph
def test_a_velocity_controller_says_at_once_that_a_reference_wait_ran_out(ros_context, spin):
    """References stream one per sample; sample 5's never comes. The controller answers samples 1-4 at once,
    sample 5 after ``reference_wait`` wall seconds with the reference in force, counts it late and says so on
    ``/diagnostics`` with that very answer (its paced status would come much later, or never in a short run)."""
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.lifecycle import TransitionCallbackReturn
    from rclpy.parameter import Parameter
    from seapup_bringup.graph.readiness import ended_waits
    from seapup_control.velocity_controller_node import VelocityControllerNode
    node = VelocityControllerNode(context=ros_context, parameter_overrides=[
        Parameter("controller_type", value="hold"), Parameter("sample_period", value=0.2),
        Parameter("lockstep", value=True), Parameter("reference_every_sample", value=True),
        Parameter("reference_wait", value=0.3), Parameter("diagnostics_every", value=1000)])
    assert node.trigger_configure() == TransitionCallbackReturn.SUCCESS
    assert node.trigger_activate() == TransitionCallbackReturn.SUCCESS
    commands, said = [], []
    node.publisher.publish = commands.append
    node.diagnostics.publish = said.append
    for k in range(1, 5):
        node._on_reference(_reference(k))
        node._on_applied(_applied(k))
        node._on_velocity(_velocity(k))
        node._on_clock(_clock(k))
    assert len(commands) == 4 and node.counts["late_references"] == 0
    assert ended_waits(said) == {}
    node._on_applied(_applied(5))
    node._on_velocity(_velocity(5))            # its reference never comes
    node._on_clock(_clock(5))
    assert len(commands) == 4                  # it waits
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    start = time.monotonic()
    assert spin(executor, lambda: len(commands) == 5, 10.0)
    waited = time.monotonic() - start
    executor.shutdown()
    assert 0.25 < waited < 5.0 and node.counts["late_references"] == 1, (waited, node.counts)
    assert ended_waits(said) == {"seapup/" + node.get_name(): {"late_references": 1}}, said
    node.destroy_node()


@pytest.mark.graph
def test_a_velocity_controller_says_at_once_that_it_has_the_first_reference(ros_context):
    """Issue 43: a harness holding the lockstep graph resumes it once the active velocity controller has the
    position controller's first reference (``SilGraph`` waits for this status): the configured node says
    ``reference_stream_start`` on ``/diagnostics`` when it hears its first stamped reference, not again after."""
    from rclpy.lifecycle import TransitionCallbackReturn
    from rclpy.parameter import Parameter
    from seapup_bringup.graph.readiness import stream_started
    from seapup_control.velocity_controller_node import VelocityControllerNode
    node = VelocityControllerNode(context=ros_context, parameter_overrides=[
        Parameter("controller_type", value="hold"), Parameter("sample_period", value=0.2),
        Parameter("lockstep", value=True), Parameter("reference_every_sample", value=True),
        Parameter("diagnostics_every", value=1000)])
    assert node.trigger_configure() == TransitionCallbackReturn.SUCCESS
    said = []
    node.diagnostics.publish = said.append
    name = "seapup/" + node.get_name()
    node._on_clock(_clock(1))
    assert not stream_started(said, name, 0.0, key="reference_stream_start")
    node._on_reference(_reference(3))           # stamped t_3, heard while the graph is held at t_1
    assert len(said) == 1 and stream_started(said, name, 3 * T_NS * 1e-9, key="reference_stream_start")
    assert not stream_started(said, name, 4 * T_NS * 1e-9, key="reference_stream_start")
    node._on_reference(_reference(4))
    assert len(said) == 1                       # once: the stream's start
    node.destroy_node()
