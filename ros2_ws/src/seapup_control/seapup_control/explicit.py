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

**Commissioning and jacketing** (:mod:`seapup_control.self_tuning`): five samples on the self-tested gains
first; estimation frozen at the set point or without excitation; the fixed gains fly while trace P is above its
limit, while the estimated B_0^-1 is not safely invertible (reciprocal condition of its equilibrated rows below
``min_rcond``: ``fallback_singular_b0``) or while the estimate is not sane (non-finite, or an open-loop pole of
Phi at or beyond ``max_pole``, 1.3: the Seapup's velocity modes are stable, an estimate a little beyond 1 --
a slow surge mode near z = 0.98 seen through noise, or the yaw mode of a sway square wave, barely excited in
closed loop, at |z| 1.10-1.12 -- still designs a loop that places the poles, while |z| = 1.3, a mode doubling
in 0.5 s at 5 Hz, is no damped vehicle's; a limit of 1.1 held the sway case on its fixed gains for 269 of its
295 samples);
the return is bumpless, since this law too continues from the applied setting.

Bad measurements and references never reach the state: :meth:`update` raises
:class:`~seapup_common.contract.ContractError` and changes nothing.
"""
from __future__ import annotations

import math
import types

import numpy as np

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_common.controllers import ControllerType, Ranged
from seapup_common.kernels import compiled_by_default
from seapup_control.mfol import DesignError, LoopPoles, MFOLModel, TwoTermGains, design
from seapup_control.mfol_controller import GainSchedule
from seapup_control.self_tuning import OUTPUTS, TUNER_PARAMETERS, SelfTuner, TunerJacket, jacket_from
from seapup_ident.armax import ArmaxOrders
from seapup_ident.recursive import Forgetting, RecursiveArmax

__all__ = ["ExplicitSelfTuner", "EXPLICIT_TYPE", "create_explicit"]


class ExplicitSelfTuner(SelfTuner):
    """Sec. 7.3's explicit adaptive autopilot (see the module docstring).

    Parameters
    ----------
    fixed : TwoTermGains
        The self-tested fixed gains: flown while commissioning and as the fallback.
    poles : LoopPoles
        The loop poles each redesign places (sec. 5.2), at the gains' sample period.
    forgetting, p0, commissioning_samples, jacket, limit
        As :class:`~seapup_control.self_tuning.SelfTuner`.
    compiled : bool, optional
        The redesign (:func:`seapup_control.compiled.explicit_design`) and the estimator's square-root update
        compiled, or both in NumPy (False); default :func:`seapup_common.kernels.compiled_by_default`. The
        same numbers (tested).

    Examples
    --------
    >>> from seapup_common.contract import Command, Measurement, Reference
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

    kind = "explicit self-tuner"
    RULES = ("fallback_trace", "fallback_singular_b0", "fallback_insane")

    def __init__(self, fixed: TwoTermGains, poles: LoopPoles, forgetting: float = 0.999, p0: float = 1e4,
                 commissioning_samples: int = 5, jacket: TunerJacket | None = None,
                 limit: float = BLADE_PITCH_LIMIT, compiled: bool | None = None):
        super().__init__(fixed, forgetting, p0, commissioning_samples, jacket, limit)
        if poles.k.size != 4 or not math.isclose(poles.sample_period, fixed.sample_period, rel_tol=1e-9):
            raise DesignError("the loop poles must be four, at the fixed gains' sample period")
        self.poles = poles
        self.estimator = RecursiveArmax(ArmaxOrders(ny=4, nu=4, na=1, nb=1, nc=0, offset=True), "ls",
                                        forgetting=Forgetting(self.forgetting), p0=self.p0, compiled=compiled)
        self.kernel = None   # seapup_control.compiled.explicit_design, or None: the reference (_design_numpy)
        if compiled_by_default() if compiled is None else compiled:
            from seapup_control.compiled import explicit_design
            self.kernel = explicit_design
            self._poles = (np.array(poles.k, dtype=float), np.array(poles.c, dtype=float))
        self._start(np.zeros(4))

    def _restart(self) -> None:
        self.estimator.reset()
        self.gains = self.fixed
        self._u_before: np.ndarray | None = None   # the input held over the interval before the last

    # -- the estimate as the thesis's matrices -----------------------------------------------------------
    def estimate(self) -> dict:
        """The present estimate: Phi = -A_1, Gamma = B_1 and the offset d (SI units, radians)."""
        phi, gamma = self._blocks()
        return {"Phi": phi, "Gamma": gamma.copy(), "d": self.estimator.theta[8].copy()}   # d: Theta's last row

    def _blocks(self) -> tuple[np.ndarray, np.ndarray]:
        """(Phi, Gamma) = (-A_1, B_1) read straight from Theta, as :meth:`estimate` has them through
        :meth:`seapup_ident.armax.ArmaxModel.from_theta` (Theta's rows 0-3 are A_1 transposed, 4-7 B_1 transposed):
        the same numbers, made without the model (a self-tuner reads them every sample)."""
        theta = self.estimator.theta
        return -theta[:4].T, theta[4:8].T

    #: the named traces (:meth:`estimate_names`): the diagonal of A_1, the main-port thruster's column of B_1 (per
    #: output), and trace P
    ESTIMATE_NAMES = (*(f"a_{name}" for name in OUTPUTS), *(f"b_{name}_main_port" for name in OUTPUTS), "trace_P")

    def estimate_names(self) -> tuple:
        return self.ESTIMATE_NAMES

    def estimate_values(self) -> list:
        """The diagonal of A_1, the main-port column of B_1 and trace P (:data:`ESTIMATE_NAMES`), read from Theta:
        A_1[j, j] = Theta[j, j], B_1[j, 0] = Theta[4, j] (:meth:`_blocks`)."""
        theta = self.estimator.theta
        return theta[(0, 1, 2, 3), (0, 1, 2, 3)].tolist() + theta[4, :4].tolist() + [self.estimator.shared_trace]

    def _designed(self) -> tuple[TwoTermGains | None, str, str]:
        """The estimate's design, or None with the jacket rule that refused it and why."""
        wound_up = self._wound_up(self.estimator.shared_trace)
        if wound_up:
            return None, "fallback_trace", wound_up
        if not np.isfinite(self.estimator.theta[:8]).all():   # A_1 and B_1
            return None, "fallback_insane", "non-finite estimate"
        phi, gamma = self._blocks()
        radius = float(np.max(np.abs(np.linalg.eigvals(phi))))
        if radius >= self.jacket.max_pole:
            return None, "fallback_insane", f"estimated open-loop pole |z| = {radius:.3f} >= {self.jacket.max_pole:g}"
        if self.kernel is not None:   # the same design compiled; what it cannot make, the reference explains
            k_int, k_err = np.empty((4, 4)), np.empty((4, 4))
            try:
                code, rcond = self.kernel(np.ascontiguousarray(phi), np.ascontiguousarray(gamma), *self._poles,
                                          float(self.jacket.min_rcond), k_int, k_err)
            except np.linalg.LinAlgError:   # I - Phi exactly singular
                code, rcond = 2, math.nan
            if code == 0:
                return TwoTermGains(k_int, k_err, np.zeros(4), np.zeros(4), self.sample_period), "", ""
            if code == 1:
                return None, "fallback_singular_b0", f"estimated B0^-1 nearly singular (rcond {rcond:.2g})"
        return self._design_numpy(phi, gamma)

    def _design_numpy(self, phi: np.ndarray, gamma: np.ndarray) -> tuple[TwoTermGains | None, str, str]:
        """:meth:`_designed` after its trace and pole rules, in NumPy: the reference the compiled design
        (:func:`seapup_control.compiled.explicit_design`) is tested against, and what says why it failed."""
        scale = np.maximum(np.abs(gamma).max(axis=1, keepdims=True), 1e-300)  # equilibrate the rows (units)
        rcond = 1.0 / np.linalg.cond(gamma / scale)
        if not rcond >= self.jacket.min_rcond:
            return None, "fallback_singular_b0", f"estimated B0^-1 nearly singular (rcond {rcond:.2g})"
        try:
            gains = design(MFOLModel.from_state_space(phi, gamma, np.eye(4), self.sample_period), self.poles)
        except DesignError as exc:
            return None, "fallback_singular_b0", f"no design from the estimate: {exc}"
        if not (np.all(np.isfinite(gains.K_int)) and np.all(np.isfinite(gains.K_err))):
            return None, "fallback_insane", "non-finite gains from the estimate"
        return gains, "", ""

    def _law(self, t, y, r, error, u_held):
        """Estimate with y(t), redesign, and the incremental two-term law on the design."""
        if self.samples == 0:
            self.estimator.restart()
            self.estimator.observe(y, update=False)
            self.frozen = "first sample"
        else:
            self.estimator.input(u_held)
            moved = float(np.max(np.abs(u_held - self._u_before))) if self._u_before is not None else math.inf
            self.estimator.observe(y, update=self._freeze(error, moved))
        self._u_before = u_held.copy()
        if self.samples < self.commissioning_samples:
            self.gains = self.fixed
            self._switch(t, "commissioning", "commissioning: the fixed gains fly while the estimator watches")
            return None
        gains, rule, reason = self._designed()
        if gains is None:
            self.gains = self.fixed
            self._switch(t, "fallback", reason, rule)
            return None
        self.gains = gains
        self._switch(t, "adaptive", "the estimate's design")
        return u_held + gains.K_int @ self.e_prev + gains.K_err @ (error - self.e_prev)

    def _diagnostics(self) -> dict:
        return {"K_int": self.gains.K_int.tolist(), "K_err": self.gains.K_err.tolist()}


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
    return ExplicitSelfTuner(fixed, poles, forgetting=p["forgetting"], p0=p["p0"],
                             commissioning_samples=p["commissioning_samples"], jacket=jacket_from(p),
                             limit=p["blade_pitch_limit"])


#: The explicit self-tuner (registered as ``explicit``).
EXPLICIT_TYPE = ControllerType(
    "explicit", create_explicit, types.MappingProxyType({
        **TUNER_PARAMETERS,
        "max_pole": Ranged(1.3, 1.0, 10.0, "|z| of an estimated open-loop pole (sec. 7.3's sanity rule): the "
                                           "vehicle is open-loop stable, |z| < 1; below 1 a sound estimate is "
                                           "refused, beyond 10 (x10 per sample) none ever is")}),
    "explicit self-tuner (sec. 7.3): square-root RLS on a first-order model of u, v, w, r, the two-term law "
    "redesigned each sample; commissioned by and falling back to a self-test's fixed gains",
    needs_document=True, needs_applied=True)
