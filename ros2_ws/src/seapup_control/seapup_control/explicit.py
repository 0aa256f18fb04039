"""The explicit self-tuning autopilot of thesis sec. 7.3-7.4: recursive least squares on a first-order
model of (u, v, w, r), and each sample Owens and Chotai's two-term law redesigned from the estimate.

**Estimator** (sec. 7.3, eq. 6.12, 6.17, 6.27). Multivariable recursive least squares
(:class:`seapup_ident.recursive.RecursiveArmax`, method ``ls``: Peterka's square-root / UD update of P,
eq. 6.17) on

    y(t) + A_1 y(t-1) = B_1 u(t-1) + d            (na = nb = 1, the thesis's 32 parameters of A_1, B_1)

with the outputs y = (u, v, w, r) [m/s, rad/s] and the inputs the four blade pitches [rad], forgetting
factor lambda (0.999 by default, sec. 7.4.2 also flies 0.95) and Theta(0) = 0. The thesis does not say how
the hover setting is handled; here the offset d of eq. 6.27 is estimated beside A_1 and B_1 (36
parameters): the blade pitches that hold the vehicle at rest are far from zero (buoyancy and the
umbilical), and without d their mean would be read as a gain. The input is the blade pitch the vehicle
reports applied over each interval (:meth:`ExplicitSelfTuner.applied`; clipped, held, or another
controller's before a switch), else the command this law sent, clipped.

**Design** (eq. 4.9-4.11, 4.18-4.19). The estimate is a discrete MFOL with Phi = -A_1, Gamma = B_1:
B_0^-1 = Gamma (the response one sample after a unit step) and B_1^-1 = (I - Phi)^-1 Gamma (its steady
state), :meth:`seapup_control.mfol.MFOLModel.from_state_space`; :func:`seapup_control.mfol.design` gives
K_int and K_err for the loop poles of sec. 5.2 (those of the self-test's controller file). On a plant
that is exactly first order the closed-loop poles are then exactly k_j and c_j.

**Law**. Eq. 4.11's two-term law in its incremental (velocity) form,

    u(t) = u_applied(t-1) + K_int e(t-1) + K_err [e(t) - e(t-1)],

which is eq. 4.11 for fixed gains and stays continuous when the gains change every sample, start from the
applied setting (bumpless, as :class:`~seapup_control.mfol_controller.MFOLController` starts) and cannot
wind up (it continues from what the thrusters hold). The hover offset u0 of eq. 5.6 is in u_applied.

**Commissioning** (sec. 7.4.1): for the first ``commissioning_samples`` samples the self-tested fixed gains
(the controller file's zero-speed point) fly the vehicle while the estimator watches.

**Jacketing** (sec. 7.3 and 8.3 recommend it; the thesis's runs had none):

- estimation is frozen (no update, no forgetting) while every output is within ``set_point_band`` of its
  reference, or while the input does not excite (every blade pitch moved less than ``excitation`` since
  the last sample) -- sec. 7.3's "estimator going to sleep" and bursting (eq. 6.12);
- the design falls back to the fixed gains while trace P exceeds ``max_trace`` (the estimate still
  updates, as sec. 7.3 says), while the estimated B_0^-1 is not safely invertible (reciprocal condition
  below ``min_rcond``), or while the estimate is not sane (non-finite, or an open-loop pole of Phi outside
  ``max_pole``: the Seapup's velocity dynamics are stable);
- every change of state is logged with its reason and counted (:meth:`ExplicitSelfTuner.diagnostics`);
  the return from the fallback is bumpless, since the law continues from the applied setting.

Bad measurements and references never reach the state: :meth:`update` raises
:class:`~seapup_common.contract.ContractError` and changes nothing.
"""
from __future__ import annotations

import logging
import math
import types
from dataclasses import dataclass

import numpy as np

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_common.contract import Command, ContractError, Measurement, Reference
from seapup_common.controllers import ControllerType
from seapup_control.mfol import DesignError, LoopPoles, MFOLModel, TwoTermGains, design
from seapup_control.mfol_controller import GainSchedule
from seapup_ident.armax import ArmaxOrders
from seapup_ident.recursive import Forgetting, RecursiveArmax

__all__ = ["ExplicitJacket", "ExplicitSelfTuner", "EXPLICIT_TYPE", "create_explicit", "MODES", "OUTPUTS"]

_log = logging.getLogger(__name__)

OUTPUTS = ("u", "v", "w", "r")
#: What the law is doing: flying the fixed gains while the estimator watches, flying the estimate's design,
#: or flying the fixed gains because a jacket rule refused the estimate.
MODES = ("commissioning", "adaptive", "fallback")


@dataclass(frozen=True)
class ExplicitJacket:
    """The safeguards of sec. 7.3 (see the module docstring); SI units and radians."""

    set_point_band: tuple = (0.005, 0.005, 0.005, 0.005)   # |e| [m/s, m/s, m/s, rad/s] counted "at the set point"
    excitation: float = math.radians(0.05)                  # a blade pitch moving less than this does not excite
    max_trace: float = 1e5                                  # trace P above it: fall back (estimate still updates)
    min_rcond: float = 1e-4                                 # B_0^-1's reciprocal condition below it: fall back
    max_pole: float = 1.0                                   # an estimated open-loop pole |z| at or beyond: fall back

    def __post_init__(self):
        band = np.asarray(self.set_point_band, dtype=float)
        if band.shape != (4,) or not np.all(np.isfinite(band)) or np.any(band < 0):
            raise DesignError(f"set_point_band needs four finite values >= 0, got {self.set_point_band!r}")
        for name in ("excitation", "max_trace", "min_rcond", "max_pole"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise DesignError(f"jacket {name} must be a finite number >= 0, got {value!r}")


class ExplicitSelfTuner:
    """Sec. 7.3's explicit adaptive autopilot (see the module docstring).

    Parameters
    ----------
    fixed : TwoTermGains
        The self-tested fixed gains: flown while commissioning and as the fallback.
    poles : LoopPoles
        The loop poles each redesign places (sec. 5.2), at the gains' sample period.
    forgetting : float
        lambda of eq. 6.13, in (0, 1].
    p0 : float
        P(0) = p0 I (eq. 6.16). Sec. 6.3 suggests p = 100 / E{y^2}: 1e4 for velocities of about 0.1 m/s.
    commissioning_samples : int
        Samples flown on the fixed gains before the first redesign (sec. 7.4.1: five).
    jacket : ExplicitJacket
    limit : float
        Blade-pitch limit [rad].

    Examples
    --------
    >>> from seapup_control.mfol import THESIS_POLES_5HZ
    >>> plant = MFOLModel(np.eye(4) * 0.02, np.eye(4) * 0.1, 0.2)
    >>> tuner = ExplicitSelfTuner(design(plant, THESIS_POLES_5HZ), THESIS_POLES_5HZ)
    >>> tuner.reset(Command(np.zeros(4)))
    >>> at_rest = Measurement.build(0.0, velocity=(0.0, 0.0, 0.0), rates=(0.0, 0.0, 0.0))
    >>> tuner.update(0.0, at_rest, Reference([0.0, 0.0, 0.0, 0.0])).blade_pitch
    array([0., 0., 0., 0.])
    >>> tuner.diagnostics()["mode"]
    'commissioning'
    """

    def __init__(self, fixed: TwoTermGains, poles: LoopPoles, forgetting: float = 0.999, p0: float = 1e4,
                 commissioning_samples: int = 5, jacket: ExplicitJacket | None = None,
                 limit: float = BLADE_PITCH_LIMIT):
        if fixed.K_int.shape != (4, 4):
            raise DesignError(f"the fixed gains must be 4 x 4, got {fixed.K_int.shape}")
        if poles.k.size != 4 or not math.isclose(poles.sample_period, fixed.sample_period, rel_tol=1e-9):
            raise DesignError("the loop poles must be four, at the fixed gains' sample period")
        if not (math.isfinite(forgetting) and 0.0 < forgetting <= 1.0):
            raise DesignError(f"forgetting must be in (0, 1], got {forgetting!r}")
        if not (math.isfinite(p0) and p0 > 0):
            raise DesignError(f"p0 must be > 0, got {p0!r}")
        if int(commissioning_samples) != commissioning_samples or commissioning_samples < 1:
            raise DesignError(f"commissioning_samples must be a whole number >= 1, got {commissioning_samples!r}")
        if not (math.isfinite(limit) and limit > 0):
            raise DesignError(f"limit must be > 0 rad, got {limit!r}")
        self.fixed, self.poles = fixed, poles
        self.sample_period = fixed.sample_period
        self.forgetting, self.p0 = float(forgetting), float(p0)
        self.commissioning_samples = int(commissioning_samples)
        self.jacket = jacket or ExplicitJacket()
        self.limit = float(limit)
        self.estimator = RecursiveArmax(ArmaxOrders(ny=4, nu=4, na=1, nb=1, nc=0, offset=True), "ls",
                                        forgetting=Forgetting(self.forgetting), p0=self.p0)
        self._start(np.zeros(4))

    # -- state ---------------------------------------------------------------------------------------
    def _start(self, pitch: np.ndarray) -> None:
        self.estimator.reset()
        self.samples = 0
        self.u_prev = pitch.copy()          # the setting held now (the law continues from it)
        self.e_prev = np.zeros(4)
        self.applied_prev: np.ndarray | None = None
        self.gains = self.fixed
        self.mode, self.reason = "", ""     # set at the first sample (commissioning)
        self.frozen = ""
        self.counts = {"samples": 0, "estimated": 0, "frozen_at_set_point": 0, "frozen_no_excitation": 0,
                       "fallback_trace": 0, "fallback_singular_b0": 0, "fallback_insane": 0,
                       "commissioning": 0, "adaptive": 0, "fallback": 0, "engagements": 0}
        self.events: list[dict] = []
        self.last: dict = {}
        self._u_before: np.ndarray | None = None   # the input held over the interval before the last
        self._rule = ""                             # the jacket rule behind the present fallback

    def reset(self, applied: Command) -> None:
        """Bumpless start from the applied setting; the estimator starts again from Theta(0) = 0 and the
        fixed gains commission it."""
        self._start(np.clip(np.asarray(applied.blade_pitch, dtype=float), -self.limit, self.limit))

    def fallback_command(self) -> np.ndarray:
        """What to start from when no applied blade pitch is known: the fixed gains' offset u0 [rad]."""
        return self.fixed.u0.copy()

    def applied(self, t: float, command: Command) -> None:
        """The blade pitch the vehicle held over the interval ending at ``t``: the estimator's input."""
        pitch = np.asarray(command.blade_pitch, dtype=float)
        if pitch.shape == (4,) and np.all(np.isfinite(pitch)):
            self.applied_prev = pitch.copy()

    # -- the estimate as the thesis's matrices -----------------------------------------------------------
    def estimate(self) -> dict:
        """The present estimate: Phi = -A_1, Gamma = B_1 and the offset d (SI units, radians)."""
        model = self.estimator.model
        return {"Phi": -model.A[0], "Gamma": model.B[0], "d": np.asarray(model.d, dtype=float).reshape(-1)}

    def named_estimate(self) -> dict:
        """The estimate's named traces for a run's ``series.estimate``: the diagonal of A_1 and the
        main-port thruster's column of B_1 (per output), and trace P."""
        est = self.estimate()
        out = {f"a_{name}": float(-est["Phi"][j, j]) for j, name in enumerate(OUTPUTS)}
        out.update({f"b_{name}_main_port": float(est["Gamma"][j, 0]) for j, name in enumerate(OUTPUTS)})
        out["trace_P"] = float(self.estimator.trace[0])
        return out

    def _designed(self) -> tuple[TwoTermGains | None, str, str]:
        """The estimate's design, or None with the counter and reason of the jacket rule that refused it."""
        trace = float(self.estimator.trace[0])
        if trace > self.jacket.max_trace:
            return None, "fallback_trace", f"trace P {trace:.3g} > {self.jacket.max_trace:g}"
        est = self.estimate()
        phi, gamma = est["Phi"], est["Gamma"]
        if not (np.all(np.isfinite(phi)) and np.all(np.isfinite(gamma))):
            return None, "fallback_insane", "non-finite estimate"
        radius = float(np.max(np.abs(np.linalg.eigvals(phi))))
        if radius >= self.jacket.max_pole:
            return None, "fallback_insane", f"estimated open-loop pole |z| = {radius:.3f} >= {self.jacket.max_pole:g}"
        scale = np.maximum(np.abs(gamma).max(axis=1, keepdims=True), 1e-300)  # equilibrate the rows (units)
        rcond = 1.0 / np.linalg.cond(gamma / scale)
        if not rcond >= self.jacket.min_rcond:
            return None, "fallback_singular_b0", f"estimated B0^-1 nearly singular (rcond {rcond:.2g})"
        try:
            model = MFOLModel.from_state_space(phi, gamma, np.eye(4), self.sample_period)
            gains = design(model, self.poles)
        except DesignError as exc:
            return None, "fallback_singular_b0", f"no design from the estimate: {exc}"
        if not (np.all(np.isfinite(gains.K_int)) and np.all(np.isfinite(gains.K_err))):
            return None, "fallback_insane", "non-finite gains from the estimate"
        return gains, "", ""

    def _switch(self, t: float, mode: str, reason: str, rule: str = "") -> None:
        if mode != self.mode or rule != self._rule:
            self._rule = rule
            if mode == "fallback":
                self.counts["engagements"] += 1
            self.events.append({"t": float(t), "mode": mode, "reason": reason})
            del self.events[:-100]
            log = _log.warning if mode == "fallback" else _log.info
            log("explicit self-tuner at t=%.2f s: %s (%s)", t, mode, reason)
        self.mode, self.reason = mode, reason

    # -- one sample ----------------------------------------------------------------------------------
    def update(self, t: float, measurement: Measurement, reference: Reference) -> Command:
        """Estimate with y(t), redesign, and one sample of the incremental two-term law.

        Raises
        ------
        ContractError
            If the measurement has no valid velocity/rate reading or the reference is not a
            :class:`Reference` (nothing changes).
        """
        y = measurement.body_velocity()  # raises ContractError when invalid
        if not isinstance(reference, Reference):
            raise ContractError(f"reference must be a Reference, got {type(reference).__name__}")
        error = reference.velocity - y
        # the input held over the last interval: what the vehicle reports, else what this law sent
        u_held = self.applied_prev if self.applied_prev is not None else self.u_prev
        if self.samples == 0:
            self.estimator.restart()
            self.estimator.observe(y, update=False)
            self.frozen = "first sample"
        else:
            self.estimator.input(u_held)
            at_set_point = bool(np.all(np.abs(error) < np.asarray(self.jacket.set_point_band)))
            moved = float(np.max(np.abs(u_held - self._u_before))) if self._u_before is not None else math.inf
            self.frozen = ("at the set point" if at_set_point else
                           "no excitation" if moved < self.jacket.excitation else "")
            self.estimator.observe(y, update=not self.frozen)
            if self.frozen:
                self.counts["frozen_at_set_point" if at_set_point else "frozen_no_excitation"] += 1
            else:
                self.counts["estimated"] += 1
        self._u_before = u_held.copy()
        if self.samples < self.commissioning_samples:
            self.gains = self.fixed
            self._switch(t, "commissioning", "commissioning: the fixed gains fly while the estimator watches")
        else:
            gains, counter, reason = self._designed()
            if gains is None:
                self.counts[counter] += 1
                self.gains = self.fixed
                self._switch(t, "fallback", reason, counter)
            else:
                self.gains = gains
                self._switch(t, "adaptive", "the estimate's design")
        self.counts[self.mode] += 1
        g = self.gains
        raw = u_held + g.K_int @ self.e_prev + g.K_err @ (error - self.e_prev)
        command = np.clip(raw, -self.limit, self.limit)
        self.u_prev, self.e_prev = command, error
        self.applied_prev = None
        self.samples += 1
        self.counts["samples"] += 1
        self.last = {"t": float(t), "error": error.tolist(), "command_unsaturated": raw.tolist(),
                     "saturated": [bool(s) for s in np.abs(raw) > self.limit]}
        return Command(command, stamp=t)

    def diagnostics(self) -> dict:
        """Mode and reason, whether and why estimation is frozen, the jacket counts and last events, the
        named estimate and the last sample's error and command (empty before the first sample)."""
        if not self.last:
            return {}
        return {"mode": self.mode, "reason": self.reason, "frozen": self.frozen, "counts": dict(self.counts),
                "events": list(self.events[-10:]), "estimate": self.named_estimate(),
                "K_int": self.gains.K_int.tolist(), "K_err": self.gains.K_err.tolist(), **self.last}


def create_explicit(parameters: dict, document, sample_period: float | None) -> ExplicitSelfTuner:
    """The ``explicit`` controller type's factory: the fixed gains and loop poles of a self-test's
    controller file (its zero-speed point), the estimator's and the jacket's settings from ``parameters``.

    Raises
    ------
    DesignError
        On a malformed document, a sample period other than the file's, or a bad setting.
    """
    schedule = GainSchedule.from_document(document)
    fixed = schedule.gains[0]
    if sample_period is not None and abs(fixed.sample_period - sample_period) > 1e-9:
        raise DesignError(f"the controller file's gains are for T = {fixed.sample_period:g} s, not {sample_period:g} s")
    try:
        poles = LoopPoles(document["poles"]["k"], document["poles"]["c"], fixed.sample_period)
    except (KeyError, TypeError) as exc:
        raise DesignError(f"the controller file has no loop poles: {exc}") from None
    p = parameters
    jacket = ExplicitJacket(tuple(p["set_point_band"]), math.radians(p["excitation_deg"]), p["max_trace"],
                            p["min_rcond"], p["max_pole"])
    return ExplicitSelfTuner(fixed, poles, forgetting=p["forgetting"], p0=p["p0"],
                             commissioning_samples=p["commissioning_samples"], jacket=jacket,
                             limit=p["blade_pitch_limit"])


#: The explicit self-tuner (registered as ``explicit``).
EXPLICIT_TYPE = ControllerType(
    "explicit", create_explicit,
    types.MappingProxyType({"forgetting": 0.999, "p0": 1e4, "commissioning_samples": 5,
                            "set_point_band": [0.005, 0.005, 0.005, 0.005], "excitation_deg": 0.05,
                            "max_trace": 1e5, "min_rcond": 1e-4, "max_pole": 1.0,
                            "blade_pitch_limit": BLADE_PITCH_LIMIT}),
    "explicit self-tuner (sec. 7.3): square-root RLS on a first-order model of u, v, w, r, the two-term law "
    "redesigned each sample; commissioned by and falling back to a self-test's fixed gains",
    needs_document=True, needs_applied=True)
