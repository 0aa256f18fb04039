"""Metrics of a run, by name: what the thesis reports about a closed-loop case, computed from a result.

A :class:`~seapup_runs.spec.RunSpec` names its metrics (``metrics:
[step_response]``); :func:`compute` runs each registered extractor over the
:class:`~seapup_runs.result.RunResult`, so the in-process and the graph run of
a spec are measured by the same code from the same shape of data.

``step_response`` (sec. 5.4.2-5.4.3, figs 5.10-5.24): per output (u, v, w [m/s]
and r [deg/s], thesis units) the reference, the final value -- the mean over
the last second, with whether it settled there (:func:`settled_window`,
:func:`~seapup_control.response_metrics.settle`) -- and the steady error, the 95 % rise time and overshoot
after the last reference step (up to a later current step), the largest interaction in outputs asked to stay at
zero; for a stepped output also the band it keeps after first reaching 95 %
(``band_pct``, sec. 5.4.2: "the yaw velocity remained within 7 percent") and
whether a steady-state error is seen (``steady_error_seen``, fig. 5.19);
whether the case is a good response in every output at once
(``good_response``, figs 5.17-5.18, 5.33); thruster saturation per thruster;
a sway limit cycle in the second half; body pitch and roll peaks; station
keeping after a controller connected late; the current step's surge peak and
recovery.

:func:`compute_all` measures many runs at once (a campaign's batch): the figures of runs that share their sample
times and reference steps are reduced over all their rows together (:func:`step_response_all`,
:func:`~seapup_runs.adaptive_metrics.adaptive_all`), the same numbers as run by run.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_control.response_metrics import (MetricError, limit_cycle, overshoot_percents, rise_times, saturation_time,
                                             settle_rows)
from seapup_runs.adaptive_metrics import adaptive, adaptive_all, grouped, shared_key
from seapup_runs.result import REFERENCE_NAMES, RunResult

__all__ = ["METRICS", "compute", "compute_all", "check_names", "step_response", "step_response_all", "MetricError",
           "settled_window", "settle_floors", "STEADY_ERROR_PCT", "interaction_limits"]

#: A steady-state error is *seen* when the final value misses its reference by more than this [% of the
#: reference]: an integral controller ends at zero error, and fig. 5.19's error is one a reader sees on a plot
#: scaled to the reference, where 2 % is a line's width away from it (the overshoots the thesis calls small,
#: 0.35-1.7 %, are about that size).
STEADY_ERROR_PCT = 2.0

#: The largest final yaw rate that still counts as "little interaction" [deg/s]: a heading drifting 5 deg in a
#: 10 s case, what its plot shows.
YAW_INTERACTION_LIMIT = 0.5


def settled_window(duration: float) -> float:
    """The window a case's final values are means over [s]: the last 1 s, or the last 20 % of a run
    shorter than 5 s. The thesis's steps are 10 s with 95 % rise times up to 5 s (sec. 5.4.2), so a
    longer window would average part of the rise; 1 s still holds 6 samples at 5 Hz (21 at 20 Hz).
    Whether the signal really is steady over it is reported with the value (:func:`settle`)."""
    return min(1.0, 0.2 * float(duration))


def settle_floors() -> tuple[np.ndarray, float]:
    """The smallest settling bands: what the baseline instruments resolve (``sensors.yaml``, 3 sigma:
    0.02 kt for u, v, w, 0.005 deg/s for r, 0.25 deg for roll and pitch); SI (m/s, rad/s for u, v, w,
    r; rad for the pitch angle). A swing the instruments cannot see is settled. Worked out once per version of
    ``sensors.yaml`` (every run's metrics ask: reading the profile cost a tenth of a campaign run's metrics)."""
    from seapup_sim.sensors import load_sensor_profile, profiles_document
    document = profiles_document()   # the same object while the file is unchanged
    if _FLOORS.get("document") is not document:
        baseline = load_sensor_profile("baseline")
        _FLOORS.update(document=document, floors=(3.0 * np.array([*baseline.velocity_std, baseline.rate_std[2]]),
                                                  3.0 * baseline.attitude_std[1]))
    floors, attitude = _FLOORS["floors"]
    return floors.copy(), attitude


_FLOORS: dict = {}


def interaction_limits() -> np.ndarray:
    """The largest final value of an output asked to stay at zero that still counts as "little interaction"
    (figs 5.17-5.18, 5.33), thesis units (u, v, w [m/s], r [deg/s]): for u, v, w what the baseline
    instruments resolve (:func:`settle_floors`, 3 sigma of 0.02 kt), for r :data:`YAW_INTERACTION_LIMIT`."""
    floors, _ = settle_floors()
    return np.array([*floors[:3], YAW_INTERACTION_LIMIT])


def _late_controller(result: RunResult) -> float:
    """When the first closed-loop controller took over (0: from the start; a hold before it is drifting)."""
    timeline = result.spec.controller_timeline()
    if timeline[0][1].type == "hold" and len(timeline) > 1:
        return timeline[1][0]
    return 0.0


def _current_step_time(result: RunResult) -> float:
    times = [e.time for e in result.spec.events if e.kind == "current" and e.time > 0]
    return times[0] if times else 0.0


def step_response(result: RunResult) -> dict:
    """The step-response figures of merit (see the module docstring)."""
    return _step_responses([result])[0]


def step_response_all(results) -> list[dict]:
    """:func:`step_response` of each result, the figures of runs that share their sample times, reference steps,
    duration, current step and controller timing (a campaign's batch) reduced over all of them at once: the same
    numbers as one by one (tested)."""
    out: list = [None] * len(results)
    for members in grouped(results, lambda r: (*shared_key(r), _current_step_time(r), _late_controller(r))):
        for i, figures in zip(members, _step_responses([results[i] for i in members])):
            out[i] = figures
    return out


def _step_responses(results) -> list[dict]:
    """:func:`step_response` of runs sharing what :func:`step_response_all` groups them by: the windows' means,
    extremes, rises and overshoots reduced over the runs' rows at once, the rest run by run."""
    first = results[0]
    spec, t = first.spec, first.series.t
    if len(t) < 3:
        raise MetricError("a step response needs at least three samples")
    states = np.stack([r.series.states() for r in results])
    y = np.stack([r.series.velocity() for r in results])
    rows = np.arange(len(results))
    to_thesis = np.array([1.0, 1.0, 1.0, 180.0 / math.pi])  # r in deg/s
    steps = first.reference_steps_flown()
    final_ref = np.array(steps[-1][1])
    last_change = steps[-1][0]
    prev_ref = np.array(steps[-2][1]) if len(steps) > 1 else np.zeros(4)
    window = settled_window(spec.duration)
    floors, attitude_floor = settle_floors()
    disturbed = _current_step_time(first)
    end = disturbed if disturbed > last_change else math.inf  # the step response ends where a disturbance starts
    sel = (t >= last_change - 1e-9) & (t < end)
    outputs: list[dict] = [{} for _ in results]
    for j, key in enumerate(REFERENCE_NAMES):
        finals = settle_rows(t, y[:, :, j], window, floor=floors[j])
        stepped = final_ref[j] != prev_ref[j]
        if stepped:
            rises = rise_times(t[sel], y[:, sel, j], final_ref[j], start=prev_ref[j])
            overshoots = overshoot_percents(y[:, sel, j], final_ref[j], start=prev_ref[j])
            if final_ref[j] != 0.0:   # a band in per cent of a non-zero reference
                bands = _bands_after_rise(t[sel], y[:, sel, j], final_ref[j], rises)
        if final_ref[j] == 0.0:
            interactions = np.max(np.abs(y[:, :, j]), axis=1)
        for i, final in enumerate(finals):
            entry = {"reference": final_ref[j] * to_thesis[j], **final.scaled(to_thesis[j]).as_dict()}
            if stepped:
                entry["rise95_s"] = float(rises[i])
                entry["overshoot_pct"] = float(overshoots[i])
            entry["steady_error"] = (final_ref[j] - final.value) * to_thesis[j]
            if final_ref[j] == 0.0:
                entry["max_interaction"] = float(interactions[i]) * to_thesis[j]
            else:
                entry["steady_error_pct"] = 100.0 * entry["steady_error"] / abs(entry["reference"])
                entry["steady_error_seen"] = bool(abs(entry["steady_error_pct"]) > STEADY_ERROR_PCT)
            if stepped and final_ref[j] != 0.0:
                entry["band_pct"] = float(bands[i])
            outputs[i][key] = entry
    half = t >= t[-1] / 2
    pitch = np.degrees(states[:, :, 4])
    pitch_peaks = pitch[rows, np.argmax(np.abs(pitch), axis=1)]
    pitch_final = settle_rows(t, states[:, :, 4], window, floor=attitude_floor)
    roll_peaks = np.degrees(states[rows, np.argmax(np.abs(states[:, :, 3]), axis=1), 3])
    t_on = _late_controller(first)
    out = []
    for i, result in enumerate(results):
        cycle = limit_cycle(t[half], y[i, half, 1], min_amplitude=0.005)
        figures = {"outputs": outputs[i],
                   "saturation_s": saturation_time(t[:-1], result.series.command[:-1], BLADE_PITCH_LIMIT),
                   "limit_cycle": {"detected": cycle.detected, "period_s": cycle.period, "amplitude": cycle.amplitude},
                   "pitch_deg": {"peak": float(pitch_peaks[i]), **pitch_final[i].scaled(math.degrees(1.0)).as_dict()},
                   "roll_deg": {"peak": float(roll_peaks[i])},
                   "good_response": _good_response(outputs[i], spec.duration - last_change)}
        if t_on > 0:
            on = int(np.argmin(np.abs(t - t_on)))
            after = states[i, on:]
            figures["station_keep"] = {
                "max_abs_x": float(np.max(np.abs(after[:, 0] - after[0, 0]))),
                "max_abs_y": float(np.max(np.abs(after[:, 1] - after[0, 1]))),
                "max_abs_z": float(np.max(np.abs(after[:, 2] - after[0, 2]))),
                "max_abs_yaw_deg": float(np.degrees(np.max(np.abs(after[:, 5] - after[0, 5]))))}
        if disturbed > 0 and t_on == 0:
            after = t >= disturbed
            u = y[i, :, 0]
            figures["u_peak_after_current"] = float(np.max(u[after]))
            outside = np.flatnonzero(after & (np.abs(u - final_ref[0]) > 0.05 * abs(final_ref[0])))
            figures["recovery_5pct_s"] = float(t[outside[-1]] - disturbed) if outside.size else 0.0
        out.append(figures)
    return out


def _bands_after_rise(t: np.ndarray, ys: np.ndarray, reference: float, rises: np.ndarray) -> np.ndarray:
    """The largest miss of ``reference`` from the moment each row first reached 95 % of its step on [% of the
    reference]; NaN for a row that never got there (sec. 5.4.2: "remained within 7 percent of its reference")."""
    after = (t - t[0])[None, :] >= rises[:, None] - 1e-9           # no sample for a NaN rise
    largest = np.max(np.where(after, np.abs(ys - reference), -np.inf), axis=1)
    return np.where(np.isfinite(rises), 100.0 * largest / abs(reference), math.nan)


def _good_response(outputs: dict, span: float) -> dict:
    """"Very good response in all outputs simultaneously" (fig. 5.17), decided: every stepped output reached 95 %
    within the first half of the time after its step ("fast rise times") and ends within 5 % of its reference
    ("zero steady-state errors", the thesis's own 95 % band), and every output asked to stay at zero ends
    within :func:`interaction_limits` ("little interaction")."""
    stepped = {k: e for k, e in outputs.items() if "rise95_s" in e}
    rose = bool(stepped) and all(math.isfinite(e["rise95_s"]) and e["rise95_s"] <= span / 2 for e in stepped.values())
    steady = all(abs(e["steady_error"]) <= 0.05 * abs(e["reference"]) for e in stepped.values())
    limits = dict(zip(REFERENCE_NAMES, interaction_limits()))
    quiet = all(abs(e["final"]) <= limits[key] for key, e in outputs.items() if e["reference"] == 0.0)
    return {"ok": bool(rose and steady and quiet), "fast_rise": rose, "no_steady_error": steady,
            "little_interaction": quiet}


#: Metric extractors by name: ``name(result) -> dict``.
METRICS: dict[str, Callable[[RunResult], dict]] = {"step_response": step_response, "adaptive": adaptive}
#: Those with a form over many runs at once (:func:`compute_all`): ``name(results) -> [dict, ...]``.
_MANY = {"step_response": step_response_all, "adaptive": adaptive_all}


def check_names(names) -> None:
    """Refuse a name not in :data:`METRICS` -- before a run flies (:func:`seapup_runs.runner.run`, a campaign's
    check, ``./seapup fly``), not after.

    Raises
    ------
    MetricError
        Naming the unknown metric(s) and the known ones.
    """
    unknown = [name for name in names if name not in METRICS]
    if unknown:
        raise MetricError(f"unknown metric(s) {unknown}; known: {', '.join(METRICS)}"[:400])


def compute_all(results) -> list[dict]:
    """:func:`compute` of each result, a metric that has a form over many runs (``adaptive``:
    :func:`~seapup_runs.adaptive_metrics.adaptive_all`) computed over all the results that name it at once:
    a campaign's batch (:func:`seapup_runs.batch_runner.fly_batch`). The same mappings as one by one (tested).

    Raises
    ------
    MetricError
        On a name not in :data:`METRICS`.
    """
    results = list(results)
    for result in results:
        check_names(result.spec.metrics)
    together: dict = {}   # metric -> run index -> its figures
    for name, many in _MANY.items():
        members = [i for i, result in enumerate(results) if name in result.spec.metrics]
        if members:
            together[name] = dict(zip(members, many([results[i] for i in members])))
    out = []
    for i, result in enumerate(results):
        merged = {}
        for name in result.spec.metrics:   # merged in the spec's order, as compute merges them
            merged.update(together[name][i] if name in together else METRICS[name](result))
        out.append(merged)
    return out


def compute(result: RunResult) -> dict:
    """Every metric the result's spec names, merged into one mapping.

    Raises
    ------
    MetricError
        On a name not in :data:`METRICS`.
    """
    out = {}
    for name in result.spec.metrics:
        if name not in METRICS:
            raise MetricError(f"unknown metric {name!r}; known: {', '.join(METRICS)}")
        out.update(METRICS[name](result))
    return out
