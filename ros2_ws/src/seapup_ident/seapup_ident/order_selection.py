"""Batch least squares and the order tests of thesis sec. 6.3: loss, AIC, F-test, residual whiteness.

- ``batch_least_squares``: the off-line reference estimate of eq. 6.9 (optionally weighted),
  solved with ``scipy.linalg.lstsq``;
- ``loss``: V_N = (1/N) sum e(t)^2 per output (eq. 6.11);
- ``aic``: AIC = N (log 2 pi + 1 + log R_v) + 2 v per output (eq. 6.21);
- ``f_test``: F_{n->m} = (V_n - V_m) / V_m (N - m) / (m - n), compared with the F(m - n, N - m)
  quantile at risk alpha (eq. 6.18, ``scipy.stats.f.ppf`` as scipy.stats computes it: ``scipy.special.fdtri``);
- ``residual_autocorrelation``: the normalised autocorrelation of the residuals with its 95 %
  band +-1.96 / sqrt(N) ("ninety-five percent ... should fall within 2 sigma limits", fig. 6.2).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
from scipy import special

from seapup_ident.armax import ArmaxOrders, Regressor

__all__ = ["regressors", "batch_least_squares", "loss", "aic", "f_test", "FTest", "residual_autocorrelation"]


def regressors(orders: ArmaxOrders, y: np.ndarray, u: np.ndarray) -> np.ndarray:
    """phi(t) for t = 0 .. N-1 (N x n_params) from rest (zero history), without noise terms (nc = 0)."""
    if orders.nc:
        raise ValueError("batch least squares has no noise model: nc must be 0")
    y, u = np.asarray(y, float).reshape(-1, orders.ny), np.asarray(u, float).reshape(-1, orders.nu)
    regressor = Regressor(orders)
    rows = np.empty((len(y), orders.n_params))
    for t in range(len(y)):
        rows[t] = regressor.phi()
        regressor.push(y[t], u[t], np.zeros(orders.ny))
    return rows


def batch_least_squares(orders: ArmaxOrders, y, u, weights=None, skip: int | None = None):
    """Theta minimising sum_t w_t |y(t) - Theta^T phi(t)|^2 (eq. 6.9); also the residuals.

    ``skip`` (default the model's lag) leaves out the first samples, whose regressors reach back
    before the data. Returns (Theta (n_params x ny), residuals (N - skip x ny)).
    """
    y = np.asarray(y, float).reshape(-1, orders.ny)
    phi = regressors(orders, y, u)
    skip = orders.lag if skip is None else skip
    phi, target = phi[skip:], y[skip:]
    if len(phi) <= orders.n_params:
        raise ValueError(f"{len(phi)} samples cannot determine {orders.n_params} parameters per output")
    w = np.ones(len(phi)) if weights is None else np.asarray(weights, float)[skip:]
    root = np.sqrt(w)[:, None]
    theta, *_ = scipy.linalg.lstsq(root * phi, root * target)
    return theta, target - phi @ theta


def loss(residuals) -> np.ndarray:
    """V_N per output (eq. 6.11): the mean squared residual."""
    residuals = np.asarray(residuals, float)
    return np.mean(residuals ** 2, axis=0)


def aic(residuals, n_params: int) -> np.ndarray:
    """Akaike's information criterion per output (eq. 6.21): N (log 2 pi + 1 + log R_v) + 2 v."""
    residuals = np.asarray(residuals, float)
    n = len(residuals)
    return n * (np.log(2 * np.pi) + 1 + np.log(loss(residuals))) + 2 * n_params


@dataclass(frozen=True)
class FTest:
    """eq. 6.18 per output: the statistic, the F(m - n, N - m) quantile at risk ``alpha``, and whether the
    larger model is significantly better (statistic above the quantile)."""

    statistic: np.ndarray
    threshold: float
    larger_is_better: np.ndarray


def f_test(loss_small, loss_large, n_small: int, n_large: int, n_samples: int, alpha: float = 0.05) -> FTest:
    """Is the loss drop from n_small to n_large parameters significant at risk alpha (eq. 6.18)?"""
    if not n_large > n_small or n_samples <= n_large:
        raise ValueError(f"F-test needs n_small < n_large < N, got {n_small}, {n_large}, {n_samples}")
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"the F-test's risk alpha must be in (0, 1), got {alpha}")
    v_n, v_m = np.asarray(loss_small, float), np.asarray(loss_large, float)
    statistic = (v_n - v_m) / v_m * (n_samples - n_large) / (n_large - n_small)
    threshold = float(special.fdtri(n_large - n_small, n_samples - n_large, 1.0 - alpha))
    return FTest(statistic, threshold, statistic > threshold)


def residual_autocorrelation(residuals, max_lag: int = 20) -> tuple[np.ndarray, float]:
    """Normalised autocorrelation R(k) / R(0), k = 0 .. max_lag, per output (columns), and the 95 % band."""
    if int(max_lag) < 1:
        raise ValueError(f"the autocorrelation needs max_lag >= 1, got {max_lag}")
    e = np.asarray(residuals, float)
    e = e.reshape(len(e), -1) - e.reshape(len(e), -1).mean(axis=0)
    n = len(e)
    r0 = np.sum(e * e, axis=0)
    r = np.array([np.sum(e[k:] * e[:n - k], axis=0) for k in range(max_lag + 1)]) / r0
    return r, 1.96 / np.sqrt(n)
