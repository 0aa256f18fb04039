"""Vehicle sensors with the thesis's noise levels (sec. 1.3, 6.5.1, 7.4.2, App. A).

Profiles live in ``seapup_sim/environment/sensors.yaml``: ``ideal`` (no
noise), ``baseline`` (Kallstrom's doppler log and gyros, 3-sigma figures) and
``haslar`` (the ARE Haslar pack, optionally with strapdown accelerometer
integration). Each instrument draws from its own random stream
(:class:`seapup_common.random_streams.RandomStreams`), so changing one
instrument's noise or the profile never changes another's draws, nor the
current's. The readings are a :class:`seapup_common.contract.Measurement`,
each with its stamp, variance and validity -- what a controller may see.

Readings (all SI, body axes FRD unless named):

- ``velocity`` (u, v, w) -- doppler log: velocity over the ground (the log
  looks at the seabed), white noise;
- ``rates`` (p, q, r) -- rate gyros;
- ``attitude`` (phi, theta, psi) -- vertical gyro and compass;
- ``depth`` -- pressure gauge, NED z of the body origin;
- ``altitude`` -- altimeter range to the seabed along the body z axis, invalid
  outside the altimeter's range or when the seabed is out of its view;
- ``position`` (x, y, z NED) -- acoustic fix at ``rate_hz`` with dropouts,
  invalid between fixes or when a fix is lost.

With ``strapdown.enabled`` the velocity comes instead from integrating
accelerometers as at Haslar: specific force plus a drifting zero, with gravity
removed using an attitude that is wrong by ``attitude_error`` -- a 0.1 deg
roll error leaks g sin(0.1 deg) into sway, 0.17 m/s after 10 s (App. A.3).
"""
from __future__ import annotations

import copy
import functools
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from seapup_common.config import parsed_yaml
from seapup_common.contract import INVALID_READING, CheckedVariances, ContractError, Measurement, Reading
from seapup_common.random_streams import RandomStreams
from seapup_sim.vehicle import cross, rotation_body_to_ned

__all__ = ["SensorProfile", "load_sensor_profile", "sensor_profiles", "profiles_document", "SensorSuite", "INSTRUMENTS"]

#: The instruments, each with its own random stream ``sensors.<name>``.
INSTRUMENTS = ("velocity", "rates", "attitude", "depth", "altitude", "position", "position_dropout",
               "strapdown")


@functools.cache
def _profiles_file() -> Path:
    return Path(str(resources.files("seapup_sim") / "environment" / "sensors.yaml"))


def profiles_document() -> dict:
    """``sensors.yaml`` as parsed, shared and read only: the same object while the file is unchanged (a cache
    keyed on it is dropped when the file changes)."""
    return parsed_yaml(_profiles_file(), shared=True)


def sensor_profiles() -> list[str]:
    """Names of the profiles in ``sensors.yaml``."""
    return sorted(parsed_yaml(_profiles_file()))


@dataclass(frozen=True)
class SensorProfile:
    """Noise levels of one instrument fit (SI standard deviations) and the altimeter's geometry."""

    name: str
    velocity_std: tuple = (0.0, 0.0, 0.0)
    rate_std: tuple = (0.0, 0.0, 0.0)
    attitude_std: tuple = (0.0, 0.0, 0.0)
    depth_std: float = 0.0
    altitude_std: float = 0.0
    position_std: float = 0.0
    position_rate_hz: float = 1.0
    position_dropout: float = 0.0
    altimeter_min_range: float = 0.0
    altimeter_max_range: float = math.inf
    altimeter_field_of_view: float = 0.0
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
        if not (0 <= self.altimeter_min_range < self.altimeter_max_range
                and 0 <= self.altimeter_field_of_view < math.pi):
            raise ValueError(f"sensor profile {self.name!r}: altimeter range must satisfy 0 <= min < max "
                             "and its field of view be in [0, pi) rad")

    @property
    def strapdown_enabled(self) -> bool:
        """Velocity from integrated accelerometers instead of the doppler log."""
        return bool((self.strapdown or {}).get("enabled", False))

    def variances(self) -> dict:
        """Variance of each measurement field (for the readings and the message covariances)."""
        return {"velocity": np.square(self.velocity_std), "rates": np.square(self.rate_std),
                "attitude": np.square(self.attitude_std), "depth": self.depth_std ** 2,
                "altitude": self.altitude_std ** 2, "position": np.full(3, self.position_std ** 2)}


def load_sensor_profile(name: str) -> SensorProfile:
    """A profile from ``sensors.yaml`` by name."""
    profiles = parsed_yaml(_profiles_file(), shared=True)   # read only: the profile copies what it takes
    if name not in profiles:
        raise ValueError(f"no sensor profile {str(name)[:80]!r} (available: {', '.join(sorted(profiles))})")
    p = profiles[name] or {}
    pos = p.get("position", {})
    alt = p.get("altimeter", {})
    return SensorProfile(name, tuple(p.get("velocity_std", (0.0,) * 3)), tuple(p.get("rate_std", (0.0,) * 3)),
                         tuple(p.get("attitude_std", (0.0,) * 3)), float(p.get("depth_std", 0.0)),
                         float(p.get("altitude_std", 0.0)), float(pos.get("std", 0.0)),
                         float(pos.get("rate_hz", 1.0)), float(pos.get("dropout", 0.0)),
                         float(alt.get("min_range", 0.0)), float(alt.get("max_range", math.inf)),
                         float(alt.get("field_of_view", 0.0)), copy.deepcopy(dict(p.get("strapdown", {}))))


def _frozen(values: list) -> np.ndarray:
    """A read-only array of ``values``."""
    array = np.array(values)
    array.setflags(write=False)
    return array


def _measurement(t: float, values: dict, variances: CheckedVariances) -> Measurement:
    """What ``Measurement.build(t, variances=variances, **values)`` gives for readings :meth:`SensorSuite.measure`
    made itself -- lists of floats of their fields' sizes (made read-only arrays here) and floats, None where
    invalid -- checked at once: every number finite (a NaN or inf is refused with build's error), stamped ``t``."""
    total = 0.0
    for value in values.values():   # a NaN or inf anywhere makes the sum non-finite (so may an overflow: looked at)
        if value is not None:
            total += value if isinstance(value, float) else sum(value)
    if not math.isfinite(total):
        bad = next((name for name, value in values.items() if value is not None
                    and not all(map(math.isfinite, value if isinstance(value, list) else [value]))), None)
        if bad is not None:
            raise ContractError(f"{bad} must be finite, got {np.atleast_1d(values[bad]).tolist()}")
    readings = {}
    for name, value in values.items():
        if value is not None:
            if isinstance(value, list):
                value = np.array(value)
                value.setflags(write=False)
            readings[name] = Reading(value, t, variances[name])
    return Measurement(t, **readings)


#: standard normal draws read from an instrument's stream at a time (:meth:`SensorSuite._draws`)
NORMALS_BLOCK = 48   # whole readings of 1 and 3 draws, fewer than a batch block (seapup_sim.batch._Draws)
_EMPTY = ([], 0)
_ZEROS = {k: [0.0] * k for k in (1, 3)}


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


class SensorSuite:
    """Samples the sensors of one profile.

    Parameters
    ----------
    profile : SensorProfile
        May be replaced at run time (:attr:`profile`); a change of strapdown
        mode takes effect at the next reading.
    streams : RandomStreams
        One stream per instrument (``sensors.<instrument>``).
    seabed : callable (x, y) -> depth, optional
        For the altimeter; without it altitude is invalid.
    g : float
        Gravity [m/s^2] (the vehicle configuration's), for the strapdown's
        gravity compensation.
    """

    def __init__(self, profile: SensorProfile, streams: RandomStreams, seabed=None, g: float = 9.81):
        if not isinstance(streams, RandomStreams):
            raise TypeError("streams must be a seapup_common.random_streams.RandomStreams")
        self.profile = profile
        self.rng = {name: streams.generator(f"sensors.{name}") for name in INSTRUMENTS}
        self.seabed = seabed
        self.g = float(g)
        self._next_fix = 0.0
        self._sd_velocity = None
        self._sd_bias = np.zeros(3)
        self._last_t = None
        self._profile_arrays = (None, None, None)
        self._buffered: dict = {}   # instrument -> (standard normal draws read from its stream, how many used)

    def _checked(self) -> tuple:
        """(profile, its variances checked for the readings, instrument -> its noise std as an array or None
        when every component is noise-free): worked out once per profile (it may be replaced)."""
        p = self.profile
        if self._profile_arrays[0] is not p:
            stds = {"velocity": p.velocity_std, "rates": p.rate_std, "attitude": p.attitude_std,
                    "depth": [p.depth_std], "altitude": [p.altitude_std], "position": [p.position_std] * 3}
            stds = {name: tuple(float(v) for v in std) for name, std in stds.items()}
            self._profile_arrays = (p, CheckedVariances.of(p.variances()),
                                    {name: std if any(v > 0 for v in std) else None for name, std in stds.items()})
        return self._profile_arrays

    def _draws(self, std, instrument: str, k: int) -> list:
        """``k`` noise values of ``instrument`` whose standard deviations are ``std`` (k floats; None:
        noise-free, no draw, zeros): ``std[i]`` times the stream's next standard normal draws, each product the
        one ``std * draws`` gives on arrays. The draws are read :data:`NORMALS_BLOCK` at a time: a generator's
        ``standard_normal(n)`` is its next n single draws, so the readings are those of drawing k at each
        (tested), at a fraction of the cost of a generator call per reading."""
        if std is None:
            return _ZEROS[k]
        buffer, used = self._buffered.get(instrument, _EMPTY)
        if used + k > len(buffer):
            buffer = buffer[used:] + self.rng[instrument].standard_normal(NORMALS_BLOCK).tolist()
            used = 0
        self._buffered[instrument] = (buffer, used + k)
        if k == 3:
            return [std[0] * buffer[used], std[1] * buffer[used + 1], std[2] * buffer[used + 2]]
        return [a * b for a, b in zip(std, buffer[used:used + k])]

    def reading_variances(self) -> CheckedVariances:
        """Each field's variance as the readings carry it (the present profile's, checked)."""
        return self._checked()[1]

    def unused_normals(self, instrument: str) -> np.ndarray:
        """The draws read from the instrument's stream and not yet used (a copy): who takes the stream over
        (:class:`seapup_sim.batch.BatchSensors`) uses them first."""
        buffer, used = self._buffered.get(instrument, _EMPTY)
        return np.array(buffer[used:], dtype=float)

    def _strapdown_velocity(self, t: float, state: np.ndarray, specific_force: np.ndarray) -> np.ndarray:
        """Integrate accelerometers (true specific force + drifting zero + noise), removing
        gravity with an attitude that is wrong by the profile's ``attitude_error``."""
        sd = self.profile.strapdown
        est = state[3:6] + np.asarray(sd.get("attitude_error", (0.0, 0.0, 0.0)), float)
        est_down = rotation_body_to_ned(*est)[2]
        if self._sd_velocity is None or self._last_t is None:
            self._sd_velocity = state[6:9].copy()  # aligned when strapdown starts
            self._last_t = t
            return self._sd_velocity.copy()
        dt = t - self._last_t
        self._last_t = t
        rng = self.rng["strapdown"]
        self._sd_bias += float(sd.get("bias_random_walk", 0.0)) * math.sqrt(max(dt, 0.0)) * rng.standard_normal(3)
        measured = specific_force + self._sd_bias + float(sd.get("accel_std", 0.0)) * rng.standard_normal(3)
        v = self._sd_velocity
        v_dot = measured + self.g * est_down - cross(state[9:12], v)
        self._sd_velocity = v + dt * v_dot
        return self._sd_velocity.copy()

    def _altitude(self, state: np.ndarray, stds: dict | None = None) -> float | None:
        p = self.profile
        if self.seabed is None:
            return None
        x, y, z, phi, theta = state[:5].tolist()
        vertical = self.seabed(x, y) - z
        tilt = math.cos(phi) * math.cos(theta)
        if vertical <= 0 or tilt <= 0:
            return None  # seabed above the vehicle, or the beam pointing up
        # slant range along body z over a locally flat bottom; beyond max_range: no echo
        stds = self._checked()[2] if stds is None else stds
        reading = vertical / tilt + self._draws(stds["altitude"], "altitude", 1)[0]
        return reading if p.altimeter_min_range <= reading <= p.altimeter_max_range else None

    def measure(self, t: float, state: np.ndarray, specific_force=None) -> Measurement:
        """Readings at time ``t`` for the true ``state`` (see module docstring).

        ``specific_force`` (body axes, :func:`seapup_sim.vehicle.specific_force`)
        is needed only for strapdown velocity.
        """
        p, variances, stds = self._checked()
        draws, t = self._draws, float(t)
        x = state.tolist()
        # each reading in plain floats, the sums those of the arrays' (state + noise), then one array a field
        if p.strapdown_enabled:
            if specific_force is None:
                raise ValueError("strapdown velocity needs the specific force")
            velocity = self._strapdown_velocity(t, state, np.asarray(specific_force, float)).tolist()
        else:
            self._sd_velocity = self._last_t = None  # re-aligned if strapdown is switched on later
            n = draws(stds["velocity"], "velocity", 3)
            velocity = [x[6] + n[0], x[7] + n[1], x[8] + n[2]]
        n = draws(stds["rates"], "rates", 3)
        rates = [x[9] + n[0], x[10] + n[1], x[11] + n[2]]
        n = draws(stds["attitude"], "attitude", 3)
        attitude = [_wrap(x[3] + n[0]), x[4] + n[1], _wrap(x[5] + n[2])]
        depth = x[2] + draws(stds["depth"], "depth", 1)[0]
        altitude = self._altitude(state, stds)
        position = None
        if t + 1e-9 >= self._next_fix:
            self._next_fix = t + 1.0 / p.position_rate_hz
            if self.rng["position_dropout"].random() >= p.position_dropout:
                n = draws(stds["position"], "position", 3)
                position = [x[0] + n[0], x[1] + n[1], x[2] + n[2]]
        total = sum(velocity) + sum(rates) + sum(attitude) + depth   # NaN or inf anywhere: not finite
        if altitude is not None:
            total += altitude
        if position is not None:
            total += sum(position)
        if not math.isfinite(total):
            return _measurement(t, {"velocity": velocity, "rates": rates, "attitude": attitude, "depth": depth,
                                    "altitude": altitude, "position": position}, variances)
        return Measurement(t, Reading(_frozen(velocity), t, variances["velocity"]),
                           Reading(_frozen(rates), t, variances["rates"]),
                           Reading(_frozen(attitude), t, variances["attitude"]), Reading(depth, t, variances["depth"]),
                           INVALID_READING if altitude is None else Reading(altitude, t, variances["altitude"]),
                           INVALID_READING if position is None else Reading(_frozen(position), t, variances["position"]))
