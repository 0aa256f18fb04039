"""Vehicle sensors with the thesis's noise levels (sec. 1.3, 6.5.1, 7.4.2, App. A).

Profiles live in ``seapup_sim/environment/sensors.yaml``: ``ideal`` (no
noise), ``baseline`` (Kallstrom's doppler log and gyros, 3-sigma figures) and
``haslar`` (the ARE Haslar pack, optionally with strapdown accelerometer
integration). Every draw comes from the ``numpy.random.Generator`` passed in.

Readings (all SI, body axes FRD unless named):

- ``velocity`` (u, v, w) -- doppler log: velocity over the ground (the log
  looks at the seabed), white noise;
- ``rates`` (p, q, r) -- rate gyros;
- ``attitude`` (phi, theta, psi) -- vertical gyro and compass;
- ``depth`` -- pressure gauge, NED z of the body origin;
- ``altitude`` -- altimeter range to the seabed along the body z axis;
- ``position`` (x, y, z NED) -- acoustic fix at ``rate_hz`` with dropouts, or
  None between fixes or when a fix is lost.

With ``strapdown.enabled`` the velocity comes instead from integrating
accelerometers as at Haslar: specific force plus a drifting zero, with gravity
removed using an attitude that is wrong by ``attitude_error`` -- a 0.1 deg
roll error leaks g sin(0.1 deg) into sway, 0.17 m/s after 10 s (App. A.3).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np
import yaml

from seapup_sim.vehicle import cross, rotation_body_to_ned

__all__ = ["SensorProfile", "load_sensor_profile", "sensor_profiles", "SensorSuite"]


def _profiles_file() -> Path:
    return Path(str(resources.files("seapup_sim") / "environment" / "sensors.yaml"))


def sensor_profiles() -> list[str]:
    return sorted(yaml.safe_load(_profiles_file().read_text()))


@dataclass(frozen=True)
class SensorProfile:
    """Noise levels of one instrument fit (SI standard deviations)."""

    name: str
    velocity_std: tuple = (0.0, 0.0, 0.0)
    rate_std: tuple = (0.0, 0.0, 0.0)
    attitude_std: tuple = (0.0, 0.0, 0.0)
    depth_std: float = 0.0
    altitude_std: float = 0.0
    position_std: float = 0.0
    position_rate_hz: float = 1.0
    position_dropout: float = 0.0
    strapdown: dict = field(default_factory=dict)

    def __post_init__(self):
        values = [*self.velocity_std, *self.rate_std, *self.attitude_std, self.depth_std,
                  self.altitude_std, self.position_std, self.position_dropout]
        if len(self.velocity_std) != 3 or len(self.rate_std) != 3 or len(self.attitude_std) != 3:
            raise ValueError(f"sensor profile {self.name!r}: std vectors need 3 values")
        if not all(math.isfinite(v) and v >= 0 for v in values) or self.position_dropout > 1:
            raise ValueError(f"sensor profile {self.name!r}: standard deviations must be finite and "
                             ">= 0, dropout in [0, 1]")
        if not (0 < self.position_rate_hz <= 1.0):
            raise ValueError(f"sensor profile {self.name!r}: acoustic fix rate must be in (0, 1] Hz")


def load_sensor_profile(name: str) -> SensorProfile:
    """A profile from ``sensors.yaml`` by name."""
    profiles = yaml.safe_load(_profiles_file().read_text())
    if name not in profiles:
        raise ValueError(f"no sensor profile {name!r} (available: {', '.join(sorted(profiles))})")
    p = profiles[name] or {}
    pos = p.get("position", {})
    return SensorProfile(name, tuple(p.get("velocity_std", (0.0,) * 3)), tuple(p.get("rate_std", (0.0,) * 3)),
                         tuple(p.get("attitude_std", (0.0,) * 3)), float(p.get("depth_std", 0.0)),
                         float(p.get("altitude_std", 0.0)), float(pos.get("std", 0.0)),
                         float(pos.get("rate_hz", 1.0)), float(pos.get("dropout", 0.0)),
                         dict(p.get("strapdown", {})))


class SensorSuite:
    """Samples the sensors of one profile.

    Parameters
    ----------
    profile : SensorProfile
    rng : numpy.random.Generator
    seabed : callable (x, y) -> depth, optional
        For the altimeter; without it altitude is None.
    """

    def __init__(self, profile: SensorProfile, rng: np.random.Generator, seabed=None):
        if not isinstance(rng, np.random.Generator):
            raise TypeError("rng must be a numpy.random.Generator")
        self.profile = profile
        self.rng = rng
        self.seabed = seabed
        self._next_fix = 0.0
        sd = profile.strapdown or {}
        self.strapdown = bool(sd.get("enabled", False))
        self._sd_velocity = None
        self._sd_bias = np.zeros(3)
        self._sd_att_err = np.asarray(sd.get("attitude_error", (0.0, 0.0, 0.0)), float)
        self._sd_walk = float(sd.get("bias_random_walk", 0.0))
        self._sd_noise = float(sd.get("accel_std", 0.0))
        self._last_t = None

    def _noise(self, std) -> np.ndarray:
        std = np.asarray(std, float)
        return std * self.rng.standard_normal(std.shape) if np.any(std > 0) else np.zeros(std.shape)

    def _strapdown_velocity(self, t: float, state: np.ndarray, accel_body: np.ndarray) -> np.ndarray:
        """Integrate accelerometers with a wrong attitude and drifting zeros."""
        g = 9.81
        true_down = rotation_body_to_ned(*state[3:6])[2]
        est = state[3:6] + self._sd_att_err
        est_down = rotation_body_to_ned(*est)[2]
        # specific force measured: f = v_dot + w x v - g (body); gravity removed
        # with the estimated attitude
        specific = accel_body + cross(state[9:12], state[6:9]) - g * true_down
        if self._sd_velocity is None or self._last_t is None:
            self._sd_velocity = state[6:9].copy()  # aligned at start
            self._last_t = t
            return self._sd_velocity.copy()
        dt = t - self._last_t
        self._last_t = t
        self._sd_bias += self._sd_walk * math.sqrt(max(dt, 0.0)) * self.rng.standard_normal(3)
        measured = specific + self._sd_bias + self._sd_noise * self.rng.standard_normal(3)
        v = self._sd_velocity
        v_dot = measured + g * est_down - cross(state[9:12], v)
        self._sd_velocity = v + dt * v_dot
        return self._sd_velocity.copy()

    def measure(self, t: float, state: np.ndarray, accel_body=None) -> dict:
        """Readings at time ``t`` for the true ``state`` (see module docstring).

        ``accel_body`` (du/dt, dv/dt, dw/dt) is needed only for strapdown.
        """
        p = self.profile
        out = {"t": t}
        if self.strapdown:
            if accel_body is None:
                raise ValueError("strapdown velocity needs the body accelerations")
            out["velocity"] = self._strapdown_velocity(t, state, np.asarray(accel_body, float))
        else:
            out["velocity"] = state[6:9] + self._noise(p.velocity_std)
        out["rates"] = state[9:12] + self._noise(p.rate_std)
        att = state[3:6] + self._noise(p.attitude_std)
        att[0] = (att[0] + math.pi) % (2 * math.pi) - math.pi
        att[2] = (att[2] + math.pi) % (2 * math.pi) - math.pi
        out["attitude"] = att
        out["depth"] = float(state[2] + self._noise([p.depth_std])[0])
        out["altitude"] = None
        if self.seabed is not None:
            vertical = self.seabed(state[0], state[1]) - state[2]
            tilt = math.cos(state[3]) * math.cos(state[4])
            if vertical > 0 and tilt > 0.1:  # range along the body z axis, flat-bottom approximation
                out["altitude"] = float(vertical / tilt + self._noise([p.altitude_std])[0])
        out["position"] = None
        if t + 1e-9 >= self._next_fix:
            self._next_fix = t + 1.0 / p.position_rate_hz
            if self.rng.random() >= p.position_dropout:
                out["position"] = state[:3] + self._noise([p.position_std] * 3)
        return out
