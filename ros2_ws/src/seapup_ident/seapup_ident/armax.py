"""The multivariable ARMAX model in linear-regression form (thesis sec. 6.3, eq. 6.5-6.8, 6.24, 6.27).

The model of ``ny`` outputs driven by ``nu`` inputs is

    A(z^-1) y(t) = B(z^-1) u(t) + C(z^-1) e(t) + d                          (eq. 6.5, 6.27)
    A(z^-1) = I + A_1 z^-1 + ... + A_na z^-na                                (eq. 6.7, matrices ny x ny)
    B(z^-1) =     B_1 z^-1 + ... + B_nb z^-nb                                (ny x nu)
    C(z^-1) = I + C_1 z^-1 + ... + C_nc z^-nc                                (ny x ny)

and, in linear-regression form, every output shares one regressor (eq. 6.24, 6.27):

    y(t) = Theta^T phi(t) + e(t)
    phi(t) = (-y(t-1), ..., -y(t-na), u(t-1), ..., u(t-nb), e(t-1), ..., e(t-nc), 1)
    Theta^T = [A_1, ..., A_na, B_1, ..., B_nb, C_1, ..., C_nc, d]            (ny x n_params)

so each output is a SISO regression on the same data (sec. 6.3.1: "a collection of SISO
models"), with the same orders for every output. The noise terms e(t-k) are not measured:
the estimators put their residuals there (pseudo-linear regression, sec. 6.3).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

__all__ = ["OrderError", "ArmaxOrders", "ArmaxModel", "Regressor", "polynomial_roots", "is_stable"]


class OrderError(ValueError):
    """Orders or dimensions that do not make a model."""


@dataclass(frozen=True)
class ArmaxOrders:
    """Orders (na, nb, nc) and sizes of a multivariable ARMAX model (eq. 6.24).

    Parameters
    ----------
    ny, nu : int
        Numbers of outputs and inputs (>= 1).
    na, nb, nc : int
        Orders of A, B and C (na, nc >= 0; nb >= 1: B starts at z^-1).
    offset : bool
        Estimate the offset d (eq. 6.27).
    """

    ny: int
    nu: int
    na: int
    nb: int
    nc: int = 0
    offset: bool = True

    def __post_init__(self):
        for name in ("ny", "nu", "na", "nb", "nc"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or value < 0:
                raise OrderError(f"ARMAX order {name} must be an integer >= 0, got {value!r}")
        if self.ny < 1 or self.nu < 1:
            raise OrderError(f"ARMAX model needs at least one output and one input, got ny={self.ny}, nu={self.nu}")
        if self.nb < 1:
            raise OrderError(f"ARMAX order nb must be >= 1 (B starts at z^-1), got {self.nb}")

    @property
    def n_params(self) -> int:
        """Parameters per output: ny na + nu nb + ny nc (+1 for d)."""
        return self.ny * self.na + self.nu * self.nb + self.ny * self.nc + int(self.offset)

    @property
    def c_slice(self) -> slice:
        """Where the C coefficients sit in phi and in each column of Theta."""
        start = self.ny * self.na + self.nu * self.nb
        return slice(start, start + self.ny * self.nc)

    @property
    def lag(self) -> int:
        """Samples of history the regressor needs."""
        return max(self.na, self.nb, self.nc)


@dataclass
class ArmaxModel:
    """A, B, C, d of eq. 6.27 (thesis sign convention, A and C monic) and its parameter matrix.

    Attributes
    ----------
    A : ndarray (na, ny, ny)   A_1 .. A_na
    B : ndarray (nb, ny, nu)   B_1 .. B_nb
    C : ndarray (nc, ny, ny)   C_1 .. C_nc
    d : ndarray (ny,)
    """

    orders: ArmaxOrders
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    d: np.ndarray

    @classmethod
    def from_theta(cls, orders: ArmaxOrders, theta: np.ndarray) -> "ArmaxModel":
        """Unpack Theta (n_params x ny, one column per output) into the coefficient matrices."""
        o = orders
        theta = np.asarray(theta, dtype=float)
        if theta.shape != (o.n_params, o.ny):
            raise OrderError(f"Theta must be {o.n_params} x {o.ny} for {o}, got {theta.shape}")
        rows = theta.T  # (ny, n_params): row i is output i's regression
        k = 0

        def take(count: int, width: int) -> np.ndarray:
            nonlocal k
            block = rows[:, k:k + count * width].reshape(o.ny, count, width).transpose(1, 0, 2)
            k += count * width
            return block.copy()
        A, B, C = take(o.na, o.ny), take(o.nb, o.nu), take(o.nc, o.ny)
        d = rows[:, k].copy() if o.offset else np.zeros(o.ny)
        return cls(o, A, B, C, d)

    def theta(self) -> np.ndarray:
        """The parameter matrix Theta (n_params x ny) of eq. 6.24."""
        o = self.orders
        blocks = [np.concatenate(list(m), axis=1) if len(m) else np.zeros((o.ny, 0)) for m in (self.A, self.B, self.C)]
        rows = np.concatenate(blocks + ([self.d[:, None]] if o.offset else []), axis=1)
        return rows.T.copy()

    def simulate(self, u: np.ndarray, e: np.ndarray | None = None, y0: np.ndarray | None = None) -> np.ndarray:
        """Outputs of eq. 6.27 driven by ``u`` (N x nu) and noise ``e`` (N x ny, default 0), from rest.

        ``y0`` (lag x ny) sets the outputs before t = 0 (default zero); inputs and noise before t = 0 are zero.
        """
        o = self.orders
        u = np.atleast_2d(np.asarray(u, dtype=float))
        n = len(u)
        e = np.zeros((n, o.ny)) if e is None else np.asarray(e, dtype=float).reshape(n, o.ny)
        lag = max(o.lag, 1)
        y = np.zeros((n + lag, o.ny))
        if y0 is not None:
            y[:lag] = np.asarray(y0, dtype=float).reshape(lag, o.ny)
        up = np.vstack([np.zeros((lag, o.nu)), u])
        ep = np.vstack([np.zeros((lag, o.ny)), e])
        for t in range(lag, n + lag):
            value = self.d + ep[t]
            for k in range(1, o.na + 1):
                value -= self.A[k - 1] @ y[t - k]
            for k in range(1, o.nb + 1):
                value += self.B[k - 1] @ up[t - k]
            for k in range(1, o.nc + 1):
                value += self.C[k - 1] @ ep[t - k]
            y[t] = value
        return y[lag:]


class Regressor:
    """phi(t) of eq. 6.24/6.27 from the running history of outputs, inputs and residuals."""

    def __init__(self, orders: ArmaxOrders):
        self.orders = orders
        self.reset()

    def reset(self) -> None:
        o = self.orders
        self._y = np.zeros((o.na, o.ny))   # y(t-1) first
        self._u = np.zeros((o.nb, o.nu))
        self._e = np.zeros((o.nc, o.ny))

    def phi(self) -> np.ndarray:
        """The regressor for the coming sample t (from data up to t-1)."""
        parts = [-self._y.ravel(), self._u.ravel(), self._e.ravel()]
        if self.orders.offset:
            parts.append(np.ones(1))
        return np.concatenate(parts)

    def push(self, y: np.ndarray, u: np.ndarray, e: np.ndarray) -> None:
        """Shift in sample t's output, input and residual."""
        for store, value in ((self._y, y), (self._u, u), (self._e, e)):
            if len(store):
                store[1:] = store[:-1]
                store[0] = value

    def replace_residuals(self, e_history: np.ndarray) -> None:
        """Overwrite e(t-1) .. e(t-nc) (the a posteriori residuals once Theta moved)."""
        if len(self._e):
            self._e[:] = e_history


def polynomial_roots(coefficients: np.ndarray) -> np.ndarray:
    """Roots in z of det(I + M_1 z^-1 + ... + M_n z^-n) = 0 for matrices M_k (n x m x m).

    They are the eigenvalues of the block companion matrix (scipy.linalg.eigvals): a monic matrix
    polynomial is stable -- all roots strictly inside the unit circle -- exactly when this matrix is.
    """
    coefficients = np.asarray(coefficients, dtype=float)
    n = len(coefficients)
    if n == 0:
        return np.zeros(0, dtype=complex)
    m = coefficients.shape[1]
    companion = np.zeros((n * m, n * m))
    companion[:m, :] = -np.concatenate(list(coefficients), axis=1)
    companion[m:, :-m] = np.eye((n - 1) * m)
    return scipy.linalg.eigvals(companion)


def is_stable(coefficients: np.ndarray, margin: float = 0.0) -> bool:
    """True when every root of the monic matrix polynomial lies inside |z| < 1 - margin (sec. 6.3's
    stability region for C(z^-1), which the RPEM's prediction-error filter needs).

    For a first-order polynomial the roots are the eigenvalues of -M_1, whose moduli no induced norm
    exceeds: when the largest absolute row sum is already below 1 - margin the answer is yes without
    the eigenvalues (the RPEM asks at every sample; the same answer, tested against the roots)."""
    coefficients = np.asarray(coefficients, dtype=float)
    if len(coefficients) == 1 and np.abs(coefficients[0]).sum(axis=1).max() < 1.0 - margin:
        return True
    roots = polynomial_roots(coefficients)
    return bool(np.all(np.abs(roots) < 1.0 - margin)) if len(roots) else True
