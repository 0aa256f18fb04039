"""How fast a paced lockstep graph may run against the wall clock, pure (the caller passes the wall time).

A lockstep graph runs as fast as its nodes answer. To be watched (the live view) the simulator can
pace it: :class:`Pacer` says how long to wait before publishing the next sample. Simulated time, and so
every result, is the same at any pace.
"""
from __future__ import annotations

import math

__all__ = ["Pacer"]


class Pacer:
    """When a paced lockstep simulator may publish a sample: at ``rate`` x real time (0: at once).

    A lockstep graph runs as fast as its nodes answer; to be watched (the live view) it can be paced so that
    sample t_k is published no earlier than ``wall0 + (t_k - t0) / rate``, where (t0, wall0) is where the
    pacing (re)started. The pace never speeds a graph up (a slow sample is not caught up on: the schedule
    restarts from it once it is more than :attr:`SLACK` wall seconds late, so a burst never follows a
    stall), and changing the rate restarts the schedule at the present sample. Simulated time, and so every
    result, is the same at any pace.
    """

    #: wall seconds a paced graph may fall behind its schedule and still catch up
    SLACK = 0.5

    def __init__(self, rate: float = 0.0):
        self._rate = 0.0
        self._origin: tuple[float, float] | None = None
        self.rate = rate

    @property
    def rate(self) -> float:
        return self._rate

    @rate.setter
    def rate(self, value: float) -> None:
        value = float(value)
        if not (math.isfinite(value) and value >= 0.0):
            raise ValueError(f"a lockstep pace must be a finite real-time factor >= 0 (0: unpaced), got {value!r}")
        self._rate = value
        self._origin = None

    def restart(self) -> None:
        """The schedule starts again at the next sample asked about (a reset graph)."""
        self._origin = None

    def delay(self, t_sim: float, wall: float) -> float:
        """Wall seconds to wait before publishing the sample at ``t_sim`` [s], the wall clock reading ``wall``."""
        if self._rate == 0.0:
            return 0.0
        if self._origin is None:
            self._origin = (t_sim, wall)
            return 0.0
        due = self._origin[1] + (t_sim - self._origin[0]) / self._rate
        if due <= wall:
            if wall - due > self.SLACK:   # a stall: go on from here at the pace, without a burst
                self._origin = (t_sim, wall)
            return 0.0
        return due - wall
