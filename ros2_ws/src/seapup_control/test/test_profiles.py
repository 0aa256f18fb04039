"""Tests of seapup_control.profiles (piecewise-constant blade-pitch inputs and velocity references)."""
import math

import numpy as np
import pytest

from seapup_control.profiles import PitchProfile, ReferenceProfile, ProfileError

LIMIT = math.radians(35.0)
SURGE = [[LIMIT, LIMIT, 0, 0], [0, 0, 0, 0]]  # Table 3.2 style: mains full ahead, then off


def test_holds_each_row_until_the_next_switch():
    s = PitchProfile([0.0, 10.0], SURGE, LIMIT)
    np.testing.assert_array_equal(s.at(0.0), SURGE[0])
    np.testing.assert_array_equal(s.at(9.999), SURGE[0])
    np.testing.assert_array_equal(s.at(10.0), SURGE[1])
    np.testing.assert_array_equal(s.at(1e6), SURGE[1])
    assert s.duration == 10.0


def test_flat_pitch_list_as_in_the_yaml():
    s = PitchProfile([0.0, 1.0], np.ravel(SURGE), LIMIT)
    np.testing.assert_array_equal(s.pitches, SURGE)


def test_returned_rows_are_copies():
    s = PitchProfile([0.0], [[0.1, 0.1, 0.1, 0.1]], LIMIT)
    s.at(0.0)[:] = 5.0
    assert s.at(0.0)[0] == 0.1


@pytest.mark.parametrize("times,pitches", [
    ([], []),
    ([1.0], [0, 0, 0, 0]),              # does not start at 0
    ([0.0, 0.0], [0] * 8),              # not strictly increasing
    ([0.0, math.nan], [0] * 8),
    ([0.0], [0, 0, 0]),                 # wrong count
    ([0.0, 1.0], [[0, 0, 0, 0]]),
    ([0.0], [1.0, 0, 0, 0]),            # beyond the blade limit
    ([0.0], [math.nan, 0, 0, 0]),
])
def test_inconsistent_schedules_are_refused(times, pitches):
    with pytest.raises(ValueError):
        PitchProfile(times, pitches, LIMIT)


@pytest.mark.parametrize("t", [-0.1, math.nan, math.inf])
def test_bad_query_time(t):
    with pytest.raises(ProfileError):
        PitchProfile([0.0], [0, 0, 0, 0], LIMIT).at(t)


def test_reference_schedule_repeats_the_thesis_square_wave():
    """Sec. 6.5.5: half-period 10 s between (0.2, 0, 0, 15 deg/s) and (0, 0.1, -0.1, 0)."""
    high, low = [0.2, 0.0, 0.0, np.radians(15.0)], [0.0, 0.1, -0.1, 0.0]
    s = ReferenceProfile([0.0, 10.0], [high, low], period=20.0)
    for t, expected in ((0.0, high), (9.99, high), (10.0, low), (19.99, low), (20.0, high), (45.0, high),
                        (55.0, low)):
        np.testing.assert_array_equal(s.at(t).velocity, expected)
    held = ReferenceProfile([0.0, 10.0], [high, low])          # no period: the last row for ever
    np.testing.assert_array_equal(held.at(1e6).velocity, low)


@pytest.mark.parametrize("times, references, period, reason", [
    ([0.0, 10.0], [[0.2, 0, 0, 0], [0, 0.1, -0.1, 0]], 10.0, "period"),
    ([0.0, 10.0], [0.2, 0, 0, 0], None, "need 8"),
    ([1.0], [0, 0, 0, 0], None, "start at 0"),
    ([0.0], [np.nan, 0, 0, 0], None, "finite"),
])
def test_reference_schedule_refuses_inconsistent_schedules(times, references, period, reason):
    with pytest.raises(ProfileError, match=reason):
        ReferenceProfile(times, references, period)
