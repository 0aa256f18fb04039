"""Online identification: readings of each sample joined by stamp, fed to the recursive estimator (thesis ch. 6, 7).

The ``identifier`` node's core. Each control sample t_k brings a velocity reading (u, v, w and
the yaw rate r), optionally the attitude (roll, pitch) and the blade pitch the vehicle applied
from t_k on; once all of a sample's readings are in, the sample is used:

    y(t_k) = (outputs named in ``outputs``),  u(t_k) = applied blade pitch,
    RecursiveArmax.step(y(t_k), u(t_k))

exactly as :func:`seapup_ident.identify.fit` treats a recorded record, so a fit of the samples the
node used gives the model it published (a missing sample is a gap: the regressor refills and the
first ``lag`` samples after it only fill it). Readings older than a used sample, or incomplete
when a later sample completes, count as dropped.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from seapup_ident.armax import ArmaxOrders
from seapup_ident.recursive import DataError, Forgetting, RecursiveArmax

__all__ = ["OUTPUTS", "UsedSample", "OnlineIdentifier"]

#: Output names and the reading each comes from.
OUTPUTS = {"u": ("velocity", 0), "v": ("velocity", 1), "w": ("velocity", 2), "r": ("velocity", 3),
           "roll": ("attitude", 0), "pitch": ("attitude", 1)}


@dataclass(frozen=True)
class UsedSample:
    """One sample the estimator took."""

    stamp_ns: int
    y: np.ndarray
    u: np.ndarray
    theta: np.ndarray
    prediction_error: np.ndarray
    updated: bool


class OnlineIdentifier:
    """Join readings by stamp and run :class:`RecursiveArmax` on each complete sample.

    Parameters
    ----------
    orders : ArmaxOrders
        With ny = len(outputs) and nu = 4 (the blade pitches).
    method : str
        ``ls``, ``els`` or ``rpem``.
    outputs : sequence of str
        From ``u, v, w, r, roll, pitch`` (ch. 6) or ``u, v, w, r`` (ch. 7).
    sample_period : float
        T [s]; a sample more than 1.5 T after the previous one used starts a new segment.
    """

    def __init__(self, orders: ArmaxOrders, method: str = "ls", outputs=("u", "v", "w", "r", "roll", "pitch"), *,
                 forgetting: Forgetting | None = None, p0: float = 100.0, sample_period: float = 0.2):
        unknown = [o for o in outputs if o not in OUTPUTS]
        if unknown or len(outputs) != orders.ny or orders.nu != 4:
            raise ValueError(f"outputs {list(outputs)} must be {orders.ny} of {', '.join(OUTPUTS)} and nu 4 "
                             f"(blade pitches), got unknown {unknown}, nu {orders.nu}")
        self.orders, self.outputs = orders, tuple(outputs)
        self.kinds = {"velocity", "applied"} | {OUTPUTS[o][0] for o in outputs}
        self.estimator = RecursiveArmax(orders, method, forgetting=forgetting, p0=p0)
        self.sample_period = float(sample_period)
        self._pending: dict[int, dict] = {}
        self._last_used: int | None = None
        self._filled = 0          # samples in the regressor since the last restart
        self.counts = {"used": 0, "dropped": 0, "rejected": 0, "segments": 0}

    def add(self, kind: str, stamp_ns: int, values) -> UsedSample | None:
        """A reading of ``kind`` (velocity: u, v, w, r; attitude: roll, pitch; applied: 4 pitches) for sample
        ``stamp_ns``; the sample it completes, used, or None."""
        if kind not in ("velocity", "attitude", "applied"):
            raise ValueError(f"unknown reading kind {kind!r}")
        values = np.asarray(values, dtype=float).ravel()
        size = {"velocity": 4, "attitude": 2, "applied": 4}[kind]
        if values.shape != (size,) or not np.all(np.isfinite(values)):
            self.counts["rejected"] += 1
            raise DataError(f"{kind} reading at {stamp_ns * 1e-9:.3f} s must be {size} finite values, "
                            f"got {values.tolist()}")
        if kind not in self.kinds:
            return None
        if self._last_used is not None and stamp_ns <= self._last_used:
            self.counts["dropped"] += 1  # late: its sample was used (or skipped) already
            return None
        self._pending.setdefault(stamp_ns, {})[kind] = values
        if set(self._pending[stamp_ns]) != self.kinds:
            return None
        return self._use(stamp_ns)

    def _use(self, stamp_ns: int) -> UsedSample:
        for older in [s for s in self._pending if s < stamp_ns]:
            del self._pending[older]
            self.counts["dropped"] += 1
        readings = self._pending.pop(stamp_ns)
        y = np.array([readings[OUTPUTS[o][0]][OUTPUTS[o][1]] for o in self.outputs])
        u = readings["applied"]
        gap = self._last_used is None or (stamp_ns - self._last_used) * 1e-9 > 1.5 * self.sample_period
        if gap:
            self.estimator.restart()
            self._filled = 0
            self.counts["segments"] += 1
        update = self._filled >= self.orders.lag
        theta, y_hat = self.estimator.step(y, u, update=update)
        self._filled += 1
        self._last_used = stamp_ns
        self.counts["used"] += 1
        return UsedSample(stamp_ns, y, u, theta, y - y_hat, update)
