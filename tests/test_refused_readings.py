"""Every sensor reading the navigator or the identifier refuses is counted in its diagnostics (issue 40: the
identifier's ``rejected`` said 8 where 13 were refused; the navigator fused depth and IMU readings stamped in
``map`` and ``odom_enu``).

N bad readings of each kind are published on the graph to a node in this process; its diagnostics must count
exactly as many as were sent (truth: the test's own count), and none may move the estimate.
"""
import math

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseWithCovarianceStamped, TwistWithCovarianceStamped
from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import Imu
from seapup_msgs.msg import BladePitch, Depth

from seapup_common import frames
from seapup_common.ros.messages import ns_to_stamp
from seapup_common.ros.node import COMMAND_QOS

N = 3   # of each kind


def _stamped(msg, k, frame):
    msg.header.stamp, msg.header.frame_id = ns_to_stamp(200_000_000 * (k + 1)), frame
    return msg


def _velocity(k, frame=frames.FRAME_FRD, u=0.1):
    msg = _stamped(TwistWithCovarianceStamped(), k, frame)
    msg.twist.twist.linear.x = u
    return msg


def _imu(k, frame=frames.FRAME_FRD, w=1.0):
    msg = _stamped(Imu(), k, frame)
    msg.orientation.w = w
    return msg


def _depth(k, frame=frames.FRAME_NED, depth=10.0):
    msg = _stamped(Depth(), k, frame)
    msg.depth, msg.variance = depth, 0.01
    return msg


def _position(k, frame=frames.FRAME_NED, x=0.0):
    msg = _stamped(PoseWithCovarianceStamped(), k, frame)
    msg.pose.pose.position.x = x
    msg.pose.pose.orientation.w = 1.0
    return msg


def _applied(k, pitch=0.0):
    msg = _stamped(BladePitch(), k, frames.FRAME_FRD)
    msg.pitch = [pitch, 0.0, 0.0, 0.0]
    return msg


#: (topic, bad reading of sample k) -- each kind of refusal the conversion makes
NAVIGATOR_BAD = [
    ("sensors/velocity", lambda k: _velocity(k, u=math.nan)), ("sensors/velocity", lambda k: _velocity(k, "map")),
    ("sensors/imu", lambda k: _imu(k, w=2.5)), ("sensors/imu", lambda k: _imu(k, w=math.nan)),
    ("sensors/imu", lambda k: _imu(k, "map")), ("sensors/imu", lambda k: _imu(k, frames.FRAME_NED)),
    ("sensors/depth", lambda k: _depth(k, "map")), ("sensors/depth", lambda k: _depth(k, "odom_enu")),
    ("sensors/depth", lambda k: _depth(k, depth=math.inf)),
    ("sensors/position", lambda k: _position(k, "map")), ("sensors/position", lambda k: _position(k, x=math.nan))]
IDENTIFIER_BAD = [
    ("sensors/velocity", lambda k: _velocity(k, u=math.nan)), ("sensors/velocity", lambda k: _velocity(k, "odom")),
    ("sensors/imu", lambda k: _imu(k, w=2.5)), ("sensors/imu", lambda k: _imu(k, "odom_enu")),
    ("thrusters/applied", lambda k: _applied(k, pitch=math.nan))]


def _count(diagnostics: list, name: str, key: str):
    for array in reversed(diagnostics):
        for status in array.status:
            if status.name == name:
                return int(next(v.value for v in status.values if v.key == key))
    return None


def _publish_and_count(ros_context, spin, node, bad, status_name, counted):
    import rclpy
    sender = rclpy.create_node("bad_sensors", namespace="/seapup", context=ros_context)
    heard = []
    sender.create_subscription(DiagnosticArray, "/diagnostics", heard.append, 10)
    publishers = {topic: sender.create_publisher(type(make(0)), topic, COMMAND_QOS) for topic, make in bad}
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    executor.add_node(sender)
    assert spin(executor, lambda: all(p.get_subscription_count() > 0 for p in publishers.values()), 20.0)
    for k in range(N):
        for topic, make in bad:
            publishers[topic].publish(make(k))
    expected = N * len(bad)
    assert spin(executor, lambda: _count(heard, status_name, "rejected_readings") == expected, 20.0), \
        (counted(), expected)
    assert counted() == expected
    executor.shutdown()


def test_the_navigator_counts_every_refused_reading_and_fuses_none(ros_context, spin):
    from seapup_control.navigator_node import NavigatorNode
    node = NavigatorNode(context=ros_context)
    _publish_and_count(ros_context, spin, node, NAVIGATOR_BAD, "seapup/navigator", lambda: node.rejected)
    assert node.navigator.estimate() is None and node.collector.latest == {}


def test_the_identifier_counts_every_refused_reading(ros_context, spin):
    from rclpy.parameter import Parameter
    from seapup_ident.identifier_node import IdentifierNode
    node = IdentifierNode(context=ros_context, parameter_overrides=[Parameter("bag_path", value="none")])
    _publish_and_count(ros_context, spin, node, IDENTIFIER_BAD, "seapup/identifier", node.rejected)
    assert node.core.counts["used"] == 0


def _reference(k, frame=frames.FRAME_FRD, u=0.1):
    from geometry_msgs.msg import TwistStamped
    msg = _stamped(TwistStamped(), k, frame)
    msg.twist.linear.x = u
    return msg


class _Bytes:
    """A message that is only bytes (published raw): cut short, or empty."""

    def __init__(self, msg, keep):
        from rclpy.serialization import serialize_message
        self.type, self.data = type(msg), serialize_message(msg)[:keep]


#: (topic, bad message of sample k, counter) -- each kind of refusal a velocity controller makes, malformed bytes
#: (its inputs are read from the bytes: sample_inputs) included
CONTROLLER_BAD = [
    ("sensors/velocity", lambda k: _velocity(k, u=math.nan), "rejected_measurements"),
    ("sensors/velocity", lambda k: _velocity(k, "map"), "rejected_measurements"),
    ("sensors/velocity", lambda k: _Bytes(_velocity(k), 40), "rejected_measurements"),
    ("sensors/velocity", lambda k: _Bytes(_velocity(k), 0), "rejected_measurements"),
    ("velocity_controller/reference", lambda k: _reference(k, u=math.inf), "rejected_references"),
    ("velocity_controller/reference", lambda k: _reference(k, "odom"), "rejected_references"),
    ("velocity_controller/reference", lambda k: _Bytes(_reference(k), 20), "rejected_references"),
    ("thrusters/applied", lambda k: _applied(k, pitch=math.nan), "rejected_applied"),
    ("thrusters/applied", lambda k: _Bytes(_applied(k), 50), "rejected_applied")]


def test_the_velocity_controller_counts_every_refused_input_malformed_bytes_included(ros_context, spin):
    """Its per-sample inputs are subscribed as bytes: bytes rclpy cannot read are refused and counted with the
    typed refusals, none reaches the law (no sample is answered, the applied pitch stays unknown)."""
    import rclpy
    from rclpy.parameter import Parameter
    from seapup_control.velocity_controller_node import VelocityControllerNode
    node = VelocityControllerNode(context=ros_context, parameter_overrides=[
        Parameter("controller_type", value="hold"), Parameter("sample_period", value=0.2)])
    from rclpy.lifecycle import TransitionCallbackReturn
    assert node.trigger_configure() == TransitionCallbackReturn.SUCCESS   # subscribed from here on
    sender = rclpy.create_node("bad_inputs", namespace="/seapup", context=ros_context)
    kinds = {topic: (make(0).type if isinstance(make(0), _Bytes) else type(make(0))) for topic, make, _ in
             CONTROLLER_BAD}
    publishers = {topic: sender.create_publisher(kind, topic, COMMAND_QOS) for topic, kind in kinds.items()}
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    executor.add_node(sender)
    assert spin(executor, lambda: all(p.get_subscription_count() > 0 for p in publishers.values()), 20.0)
    expected = {}
    for k in range(N):
        for topic, make, counter in CONTROLLER_BAD:
            msg = make(k)
            publishers[topic].publish(msg.data if isinstance(msg, _Bytes) else msg)
            expected[counter] = expected.get(counter, 0) + 1
    counters = sorted(expected)
    assert spin(executor, lambda: [node.counts[c] for c in counters] == [expected[c] for c in counters], 20.0), \
        (node.counts, expected)
    assert node.counts["samples"] == 0 and node.applied is None and node.collector.latest == {}
    executor.shutdown()
