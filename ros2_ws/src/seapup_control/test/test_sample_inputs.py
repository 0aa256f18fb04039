"""A controller's ``/clock`` read from its bytes (``RawSampleFeed.clock``) answers as the typed path does.

Truth: a twin feed given the same messages through rclpy's typed conversion (``SampleFeed``), and what the
feed's policy is left holding. No process is started.
"""
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock

from seapup_common.lockstep import SamplePolicy
from seapup_common.ros.messages import MeasurementCollector, SampleFeed
from seapup_common.ros.sample_bytes import SampleEncoder
from seapup_control.ros.sample_inputs import RawSampleFeed


class Logger:
    def __init__(self):
        self.warnings = []

    def warn(self, text, **_):
        self.warnings.append(text)


def _feed() -> SampleFeed:
    policy = SamplePolicy(True)
    policy.activate(heard_applied=True)
    return SampleFeed(MeasurementCollector(), policy, lambda reason: None)


def test_clock_bytes_answer_as_the_typed_clock():
    """A clock before its sample's reading, after it, said again before and after the answer, a reset."""
    encoder, raw, typed = SampleEncoder(), RawSampleFeed(_feed()), _feed()
    events = [("clock", 0), ("sample", 0), ("clock", 0), ("clock", 0), ("answer", 0), ("clock", 0),
              ("clock", 200_000_000), ("sample", 200_000_000), ("clock", 200_000_000), ("clock", 0)]
    answers = []
    for kind, t_ns in events:
        if kind == "sample":
            raw.feed.policy.on_sample(t_ns), typed.policy.on_sample(t_ns)
        elif kind == "answer":
            raw.feed.policy.answered(t_ns), typed.policy.answered(t_ns)
        else:
            data = encoder.clock(t_ns)
            answers.append((raw.clock(data, Logger()), typed.clock(deserialize_message(data, Clock))))
    assert [a for a, _ in answers] == [b for _, b in answers]
    assert [a for a, _ in answers] == [None, 0, 0, None, None, 200_000_000, None]


def test_unreadable_clock_bytes_are_ignored_with_a_warning():
    raw, logger = RawSampleFeed(_feed()), Logger()
    assert raw.clock(b"\x00\x01\x00\x00\x07", logger) is None
    assert len(logger.warnings) == 1 and logger.warnings[0].startswith("/clock message ignored")
    # the policy is untouched: a real clock afterwards is answered as on a fresh feed
    fresh = RawSampleFeed(_feed())
    data = SampleEncoder().clock(0)
    assert raw.clock(data, logger) == fresh.clock(data, logger)
