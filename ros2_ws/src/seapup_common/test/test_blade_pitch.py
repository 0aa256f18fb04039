"""Tests of seapup_common.blade_pitch: the gate in front of the vehicle model."""
import math
import re

import numpy as np
import pytest

from seapup_common.blade_pitch import (CommandGate, InvalidBladePitchError, MAIN_PORT,
                                    VECTORED_PORT, check_blade_pitch, within_limits)

LIMIT = math.radians(35.0)


def test_valid_command_passes_unchanged():
    cmd = [0.1, -0.2, 0.3, -0.4]
    out, n = check_blade_pitch(cmd, LIMIT)
    assert n == 0
    np.testing.assert_array_equal(out, cmd)


def test_saturates_to_the_blade_limit_and_counts():
    out, n = check_blade_pitch([1.0, -1.0, 0.2, LIMIT], LIMIT)
    assert n == 2
    np.testing.assert_array_equal(out, [LIMIT, -LIMIT, 0.2, LIMIT])


@pytest.mark.parametrize("bad", [
    [math.nan, 0, 0, 0], [0, math.inf, 0, 0], [0, 0, -math.inf, 0],
    [0, 0, 0], [0, 0, 0, 0, 0], [], [[0, 0], [0, 0]], "abcd", [None, 0, 0, 0],
])
def test_rejects_non_finite_and_wrong_length(bad):
    with pytest.raises(InvalidBladePitchError):
        check_blade_pitch(bad, LIMIT)


@pytest.mark.parametrize("values", [[0.1, -0.2, 0.3, -0.4], [LIMIT, -LIMIT, -0.0, 0.0], [1.0, -0.2, 0.3, -0.4],
                                    [math.nan, 0.0, 0.0, 0.0], [0.0, math.inf, 0.0, 0.0]])
def test_a_float_array_gives_what_a_list_of_the_same_values_gives(values):
    """The float64 (4,) array of a controller (checked on a fast path) against the same values as a list:
    equal results bit for bit (a new array, the sign of zero kept, clipped and counted alike), equal refusals."""
    array = np.array(values)
    try:
        expected = check_blade_pitch(list(values), LIMIT)
    except InvalidBladePitchError as exc:
        with pytest.raises(InvalidBladePitchError, match=re.escape(str(exc))):
            check_blade_pitch(array, LIMIT)
        return
    out, n = check_blade_pitch(array, LIMIT)
    assert out is not array and n == expected[1]
    np.testing.assert_array_equal(out, expected[0])
    assert np.signbit(out).tolist() == np.signbit(expected[0]).tolist()
    out[0] = 9.0
    assert array[0] == values[0]   # the caller's array untouched


def test_within_limits_says_yes_only_to_what_the_check_passes_unchanged():
    assert within_limits(np.array([0.1, -0.2, LIMIT, -LIMIT]), LIMIT)
    for no in ([0.1, 0.1, 0.1, 0.1], np.array([0.1, 0.1, 0.1, 1.0]), np.array([math.nan, 0, 0, 0.0]),
               np.array([0, 0, 0, 0]), np.zeros(5), np.zeros((2, 2)), np.zeros(4, dtype=np.float32)):
        assert not within_limits(no, LIMIT), no


def test_error_names_the_thruster():
    with pytest.raises(InvalidBladePitchError, match="main_port.*vectored_port"):
        check_blade_pitch([math.nan, 0.0, 0.0, math.inf], LIMIT)


def test_bad_limit_is_refused():
    for limit in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError):
            check_blade_pitch([0, 0, 0, 0], limit)


def test_gate_counts_and_keeps_last_valid_command():
    gate = CommandGate(limit=LIMIT)
    first = gate.submit([0.1, 0.1, -0.2, -0.2])
    assert gate.submit([math.nan, 0, 0, 0]) is None
    assert gate.submit([0, 0, 0]) is None
    clipped = gate.submit([2.0, 0, 0, -2.0])
    assert gate.counters() == {"accepted": 2, "rejected": 2, "saturated": 2}
    assert clipped[MAIN_PORT] == LIMIT and clipped[VECTORED_PORT] == -LIMIT
    assert "shape (3,)" in gate.last_error
    np.testing.assert_array_equal(gate.last, clipped)
    # the returned arrays are copies: mutating them cannot change the gate
    first[:] = 9.0
    clipped[:] = 9.0
    assert np.all(np.abs(gate.last) <= LIMIT)


def test_gate_before_any_command_has_no_last():
    assert CommandGate(limit=LIMIT).last is None
