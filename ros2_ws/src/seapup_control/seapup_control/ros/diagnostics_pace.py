"""When a velocity controller publishes its ``/diagnostics``: every ``every`` samples, and in lockstep
no more often than it would in real time.

A lockstep graph runs a hundred times faster than real time or more; a status every ``every`` samples
would then be a hundred statuses per wall second, each costing the controller a sample's worth of
work, for readers (a human, ``rqt_runtime_monitor``, a recorder) who see one per second at most. In
lockstep a status is therefore also at least ``every`` x T wall seconds after the previous one: what
real time would give. Sampling on a timer (not lockstep), it is every ``every`` samples as before.
"""
from __future__ import annotations

__all__ = ["DiagnosticsPace"]


class DiagnosticsPace:
    """Decide, sample by sample, whether the status is due (pure: wall times are given).

    Parameters
    ----------
    sample_period : float
        T [s].
    lockstep : bool
        Throttle to the real-time rate (see the module docstring).

    Examples
    --------
    >>> pace = DiagnosticsPace(0.2, lockstep=True)
    >>> [n for n in range(1, 21) if pace.due(n, every=5, now=0.01 * n)]   # 100x real time: the first only
    [5]
    >>> pace.due(105, every=5, now=1.06)
    True
    >>> timer = DiagnosticsPace(0.2, lockstep=False)
    >>> [n for n in range(1, 21) if timer.due(n, every=5, now=0.01 * n)]
    [5, 10, 15, 20]
    """

    def __init__(self, sample_period: float, lockstep: bool):
        self.sample_period = float(sample_period)
        self.lockstep = bool(lockstep)
        self._sample = 0          # samples answered at the last status
        self._wall = None         # monotonic wall time of the last status [s]

    def due(self, samples: int, every: int, now: float) -> bool:
        """Whether to publish after ``samples`` answered samples at wall time ``now`` [s]; a True is taken as
        published."""
        if samples - self._sample < every:
            return False
        if self.lockstep and self._wall is not None and now < self._wall + every * self.sample_period:
            return False
        self._sample, self._wall = samples, now
        return True
