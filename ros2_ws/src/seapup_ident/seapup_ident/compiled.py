"""The RPEM step's and the square-root least squares' arithmetic compiled with numba (issue 26: RPEM at <= 100 us
per sample; issue 42: the self-tuners' estimators).

:meth:`seapup_ident.recursive.RecursiveArmax._rpem_update_numpy` stays the reference (eq. 6.19-6.22: the
gradient psi_i filtered through 1/C_ii, the covariance update per output with forgetting, symmetrisation
and the Levenberg-Marquardt term); :func:`rpem_gradient_step` does the same per output in one compiled
call, where the NumPy version spends its time in some twenty small array operations. The projection of
sec. 6.3 (shrinking the step until C is stable) stays in Python: it tests roots. Both paths are tested to
agree to rounding along whole estimation runs (``test/test_recursive.py``). :func:`ud_update` is
:func:`seapup_ident.recursive.ud_update` (Bierman's and Peterka's update of P = U D U^T, eq. 6.17) with its
running sums as loops, in the reference's order (its one product, U^T phi, is the same BLAS call), so the two
give the same bits (tested). ``cache=True``: compiled once per machine (``./seapup setup`` warms it).
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["rpem_gradient_step", "ud_update", "warm"]


@njit(cache=True, nogil=True)
def rpem_gradient_step(P, psi_hist, phi, weights, lam_i, regularisation, error, step):
    """One RPEM gradient step for every output i, in place: ``psi_i = phi - sum_k weights[i, k]
    psi_hist[i, k]`` (weights: c_ii,k mu^k, none for nc = 0), ``P[i]`` updated (eq. 6.20-6.22, with
    ``lam_i[i]``), symmetrised and regularised (``regularisation`` added to the diagonal of P_i's inverse,
the Hessian approximation, as Levenberg and Marquardt regularise), ``step[:, i] = gain_i error_i`` (eq. 6.19) and psi_i pushed
    into ``psi_hist[i]``."""
    ny, n = P.shape[0], P.shape[1]
    nc = weights.shape[1]
    psi = np.empty(n)
    pp = np.empty(n)
    L = np.empty((n, n))
    Q = np.empty((n, n))
    for i in range(ny):
        for a in range(n):
            s = phi[a]
            for k in range(nc):
                s -= weights[i, k] * psi_hist[i, k, a]
            psi[a] = s
        denom = lam_i[i]
        for a in range(n):
            s = 0.0
            for b in range(n):
                s += P[i, a, b] * psi[b]
            pp[a] = s
        quad = 0.0
        for a in range(n):
            quad += psi[a] * pp[a]
        denom += quad
        for a in range(n):
            gain = pp[a] / denom
            step[a, i] = gain * error[i]
            for b in range(n):
                P[i, a, b] = (P[i, a, b] - gain * pp[b]) / lam_i[i]
        for a in range(n):
            for b in range(a + 1, n):
                m = 0.5 * (P[i, a, b] + P[i, b, a])
                P[i, a, b] = m
                P[i, b, a] = m
        if regularisation > 0.0:   # Levenberg-Marquardt: P^-1 + delta I, i.e. P <- (I + delta P)^-1 P
            _regularise(P[i], regularisation, L, Q)
        if nc > 0:
            for k in range(nc - 1, 0, -1):
                for a in range(n):
                    psi_hist[i, k, a] = psi_hist[i, k - 1, a]
            for a in range(n):
                psi_hist[i, 0, a] = psi[a]


@njit(cache=True, nogil=True)
def _regularise(P, delta, L, Q):
    """``P <- (I + delta P)^-1 P``, symmetrised, in place: M = I + delta P (symmetric positive definite, as P
    is) factored by Cholesky, M L = P solved column by column (work arrays ``L``, ``Q`` of P's shape)."""
    n = P.shape[0]
    for a in range(n):
        for b in range(a + 1):
            s = delta * P[a, b] + (1.0 if a == b else 0.0)
            for k in range(b):
                s -= L[a, k] * L[b, k]
            L[a, b] = np.sqrt(s) if a == b else s / L[b, b]
    for col in range(n):
        for a in range(n):            # L z = p_col
            s = P[a, col]
            for k in range(a):
                s -= L[a, k] * Q[k, col]
            Q[a, col] = s / L[a, a]
        for a in range(n - 1, -1, -1):  # L^T q = z
            s = Q[a, col]
            for k in range(a + 1, n):
                s -= L[k, a] * Q[k, col]
            Q[a, col] = s / L[a, a]
    for a in range(n):
        for b in range(a, n):
            m = 0.5 * (Q[a, b] + Q[b, a])
            P[a, b] = m
            P[b, a] = m


@njit(cache=True, nogil=True)
def ud_update(U, D, phi, lam, gain):
    """:func:`seapup_ident.recursive.ud_update` in place on ``U``, ``D``; the gain into ``gain``. The reference's
    cumulative sums (beta_j = lam + sum_{k<=j} f_k g_k; nu_ij = sum_{k<=j} U_ik g_k, from the U before the
    update) as running sums, added in the same order."""
    n = U.shape[0]
    f = U.T @ phi
    g = D * f
    beta = np.empty(n + 1)
    beta[0] = lam
    for j in range(n):
        beta[j + 1] = beta[j] + f[j] * g[j]
    for i in range(n):
        running = U[i, 0] * g[0]   # nu_i0: the cumulative sum's first term, as it is
        for j in range(1, n):
            nu_before = running
            running = running + U[i, j] * g[j]
            U[i, j] = U[i, j] + nu_before * (-f[j] / beta[j])
        gain[i] = running / beta[n]
    for j in range(n):
        D[j] = D[j] * (beta[j] / (beta[j + 1] * lam))


def warm() -> None:
    """Compile (or load from the cache) the kernel with the types the estimator passes."""
    rpem_gradient_step(np.repeat(np.eye(3)[None], 2, axis=0), np.zeros((2, 1, 3)), np.ones(3), np.zeros((2, 1)),
                       np.ones(2), 1e-6, np.ones(2), np.zeros((3, 2)))
    rpem_gradient_step(np.repeat(np.eye(3)[None], 2, axis=0), np.zeros((2, 1, 3)), np.ones(3), np.zeros((2, 0)),
                       np.ones(2), 1e-6, np.ones(2), np.zeros((3, 2)))
    U, D, gain = np.eye(3), np.full(3, 10.0), np.zeros(3)
    ud_update(U, D, np.ones(3), 0.99, gain)
    phi = np.ones(3)
    phi.setflags(write=False)
    ud_update(U, D, phi, 0.99, gain)
