"""The environment of a run as one typed, validated object, loaded once from YAML.

``environment/default.yaml`` holds the thesis's environment (current of
sec. 3.9, cable of sec. 3.8, a flat seabed, the baseline sensors) and is the
one place of those values. :func:`load_environment` merges overrides over it
-- a mapping, or another YAML file that may itself ``extends: default`` -- and
reads the result through :class:`~seapup_common.config.ConfigView`, so every
missing or bad key is named in a :class:`~seapup_common.config.ConfigError`
with the allowed range, before anything is built. The simulator node exposes
every leaf of the same mapping as a ``environment.<section>.<key>`` parameter.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from seapup_common.config import ConfigError, ConfigView, load_yaml, merge
from seapup_sim.current import CurrentParams
from seapup_sim.seabed import Seabed
from seapup_sim.sensors import SensorProfile, load_sensor_profile, sensor_profiles
from seapup_sim.umbilical import Umbilical, UmbilicalParams

__all__ = ["CurrentConfig", "UmbilicalConfig", "EnvironmentConfig", "default_environment_file",
           "default_environment_mapping", "environment_from_mapping", "load_environment", "RequestLimits",
           "load_limits"]


def default_environment_file() -> Path:
    return Path(str(resources.files("seapup_sim") / "environment" / "default.yaml"))


def default_environment_mapping() -> dict:
    """The default environment as plain data (what the node declares as parameters)."""
    return load_yaml(default_environment_file())


@dataclass(frozen=True)
class CurrentConfig:
    """Gauss-Markov current (sec. 2.4): on or off, and its statistics."""

    enabled: bool
    params: CurrentParams

    @classmethod
    def from_view(cls, v: ConfigView) -> "CurrentConfig":
        return cls(v.flag("enabled"), CurrentParams(
            v.number("mean_speed", lo=0.0), v.number("speed_std", lo=0.0),
            v.number("mean_direction", lo=-2 * math.pi, hi=2 * math.pi), v.number("direction_std", lo=0.0),
            v.number("break_time", lo=0.0, lo_open=True)))


@dataclass(frozen=True)
class UmbilicalConfig:
    """Quasi-static umbilical (sec. 2.3.4, 3.8): on or off, cable data, ship position."""

    enabled: bool
    params: UmbilicalParams
    ship_ned: tuple

    @classmethod
    def from_view(cls, v: ConfigView, rho: float) -> "UmbilicalConfig":
        drag = v.number("strumming_factor", lo=0.0, lo_open=True) * \
            v.number("still_water_drag_coefficient", lo=0.0, lo_open=True)
        params = UmbilicalParams(
            v.number("diameter", lo=0.0, lo_open=True), drag, v.number("weight_per_length", lo=0.0),
            v.number("length_ratio", lo=1.0, lo_open=True), rho, tuple(v.vector("attachment", 3)),
            v.number("min_flow", lo=0.0, lo_open=True), v.number("max_gravity_ratio", lo=0.0, lo_open=True))
        return cls(v.flag("enabled"), params, tuple(v.vector("ship_ned", 3)))

    def build(self) -> Umbilical:
        """A new :class:`Umbilical` with these data."""
        return Umbilical(self.params, self.ship_ned)


def _seabed(v: ConfigView) -> Seabed:
    """Seabed from its section; ``points`` as [[distance, depth], ...] or flattened pairs."""
    try:
        points = np.asarray(v.get("points", []), float).ravel()
    except (TypeError, ValueError):
        raise v.error("points", f"must be (distance, depth) pairs, got {v.get('points')!r}") from None
    if points.size % 2:
        raise v.error("points", f"needs (distance, depth) pairs, got {points.size} numbers")
    try:
        return Seabed(v.choice("kind", ("flat", "slope", "polyline")), v.number("depth", lo=0.0, lo_open=True),
                      v.number("gradient"), v.number("direction", lo=-2 * math.pi, hi=2 * math.pi),
                      points.reshape(-1, 2))
    except ValueError as exc:
        raise ConfigError(f"{v.source}: seabed: {exc}") from None


@dataclass(frozen=True)
class EnvironmentConfig:
    """Everything around the vehicle: current, umbilical, seabed and sensor profile.

    Build it with :func:`load_environment`; the fields are already validated.
    """

    current: CurrentConfig
    umbilical: UmbilicalConfig
    seabed: Seabed
    sensors: SensorProfile
    source: str = "environment"


def environment_from_mapping(mapping, source: str = "environment", rho: float = 1025.0) -> EnvironmentConfig:
    """Validate a complete environment mapping (all four sections) into an :class:`EnvironmentConfig`.

    ``rho`` is the water density for the cable's drag (the vehicle configuration's).
    """
    v = ConfigView(mapping, source)
    name = v.choice("sensors", sensor_profiles())
    current = CurrentConfig.from_view(v.section("current"))
    try:
        load_limits().check_current(current.params)
    except ValueError as exc:
        raise ConfigError(f"{source}: current: {exc}") from None
    return EnvironmentConfig(current,
                             UmbilicalConfig.from_view(v.section("umbilical"), rho),
                             _seabed(v.section("seabed")), load_sensor_profile(name), source)


def load_environment(overrides=None, *, rho: float = 1025.0) -> EnvironmentConfig:
    """The default environment with ``overrides`` merged over it.

    Parameters
    ----------
    overrides : dict, str, Path or EnvironmentConfig, optional
        A partial mapping (``{"current": {"enabled": True}}``), a YAML file of
        such overrides, or an already built configuration (returned as it is).
    rho : float
        Water density [kg/m^3] for the cable (the vehicle's).

    Raises
    ------
    ConfigError
        Naming the file and key of anything missing, mistyped or out of range.
    """
    if isinstance(overrides, EnvironmentConfig):
        return overrides
    source = "environment/default.yaml"
    if isinstance(overrides, (str, Path)):
        path = Path(overrides)
        overrides, source = load_yaml(path), f"{path.name} over environment/default.yaml"
    return environment_from_mapping(merge(default_environment_mapping(), overrides or {}, strict=source), source, rho)


@dataclass(frozen=True)
class RequestLimits:
    """The physical bounds of ``environment/limits.yaml`` and the checks that use them.

    Every check raises ``ValueError`` naming the value and the allowed range.
    """

    horizontal_max: float
    depth: tuple
    roll_max: float
    pitch_max: float
    linear_speed_max: float
    angular_speed_max: float
    current_speed_max: float
    direction_std_max: float
    break_time: tuple
    timer_period_max: float

    def check_state(self, state) -> np.ndarray:
        """A start state (12,) inside the bounds, as a float array."""
        try:
            x = np.array(state, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"state must be 12 numbers, got {str(state)[:80]}") from None
        if x.shape != (12,) or not np.all(np.isfinite(x)):
            raise ValueError(f"state must be 12 finite numbers, got {np.array2string(np.asarray(x), threshold=20)[:200]}")
        names = ("x", "y", "z", "phi", "theta", "psi", "u", "v", "w", "p", "q", "r")
        bounds = [(-self.horizontal_max, self.horizontal_max)] * 2 + [tuple(self.depth)] + \
            [(-self.roll_max, self.roll_max), (-self.pitch_max, self.pitch_max), (-math.inf, math.inf)] + \
            [(-self.linear_speed_max, self.linear_speed_max)] * 3 + [(-self.angular_speed_max, self.angular_speed_max)] * 3
        for name, value, (lo, hi) in zip(names, x, bounds):
            if not lo <= value <= hi:
                raise ValueError(f"state {name} = {float(value):g} is outside the allowed range [{lo:g}, {hi:g}] "
                                 "(environment/limits.yaml)")
        return x

    def check_current(self, params: CurrentParams) -> CurrentParams:
        """Current statistics inside the bounds."""
        peak = params.mean_speed + 3.0 * params.speed_std
        if not peak <= self.current_speed_max:
            raise ValueError(f"current mean + 3 sigma = {peak:g} m/s is beyond the maximum "
                             f"{self.current_speed_max:g} m/s (environment/limits.yaml)")
        if not params.direction_std <= self.direction_std_max:
            raise ValueError(f"current direction_std = {params.direction_std:g} rad is beyond the maximum "
                             f"{self.direction_std_max:g} rad")
        lo, hi = self.break_time
        if not lo <= params.break_time <= hi:
            raise ValueError(f"current break_time = {params.break_time:g} s is outside the allowed range "
                             f"[{lo:g}, {hi:g}] s")
        return params

    def check_real_time_factor(self, rtf: float, control_period: float) -> float:
        """0 (as fast as possible) or a factor whose timer period T / rtf is at most ``timer_period_max``."""
        rtf = float(rtf)
        least = control_period / self.timer_period_max
        if not (math.isfinite(rtf) and (rtf == 0.0 or rtf >= least)):
            raise ValueError(f"real_time_factor = {rtf:g} must be 0 (as fast as possible) or >= {least:.3g} "
                             f"(a step of T = {control_period:g} s at most every {self.timer_period_max:g} s)")
        return rtf


def load_limits() -> RequestLimits:
    """The bounds of ``environment/limits.yaml``."""
    path = default_environment_file().parent / "limits.yaml"
    v = ConfigView(load_yaml(path), "environment/limits.yaml")
    s, c = v.section("start_state"), v.section("current")
    return RequestLimits(s.number("horizontal_max", lo=0.0), tuple(s.vector("depth", 2)), s.number("roll_max", lo=0.0),
                         s.number("pitch_max", lo=0.0, hi=math.radians(85.0)), s.number("linear_speed_max", lo=0.0),
                         s.number("angular_speed_max", lo=0.0), c.number("speed_max", lo=0.0),
                         c.number("direction_std_max", lo=0.0), tuple(c.vector("break_time", 2, lo=0.0)),
                         v.section("realtime").number("timer_period_max", lo=0.0, lo_open=True))
