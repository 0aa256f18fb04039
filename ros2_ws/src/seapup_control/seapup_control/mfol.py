"""The multivariable first-order lag (MFOL) and Owens and Chotai's two-term controller.

Thesis sec. 4.4-4.6 and 5.2-5.3 (after Owens and Chotai [48]). An unknown
stable plant with m inputs and m outputs is approximated by the MFOL

    G_A^-1(z) = (z - 1) B0 + B1,   |B0| != 0                    (eq. 4.9)

whose two matrices come from step tests: ``B0^-1`` is the response one
sample after a unit step, ``B1^-1`` the steady-state response (eq. 4.18-4.21,
4.24). For it the PI law

    K(z) = B0 diag(1 - k_j c_j + (1 - k_j)(1 - c_j) z / (z - 1)) - B1     (eq. 4.10)

realised as

    q_{k+1} = q_k + e_k
    u_k = B0 diag((1 - k_j)(1 - c_j)) q_k + (B0 diag(2 - k_j - c_j) - B1) e_k + u0   (eq. 4.11, 5.6)

puts the closed-loop poles of loop j at k_j and c_j with unit DC gain
(eq. 4.13-4.16). For the Seapup: inputs are the four blade pitches (main
port, main starboard, vectored starboard, vectored port, ``BladePitch``
order) and outputs (u, v, w, r) (eq. 4.22).

Units here are SI and radians (r in rad/s, pitches in rad); the thesis
prints B0^-1, B1^-1 with r in deg/s per degree of pitch, which
:meth:`MFOLModel.in_thesis_units` gives for comparison.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["DesignError", "MFOLModel", "LoopPoles", "TwoTermGains", "design", "equilibrated_condition",
           "THESIS_POLES_5HZ"]


class DesignError(ValueError):
    """A model or a pole choice from which no controller can be designed (the reason says why)."""


def _matrix(value, shape, what: str) -> np.ndarray:
    arr = np.array(value, dtype=float)
    if arr.shape != shape:
        raise DesignError(f"{what} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise DesignError(f"{what} must be finite")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class MFOLModel:
    """The MFOL of eq. 4.9 about an operating point, from its inverse matrices.

    Parameters
    ----------
    B0inv : array_like, shape (m, m)
        Response at t = T_s to unit steps (column j: input j) (eq. 4.18, 4.20, 4.24a).
    B1inv : array_like, shape (m, m)
        Steady-state response to unit steps (eq. 4.19, 4.21, 4.24b).
    sample_period : float
        T_s [s] the model was identified at.
    y0, u0 : array_like, shape (m,)
        Operating point: outputs and the inputs that hold them (eq. 5.4-5.5;
        the quiescent setting u0 of eq. 5.2 at zero speed).

    Raises
    ------
    DesignError
        If a matrix is not square and finite, or B0^-1 or B1^-1 is singular
        (|B0| != 0 in eq. 4.9; B1 needs B1^-1 invertible).
    """

    B0inv: np.ndarray
    B1inv: np.ndarray
    sample_period: float
    y0: np.ndarray = None
    u0: np.ndarray = None
    B0: np.ndarray = field(init=False, repr=False)
    B1: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        b0inv = np.array(self.B0inv, dtype=float)
        m = b0inv.shape[0] if b0inv.ndim == 2 else 0
        set_ = object.__setattr__
        set_(self, "B0inv", _matrix(b0inv, (m, m), "B0^-1"))
        set_(self, "B1inv", _matrix(self.B1inv, (m, m), "B1^-1"))
        if not (math.isfinite(self.sample_period) and self.sample_period > 0):
            raise DesignError(f"sample_period must be > 0 s, got {self.sample_period!r}")
        set_(self, "y0", _matrix(np.zeros(m) if self.y0 is None else self.y0, (m,), "y0"))
        set_(self, "u0", _matrix(np.zeros(m) if self.u0 is None else self.u0, (m,), "u0"))
        set_(self, "B0", _inverse(self.B0inv, "B0^-1 (the initial responses)"))
        set_(self, "B1", _inverse(self.B1inv, "B1^-1 (the steady-state responses)"))

    @property
    def size(self) -> int:
        return self.B0inv.shape[0]

    @classmethod
    def from_responses(cls, first, final, steps, sample_period: float, y0=None, u0=None) -> "MFOLModel":
        """The MFOL from m step tests (eq. 4.20-4.21).

        Parameters
        ----------
        first, final : array_like, shape (m, m)
            Column j: the output deviations one sample after test j's step, and
            their steady-state values.
        steps : array_like, shape (m, m)
            Column j: test j's input step; the columns must span the input space.
        """
        steps = np.array(steps, dtype=float)
        m = steps.shape[0]
        steps_inv = _inverse(_matrix(steps, (m, m), "step inputs"), "the step inputs (they must span the inputs)")
        return cls(_matrix(first, (m, m), "first responses") @ steps_inv,
                   _matrix(final, (m, m), "final responses") @ steps_inv, sample_period, y0, u0)

    @classmethod
    def from_state_space(cls, phi, delta, c, sample_period: float, y0=None, u0=None) -> "MFOLModel":
        """The exact MFOL matrices of a known discrete model x+ = Φx + Δu, y = Cx (eq. 4.18-4.19).

        ``B0^-1 = C Δ`` and ``B1^-1 = C (I - Φ)^-1 Δ``.
        """
        phi, delta, c = (np.asarray(a, dtype=float) for a in (phi, delta, c))
        n = phi.shape[0]
        try:
            dc = c @ np.linalg.solve(np.eye(n) - phi, delta)
        except np.linalg.LinAlgError:
            raise DesignError("I - Φ is singular: the plant has a pole at z = 1, no steady-state gain") from None
        return cls(c @ delta, dc, sample_period, y0, u0)

    def in_thesis_units(self, yaw_row: int = 3) -> tuple[np.ndarray, np.ndarray]:
        """(B0^-1, B1^-1) with outputs in m/s and deg/s per degree of pitch, as eq. 5.3 and 5.7 print them."""
        scale = np.full(self.size, math.pi / 180.0)  # m/s per rad -> m/s per deg
        scale[yaw_row] = 1.0                          # rad/s per rad == deg/s per deg
        return self.B0inv * scale[:, None], self.B1inv * scale[:, None]


def equilibrated_condition(matrix) -> tuple[float, int]:
    """Condition number of a response matrix with each output row scaled to a largest entry of 1.

    The rows of B0^-1 and B1^-1 mix units (m/s and rad/s per rad), so the
    plain condition number depends on the units chosen; scaling every row
    by its largest magnitude (row equilibration, van der Sluis) removes that
    and leaves how nearly dependent the *inputs'* effects are. A column that
    is small in every scaled row is an input that moves nothing: a dead or
    disconnected thruster.

    Returns
    -------
    condition : float
        inf for a zero row or a singular matrix.
    weakest : int
        Index of the column with the smallest largest scaled entry.

    Examples
    --------
    >>> c, j = equilibrated_condition([[1.0, 0.0], [0.0, 1e-3]])   # units differ: well conditioned
    >>> round(c, 6), j
    (1.0, 0)
    >>> c, j = equilibrated_condition([[1.0, 0.01], [1.0, 0.02]])  # input 1 barely moves anything
    >>> round(c), j
    (200, 1)
    """
    m = np.abs(np.asarray(matrix, dtype=float))
    scale = m.max(axis=1, keepdims=True)
    if not np.all(np.isfinite(m)) or np.any(scale == 0.0):
        return math.inf, int(np.argmin(m.max(axis=0))) if np.all(np.isfinite(m)) else 0
    scaled = np.asarray(matrix, dtype=float) / scale
    return float(np.linalg.cond(scaled)), int(np.argmin(np.abs(scaled).max(axis=0)))


def _inverse(matrix: np.ndarray, what: str) -> np.ndarray:
    cond = np.linalg.cond(matrix)
    if not np.isfinite(cond) or cond > 1e12:
        raise DesignError(f"{what} is singular (condition number {cond:.3g}): no controller can be designed")
    inv = np.linalg.inv(matrix)
    inv.setflags(write=False)
    return inv


@dataclass(frozen=True)
class LoopPoles:
    """Desired discrete closed-loop poles k_j, c_j of each loop (eq. 4.10, 4.16).

    Raises
    ------
    DesignError
        Unless every |k_j| < 1 and |c_j| < 1 (eq. 4.16) and they are real.
    """

    k: np.ndarray
    c: np.ndarray
    sample_period: float

    def __post_init__(self):
        k = np.array(self.k, dtype=float).reshape(-1)
        c = np.array(self.c, dtype=float).reshape(-1)
        if k.shape != c.shape or k.size == 0:
            raise DesignError(f"k and c need one value per loop, got {k.size} and {c.size}")
        if not (np.all(np.isfinite(k)) and np.all(np.isfinite(c))):
            raise DesignError("k and c must be finite")
        bad = [j for j in range(k.size) if not (abs(k[j]) < 1 and abs(c[j]) < 1)]
        if bad:
            raise DesignError(f"|k_j| < 1 and |c_j| < 1 (eq. 4.16) fail for loop(s) {bad}: "
                              f"k = {k.tolist()}, c = {c.tolist()}")
        if not (math.isfinite(self.sample_period) and self.sample_period > 0):
            raise DesignError(f"sample_period must be > 0 s, got {self.sample_period!r}")
        for name, value in (("k", k), ("c", c)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    def continuous(self) -> tuple[np.ndarray, np.ndarray]:
        """The s-plane poles they stand for: ``s = ln(z) / T_s`` (eq. 5.1; complex for z < 0)."""
        return (np.log(self.k.astype(complex)) / self.sample_period,
                np.log(self.c.astype(complex)) / self.sample_period)

    def at_rate(self, sample_period: float) -> "LoopPoles":
        """The same continuous-time poles at another sample period: ``z' = z^(T'/T)`` (eq. 5.1).

        Sec. 5.2 maps the 5 Hz choice to 20 Hz this way (0.8 -> 0.94574).

        Raises
        ------
        DesignError
            For a negative pole (it has no real counterpart at another rate).
        """
        if np.any(self.k <= 0) or np.any(self.c <= 0):
            raise DesignError("only positive real poles map to another rate as real poles")
        ratio = sample_period / self.sample_period
        return LoopPoles(self.k ** ratio, self.c ** ratio, sample_period)


#: Sec. 5.2's closed-loop poles at T_s = 0.2 s (loops u, v, w, r); k_j = c_j.
THESIS_POLES_5HZ = LoopPoles([0.8, 0.85, 0.75, 0.65], [0.8, 0.85, 0.75, 0.65], 0.2)


@dataclass(frozen=True)
class TwoTermGains:
    """The matrices of eq. 4.11 / 5.6 for one operating point.

    ``u_k = K_int q_k + K_err e_k + u0`` with ``q_{k+1} = q_k + e_k``.
    """

    K_int: np.ndarray
    K_err: np.ndarray
    u0: np.ndarray
    y0: np.ndarray
    sample_period: float


def design(model: MFOLModel, poles: LoopPoles) -> TwoTermGains:
    """Owens and Chotai's two-term controller for an MFOL model (eq. 4.10-4.11, 5.6).

    .. math::
        K_{int} = B_0 \\operatorname{diag}((1-k_j)(1-c_j)), \\quad
        K_{err} = B_0 \\operatorname{diag}(2-k_j-c_j) - B_1

    Notes
    -----
    Eq. 5.6 (the law about a non-zero operating point) omits the ``- B1`` of
    eq. 4.11; with it the poles of an exact MFOL plant are exactly k_j and c_j
    (eq. 4.13 with the plant's own B0^-1 B1), so it is kept at every point.

    Raises
    ------
    DesignError
        If the model and the poles disagree on the number of loops or the sample period.
    """
    if poles.k.size != model.size:
        raise DesignError(f"{poles.k.size} loop poles for a {model.size}-loop model")
    if not math.isclose(poles.sample_period, model.sample_period, rel_tol=1e-9):
        raise DesignError(f"poles for T_s = {poles.sample_period} s, model identified at {model.sample_period} s: "
                          "map the poles with LoopPoles.at_rate or identify at the controller's rate")
    k_int = model.B0 @ np.diag((1.0 - poles.k) * (1.0 - poles.c))
    k_err = model.B0 @ np.diag(2.0 - poles.k - poles.c) - model.B1
    return TwoTermGains(k_int, k_err, model.u0.copy(), model.y0.copy(), model.sample_period)
