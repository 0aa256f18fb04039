"""Eigenvalues of the sampled-data closed loop: plant, zero-order hold, two-term controller (sec. 5.4.1).

The continuous linearised plant ``dx/dt = A x + B u``, ``y = C x`` (eq. 3.2)
behind a zero-order hold and samplers at T_s is the discrete model

    x_{k+1} = Φ x_k + Δ u_k,   Φ = exp(A T_s),   Δ = ∫_0^T_s exp(A (T_s - t)) B dt      (eq. 5.8)

(computed here with ``scipy.signal.cont2discrete``, the exact matrix
exponential, instead of the truncated series of eq. 5.9-5.11). Augmented with
the controller's integrators ``q`` (eq. 4.11) and closed by ``e = r - y``:

    [x; q]_{k+1} = ([Φ, Δ K_int; 0, I] - [Δ K_err; I] [C, 0]) [x; q]_k + [Δ K_err; I] r_k   (eq. 5.12-5.14)

whose eigenvalues are the closed-loop poles (eq. 5.15), mapped to the
s-plane by ``s = ln(z) / T_s`` (eq. 5.1) to compare sampling rates (a pole on
the negative real z-axis maps to the Nyquist frequency, pi / T_s).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

__all__ = ["ClosedLoop", "discretise", "closed_loop", "closed_loop_discrete"]


def discretise(a, b, sample_period: float) -> tuple[np.ndarray, np.ndarray]:
    """(Φ, Δ) of eq. 5.8: the plant behind a zero-order hold, sampled every T_s. (``scipy.signal`` is imported
    here, not with the module: it costs about 1 s of CPU, paid before by every command that imports this one,
    ``./seapup selftest --help`` included.)"""
    import scipy.signal
    a, b = np.asarray(a, float), np.asarray(b, float)
    n, m = b.shape
    phi, delta, *_ = scipy.signal.cont2discrete((a, b, np.eye(n), np.zeros((n, m))), sample_period, method="zoh")
    return phi, delta


@dataclass(frozen=True)
class ClosedLoop:
    """The closed loop of eq. 5.14 and its poles.

    Attributes
    ----------
    phi, gamma : ndarray
        State and reference matrices of eq. 5.14 (states x then q).
    z_poles : ndarray
        Its eigenvalues (eq. 5.15), sorted by magnitude, largest first.
    s_poles : ndarray
        The same poles in the s-plane, ``ln(z) / T_s`` (eq. 5.1).
    sample_period : float
    """

    phi: np.ndarray
    gamma: np.ndarray
    c_aug: np.ndarray
    z_poles: np.ndarray
    s_poles: np.ndarray
    sample_period: float

    @property
    def stable(self) -> bool:
        """Every pole strictly inside the unit circle."""
        return bool(np.max(np.abs(self.z_poles)) < 1.0)

    @property
    def spectral_radius(self) -> float:
        return float(np.max(np.abs(self.z_poles)))

    def dc_gain(self) -> np.ndarray:
        """Steady-state y per unit constant r: ``C_s (I - Φ_s)^-1 Γ`` (identity with integral action, eq. 4.15)."""
        n = self.phi.shape[0]
        return self.c_aug @ np.linalg.solve(np.eye(n) - self.phi, self.gamma)


def closed_loop(a, b, c, k_int, k_err, sample_period: float) -> ClosedLoop:
    """The sampled-data closed loop of a continuous plant under eq. 4.11 (eq. 5.8-5.15).

    Parameters
    ----------
    a, b, c : array_like
        Continuous plant ``dx/dt = A x + B u``, ``y = C x`` (n states, m inputs, m outputs).
    k_int, k_err : array_like, shape (m, m)
        The controller's integral and error gains (:class:`~seapup_control.mfol.TwoTermGains`).
    sample_period : float
        T_s [s].

    Returns
    -------
    ClosedLoop

    Raises
    ------
    ValueError
        On inconsistent shapes, non-finite matrices or a non-positive period.
    """
    a, b, c = (np.atleast_2d(np.asarray(v, float)) for v in (a, b, c))
    k_int, k_err = np.atleast_2d(np.asarray(k_int, float)), np.atleast_2d(np.asarray(k_err, float))
    n, m = b.shape
    if a.shape != (n, n) or c.shape != (m, n) or k_int.shape != (m, m) or k_err.shape != (m, m):
        raise ValueError(f"shapes do not fit: A {a.shape}, B {b.shape}, C {c.shape}, "
                         f"K_int {k_int.shape}, K_err {k_err.shape} (need n x n, n x m, m x n, m x m)")
    if not all(np.all(np.isfinite(v)) for v in (a, b, c, k_int, k_err)):
        raise ValueError("plant and gains must be finite")
    if not (math.isfinite(sample_period) and sample_period > 0):
        raise ValueError(f"sample_period must be > 0 s, got {sample_period!r}")
    phi, delta = discretise(a, b, sample_period)
    return closed_loop_discrete(phi, delta, c, k_int, k_err, sample_period)


def closed_loop_discrete(phi, delta, c, k_int, k_err, sample_period: float) -> ClosedLoop:
    """The closed loop of eq. 5.12-5.15 for a plant already in discrete form (Φ, Δ, C) at T_s."""
    phi, delta, c = (np.atleast_2d(np.asarray(v, float)) for v in (phi, delta, c))
    k_int, k_err = np.atleast_2d(np.asarray(k_int, float)), np.atleast_2d(np.asarray(k_err, float))
    n, m = delta.shape
    if phi.shape != (n, n) or c.shape != (m, n) or k_int.shape != (m, m) or k_err.shape != (m, m):
        raise ValueError(f"shapes do not fit: Φ {phi.shape}, Δ {delta.shape}, C {c.shape}")
    phi_s = np.block([[phi, delta @ k_int], [np.zeros((m, n)), np.eye(m)]])     # eq. 5.12
    delta_s = np.vstack([delta @ k_err, np.eye(m)])
    c_s = np.hstack([c, np.zeros((m, m))])
    closed = phi_s - delta_s @ c_s                                               # eq. 5.14
    z = scipy.linalg.eigvals(closed)                                             # eq. 5.15
    z = z[np.argsort(-np.abs(z), kind="stable")]
    with np.errstate(divide="ignore"):  # a pole at z = 0 is infinitely fast: s = -inf
        s = np.log(z.astype(complex)) / sample_period                             # eq. 5.1
    return ClosedLoop(closed, delta_s, c_s, z, s, float(sample_period))
