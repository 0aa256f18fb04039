"""Tests of seapup_common.ros.messages: contract <-> ROS messages, both ways."""
import math

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import Imu

from seapup_common import frames
from seapup_common.blade_pitch import InvalidBladePitchError
from seapup_common.contract import Command, ContractError, Measurement
from seapup_common.ros import messages as conv

T_NS = 12_345_000_000


def roundtrip(msg):
    return deserialize_message(serialize_message(msg), type(msg))


def test_stamps():
    assert conv.stamp_to_ns(conv.ns_to_stamp(T_NS)) == T_NS
    assert conv.ns_to_stamp(T_NS).sec == 12 and conv.ns_to_stamp(T_NS).nanosec == 345_000_000


def test_command_roundtrip_and_rejection():
    cmd = Command([0.1, -0.2, 0.3, -0.4], 12.345)
    back = conv.command_from_msg(roundtrip(conv.command_to_msg(cmd)))
    np.testing.assert_array_equal(back.blade_pitch, cmd.blade_pitch)
    assert back.stamp == pytest.approx(12.345)
    msg = conv.command_to_msg(cmd)
    msg.pitch[0] = math.nan
    with pytest.raises(InvalidBladePitchError):
        conv.command_from_msg(msg)


def test_measurement_roundtrip_through_every_sensor_message():
    m = Measurement.build(12.345, velocity=[0.5, -0.1, 0.05], rates=[0.01, -0.02, 0.3],
                          attitude=[0.1, -0.2, 3.0], depth=30.0, altitude=12.0, position=[1.0, 2.0, 30.0],
                          variances={"velocity": [1e-4] * 3, "rates": [1e-6] * 3, "attitude": [4e-6] * 3,
                                     "depth": 0.0025, "altitude": 0.0025, "position": [0.25] * 3})
    collector = conv.MeasurementCollector()
    msgs = [conv.velocity_to_msg(m.velocity, m.rates, T_NS),
            conv.imu_to_msg(m.attitude, m.rates, [0.0, 0.0, -9.81], T_NS),
            conv.depth_to_msg(m.depth, T_NS),
            conv.altitude_to_msg(m.altitude, T_NS, field_of_view=0.17, min_range=0.3, max_range=200.0),
            conv.position_to_msg(m.position, T_NS)]
    for msg in msgs:
        assert collector.add(roundtrip(msg))
    back = collector.measurement(12.345)
    for name in ("velocity", "rates", "attitude", "depth", "altitude", "position"):
        a, b = getattr(m, name), getattr(back, name)
        np.testing.assert_allclose(b.value, a.value, atol=1e-12, err_msg=name)
        np.testing.assert_allclose(b.variance, a.variance, err_msg=name)
        assert b.stamp == pytest.approx(12.345)
    # stale readings are not readings
    late = collector.measurement(12.345 + 2.0)
    assert not late.velocity.valid and late.position.valid  # fixes may be 5 s old


def test_imu_orientation_is_frd_in_ned_and_bad_messages_are_counted():
    att = [0.1, -0.2, 3.0]
    m = Measurement.build(0.0, attitude=att, rates=[0, 0, 0])
    imu = conv.imu_to_msg(m.attitude, m.rates, [0, 0, -9.81], 0)
    q = [imu.orientation.x, imu.orientation.y, imu.orientation.z, imu.orientation.w]
    np.testing.assert_allclose(Rotation.from_quat(q).as_euler("ZYX")[::-1], att, atol=1e-12)
    assert imu.header.frame_id == frames.FRAME_FRD
    collector = conv.MeasurementCollector()
    bad = Imu()
    bad.orientation.w = math.nan
    assert not collector.add(bad) and collector.rejected == 1
    assert not collector.add(conv.command_to_msg(Command([0] * 4))) and collector.rejected == 2
    with pytest.raises(ContractError, match="base_link_frd"):
        tw = conv.velocity_to_msg(m.rates, m.rates, 0)
        tw.header.frame_id = "base_link"
        conv.velocity_from_msg(tw)


def test_altitude_outside_the_range_is_invalid_and_odometry_frames():
    m = Measurement.build(0.0, altitude=250.0)
    msg = conv.altitude_to_msg(m.altitude, 0, field_of_view=0.17, min_range=0.3, max_range=200.0)
    assert not conv.altitude_from_msg(msg).valid
    x = np.zeros(12)
    x[:3], x[5], x[6] = [1.0, 2.0, 3.0], math.pi / 2, 0.5
    ned, enu = conv.odometry_ned(x, 0), conv.odometry_enu(x, 0)
    assert (ned.header.frame_id, ned.child_frame_id) == (frames.FRAME_NED, frames.FRAME_FRD)
    assert (enu.header.frame_id, enu.child_frame_id) == (frames.FRAME_ENU, frames.FRAME_FLU)
    assert (enu.pose.pose.position.x, enu.pose.pose.position.y, enu.pose.pose.position.z) == (2.0, 1.0, -3.0)
    assert enu.twist.twist.linear.x == 0.5


def test_a_sample_feed_answers_samples_once_and_refuses_what_the_collector_refuses():
    from geometry_msgs.msg import TwistWithCovarianceStamped
    from rosgraph_msgs.msg import Clock

    from seapup_common.lockstep import SamplePolicy
    from seapup_common.ros.messages import MeasurementCollector, SampleFeed, ns_to_stamp

    def velocity(t_ns, u=0.1):
        msg = TwistWithCovarianceStamped()
        msg.header.stamp, msg.header.frame_id = ns_to_stamp(t_ns), "base_link_frd"
        msg.twist.twist.linear.x = u
        return msg
    refused = []
    policy = SamplePolicy(True)
    policy.activate(heard_applied=True)
    feed = SampleFeed(MeasurementCollector(), policy, refused.append)
    assert feed.clock(Clock(clock=ns_to_stamp(0))) is None            # announced, its sample not here yet
    assert feed.velocity(velocity(0)) == 0                            # the sample: answer t_0
    assert feed.clock(Clock(clock=ns_to_stamp(0))) == 0               # the handshake's repeat, still pending
    policy.answered(0)
    assert feed.velocity(velocity(200_000_000, u=float("nan"))) is None  # refused: never a sample
    assert len(refused) == 1 and "finite" in refused[0] and policy.latest_ns == 0
    assert feed.collector.measurement(0.0).velocity.value[0] == 0.1


def test_the_frame_tree_puts_the_vehicle_upright_in_enu_and_its_ned_frames_where_the_thesis_has_them():
    """Compose /tf_static and /tf as tf2 would (child in parent: p_parent = R p_child + t) and check a point
    given in base_link_frd lands, in odom_ned, where the 12-state's rotation of eq. 2.1 puts it."""
    def pose(transform):
        t, q = transform.transform.translation, transform.transform.rotation
        return Rotation.from_quat([q.x, q.y, q.z, q.w]), np.array([t.x, t.y, t.z])

    rng = np.random.default_rng(3)
    for _ in range(20):
        state = np.zeros(12)
        state[:3] = rng.normal(0.0, 20.0, 3)
        state[3:6] = rng.uniform(-1.2, 1.2, 3)
        dynamic = conv.transforms_enu(state, 5_000_000_000).transforms
        static = {t.child_frame_id: t for t in conv.static_transforms(0).transforms}
        assert [(t.header.frame_id, t.child_frame_id) for t in dynamic] == [("odom", "base_link")]
        assert {c: t.header.frame_id for c, t in static.items()} == {"odom_ned": "odom", "base_link_frd": "base_link"}
        assert conv.stamp_to_ns(dynamic[0].header.stamp) == 5_000_000_000
        r_vehicle, t_vehicle = pose(dynamic[0])
        r_frd, _ = pose(static["base_link_frd"])
        r_ned, _ = pose(static["odom_ned"])
        point_frd = rng.normal(size=3)
        in_odom = r_vehicle.apply(r_frd.apply(point_frd)) + t_vehicle          # odom <- base_link <- base_link_frd
        in_ned = r_ned.inv().apply(in_odom)                                      # odom_ned <- odom
        expected = frames.rotation_body_to_ned(*state[3:6]) @ point_frd + state[:3]
        np.testing.assert_allclose(in_ned, expected, atol=1e-9)
    level = conv.transforms_enu(np.zeros(12), 0).transforms[0].transform   # level, heading north
    up_flu = Rotation.from_quat([level.rotation.x, level.rotation.y, level.rotation.z, level.rotation.w]).apply([0, 0, 1])
    np.testing.assert_allclose(up_flu, [0, 0, 1], atol=1e-12)   # the vehicle's top is up: drawn upright
    assert conv.transforms_enu(np.r_[0, 0, 10.0, np.zeros(9)], 0).transforms[0].transform.translation.z == -10.0
