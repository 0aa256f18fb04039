"""The lockstep timing policy (seapup_common.lockstep), with explicit wall times.

Each rule is the one the controller nodes used to carry inline (where most lockstep bugs lived):
a sample answered once, past samples not pending, resets followed, and the waits for the applied
pitch, the first reference and the stream's reference bounded by their settings.
"""
import pytest

from seapup_common.lockstep import ANSWER, SKIP, WAIT, SamplePolicy, WaitSettings

MS = 1_000_000  # ns


def test_each_sample_is_answered_once_and_past_samples_are_not_pending():
    policy = SamplePolicy(True, WaitSettings(applied_wait=0.0))
    assert policy.decide(0, now=0.0).action == SKIP      # not active yet: answers nothing
    policy.activate(heard_applied=True)
    assert policy.on_clock(0) is None                   # t_0 announced, its sample not here
    assert policy.on_sample(0) == 0                     # the sample: answer t_0
    assert policy.on_clock(0) == 0                      # handshake repeat, still unanswered
    policy.answered(0)
    assert policy.on_clock(0) is None                   # answered once only
    assert policy.decide(0, now=0.0).action == SKIP
    assert policy.on_sample(200 * MS) == 200 * MS
    # another node answered 0.2 s (a controller activated just then): the simulator announces 0.4 s
    # before this node hears its sample; 0.2 s is past, answering it would be refused as stale
    assert policy.on_clock(400 * MS) is None
    assert policy.pending(200 * MS) is None and policy.pending(400 * MS) == 400 * MS
    assert policy.decide(200 * MS, now=0.0).action == SKIP
    assert policy.on_sample(400 * MS) == 400 * MS
    policy.on_clock(0)                                  # a reset: time goes back
    assert policy.pending(200 * MS) == 200 * MS          # and 0.2 s is ahead again


def test_timer_mode_never_waits_and_every_time_is_pending():
    policy = SamplePolicy(False, WaitSettings(reference_wait=5.0, first_reference_wait=5.0))
    policy.activate(heard_applied=False)
    assert policy.on_sample(0) is None                  # a timer decides when, not the sample
    assert policy.pending(5) == 5
    policy.on_reference(0.2)
    policy.on_reference(0.4)
    assert policy.decide(600 * MS, now=0.0).action == ANSWER


def test_activation_before_the_applied_pitch_waits_for_it_then_starts_from_it():
    policy = SamplePolicy(True, WaitSettings(applied_wait=0.25))
    policy.on_sample(0)
    assert policy.activate(heard_applied=False) is False
    d = policy.decide(0, now=10.0)
    assert (d.action, d.wake_at) == (WAIT, pytest.approx(10.25))
    assert policy.decide(0, now=10.1).action == WAIT    # still within applied_wait
    assert policy.on_applied(0) is True                 # what it waited for: decide again
    d = policy.decide(0, now=10.12)
    assert (d.action, d.start) == (ANSWER, True)
    policy.answered(0)
    assert policy.decide(0, now=10.13).action == SKIP


def test_activation_without_any_applied_pitch_starts_from_the_fallback_after_applied_wait():
    policy = SamplePolicy(True, WaitSettings(applied_wait=0.25))
    policy.on_sample(0)
    policy.activate(heard_applied=False)
    assert policy.decide(0, now=1.0).action == WAIT
    d = policy.decide(0, now=1.25)
    assert (d.action, d.start) == (ANSWER, True)
    assert policy.decide(0, now=1.3).start is False or policy.decide(0, now=1.3).action == ANSWER
    assert SamplePolicy(True).activate(heard_applied=True) is True   # heard: start at once


def test_inactive_nodes_skip_and_a_reference_wakes_no_one():
    policy = SamplePolicy(True)
    policy.on_sample(0)
    policy.deactivate()
    assert policy.decide(0, now=0.0).action == SKIP
    assert policy.on_reference(0.0) is False and policy.on_applied(0) is False


def test_the_first_sample_waits_for_the_first_reference_at_most_first_reference_wait():
    policy = SamplePolicy(True, WaitSettings(first_reference_wait=30.0))
    policy.activate(heard_applied=True)
    policy.on_sample(0)
    assert policy.decide(0, now=0.0).action == WAIT
    assert policy.on_reference(None) is True            # the first reference: decide again
    assert policy.decide(0, now=0.5).action == ANSWER
    late = SamplePolicy(True, WaitSettings(first_reference_wait=2.0))
    late.activate(heard_applied=True)
    late.on_sample(0)
    assert late.decide(0, now=0.0).wake_at == pytest.approx(2.0)
    d = late.decide(0, now=2.0)                          # waited its limit: on with the reference in force
    assert (d.action, d.late) == (ANSWER, ("reference",)) and late.late["references"] == 1


def test_while_references_stream_a_sample_waits_for_its_own_reference():
    policy = SamplePolicy(True, WaitSettings(reference_wait=0.2, reference_stream=1.0))
    policy.activate(heard_applied=True)
    policy.on_reference(0.2)
    policy.on_reference(0.4)                             # a stream: two stamps 0.2 s apart
    policy.on_sample(600 * MS)
    d = policy.decide(600 * MS, now=5.0)                 # newest 0.4 < 0.6: its reference is not here
    assert (d.action, d.wake_at) == (WAIT, pytest.approx(5.2))
    assert policy.on_reference(0.6) is True
    assert policy.decide(600 * MS, now=5.05).action == ANSWER
    policy.answered(600 * MS)
    policy.on_sample(800 * MS)
    assert policy.decide(800 * MS, now=6.0).action == WAIT
    d = policy.decide(800 * MS, now=6.2)                 # never came: on, counted late
    assert (d.action, d.late) == (ANSWER, ("reference",)) and policy.late["references"] == 1


@pytest.mark.parametrize("stamps, sample_ms", [
    ((0.2,), 600),           # one reference is no stream
    ((0.2, 2.0), 2200),      # two stamps further apart than reference_stream
    ((0.2, 0.4), 3000),      # the stream stopped long before the sample
    ((0.2, 0.4), 400),       # the sample's reference is here (newest >= t)
])
def test_no_stream_no_wait(stamps, sample_ms):
    policy = SamplePolicy(True, WaitSettings(reference_wait=0.2, reference_stream=1.0))
    policy.activate(heard_applied=True)
    for at in stamps:
        policy.on_reference(at)
    policy.on_sample(sample_ms * MS)
    assert policy.decide(sample_ms * MS, now=0.0).action == ANSWER


def test_a_law_that_needs_the_applied_pitch_waits_for_the_samples_own():
    policy = SamplePolicy(True, WaitSettings(applied_wait=0.25, needs_applied=True))
    policy.on_applied(0)
    policy.activate(heard_applied=True)
    policy.on_sample(0)
    assert policy.decide(0, now=0.0).action == ANSWER    # the applied pitch of t_0 is here
    policy.answered(0)
    policy.on_sample(200 * MS)
    assert policy.decide(200 * MS, now=1.0).action == WAIT
    assert policy.on_applied(200 * MS) is True
    assert policy.decide(200 * MS, now=1.01).action == ANSWER
    policy.answered(200 * MS)
    policy.on_sample(400 * MS)
    assert policy.decide(400 * MS, now=2.0).action == WAIT
    d = policy.decide(400 * MS, now=2.25)
    assert (d.action, d.late) == (ANSWER, ("applied",)) and policy.late["applied"] == 1
    # a vehicle that never publishes an applied pitch is not waited for
    silent = SamplePolicy(True, WaitSettings(needs_applied=True))
    silent.activate(heard_applied=True)
    silent.on_sample(0)
    assert silent.decide(0, now=0.0).action == ANSWER


@pytest.mark.parametrize("name", ["applied_wait", "reference_wait", "reference_stream", "first_reference_wait"])
@pytest.mark.parametrize("value", [-1.0, float("nan"), float("inf")])
def test_wait_settings_refuse_negative_and_non_finite_times(name, value):
    with pytest.raises(ValueError, match=name):
        WaitSettings(**{name: value})


def test_a_windowed_controller_answers_only_its_samples_and_starts_from_its_first_samples_applied_pitch():
    policy = SamplePolicy(True, WaitSettings(applied_wait=0.25, start_at=10.0, stop_at=20.0))
    policy.on_applied(9_800 * MS)
    assert policy.activate(heard_applied=True) is False        # activated ahead: the window starts it
    policy.on_sample(9_800 * MS)
    assert policy.decide(9_800 * MS, now=0.0).action == SKIP    # before the window: another's sample
    policy.on_sample(10_000 * MS)
    d = policy.decide(10_000 * MS, now=1.0)                     # its first sample: the applied pitch of 10 s
    assert (d.action, d.wake_at) == (WAIT, pytest.approx(1.25))
    policy.on_applied(10_000 * MS)
    d = policy.decide(10_000 * MS, now=1.01)
    assert (d.action, d.start, d.late) == (ANSWER, True, ())
    policy.answered(10_000 * MS)
    policy.on_sample(20_000 * MS)
    assert policy.decide(20_000 * MS, now=2.0).action == SKIP   # the window ended
    lost = SamplePolicy(True, WaitSettings(applied_wait=0.25, start_at=1.0))
    lost.activate(heard_applied=False)
    lost.on_sample(1_000 * MS)
    d = lost.decide(1_000 * MS, now=3.25 + 1e-9) if lost.decide(1_000 * MS, now=3.0).action == WAIT else None
    assert (d.action, d.start, d.late) == (ANSWER, True, ("applied",))
    with pytest.raises(ValueError, match="stop_at"):
        WaitSettings(start_at=5.0, stop_at=5.0)


def test_with_a_reference_every_sample_each_sample_waits_for_its_own_even_before_a_stream():
    policy = SamplePolicy(True, WaitSettings(reference_wait=0.2, reference_every_sample=True))
    policy.activate(heard_applied=True)
    policy.on_sample(0)
    assert policy.decide(0, now=0.0).action == ANSWER         # nothing heard yet: nothing to wait for
    policy.answered(0)
    policy.on_reference(0.0)                                  # one reference: no stream, yet
    policy.on_sample(200 * MS)
    assert policy.decide(200 * MS, now=1.0).action == WAIT    # waits for the one stamped 0.2 s
    assert policy.on_reference(0.2) is True
    assert policy.decide(200 * MS, now=1.01).action == ANSWER


def test_with_a_reference_every_sample_a_first_one_stamped_zero_starts_the_stream():
    """The reference schedule stamps its first reference 0, which the controller node reads as "no stamp": it is
    still t = 0's, so sample 0.2 waits for its own (a fresh clone's suite once raced a slow schedule for 28
    samples); without reference_every_sample an unstamped reference starts no stream."""
    policy = SamplePolicy(True, WaitSettings(reference_wait=0.2, reference_every_sample=True))
    policy.activate(heard_applied=True)
    policy.on_sample(0)
    policy.on_reference(None)                                 # t = 0's reference, stamp 0
    assert policy.decide(0, now=0.0).action == ANSWER
    policy.answered(0)
    policy.on_sample(200 * MS)
    assert policy.decide(200 * MS, now=1.0).action == WAIT    # waits for the one stamped 0.2 s
    assert policy.decide(200 * MS, now=1.25).action == ANSWER  # up to reference_wait, then goes on (late)
    assert policy.late["references"] == 1
    loose = SamplePolicy(True, WaitSettings(reference_wait=0.2))
    loose.activate(heard_applied=True)
    loose.on_reference(None)
    loose.on_sample(200 * MS)
    assert loose.decide(200 * MS, now=1.0).action == ANSWER   # unstamped: in force at once, no stream


def test_the_stamp_gate_refuses_a_far_future_stamp_follows_resets_and_resyncs_a_real_jump():
    from seapup_common.lockstep import StampGate
    s = 10**9
    gate = StampGate(max_jump=60.0, resync_after=3)
    assert gate.accept(10 * s) and gate.accept(10 * s + s // 5)
    assert not gate.accept(10**6 * s) and gate.refused == 1            # one hostile stamp: refused
    assert gate.accept(11 * s) and gate.latest_ns == 11 * s            # real samples go on
    assert gate.accept(70 * s) and gate.latest_ns == 70 * s
    assert gate.accept(0) and gate.latest_ns == 0                      # a reset (time back to 0)
    assert gate.accept(5 * s) and gate.latest_ns == 5 * s
    assert gate.accept(4 * s) and gate.latest_ns == 5 * s              # a little late: changes nothing
    # the source really jumped 1000 s ahead: after three consistent refusals the gate follows it
    assert [gate.accept((1000 + k) * s) for k in range(4)] == [False, False, True, True]
    assert "ahead of the graph's time" in StampGate().why(10**18)
    with pytest.raises(ValueError):
        StampGate(max_jump=float("nan"))


def test_a_controller_activated_at_a_sample_the_vehicle_already_has_starts_at_the_next_from_its_applied_pitch():
    # the graph is held at t = 1.0 s, whose answer (the outgoing controller's) was forwarded: the incoming
    # one must not answer 1.0 s again (the manager would drop it and the law would have stepped on a command
    # never applied), but start at 1.2 s from the pitch applied up to 1.2 s -- the outgoing one's answer
    policy = SamplePolicy(True, WaitSettings(applied_wait=0.25))
    policy.on_applied(1_000 * MS)
    policy.on_sample(1_000 * MS)
    policy.on_clock(1_000 * MS)
    policy.on_vehicle_command(1_000 * MS)
    assert policy.activate(heard_applied=True) is False
    assert policy.decide(1_000 * MS, now=0.0).action == SKIP          # the held sample is not its own
    policy.on_sample(1_200 * MS)
    policy.on_clock(1_200 * MS)
    d = policy.decide(1_200 * MS, now=1.0)                            # waits for 1.2 s's applied pitch
    assert (d.action, d.wake_at) == (WAIT, pytest.approx(1.25))
    policy.on_applied(1_200 * MS)
    d = policy.decide(1_200 * MS, now=1.01)
    assert (d.action, d.start, d.late) == (ANSWER, True, ())
    # activated while the newest sample still waits for its answer: that sample is the incoming one's
    pending = SamplePolicy(True, WaitSettings(applied_wait=0.25))
    pending.on_applied(1_000 * MS)
    pending.on_vehicle_command(800 * MS)
    pending.on_sample(1_000 * MS)
    assert pending.activate(heard_applied=True) is True               # starts at once, from what is applied
    assert pending.decide(1_000 * MS, now=0.0).action == ANSWER
    # a simulator reset (the clock goes back) forgets the commands heard before it
    pending.on_clock(1_000 * MS)
    pending.on_clock(0)
    assert pending.commanded_ns is None
