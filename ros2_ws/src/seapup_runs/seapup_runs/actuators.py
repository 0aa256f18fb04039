"""Actuator activity of a stretch of flight: how hard, and how nervously, the blade pitches were driven.

A leg can reach its goal while its thrusters chatter between their limits: the task's verdict and the
tracking error do not see it, the thrusters (and a real vehicle's servos) do. From the commanded blade
pitches (one row per control sample, one column per thruster) :func:`actuator_activity` measures

- ``saturation_pct``: the share of samples in which some pitch is at its limit [%];
- ``max_step_deg`` and ``max_rate_deg_s``: the largest one-sample change of a pitch [deg] and that change over
  its sample interval [deg/s];
- ``swings_per_min``: *swings* -- one-sample changes of at least the limit, half the full range, such as a jump
  from one limit to the other -- per minute of the stretch, on the most active thruster;
- ``thrash_s`` and ``thrash_t``: the longest *thrashing* episode and when it began [s]: a chain of swings (any
  thruster) each following the previous within :data:`THRASH_ALLOWANCE_S`, from its first swing to its last;
- ``thrashed``: that episode lasted longer than :data:`THRASH_ALLOWANCE_S`.

The allowance is the thesis's own: in sec. 7.6.1 (fig. 7.3) its self-tuner's commissioning stage is one
"during which the thrusters have thrashed about for approximately 1.6 seconds" and is accepted as such;
thrashing that lasts longer than that, or comes back within it, is more than the thesis's jacket lets through.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["actuator_activity", "THRASH_ALLOWANCE_S"]

#: Thrashing the thesis accepts [s]: its self-tuner's commissioning, sec. 7.6.1 (fig. 7.3).
THRASH_ALLOWANCE_S = 1.6


def actuator_activity(t, pitch, limit: float) -> dict:
    """The actuator activity of commanded blade pitches (see the module docstring).

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times [s], increasing.
    pitch : array_like, shape (n, m)
        Commanded blade pitch of each of m thrusters at each sample [rad].
    limit : float
        The pitch limit [rad] (commands lie in [-limit, limit]).

    Returns
    -------
    dict
        ``saturation_pct``, ``max_step_deg``, ``max_rate_deg_s``, ``swings_per_min``, ``thrash_s``,
        ``thrash_t`` (NaN when nothing thrashed), ``thrashed``, ``samples``.

    Raises
    ------
    ValueError
        Times not increasing, shapes that do not match, non-finite values or a limit that is not positive.

    Examples
    --------
    A square wave between the limits, one swing per 0.2 s sample for 10 s, thrashes for its whole length:

    >>> t = np.arange(51) * 0.2
    >>> square = np.where(np.arange(51) % 2, 0.6, -0.6)[:, None]
    >>> a = actuator_activity(t, square, 0.6)
    >>> a["thrashed"], round(a["thrash_s"], 1), round(a["swings_per_min"]), round(a["max_rate_deg_s"])
    (True, 9.8, 300, 344)
    """
    t = np.asarray(t, dtype=float)
    pitch = np.asarray(pitch, dtype=float)
    if pitch.ndim == 1:
        pitch = pitch[:, None]
    if t.ndim != 1 or pitch.ndim != 2 or len(t) != len(pitch):
        raise ValueError(f"actuator activity: {len(t)} times for {len(pitch)} rows of pitches")
    if not (math.isfinite(limit) and limit > 0):
        raise ValueError(f"actuator activity: the pitch limit must be positive and finite, got {limit!r}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(pitch))):
        raise ValueError("actuator activity: non-finite time or pitch")
    dt = np.diff(t)
    if np.any(dt <= 0):
        raise ValueError("actuator activity: sample times must increase")
    n = len(t)
    out = {"samples": n, "saturation_pct": 0.0, "max_step_deg": 0.0, "max_rate_deg_s": 0.0,
           "swings_per_min": 0.0, "thrash_s": 0.0, "thrash_t": math.nan, "thrashed": False}
    if n == 0:
        return out
    out["saturation_pct"] = 100.0 * float(np.mean(np.any(np.abs(pitch) >= limit * (1 - 1e-9), axis=1)))
    if n < 2:
        return out
    steps = np.abs(np.diff(pitch, axis=0))                  # (n - 1, m)
    out["max_step_deg"] = math.degrees(float(steps.max()))
    out["max_rate_deg_s"] = math.degrees(float((steps / dt[:, None]).max()))
    swings = steps >= limit * (1 - 1e-9)
    minutes = (t[-1] - t[0]) / 60.0
    out["swings_per_min"] = float(swings.sum(axis=0).max() / minutes)
    times = t[1:][swings.any(axis=1)]                       # when a swing ended, any thruster
    if len(times):
        breaks = np.flatnonzero(np.diff(times) > THRASH_ALLOWANCE_S)
        starts = np.concatenate([[0], breaks + 1])
        ends = np.concatenate([breaks, [len(times) - 1]])
        spans = times[ends] - times[starts]
        k = int(np.argmax(spans))
        out["thrash_s"] = float(spans[k])
        out["thrash_t"] = float(times[starts[k]])
        out["thrashed"] = bool(spans[k] > THRASH_ALLOWANCE_S)
    return out
