"""Figures of merit of closed-loop responses (thesis sec. 5.4.2-5.4.3).

The thesis characterises its step tests by the 95 % rise time, the
overshoot, the steady-state error, the interaction in the other outputs
("output decoupling"), thruster saturation, limit cycles (the sway-roll limit
cycle of the yaw test) and, for disturbance rejection, how far the vehicle
strays. These functions compute them from sampled time histories; they know
nothing of where the histories came from.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["rise_time", "overshoot_percent", "settled_value", "saturation_time", "LimitCycle", "limit_cycle"]


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
    y0 = y[0] if start is None else float(start)
    level = y0 + fraction * (target - y0)
    sign = 1.0 if target >= y0 else -1.0
    above = np.flatnonzero(sign * (y - level) >= 0)
    if above.size == 0:
        return math.nan
    k = int(above[0])
    if k == 0:
        return 0.0
    frac = (level - y[k - 1]) / (y[k] - y[k - 1])
    return float(t[k - 1] + frac * (t[k] - t[k - 1]) - t[0])


def overshoot_percent(y, target: float, start: float = 0.0) -> float:
    """Largest excursion beyond ``target``, in percent of the step (0 if none; NaN for a zero step)."""
    y = np.asarray(y, float)
    step = target - start
    if step == 0:
        return math.nan
    beyond = (y - target) / step
    return float(max(0.0, np.max(beyond)) * 100.0)


def settled_value(t, y, window: float) -> float:
    """Mean of ``y`` over the last ``window`` seconds."""
    t, y = _series(t, y)
    return float(np.mean(y[t >= t[-1] - window - 1e-9]))


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
