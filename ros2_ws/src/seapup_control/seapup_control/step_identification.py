"""Batch identification of first-order lags from step-test data (thesis sec. 4.5.1).

The self-test (sec. 4.5.2) steps one thruster at a time and fits every
input-output channel with a discrete first-order lag

    y(t+1) = f y(t) + g u(t)                                    (eq. 4.23, 4.30)

whose initial response and steady-state gain fill the MFOL matrices,
``[B0^-1]_ij = g`` and ``[B1^-1]_ij = g / (1 - f)`` (eq. 4.24). Two batch
methods are compared in the thesis (Table 4.1):

- batch least squares, :func:`fit_first_order` (eq. 4.30-4.32), and its
  n-th order ARX generalisation :func:`fit_arx` (eq. 4.31): biased but robust
  with measurement noise;
- Prony's method constrained to a first-order step response
  ``y(t) = C (1 - exp(d t))``, :func:`fit_prony_step` (eq. 4.25-4.29): exact
  without noise, useless with it, because it works on sample differences.

Data about a non-zero operating point are fitted as deviations
``y' = y - y0``, ``u' = u - u0`` (eq. 5.5).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

__all__ = ["IdentificationError", "FirstOrderLag", "fit_first_order", "fit_arx", "PronyStep", "fit_prony_step",
           "step_fits", "NO_RESPONSE"]

#: An output whose deviations never exceed this times the input's did not
#: respond (rounding of an exactly decoupled channel): a zero-gain lag.
NO_RESPONSE = 1e-9


class IdentificationError(ValueError):
    """Step data that cannot give a model (too short, non-finite, no excitation, unstable fit)."""


def _finite_series(values, name: str, length: int | None = None) -> np.ndarray:
    arr = np.asarray(values, dtype=float)
    if arr.ndim != 1:
        raise IdentificationError(f"{name} must be a 1-D series, got shape {arr.shape}")
    if length is not None and arr.size != length:
        raise IdentificationError(f"{name} has {arr.size} samples, the outputs {length}")
    if not np.all(np.isfinite(arr)):
        raise IdentificationError(f"{name} holds non-finite samples at {np.flatnonzero(~np.isfinite(arr))[:5]}")
    return arr


@dataclass(frozen=True)
class FirstOrderLag:
    """A discrete first-order lag ``y(t+1) = f y(t) + g u(t)`` sampled every ``sample_period`` s.

    Attributes
    ----------
    f, g : float
        Pole and input gain (``a_ij``, ``b_ij`` of eq. 4.23).
    sample_period : float
        T_s [s].
    residual_std : float
        Standard deviation of the equation errors of the fit.
    """

    f: float
    g: float
    sample_period: float
    residual_std: float = 0.0

    @property
    def initial_response(self) -> float:
        """Response one sample after a unit step: ``g`` (eq. 4.24a, an element of B0^-1)."""
        return self.g

    @property
    def steady_state_gain(self) -> float:
        """Final response to a unit step: ``g / (1 - f)`` (eq. 4.24b, 4.33b; an element of B1^-1).

        Raises
        ------
        IdentificationError
            If ``f == 1`` (an integrator has no steady state).
        """
        if self.f == 1.0:
            raise IdentificationError("the fitted pole is f = 1 (an integrator): no steady-state gain")
        return self.g / (1.0 - self.f)

    @property
    def time_constant(self) -> float:
        """``T_s / ln f`` [s] (eq. 4.33a): negative for a stable lag, -1/a for ``dy/dt = a y + b u``.

        The thesis's sign convention (Table 4.1 lists tau_c = -1 for dy/dt = -y + u).

        Raises
        ------
        IdentificationError
            If ``f <= 0`` (no continuous first-order lag samples to it).
        """
        if not self.f > 0.0:
            raise IdentificationError(f"the fitted pole f = {self.f:.4g} is not positive: no continuous time constant")
        return self.sample_period / math.log(self.f)


def fit_arx(y, u, order: int = 1) -> tuple[np.ndarray, np.ndarray, float]:
    """Batch least squares fit of an n-th order ARX model (eq. 4.31-4.32).

    .. math:: y(t) = a_1 y(t-1) + ... + a_n y(t-n) + b_1 u(t-1) + ... + b_n u(t-n) + e(t)

    minimising :math:`J = \\sum e^2(t)` (eq. 4.32) with ``scipy.linalg.lstsq``.

    Parameters
    ----------
    y, u : array_like, shape (N,)
        Output and input samples at the same instants.
    order : int
        n >= 1.

    Returns
    -------
    a, b : ndarray, shape (n,)
        The coefficients.
    residual_std : float
        Standard deviation of the equation errors.

    Raises
    ------
    IdentificationError
        On non-finite data, too few samples (fewer than 2n + 2 equations) or
        data that do not determine the coefficients (e.g. no excitation).
    """
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 1:
        raise IdentificationError(f"order must be an integer >= 1, got {order!r}")
    y = _finite_series(y, "outputs")
    u = _finite_series(u, "inputs", y.size)
    n = int(order)
    rows = y.size - n
    if rows < 2 * n + 2:
        raise IdentificationError(f"{y.size} samples are too few for an order-{n} fit (need {3 * n + 2})")
    phi = np.column_stack([y[n - i - 1:y.size - i - 1] for i in range(n)]
                          + [u[n - i - 1:u.size - i - 1] for i in range(n)])
    target = y[n:]
    theta, _, rank, _ = scipy.linalg.lstsq(phi, target)
    if rank < 2 * n:
        raise IdentificationError(f"the data do not determine an order-{n} model (regressor rank {rank} < {2 * n}): "
                                  "is the input stepped and the output moving?")
    residuals = target - phi @ theta
    return theta[:n], theta[n:], float(np.sqrt(np.mean(residuals ** 2)))


def fit_first_order(y, u, sample_period: float, y0: float = 0.0, u0: float = 0.0) -> FirstOrderLag:
    """Batch least squares first-order lag ``y'(t+1) = f y'(t) + g u'(t)`` (eq. 4.30, 4.23b, 5.5).

    Parameters
    ----------
    y, u : array_like, shape (N,)
        Output and input samples (e.g. surge velocity and one thruster's blade
        pitch during its step test).
    sample_period : float
        T_s [s] (for :attr:`FirstOrderLag.time_constant`).
    y0, u0 : float
        Operating point the data are deviations from (eq. 5.5).

    Returns
    -------
    FirstOrderLag

    Notes
    -----
    Implements eq. 4.30-4.33 (and eq. 5.5 about a non-zero operating point).
    An output that does not move (every deviation at most ``NO_RESPONSE``
    times the input's) is a zero-gain channel (f = g = 0), not an error.
    With noise on the measured output the least-squares pole is biased
    towards zero (the regressor y(t) carries the noise): Table 4.1's shorter
    time constants. It stays usable where Prony's method fails.

    Examples
    --------
    >>> k = np.arange(50); y = 1 - np.exp(-0.2 * k)          # dy/dt = -y + u, 5 Hz
    >>> lag = fit_first_order(y, np.ones(50), 0.2)
    >>> round(lag.time_constant, 6), round(lag.steady_state_gain, 6)
    (-1.0, 1.0)
    """
    if not (math.isfinite(sample_period) and sample_period > 0):
        raise IdentificationError(f"sample_period must be > 0 s, got {sample_period!r}")
    y = _finite_series(y, "outputs") - float(y0)
    u = _finite_series(u, "inputs", y.size) - float(u0)
    if np.any(u != 0.0) and np.max(np.abs(y)) <= NO_RESPONSE * np.max(np.abs(u)):
        # the output never left its operating point (a decoupled channel, or a
        # dead input): zero gain. f is then undetermined; 0 is the minimum-norm
        # solution and gives B0^-1 = B1^-1 = 0 for the channel, as it should.
        return FirstOrderLag(0.0, 0.0, float(sample_period), float(np.sqrt(np.mean(y ** 2))))
    a, b, std = fit_arx(y, u, 1)
    return FirstOrderLag(float(a[0]), float(b[0]), float(sample_period), std)


@dataclass(frozen=True)
class PronyStep:
    """Prony's first-order step-response model ``y(t) = C (1 - exp(d t))`` (eq. 4.28).

    Attributes
    ----------
    final_value : float
        C = y_inf (eq. 4.29b).
    exponent : float
        d [1/s]; the time constant is ``1 / d`` (eq. 4.29a, negative when stable).
    """

    final_value: float
    exponent: float

    @property
    def time_constant(self) -> float:
        return 1.0 / self.exponent


def fit_prony_step(y, sample_period: float) -> PronyStep:
    """Prony's method constrained to a first-order step response (eq. 4.25-4.29).

    With ``n = 2``, ``d_1 = 0`` and ``C_2 = -C_1`` (sec. 4.5.1) the samples
    ``y_k = C (1 - mu^k)``, ``mu = exp(d T_s)``, satisfy the linear prediction
    ``Δy_{k+1} = mu Δy_k`` of their differences: ``mu`` by least squares
    (the first linear problem), then ``C`` by least squares given ``mu`` (the
    second).

    Parameters
    ----------
    y : array_like, shape (N,)
        Response to a step applied at sample 0 (``y_0`` the value before it).
    sample_period : float
        T_s [s].

    Raises
    ------
    IdentificationError
        If the fitted ``mu`` is not in (0, 1): no stable first-order lag fits
        (the "failures" of Table 4.1, frequent with noise).
    """
    if not (math.isfinite(sample_period) and sample_period > 0):
        raise IdentificationError(f"sample_period must be > 0 s, got {sample_period!r}")
    y = _finite_series(y, "outputs")
    if y.size < 4:
        raise IdentificationError(f"{y.size} samples are too few for Prony's method (need 4)")
    d = np.diff(y)
    denominator = float(d[:-1] @ d[:-1])
    if denominator == 0.0:
        raise IdentificationError("the response does not move: nothing to fit")
    mu = float(d[1:] @ d[:-1]) / denominator
    if not 0.0 < mu < 1.0:
        raise IdentificationError(f"Prony's method failed: mu = {mu:.4g} is not in (0, 1)")
    shape = 1.0 - mu ** np.arange(y.size)
    final = float(shape @ (y - y[0]) / (shape @ shape)) + float(y[0])
    return PronyStep(final, math.log(mu) / sample_period)


def step_fits(method: str, samples: int, noise_power: float, realisations: int, rng,
              sample_period: float = 0.2) -> tuple[np.ndarray, float]:
    """Table 4.1's experiment: fit ``realisations`` noisy unit-step responses of dy/dt = -y + u (y(0) = 0,
    y_0 = 1, tau_c = -1 s), white noise of power ``noise_power`` on the measured output, with ``method``
    ``"bls"`` (:func:`fit_first_order`) or ``"prony"`` (:func:`fit_prony_step`).

    Returns
    -------
    fits : ndarray, shape (k, 2)
        (y_0, tau_c) of every realisation that did not fail.
    failed : float
        The share of realisations that failed.
    """
    if method not in ("bls", "prony"):
        raise ValueError(f"method must be 'bls' or 'prony', got {method!r}")
    clean = 1.0 - np.exp(-np.arange(samples) * sample_period)
    fits, failures = [], 0
    for _ in range(realisations):
        y = clean + (rng.normal(0.0, math.sqrt(noise_power), samples) if noise_power else 0.0)
        try:
            if method == "bls":
                lag = fit_first_order(y, np.ones(samples), sample_period)
                fits.append((lag.steady_state_gain, lag.time_constant))
            else:
                fit = fit_prony_step(y, sample_period)
                fits.append((fit.final_value, fit.time_constant))
        except IdentificationError:
            failures += 1
    return np.array(fits, dtype=float).reshape(-1, 2), failures / realisations
