"""The simulation loop without ROS: vehicle, environment and a sampled controller.

This is fig. 5.1 of the thesis in code. A controller sampled every
``control_period`` T sees the outputs sampled at t_k (truth and sensor
readings) and returns a blade-pitch command, which is held (zero-order hold)
while the plant is integrated from t_k to t_k + T in physics steps of ``dt``.
Within each physics step the current advances one sample of its Gauss-Markov
process (sample time dt: its statistics do not depend on dt) and the
umbilical's quasi-static equilibrium is solved for the state at the start of
the step and held as an external wrench. Scheduled events change the
configuration (e.g. the camera added at 65 s, sec. 7.4.4), thruster
efficiencies (fouling) or the current statistics (step changes, sec. 5.4.3)
at given times.

Every later scenario -- open-loop tests, closed-loop SIL, identification
runs -- can run through :class:`Simulation` with or without ROS; the
simulator node is a shell around it.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Callable

import numpy as np
import yaml

from seapup_sim.current import CurrentParams, GaussMarkovCurrent
from seapup_sim.integrator import VehicleIntegrator
from seapup_sim.seabed import Seabed
from seapup_sim.sensors import SensorSuite, load_sensor_profile
from seapup_sim.umbilical import Umbilical, UmbilicalParams
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config, merge_config

__all__ = ["Event", "Sample", "SimulationLog", "Simulation", "load_environment", "umbilical_from_environment"]


def load_environment(overrides: dict | None = None) -> dict:
    """The default environment (``environment/default.yaml``) merged with ``overrides``."""
    path = Path(str(resources.files("seapup_sim") / "environment" / "default.yaml"))
    return merge_config(yaml.safe_load(path.read_text()), overrides or {})


def umbilical_from_environment(section: dict, rho: float) -> Umbilical:
    """The umbilical of an environment's ``umbilical`` section (C_D = strumming
    factor x still-water C_D0, sec. 2.3.4)."""
    params = UmbilicalParams(section["diameter"],
                             section["strumming_factor"] * section["still_water_drag_coefficient"],
                             section["weight_per_length"], section["length_ratio"], rho,
                             tuple(section["attachment"]), section["min_flow"], section["max_gravity_ratio"])
    return Umbilical(params, section["ship_ned"])


@dataclass(frozen=True)
class Event:
    """A change at ``time`` [s]: kind 'configuration' (name or dict),
    'thruster_efficiency' (4 factors), or 'current' (CurrentParams, or None for
    no current)."""

    time: float
    kind: str
    value: object

    def __post_init__(self):
        if self.kind not in ("configuration", "thruster_efficiency", "current"):
            raise ValueError(f"unknown event kind {self.kind!r}")
        if not (math.isfinite(self.time) and self.time >= 0):
            raise ValueError(f"event time must be finite and >= 0, got {self.time!r}")


@dataclass
class Sample:
    """What the controller sees at t_k."""

    t: float
    state: np.ndarray                 # truth (12,)
    measurement: dict | None          # sensor readings (None without sensors)
    current_ned: np.ndarray           # (3,)
    umbilical_body: np.ndarray        # (6,) wrench on the vehicle


@dataclass
class SimulationLog:
    """Histories at the control instants, in preallocated arrays."""

    t: np.ndarray
    state: np.ndarray
    command: np.ndarray               # held from t[k] to t[k+1]
    pitch: np.ndarray                 # applied blade pitch at t[k]
    current_ned: np.ndarray
    umbilical_body: np.ndarray
    measured_velocity: np.ndarray     # NaN without sensors
    extra: dict = field(default_factory=dict)


class Simulation:
    """Plant and environment stepped in lockstep with a sampled controller.

    Parameters
    ----------
    model : VehicleModel
    dt : float
        Physics step [s] (0.1 s, sec. 3.2).
    control_period : float
        Controller sample period T [s]; a whole number of physics steps.
    current, umbilical, sensors : optional environment parts
    events : iterable of Event
    state, pitch : initial state (12,) and applied blade pitch (4,)
    rng : numpy.random.Generator, optional
        For a current created by an event (default: seeded with 0).
    """

    def __init__(self, model: VehicleModel, *, dt: float = 0.1, control_period: float = 0.2,
                 current: GaussMarkovCurrent | None = None, umbilical: Umbilical | None = None,
                 sensors: SensorSuite | None = None, events=(), state=None, pitch=None,
                 rng: np.random.Generator | None = None):
        self.rng = rng if rng is not None else np.random.default_rng(0)
        steps = control_period / dt
        if not (math.isfinite(steps) and steps >= 1 - 1e-9 and abs(steps - round(steps)) < 1e-9):
            raise ValueError(f"control period {control_period} s must be a whole number of "
                             f"physics steps of {dt} s")
        self.substeps = int(round(steps))
        self.control_period = float(control_period)
        self.plant = VehicleIntegrator(model, dt=dt, state=state, pitch=pitch)
        if current is not None and abs(current.sample_time - dt) > 1e-12:
            raise ValueError("the current's sample time must equal the physics step")
        self.current = current
        self.umbilical = umbilical
        self.sensors = sensors
        self.events = sorted(events, key=lambda e: e.time)
        self._next_event = 0
        self._umbilical_wrench = np.zeros(6)
        self._accel = np.zeros(3)

    @classmethod
    def from_config(cls, vehicle: str | dict, environment: dict | None = None, *, seed: int = 0,
                    dt: float = 0.1, control_period: float = 0.2, events=(), state=None, pitch=None):
        """Build vehicle and environment from names/dicts (see ``load_environment``)."""
        model = VehicleModel(load_vehicle_config(vehicle) if isinstance(vehicle, str) else vehicle)
        env = load_environment(environment)
        rng = np.random.default_rng(seed)
        current = None
        if env["current"].get("enabled"):
            c = env["current"]
            current = GaussMarkovCurrent(CurrentParams(c["mean_speed"], c["speed_std"], c["mean_direction"],
                                                       c["direction_std"], c["break_time"]), dt, rng)
        umbilical = umbilical_from_environment(env["umbilical"], model.rho) if env["umbilical"].get("enabled") else None
        seabed = Seabed.from_config(env["seabed"])
        sensors = SensorSuite(load_sensor_profile(env["sensors"]), rng, seabed)
        return cls(model, dt=dt, control_period=control_period, current=current, umbilical=umbilical,
                   sensors=sensors, events=events, state=state, pitch=pitch, rng=rng)

    @property
    def t(self) -> float:
        return self.plant.t

    @property
    def state(self) -> np.ndarray:
        return self.plant.state.copy()

    @property
    def acceleration(self) -> np.ndarray:
        """d(u, v, w)/dt over the last physics step [m/s^2], body axes."""
        return self._accel.copy()

    def _current_ned(self) -> np.ndarray:
        return self.current.velocity_ned() if self.current is not None else np.zeros(3)

    def _apply_events(self) -> None:
        while self._next_event < len(self.events) and self.events[self._next_event].time <= self.t + 1e-9:
            ev = self.events[self._next_event]
            self._next_event += 1
            model = self.plant.model
            if ev.kind == "configuration":
                cfg = load_vehicle_config(ev.value) if isinstance(ev.value, str) else copy.deepcopy(ev.value)
                efficiency = model.thrusters.efficiency.copy()
                model.configure(cfg)
                if "thruster_efficiency" not in cfg:
                    model.thrusters.set_efficiency(efficiency)
            elif ev.kind == "thruster_efficiency":
                model.thrusters.set_efficiency(ev.value)
            elif ev.value is None:
                self.current = None
            elif self.current is None:
                self.current = GaussMarkovCurrent(ev.value, self.plant.dt, self.rng)
            else:
                self.current.set_params(ev.value)

    def sample(self) -> Sample:
        """Outputs at the present control instant."""
        state = self.plant.state.copy()
        meas = self.sensors.measure(self.t, state, self._accel) if self.sensors is not None else None
        return Sample(self.t, state, meas, self._current_ned(), self._umbilical_wrench.copy())

    def advance(self, command) -> None:
        """Hold ``command`` [rad] for one control period."""
        for _ in range(self.substeps):
            self._apply_events()
            current = self._current_ned()
            if self.umbilical is not None:
                self._umbilical_wrench = self.umbilical.wrench(self.plant.state, current)
            before = self.plant.state[6:9].copy()
            self.plant.step(command, current_ned=current,
                            external=self._umbilical_wrench if self.umbilical is not None else None)
            self._accel = (self.plant.state[6:9] - before) / self.plant.dt
            if self.current is not None:
                self.current.step()

    def run(self, controller: Callable[[Sample], np.ndarray], duration: float,
            progress: Callable[[float], None] | None = None) -> SimulationLog:
        """Run ``controller`` in the loop for ``duration`` [s]; return the log."""
        n = int(round(duration / self.control_period))
        log = SimulationLog(np.empty(n + 1), np.empty((n + 1, 12)), np.full((n + 1, 4), np.nan),
                            np.empty((n + 1, 4)), np.empty((n + 1, 3)), np.empty((n + 1, 6)),
                            np.full((n + 1, 3), np.nan))
        for k in range(n + 1):
            s = self.sample()
            log.t[k], log.state[k], log.pitch[k] = s.t, s.state, self.plant.pitch
            log.current_ned[k], log.umbilical_body[k] = s.current_ned, s.umbilical_body
            if s.measurement is not None:
                log.measured_velocity[k] = s.measurement["velocity"]
            if k == n:
                break
            command = np.asarray(controller(s), float)
            log.command[k] = command
            self.advance(command)
            if progress is not None:
                progress((k + 1) / n)
        return log
