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


def _square_reference(t, y, steps, end) -> dict:
    """The square-wave figures as written run by run before issue 42 (one rise time, overshoot and mean per
    cycle and run): the reference compute_all's stacked form must give bit for bit."""
    from seapup_control.response_metrics import overshoot_percent, rise_time
    from seapup_runs.adaptive_metrics import _TO_THESIS
    from seapup_runs.result import REFERENCE_NAMES
    out = {}
    for j, key in enumerate(REFERENCE_NAMES):
        on = [(t0, r[j], (steps[k + 1][0] if k + 1 < len(steps) else end)) for k, (t0, r) in enumerate(steps)
              if r[j] != 0.0]
        if not on:
            continue
        cycles = []
        for t0, ref, t1 in on:
            sel = (t >= t0 - 1e-9) & (t < t1 - 1e-9)
            last = sel & (t >= t1 - 1.0 - 1e-9)
            cycles.append({"start_s": t0, "rise95_s": rise_time(t[sel], y[sel, j], ref, start=0.0),
                           "overshoot_pct": overshoot_percent(y[sel, j], ref, start=0.0),
                           "steady_error_pct": float(100.0 * (ref - np.mean(y[last, j])) / abs(ref))})
        later = cycles[1:] or cycles
        out[key] = {"reference": float(on[0][1] * _TO_THESIS[j]), "cycles": cycles,
                    "later": {name: float(np.mean([c[name] for c in later])) for name in
                              ("rise95_s", "overshoot_pct", "steady_error_pct")}}
    return out


def test_a_campaign_s_metrics_computed_together_are_each_run_s_own_bit_for_bit():
    """compute_all (a batch's metrics at once: the square waves' figures of runs that share their times and
    steps stacked) gives each run exactly what compute gives it alone, and the square figures are those of the
    run-by-run code they replaced -- runs of two scenarios (two groups), seeds, a fouling, a noisy and an ideal
    instrument fit."""
    import dataclasses
    import json
    from seapup_runs.metrics import compute, compute_all
    from seapup_runs.runner import run
    from seapup_runs.scenarios import scenario_spec
    from seapup_runs.spec import RunEvent
    specs = [scenario_spec("square-inspection", seed=1), scenario_spec("square-inspection", seed=2, sensors="ideal"),
             scenario_spec("square-turn", seed=3), scenario_spec("square-turn", seed=9)]
    fouled = scenario_spec("square-inspection", seed=4)
    specs.append(dataclasses.replace(fouled, events=(*fouled.events,
                                                    RunEvent(12.0, "thruster_efficiency", [0.5, 1.0, 1.0, 1.0]))))
    results = [run(spec) for spec in specs]
    together = compute_all(results)
    assert json.dumps(together, sort_keys=True, default=str) == json.dumps([compute(r) for r in results],
                                                                           sort_keys=True, default=str)
    for result, metrics in zip(results, together):
        t, y = result.series.t[:-1], result.series.velocity()[:-1]
        steps = [(float(t0), np.asarray(r, float)) for t0, r in result.reference_steps_flown()]
        expected = _square_reference(t, y, steps, result.spec.duration)
        assert json.dumps(metrics["adaptive"]["square"], sort_keys=True) == json.dumps(expected, sort_keys=True)
        assert metrics["adaptive"]["square"]                                  # stepped outputs were measured
