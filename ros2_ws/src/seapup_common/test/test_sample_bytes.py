"""Packed messages against rclpy's own serialiser and the message builders of seapup_common.ros.messages."""
import math

import numpy as np
import pytest
from builtin_interfaces.msg import Duration
from geometry_msgs.msg import AccelWithCovarianceStamped, Polygon, PoseWithCovarianceStamped
from nav_msgs.msg import Odometry, Path
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu, Range
from rosgraph_msgs.msg import Clock
from seapup_msgs.msg import BladePitch, SampleManifest
from tf2_msgs.msg import TFMessage

from seapup_common import frames
from seapup_common.contract import Command, Reading
from seapup_common.ros import messages as conv
from seapup_common.ros.cdr import Packer, Restamper, zero_padding
from seapup_common.ros.sample_bytes import SampleEncoder, command_bytes

RNG = np.random.default_rng(7)


def _values(packer):
    values = []
    for name in packer.fields:
        if name.split(".")[-1] == "sec":
            values.append(int(RNG.integers(-2**31, 2**31)))
        elif name.endswith("nanosec"):
            values.append(int(RNG.integers(0, 10**9)))
        elif name == "radiation_type":
            values.append(int(RNG.integers(0, 2)))
        else:
            values.append(float(RNG.normal(0.0, 1e3)))
    return values


def _field(msg, name):
    for part in name.replace("]", "").split("."):
        attribute, _, index = part.partition("[")
        msg = getattr(msg, attribute)
        if index:
            msg = msg[int(index)]
    return msg


@pytest.mark.parametrize("msg_type, strings", [
    (Odometry, {"header.frame_id": "odom_ned", "child_frame_id": "base_link_frd"}),
    (Imu, {"header.frame_id": "x"}),          # a 1-byte string: every later field realigned
    (Range, {}),                              # empty strings, a uint8 then float32s
    (BladePitch, {"header.frame_id": "abcdefg"}),
    (AccelWithCovarianceStamped, {"header.frame_id": "base_link_frd"}),
    (Duration, {}),                           # no header at all
    (TFMessage, {"transforms[0].header.frame_id": "odom", "transforms[0].child_frame_id": "b"}),   # a sequence
    (TFMessage, {"transforms[1].child_frame_id": "abc"}),   # its second element realigned after a 4-byte string
])
def test_packed_bytes_are_what_rclpy_serialises_for_the_same_fields(msg_type, strings):
    lengths = {"transforms": 2 if "transforms[1].child_frame_id" in strings else 1} if msg_type is TFMessage \
        else None
    packer = Packer(msg_type, strings, lengths)
    for _ in range(5):
        values = _values(packer)
        data = packer.pack(values)
        msg = deserialize_message(data, msg_type)
        assert len(data) == len(serialize_message(msg)) == packer.size
        for name, value in zip(packer.fields, values):
            got = _field(msg, name)
            if isinstance(value, float) and type(got) is float and _is_float32(msg_type, name):
                assert got == pytest.approx(value, rel=1e-6)
            else:
                assert got == value, name
        for path, text in strings.items():
            assert _field(msg, path) == text


def _is_float32(msg_type, name):
    return msg_type is Range and name in ("field_of_view", "min_range", "max_range", "range", "variance")


def test_a_packer_refuses_what_has_no_fixed_layout_and_the_wrong_number_of_values():
    with pytest.raises(TypeError, match="no fixed layout"):
        Packer(Path)  # a sequence of poses
    with pytest.raises(TypeError, match="no fixed layout"):
        Packer(Polygon)
    with pytest.raises(ValueError, match="no string field"):
        Packer(Imu, {"header.frame": "x"})
    with pytest.raises(ValueError, match="no sequence field"):
        Packer(Imu, lengths={"transforms": 1})
    with pytest.raises(TypeError, match="no fixed layout"):
        Packer(TFMessage)   # a sequence without a length
    packer = Packer(BladePitch)
    with pytest.raises(ValueError, match="5 values for 6 fields"):
        packer.pack([0, 0, 1.0, 2.0, 3.0])


def _reading(value, variance):
    return Reading(np.asarray(value, float), 1.0, variance)


@pytest.mark.parametrize("seed", range(4))
def test_every_sample_message_deserialises_to_what_the_message_builders_make(seed):
    rng = np.random.default_rng(seed)
    encoder = SampleEncoder()
    t_ns = int(rng.integers(0, 10**13))
    state = rng.normal(0.0, 1.0, 12) * [50, 50, 50, 0.5, 0.5, 3, 1, 1, 1, 0.3, 0.3, 0.3]
    velocity = _reading(rng.normal(size=3), rng.uniform(0, 1e-3, 3))
    rates = _reading(rng.normal(size=3), float(rng.uniform(0, 1e-4)))  # scalar variance: each axis
    attitude = _reading(state[3:6], rng.uniform(0, 1e-4, 3))
    position = _reading(state[:3], rng.uniform(0, 1, 3))
    depth = Reading(float(state[2]), 1.0, float(rng.uniform(0, 0.1)))
    altitude = Reading(float(rng.uniform(0.5, 20)), 1.0, 0.01) if seed % 2 else Reading.invalid()
    force, wrench, pitch = rng.normal(size=3), rng.normal(size=6), rng.uniform(-0.6, 0.6, 4)
    ranges = dict(field_of_view=0.2, min_range=0.3, max_range=30.0)
    cable = rng.normal(size=(2 + seed * 6, 3)) * 30   # the umbilical's polyline, of any length
    pairs = [
        (encoder.applied(pitch, t_ns), conv.command_to_msg(Command(pitch), t_ns, frames.FRAME_FRD)),
        (encoder.velocity(velocity, rates, t_ns), conv.velocity_to_msg(velocity, rates, t_ns)),
        (encoder.imu(attitude, rates, force, t_ns), conv.imu_to_msg(attitude, rates, force, t_ns)),
        (encoder.position(position, t_ns), conv.position_to_msg(position, t_ns)),
        (encoder.depth(depth, t_ns), conv.depth_to_msg(depth, t_ns)),
        (encoder.altitude(altitude, t_ns, **ranges), conv.altitude_to_msg(altitude, t_ns, **ranges)),
        (encoder.odometry_ned(state, t_ns), conv.odometry_ned(state, t_ns)),
        (encoder.odometry_enu(state, t_ns), conv.odometry_enu(state, t_ns)),
        (encoder.vector3_stamped(force, t_ns, frames.FRAME_NED), conv.vector3_stamped(force, t_ns, frames.FRAME_NED)),
        (encoder.wrench_stamped(wrench, t_ns, frames.FRAME_FRD), conv.wrench_stamped(wrench, t_ns, frames.FRAME_FRD)),
        (encoder.transforms_enu(state, t_ns), conv.transforms_enu(state, t_ns)),
        (encoder.path_ned(cable, t_ns), conv.path_ned(cable, t_ns)),
    ]
    for data, expected in pairs:
        got = deserialize_message(data, type(expected))
        received = deserialize_message(serialize_message(expected), type(expected))  # float32s rounded
        assert got == received, type(expected).__name__
        assert len(data) == len(serialize_message(expected))
    if not seed % 2:
        assert math.isinf(deserialize_message(pairs[5][0], Range).range)
    assert deserialize_message(encoder.clock(t_ns), Clock).clock == conv.ns_to_stamp(t_ns)
    assert deserialize_message(command_bytes(pitch, t_ns), BladePitch) == conv.command_to_msg(Command(pitch), t_ns)
    topics = ["/seapup/sensors/velocity", "/seapup/sensors/position"][:1 + seed % 2]
    manifest = deserialize_message(encoder.manifest(topics, t_ns), SampleManifest)
    assert manifest.topics == topics and manifest.header.stamp == conv.ns_to_stamp(t_ns)


def test_a_restamped_message_keeps_everything_but_its_stamp():
    original = SampleManifest(topics=["/a", "/bc", "/def"])
    original.header.frame_id = "odom_ned"
    restamper = Restamper(original)
    for t_ns in (0, 1, 999_999_999, 1_000_000_000, 2**31 * 10**9 - 1):
        got = deserialize_message(restamper.pack(t_ns), SampleManifest)
        assert got.header.stamp == conv.ns_to_stamp(t_ns)
        assert (got.header.frame_id, got.topics) == ("odom_ned", ["/a", "/bc", "/def"])
    with pytest.raises(TypeError, match="does not begin with a header"):
        Restamper(Clock())


def test_a_restamped_message_has_zero_padding_byte_for_byte():
    """The CDR of a manifest written out by hand (independent of rclpy's writer): padding and all."""
    import struct
    restamper = Restamper(SampleManifest(topics=["/a", "/bcd"]))
    expected = (b"\x00\x01\x00\x00" + struct.pack("<iI", 3, 5)     # encapsulation, stamp
                + struct.pack("<I", 1) + b"\x00" + b"\x00" * 3       # frame_id "", padding to 4
                + struct.pack("<I", 2)                              # two topics
                + struct.pack("<I", 3) + b"/a\x00" + b"\x00"         # "/a", padding
                + struct.pack("<I", 5) + b"/bcd\x00")                # "/bcd"
    got = restamper.pack(3_000_000_005)
    assert got[:len(expected)] == expected and not any(got[len(expected):])


def test_zero_padding_zeroes_garbage_between_fields_and_keeps_the_fields():
    data = bytearray(serialize_message(SampleManifest(topics=["/a"])))
    data[4 + 8 + 5:4 + 8 + 8] = b"\xaa\xbb\xcc"                        # after frame_id's 1 byte: padding
    cleaned = zero_padding(bytes(data), SampleManifest)
    assert cleaned[4 + 8 + 5:4 + 8 + 8] == bytes(3)
    assert deserialize_message(cleaned, SampleManifest).topics == ["/a"]
    with pytest.raises(ValueError, match="bytes"):
        zero_padding(bytes(data[:-2]), SampleManifest)


# -- reading bytes: the decoders against rclpy's deserialiser and the typed conversions ---------------------
from geometry_msgs.msg import TwistStamped, TwistWithCovarianceStamped  # noqa: E402

from seapup_common.blade_pitch import InvalidBladePitchError  # noqa: E402
from seapup_common.contract import ContractError  # noqa: E402
from seapup_common.ros.sample_bytes import (StampedDoubles, blade_pitch_values, decode_blade_pitch,  # noqa: E402
                                            decode_clock, decode_reference, decode_velocity)

SPECIAL = [math.nan, math.inf, -math.inf, 1e308, -0.0, 5e-324]


def _random_doubles(n, rng, special=0.05):
    values = rng.normal(0.0, 10.0, n)
    mask = rng.random(n) < special
    values[mask] = rng.choice(SPECIAL, mask.sum())
    return values.tolist()


def _random_stamped(msg_type, rng, frames_=("base_link_frd", "", "map", "base_link_frdx")):
    msg = msg_type()
    msg.header.stamp.sec = int(rng.integers(-2**31, 2**31))
    msg.header.stamp.nanosec = int(rng.integers(0, 10**9))
    msg.header.frame_id = str(rng.choice(frames_))
    return msg


def _random_velocity(rng):
    msg = _random_stamped(TwistWithCovarianceStamped, rng)
    v = _random_doubles(42, rng, 0.02)
    conv._set_xyz(msg.twist.twist.linear, v[:3])
    conv._set_xyz(msg.twist.twist.angular, v[3:6])
    msg.twist.covariance = v[6:]
    return msg


def _random_reference(rng):
    msg = _random_stamped(TwistStamped, rng)
    v = _random_doubles(6, rng, 0.1)
    conv._set_xyz(msg.twist.linear, v[:3])
    conv._set_xyz(msg.twist.angular, v[3:])
    return msg


def _random_pitch(rng):
    msg = _random_stamped(BladePitch, rng)
    msg.pitch = _random_doubles(4, rng, 0.1)
    return msg


def _same(a, b):
    """Equal bit for bit (NaNs and signed zeros included), arrays read-only like the typed path's."""
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def _outcome(convert, *args):
    try:
        return "ok", convert(*args)
    except (ContractError, InvalidBladePitchError) as exc:
        return type(exc), str(exc)


@pytest.mark.parametrize("seed", range(3))
def test_velocity_bytes_read_as_velocity_from_msg_reads_the_message(seed):
    rng = np.random.default_rng(seed)
    fast = 0
    for _ in range(300):
        msg = _random_velocity(rng)
        data = serialize_message(msg)
        typed = _outcome(conv.velocity_from_msg, msg)
        decoded = decode_velocity(data)
        if decoded is None:   # the caller goes the typed way: only for what the typed path refuses or another frame
            assert typed[0] != "ok" or msg.header.frame_id != frames.FRAME_FRD
            continue
        fast += 1
        t_ns, velocity, rates = decoded
        assert typed[0] == "ok" and t_ns == conv.stamp_to_ns(msg.header.stamp)
        for mine, theirs in zip((velocity, rates), typed[1]):
            assert mine.stamp == theirs.stamp
            assert _same(mine.value, theirs.value) and _same(mine.variance, theirs.variance)
            assert not mine.value.flags.writeable and not mine.variance.flags.writeable
    assert fast > 50


@pytest.mark.parametrize("seed", range(3))
def test_reference_and_blade_pitch_bytes_read_as_the_typed_conversions(seed):
    rng = np.random.default_rng(100 + seed)
    fast = 0
    for _ in range(300):
        ref, pitch = _random_reference(rng), _random_pitch(rng)
        decoded = _outcome(decode_reference, serialize_message(ref))
        if decoded != ("ok", None):
            fast += 1
            typed = _outcome(conv.reference_from_msg, ref)
            assert decoded[0] == typed[0]
            if typed[0] == "ok":
                assert decoded[1][0] == conv.stamp_to_ns(ref.header.stamp)
                assert _same(decoded[1][1].velocity, typed[1].velocity)
            else:
                assert decoded[1] == typed[1]   # the same refusal, word for word
        else:
            assert ref.header.frame_id not in ("", frames.FRAME_FRD)
        decoded = _outcome(decode_blade_pitch, serialize_message(pitch))
        if decoded != ("ok", None):
            typed = _outcome(conv.command_from_msg, pitch)
            assert decoded[0] == typed[0]
            if typed[0] == "ok":
                t_ns, command = decoded[1]
                assert t_ns == conv.stamp_to_ns(pitch.header.stamp) and command.stamp == typed[1].stamp
                assert _same(command.blade_pitch, typed[1].blade_pitch)
            else:
                assert decoded[1] == typed[1]
        else:
            assert pitch.header.frame_id not in ("", frames.FRAME_FRD)
    assert fast > 100


def test_blade_pitch_values_are_the_messages_as_sent_checked_or_not():
    """What the simulator reads of a command: stamp and pitches as rclpy deserialises them (a non-finite pitch
    included: the simulator's gate refuses and counts it), None for a frame the typed path must read."""
    rng = np.random.default_rng(7)
    read = 0
    for _ in range(300):
        pitch = _random_pitch(rng)
        values = blade_pitch_values(serialize_message(pitch))
        if values is None:
            assert pitch.header.frame_id not in ("", frames.FRAME_FRD)
            continue
        read += 1
        typed = deserialize_message(serialize_message(pitch), BladePitch)
        assert values[0] == conv.stamp_to_ns(typed.header.stamp)
        assert _same(np.array(values[1]), np.array(typed.pitch))
    assert read > 100


def test_clock_bytes_read_as_the_message():
    rng = np.random.default_rng(3)
    for _ in range(100):
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = int(rng.integers(-2**31, 2**31)), int(rng.integers(0, 10**9))
        assert decode_clock(serialize_message(msg)) == conv.stamp_to_ns(msg.clock)


@pytest.mark.parametrize("msg_type, make, decode", [
    (TwistWithCovarianceStamped, _random_velocity, decode_velocity),
    (TwistStamped, _random_reference, decode_reference),
    (BladePitch, _random_pitch, decode_blade_pitch),
    (Clock, lambda rng: Clock(), decode_clock)])
def test_short_long_and_foreign_bytes_are_never_decoded(msg_type, make, decode):
    """Cut, lengthened, big-endian or garbage bytes: the fast readers say None (the caller then asks rclpy,
    which refuses what it cannot read), never a guess."""
    rng = np.random.default_rng(5)
    for _ in range(50):
        msg = make(rng)
        if hasattr(msg, "header"):
            msg.header.frame_id = "base_link_frd"
        data = serialize_message(msg)
        for cut in {0, 1, 4, 11, 12, len(data) // 2, len(data) - 8, len(data) - 1} - {len(data)}:
            assert decode(data[:cut]) is None
            with pytest.raises(Exception):   # rclpy refuses them too
                deserialize_message(data[:cut], msg_type)
        assert decode(data + b"\x00" * 8) is None   # rclpy reads it (ignores the tail): the caller does too
        assert decode(b"\x00\x00\x00\x00" + data[4:]) is None    # big-endian CDR
        assert decode(data[:4] + b"\x00" * (len(data) - 4)) is None or msg_type is Clock   # a zero-length frame


def test_a_stamped_doubles_reader_refuses_a_message_with_other_fields():
    with pytest.raises(TypeError, match="float64"):
        StampedDoubles(Range, [""])
