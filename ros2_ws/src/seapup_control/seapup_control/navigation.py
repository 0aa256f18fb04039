"""Navigation: where the vehicle is, from the instruments the thesis lists (sec. 1.3).

The global position controller needs a position estimate at every control
sample, but the only absolute position sensor is an acoustic fix: slow (at
most 1 Hz), noisy ("a large fraction of a metre") and subject to drop-outs
(sec. 1.3). Dead reckoning -- the doppler log's body velocity rotated into
the world frame with the attitude (eq. 2.1) and integrated -- is smooth and
fast but drifts. A linear Kalman filter fuses the two, with the depth gauge
as a third, precise measurement of z.

State and model (sample period T, world frame ``odom_ned``)::

    x_k = (x, y, z)_k                                   position of the body origin [m]
    x_{k+1} = x_k + T R(phi, theta, psi)_k v_k + n_k    v_k = (u, v, w) from the log (eq. 2.1), held over the sample
    Q_k = T^2 R Sigma_v R^T + q_walk T I                log noise + model error (attitude noise,
                                                        the velocity's change within a sample)
    fix:    y = x + e_fix,   Var e_fix = diag(sigma_fix^2)     when a fix is valid
    depth:  y = z + e_depth, Var e_depth = sigma_depth^2       every sample

The filter is linear (R is known from the attitude measurement each sample),
so it is the standard predict/update (Kalman 1960) in Joseph form. A fix
whose normalised innovation squared exceeds the chi-square quantile
``gate_probability`` for 3 degrees of freedom (:func:`chi2_quantile`) is an
outlier (multipath, sec. 1.3): rejected and counted, never fused. A missing
velocity reading makes the prediction hold the last velocity with the
process noise inflated by ``coast_inflation``.

Faults are not data: a velocity beyond ``max_speed`` is treated as a lost
log reading (the prediction coasts), a depth outside ``depth_range`` or whose
innovation fails the 1-dof chi-square gate is rejected and counted. And the
filter recovers from a divergence instead of gating out every true fix
forever: ``reacquire_after`` rejected fixes in a row that agree with each
other (their innovations all within ``4 fix_std`` of their mean: the fixes are
consistent, the estimate is not, which sporadic multipath never is)
re-initialise the position at the latest fix (``reacquisitions`` counted).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import special

from seapup_common.contract import ContractError, Measurement, NavigationEstimate
from seapup_common.frames import rotation_body_to_ned
from seapup_common.kernels import numba_installed

__all__ = ["NavigatorParams", "Navigator", "SHELL_PARAMETERS", "chi2_quantile"]


def chi2_quantile(probability: float, dof: int) -> float:
    """The chi-square quantile: ``scipy.stats.chi2.ppf(probability, dof)``, computed as scipy.stats computes it
    (twice the inverse regularised lower incomplete gamma function at ``dof / 2``) from ``scipy.special``, whose
    import costs a node a fraction of ``scipy.stats``' (about 0.3 s of CPU against 0.9 s at each navigator start)."""
    return float(2.0 * special.gammaincinv(dof / 2.0, probability))

#: Keys of ``config/navigator.yaml`` that belong to the node shell (when a sample is complete), not to
#: the filter: :meth:`NavigatorParams.from_mapping` takes the rest.
SHELL_PARAMETERS = ("sample_topics", "manifest_patience")


@dataclass(frozen=True)
class NavigatorParams:
    """Tuning of :class:`Navigator` (YAML: ``seapup_control/config/navigator.yaml``).

    Parameters
    ----------
    q_walk : float
        Position random-walk intensity [m^2/s] (model error beyond the log's white noise).
    velocity_std : tuple of 3 float
        Doppler-log noise [m/s] used when a reading carries no variance (0 = unknown).
    fix_std : float
        Acoustic-fix noise [m] used when a fix carries no variance.
    depth_std : float
        Depth-gauge noise [m] used when a reading carries no variance.
    initial_std : float
        Standard deviation [m] of the first estimate (from the first fix or depth).
    gate_probability : float
        Fixes beyond this chi-square quantile (3 dof) of the innovation are rejected; 1 = no gate.
    coast_inflation : float
        Process-noise factor while the velocity log is lost.
    max_speed : float
        [m/s] A log reading faster than this is a fault: the prediction coasts on the last good one.
    depth_range : tuple of 2 float
        [m] Depth readings outside are faults, never fused.
    reacquire_after : int
        Consistent rejected fixes in a row that re-initialise the position (0: never).
    """

    q_walk: float = 1e-4
    velocity_std: tuple = (0.0034, 0.0034, 0.0034)
    fix_std: float = 0.5
    depth_std: float = 0.05
    initial_std: float = 2.0
    gate_probability: float = 0.9999
    coast_inflation: float = 100.0
    max_speed: float = 5.0
    depth_range: tuple = (-10.0, 11000.0)
    reacquire_after: int = 5

    def __post_init__(self):
        values = [self.q_walk, *self.velocity_std, self.fix_std, self.depth_std, self.initial_std]
        if len(self.velocity_std) != 3 or not all(math.isfinite(v) and v >= 0 for v in values):
            raise ValueError(f"navigator: q_walk, velocity_std (3), fix_std, depth_std, initial_std must be "
                             f"finite and >= 0, got {values}")
        if self.fix_std <= 0 or self.depth_std <= 0 or self.initial_std <= 0:
            raise ValueError("navigator: fix_std, depth_std and initial_std must be > 0")
        if not 0 < self.gate_probability <= 1 or self.coast_inflation < 1:
            raise ValueError(f"navigator: gate_probability in (0, 1] and coast_inflation >= 1, got "
                             f"{self.gate_probability}, {self.coast_inflation}")
        if not (math.isfinite(self.max_speed) and self.max_speed > 0 and len(self.depth_range) == 2
                and self.depth_range[0] < self.depth_range[1] and int(self.reacquire_after) >= 0):
            raise ValueError(f"navigator: max_speed > 0, depth_range (lo < hi), reacquire_after >= 0, got "
                             f"{self.max_speed}, {self.depth_range}, {self.reacquire_after}")

    @classmethod
    def from_mapping(cls, mapping: dict) -> "NavigatorParams":
        known = {k: mapping[k] for k in cls.__dataclass_fields__ if k in mapping}
        unknown = set(mapping) - set(known)
        if unknown:
            raise ValueError(f"navigator: unknown parameter(s) {sorted(unknown)}")
        for name in ("velocity_std", "depth_range"):
            if name in known:
                known[name] = tuple(float(v) for v in known[name])
        return cls(**known)


class Navigator:
    """Linear Kalman filter of the module docstring: dead reckoning corrected by fixes and depth.

    Feed it one :class:`~seapup_common.contract.Measurement` per control
    sample with :meth:`update`; it returns the estimate, or None until it
    has an attitude and a first position (a fix; until then nothing is
    known about x, y).

    Parameters
    ----------
    params : NavigatorParams
    compiled : bool, optional
        The prediction and the updates by the compiled kernels of :mod:`seapup_control.compiled` (default:
        when numba is installed) or by the NumPy reference (False); the two agree to rounding.
    """

    def __init__(self, params: NavigatorParams | None = None, compiled: bool | None = None):
        self.params = params or NavigatorParams()
        self.kernels = None
        if numba_installed() if compiled is None else compiled:   # loaded now (from numba's cache), not at the first sample
            from seapup_control import compiled as kernels
            self.kernels = kernels
        self.chi2_gate = (math.inf if self.params.gate_probability >= 1
                          else chi2_quantile(self.params.gate_probability, 3))
        self.chi2_gate_depth = (math.inf if self.params.gate_probability >= 1
                                else chi2_quantile(self.params.gate_probability, 1))
        self.reset()

    def reset(self) -> None:
        """Forget everything (the next fix starts the filter again)."""
        self.x: np.ndarray | None = None
        self.P: np.ndarray | None = None
        self.t: float | None = None
        self.velocity = np.zeros(3)
        self.rates = np.zeros(3)
        self.attitude: np.ndarray | None = None
        self._velocity_lost = False
        self._velocity_variance = np.asarray(self.params.velocity_std, dtype=float) ** 2
        self.counts = {"samples": 0, "fixes_fused": 0, "fixes_rejected": 0, "depths_fused": 0,
                       "depths_rejected": 0, "velocities_rejected": 0, "reacquisitions": 0,
                       "coasting_samples": 0, "rejected_samples": 0}
        self._rejected_innovations: list[np.ndarray] = []  # of the rejected fixes in a row
        self._last_fix_stamp = -math.inf
        self._last_depth_stamp = -math.inf
        self._variances: dict = {}   # (a float variance or a read-only one's id, the default's id) -> (it, result, default)

    # -- the filter ------------------------------------------------------------------------
    def _predict(self, dt: float, velocity_variance: np.ndarray, coasting: bool) -> None:
        if self.kernels is not None:
            self.kernels.predict(self.x, self.P, self.attitude, self.velocity, velocity_variance, float(dt),
                                 float(self.params.q_walk), float(self.params.coast_inflation) if coasting else 1.0)
            return
        R = rotation_body_to_ned(*self.attitude)
        self.x = self.x + dt * (R @ self.velocity)
        # R diag(var) R^T, the diagonal product as a column scaling (the same products, without the zeros)
        Q = dt * dt * R * velocity_variance @ R.T + self.params.q_walk * dt * np.eye(3)
        self.P = self.P + (self.params.coast_inflation * Q if coasting else Q)

    def _fuse(self, H: np.ndarray, y: np.ndarray, Rm: np.ndarray, gate: float) -> bool:
        innovation = y - H @ self.x
        S = H @ self.P @ H.T + Rm
        if float(innovation @ np.linalg.solve(S, innovation)) > gate:
            return False
        K = np.linalg.solve(S, H @ self.P).T
        self._update(K, np.eye(3) - K @ H, K @ innovation, Rm)
        return True

    def _update(self, K: np.ndarray, I_KH: np.ndarray, correction: np.ndarray, Rm: np.ndarray) -> None:
        """x += K innovation; P in Joseph form (stays symmetric positive definite)."""
        self.x = self.x + correction
        self.P = I_KH @ self.P @ I_KH.T + K @ Rm @ K.T
        self.P = 0.5 * (self.P + self.P.T)

    def _fuse_component(self, index: int, y: float, variance: float, gate: float) -> bool:
        """:meth:`_fuse` of one position component measured (H the unit row ``index``, S a scalar): the same
        arithmetic as the matrix form (the innovation test y S^-1 y, K = P H^T S^-1, the Joseph update),
        without its solves (LAPACK's solve of one equation divides, and multiplies several right-hand sides
        by 1 / S)."""
        if self.kernels is not None:
            return bool(self.kernels.fuse_component(self.x, self.P, index, float(y), float(variance), float(gate)))
        innovation = y - float(self.x[index])
        s = float(self.P[index, index]) + variance
        if innovation * (innovation / s) > gate:
            return False
        K = (self.P[index] * (1.0 / s)).reshape(3, 1)
        I_KH = np.eye(3)
        I_KH[:, index] -= K[:, 0]
        self._update(K, I_KH, K[:, 0] * innovation, np.array([[variance]]))
        return True

    def _variance(self, reading, default_std) -> np.ndarray:
        """The reading's variance, each component not stated (0) the default's square. One that cannot change --
        a float, or a read-only array that owns its data (a sensor suite's, the same every sample) -- is worked out
        once per default (the filter never writes the result)."""
        given = reading.variance
        if isinstance(given, float):
            key = (given, id(default_std))
        elif isinstance(given, np.ndarray) and not given.flags.writeable and given.base is None:   # owns its data
            key = (id(given), id(default_std))
        else:
            key = None
        if key is not None:
            known = self._variances.get(key)
            if known is not None and known[2] is default_std and (known[0] is given or isinstance(given, float)):
                return known[1]
        var = np.atleast_1d(np.asarray(given, dtype=float))
        if (var > 0).all():   # every component stated (the usual case): the reading's own
            var = var.copy()
        else:
            default = np.broadcast_to(np.asarray(default_std, dtype=float) ** 2, var.shape)
            var = np.where(var > 0, var, default)
        if key is not None:
            if len(self._variances) >= 16:
                self._variances.clear()
            self._variances[key] = (given, var, default_std)   # both kept: their ids stay theirs
        return var

    def update(self, measurement: Measurement) -> NavigationEstimate | None:
        """Advance to ``measurement.t`` and fuse what it holds; the estimate (None until initialised).

        Raises
        ------
        ContractError
            If the measurement's time goes backwards (nothing changes).
        """
        t = float(measurement.t)
        if self.t is not None and t < self.t - 1e-9:
            self.counts["rejected_samples"] += 1
            raise ContractError(f"navigation sample at t = {t:.3f} s is before the last one ({self.t:.3f} s)")
        # dead reckoning over [t_prev, t] with the readings of t_prev (held, like the log's output)
        coasting = self._velocity_lost
        if self.x is not None and self.t is not None and self.attitude is not None:
            self._predict(t - self.t, self._velocity_variance, coasting)
            self.counts["coasting_samples"] += int(coasting)
        if measurement.attitude.valid:
            self.attitude = np.array(measurement.attitude.value, dtype=float)
        self._velocity_lost = not measurement.velocity.valid
        velocity = measurement.velocity.value
        if not self._velocity_lost and not math.sqrt(velocity.dot(velocity)) <= self.params.max_speed:
            self._velocity_lost = True  # a fault, not a velocity: coast on the last good one
            self.counts["velocities_rejected"] += 1
        if not self._velocity_lost:
            self.velocity = np.array(measurement.velocity.value, dtype=float)
            self._velocity_variance = self._variance(measurement.velocity, self.params.velocity_std)
        if measurement.rates.valid:
            self.rates = np.array(measurement.rates.value, dtype=float)
        if self.attitude is None:
            return None
        self.t = t
        self.counts["samples"] += 1
        self._take_fix(measurement)
        self._take_depth(measurement)
        return self.estimate()

    def _take_fix(self, measurement: Measurement) -> None:
        fix = measurement.position
        if not fix.valid or fix.stamp <= self._last_fix_stamp:
            return
        self._last_fix_stamp = fix.stamp
        variance = self._variance(fix, self.params.fix_std)
        if self.x is None:  # the first fix starts the filter
            self.x = np.array(fix.value, dtype=float)
            self.P = np.diag(np.maximum(variance, self.params.initial_std ** 2))
            self.counts["fixes_fused"] += 1
            return
        y = np.asarray(fix.value, float)
        if (self.kernels.fuse_fix(self.x, self.P, y, variance, float(self.chi2_gate)) if self.kernels is not None
                else self._fuse(np.eye(3), y, np.diag(variance), self.chi2_gate)):
            self.counts["fixes_fused"] += 1
            self._rejected_innovations = []
            return
        self.counts["fixes_rejected"] += 1
        self._rejected_innovations.append(y - self.x)
        n = int(self.params.reacquire_after)
        recent = np.array(self._rejected_innovations[-n:]) if n else np.zeros((0, 3))
        if n and len(recent) == n and np.all(np.linalg.norm(recent - recent.mean(axis=0), axis=1)
                                             <= 4.0 * math.sqrt(float(np.max(variance)))):
            # the fixes agree with each other, not with the estimate: the estimate diverged
            self.x = y.copy()
            self.P = np.diag(np.maximum(variance, self.params.initial_std ** 2))
            self.counts["reacquisitions"] += 1
            self._rejected_innovations = []

    def _take_depth(self, measurement: Measurement) -> None:
        depth = measurement.depth
        if self.x is None or not depth.valid or depth.stamp <= self._last_depth_stamp:
            return
        self._last_depth_stamp = depth.stamp
        variance = self._variance(depth, self.params.depth_std)
        lo, hi = self.params.depth_range
        if lo <= float(depth.value) <= hi and self._fuse_component(2, float(depth.value), float(variance[0]),
                                                                   self.chi2_gate_depth):
            self.counts["depths_fused"] += 1
        else:
            self.counts["depths_rejected"] += 1

    def estimate(self) -> NavigationEstimate | None:
        """The present estimate (None before the first fix or attitude)."""
        if self.x is None or self.attitude is None:
            return None
        return NavigationEstimate(self.t, self.x.copy(), self.P.copy(), self.attitude.copy(),
                                  self.velocity.copy(), self.rates.copy())
