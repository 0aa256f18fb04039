"""Figures of merit against responses with known answers."""
import math

import numpy as np
import pytest

from seapup_control.response_metrics import (MetricError, Settled, limit_cycle, overshoot_percent, rise_time,
                                             saturation_time, settle, settled_value)


def test_rise_time_of_first_and_second_order_steps():
    t = np.linspace(0.0, 20.0, 20001)
    assert rise_time(t, 0.85 * (1 - np.exp(-t / 2.0)), 0.85) == pytest.approx(-2.0 * math.log(0.05), rel=1e-4)
    # decreasing steps and a non-zero start
    assert rise_time(t, 1.0 - 0.5 * (1 - np.exp(-t)), 0.5, start=1.0) == pytest.approx(-math.log(0.05), rel=1e-4)
    assert math.isnan(rise_time(t, 0.26 * (1 - np.exp(-t)), 0.29))  # never reaches 95 % of 0.29


def test_overshoot_of_an_underdamped_second_order_step():
    zeta, wn = 0.5, 2.0
    t = np.linspace(0.0, 20.0, 40001)
    wd = wn * math.sqrt(1 - zeta ** 2)
    y = 1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta ** 2) * np.sin(wd * t))
    expected = 100 * math.exp(-zeta * math.pi / math.sqrt(1 - zeta ** 2))  # 16.3 %
    assert overshoot_percent(y, 1.0) == pytest.approx(expected, rel=1e-4)
    assert overshoot_percent(1 - np.exp(-t), 1.0) == 0.0
    assert settled_value(t, y, 2.0) == pytest.approx(1.0, abs=1e-3)


def test_a_decaying_exponential_settles_and_its_mean_is_the_analytic_one():
    t = np.arange(0.0, 10.0 + 1e-9, 0.2)
    y = 0.85 * (1 - np.exp(-t / 1.5))
    s = settle(t, y, 1.0)
    last = t >= 9.0 - 1e-9                                        # 6 samples: 9.0, 9.2, ..., 10.0
    assert isinstance(s, Settled) and s.settled and s.window_s == 1.0
    assert s.value == pytest.approx(np.mean(0.85 * (1 - np.exp(-t[last] / 1.5))), rel=1e-12)
    assert (s.low, s.high) == pytest.approx((0.85 * (1 - math.exp(-9 / 1.5)), 0.85 * (1 - math.exp(-10 / 1.5))))
    assert s.value == settled_value(t, y, 1.0)
    # earlier, still rising by more than 5 % of its value within the window: not settled
    assert not settle(t[t <= 2.0], y[t <= 2.0], 1.0).settled


def test_a_sustained_sine_does_not_settle_and_its_window_mean_is_its_offset():
    period, dt = 5.6, 0.2
    t = np.arange(0.0, 30.0, dt)
    for phase in (0.0, 0.7, 2.0):
        y = 20.0 + 5.0 * np.sin(2 * np.pi * t / period + phase)
        # a window of 2 periods less one step holds 2 periods' worth of samples (56 = 2 * 28)
        s = settle(t, y, 2 * period - dt)
        assert not s.settled and s.value == pytest.approx(20.0, abs=1e-12)
        assert s.high - s.low == pytest.approx(10.0, abs=0.1) and s.tolerance == pytest.approx(1.0)
    # a tolerance wider than the swing (relative 30 % of 20 = 6 > 5) calls it settled
    assert settle(t, 20.0 + 5.0 * np.sin(t), 2.0, relative=0.3).settled


def test_the_floor_keeps_a_signal_settled_at_zero_from_being_judged_on_its_noise():
    t = np.arange(0.0, 10.0, 0.2)
    y = 1e-4 * np.sin(7 * t)
    assert not settle(t, y, 2.0).settled                                  # 5 % of ~0
    s = settle(t, y, 2.0, floor=0.01)
    assert s.settled and s.tolerance == 0.01
    assert s.as_dict() == {"final": s.value, "settled": True, "window_s": 2.0, "range": [s.low, s.high],
                           "tolerance": 0.01}


def test_settle_refuses_a_window_it_cannot_answer_for():
    t = np.arange(0.0, 10.0, 0.2)
    for window in (0.0, -1.0, math.nan, 20.0):
        with pytest.raises(MetricError, match="window must be in"):
            settle(t, np.ones_like(t), window)
    with pytest.raises(MetricError, match="window must be in"):
        settled_value(t, np.ones_like(t), 20.0)
    with pytest.raises(MetricError, match="relative and floor"):
        settle(t, np.ones_like(t), 1.0, relative=-0.1)


def test_saturation_time_counts_held_samples_at_the_limit():
    t = np.arange(0, 2.0, 0.2)
    command = np.zeros((10, 4))
    command[2:6, 0] = 0.6109
    command[3, 1] = -0.6109
    np.testing.assert_allclose(saturation_time(t, command, 0.6109), [0.8, 0.2, 0.0, 0.0])


def test_limit_cycle_found_with_its_period_and_not_in_a_decay_or_noise():
    t = np.arange(0, 20.0, 0.2)
    rng = np.random.default_rng(0)
    cycle = limit_cycle(t, 0.02 * np.sin(2 * np.pi * t / 6.2) + 0.001 * rng.normal(size=t.size) + 0.01 * t, 0.005)
    assert cycle.detected and cycle.period == pytest.approx(6.2, rel=0.05) and cycle.amplitude > 0.035
    assert not limit_cycle(t, 0.1 * np.exp(-t), 0.005).detected
    assert not limit_cycle(t, 0.001 * rng.normal(size=t.size), 0.005).detected  # too small to count
    assert not limit_cycle(t, 0.02 * rng.normal(size=t.size), 0.005).detected   # large, but not periodic
    fast = limit_cycle(t, 0.01 * np.sign(np.sin(2 * np.pi * t / 2.0)), 0.005)
    assert fast.detected and fast.period == pytest.approx(2.0, rel=0.05)


def _rise_time_reference(t, y, target, start=None, fraction=0.95):
    """rise_time as written before it worked on rows (issue 42): the scalar search and interpolation."""
    y0 = y[0] if start is None else float(start)
    level = y0 + fraction * (target - y0)
    sign = 1.0 if target >= y0 else -1.0
    above = np.flatnonzero(sign * (y - level) >= 0)
    if above.size == 0:
        return math.nan
    k = int(above[0])
    if k == 0:
        return 0.0
    frac = (level - y[k - 1]) / (y[k] - y[k - 1])
    return float(t[k - 1] + frac * (t[k] - t[k - 1]) - t[0])


def test_rise_times_and_overshoots_of_many_rows_are_the_one_row_figures_bit_for_bit():
    """A campaign's metrics work on all its runs at once: each row's rise time and overshoot are the scalar
    search's, to the bit -- rising and falling steps, from the first sample or a given start, a row that never
    gets there, one there at once, one with a NaN."""
    from seapup_control.response_metrics import overshoot_percents, rise_times
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 10.0, 0.2)
    lag = 1.0 - np.exp(-t / rng.uniform(0.3, 3.0, (40, 1)))
    rows = np.vstack([0.3 * lag + 0.01 * rng.standard_normal(lag.shape),      # rising, noisy
                      0.3 - 0.25 * lag,                                         # falling from 0.3
                      0.1 * lag,                                                # never reaches 0.3
                      np.full((1, t.size), 0.31)])                              # there from the first sample
    rows[5, 7] = math.nan
    for target, start in ((0.3, 0.0), (0.3, None), (0.05, 0.3), (-0.2, 0.0)):
        many = rise_times(t, rows, target, start=start)
        one = [_rise_time_reference(t, row, target, start) for row in rows]
        np.testing.assert_array_equal(many, one)
        assert [rise_time(t, row, target, start=start) for row in rows] == pytest.approx(one, nan_ok=True, abs=0)
        expected = [overshoot_percent(row, target, start or 0.0) for row in rows]
        np.testing.assert_array_equal(overshoot_percents(rows, target, start or 0.0), expected)
    assert np.isnan(rise_times(t, rows[80:120], 0.3, start=0.0)).all()          # the row cases meant are there
    assert rise_times(t, rows[-1:], 0.3, start=0.0)[0] == 0.0
    assert np.isnan(overshoot_percents(rows, 0.0, 0.0)).all()    # a zero step has no overshoot
