"""Online identification: readings of each sample joined by stamp, fed to the recursive estimator (thesis ch. 6, 7).

The ``identifier`` node's core. Each control sample t_k brings a velocity reading (u, v, w and
the yaw rate r), optionally the attitude (roll, pitch), and the blade pitch the thrusters have
at t_k. The input that drives the vehicle from t_k to t_k+1 -- the u(t_k) of the regression
y(t_k+1) = ... + B_1 u(t_k) (eq. 6.24, B from z^-1) -- is the pitch held over that interval, which
the *next* sample's applied reading measures: the actuator lag (0.05 s) has settled by then, and
the applied pitch at t_k itself is still the previous interval's (using it as u(t_k) delays every
input by one sample; the ch. 6 losses came out 5-20 times the thesis's that way). So

    y(t_k) = (outputs named in ``outputs``),  u(t_k) = applied pitch read at t_k+1,
    RecursiveArmax.step(y(t_k), u(t_k))                      (taken when t_k+1's pitch arrives)

exactly as :func:`seapup_ident.identify.fit` treats a recorded record read by
:func:`held_inputs`, so a fit of the samples the node used gives the model it published (a
missing sample is a gap: the regressor refills and the first ``lag`` samples after it only fill
it). Readings older than a used sample, or incomplete when a later sample completes, count as
dropped.
"""
from __future__ import annotations

import bisect
from dataclasses import dataclass

import numpy as np

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_common.lockstep import StampGate
from seapup_ident.armax import ArmaxOrders
from seapup_ident.recursive import DataError, Forgetting, RecursiveArmax

__all__ = ["OUTPUTS", "UsedSample", "OnlineIdentifier", "input_stamp", "held_inputs"]

#: Output names and the reading each comes from.
#: The largest magnitude a reading may have: [m/s] and [rad/s] (velocity u, v, w, r: ten times the
#: Seapup's top speed), [rad] (roll, pitch), [rad] (blade pitches: the +/-35 deg stops). Beyond them a
#: reading is a fault, not data.
READING_LIMITS = {"velocity": 10.0, "attitude": np.pi, "applied": BLADE_PITCH_LIMIT + 1e-9}
OUTPUTS = {"u": ("velocity", 0), "v": ("velocity", 1), "w": ("velocity", 2), "r": ("velocity", 3),
           "roll": ("attitude", 0), "pitch": ("attitude", 1)}


def input_stamp(stamp_ns: int, applied_stamps, sample_period: float) -> int | None:
    """The stamp of the applied reading that measures u(t_k) for the sample at ``stamp_ns``: the first
    after it, no later than 1.5 T (None: the pitch over this interval was not read). ``applied_stamps``
    sorted ascending."""
    i = bisect.bisect_right(applied_stamps, stamp_ns)
    if i == len(applied_stamps) or (applied_stamps[i] - stamp_ns) * 1e-9 > 1.5 * sample_period:
        return None
    return int(applied_stamps[i])


def held_inputs(stamps_ns, applied: dict, sample_period: float) -> np.ndarray:
    """u(t_k) for each sample stamp: the applied pitch (4,) read at :func:`input_stamp`, NaN where none.

    ``applied`` maps stamp [ns] -> the four applied blade pitches [rad]."""
    ordered = sorted(applied)
    u = np.full((len(stamps_ns), 4), np.nan)
    for k, stamp in enumerate(stamps_ns):
        found = input_stamp(int(stamp), ordered, sample_period)
        if found is not None:
            u[k] = applied[found]
    return u


@dataclass(frozen=True)
class UsedSample:
    """One sample the estimator took."""

    stamp_ns: int
    input_stamp_ns: int           # the applied reading used as u(t_k)
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
    filter_weakening : (K(0), gamma), optional
        RPEM only: see :class:`~seapup_ident.recursive.RecursiveArmax`.
    """

    def __init__(self, orders: ArmaxOrders, method: str = "ls", outputs=("u", "v", "w", "r", "roll", "pitch"), *,
                 forgetting: Forgetting | None = None, p0: float = 100.0, sample_period: float = 0.2,
                 filter_weakening: tuple[float, float] | None = None):
        unknown = [o for o in outputs if o not in OUTPUTS]
        if unknown or len(outputs) != orders.ny or orders.nu != 4:
            raise ValueError(f"outputs {list(outputs)} must be {orders.ny} of {', '.join(OUTPUTS)} and nu 4 "
                             f"(blade pitches), got unknown {unknown}, nu {orders.nu}")
        self.orders, self.outputs = orders, tuple(outputs)
        self.output_kinds = {"velocity"} | {OUTPUTS[o][0] for o in outputs}
        self.kinds = self.output_kinds | {"applied"}
        self.estimator = RecursiveArmax(orders, method, forgetting=forgetting, p0=p0, filter_weakening=filter_weakening)
        self.sample_period = float(sample_period)
        self._pending: dict[int, dict] = {}
        self._last_used: int | None = None
        self._filled = 0          # samples in the regressor since the last restart
        self.counts = {"used": 0, "dropped": 0, "rejected": 0, "segments": 0}
        # one gate per stream: the graph's time each stream has reached. A stream that lags another (an executor
        # that takes one topic's queue before the next, on a loaded machine) is then not read as a reset of the
        # shared time, after which the leading stream's next reading looked 60 s ahead and was refused
        self.stamps = {kind: StampGate() for kind in ("velocity", "attitude", "applied")}

    def add(self, kind: str, stamp_ns: int, values) -> list[UsedSample]:
        """A reading of ``kind`` (velocity: u, v, w, r; attitude: roll, pitch; applied: 4 pitches) at
        ``stamp_ns``; the samples it completes, used, in stamp order (usually none or one)."""
        if kind not in ("velocity", "attitude", "applied"):
            raise ValueError(f"unknown reading kind {kind!r}")
        values = np.asarray(values, dtype=float).ravel()
        size = {"velocity": 4, "attitude": 2, "applied": 4}[kind]
        if values.shape != (size,) or not np.all(np.isfinite(values)):
            self.counts["rejected"] += 1
            raise DataError(f"{kind} reading at {stamp_ns * 1e-9:.3f} s must be {size} finite values, "
                            f"got {values.tolist()}")
        if np.any(np.abs(values) > READING_LIMITS[kind]):  # one 1e200 would make every later model non-finite
            self.counts["rejected"] += 1
            raise DataError(f"{kind} reading at {stamp_ns * 1e-9:.3f} s is beyond what the vehicle can do "
                            f"(|value| <= {READING_LIMITS[kind]:g}): {values.tolist()}")
        gate = self.stamps[kind]
        if gate.latest_ns is None:   # a stream's first reading: judged by the time the others have reached
            known = [other for other in self.stamps.values() if other.latest_ns is not None]
            leader = max(known, key=lambda other: other.latest_ns) if known else None
            if leader is not None and stamp_ns > leader.latest_ns + leader.max_jump_ns:
                self.counts["rejected"] += 1
                leader.refused += 1
                raise DataError(f"{kind} reading {leader.why(stamp_ns)}")
        if not gate.accept(stamp_ns):  # one far-future stamp would make every real sample late
            self.counts["rejected"] += 1
            raise DataError(f"{kind} reading {gate.why(stamp_ns)}")
        if kind not in self.kinds:
            return []
        if self._last_used is not None and stamp_ns <= self._last_used:
            self.counts["dropped"] += 1  # late: its sample (or the one it is the input of) was used already
            return []
        self._pending.setdefault(stamp_ns, {})[kind] = values
        used = []
        while (sample := self._complete()) is not None:
            used.append(self._use(*sample))
        return used

    def _complete(self) -> tuple[int, int] | None:
        """The earliest pending sample with its outputs and its input in: (stamp, input stamp)."""
        applied = sorted(s for s, r in self._pending.items() if "applied" in r)
        for stamp in sorted(self._pending):
            if self._last_used is not None and stamp <= self._last_used:
                continue
            if self.output_kinds <= set(self._pending[stamp]):
                after = input_stamp(stamp, applied, self.sample_period)
                if after is not None:
                    return stamp, after
        return None

    def _use(self, stamp_ns: int, input_ns: int) -> UsedSample:
        for older in [s for s in self._pending if s < stamp_ns]:
            if self.output_kinds & set(self._pending[older]):
                self.counts["dropped"] += 1
            del self._pending[older]
        readings = self._pending[stamp_ns]
        y = np.array([readings[OUTPUTS[o][0]][OUTPUTS[o][1]] for o in self.outputs])
        u = self._pending[input_ns]["applied"]
        del self._pending[stamp_ns]   # its own applied reading measured the interval before it
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
        return UsedSample(stamp_ns, input_ns, y, u, theta, y - y_hat, update)
