"""Thrust allocation: generalised forces demanded of a vehicle to the commands of its N thrusters.

Thesis sec. 8.3 names the problem the Seapup never had ("ROVs which have more thrusters than controllable
outputs. The difficulty then is allocating the demands to each thruster subject to the constraints that the
power to each individual unit as well as the total power is limited") and a way around it ("a series of
single-input/single-output loops combined with a simple thruster allocation matrix"). A vehicle whose
thrusters outnumber the outputs its laws control (a BlueROV2 Heavy: eight thrusters, and the four outputs
u, v, w, r of sec. 4.2) is flown through *virtual inputs*, one generalised force per controlled output,
which this layer spreads over the thrusters.

The configuration matrix ``B`` (m x N) maps the thrusters' efforts ``f`` (each in [low_i, high_i], a
thruster's own units: thrust, or a normalised command) to the generalised forces ``tau = B f`` of the m
controlled degrees of freedom. For a demand ``tau``:

1. the weighted minimum-effort solution ``f = W^-1 B^T (B W^-1 B^T)^-1 tau`` (the weighted pseudo-inverse:
   least ``sum w_i f_i^2`` among the ``f`` with ``B f = tau``; W = diag(weights), a larger weight sparing a
   thruster); if it is within every limit, that is the allocation;
2. otherwise the thrusters beyond a limit are held there and the rest of the demand is spread over the
   others in the same way (the redistributed pseudo-inverse), until every thruster is within its limits and
   the demand met, or no free thruster can meet it;
3. a demand the thrusters cannot meet is scaled down *along its own direction*: the largest ``alpha`` in
   [0, 1] for which some ``f`` within the limits gives ``B f = alpha tau`` (a linear programme,
   ``scipy.optimize.linprog``), allocated by 1-2 at ``alpha tau``. Every output then gets the same fraction
   of what its loop asked, so the controller's decoupling is kept (clipping thrusters one by one would turn
   a surge demand into a yaw). ``alpha`` is reported, so an anti-windup can see the saturation.

The zero demand must be achievable (every ``low_i <= 0 <= high_i``), so scaling down always ends within
the limits. A vehicle with exactly as many independent thrusters as outputs (the Seapup: four blade
pitches, four outputs) needs no allocation: its laws keep their direct inputs.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["AllocationError", "Allocation", "ThrustAllocator"]

#: Relative tolerance on ``B f = tau`` and on the limits (the redistribution's arithmetic).
TOLERANCE = 1e-9


class AllocationError(ValueError):
    """A configuration or a demand the allocator cannot take (the message says why)."""


@dataclass(frozen=True)
class Allocation:
    """One allocation.

    Attributes
    ----------
    efforts : ndarray (N,)
        Each thruster's effort, within its limits.
    achieved : ndarray (m,)
        ``B efforts``: the demand, or ``scale`` times it.
    scale : float
        ``alpha``: 1 when the demand is met, less when it was scaled down along its direction.
    saturated : ndarray of bool (N,)
        Thrusters at a limit.
    """

    efforts: np.ndarray
    achieved: np.ndarray
    scale: float
    saturated: np.ndarray


def _finite(values, shape: tuple, what: str) -> np.ndarray:
    try:
        array = np.array(values, dtype=float)
    except (TypeError, ValueError):
        raise AllocationError(f"{what} must be numbers, got {str(values)[:80]}") from None
    if array.shape != shape:
        raise AllocationError(f"{what} must have shape {shape}, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise AllocationError(f"{what} must be finite, got {array.tolist()}")
    return array


class ThrustAllocator:
    """Weighted pseudo-inverse allocation with redistribution and direction-keeping saturation (module
    docstring).

    Parameters
    ----------
    configuration : array_like (m, N)
        ``B``: column i the generalised forces of thruster i at unit effort; rows the controlled outputs.
    low, high : array_like (N,)
        Each thruster's effort limits, ``low_i <= 0 <= high_i`` (a reverse weaker than the forward: a
        smaller ``-low_i``).
    weights : array_like (N,), optional
        Positive costs of each thruster's effort (default 1 each).

    Raises
    ------
    AllocationError
        On a malformed, non-finite or rank-deficient configuration (an output no thruster moves), limits
        that exclude zero or weights that are not positive.
    """

    def __init__(self, configuration, low, high, weights=None):
        B = np.array(configuration, dtype=float) if np.ndim(configuration) == 2 else None
        if B is None or B.shape[0] < 1 or B.shape[1] < B.shape[0]:
            raise AllocationError("the configuration matrix must be m x N with at least as many thrusters (N) "
                                  f"as outputs (m), got shape {np.shape(configuration)}")
        m, n = B.shape
        B = _finite(B, (m, n), "the configuration matrix")
        self.low, self.high = _finite(low, (n,), "low"), _finite(high, (n,), "high")
        if np.any(self.low > 0.0) or np.any(self.high < 0.0):
            raise AllocationError("every thruster's limits must include zero effort (low <= 0 <= high)")
        w = np.ones(n) if weights is None else _finite(weights, (n,), "weights")
        if np.any(w <= 0.0):
            raise AllocationError(f"weights must be > 0, got {w.tolist()}")
        if np.linalg.matrix_rank(B) < m:
            raise AllocationError(f"the thrusters cannot move every output independently (rank "
                                  f"{np.linalg.matrix_rank(B)} of {m}): an output no thruster combination reaches")
        self.B, self.weights = B, w
        self.m, self.n = m, n

    def _minimum_effort(self, tau: np.ndarray, free: np.ndarray) -> np.ndarray | None:
        """The least weighted effort of the ``free`` thrusters giving ``tau`` (None: they cannot)."""
        Bf = self.B[:, free]
        if Bf.shape[1] == 0 or np.linalg.matrix_rank(Bf) < self.m:
            return None
        inverse_w = 1.0 / self.weights[free]
        gram = (Bf * inverse_w) @ Bf.T
        return inverse_w * (Bf.T @ np.linalg.solve(gram, tau))

    def _redistributed(self, tau: np.ndarray) -> np.ndarray | None:
        """Steps 1-2 of the module docstring: efforts within the limits meeting ``tau``, or None."""
        f = np.zeros(self.n)
        free = np.ones(self.n, dtype=bool)
        while True:
            held = self.B[:, ~free] @ f[~free]
            part = self._minimum_effort(tau - held, free)
            if part is None:
                return None
            f[free] = part
            span = np.maximum(self.high - self.low, 1.0)
            over = free & ((f > self.high + TOLERANCE * span) | (f < self.low - TOLERANCE * span))
            if not over.any():
                return np.clip(f, self.low, self.high)
            f[over] = np.clip(f[over], self.low[over], self.high[over])
            free &= ~over

    def _largest_scale(self, tau: np.ndarray) -> tuple[float, np.ndarray]:
        """The largest alpha in [0, 1] with some f in the limits and B f = alpha tau (a linear programme), and
        such an f."""
        from scipy.optimize import linprog
        # variables (f, alpha): maximise alpha; B f - alpha tau = 0; low <= f <= high; 0 <= alpha <= 1
        cost = np.zeros(self.n + 1)
        cost[-1] = -1.0
        equality = np.hstack([self.B, -tau[:, None]])
        bounds = [*zip(self.low.tolist(), self.high.tolist()), (0.0, 1.0)]
        result = linprog(cost, A_eq=equality, b_eq=np.zeros(self.m), bounds=bounds, method="highs")
        if result.status != 0:   # alpha = 0, f = 0 is always feasible: only a solver failure lands here
            return 0.0, np.zeros(self.n)
        return float(result.x[-1]), np.clip(result.x[:-1], self.low, self.high)

    def allocate(self, demand) -> Allocation:
        """Efforts for the generalised ``demand`` (m,): met if the thrusters can, else scaled down along its
        direction (module docstring).

        Raises
        ------
        AllocationError
            On a demand of the wrong shape or not finite (nothing is allocated).
        """
        tau = _finite(demand, (self.m,), "the demand")
        scale = 1.0
        f = self._redistributed(tau)
        if f is None:
            scale, vertex = self._largest_scale(tau)
            # the least-effort efforts a hair inside that boundary, else the programme's own (a vertex)
            f = self._redistributed(scale * (1.0 - 1e-9) * tau)
            if f is None:
                f = vertex
            else:
                scale *= 1.0 - 1e-9
        span = np.maximum(self.high - self.low, 1.0)
        saturated = (((f >= self.high - TOLERANCE * span) & (self.high > 0))
                     | ((f <= self.low + TOLERANCE * span) & (self.low < 0)))
        return Allocation(f, self.B @ f, float(scale), saturated)

    def capacity(self, direction) -> float:
        """How far along ``direction`` (m,) the thrusters can push: the largest ``c`` with ``c direction``
        achievable (inf if unbounded, which limited thrusters never are)."""
        d = _finite(direction, (self.m,), "the direction")
        norm = float(np.linalg.norm(d))
        if norm == 0.0:
            raise AllocationError("the direction must not be zero")
        # a demand beyond anything the thrusters together could give, scaled down to what they can
        reach = float(np.sum(np.linalg.norm(self.B, axis=0) * np.maximum(self.high, -self.low)))
        big = 10.0 * (reach + 1.0) / norm
        return self._largest_scale(big * d)[0] * big
