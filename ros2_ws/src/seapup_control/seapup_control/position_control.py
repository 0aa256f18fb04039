"""The global position controller: the middle level of the thesis's supervisory hierarchy (sec. 4.2, fig. 4.3).

"The global position controller, using the ROV's Euler angles as a feedback
signal, will convert a global position error into a body coordinate position
error and demand local velocities to reduce this error" (sec. 4.2); "these
velocity references ... should take the vehicle's capabilities into account"
(sec. 8.2). At each sample::

    e_ned  = p_ref - p_hat                                   (odom_ned)
    e_body = R(phi, theta, psi)^T e_ned                      (eq. 2.1 inverted: R is orthonormal)
    v_ff   = R^T dp_ref/dt                                   (a moving setpoint's own velocity)
    (u, v, w) = K_p e_body + v_ff,  (u, v) scaled down together until both are within their speed
                                    limits, w clipped to its own
    r      = k_psi wrap(psi_ref - psi_hat) + dpsi_ref/dt,    within the yaw-rate limit

and each reference changes by at most its acceleration limit times T from
one sample to the next, so a large step of the setpoint never drives the
thrusters into saturation (sec. 8.3: "thruster saturation was avoided by ...
limiting the reference velocities' magnitudes"). Scaling the horizontal
pair, not clipping each axis, keeps the horizontal direction of travel: the
vehicle still heads for the setpoint. Heave is limited on its own: depth and
height over the seabed come first, so a climb is never slowed because the
surge demand sits at its limit (seabed following at full speed up a 1 in 5
slope kept 0.4 m of altitude error when the whole vector was scaled). ``wrap``
takes the short way round (yaw 350 deg -> 10 deg turns 20 deg, not 340).

The setpoint's rate comes from successive stamped setpoints (a task
controller that moves the setpoint along a line produces a steady rate); a
jump faster than the speed limits is a step, not a trajectory, and gives no
feed-forward.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from seapup_common.contract import ContractError, Reference
from seapup_common.frames import wrap_angle
from seapup_common.kernels import compiled_by_default

__all__ = ["PositionControllerParams", "PoseReference", "PositionController"]


@dataclass(frozen=True)
class PositionControllerParams:
    """Gains and the velocity loop's capabilities (YAML: ``config/position_controller.yaml``).

    Parameters
    ----------
    gains : tuple of 3 float
        K_p for the body-frame position error (x, y, z) [1/s].
    yaw_gain : float
        k_psi [1/s].
    speed_limits : tuple of 3 float
        Largest |u|, |v|, |w| references [m/s].
    max_yaw_rate : float
        Largest |r| reference [rad/s].
    acceleration_limits : tuple of 4 float
        Largest change of u, v, w [m/s^2] and r [rad/s^2] references per second.
    feedforward : bool
        Add the setpoint's own velocity.
    """

    gains: tuple = (0.2, 0.2, 0.3)
    yaw_gain: float = 0.5
    speed_limits: tuple = (0.3, 0.15, 0.15)
    max_yaw_rate: float = 0.26
    acceleration_limits: tuple = (0.05, 0.05, 0.05, 0.1)
    feedforward: bool = True

    def __post_init__(self):
        vectors = {"gains": (self.gains, 3), "speed_limits": (self.speed_limits, 3),
                   "acceleration_limits": (self.acceleration_limits, 4)}
        for name, (value, n) in vectors.items():
            if len(value) != n or not all(math.isfinite(float(v)) and float(v) > 0 for v in value):
                raise ValueError(f"position controller: {name} needs {n} finite values > 0, got {list(value)}")
            object.__setattr__(self, name, tuple(float(v) for v in value))
        for name in ("yaw_gain", "max_yaw_rate"):
            value = float(getattr(self, name))
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"position controller: {name} must be finite and > 0, got {value}")

    @classmethod
    def from_mapping(cls, mapping: dict) -> "PositionControllerParams":
        unknown = set(mapping) - set(cls.__dataclass_fields__)
        if unknown:
            raise ValueError(f"position controller: unknown parameter(s) {sorted(unknown)}")
        return cls(**mapping)


@dataclass(frozen=True)
class PoseReference:
    """A setpoint: position (x, y, z) [m] in odom_ned and yaw [rad], in force from time ``t`` [s]."""

    position: np.ndarray
    yaw: float
    t: float = 0.0

    def __init__(self, position, yaw: float, t: float = 0.0):
        # the frozen fields written into the dict (as seapup_common.contract.Reading's), checked first
        checked = np.array(position, dtype=float)
        if checked.shape != (3,) or not all(map(math.isfinite, checked.tolist())):
            raise ContractError(f"pose reference position needs 3 finite values, got {position!r}")
        if not math.isfinite(float(yaw)) or not math.isfinite(float(t)):
            raise ContractError(f"pose reference yaw and time must be finite, got {yaw!r}, {t!r}")
        checked.setflags(write=False)
        d = self.__dict__
        d["position"], d["yaw"], d["t"] = checked, float(yaw), t


class PositionController:
    """Pose error to body-velocity references (module docstring); pure, one call per sample.

    Parameters
    ----------
    params : PositionControllerParams
    sample_period : float
        T [s] of the velocity loop it feeds.
    compiled : bool, optional
        The sample by the compiled kernel (:func:`seapup_control.compiled.position_sample`) or in plain floats
        (False); default :func:`seapup_common.kernels.compiled_by_default`. The same numbers (tested).
    """

    def __init__(self, params: PositionControllerParams, sample_period: float, compiled: bool | None = None):
        if not (math.isfinite(sample_period) and sample_period > 0):
            raise ValueError(f"sample period must be finite and > 0 s, got {sample_period!r}")
        self.params = params
        self.sample_period = float(sample_period)
        self.reference: PoseReference | None = None
        self._feedforward = np.zeros(4)  # (dx, dy, dz [m/s] odom_ned, dpsi [rad/s])
        self.kernel = None   # seapup_control.compiled.position_sample, or None: the reference below
        if compiled_by_default() if compiled is None else compiled:
            from seapup_control.compiled import position_sample
            self.kernel = position_sample
            self._tables = tuple(np.array(v, dtype=float) for v in (params.gains, params.speed_limits))
            self._scalars = (float(params.yaw_gain), float(params.max_yaw_rate))
            self._acceleration = np.array(params.acceleration_limits, dtype=float)
        self.reset()

    def reset(self, velocity_reference=None) -> None:
        """Start again from the body-velocity reference in force (zero by default): the slew limit starts there."""
        self.last = np.zeros(4) if velocity_reference is None else np.array(velocity_reference, dtype=float)
        self.limited = np.zeros(4, dtype=bool)

    def set_reference(self, reference: PoseReference) -> None:
        """A new setpoint; its rate from the previous one becomes the feed-forward (if a trajectory)."""
        previous = self.reference
        self.reference = reference
        self._feedforward = np.zeros(4)
        if previous is None or not self.params.feedforward:
            return
        dt = reference.t - previous.t
        if dt <= 1e-9:
            return
        (x, y, z), (x0, y0, z0) = reference.position.tolist(), previous.position.tolist()
        rate = ((x - x0) / dt, (y - y0) / dt, (z - z0) / dt, wrap_angle(reference.yaw - previous.yaw) / dt)
        p = self.params
        horizontal = math.hypot(rate[0], rate[1])
        if horizontal <= max(p.speed_limits[:2]) and abs(rate[2]) <= p.speed_limits[2] \
                and abs(rate[3]) <= p.max_yaw_rate:
            self._feedforward = np.array(rate)  # a trajectory, not a step

    def update(self, position, attitude) -> Reference:
        """Body-velocity reference (u, v, w, r) for the estimated ``position`` (odom_ned) and ``attitude``.

        Without a setpoint the reference is zero (hold velocity zero). Plain floats for the 3-vectors (a
        sample's dozen small numpy operations cost more than the arithmetic); the products R^T e are summed
        in index order.
        """
        position = np.asarray(position, dtype=float)
        attitude = np.asarray(attitude, dtype=float)
        if position.shape != (3,) or attitude.shape != (3,) or not all(map(math.isfinite,
                                                                           [*position.tolist(), *attitude.tolist()])):
            raise ContractError(f"position controller needs a finite position (3) and attitude (3), got "
                                f"{position.tolist()}, {attitude.tolist()}")
        if self.kernel is not None:   # the same arithmetic compiled (seapup_control.compiled.position_sample)
            reference = self.reference
            rx, ry, rz = (0.0, 0.0, 0.0) if reference is None else reference.position.tolist()
            out, limited = np.empty(4), np.empty(4, dtype=bool)
            self.kernel(*position.tolist(), *attitude.tolist(), reference is not None, rx, ry, rz,
                        0.0 if reference is None else reference.yaw, self._feedforward, *self._tables,
                        *self._scalars, self._acceleration, self.sample_period, self.last, out, limited)
            self.last, self.limited = out, limited
            return Reference(out)
        p = self.params
        if self.reference is None:
            wanted = (0.0, 0.0, 0.0, 0.0)
        else:
            phi, theta, psi = attitude.tolist()
            x, y, z = position.tolist()
            rx, ry, rz = self.reference.position.tolist()
            fx, fy, fz, fr = self._feedforward.tolist()
            # R of eq. 2.1 (frames.rotation_body_to_ned's products, in floats)
            cf, sf, ct, st = math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta)
            cp, sp = math.cos(psi), math.sin(psi)
            r00, r01, r02 = cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf
            r10, r11, r12 = sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf
            r20, r21, r22 = -st, ct * sf, ct * cf
            c0, c1, c2 = (r00, r10, r20), (r01, r11, r21), (r02, r12, r22)   # R's columns: the body axes in odom_ned
            dx, dy, dz = rx - x, ry - y, rz - z
            v = [g * (c[0] * dx + c[1] * dy + c[2] * dz) + (c[0] * fx + c[1] * fy + c[2] * fz)
                 for g, c in zip(p.gains, (c0, c1, c2))]
            limits = p.speed_limits
            scale = max(1.0, abs(v[0]) / limits[0], abs(v[1]) / limits[1])
            v[0] /= scale
            v[1] /= scale
            v[2] = min(max(v[2], -limits[2]), limits[2])
            r = p.yaw_gain * wrap_angle(self.reference.yaw - psi) + fr
            wanted = (*v, min(max(r, -p.max_yaw_rate), p.max_yaw_rate))
        T = self.sample_period
        out, limited = [], []
        for want, last, accel in zip(wanted, self.last.tolist(), p.acceleration_limits):
            step = accel * T
            value = last + min(max(want - last, -step), step)
            out.append(value)
            limited.append(abs(want - value) > 1e-12)
        self.limited = np.array(limited)
        self.last = np.array(out)
        return Reference(self.last)
