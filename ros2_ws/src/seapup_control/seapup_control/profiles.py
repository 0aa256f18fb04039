"""Piecewise-constant profiles: the open-loop tests' blade pitches and the velocity references of
closed-loop runs.

The open-loop verification tests of the thesis (sec. 3.3, Table 3.2) drive the
vehicle with blade pitches held constant between switching instants, e.g. both
main thrusters at +35 deg from t = 0 for the surge test. A
:class:`PitchProfile` is such an input: switching times and the four pitches
held from each time on. A :class:`ReferenceProfile` holds body-velocity references (u, v, w, r)
the same way and may repeat with a period: the square wave of half-period 10 s under which thesis
sec. 6.5.5 identifies the closed loop is two rows and a 20 s period.
"""
from __future__ import annotations

import types

import numpy as np

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT, INPUT_LIMIT_RANGE, VIRTUAL_INPUT_LIMIT, check_blade_pitch
from seapup_common.contract import Command, Measurement, Reference
from seapup_common.controllers import ControllerType, Ranged

__all__ = ["ProfileError", "PitchProfile", "OpenLoop", "ReferenceProfile", "OPEN_LOOP_TYPE"]


class ProfileError(ValueError):
    """A profile whose times or pitches are inconsistent."""


class PitchProfile:
    """Blade pitches held constant between switching times.

    Parameters
    ----------
    times : array_like, shape (n,)
        Switching times [s], strictly increasing, starting at 0.
    pitches : array_like, shape (n, 4) or (4 * n,)
        Blade pitches [rad] held from ``times[i]`` until ``times[i+1]`` (the
        last row is held for ever), in ``seapup_msgs/BladePitch`` order.
    limit : float, optional
        Blade-pitch limit [rad]; a schedule may not ask for more (default the
        Seapup's +/-35 deg, :data:`~seapup_common.blade_pitch.BLADE_PITCH_LIMIT`).

    Examples
    --------
    >>> s = PitchProfile([0.0, 5.0], [[0.6, 0.6, 0, 0], [0, 0, 0, 0]], limit=0.61)
    >>> float(s.at(4.9)[0]), float(s.at(5.0)[0])
    (0.6, 0.0)
    """

    def __init__(self, times, pitches, limit: float = BLADE_PITCH_LIMIT):
        t, p = _rows(times, pitches, "pitches")
        for i, row in enumerate(p):
            _, clipped = check_blade_pitch(row, limit)  # raises on non-finite rows
            if clipped:
                raise ProfileError(
                    f"row {i} asks for more than the blade limit {limit:.4f} rad: {row.tolist()}")
        self.times = t
        self.pitches = p

    def at(self, t: float) -> np.ndarray:
        """Blade pitches [rad] at time ``t`` >= 0 (a copy)."""
        if not (np.isfinite(t) and t >= 0.0):
            raise ProfileError(f"schedule time must be finite and >= 0, got {t!r}")
        i = int(np.searchsorted(self.times, t, side="right")) - 1
        return self.pitches[i].copy()

    @property
    def duration(self) -> float:
        """Time of the last switch [s]; the last row is held after it."""
        return float(self.times[-1])


def _rows(times, values, what: str) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(times, dtype=float)
    v = np.asarray(values, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise ProfileError(f"times must be a non-empty list, got shape {t.shape}")
    if v.ndim == 1:
        if v.size != 4 * t.size:
            raise ProfileError(f"{t.size} switching times need {4 * t.size} {what} (4 each), got {v.size}")
        v = v.reshape(t.size, 4)
    if v.shape != (t.size, 4):
        raise ProfileError(f"{what} must have shape ({t.size}, 4), got {v.shape}")
    if not np.all(np.isfinite(t)) or t[0] != 0.0 or np.any(np.diff(t) <= 0.0):
        raise ProfileError(f"times must be finite, start at 0 and increase strictly: {t.tolist()}")
    return t, v


class ReferenceProfile:
    """Body-velocity references (u, v, w [m/s], r [rad/s]) held between switching times, optionally
    repeating: a fixed test profile (unlike :class:`seapup_common.contract.StampedReferences`, the
    velocity controller's queue of stamped references as they arrive).

    Parameters
    ----------
    times : array_like, shape (n,)
        Switching times [s], strictly increasing, starting at 0.
    references : array_like, shape (n, 4) or (4 * n,)
        (u, v, w, r) held from ``times[i]`` on, finite.
    period : float, optional
        Repeat the schedule every ``period`` seconds (> the last switching time); 0 or None holds the
        last row for ever.

    Examples
    --------
    The reference of thesis sec. 6.5.5, a square wave of half-period 10 s:

    >>> import math
    >>> s = ReferenceProfile([0.0, 10.0], [[0.2, 0, 0, math.radians(15)], [0, 0.1, -0.1, 0]], period=20.0)
    >>> s.at(25.0).velocity.tolist()
    [0.2, 0.0, 0.0, 0.2617993877991494]
    """

    def __init__(self, times, references, period: float | None = None):
        self.times, self.references = _rows(times, references, "references")
        if not np.all(np.isfinite(self.references)):
            raise ProfileError(f"references must be finite: {self.references.tolist()}")
        period = 0.0 if period is None else float(period)
        if not np.isfinite(period) or (period != 0.0 and period <= self.times[-1]):
            raise ProfileError(f"period must be 0 (no repeat) or longer than the last switch "
                                f"{self.times[-1]:g} s, got {period!r}")
        self.period = period

    def at(self, t: float) -> Reference:
        """The reference at time ``t`` >= 0."""
        if not (np.isfinite(t) and t >= 0.0):
            raise ProfileError(f"schedule time must be finite and >= 0, got {t!r}")
        if self.period:
            t = t % self.period
        i = int(np.searchsorted(self.times, t, side="right")) - 1
        return Reference(self.references[i].copy())


class OpenLoop:
    """A :class:`PitchProfile` flown as a velocity controller (open loop).

    Parameters
    ----------
    schedule : PitchProfile
    sample_period : float
        T [s], > 0.
    start_time : float
        Simulation time [s] at which the schedule's time 0 is (set by
        :meth:`reset` to the time of the applied command when it has one).

    Examples
    --------
    >>> ctl = OpenLoop(PitchProfile([0.0, 1.0], [[0.1] * 4, [0.0] * 4]), 0.2)
    >>> ctl.reset(Command([0.0] * 4, stamp=0.0))
    >>> ctl.update(1.2, Measurement(1.2), Reference()).blade_pitch.tolist()
    [0.0, 0.0, 0.0, 0.0]
    """

    def __init__(self, schedule: PitchProfile, sample_period: float, start_time: float = 0.0):
        if not (np.isfinite(sample_period) and sample_period > 0):
            raise ProfileError(f"sample period must be finite and > 0 s, got {sample_period!r}")
        self.schedule = schedule
        self.sample_period = float(sample_period)
        self.start_time = float(start_time)

    def reset(self, applied: Command) -> None:
        """Start the schedule at the applied command's time (an open loop has no other state)."""
        if np.isfinite(applied.stamp):
            self.start_time = float(applied.stamp)

    def applied(self, t: float, command: Command) -> None:
        """Nothing to learn: an open loop does not depend on what the vehicle did."""

    def update(self, t: float, measurement: Measurement, reference: Reference) -> Command:
        """The schedule's pitches at ``t`` (measurement and reference are not used)."""
        return Command(self.schedule.at(max(t - self.start_time, 0.0)), stamp=t)

    def diagnostics(self) -> dict:
        return {"start_time": self.start_time}


def _open_loop(parameters: dict, document, sample_period: float | None) -> OpenLoop:
    if sample_period is None:
        raise ProfileError("the open_loop controller needs the sample period of its caller")
    if not parameters["times"] or not parameters["pitches"]:
        raise ProfileError("open_loop needs its switching times and four pitches per time")
    return OpenLoop(PitchProfile(parameters["times"], parameters["pitches"], parameters["blade_pitch_limit"]),
                    sample_period)


#: An open-loop blade-pitch schedule flown as a velocity controller (registered as ``open_loop``): the
#: open-loop tests of sec. 3.3 / Table 3.2 as run specifications. ``times`` [s] from the controller's
#: start, ``pitches`` [rad] four per time (``BladePitch`` order), ``blade_pitch_limit`` [rad].
OPEN_LOOP_TYPE = ControllerType(
    "open_loop", _open_loop,
    types.MappingProxyType({
        "times": Ranged([], 0.0, 1e6, "[s] from the controller's start: not before it; 1e6 s (11 days) bounds "
                                      "a schedule"),
        "pitches": Ranged([], -BLADE_PITCH_LIMIT, BLADE_PITCH_LIMIT, "the blade-pitch limit, +/-35 deg (sec. 3.1)"),
        "blade_pitch_limit": Ranged(BLADE_PITCH_LIMIT, 0.01, VIRTUAL_INPUT_LIMIT, INPUT_LIMIT_RANGE)}),
    "blade pitches held between switching times from its start (open loop, sec. 3.3)")
