"""seapup_msgs interfaces: generated, importable, and round-trip through rclpy.serialization."""
import math

from rclpy.serialization import deserialize_message, serialize_message
from seapup_msgs.action import SelfTest
from seapup_msgs.msg import BladePitch


def test_blade_pitch_index_constants_follow_table_3_2():
    assert (BladePitch.MAIN_PORT, BladePitch.MAIN_STARBOARD,
            BladePitch.VECTORED_STARBOARD, BladePitch.VECTORED_PORT, BladePitch.COUNT) == (0, 1, 2, 3, 4)


def test_blade_pitch_core_indices_match_the_message():
    from seapup_common import blade_pitch as bp
    assert (bp.MAIN_PORT, bp.MAIN_STARBOARD, bp.VECTORED_STARBOARD, bp.VECTORED_PORT) == (
        BladePitch.MAIN_PORT, BladePitch.MAIN_STARBOARD, BladePitch.VECTORED_STARBOARD,
        BladePitch.VECTORED_PORT)


def test_blade_pitch_round_trip_is_exact():
    msg = BladePitch()
    msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 200_000_000
    msg.header.frame_id = "base_link_frd"
    msg.pitch = [math.radians(-3.38), math.radians(-3.38), math.radians(-13.1), math.pi / 7]
    data = serialize_message(msg)
    # CDR: 4-byte encapsulation, then the body: Header (stamp 8, string length 4
    # + 13 chars + NUL = 26 bytes), padding to the 8-byte float64 alignment (32),
    # then 4 float64
    assert len(data) == 4 + 26 + 6 + 4 * 8
    back = deserialize_message(data, BladePitch)
    assert back == msg


def test_blade_pitch_wire_format_carries_exactly_four_pitches():
    # The generated Python setter does not check the fixed length (seen with the
    # Jazzy wheels): a 5-element array is truncated by the serializer, and a
    # shorter one would be padded from memory. Senders must build 4 values; the
    # simulator's gate checks what it receives.
    msg = BladePitch()
    msg.pitch = [0.1, 0.2, 0.3, 0.4, 0.5]
    back = deserialize_message(serialize_message(msg), BladePitch)
    assert list(back.pitch) == [0.1, 0.2, 0.3, 0.4]


def test_self_test_action_types_round_trip():
    goal = SelfTest.Goal(surge_speed=0.7, step_amplitude=math.radians(8), sample_period=0.2)
    assert deserialize_message(serialize_message(goal), SelfTest.Goal) == goal
    result = SelfTest.Result(success=True, message="ok")
    result.b0_inverse = [float(i) for i in range(16)]
    assert deserialize_message(serialize_message(result), SelfTest.Result) == result
    fb = SelfTest.Feedback(thruster_index=BladePitch.VECTORED_PORT, progress=0.5, stage="stepping")
    assert deserialize_message(serialize_message(fb), SelfTest.Feedback) == fb
