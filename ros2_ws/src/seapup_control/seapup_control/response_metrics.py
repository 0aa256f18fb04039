"""Figures of merit of closed-loop responses (thesis sec. 5.4.2-5.4.3).

The thesis characterises its step tests by the 95 % rise time, the
overshoot, the steady-state error, the interaction in the other outputs
("output decoupling"), thruster saturation, limit cycles (the sway-roll limit
cycle of the yaw test) and, for disturbance rejection, how far the vehicle
strays. These functions compute them from sampled time histories; they know
nothing of where the histories came from.

A final value is the mean over a stated window at the end of the run, with
whether the signal has settled there (:func:`settle`): a snapshot of the last
sample of a signal still swinging is not a final value.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["rise_time", "rise_times", "overshoot_percent", "overshoot_percents", "settled_value", "Settled", "settle",
           "settle_rows", "MetricError", "saturation_time", "LimitCycle", "limit_cycle"]


class MetricError(ValueError):
    """A figure of merit has no answer for this signal (the message says why and what was allowed)."""


def _series(t, y) -> tuple[np.ndarray, np.ndarray]:
    t, y = np.asarray(t, float), np.asarray(y, float)
    if t.ndim != 1 or t.shape != y.shape or t.size < 2 or np.any(np.diff(t) <= 0):
        raise ValueError(f"need increasing times and values of the same length, got {t.shape} and {y.shape}")
    return t, y


def rise_time(t, y, target: float, start: float | None = None, fraction: float = 0.95) -> float:
    """Time from ``t[0]`` until ``y`` first reaches ``fraction`` of the way from ``start`` to ``target``.

    Linear interpolation between samples; NaN if it never gets there (e.g.
    the sway test's 0.277 of 0.29 m/s).

    Examples
    --------
    >>> t = np.linspace(0, 10, 1001)
    >>> round(rise_time(t, 1 - np.exp(-t), 1.0), 3)   # -ln(0.05) for a unit first-order lag
    2.996
    """
    t, y = _series(t, y)
    return float(_rise_times(t, y[None], target, start, fraction)[0])


def rise_times(t, ys, target: float, start: float | None = None, fraction: float = 0.95) -> np.ndarray:
    """:func:`rise_time` of each row of ``ys`` (runs x samples) over the times ``t`` they share, computed for
    all rows at once (a campaign's runs: :func:`seapup_runs.metrics.compute_all`); the same numbers, element for
    element (the one implementation: :func:`rise_time` is this of one row)."""
    t, ys = np.asarray(t, float), np.asarray(ys, float)
    if ys.ndim != 2:
        raise ValueError(f"need rows of samples (runs x samples), got shape {ys.shape}")
    _series(t, ys[0] if len(ys) else t)
    return _rise_times(t, ys, target, start, fraction)


def _rise_times(t: np.ndarray, ys: np.ndarray, target: float, start: float | None, fraction: float) -> np.ndarray:
    """:func:`rise_times` of checked arrays: per row, the first sample at or beyond the level (linear
    interpolation from the one before), 0 when the first is, NaN when none is."""
    y0 = ys[:, 0] if start is None else np.full(len(ys), float(start))
    level = y0 + fraction * (target - y0)
    sign = np.where(target >= y0, 1.0, -1.0)
    hit = sign[:, None] * (ys - level[:, None]) >= 0
    k = hit.argmax(axis=1)
    reached = hit.any(axis=1)
    crossed = reached & (k > 0)          # interpolated from the sample before: y[k - 1] short of the level, y[k] not
    before = np.maximum(k, 1) - 1
    rows = np.arange(len(ys))
    below, at = ys[rows, before], ys[rows, before + 1]
    frac = (level - below) / np.where(crossed, at - below, 1.0)   # a crossing's two samples differ
    value = t[before] + frac * (t[before + 1] - t[before]) - t[0]
    return np.where(crossed, value, np.where(reached, 0.0, math.nan))


def overshoot_percent(y, target: float, start: float = 0.0) -> float:
    """Largest excursion beyond ``target``, in percent of the step (0 if none; NaN for a zero step)."""
    return float(overshoot_percents(np.asarray(y, float).reshape(1, -1), target, start)[0])


def overshoot_percents(ys, target: float, start: float = 0.0) -> np.ndarray:
    """:func:`overshoot_percent` of each row of ``ys`` (runs x samples) at once."""
    ys = np.asarray(ys, float)
    if ys.ndim != 2:
        raise ValueError(f"need rows of samples (runs x samples), got shape {ys.shape}")
    step = target - start
    if step == 0:
        return np.full(len(ys), math.nan)
    largest = np.max((ys - target) / step, axis=1)
    return np.where(largest > 0.0, largest, 0.0) * 100.0   # max(0, .) of each: NaN (no finite excursion) is 0


def _window(t: np.ndarray, window: float) -> np.ndarray:
    """The samples of the last ``window`` seconds, both ends included: t >= t[-1] - window."""
    span = float(t[-1] - t[0])
    if not (math.isfinite(window) and 0.0 < window <= span + 1e-9):
        raise MetricError(f"window must be in (0, {span:g}] s (the record's span), got {window!r}")
    return t >= t[-1] - window - 1e-9


def settled_value(t, y, window: float) -> float:
    """Mean of ``y`` over the samples of the last ``window`` seconds (``settle(...).value``).

    Raises
    ------
    MetricError
        ``window`` is not in (0, record span].
    """
    t, y = _series(t, y)
    return float(np.mean(y[_window(t, window)]))


@dataclass(frozen=True)
class Settled:
    """A final value: the mean over the last ``window_s`` seconds of a run, and whether it settled there.

    Attributes
    ----------
    value : float
        Mean of the samples in the window.
    settled : bool
        Every sample of the window lies within ``tolerance`` of ``value``.
    window_s : float
        The window's length [s]: the samples with t >= t_end - window_s.
    low, high : float
        The smallest and the largest sample in the window.
    tolerance : float
        The half-width of the band the samples had to stay in (units of the signal).
    """

    value: float
    settled: bool
    window_s: float
    low: float
    high: float
    tolerance: float

    def scaled(self, factor: float) -> "Settled":
        """The same in other units (``factor`` > 0, e.g. 180/pi for degrees)."""
        if not (math.isfinite(factor) and factor > 0):
            raise MetricError(f"factor must be finite and > 0, got {factor!r}")
        return Settled(self.value * factor, self.settled, self.window_s, self.low * factor, self.high * factor,
                       self.tolerance * factor)

    def as_dict(self) -> dict:
        """JSON fields: ``final`` (the mean), ``settled``, ``window_s``, ``range`` [low, high], ``tolerance``."""
        return {"final": self.value, "settled": self.settled, "window_s": self.window_s,
                "range": [self.low, self.high], "tolerance": self.tolerance}


def settle(t, y, window: float, *, relative: float = 0.05, floor: float = 0.0) -> Settled:
    r"""The mean of ``y`` over the last ``window`` seconds and whether ``y`` has settled there.

    .. math::

        \bar y = \frac{1}{n} \sum_{t_k \ge t_N - W} y_k, \qquad
        \text{settled} \iff \max_{t_k \ge t_N - W} |y_k - \bar y| \le
        \max(\rho\,|\bar y|, \epsilon)

    Parameters
    ----------
    t, y : array_like
        Increasing sample times [s] and the signal.
    window : float
        W [s], in (0, t_N - t_0]. Over W = m T (sample period T) the window holds m + 1 samples.
    relative : float
        rho: the band's half-width relative to the mean (default 5 %, the band of the 95 % rise
        time, sec. 5.4.2).
    floor : float
        epsilon: the smallest half-width, in the signal's units (e.g. what a sensor resolves), so
        that a signal settled at zero is not judged on its rounding noise.

    Returns
    -------
    Settled

    Raises
    ------
    MetricError
        ``window`` outside (0, t_N - t_0], or ``relative``/``floor`` negative or not finite.

    Notes
    -----
    The mean weighs every sample of the window equally, so over a window holding whole periods'
    worth of samples (n T = whole periods) the mean of a sinusoid is its offset whatever its phase.

    Examples
    --------
    >>> t = np.arange(0, 10.01, 0.2)
    >>> s = settle(t, 20 + 5 * np.sin(2 * np.pi * t / 5.6), 1.0)
    >>> s.settled, round(s.low, 1), round(s.high, 1)
    (False, 15.0, 16.9)
    >>> settle(t, 1 - np.exp(-t), 1.0).settled
    True
    """
    t, y = _series(t, y)
    return settle_rows(t, y[None], window, relative=relative, floor=floor)[0]


def settle_rows(t, ys, window: float, *, relative: float = 0.05, floor: float = 0.0) -> list[Settled]:
    """:func:`settle` of each row of ``ys`` (runs x samples) over the times ``t`` they share, the window's means,
    extremes and deviations reduced for all rows at once (a campaign's runs); the same numbers, row for row
    (the one implementation: :func:`settle` is this of one row)."""
    t, ys = np.asarray(t, float), np.asarray(ys, float)
    if ys.ndim != 2:
        raise ValueError(f"need rows of samples (runs x samples), got shape {ys.shape}")
    _series(t, ys[0] if len(ys) else t)
    if not (math.isfinite(relative) and relative >= 0 and math.isfinite(floor) and floor >= 0):
        raise MetricError(f"relative and floor must be finite and >= 0, got {relative!r}, {floor!r}")
    inside = np.ascontiguousarray(ys[:, _window(t, window)])   # rows in memory order: each row's mean sums as
    values = np.mean(inside, axis=1)                             # the one-row mean does (pairwise from 8 on)
    deviation = np.max(np.abs(inside - values[:, None]), axis=1)
    lows, highs = np.min(inside, axis=1), np.max(inside, axis=1)
    out = []
    for value, worst, low, high in zip(values.tolist(), deviation.tolist(), lows.tolist(), highs.tolist()):
        tolerance = max(relative * abs(value), floor)
        out.append(Settled(value, bool(worst <= tolerance), float(window), low, high, tolerance))
    return out


def saturation_time(t, command, limit: float) -> np.ndarray:
    """Seconds each input spent at its limit (commands held from sample to sample)."""
    t = np.asarray(t, float)
    command = np.asarray(command, float)
    held = np.diff(t, append=t[-1] + (t[-1] - t[-2]))
    at_limit = np.abs(command) >= limit * (1 - 1e-9)
    return (at_limit * held[:, None]).sum(axis=0)


@dataclass(frozen=True)
class LimitCycle:
    """A sustained oscillation: ``detected``, its ``period`` [s] and peak-to-peak ``amplitude``."""

    detected: bool
    period: float
    amplitude: float


def limit_cycle(t, y, min_amplitude: float, min_cycles: float = 2.0, min_correlation: float = 0.6) -> LimitCycle:
    """Look for a sustained periodic oscillation in ``y`` (e.g. the last half of a run).

    The signal is detrended (a straight line removed); the period is the lag
    of the first autocorrelation maximum after its first zero crossing. An
    oscillation counts when that peak's correlation is at least
    ``min_correlation``, at least ``min_cycles`` periods fit in the record and
    the peak-to-peak amplitude is at least ``min_amplitude``.

    Examples
    --------
    >>> t = np.arange(0, 40, 0.2)
    >>> lc = limit_cycle(t, 0.01 * np.sin(2 * np.pi * t / 6.2), 0.005)
    >>> lc.detected, round(lc.period, 1)
    (True, 6.2)
    """
    t, y = _series(t, y)
    dt = float(np.mean(np.diff(t)))
    x = y - np.polyval(np.polyfit(t, y, 1), t)
    amplitude = float(np.max(x) - np.min(x))
    n = x.size
    if amplitude < min_amplitude or n < 8:
        return LimitCycle(False, math.nan, amplitude)
    r = np.correlate(x, x, mode="full")[n - 1:]
    r = r / (r[0] * (n - np.arange(n)) / n)  # unbiased, normalised
    negative = np.flatnonzero(r < 0)
    if negative.size == 0:
        return LimitCycle(False, math.nan, amplitude)
    start = int(negative[0])
    peaks = [k for k in range(start + 1, n // 2) if r[k] > 0 and r[k] >= r[k - 1] and r[k] >= r[k + 1]]
    if not peaks:
        return LimitCycle(False, math.nan, amplitude)
    k = peaks[0]  # the first period, not a multiple of it
    # refine the peak with a parabola through its neighbours
    if 0 < k < n - 1:
        a, b, c = r[k - 1], r[k], r[k + 1]
        shift = 0.5 * (a - c) / (a - 2 * b + c) if (a - 2 * b + c) != 0 else 0.0
    else:
        shift = 0.0
    period = (k + shift) * dt
    detected = bool(r[k] >= min_correlation and (t[-1] - t[0]) >= min_cycles * period)
    return LimitCycle(detected, float(period) if detected else math.nan, amplitude)
