"""Stochastic sea current: coupled first-order Gauss-Markov speed and direction.

Implements thesis sec. 2.4. Current speed c and direction alpha (0 along the
NED x axis, pi/2 along y; horizontal only) follow

    c(k+1)     = a_c + b c(k)     + d w_c(k)          (eq. 2.25)
    alpha(k+1) = a_a + b alpha(k) + d w_a(k)          (eq. 2.26)

    b = exp(-T_s / T_c),  d = 1 - b                   (eq. 2.27, 2.28)
    a_c = c_mean (1 - b),  a_a = alpha_mean (1 - b)   (eq. 2.29, 2.30: the
                                                       thesis's fix of [28])
    var(w_c) = [(1 - b^2)(sigma_c^2 + c_mean^2) - 2 a_c b c_mean - a_c^2] / d^2   (eq. 2.31)
    w_a = (sigma_a / sigma_c) w_c                     (eq. 2.33: fully correlated)

With eq. 2.29 the mean terms of eq. 2.31 cancel exactly, leaving
var(w_c) = (1 - b^2) sigma_c^2 / d^2: the stationary mean and standard
deviation are c_mean and sigma_c and the correlation time is T_c *for any
sample time*, so the statistics do not depend on the simulation step (unlike
generators that draw uniform noise, decay to zero, or fix the coefficients for
one step). Randomness comes only from the ``numpy.random.Generator`` passed in.

The current's velocity in NED is (c cos alpha, c sin alpha, 0); the vehicle
model turns it into body-axis relative velocities with its Euler angles
(sec. 2.4).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["CurrentParams", "CurrentCoefficients", "coefficients", "noise_power_eq_2_31",
           "GaussMarkovCurrent"]


@dataclass(frozen=True)
class CurrentParams:
    """Statistics of the current (SI: m/s, rad, s).

    The thesis's values (sec. 3.9: mean 0.26 m/s, sigma_c 0.086 m/s, mean
    direction 0, sigma_alpha 20 deg, T_c 10 s) are the ``current`` section of
    ``environment/default.yaml``, their one place
    (:func:`seapup_sim.environment_config.load_environment`).
    """

    mean_speed: float
    speed_std: float
    mean_direction: float
    direction_std: float
    break_time: float

    def __post_init__(self):
        for name in ("mean_speed", "speed_std", "mean_direction", "direction_std", "break_time"):
            value = getattr(self, name)
            if not math.isfinite(value):
                raise ValueError(f"current {name} must be finite, got {value!r}")
        if self.mean_speed < 0 or self.speed_std < 0 or self.direction_std < 0:
            raise ValueError("current mean speed and standard deviations must be >= 0")
        if self.break_time <= 0:
            raise ValueError(f"current break time must be > 0 s, got {self.break_time!r}")


@dataclass(frozen=True)
class CurrentCoefficients:
    """Discrete coefficients of eq. 2.25-2.33 for one sample time."""

    b: float
    d: float
    a_c: float
    a_alpha: float
    var_w_c: float          # E{w_c^2}, eq. 2.31
    var_w_alpha: float      # E{w_alpha^2}, eq. 2.32
    w_alpha_per_w_c: float  # sigma_alpha / sigma_c, eq. 2.33 [rad per m/s]


def coefficients(params: CurrentParams, sample_time: float) -> CurrentCoefficients:
    """The coefficients of eq. 2.27-2.33 for ``sample_time`` T_s [s].

    Examples
    --------
    The thesis's case (eq. 3.13-3.14):

    >>> c = coefficients(CurrentParams(0.26, 0.086, 0.0, math.radians(20.0), 10.0), 0.2)
    >>> round(c.b, 7), round(c.d, 7), round(c.a_c, 7)
    (0.9801987, 0.0198013, 0.0051483)
    """
    if not (math.isfinite(sample_time) and sample_time > 0):
        raise ValueError(f"current sample time must be > 0 s, got {sample_time!r}")
    p = params
    b = math.exp(-sample_time / p.break_time)
    d = 1.0 - b
    a_c = p.mean_speed * (1.0 - b)
    a_alpha = p.mean_direction * (1.0 - b)

    # eq. 2.31/2.32 with eq. 2.29/2.30 substituted: the mean terms cancel
    # exactly. Evaluating them numerically would leave rounding noise
    # (~1e-13) where sigma = 0, i.e. a "constant" current that jitters.
    def noise_power(sigma):
        return (1 - b * b) * sigma * sigma / (d * d)

    ratio = p.direction_std / p.speed_std if p.speed_std > 0 else 0.0
    return CurrentCoefficients(b, d, a_c, a_alpha, noise_power(p.speed_std),
                               noise_power(p.direction_std), ratio)


def noise_power_eq_2_31(sigma: float, mean: float, b: float) -> float:
    """E{w^2} exactly as eq. 2.31/2.32 print it (for checking the simplification)."""
    d = 1.0 - b
    a = mean * (1.0 - b)
    return ((1 - b * b) * (sigma * sigma + mean * mean) - 2 * a * b * mean - a * a) / (d * d)


class GaussMarkovCurrent:
    """A realisation of the current, advanced one sample at a time.

    Parameters
    ----------
    params : CurrentParams
    sample_time : float
        T_s [s] between :meth:`step` calls.
    rng : numpy.random.Generator
        The only source of randomness.
    start_at_mean : bool
        Start at (c_mean, alpha_mean) (default) or draw from the stationary
        distribution.
    """

    def __init__(self, params: CurrentParams, sample_time: float, rng: np.random.Generator,
                 start_at_mean: bool = True):
        if not isinstance(rng, np.random.Generator):
            raise TypeError("rng must be a numpy.random.Generator")
        self.rng = rng
        self.sample_time = float(sample_time)
        self.params = params
        self.coef = coefficients(params, self.sample_time)
        self.speed = params.mean_speed
        self.direction = params.mean_direction
        if not start_at_mean:
            z = rng.standard_normal()
            self.speed = params.mean_speed + params.speed_std * z
            self.direction = params.mean_direction + params.direction_std * z

    def set_params(self, params: CurrentParams, reset: bool = False) -> None:
        """Change the statistics (a step change in current, sec. 5.4.3); the
        state relaxes to the new mean with time constant T_c unless ``reset``."""
        self.params = params
        self.coef = coefficients(params, self.sample_time)
        if reset:
            self.speed, self.direction = params.mean_speed, params.mean_direction

    @classmethod
    def constant(cls, speed: float, direction: float, sample_time: float, rng: np.random.Generator):
        """A steady current (no noise; it starts at its mean, so T_c plays no part)."""
        return cls(CurrentParams(speed, 0.0, direction, 0.0, 1.0), sample_time, rng)

    def step(self) -> tuple[float, float]:
        """Advance one sample (eq. 2.25, 2.26, 2.33); return (speed, direction)."""
        c = self.coef
        w_c = math.sqrt(c.var_w_c) * self.rng.standard_normal() if c.var_w_c > 0 else 0.0
        w_a = c.w_alpha_per_w_c * w_c
        self.speed = c.a_c + c.b * self.speed + c.d * w_c
        self.direction = c.a_alpha + c.b * self.direction + c.d * w_a
        return self.speed, self.direction

    def velocities(self, n: int) -> np.ndarray:
        """The next ``n`` samples' velocities in NED, (n, 3): row i is :meth:`velocity_ned` before the i-th of ``n``
        calls of :meth:`step`, which are made -- the same numbers, the draws read at once (a generator's
        ``standard_normal(n)`` is its next n single draws) and the recursion in plain floats."""
        c = self.coef
        draws = (math.sqrt(c.var_w_c) * self.rng.standard_normal(n)).tolist() if c.var_w_c > 0 else [0.0] * n
        speed, direction, rows = self.speed, self.direction, []
        for w_c in draws:
            rows.append((speed * math.cos(direction), speed * math.sin(direction), 0.0))
            speed = c.a_c + c.b * speed + c.d * w_c
            direction = c.a_alpha + c.b * direction + c.d * (c.w_alpha_per_w_c * w_c)
        self.speed, self.direction = speed, direction
        return np.array(rows).reshape(n, 3)

    def velocity_ned(self) -> np.ndarray:
        """Current velocity in NED [m/s] (horizontal)."""
        return np.array([self.speed * math.cos(self.direction), self.speed * math.sin(self.direction), 0.0])

    def sample(self, n: int) -> np.ndarray:
        """``n`` further samples as an (n, 2) array of (speed, direction)."""
        out = np.empty((n, 2))
        for k in range(n):
            out[k] = self.step()
        return out
