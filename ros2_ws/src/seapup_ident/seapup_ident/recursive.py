"""Recursive identification of the multivariable ARMAX model: LS, ELS and RPEM in one framework (thesis sec. 6.3).

Every method is the update of eq. 6.12,

    Theta(t) = Theta(t-1) + P(t) eta(t) [y(t) - y_hat(t)]^T / (lambda(t) + eta^T P(t-1) eta)

with the forgetting factor lambda(t) (fixed, or eq. 6.15: lambda(t) = alpha lambda(t-1) + 1 - alpha,
lambda(0) = 0.6-0.7) and P(0) = p I (eq. 6.16). The methods differ in the regressor and the
search direction eta (Ljung and Soderstrom 1983, the thesis's ref. [55]):

- ``ls``: phi without noise terms (C = I), eta = phi. P in UD form (eq. 6.17) updated with
  Bierman's / Peterka's square-root algorithm, so it stays positive definite;
- ``els``: pseudo-linear regression -- the a posteriori residuals stand in for e(t-k) in phi
  (the noise model C is estimated), eta = phi, P in UD form;
- ``rpem``: the Gauss-Newton direction eta = psi, the gradient of the prediction: phi filtered by
  1 / C_ii(z^-1) for output i (the diagonal of C: each output a SISO model, sec. 6.3.1), P per
  output in covariance form with Levenberg-Marquardt regularisation (a small number added to the
  diagonal of its inverse, the Hessian approximation, sec. 6.3), and the projection of sec. 6.3: an
  update that would take C(z^-1) out of the stability region is halved until it does not (stability
  from the roots of det C,
  :func:`seapup_ident.armax.is_stable`).

Estimation can be "jacketed" (sec. 7.3) for adaptive control: no update inside a dead zone of
the prediction error, and no forgetting while trace P exceeds a limit (no covariance wind-up).
Bad data (NaN, inf, wrong length) raise :class:`DataError` and change nothing.

A sample is :meth:`RecursiveArmax.step` (y(t) and the input u(t) applied after it), or its two halves for a
controller that chooses u(t) after the estimate has seen y(t): :meth:`RecursiveArmax.observe` then
:meth:`RecursiveArmax.input`.
"""
from __future__ import annotations

import importlib
import math
from dataclasses import dataclass, field

import numpy as np

from seapup_common.kernels import compiled_by_default, numba_installed
from seapup_ident.armax import ArmaxModel, ArmaxOrders, Regressor, is_stable

__all__ = ["DataError", "Forgetting", "Jacket", "ud_update", "RecursiveArmax", "RecursiveRegression", "METHODS"]

METHODS = ("ls", "els", "rpem")


class DataError(ValueError):
    """A sample the estimator refuses (non-finite or of the wrong size); nothing was changed."""


@dataclass
class Forgetting:
    """The forgetting factor lambda(t): fixed, or growing to 1 as eq. 6.15 from ``lambda0`` with ``alpha``.

    Parameters
    ----------
    factor : float
        Fixed lambda (0 < lambda <= 1), used when ``alpha`` is None. Data older than
        1 / (1 - lambda) samples weigh less than 36 % (eq. 6.14).
    lambda0, alpha : float
        eq. 6.15: lambda(t) = alpha lambda(t-1) + (1 - alpha), lambda(0) = lambda0; the thesis
        takes lambda(0) = 0.6-0.7 and alpha close to 1 (0.9 here by default).
    """

    factor: float = 1.0
    lambda0: float | None = None
    alpha: float | None = None
    value: float = field(init=False)

    def __post_init__(self):
        if self.alpha is None:
            if not 0.0 < self.factor <= 1.0:
                raise ValueError(f"forgetting factor must be in (0, 1], got {self.factor}")
        else:
            if self.lambda0 is None:
                self.lambda0 = 0.6
            if not (0.0 < self.lambda0 <= 1.0 and 0.0 <= self.alpha < 1.0):
                raise ValueError(f"forgetting schedule needs 0 < lambda0 <= 1 and 0 <= alpha < 1, "
                                 f"got lambda0={self.lambda0}, alpha={self.alpha}")
        self.reset()

    @classmethod
    def schedule(cls, lambda0: float = 0.6, alpha: float = 0.9) -> "Forgetting":
        """The thesis's schedule (eq. 6.15)."""
        return cls(lambda0=lambda0, alpha=alpha)

    def reset(self) -> None:
        self.value = self.factor if self.alpha is None else float(self.lambda0)

    def next(self) -> float:
        """lambda for the coming sample (the schedule's first sample uses alpha lambda(0) + 1 - alpha)."""
        if self.alpha is not None:
            self.value = self.alpha * self.value + (1.0 - self.alpha)
        return self.value


@dataclass(frozen=True)
class Jacket:
    """Safety "jacketing" of the estimator for adaptive control (sec. 7.3).

    Parameters
    ----------
    dead_zone : float or array (ny,)
        No update while every |prediction error| is below this (near the set point the data say
        nothing new, and noise would only drift the estimate). 0: always update.
    max_trace : float
        While trace P (per output) exceeds this, lambda is taken as 1 (no covariance wind-up when
        the input does not excite). inf: never.
    """

    dead_zone: float | np.ndarray = 0.0
    max_trace: float = math.inf


def ud_update(U: np.ndarray, D: np.ndarray, phi: np.ndarray, lam: float) -> np.ndarray:
    """Bierman's / Peterka's square-root update of P = U D U^T (eq. 6.17) for one regressor; the gain.

    Computes, in place, the UD factors of

        P(t) = [P - P phi phi^T P / (lam + phi^T P phi)] / lam

    and returns L = P(t-1) phi / (lam + phi^T P(t-1) phi) (Ljung and Soderstrom 1983, sec. 6.2;
    U unit upper triangular, D > 0, so P stays symmetric positive definite to rounding).
    """
    f = U.T @ phi
    g = D * f
    # Bierman's loop over the columns j, as running sums (the same additions in the same order, so the
    # same bits): beta_j = lam + sum_{k<=j} f_k g_k, and nu before column j = sum_{k<j} U_:,k g_k, which
    # is zero on and below row j because U is unit upper triangular
    beta = np.cumsum(np.concatenate(([lam], f * g)))
    beta_prev = beta[:-1]
    nu = np.cumsum(U * g, axis=1)
    D *= beta_prev / (beta[1:] * lam)
    U[:, 1:] += nu[:, :-1] * (-f[1:] / beta_prev[1:])
    return nu[:, -1] / beta[-1]


def _ud_compiled(U: np.ndarray, D: np.ndarray, phi: np.ndarray, lam: float) -> np.ndarray:
    """:func:`ud_update` by the compiled kernel (:func:`seapup_ident.compiled.ud_update`, the same bits): a fresh
    gain array, the regressor made contiguous."""
    from seapup_ident.compiled import ud_update as kernel
    gain = np.empty(U.shape[0])
    kernel(U, D, np.ascontiguousarray(phi, dtype=float), float(lam), gain)
    return gain


def _ud_kernel(compiled: bool):
    """:func:`ud_update`'s implementation (U, D, phi, lam) -> the gain: the compiled one when ``compiled`` (loaded
    now, from numba's cache), else the reference itself. Module functions both, so an estimator pickles."""
    if not compiled:
        return ud_update
    importlib.import_module("seapup_ident.compiled")   # numba and the kernel loaded now, not at the first sample
    return _ud_compiled


class RecursiveArmax:
    """Recursive multivariable ARMAX identification (eq. 6.12, 6.24, 6.27), MATLAB-like object API.

    Parameters
    ----------
    orders : ArmaxOrders
        ny, nu, na, nb, nc and the offset d. ``ls`` needs nc = 0.
    method : {"ls", "els", "rpem"}
    forgetting : Forgetting, optional
        Default: no forgetting (lambda = 1).
    p0 : float
        P(0) = p0 I (eq. 6.16).
    theta0 : array (n_params, ny), optional
        Initial estimate (default zero).
    jacket : Jacket, optional
    regularisation : float
        RPEM's Levenberg-Marquardt term (sec. 6.3, eq. 6.17: "a small number is added to each diagonal
        element", in the paragraph on keeping P(t) positive definite and nonsingular). Our reading: added
        each sample to the diagonal of the Hessian approximation R = P^-1, as Levenberg and Marquardt (the
        thesis's refs. [62, 63]) regularise the Gauss-Newton step: P <- (I + delta P)^-1 P.
        It keeps P nonsingular and bounded without keeping it from shrinking as 1/t, so a long record
        converges (added to P itself, the estimate kept a memory of about 1 / sqrt(delta) samples and
        wandered: +-8 % in c_1 of a first-order ARMAX after 20 000 samples, where ELS is within 1 %).
    stability_margin : float
        RPEM keeps every root of det C(z) inside |z| < 1 - margin.
    filter_weakening : (float, float), optional
        RPEM: (K(0), gamma) of the factor that weakens the gradient filter in the initial phase
        (thesis Table 6.3: K(0) = 0.1, gamma = 0.98; sec. 6.5.3). The thesis names the factor and
        its values but not its law; here it grows to 1 as eq. 6.15 does, K(t) = gamma K(t-1) +
        1 - gamma, and the filter 1/C(z^-1) is contracted to 1/C(K(t) z^-1) (coefficient c_k times
        K(t)^k, Ljung and Soderstrom's way to keep a young filter stable): at first nearly ELS's
        unfiltered regressor, the full RPEM gradient once K -> 1. None: no weakening.
    keep_history : bool
        Keep Theta, lambda, trace P and the prediction errors of every sample (``history``).
    compiled : bool, optional
        RPEM's gradient step by the compiled kernel (default: when numba is installed) and the square-root
        update of LS and ELS by :func:`seapup_ident.compiled.ud_update` (the same bits; default
        :func:`seapup_common.kernels.compiled_by_default`), or both by the NumPy reference (False).

    Examples
    --------
    >>> est = RecursiveArmax(ArmaxOrders(ny=1, nu=1, na=1, nb=1, offset=False), "ls", p0=1e4)
    >>> rng = np.random.default_rng(0); y = 0.0
    >>> for u in rng.normal(size=300):
    ...     theta, y_hat = est.step([y], [u])    # y(t) = 0.8 y(t-1) + 0.5 u(t-1)
    ...     y = 0.8 * y + 0.5 * u
    >>> np.round(est.model.A[0, 0, 0], 3), np.round(est.model.B[0, 0, 0], 3)
    (np.float64(-0.8), np.float64(0.5))
    """

    def __init__(self, orders: ArmaxOrders, method: str = "ls", *, forgetting: Forgetting | None = None,
                 p0: float = 1e3, theta0=None, jacket: Jacket | None = None, regularisation: float = 1e-6,
                 stability_margin: float = 1e-3, filter_weakening: tuple[float, float] | None = None,
                 keep_history: bool = False, compiled: bool | None = None):
        if method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
        if method == "ls" and orders.nc:
            raise ValueError(f"least squares estimates no noise model: nc must be 0, got {orders.nc} (use els or rpem)")
        if not (math.isfinite(p0) and p0 > 0):
            raise ValueError(f"p0 must be finite and > 0, got {p0}")
        self.orders, self.method = orders, method
        self.forgetting = forgetting or Forgetting(1.0)
        self.p0 = float(p0)
        self.theta0 = np.zeros((orders.n_params, orders.ny)) if theta0 is None else \
            np.array(theta0, dtype=float).reshape(orders.n_params, orders.ny)
        self.jacket = jacket or Jacket()
        self.regularisation = float(regularisation)
        self.stability_margin = float(stability_margin)
        if filter_weakening is not None and method != "rpem":
            raise ValueError(f"filter_weakening is an RPEM option, not {method}'s")
        self.filter_weakening = None if filter_weakening is None else Forgetting.schedule(*filter_weakening)
        self.keep_history = keep_history
        self.compiled = numba_installed() if compiled is None else bool(compiled)
        if self.compiled and method == "rpem":   # loaded now (from numba's cache), not at the first sample
            from seapup_ident.compiled import rpem_gradient_step
            self._gradient_step = rpem_gradient_step
        # the square-root update compiled where numba is loaded already (the same bits: _ud_kernel)
        self._ud = _ud_kernel(compiled_by_default() if compiled is None else bool(compiled))
        self.reset()

    # -- state -----------------------------------------------------------------------------
    def reset(self) -> None:
        """Back to Theta(0), P(0) = p0 I, lambda(0) and an empty history."""
        o, n = self.orders, self.orders.n_params
        self.theta = self.theta0.copy()
        self.forgetting.reset()
        if self.filter_weakening is not None:
            self.filter_weakening.reset()
        self.regressor = Regressor(o)
        if self.method == "rpem":
            self._P = np.repeat(self.p0 * np.eye(n)[None], o.ny, axis=0)   # per output (own psi)
            self._psi = np.zeros((o.ny, max(o.nc, 1), n))                   # psi(t-1) .. psi(t-nc)
        else:
            self._U, self._D = np.eye(n), np.full(n, self.p0)               # one P shared by the outputs
        self._trace: float | None = None   # trace P of U and D as they are (None: work it out)
        self.t = 0
        self._pending = None
        self.residual = np.zeros(o.ny)   # the last sample's a posteriori residual y - Theta(t)^T phi(t)
        self.counts = {"samples": 0, "updates": 0, "dead_zone": 0, "trace_limited": 0, "projections": 0,
                       "rejected": 0}
        self.history: dict[str, list] = {"theta": [], "lambda": [], "trace": [], "error": []}

    def restart(self) -> None:
        """Forget the data history (after a gap or a bad sample), keep Theta, P and lambda.

        The next samples fill the regressor again; until they do its lagged entries are zero.
        """
        self.regressor.reset()
        self._pending = None
        if self.method == "rpem":
            self._psi[:] = 0.0

    @property
    def covariance(self) -> np.ndarray:
        """P (n_params x n_params; for ``rpem`` one per output: ny x n x n)."""
        if self.method == "rpem":
            return self._P.copy()
        return (self._U * self._D) @ self._U.T

    @property
    def trace(self) -> np.ndarray:
        """trace P per output."""
        if self.method == "rpem":
            return np.trace(self._P, axis1=1, axis2=2)
        return np.full(self.orders.ny, self.shared_trace)

    @property
    def shared_trace(self) -> float:
        """trace P of the one P that LS's and ELS's outputs share (:attr:`trace` gives it per output), worked out
        once per update of U and D (a self-tuner asks for it thrice a sample)."""
        if self.method == "rpem":
            raise ValueError("RPEM keeps a P per output: see trace")
        if self._trace is None:
            self._trace = float(np.sum(self._D * np.sum(self._U ** 2, axis=0)))
        return self._trace

    @property
    def model(self) -> ArmaxModel:
        """The present estimate as A, B, C, d (eq. 6.27)."""
        return ArmaxModel.from_theta(self.orders, self.theta)

    # -- one sample ------------------------------------------------------------------------
    def _check(self, value, size: int, what: str) -> np.ndarray:
        value = np.asarray(value, dtype=float).ravel()
        if value.shape != (size,):
            self.counts["rejected"] += 1
            raise DataError(f"sample needs {size} {what}, got {value.size}")
        if not np.isfinite(value).all():
            self.counts["rejected"] += 1
            raise DataError(f"non-finite {what} {value.tolist()}: not used")
        return value

    def step(self, y, u, update: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Take sample t: output y(t) and the input u(t) applied after it; return (Theta(t), y_hat(t)).

        y_hat(t) = Theta(t-1)^T phi(t) is the one-step prediction made before y(t) was seen.
        The regressor for t+1 then holds y(t), u(t) and the residual of t. ``update=False`` only
        fills the regressor (after :meth:`restart`, while its lags still reach before the data).
        The same as :meth:`observe` then :meth:`input` (both checked before either changes anything).
        """
        o = self.orders
        y, u = self._check(y, o.ny, "outputs"), self._check(u, o.nu, "inputs")
        out = self.observe(y, update)
        self.input(u)
        return out

    def observe(self, y, update: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """The first half of :meth:`step`, for a controller that chooses u(t) after seeing y(t) with
        the estimate updated by it (an explicit self-tuner, sec. 7.3): update Theta with y(t);
        return (Theta(t), y_hat(t)). :meth:`input` must follow before the next :meth:`observe`."""
        if getattr(self, "_pending", None) is not None:
            raise DataError("observe() twice: give the input of the last sample first (input(u))")
        y = self._check(y, self.orders.ny, "outputs")
        phi = self.regressor.phi()
        y_hat = self.theta.T @ phi
        error = y - y_hat
        if not update:
            self._pending = (y, error)
            return self.theta.copy(), y_hat
        lam = self.forgetting.next()
        trace = self.trace if self.method == "rpem" else None   # LS, ELS: the shared trace, asked below
        dead_zone = self.jacket.dead_zone
        # |e| < dz never holds for a dead zone <= 0 (the default): updated without the arrays
        updated = True if (isinstance(dead_zone, (int, float)) and dead_zone <= 0.0) else \
            not np.all(np.abs(error) < np.broadcast_to(dead_zone, error.shape))
        if not updated:
            self.counts["dead_zone"] += 1
        elif self.method == "rpem":
            self._rpem_update(phi, error, lam, trace)
        else:
            if self.shared_trace > self.jacket.max_trace:
                lam = 1.0
                self.counts["trace_limited"] += 1
            gain = self._ud(self._U, self._D, phi, lam)
            self._trace = None
            self.theta += np.outer(gain, error)
        self.counts["updates"] += int(updated)
        residual = y - self.theta.T @ phi   # a posteriori: the noise estimate e(t) for ELS/RPEM
        self._pending = (y, residual)
        self.t += 1
        self.counts["samples"] += 1
        if self.keep_history:
            for key, value in (("theta", self.theta.copy()), ("lambda", lam), ("trace", self.trace),
                               ("error", error)):
                self.history[key].append(value)
        return self.theta.copy(), y_hat

    def input(self, u) -> None:
        """The second half of :meth:`step`: the input u(t) applied after the last observed y(t) joins the
        regressor (with y(t) and its residual) for the next sample."""
        if getattr(self, "_pending", None) is None:
            raise DataError("input() without an observed output: observe(y) first")
        u = self._check(u, self.orders.nu, "inputs")
        y, residual = self._pending
        self._pending = None
        self.residual = residual
        self.regressor.push(y, u, residual)

    def _rpem_update(self, phi: np.ndarray, error: np.ndarray, lam: float, trace: np.ndarray) -> None:
        """One RPEM step (eq. 6.19-6.22 with sec. 6.3's projection), all outputs at once: output i has its
        own gradient psi_i and covariance P_i (the arrays' leading axis). The gradient step is compiled
        (:mod:`seapup_ident.compiled`) unless ``compiled=False`` chose the NumPy reference."""
        o = self.orders
        ny, nc = o.ny, o.nc
        mu = self.filter_weakening.next() if self.filter_weakening is not None else 1.0
        if nc:   # c_ii,k mu^k: the (weakened) gradient filter 1/C_ii of output i
            c = self.theta[o.c_slice].T.reshape(ny, nc, ny)[np.arange(ny), :, np.arange(ny)]       # (ny, nc)
            weights = c * mu ** np.arange(1, nc + 1)
        else:
            weights = np.zeros((ny, 0))
        limited = trace > self.jacket.max_trace
        lam_i = np.where(limited, 1.0, lam)
        if lam < 1.0:
            self.counts["trace_limited"] += int(np.count_nonzero(limited))
        if self.compiled:
            step = np.empty((len(phi), ny))
            self._gradient_step(self._P, self._psi, phi, np.ascontiguousarray(weights), lam_i, self.regularisation,
                               error, step)
        else:
            step = self._rpem_gradient_numpy(phi, weights, lam_i, error)
        candidate = self.theta + step
        for _ in range(30):  # the projection of sec. 6.3: shrink the correction until C is stable
            if not nc or is_stable(candidate[o.c_slice].T.reshape(ny, nc, ny).transpose(1, 0, 2),
                                   self.stability_margin):
                break
            self.counts["projections"] += 1
            step *= 0.5
            candidate = self.theta + step
        else:
            candidate = self.theta
        self.theta = candidate

    def _rpem_gradient_numpy(self, phi, weights, lam_i, error) -> np.ndarray:
        """The reference of :func:`seapup_ident.compiled.rpem_gradient_step` in NumPy: psi_i, P_i, the step."""
        ny, nc = self.orders.ny, weights.shape[1]
        psi = phi - np.einsum("ik,ikn->in", weights, self._psi[:, :nc]) if nc else np.broadcast_to(phi, (ny, len(phi)))
        P = self._P
        Pp = np.einsum("inm,im->in", P, psi)
        gain = Pp / (lam_i + np.einsum("in,in->i", psi, Pp))[:, None]
        P = (P - gain[:, :, None] * Pp[:, None, :]) / lam_i[:, None, None]
        P = 0.5 * (P + P.transpose(0, 2, 1))
        if self.regularisation > 0.0:   # Levenberg-Marquardt: delta added to the diagonal of P^-1 (class docstring)
            P = np.linalg.solve(np.eye(P.shape[1])[None] + self.regularisation * P, P)
            P = 0.5 * (P + P.transpose(0, 2, 1))
        self._P = P
        if nc:
            self._psi[:, 1:] = self._psi[:, :-1]
            self._psi[:, 0] = psi
        return (gain * error[:, None]).T


class RecursiveRegression:
    """Square-root (UD) recursive least squares for a multivariable linear regression z(t) = Theta^T x(t) + e(t)
    with one P shared by the outputs (eq. 6.12, 6.17), for a regression that is not an ARMAX model -- the
    implicit self-tuner's predictor of a generalised output (sec. 7.5, eq. 7.3).

    Parameters
    ----------
    n_params, n_outputs : int
        Sizes of x and z.
    forgetting : float
        lambda in (0, 1] (eq. 6.13).
    p0 : float
        P(0) = p0 I (eq. 6.16).
    compiled : bool, optional
        The square-root update by the compiled kernel (:func:`seapup_ident.compiled.ud_update`, the same bits)
        or by :func:`ud_update`; default :func:`seapup_common.kernels.compiled_by_default`.

    Examples
    --------
    >>> est = RecursiveRegression(2, 1, p0=1e6)
    >>> rng = np.random.default_rng(1)
    >>> for x in rng.normal(size=(50, 2)):
    ...     _ = est.update(x, [3.0 * x[0] - 2.0 * x[1]])
    >>> np.round(est.theta[:, 0], 4)
    array([ 3., -2.])
    """

    def __init__(self, n_params: int, n_outputs: int, forgetting: float = 1.0, p0: float = 1e3,
                 compiled: bool | None = None):
        if int(n_params) < 1 or int(n_outputs) < 1:
            raise ValueError(f"a regression needs n_params >= 1 and n_outputs >= 1, got {n_params}, {n_outputs}")
        if not (math.isfinite(forgetting) and 0.0 < forgetting <= 1.0):
            raise ValueError(f"forgetting must be in (0, 1], got {forgetting!r}")
        if not (math.isfinite(p0) and p0 > 0):
            raise ValueError(f"p0 must be finite and > 0, got {p0!r}")
        self.n_params, self.n_outputs = int(n_params), int(n_outputs)
        self.forgetting, self.p0 = float(forgetting), float(p0)
        self._ud = _ud_kernel(compiled_by_default() if compiled is None else bool(compiled))
        self.reset()

    def reset(self) -> None:
        """Back to Theta = 0 and P = p0 I."""
        self.theta = np.zeros((self.n_params, self.n_outputs))
        self._U, self._D = np.eye(self.n_params), np.full(self.n_params, self.p0)
        self._trace: float | None = None
        self.updates = 0

    @property
    def trace(self) -> float:
        """trace P (worked out once per update)."""
        if self._trace is None:
            self._trace = float(np.sum(self._D * np.sum(self._U ** 2, axis=0)))
        return self._trace

    @property
    def covariance(self) -> np.ndarray:
        return (self._U * self._D) @ self._U.T

    def predict(self, x) -> np.ndarray:
        """Theta^T x."""
        return self.theta.T @ np.asarray(x, dtype=float)

    def update(self, x, z) -> np.ndarray:
        """One sample (x(t), z(t)); returns the prediction error made before it. Non-finite or wrong-length
        data raise :class:`DataError` and change nothing."""
        x, z = np.asarray(x, dtype=float).ravel(), np.asarray(z, dtype=float).ravel()
        if x.shape != (self.n_params,) or z.shape != (self.n_outputs,):
            raise DataError(f"a sample needs {self.n_params} regressors and {self.n_outputs} outputs, "
                            f"got {x.size} and {z.size}")
        if not (np.isfinite(x).all() and np.isfinite(z).all()):
            raise DataError("non-finite sample: not used")
        error = z - self.theta.T @ x
        gain = self._ud(self._U, self._D, x, self.forgetting)
        self._trace = None
        self.theta += np.outer(gain, error)
        self.updates += 1
        return error
