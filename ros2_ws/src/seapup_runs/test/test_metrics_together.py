"""Issue 42: a campaign's step-response figures reduced over all its runs at once are each run's own, bit for bit,
against the run-by-run code they replaced (kept here as the reference): every scenario kind -- steps on each axis, a
current stepped in, a controller connected late, square waves, a vehicle change -- with noise and without, at 5 and
20 Hz."""
import json
import math

import numpy as np
import pytest

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_control.response_metrics import (MetricError, limit_cycle, overshoot_percent, rise_time, saturation_time,
                                             settle)
from seapup_runs.metrics import (STEADY_ERROR_PCT, _current_step_time, _good_response, _late_controller, compute,
                                 compute_all, settle_floors, settled_window, step_response, step_response_all)
from seapup_runs.result import REFERENCE_NAMES


def _step_response_reference(result):
    """step_response as written run by run before issue 42: the reference the stacked figures must equal."""
    spec, series = result.spec, result.series
    t = series.t
    if len(t) < 3:
        raise MetricError("a step response needs at least three samples")
    states = series.states()
    y = series.velocity()
    to_thesis = np.array([1.0, 1.0, 1.0, 180.0 / math.pi])  # r in deg/s
    steps = result.reference_steps_flown()
    final_ref = np.array(steps[-1][1])
    last_change = steps[-1][0]
    prev_ref = np.array(steps[-2][1]) if len(steps) > 1 else np.zeros(4)
    window = settled_window(spec.duration)
    floors, attitude_floor = settle_floors()
    disturbed = _current_step_time(result)
    end = disturbed if disturbed > last_change else math.inf  # the step response ends where a disturbance starts
    outputs = {}
    for j, key in enumerate(REFERENCE_NAMES):
        sel = (t >= last_change - 1e-9) & (t < end)
        final = settle(t, y[:, j], window, floor=floors[j])
        entry = {"reference": final_ref[j] * to_thesis[j], **final.scaled(to_thesis[j]).as_dict()}
        if final_ref[j] != prev_ref[j]:
            entry["rise95_s"] = rise_time(t[sel], y[sel, j], final_ref[j], start=prev_ref[j])
            entry["overshoot_pct"] = overshoot_percent(y[sel, j], final_ref[j], start=prev_ref[j])
        entry["steady_error"] = (final_ref[j] - final.value) * to_thesis[j]
        if final_ref[j] == 0.0:
            entry["max_interaction"] = float(np.max(np.abs(y[:, j]))) * to_thesis[j]
        else:
            entry["steady_error_pct"] = 100.0 * entry["steady_error"] / abs(entry["reference"])
            entry["steady_error_seen"] = bool(abs(entry["steady_error_pct"]) > STEADY_ERROR_PCT)
        if "rise95_s" in entry and final_ref[j] != 0.0:   # a band in per cent of a non-zero reference
            entry["band_pct"] = _band_reference(t[sel], y[sel, j], final_ref[j], entry["rise95_s"])
        outputs[key] = entry
    half = t >= t[-1] / 2
    good = _good_response(outputs, spec.duration - last_change)
    cycle = limit_cycle(t[half], y[half, 1], min_amplitude=0.005)
    pitch = np.degrees(states[:, 4])
    out = {"outputs": outputs, "saturation_s": saturation_time(t[:-1], series.command[:-1], BLADE_PITCH_LIMIT),
           "limit_cycle": {"detected": cycle.detected, "period_s": cycle.period, "amplitude": cycle.amplitude},
           "pitch_deg": {"peak": float(pitch[np.argmax(np.abs(pitch))]),
                         **settle(t, states[:, 4], window, floor=attitude_floor).scaled(math.degrees(1.0)).as_dict()},
           "roll_deg": {"peak": float(np.degrees(states[np.argmax(np.abs(states[:, 3])), 3]))},
           "good_response": good}
    t_on = _late_controller(result)
    if t_on > 0:
        on = int(np.argmin(np.abs(t - t_on)))
        after = states[on:]
        out["station_keep"] = {
            "max_abs_x": float(np.max(np.abs(after[:, 0] - after[0, 0]))),
            "max_abs_y": float(np.max(np.abs(after[:, 1] - after[0, 1]))),
            "max_abs_z": float(np.max(np.abs(after[:, 2] - after[0, 2]))),
            "max_abs_yaw_deg": float(np.degrees(np.max(np.abs(after[:, 5] - after[0, 5]))))}
    if disturbed > 0 and t_on == 0:
        after = t >= disturbed
        u = y[:, 0]
        out["u_peak_after_current"] = float(np.max(u[after]))
        outside = np.flatnonzero(after & (np.abs(u - final_ref[0]) > 0.05 * abs(final_ref[0])))
        out["recovery_5pct_s"] = float(t[outside[-1]] - disturbed) if outside.size else 0.0
    return out


def _band_reference(t: np.ndarray, y: np.ndarray, reference: float, rise: float) -> float:
    """The largest miss of ``reference`` from the moment the output first reached 95 % of its step on [% of
    the reference]; NaN if it never got there (sec. 5.4.2: "remained within 7 percent of its reference")."""
    if not math.isfinite(rise):
        return math.nan
    after = t - t[0] >= rise - 1e-9
    return float(100.0 * np.max(np.abs(y[after] - reference)) / abs(reference))


@pytest.fixture(scope="module")
def flown():
    from seapup_runs.runner import run
    from seapup_runs.scenarios import scenario_spec
    names = ["surge", "sway", "yaw", "current-step", "station-keep", "square-inspection", "square-turn",
             "fouling-change"]
    specs = [scenario_spec(name, seed=seed) for name in names for seed in (1, 2)]
    specs.append(scenario_spec("surge", seed=3, sensors="ideal"))
    # at 20 Hz a 1 s window holds 21 samples: numpy sums 8 or more pairwise, in the order of the row's memory
    specs += [scenario_spec(name, seed=seed, rate=20.0) for name in ("surge", "square-inspection") for seed in (4, 5)]
    return [run(spec) for spec in specs]


def _same(a, b) -> bool:
    return json.dumps(a, sort_keys=True, default=str) == json.dumps(b, sort_keys=True, default=str)


def test_the_step_response_of_runs_together_is_each_run_s_own_by_the_run_by_run_code(flown):
    reference = [_step_response_reference(result) for result in flown]
    assert _same(step_response_all(flown), reference)
    assert _same([step_response(result) for result in flown], reference)
    assert any("station_keep" in figures for figures in reference)            # a late controller was measured
    assert any("u_peak_after_current" in figures for figures in reference)    # and a current stepped in
    assert any("band_pct" in e for figures in reference for e in figures["outputs"].values())


def test_compute_all_is_compute_of_each_run(flown):
    assert _same(compute_all(flown), [compute(result) for result in flown])
