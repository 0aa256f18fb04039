"""The task controller follows the seabed at the estimate t_k with the altimeter's reading of t_k, even when
that reading arrives after the estimate (a loaded machine), so its setpoints do not depend on delivery order.

Truth: the same readings and estimates delivered altitude-first (as on a quiet machine); the node's
callbacks are called directly in a chosen order, so the test decides the interleaving. The simulator sends
an altitude every sample, +inf (REP-117, no echo) when the altimeter hears nothing: such a sample does not
wait either.
"""
import math
import time

import numpy as np
import pytest

from seapup_common.contract import Measurement, NavigationEstimate, Reading
from seapup_common.ros import messages as conv

T = 0.2


def _estimate(k):
    t = k * T
    return conv.estimate_to_odometry(NavigationEstimate(t, np.array([0.05 * k, 0.0, 30.0 + 0.01 * k]),
                                                        0.01 * np.eye(3), np.zeros(3), np.zeros(3)), round(t * 1e9))


def _altitude(k, valid=True):
    """A reading that changes from sample to sample (the seabed under a moving vehicle, with noise)."""
    reading = Measurement.build(k * T, altitude=10.0 + 0.4 * math.sin(1.7 * k)).altitude if valid else Reading.invalid()
    return conv.altitude_to_msg(reading, round(k * T * 1e9), field_of_view=0.17, min_range=0.3, max_range=200.0)


class _Handle:
    is_cancel_requested = False

    def publish_feedback(self, feedback):
        pass


def _node(ros_context, altitude_wait):
    from rclpy.parameter import Parameter
    from seapup_control.task_controller_node import TaskControllerNode, _Running
    from seapup_control.tasks import FollowSeabed
    node = TaskControllerNode(context=ros_context)
    node.set_parameters([Parameter("altitude_wait", value=altitude_wait)])
    setpoints = []
    node.setpoints.publish = lambda msg: setpoints.append(
        (conv.stamp_to_ns(msg.header.stamp), msg.pose.position.x, msg.pose.position.z))
    node._on_altitude(_altitude(0))
    start = conv.estimate_from_odometry(_estimate(0))
    task = FollowSeabed(node.limits, start, conv.altitude_from_msg(_altitude(0)), height=8.0, yaw=0.0, speed=0.2,
                        duration=100.0)
    node.running = _Running(task, _Handle())
    return node, setpoints


def _run(ros_context, deliveries, altitude_wait=2.0):
    node, setpoints = _node(ros_context, altitude_wait)
    for kind, msg in deliveries:
        (node._on_altitude if kind == "altitude" else node._on_estimate)(msg)
    late = node.counts["late_altitudes"]
    node.destroy_node()
    return setpoints, late


def _readings(k):
    return _altitude(k, valid=k % 7 != 3)  # now and then no echo: +inf on the wire


@pytest.mark.graph
def test_seabed_following_waits_for_its_samples_altitude(ros_context):
    in_order = [d for k in range(1, 30) for d in (("altitude", _readings(k)), ("estimate", _estimate(k)))]
    behind = [d for k in range(1, 30) for d in (("estimate", _estimate(k)), ("altitude", _readings(k)))]
    reference, late = _run(ros_context, in_order)
    waited, waited_late = _run(ros_context, behind)
    assert len(reference) == 29 and late == 0
    assert math.isinf(_readings(3).range) and _readings(3).range > 0
    assert waited == reference and waited_late == 0
    # without the wait each sample uses the previous sample's reading: the rule really matters
    unwaited, _ = _run(ros_context, behind, altitude_wait=0.0)
    assert len(unwaited) == 29 and unwaited != reference


@pytest.mark.graph
def test_an_altitude_that_never_comes_is_waited_for_only_altitude_wait(ros_context):
    """The altimeter stops (its driver died): the estimate goes on with the newest reading after
    altitude_wait wall seconds, counted late; the next estimate does not wait again."""
    node, setpoints = _node(ros_context, 0.3)
    said = []
    node.diagnostics.publish = lambda msg: said.extend(
        {kv.key: kv.value for kv in status.values}.get("late_altitudes") for status in msg.status)
    for k in range(1, 5):
        node._on_altitude(_readings(k))
        node._on_estimate(_estimate(k))
    node._on_estimate(_estimate(5))  # its reading never comes
    assert len(setpoints) == 4
    start = time.monotonic()
    while len(setpoints) < 5 and time.monotonic() - start < 5.0:
        node._check_parked()
        time.sleep(0.01)
    assert len(setpoints) == 5 and 0.25 < time.monotonic() - start < 2.0 and node.counts["late_altitudes"] == 1
    # the ended wait is on /diagnostics at once (a SIL harness names it: the run is no longer deterministic)
    assert said and said[-1] == "1", said
    node._on_estimate(_estimate(6))  # not streaming any more: at once
    assert len(setpoints) == 6 and node.counts["late_altitudes"] == 1
    node.destroy_node()


@pytest.mark.graph
def test_an_altitude_stamped_far_ahead_is_refused_and_changes_nothing(ros_context):
    """Issue 28 5(c): one reading stamped 10^6 s ahead must neither be used nor end the per-sample wait."""
    hostile = _readings(1)
    hostile.header.stamp.sec += 10**6
    deliveries = [("altitude", hostile)] + [d for k in range(1, 30)
                                             for d in (("estimate", _estimate(k)), ("altitude", _readings(k)))]
    node, setpoints = _node(ros_context, 2.0)
    for kind, msg in deliveries:
        (node._on_altitude if kind == "altitude" else node._on_estimate)(msg)
    assert node.counts["rejected_altitudes"] == 1 and node.counts["late_altitudes"] == 0
    reference, _ = _run(ros_context, [d for k in range(1, 30) for d in (("altitude", _readings(k)),
                                                                        ("estimate", _estimate(k)))])
    assert setpoints == reference
    node.destroy_node()


@pytest.mark.graph
def test_an_altimeter_slower_than_the_samples_is_not_waited_for(ros_context):
    """A vehicle's 1 Hz altimeter (one reading every 5 samples): no estimate waits for a reading that is not
    coming, so every setpoint goes out with its estimate and none is counted late."""
    node, setpoints = _node(ros_context, 2.0)
    for k in range(1, 30):
        node._on_estimate(_estimate(k))
        assert len(setpoints) == k, k  # at once
        if k % 5 == 0:
            node._on_altitude(_readings(k))
    assert node.counts["late_altitudes"] == 0 and node._parked is None
    node.destroy_node()


@pytest.mark.graph
def test_an_estimate_said_again_steps_the_task_once(ros_context):
    """The navigator says its newest estimate again when a reader matches late (issue 28): a task steps
    once per sample. Truth: the setpoints of every estimate delivered once."""
    in_order = [d for k in range(1, 20) for d in (("altitude", _readings(k)), ("estimate", _estimate(k)))]
    twice = [d for k in range(1, 20) for d in (("altitude", _readings(k)), ("estimate", _estimate(k)),
                                                ("estimate", _estimate(k)))]
    reference, _ = _run(ros_context, in_order)
    node, setpoints = _node(ros_context, 2.0)
    for kind, msg in twice:
        (node._on_altitude if kind == "altitude" else node._on_estimate)(msg)
    assert len(reference) == 19 and setpoints == reference and node.counts["repeated_estimates"] == 19


class _AcceptedHandle(_Handle):
    """What rclpy's action server hands its ``handle_accepted_callback``: the goal and its id."""

    def __init__(self, request):
        import uuid
        from unique_identifier_msgs.msg import UUID
        self.request, self.goal_id, self.executed, self.feedback = request, UUID(uuid=list(uuid.uuid4().bytes)), 0, []

    def execute(self):
        self.executed += 1

    def publish_feedback(self, feedback):
        self.feedback.append(feedback)


@pytest.mark.graph
def test_a_task_starts_at_its_acceptance_so_its_first_step_is_the_next_estimate(ros_context):
    """Issue 43 (a loaded demo's seabed following ended 0.4 s late): rclpy sends the goal response and then,
    with no callback in between, calls the server's accepted callback; the execute callback runs later, after
    estimates that may already be queued. A lockstep harness steps the graph as soon as it hears the
    acceptance, so the task must be running from the accepted callback on: the next estimate is its first step,
    whatever the executor does first. Truth: the task's first step and feedback at t_1, for a goal accepted at
    t_0, and nothing left to the execute callback but waiting for the end."""
    from rclpy.action import GoalResponse
    from seapup_control.task_controller_node import TaskControllerNode
    from seapup_msgs.action import FollowSeabed, Hover
    node = TaskControllerNode(context=ros_context)
    setpoints = []
    node.setpoints.publish = lambda msg: setpoints.append(conv.stamp_to_ns(msg.header.stamp))
    node.setpoints.get_subscription_count = lambda: 1  # a position controller listens
    node._on_altitude(_altitude(0))
    node._on_estimate(_estimate(0))
    goal = FollowSeabed.Goal(altitude=8.0, yaw=0.0, speed=0.2, duration=100.0)
    assert node._accept("follow_seabed", goal) == GoalResponse.ACCEPT
    assert node.running is None                     # accepting alone starts nothing (a goal may still be refused)
    handle = _AcceptedHandle(goal)
    node.servers[2]._handle_accepted_callback(handle)  # the server's own wiring: task/follow_seabed
    assert handle.executed == 1 and node.running is not None and node.running.task.kind == "follow_seabed"
    assert setpoints == [round(T * 1e9)]            # the stream starts at once, for t_1
    node._on_altitude(_altitude(1))
    node._on_estimate(_estimate(1))
    assert node.running.task.t0 == pytest.approx(T) and [fb.elapsed for fb in handle.feedback] == [0.0]
    # a second goal while it runs is refused at once (no window between acceptance and execution)
    assert node._accept("hover", Hover.Goal()) == GoalResponse.REJECT
    node.destroy_node()
