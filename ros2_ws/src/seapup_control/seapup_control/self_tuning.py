"""What the two self-tuners of ch. 7 share: commissioning on the self-tested gains, jacketing, the fallback and the
bookkeeping (:class:`SelfTuner`; the laws are :mod:`seapup_control.explicit` and :mod:`seapup_control.gmv`).

**Commissioning** (sec. 7.4.1): for the first ``commissioning_samples`` samples the self-tested fixed gains
(the controller file's zero-speed point) fly the vehicle while the estimator watches.

**Jacketing** (sec. 7.3 and 8.3 recommend it; the thesis's runs had none), :class:`TunerJacket`:

- estimation is frozen (no update, no forgetting) while every output is within ``set_point_band`` of its
  reference, or while the input does not excite (every blade pitch moved less than ``excitation`` since
  the last sample) -- sec. 7.3's "estimator going to sleep" and bursting (eq. 6.12);
- the law falls back to the fixed gains while trace P exceeds ``max_trace_growth`` times its starting value
  p0 n (covariance wind-up; the estimate still updates, as sec. 7.3 says) or while the estimate fails the
  law's own sanity rules;
- every change of mode is logged with its reason and counted (:meth:`SelfTuner.diagnostics`).

**The fixed-gain law** both fly while commissioning and fallen back is eq. 4.11 in its incremental
(velocity) form, u(t) = u_applied(t-1) + K_int e(t-1) + K_err [e(t) - e(t-1)]: it continues from the setting
the thrusters hold, so every change of mode is bumpless on its side.
"""
from __future__ import annotations

import logging
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT, INPUT_LIMIT_RANGE, VIRTUAL_INPUT_LIMIT
from seapup_common.contract import Command, ContractError, Measurement, Reference
from seapup_common.controllers import Ranged
from seapup_control.mfol import DesignError, TwoTermGains

__all__ = ["TunerJacket", "SelfTuner", "OUTPUTS", "MODES", "TUNER_PARAMETERS", "jacket_from"]

_log = logging.getLogger(__name__)

OUTPUTS = ("u", "v", "w", "r")
#: What a self-tuner is doing: flying the fixed gains while the estimator watches, flying its adaptive law,
#: or flying the fixed gains because a jacket rule refused the estimate.
MODES = ("commissioning", "adaptive", "fallback")


@dataclass(frozen=True)
class TunerJacket:
    """The safeguards of sec. 7.3 (see the module docstring); SI units and radians."""

    set_point_band: tuple = (0.005, 0.005, 0.005, 0.005)   # |e| [m/s, m/s, m/s, rad/s] counted "at the set point"
    excitation: float = math.radians(0.05)                  # a blade pitch moving less than this does not excite
    max_trace_growth: float = 10.0                          # trace P above this times trace P(0): fall back (inf: never)
    min_rcond: float = 1e-4                                 # a matrix the law inverts below it: fall back
    max_pole: float = 1.3                                   # an estimated open-loop pole |z| at or beyond: fall back

    def __post_init__(self):
        band = np.asarray(self.set_point_band, dtype=float)
        if band.shape != (4,) or not np.all(np.isfinite(band)) or np.any(band < 0):
            raise DesignError(f"set_point_band needs four finite values >= 0, got {self.set_point_band!r}")
        for name in ("excitation", "max_trace_growth", "min_rcond", "max_pole"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and not math.isnan(value) and value >= 0
                    and (math.isfinite(value) or name == "max_trace_growth")):
                raise DesignError(f"jacket {name} must be a finite number >= 0 (max_trace_growth may be inf: never), "
                                  f"got {value!r}")


#: The settings every self-tuner's registered type takes (SI, radians but the excitation in degrees), each
#: with the range a node or a run specification may set it to and where that range comes from.
TUNER_PARAMETERS = {
    "forgetting": Ranged(0.999, 0.9, 1.0, "eq. 6.13: lambda in (0, 1]; below 0.9 the memory 1/(1 - lambda) is "
                                          "under 10 samples, fewer than the 9 parameters per output of the "
                                          "explicit model (sec. 7.3), so the estimate is not determined"),
    "p0": Ranged(1e4, 1e-3, 1e10, "eq. 6.16, P(0) = p0 I; sec. 6.3's 100 / E{y^2} is 1e2 at 1 m/s and 1e8 at "
                                  "1 mm/s: two decades beyond either end"),
    "commissioning_samples": Ranged(5, 1, 100_000, "sec. 7.4.1: five; at least one (the estimator's first "
                                                   "sample), at most 100000 (5.5 h at 5 Hz)"),
    "set_point_band": Ranged([0.005, 0.005, 0.005, 0.005], 0.0, 1.0,
                             "|e| [m/s, rad/s]: 1 is beyond the vehicle's speeds (0.7 m/s, sec. 5.3.1)"),
    "excitation_deg": Ranged(0.05, 0.0, 70.0, "a blade-pitch move [deg]: at most the whole travel, 2 x 35 deg "
                                              "(sec. 3.1)"),
    "max_trace_growth": Ranged(10.0, 1.0, 1e12, "trace P over trace P(0): below 1 the law would fall back at "
                                                "once; 1e12: never in practice (inf is refused)"),
    "min_rcond": Ranged(1e-4, 0.0, 1.0, "a reciprocal condition number lies in [0, 1] by definition"),
    "blade_pitch_limit": Ranged(BLADE_PITCH_LIMIT, 0.01, VIRTUAL_INPUT_LIMIT, INPUT_LIMIT_RANGE),
}


def jacket_from(parameters: dict) -> TunerJacket:
    """The jacket of a registered type's complete parameters."""
    return TunerJacket(tuple(parameters["set_point_band"]), math.radians(parameters["excitation_deg"]),
                       parameters["max_trace_growth"], parameters["min_rcond"], parameters.get("max_pole", 1.3))


class SelfTuner(ABC):
    """The shared part of the self-tuners (see the module docstring); a law overrides :meth:`_law`.

    Parameters
    ----------
    fixed : TwoTermGains
        The self-tested fixed gains: flown while commissioning and as the fallback.
    forgetting : float
        lambda of eq. 6.13, in (0, 1].
    p0 : float
        P(0) = p0 I (eq. 6.16). Sec. 6.3 suggests p = 100 / E{y^2}: 1e4 for velocities of about 0.1 m/s.
    commissioning_samples : int
        Samples flown on the fixed gains before the adaptive law (sec. 7.4.1: five).
    jacket : TunerJacket
    limit : float
        Blade-pitch limit [rad].
    """

    kind = "self-tuner"
    #: The jacket rules that can refuse the law (each a counter and a reason)
    RULES = ("fallback_trace", "fallback_insane")

    def __init__(self, fixed: TwoTermGains, forgetting: float = 0.999, p0: float = 1e4,
                 commissioning_samples: int = 5, jacket: TunerJacket | None = None,
                 limit: float = BLADE_PITCH_LIMIT):
        if fixed.K_int.shape != (4, 4):
            raise DesignError(f"the fixed gains must be 4 x 4, got {fixed.K_int.shape}")
        if not (math.isfinite(forgetting) and 0.0 < forgetting <= 1.0):
            raise DesignError(f"forgetting must be in (0, 1], got {forgetting!r}")
        if not (math.isfinite(p0) and p0 > 0):
            raise DesignError(f"p0 must be > 0, got {p0!r}")
        if int(commissioning_samples) != commissioning_samples or commissioning_samples < 1:
            raise DesignError(f"commissioning_samples must be a whole number >= 1, got {commissioning_samples!r}")
        if not (math.isfinite(limit) and limit > 0):
            raise DesignError(f"limit must be > 0 rad, got {limit!r}")
        self.fixed = fixed
        self.sample_period = fixed.sample_period
        self.forgetting, self.p0 = float(forgetting), float(p0)
        self.commissioning_samples = int(commissioning_samples)
        self.jacket = jacket or TunerJacket()
        self.limit = float(limit)

    # -- state ---------------------------------------------------------------------------------------
    def _start(self, pitch: np.ndarray) -> None:
        """Back to the start: the estimator's own reset is the law's (:meth:`_restart`)."""
        self.samples = 0
        self.u_prev = pitch.copy()                  # the setting held now (the fixed law continues from it)
        self.e_prev = np.zeros(4)
        self.applied_prev: np.ndarray | None = None
        self.mode, self.reason, self.frozen = "", "", ""   # set at the first sample (commissioning)
        self._rule = ""                             # the jacket rule behind the present fallback
        self.counts = {"samples": 0, "estimated": 0, "frozen_at_set_point": 0, "frozen_no_excitation": 0,
                       **dict.fromkeys(self.RULES, 0), "commissioning": 0, "adaptive": 0, "fallback": 0,
                       "engagements": 0}
        self.events: list[dict] = []
        self._last = None
        self._band = np.asarray(self.jacket.set_point_band, dtype=float)   # the jacket's band, once a start
        self._restart()
        self._trace0 = float(np.max(self.estimator.trace))   # trace P(0) = p0 n

    @abstractmethod
    def _restart(self) -> None:
        """The law's estimator and history back to their start."""

    def reset(self, applied: Command) -> None:
        """Bumpless start from the applied setting; the estimator starts again from Theta = 0 and the
        fixed gains commission it."""
        self._start(np.clip(np.asarray(applied.blade_pitch, dtype=float), -self.limit, self.limit))

    def fallback_command(self) -> np.ndarray:
        """What to start from when no applied blade pitch is known: the fixed gains' offset u0 [rad]."""
        return self.fixed.u0.copy()

    def applied(self, t: float, command: Command) -> None:
        """The blade pitch the vehicle held over the interval ending at ``t``: the estimator's input."""
        pitch = np.asarray(command.blade_pitch, dtype=float)
        if pitch.shape == (4,) and np.isfinite(pitch).all():
            self.applied_prev = pitch.copy()

    # -- jacketing ------------------------------------------------------------------------------------
    def _wound_up(self, trace: float) -> str:
        """The trace rule's reason if trace P has grown beyond ``max_trace_growth`` times trace P(0), else ''."""
        limit = self.jacket.max_trace_growth * self._trace0
        return f"trace P {trace:.3g} > {self.jacket.max_trace_growth:g} x its start {self._trace0:.3g}" \
            if trace > limit else ""

    def _freeze(self, error: np.ndarray, moved: float) -> bool:
        """Whether estimation sleeps this sample (at the set point, or the input moved less than the
        excitation threshold [rad]); counted. Returns True to estimate."""
        at_set_point = bool((np.abs(error) < self._band).all())
        self.frozen = "at the set point" if at_set_point else "no excitation" if moved < self.jacket.excitation else ""
        if self.frozen:
            self.counts["frozen_at_set_point" if at_set_point else "frozen_no_excitation"] += 1
            return False
        self.counts["estimated"] += 1
        return True

    def _switch(self, t: float, mode: str, reason: str, rule: str = "") -> None:
        if rule:
            self.counts[rule] += 1
        if mode != self.mode or rule != self._rule:
            self._rule = rule
            if mode == "fallback":
                self.counts["engagements"] += 1
            self.events.append({"t": float(t), "mode": mode, "reason": reason})
            del self.events[:-100]
            (_log.warning if mode == "fallback" else _log.info)("%s at t=%.2f s: %s (%s)", self.kind, t, mode, reason)
        self.mode, self.reason = mode, reason

    # -- one sample ----------------------------------------------------------------------------------
    @abstractmethod
    def _law(self, t: float, y: np.ndarray, r: np.ndarray, error: np.ndarray, u_held: np.ndarray):
        """Estimate and return the adaptive command [rad], or None with the mode already switched to
        commissioning or fallback (then the fixed gains fly)."""

    def update(self, t: float, measurement: Measurement, reference: Reference) -> Command:
        """One sample: the law's estimate and command, or the fixed gains (commissioning, fallback).

        Raises
        ------
        ContractError
            If the measurement has no valid velocity/rate reading or the reference is not a
            :class:`Reference` (nothing changes).
        """
        y = measurement.body_velocity()  # raises ContractError when invalid
        if not isinstance(reference, Reference):
            raise ContractError(f"reference must be a Reference, got {type(reference).__name__}")
        r = reference.velocity
        error = r - y
        # the input held over the last interval: what the vehicle reports, else what this law sent
        u_held = self.applied_prev if self.applied_prev is not None else self.u_prev
        raw = self._law(t, y, r, error, u_held)
        if raw is None:
            g = self.fixed
            raw = u_held + g.K_int @ self.e_prev + g.K_err @ (error - self.e_prev)
        self.counts[self.mode] += 1
        command = np.clip(raw, -self.limit, self.limit)
        self.u_prev, self.e_prev = command, error
        self.applied_prev = None
        self.samples += 1
        self.counts["samples"] += 1
        self._last = (t, error, raw)   # the last sample, as diagnostics() words it (made only when asked)
        return Command(command, stamp=t)

    def named_estimate(self) -> dict:
        """The estimate's named traces for a run's ``series.estimate``: :meth:`estimate_names` with
        :meth:`estimate_values`."""
        return dict(zip(self.estimate_names(), self.estimate_values()))

    @abstractmethod
    def estimate_names(self) -> tuple:
        """The names of the estimate's traces, in :meth:`estimate_values`'s order (the same every sample)."""

    @abstractmethod
    def estimate_values(self) -> list:
        """The estimate's traces now, as floats in :meth:`estimate_names`'s order: what a batch of runs stores
        every sample without making the dict."""

    def estimate_matrix(self) -> np.ndarray:
        """The estimator's whole parameter matrix Theta (regressors x outputs, a copy): what a node
        publishes beside the named traces (``seapup_msgs/ControllerEstimate``)."""
        return np.array(self.estimator.theta, dtype=float)

    def _diagnostics(self) -> dict:
        """The law's own entries of :meth:`diagnostics`."""
        return {}

    def diagnostics(self) -> dict:
        """Mode and reason, whether and why estimation is frozen, the jacket counts and last events, the
        named estimate and the last sample's error and command (empty before the first sample)."""
        if self._last is None:
            return {}
        return {"mode": self.mode, "reason": self.reason, "frozen": self.frozen, "counts": dict(self.counts),
                "events": list(self.events[-10:]), "estimate": self.named_estimate(), **self._diagnostics(),
                **self.last}

    @property
    def last(self) -> dict:
        """The last sample's time, error, command before saturation and which inputs saturated (empty before the
        first sample)."""
        if self._last is None:
            return {}
        t, error, raw = self._last
        return {"t": float(t), "error": error.tolist(), "command_unsaturated": np.asarray(raw).tolist(),
                "saturated": [bool(s) for s in np.abs(raw) > self.limit]}
