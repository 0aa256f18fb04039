"""Figures of merit against responses with known answers."""
import math

import numpy as np
import pytest

from seapup_control.response_metrics import (limit_cycle, overshoot_percent, rise_time, saturation_time,
                                             settled_value)


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
