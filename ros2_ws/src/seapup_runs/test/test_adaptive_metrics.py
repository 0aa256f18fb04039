"""The ``adaptive`` metric's pieces on signals whose answers are known: a parameter trace settling at a known
sample, first-order square-wave responses with an analytic 95 % rise time, and a recovery after a change."""
import math

import numpy as np
import pytest

from seapup_runs.adaptive_metrics import CONVERGED_FRACTION, _square, converged_sample

pytestmark = pytest.mark.unit


def test_a_trace_converges_where_it_last_leaves_its_band():
    k = np.arange(300, dtype=float)
    settling = 1.0 - np.exp(-k / 20.0)            # within 5 % of 1 from k = 20 ln 20 = 59.9 on
    flat_then_kick = np.full(300, 2.0)
    flat_then_kick[200] = 3.0                      # one excursion at 200: converged only after it
    assert converged_sample(settling[:, None]) == math.ceil(20.0 * math.log(1.0 / CONVERGED_FRACTION))
    assert converged_sample(np.column_stack([settling, flat_then_kick])) == 201
    assert converged_sample(np.column_stack([settling, flat_then_kick]), start=250) == 250
    noisy = 1.0 + 0.2 * np.sin(k)                  # never within 5 % of its last value for good
    assert converged_sample(noisy[:, None]) >= 295
    assert converged_sample(np.full((1, 2), 1.0)) is None


def test_square_wave_steps_are_measured_each_with_the_first_order_rise():
    """y follows each step as 1 - exp(-t/tau): the 95 % rise is tau ln 20 after each 'on' step."""
    tau, dt = 0.5, 0.01
    t = np.arange(0.0, 40.0, dt)
    steps = [(0.0, np.array([0.5, 0, 0, 0])), (10.0, np.zeros(4)), (20.0, np.array([0.5, 0, 0, 0])), (30.0, np.zeros(4))]
    y = np.zeros((len(t), 4))
    for k in range(1, len(t)):
        target = [r for t0, r in steps if t0 <= t[k - 1] + 1e-12][-1]
        y[k] = target + (y[k - 1] - target) * math.exp(-dt / tau)
    out = _square(t, y, steps, 40.0)
    assert set(out) == {"u"} and len(out["u"]["cycles"]) == 2
    for cycle in out["u"]["cycles"]:
        assert cycle["rise95_s"] == pytest.approx(tau * math.log(20.0), abs=2 * dt)
        assert cycle["overshoot_pct"] == pytest.approx(0.0, abs=1e-6)
        assert abs(cycle["steady_error_pct"]) < 0.01
    assert out["u"]["later"]["rise95_s"] == out["u"]["cycles"][1]["rise95_s"]
