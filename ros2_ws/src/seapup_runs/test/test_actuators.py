"""Actuator activity (seapup_runs.actuators) against signals whose answers are known in closed form."""
import math

import numpy as np
import pytest

from seapup_runs.actuators import THRASH_ALLOWANCE_S, actuator_activity

LIMIT = math.radians(35.0)
DT = 0.2


def test_a_slow_full_range_sine_never_swings_and_its_fastest_change_is_the_sampled_derivative():
    """pitch = L sin(w t), w = 2 pi / 20 s: one-sample changes at most 2 L sin(w dt / 2) (analytic), far below
    a swing; saturated only at the crests (the samples where |sin| = 1 to rounding)."""
    t = np.arange(0.0, 60.0 + 1e-9, DT)
    w = 2 * math.pi / 20.0
    pitch = np.column_stack([LIMIT * np.sin(w * t), -LIMIT * np.sin(w * t)])
    a = actuator_activity(t, pitch, LIMIT)
    assert a["max_step_deg"] == pytest.approx(math.degrees(2 * LIMIT * math.sin(w * DT / 2)), rel=1e-3)
    assert a["max_rate_deg_s"] == pytest.approx(a["max_step_deg"] / DT)
    assert a["swings_per_min"] == 0 and a["thrash_s"] == 0 and not a["thrashed"] and math.isnan(a["thrash_t"])
    crests = np.sum(np.abs(np.sin(w * t)) >= 1 - 1e-9)
    assert a["saturation_pct"] == pytest.approx(100 * crests / len(t))


def test_chatter_between_the_limits_thrashes_for_as_long_as_it_lasts():
    """Calm at 0.1 rad, then 18 s of bang-bang between the limits on every thruster from t = 10 s (the demo's
    GMV leg once: 90 samples, -L first), then calm again: one episode from the jump into it (0.1 to -L, more
    than the limit) to the last jump between the limits, 18 s less a sample; 90 swings per thruster (the
    jump back from +L to 0.1 is less than the limit)."""
    t = np.arange(0.0, 60.0 + 1e-9, DT)
    pitch = np.full((len(t), 4), 0.1)
    chatter = (t >= 10.0 - 1e-9) & (t < 28.0 - 1e-9)
    pitch[chatter] = np.where(np.arange(chatter.sum()) % 2, LIMIT, -LIMIT)[:, None]
    a = actuator_activity(t, pitch, LIMIT)
    assert chatter.sum() == 90
    assert a["thrashed"] and a["thrash_t"] == pytest.approx(10.0)
    assert a["thrash_s"] == pytest.approx(18.0 - DT)   # from the first swing's sample to the last one's
    assert a["swings_per_min"] == pytest.approx(90.0)  # 90 swings in the 60 s
    assert a["max_step_deg"] == pytest.approx(70.0) and a["max_rate_deg_s"] == pytest.approx(350.0)
    assert a["saturation_pct"] == pytest.approx(100 * chatter.sum() / len(t))


def test_thrashing_within_the_thesis_s_commissioning_allowance_is_not_thrashing():
    """Three swings 0.4 s apart (a 0.8 s episode, shorter than the 1.6 s the thesis accepts) is counted, not
    flagged; the same three swings spread 2 s apart are three episodes of zero length; four swings 0.6 s apart
    (1.8 s) are flagged."""
    t = np.arange(0.0, 30.0 + 1e-9, DT)

    def with_swings(times):
        p = np.zeros((len(t), 1))
        sign = 1.0
        for s in times:
            p[t >= s - 1e-9] = sign * LIMIT
            sign = -sign
        return p
    short = actuator_activity(t, with_swings([5.0, 5.4, 5.8]), LIMIT)
    assert not short["thrashed"] and short["thrash_s"] == pytest.approx(0.8) and short["thrash_t"] == pytest.approx(5.0)
    apart = actuator_activity(t, with_swings([5.0, 7.0, 9.0]), LIMIT)
    assert apart["thrash_s"] == 0 and not apart["thrashed"]
    longer = actuator_activity(t, with_swings([5.0, 5.6, 6.2, 6.8]), LIMIT)
    assert longer["thrashed"] and longer["thrash_s"] == pytest.approx(1.8) and 1.8 > THRASH_ALLOWANCE_S
    # the first "swing" from 0 to +L is a change of exactly the limit: a swing by definition (half the range)
    assert short["swings_per_min"] == pytest.approx(3 / 0.5)


def test_bad_input_is_refused_with_the_reason():
    t = np.arange(5) * DT
    with pytest.raises(ValueError, match="5 times for 4 rows"):
        actuator_activity(t, np.zeros((4, 2)), LIMIT)
    with pytest.raises(ValueError, match="non-finite"):
        actuator_activity(t, np.array([0, 0, math.nan, 0, 0.0]), LIMIT)
    with pytest.raises(ValueError, match="increase"):
        actuator_activity(t[::-1], np.zeros(5), LIMIT)
    with pytest.raises(ValueError, match="positive"):
        actuator_activity(t, np.zeros(5), 0.0)
    empty = actuator_activity([], np.zeros((0, 4)), LIMIT)
    assert empty["samples"] == 0 and not empty["thrashed"]
