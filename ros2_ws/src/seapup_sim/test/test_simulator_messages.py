"""The simulator node's per-sample messages: packed only when asked, the same bytes whenever asked.

Truth: rclpy's own deserialisation of the packed bytes (stamp and values against the core's outputs), the
encoder called directly, and counts of what was packed and published. No process is started.
"""
import types

import numpy as np
from geometry_msgs.msg import TwistWithCovarianceStamped
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message
from seapup_msgs.msg import SampleManifest

from seapup_common.ros.sample_bytes import SampleEncoder
from seapup_sim.ros.simulator_messages import Packed, sample_messages
from seapup_sim.simulator_core import SimulatorConfig, SimulatorCore
from seapup_sim.simulator_node import SimulatorNode

NAMES = ["pub_applied", "pub_velocity", "pub_imu", "pub_position", "pub_depth", "pub_altitude", "pub_truth",
         "pub_odom", "pub_current", "pub_wrench", "pub_tf", "pub_cable", "pub_manifest"]


class CountingEncoder:
    """A SampleEncoder that counts the messages it packs."""

    def __init__(self):
        self.inner, self.packed = SampleEncoder(), []

    def __getattr__(self, name):
        method = getattr(self.inner, name)

        def pack(*args, **kwargs):
            self.packed.append(name)
            return method(*args, **kwargs)
        return pack


class Publisher:
    def __init__(self, topic, readers):
        self.topic_name, self.readers, self.sent = topic, readers, []

    def get_subscription_count(self):
        return self.readers

    def publish(self, data):
        self.sent.append(data)


def _sample(steps=3):
    core = SimulatorCore(SimulatorConfig())
    for _ in range(steps):
        core.submit(core.hover + 0.1, core.t_ns, True)
        core.step()
    return core, core.outputs()


def _publishers(readers=1):
    return types.SimpleNamespace(**{n: Publisher("/seapup/" + n[4:], readers) for n in NAMES})


def test_nothing_is_packed_until_asked_and_the_manifest_lists_every_topic():
    core, out = _sample()
    encoder, pubs = CountingEncoder(), _publishers()
    messages = sample_messages(encoder, pubs, out, core.t_ns, core.sensor_profile)
    assert encoder.packed == []
    manifest = deserialize_message(messages[-1][1](), SampleManifest)
    assert manifest.topics == [p.topic_name for p, _ in messages[:-1]]
    assert "/seapup/truth" in manifest.topics and (manifest.header.stamp.sec, manifest.header.stamp.nanosec) == \
        divmod(core.t_ns, 10**9)
    assert encoder.packed == ["manifest"]


def test_packed_bytes_are_the_encoders_and_decode_to_the_sample():
    core, out = _sample()
    messages = dict((p.topic_name, packed) for p, packed in
                    sample_messages(SampleEncoder(), _publishers(), out, core.t_ns, core.sensor_profile))
    direct = SampleEncoder()
    assert messages["/seapup/truth"]() == direct.odometry_ned(out["sample"].state, core.t_ns)
    truth = deserialize_message(messages["/seapup/truth"](), Odometry)
    assert truth.header.stamp.sec * 10**9 + truth.header.stamp.nanosec == core.t_ns
    state = out["sample"].state
    np.testing.assert_allclose([truth.pose.pose.position.x, truth.pose.pose.position.y, truth.pose.pose.position.z],
                               state[:3])
    velocity = deserialize_message(messages["/seapup/velocity"](), TwistWithCovarianceStamped)
    m = out["sample"].measurement
    np.testing.assert_allclose(velocity.twist.twist.linear.x, m.velocity.value[0])


def test_bytes_asked_for_later_are_those_of_the_sample_not_of_the_plant_now():
    """A late joiner's republish of the held sample packs then: the bytes are the sample's."""
    core, out = _sample()
    early = sample_messages(SampleEncoder(), _publishers(), out, core.t_ns, core.sensor_profile)
    late = sample_messages(SampleEncoder(), _publishers(), out, core.t_ns, core.sensor_profile)
    first = [packed() for _, packed in early]
    core.submit(core.hover - 0.2, core.t_ns, True)
    core.step()   # the plant moves on; the packed sample does not
    assert [packed() for _, packed in late] == first


def test_a_topic_without_readers_is_neither_packed_nor_published():
    core, out = _sample()
    encoder, pubs = CountingEncoder(), _publishers(readers=0)
    pubs.pub_velocity.readers = 2
    pubs.pub_manifest.readers = 1
    messages = sample_messages(encoder, pubs, out, core.t_ns, core.sensor_profile)
    SimulatorNode._send(messages)
    assert sorted(encoder.packed) == ["manifest", "velocity"]
    assert len(pubs.pub_velocity.sent) == 1 and len(pubs.pub_manifest.sent) == 1
    assert all(not getattr(pubs, n).sent for n in NAMES if n not in ("pub_velocity", "pub_manifest"))
    SimulatorNode._send(messages)   # said again: the same bytes, packed once
    assert pubs.pub_velocity.sent[0] == pubs.pub_velocity.sent[1] and sorted(encoder.packed) == ["manifest", "velocity"]


def test_packed_packs_once():
    calls = []
    packed = Packed(lambda a, b=0: calls.append((a, b)) or bytes([a, b]), 1, b=2)
    assert calls == [] and packed() == b"\x01\x02" and packed() == b"\x01\x02" and calls == [(1, 2)]
