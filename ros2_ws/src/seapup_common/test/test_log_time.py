"""The sim-time log times of the recorder (seapup_common.log_time), with explicit times: no processes."""
import pytest

from seapup_common.log_time import CLOCK_HISTORY, SimLogTime


S = 1_000_000_000          # one second [ns]
T = S // 5                 # a 5 Hz sample period


def lockstep_receipts(log: SimLogTime, samples: int, clock_lag: int = 0, lag_from: int = 0):
    """A lockstep graph's /clock t_k and sample t_k (received 1 ms later), sample k at wall time k ms; from
    sample ``lag_from`` on the recorder's /clock queue is served ``clock_lag`` samples late. The (stamp, log
    time, distrusted) of each sample."""
    out = []
    for k in range(samples):
        for j in ([k] if k < lag_from else [k - clock_lag] if k - clock_lag >= lag_from else []):
            log.on_clock(j * 1_000_000, j * T)
        log_ns, distrusted = log.log_time(k * 1_000_000 + 1, k * T, now_ns=0)
        out.append((k * T, log_ns, distrusted))
    return out


def test_a_sample_is_logged_at_the_clock_of_its_receipt():
    log = SimLogTime(S, 60 * S)
    assert all(stamp == logged and not bad for stamp, logged, bad in lockstep_receipts(log, 50))
    assert log.graph_time_at(10 * 1_000_000 + 5) == 10 * T
    assert log.graph_time_at(-1) is None


def test_a_clock_that_lags_the_samples_by_minutes_takes_no_stamp_for_a_wrong_one():
    """Seen: /clock's queue 300 samples (60 s at 5 Hz) behind the sensors of an unpaced graph; the stamps
    carried the time on, each one sample ahead of the last, so every sample is logged at its own stamp."""
    for lag_from in (0, 100):   # /clock late from the start, or from sample 100 on
        log = SimLogTime(S, 60 * S)
        got = lockstep_receipts(log, 1000, clock_lag=400, lag_from=lag_from)     # 80 s of graph time behind
        assert [logged for _, logged, _ in got] == [stamp for stamp, _, _ in got]
        assert log.distrusted == 0 and log.floor_ns == 999 * T
    # the lagging /clock samples themselves are logged at the time so far, never back in the past
    assert log.log_time(999 * 1_000_000 + 2, None, now_ns=0) == (999 * T, False)


def test_a_wrong_stamp_far_ahead_is_logged_at_the_time_so_far_and_counted():
    log = SimLogTime(S, 60 * S)
    lockstep_receipts(log, 10)
    assert log.log_time(10 * 1_000_000, 9 * T + 3600 * S, now_ns=0) == (9 * T, True)
    assert log.distrusted == 1
    # it raised nothing: the next sample is logged at its own stamp
    log.on_clock(11 * 1_000_000, 10 * T)
    assert log.log_time(11 * 1_000_000 + 1, 10 * T, now_ns=0) == (10 * T, False)


def test_a_stamp_between_lead_and_jump_is_logged_at_itself_but_moves_nothing():
    """A 1 Hz fix stamped 5 s ahead of a lagging /clock: never logged before its stamp; the graph's time so far
    stays where the clock is (a later unstamped message is not pushed 5 s on)."""
    log = SimLogTime(S, 60 * S)
    log.on_clock(0, 10 * S)
    assert log.log_time(1, 15 * S, now_ns=0) == (15 * S, False)
    assert log.floor_ns is None
    assert log.log_time(2, None, now_ns=0) == (10 * S, False)


def test_a_late_message_is_logged_at_the_clock_of_its_receipt_not_its_stamp():
    """A command stamped t_k received after /clock said t_k+3: logged when it came (the recorder is no part
    of the lockstep), not moved back."""
    log = SimLogTime(S, 60 * S)
    for k in range(5):
        log.on_clock(k * 1_000_000, k * T)
    assert log.log_time(4 * 1_000_000 + 1, 1 * T, now_ns=0) == (4 * T, False)


def test_before_the_first_clock_the_stamp_or_the_node_clock_is_the_time():
    log = SimLogTime(S, 60 * S)
    assert log.log_time(5, 7 * S, now_ns=3) == (7 * S, False)
    assert log.log_time(6, None, now_ns=3) == (7 * S, False)   # the stamp raised the time so far
    fresh = SimLogTime(S, 60 * S)
    assert fresh.log_time(6, None, now_ns=3) == (3, False)


def test_a_clock_sample_served_out_of_order_is_not_placed_and_the_history_is_bounded():
    log = SimLogTime(S, 60 * S)
    log.on_clock(100, 5 * S)
    log.on_clock(50, 4 * S)      # received earlier than one already placed
    assert log.graph_time_at(75) is None and log.graph_time_at(100) == 5 * S
    for k in range(3 * CLOCK_HISTORY):
        log.on_clock(200 + k, k)
    assert len(log._clock_wall) <= 2 * CLOCK_HISTORY
    assert log.graph_time_at(200 + 3 * CLOCK_HISTORY - 1) == 3 * CLOCK_HISTORY - 1


def test_negative_limits_are_refused():
    with pytest.raises(ValueError, match="must be >= 0"):
        SimLogTime(-1, S)
