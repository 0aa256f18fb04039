"""What sec. 7.4-7.6 say about an adaptive autopilot's run, computed from its result (metric ``adaptive``).

The thesis judges the self-tuners on square waves (steps every 10 s, zero in the second half), on a demand held
for 60 s, and on a change of the vehicle at 65 s (figs 7.3-7.25). Thesis units: u, v, w in m/s, r in deg/s,
blade pitch in degrees. ``adaptive`` gives

- ``square``: per output stepped away from zero, each "on" step's 95 % rise time, overshoot and the steady
  error over its last second [% of the reference], and ``later`` -- their means over the steps after the
  first, once the estimator has "tuned in" (sec. 7.4.1 judges "the succeeding reference changes");
- ``later_interaction``: per output held at zero, its largest magnitude after the first cycle (t >= 20 s);
- ``tracking_rms`` and ``tracking_rms_total``: the RMS tracking error after commissioning (t >= 1 s), per
  output and all four together (outputs over their reference's scale: 1 m/s, 10 deg/s);
- ``command_rate_rms_deg``: the RMS of the blade pitches' sample-to-sample change, the "thrashing" of
  fig. 7.20;
- ``estimate``: when the run logged one, the sample after which every named parameter trace stays within
  5 % of its final value (of its largest magnitude over the run): ``converged_sample`` and ``converged``
  (by the last 10 s); from the start, and after a vehicle change (``after_change``);
- ``hold_limit_cycle``: for a demand held throughout, a sway limit cycle looked for from 10 s on (a 20 s
  period, sec. 7.4.1, needs 40 s of record);
- ``change``: after a configuration or thruster-efficiency event, the largest tracking error and the samples
  until every output stays within 5 % of its reference (0.01 m/s or 0.5 deg/s at least) -- sec. 7.4.4's
  "within 100 sampling times" -- and each thruster's mean blade pitch over the last 5 s before and at the
  end (the main-port setting "at a higher level after the disturbance while the other three remain").
"""
from __future__ import annotations

import math

import numpy as np

from seapup_control.response_metrics import limit_cycle, overshoot_percents, rise_times
from seapup_runs.result import REFERENCE_NAMES, RunResult

__all__ = ["adaptive", "adaptive_all", "converged_sample", "CONVERGED_FRACTION"]

#: A parameter trace has converged once it stays within this fraction of its largest magnitude of its final value.
CONVERGED_FRACTION = 0.05
_TO_THESIS = np.array([1.0, 1.0, 1.0, 180.0 / math.pi])
_SCALE = np.array([1.0, 1.0, 1.0, 10.0])     # tracking_rms_total: m/s and 10 deg/s weigh alike
_THRUSTERS = ("main_port", "main_stbd", "vect_stbd", "vect_port")


def converged_sample(values: np.ndarray, start: int = 0) -> int | None:
    """The first sample (>= ``start``) after which every column of ``values`` stays within
    :data:`CONVERGED_FRACTION` of its largest magnitude (from ``start``) of its final value; None if never."""
    segment = values[start:]
    segment = segment[:, np.all(np.isfinite(segment), axis=0)] if segment.size else segment
    if segment.shape[0] < 2 or segment.shape[1] == 0:
        return None
    band = CONVERGED_FRACTION * np.maximum(np.abs(segment).max(axis=0), 1e-12)
    outside = np.any(np.abs(segment - segment[-1]) > band, axis=1)
    last = np.flatnonzero(outside)
    return start + (int(last[-1]) + 1 if last.size else 0)


def _steps(result: RunResult) -> list[tuple[float, np.ndarray]]:
    return [(float(t), np.asarray(r, float)) for t, r in result.reference_steps_flown()]


_CYCLE = ("rise95_s", "overshoot_pct", "steady_error_pct")


def _squares(t, ys, steps, end) -> list[dict]:
    """``square`` of each run of ``ys`` (runs x samples x 4) that share the times ``t``, the reference steps and
    the end: each cycle's figures computed for every run at once (:func:`adaptive_all`)."""
    outs = [{} for _ in range(len(ys))]
    for j, key in enumerate(REFERENCE_NAMES):
        on = [(t0, r[j], (steps[k + 1][0] if k + 1 < len(steps) else end)) for k, (t0, r) in enumerate(steps)
              if r[j] != 0.0]
        if not on:
            continue
        figures = []   # per cycle: (start, {name: one value per run})
        for t0, ref, t1 in on:
            sel = (t >= t0 - 1e-9) & (t < t1 - 1e-9)
            last = sel & (t >= t1 - 1.0 - 1e-9)
            within = ys[:, sel, j]
            figures.append((t0, {"rise95_s": rise_times(t[sel], within, ref, start=0.0),
                                 "overshoot_pct": overshoot_percents(within, ref, start=0.0),
                                 "steady_error_pct": 100.0 * (ref - _row_means(ys[:, last, j])) / abs(ref)}))
        later = figures[1:] or figures
        means = {name: _row_means(np.column_stack([f[name] for _, f in later])) for name in _CYCLE}
        for i, out in enumerate(outs):
            out[key] = {"reference": float(on[0][1] * _TO_THESIS[j]),
                        "cycles": [{"start_s": t0, **{name: float(f[name][i]) for name in _CYCLE}}
                                   for t0, f in figures],
                        "later": {name: float(means[name][i]) for name in _CYCLE}}
    return outs


def _row_means(rows: np.ndarray) -> np.ndarray:
    """Each row's mean, summed as the mean of that row alone (rows laid out in memory order first: numpy sums
    a row pairwise from 8 values on, in the order of the row's memory)."""
    return np.mean(np.ascontiguousarray(rows), axis=1)


def _square(t, y, steps, end) -> dict:
    """``square`` of one run (:func:`_squares` of it alone)."""
    return _squares(t, y[None], steps, end)[0]


def shared_key(result: RunResult) -> tuple:
    """What runs must share for their figures to be reduced together (:func:`adaptive_all`,
    :func:`seapup_runs.metrics.step_response_all`): the sample times, the reference steps flown and the duration."""
    return (result.series.t.tobytes(), tuple((t, tuple(r.tolist())) for t, r in _steps(result)),
            result.spec.duration)


def grouped(results, key) -> list[list[int]]:
    """The indices of ``results`` grouped by ``key(result)``, in order of first appearance."""
    groups: dict = {}
    for i, result in enumerate(results):
        groups.setdefault(key(result), []).append(i)
    return list(groups.values())


def adaptive_all(results) -> list[dict]:
    """:func:`adaptive` of each result, the square-wave figures of runs that share their times and steps (a
    campaign's) computed together: the same numbers as one by one (tested), at a fraction of the cost."""
    squares = {}
    for members in grouped(results, shared_key):
        first = results[members[0]]
        steps = _steps(first)
        if len(steps) > 1:
            t = first.series.t[:-1]
            ys = np.stack([results[i].series.velocity()[:-1] for i in members])
            squares.update(zip(members, _squares(t, ys, steps, first.spec.duration)))
    return [adaptive(result, squares.get(i, {})) for i, result in enumerate(results)]


def adaptive(result: RunResult, square: dict | None = None) -> dict:
    """The ``adaptive`` metric (see the module docstring); ``square``: its square-wave figures when worked out
    already (:func:`adaptive_all`)."""
    spec, series = result.spec, result.series
    t = series.t[:-1]
    y = series.velocity()[:-1]
    ref = series.reference_array()[:-1]
    n = len(t)
    steps = _steps(result)
    if square is None:
        square = _square(t, y, steps, spec.duration) if len(steps) > 1 else {}
    out: dict = {"square": square}
    held_zero = [j for j in range(4) if not any(r[j] != 0.0 for _, r in steps)]
    later = t >= 20.0
    out["later_interaction"] = {REFERENCE_NAMES[j]: float(np.max(np.abs(y[later, j])) * _TO_THESIS[j])
                                for j in held_zero if later.any()}
    after = t >= 1.0
    error = (ref - y) * _TO_THESIS
    out["tracking_rms"] = {k: float(np.sqrt(np.mean(error[after, j] ** 2))) for j, k in enumerate(REFERENCE_NAMES)}
    out["tracking_rms_total"] = float(np.sqrt(np.mean(np.sum((error[after] / _SCALE) ** 2, axis=1))))
    pitch = np.degrees(series.command[:-1])
    out["command_rate_rms_deg"] = float(np.sqrt(np.mean(np.diff(pitch[after], axis=0) ** 2)))
    changes = [e for e in spec.events if e.kind in ("configuration", "thruster_efficiency")]
    if series.estimate is not None:
        names = [k for k, name in enumerate(series.estimate["names"]) if name != "trace_P"]
        values = np.asarray(series.estimate["values"], float)[:n][:, names]
        first = converged_sample(values, int(np.searchsorted(t, 1.0)))
        tail = int(round(10.0 / spec.control_period))
        out["estimate"] = {"converged_sample": first, "converged": first is not None and first <= n - tail}
        if changes:
            k0 = int(np.searchsorted(t, changes[0].time - 1e-9))
            again = converged_sample(values, k0)
            out["estimate"]["after_change"] = None if again is None else again - k0
    if len(steps) == 1 and t[-1] > 30.0:
        sel = t >= 10.0
        cycle = limit_cycle(t[sel], y[sel, 1], min_amplitude=0.005)
        out["hold_limit_cycle"] = {"detected": cycle.detected, "period_s": cycle.period, "amplitude": cycle.amplitude}
    if changes:
        te = changes[0].time
        k0 = int(np.searchsorted(t, te - 1e-9))
        band = np.maximum(0.05 * np.abs(ref * _TO_THESIS), np.array([0.01, 0.01, 0.01, 0.5]))
        outside = np.flatnonzero(np.any(np.abs(error[k0:]) > band[k0:], axis=1))
        window = int(round(5.0 / spec.control_period))
        before = pitch[max(k0 - window, 0):k0].mean(axis=0)
        end = pitch[-window:].mean(axis=0)
        out["change"] = {"time_s": te, "kind": changes[0].kind,
                         "max_error": float(np.max(np.abs(error[k0:]) / _SCALE)),
                         "recovery_samples": int(outside[-1]) + 1 if outside.size else 0,
                         "pitch_before_deg": dict(zip(_THRUSTERS, before.tolist())),
                         "pitch_end_deg": dict(zip(_THRUSTERS, end.tolist())),
                         "main_port_rise_deg": float(end[0] - before[0]),
                         "others_largest_change_deg": float(np.max(np.abs(end[1:] - before[1:])))}
    return {"adaptive": out}
