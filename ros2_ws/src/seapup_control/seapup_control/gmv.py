"""Koivo's implicit generalised-minimum-variance self-tuner (thesis sec. 7.5-7.6, eq. 7.1-7.5).

**Cost and generalised output.** Eq. 7.1 with P(z^-1) = I, R(z^-1) = I, Q(z^-1) = lambda I and k = 1, in the
integrating form of eq. 7.5,

    phi(t) = y(t) - r(t-1) + lambda [u(t-1) - u(t-2)],

chosen over eq. 7.2 because the blade pitches that hold the Seapup are far from zero (the hover setting): eq.
7.2's lambda u(t-1) would leave a steady error lambda u of its own, eq. 7.5 penalises only the moves, and its
integrator removes steady-state errors (sec. 7.5). The horizon k = 1: a blade pitch set at t acts on the
velocities by t + T (sec. 4.4's first-order lag; no dead time at 5 Hz). P = R = I track each output's own
reference one for one, as the fixed-gain and explicit autopilots do; lambda is the one knob (sec. 7.8).

**Units.** lambda weighs outputs in m/s and deg/s against blade pitch in degrees, the thesis's units (its
eq. 5.3 and 5.7 print B in them), so its 0.001, 0 and 0.1 mean here what they meant there. Topics stay SI:
the conversion is internal.

**Implicit predictor** (eq. 7.3-7.4). With an ARMAX model of order n (C = I) and k = 1,

    phi*(t+1|t) = G0 u(t) + F_0 y(t) + ... + F_{n-1} y(t-n+1) + G_1 u(t-1) + ... + G_n u(t-n) + H r(t) + delta,

with G0 = B_1 + lambda I. The parameters F, G_1.., H and delta are estimated directly (square-root least
squares, :class:`seapup_ident.recursive.RecursiveRegression`, forgetting 0.999, sec. 7.6) from
z(t) = phi(t) - G0 u(t-1) against x(t-1) = (y(t-1) .. y(t-n), u(t-2) .. u(t-n-1), r(t-1), 1). G0 is fixed
"to allow a unique solution" (sec. 7.5: in closed loop G0 u(t) = -Theta^T x(t) holds exactly, so without it
any multiple of the law fits the data); Koivo fixes it to a prior estimate, and the one at hand is the
self-test's: G0 = B0^-1 (the response one sample after a unit step, eq. 4.18, in thesis units) + lambda I.
The control (eq. 7.4) sets the prediction to zero:

    u(t) = -G0^-1 Theta^T x(t),     clipped to the blade-pitch limit.

With lambda = 0 and exact parameters the output error y(t+1) - r(t) is the one-step prediction error:
minimum variance. The closed loop's characteristic polynomial is det(B_1 + lambda (1 - z^-1) A(z^-1)) (Koivo's
design: the roots move from those of B_1 (at the origin for a plant with no zeros) towards A's and the
integrator's as lambda grows), with unit DC gain from reference to output.

**Order.** Second-order models by default (sec. 7.6.1: the closed-loop order tests of Table 6.6 chose two for
yaw); ``order=1`` is the thesis's comparison (sec. 7.6.2: rise times about 10 % longer).

**Commissioning and jacketing** (:mod:`seapup_control.self_tuning`, as the explicit self-tuner): the
self-tested fixed gains fly the first five samples while the estimator watches and are the fallback;
estimation is frozen at the set point or without excitation; a covariance trace above its limit or a
non-finite command falls back; every engagement is logged and counted. G0 is checked once, when the law is
made: a self-test whose B0^-1 + lambda I is singular cannot fix it.
"""
from __future__ import annotations

import math
import types
from collections import deque

import numpy as np

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_common.controllers import ControllerType, Ranged
from seapup_control.mfol import DesignError, TwoTermGains
from seapup_control.mfol_controller import GainSchedule
from seapup_control.self_tuning import OUTPUTS, TUNER_PARAMETERS, SelfTuner, TunerJacket, jacket_from
from seapup_ident.recursive import RecursiveRegression

__all__ = ["GMVSelfTuner", "GMV_TYPE", "create_gmv", "THESIS_SCALE_Y", "THESIS_SCALE_U"]

#: SI (m/s, rad/s) -> the thesis's units (m/s, deg/s) of the outputs; rad -> deg of the blade pitch
THESIS_SCALE_Y = np.array([1.0, 1.0, 1.0, 180.0 / math.pi])
THESIS_SCALE_U = 180.0 / math.pi


#: The highest model order a GMV self-tuner takes: four times the thesis's largest (2, sec. 7.6.1); the
#: estimator's covariance is (8 n + 5)^2 a law, so an order of 10^6 would ask for terabytes.
MAX_ORDER = 8


class GMVSelfTuner(SelfTuner):
    """Koivo's implicit self-tuner (see the module docstring).

    Parameters
    ----------
    fixed : TwoTermGains
        The self-tested fixed gains: flown while commissioning and as the fallback.
    b0inv : array (4, 4)
        The self-test's B0^-1 [SI per rad]: the response one sample after a unit step; fixes G0.
    weighting : float
        lambda of eq. 7.1/7.5 (thesis units), >= 0.
    order : int
        n, the order of the implicit model (1 or more).
    forgetting, p0, commissioning_samples, jacket, limit
        As :class:`~seapup_control.self_tuning.SelfTuner`.
    compiled : bool, optional
        The estimator's square-root update compiled (:func:`seapup_ident.compiled.ud_update`, the same bits) or
        in NumPy (False); default :func:`seapup_common.kernels.compiled_by_default`.
    """

    kind = "gmv self-tuner"

    def __init__(self, fixed: TwoTermGains, b0inv, weighting: float = 0.001, order: int = 2,
                 forgetting: float = 0.999, p0: float = 1e4, commissioning_samples: int = 5,
                 jacket: TunerJacket | None = None, limit: float = BLADE_PITCH_LIMIT, compiled: bool | None = None):
        super().__init__(fixed, forgetting, p0, commissioning_samples, jacket, limit)
        b0inv = np.asarray(b0inv, dtype=float)
        if b0inv.shape != (4, 4) or not np.all(np.isfinite(b0inv)):
            raise DesignError("B0^-1 must be a finite 4 x 4 matrix")
        if not (math.isfinite(weighting) and weighting >= 0):
            raise DesignError(f"lambda must be a finite number >= 0, got {weighting!r}")
        if int(order) != order or not 1 <= order <= MAX_ORDER:
            raise DesignError(f"order must be a whole number in [1, {MAX_ORDER}], got {order!r}")
        self.weighting, self.order = float(weighting), int(order)
        # G0 = B_1 + lambda I in thesis units (outputs m/s, deg/s; inputs deg)
        self.G0 = THESIS_SCALE_Y[:, None] * b0inv / THESIS_SCALE_U + self.weighting * np.eye(4)
        rows = np.abs(self.G0).max(axis=1, keepdims=True)
        if not np.all(rows > 0) or 1.0 / np.linalg.cond(self.G0 / rows) < self.jacket.min_rcond:
            raise DesignError("G0 = B0^-1 + lambda I is singular: the self-test's B0^-1 cannot fix the law")
        self.G0_inv = np.linalg.inv(self.G0)
        self.n_params = 8 * self.order + 5
        self.estimator = RecursiveRegression(self.n_params, 4, self.forgetting, self.p0, compiled=compiled)
        self._start(np.zeros(4))

    def _restart(self) -> None:
        self.estimator.reset()
        self._y = deque(maxlen=self.order)         # y(t-1) .. y(t-n), thesis units, newest first
        self._u = deque(maxlen=self.order + 2)     # u(t-1) .. applied, degrees, newest first
        self._x_prev: np.ndarray | None = None     # x(t-1)
        self._r_prev: np.ndarray | None = None

    def _regressor(self, y: np.ndarray, r: np.ndarray) -> np.ndarray | None:
        """x(t) = (y(t) .. y(t-n+1), u(t-1) .. u(t-n), r(t), 1) in thesis units, once the history is full."""
        ys = [y] + list(self._y)[: self.order - 1]
        us = list(self._u)[: self.order]
        if len(ys) < self.order or len(us) < self.order:
            return None
        return np.concatenate([*ys, *us, r, [1.0]])

    #: the named traces (:meth:`estimate_names`): per output its own F_0 coefficient (the estimate's measure of
    #: y(t)'s weight), the main-port row of G_1 (u(t-1)'s coefficients), and trace P
    ESTIMATE_NAMES = (*(f"f0_{name}" for name in OUTPUTS), *(f"g1_{name}_main_port" for name in OUTPUTS), "trace_P")

    def estimate_names(self) -> tuple:
        return self.ESTIMATE_NAMES

    def estimate_values(self) -> list:
        """F_0's diagonal, G_1's main-port row (Theta's row 4 n: u(t-1)'s first) and trace P (:data:`ESTIMATE_NAMES`)."""
        theta = self.estimator.theta
        return (theta[(0, 1, 2, 3), (0, 1, 2, 3)].tolist() + theta[4 * self.order, :4].tolist()
                + [self.estimator.trace])

    def _law(self, t, y_si, r_si, error, u_held):
        """Estimate with phi(t), then eq. 7.4 (thesis units inside)."""
        y, r = y_si * THESIS_SCALE_Y, r_si * THESIS_SCALE_Y
        if self.samples:
            self._u.appendleft(u_held * THESIS_SCALE_U)   # u(t-1)
        self.frozen = "history"
        if self._x_prev is not None:   # z(t) = phi(t) - G0 u(t-1) against x(t-1)
            moved = float(np.abs(self._u[0] - self._u[1]).max()) / THESIS_SCALE_U if len(self._u) > 1 else math.inf
            if self._freeze(error, moved):
                phi = y - self._r_prev + self.weighting * (self._u[0] - self._u[1])
                self.estimator.update(self._x_prev, phi - self.G0 @ self._u[0])
        x = self._regressor(y, r)
        self._y.appendleft(y)
        self._x_prev, self._r_prev = x, r
        if self.samples < self.commissioning_samples or x is None:
            self._switch(t, "commissioning", "commissioning: the fixed gains fly while the estimator watches")
            return None
        wound_up = self._wound_up(self.estimator.trace)
        if wound_up:
            self._switch(t, "fallback", wound_up, "fallback_trace")
            return None
        command = -self.G0_inv @ (self.estimator.theta.T @ x) / THESIS_SCALE_U
        if not np.isfinite(command).all():
            self._switch(t, "fallback", "non-finite command from the estimate", "fallback_insane")
            return None
        self._switch(t, "adaptive", "eq. 7.4 on the estimate")
        return command

    def _diagnostics(self) -> dict:
        return {"lambda": self.weighting, "order": self.order}


def create_gmv(parameters: dict, document, sample_period: float | None) -> GMVSelfTuner:
    """The ``gmv`` controller type's factory: the fixed gains and B0^-1 of a self-test's controller file (its
    zero-speed point); lambda, the order and the estimator's and jacket's settings from ``parameters``."""
    schedule = GainSchedule.from_document(document)
    fixed = schedule.gains[0]
    if sample_period is not None and abs(fixed.sample_period - sample_period) > 1e-9:
        raise DesignError(f"the controller file's gains are for T = {fixed.sample_period:g} s, not {sample_period:g} s")
    try:
        b0inv = np.array(document["operating_points"][0]["B0inv"], dtype=float)
    except (KeyError, IndexError, TypeError, ValueError) as exc:
        raise DesignError(f"the controller file has no B0inv at its first operating point: {exc}") from None
    p = parameters
    return GMVSelfTuner(fixed, b0inv, weighting=p["lambda"], order=p["order"], forgetting=p["forgetting"],
                        p0=p["p0"], commissioning_samples=p["commissioning_samples"], jacket=jacket_from(p),
                        limit=p["blade_pitch_limit"])


#: Koivo's implicit GMV self-tuner (registered as ``gmv``).
GMV_TYPE = ControllerType(
    "gmv", create_gmv, types.MappingProxyType({
        "lambda": Ranged(0.001, 0.0, 10.0, "eq. 7.5's weighting of du: >= 0; the thesis flies 0 to 0.1 "
                                           "(sec. 7.6), 100 x that is the bound"),
        "order": Ranged(2, 1, MAX_ORDER, "the predictor's order: sec. 7.6.2 flies 1 and 2; each adds 4 x 4 "
                                         "parameters per output to estimate (MAX_ORDER)"),
        **TUNER_PARAMETERS}),
    "Koivo's implicit GMV self-tuner (sec. 7.5, eq. 7.5): the predictor of y(t+1) - r(t) + lambda du(t) estimated "
    "by square-root RLS and set to zero; lambda the one knob; commissioned by a self-test's fixed gains",
    needs_document=True, needs_applied=True)
