"""The simulation loop without ROS: vehicle, environment and a sampled controller.

This is fig. 5.1 of the thesis in code. A controller sampled every
``control_period`` T sees the sensor readings at t_k (a
:class:`~seapup_common.contract.Measurement`, never the true state) and a
reference, and returns a blade-pitch command, which is held (zero-order hold)
while the plant is integrated from t_k to t_k + T in physics steps of ``dt``.
Within each physics step the current advances one sample of its Gauss-Markov
process (sample time dt: its statistics do not depend on dt) and the
umbilical's quasi-static equilibrium is solved for the state at the start of
the step and held as an external wrench. Scheduled events change the
configuration (e.g. the camera added at 65 s, sec. 7.4.4), thruster
efficiencies (fouling) or the current statistics (step changes, sec. 5.4.3)
at given times.

The run-time changes -- configuration, thruster efficiency, current, sensor
profile -- are methods of :class:`Simulation`, used alike by scheduled
events and by the simulator node's services. Randomness comes from one
stream per component (:class:`~seapup_common.random_streams.RandomStreams`):
the current's realisation does not depend on the sensors, and vice versa.

Every later scenario -- open-loop tests, closed-loop SIL, identification
runs -- can run through :class:`Simulation` with or without ROS; the
simulator node is a shell around it. The log keeps the truth (for analysis)
next to every measurement and reference the controller saw.
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from seapup_common.contract import (MEASUREMENT_FIELDS, Command, Measurement, Reference,
                                    VelocityController)
from seapup_common.random_streams import RandomStreams
from seapup_sim.current import CurrentParams, GaussMarkovCurrent
from seapup_sim.environment_config import EnvironmentConfig, load_environment
from seapup_sim.integrator import DivergenceError, VehicleIntegrator
from seapup_sim.sensors import SensorProfile, SensorSuite
from seapup_sim.umbilical import Umbilical
from seapup_sim.linearised import vehicle_model
from seapup_sim.vehicle import VehicleModel, specific_force
from seapup_sim.vehicle_config import load_vehicle_config

__all__ = ["Event", "Sample", "SimulationLog", "Simulation", "events_from_data", "EVENT_DATA_KEYS"]

#: Keys of an event as plain data (a run spec's events, the simulator node's ``events`` parameter).
EVENT_DATA_KEYS = ("time", "kind", "detail")
_CURRENT_KEYS = ("mean_speed", "speed_std", "mean_direction", "direction_std", "break_time")


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


def events_from_data(items, default_break_time: float | None = None) -> list[Event]:
    """Events from plain data: ``[{"time": s, "kind": k, "detail": d}, ...]``.

    ``configuration``: a configuration name; ``thruster_efficiency``: four factors; ``current``: a
    mapping of ``mean_speed``, ``speed_std``, ``mean_direction``, ``direction_std`` and optionally
    ``break_time`` (default ``default_break_time``: the environment file's T_c), or None (no current).
    One parser for the run layer and the simulator node's ``events`` parameter.

    Raises
    ------
    ValueError
        On unknown keys, kinds or current parameters, a missing field, or a bad value.
    """
    if items is None:
        return []
    if not isinstance(items, (list, tuple)):
        raise ValueError(f"events must be a list of {{time, kind, detail}}, got {items!r}")
    events = []
    for i, item in enumerate(items):
        if not isinstance(item, dict) or set(item) - set(EVENT_DATA_KEYS) or not {"time", "kind"} <= set(item):
            raise ValueError(f"event {i} must be a mapping of {', '.join(EVENT_DATA_KEYS)} (time and kind "
                             f"required), got {item!r}")
        detail = item.get("detail")
        if item["kind"] == "current" and detail is not None:
            unknown = sorted(set(detail) - set(_CURRENT_KEYS)) if isinstance(detail, dict) else ["(not a mapping)"]
            if unknown:
                raise ValueError(f"event {i}: unknown current parameter(s) {unknown}; known: {', '.join(_CURRENT_KEYS)}")
            values = dict(detail)
            if not values.get("break_time"):
                if default_break_time is None:
                    default_break_time = load_environment().current.params.break_time
                values["break_time"] = default_break_time
            try:
                detail = CurrentParams(*(float(values[k]) for k in _CURRENT_KEYS))
            except KeyError as exc:
                raise ValueError(f"event {i}: a current needs {exc.args[0]}") from None
        elif item["kind"] == "thruster_efficiency":
            detail = [float(v) for v in detail] if isinstance(detail, (list, tuple)) else detail
            if not isinstance(detail, list) or not 1 <= len(detail) <= 32:
                raise ValueError(f"event {i}: thruster_efficiency needs a factor per thruster, got "
                                 f"{str(item.get('detail'))[:80]}")
        elif item["kind"] == "configuration" and not isinstance(detail, str):
            raise ValueError(f"event {i}: a configuration event names a configuration, got {detail!r}")
        try:
            events.append(Event(float(item["time"]), str(item["kind"]), detail))
        except (TypeError, ValueError) as exc:
            raise ValueError(f"event {i}: {exc}") from None
    return events


@dataclass(frozen=True)
class Sample:
    """Everything at t_k: the truth (for analysis and the simulator's truth
    topics) and the measurement (what a controller may see)."""

    t: float
    state: np.ndarray                 # truth (12,)
    measurement: Measurement
    specific_force: np.ndarray        # (3,) body axes [m/s^2]
    current_ned: np.ndarray           # (3,)
    umbilical_body: np.ndarray        # (6,) wrench on the vehicle


@dataclass
class SimulationLog:
    """Histories at the control instants, in preallocated arrays.

    ``measured[name]`` holds each :data:`~seapup_common.contract.MEASUREMENT_FIELDS`
    reading (NaN where invalid: no fix, seabed out of range); ``reference`` the
    reference the controller was given (NaN at the last instant, where no
    command is asked for).
    """

    t: np.ndarray
    state: np.ndarray
    command: np.ndarray               # held from t[k] to t[k+1]
    blade_pitch: np.ndarray           # applied blade pitch at t[k]
    current_ned: np.ndarray
    umbilical_body: np.ndarray
    measured: dict
    reference: np.ndarray
    extra: dict = field(default_factory=dict)

    @classmethod
    def allocate(cls, n: int) -> "SimulationLog":
        """A log for ``n`` samples, filled with NaN."""
        def nan(*shape):
            return np.full((n, *shape), np.nan)
        measured = {name: nan(size) if size else nan() for name, (size, _) in MEASUREMENT_FIELDS.items()}
        return cls(nan(), nan(12), nan(4), nan(4), nan(3), nan(6), measured, nan(4))

    def record(self, k: int, sample: Sample, blade_pitch: np.ndarray) -> None:
        self.t[k], self.state[k], self.blade_pitch[k] = sample.t, sample.state, blade_pitch
        self.current_ned[k], self.umbilical_body[k] = sample.current_ned, sample.umbilical_body
        for name in MEASUREMENT_FIELDS:
            reading = getattr(sample.measurement, name)
            if reading.valid:
                self.measured[name][k] = reading.value


def _reference_at(reference, t: float) -> Reference:
    if reference is None:
        return Reference()
    if isinstance(reference, Reference):
        return reference
    if not callable(reference):  # a constant (4,) array, as the docstring of Simulation.run promises
        return Reference(reference)
    value = reference(t)
    return value if isinstance(value, Reference) else Reference(value)


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
    streams : RandomStreams, optional
        The run's random streams (default: seed 0). A current created later
        (event or :meth:`set_current`) draws from stream ``current``.
    """

    def __init__(self, model: VehicleModel, *, dt: float = 0.1, control_period: float = 0.2,
                 current: GaussMarkovCurrent | None = None, umbilical: Umbilical | None = None,
                 sensors: SensorSuite | None = None, events=(), state=None, pitch=None,
                 streams: RandomStreams | None = None):
        self.streams = streams if streams is not None else RandomStreams(0)
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
        self._current_rng = current.rng if current is not None else self.streams.generator("current")
        self.umbilical = umbilical
        self.sensors = sensors
        self.events = sorted(events, key=lambda e: e.time)
        self._next_event = 0
        self._umbilical_wrench = np.zeros(6)
        self._accel = np.zeros(3)

    @classmethod
    def from_config(cls, vehicle: str | dict, environment=None, *, seed: int = 0,
                    dt: float = 0.1, control_period: float = 0.2, events=(), state=None, pitch=None,
                    dynamics: str = "nonlinear", model: VehicleModel | None = None):
        """Build vehicle and environment from a configuration name (or dict) and an
        environment (overrides, file or :class:`EnvironmentConfig`; see
        :func:`~seapup_sim.environment_config.load_environment`). ``dynamics`` chooses the
        plant: ``nonlinear`` (ch. 2) or ``linearised`` (eq. 3.2 about hover,
        :mod:`seapup_sim.linearised`). ``model``: that vehicle's model already built (a batch's runs of one
        vehicle share it: :mod:`seapup_runs.batch_runner`), used as it is instead of ``vehicle`` and
        ``dynamics``."""
        if model is None:
            model = vehicle_model(load_vehicle_config(vehicle) if isinstance(vehicle, str) else vehicle, dynamics)
        env: EnvironmentConfig = load_environment(environment, rho=model.rho)
        streams = RandomStreams(seed)
        current = (GaussMarkovCurrent(env.current.params, dt, streams.generator("current"))
                   if env.current.enabled else None)
        umbilical = env.umbilical.build() if env.umbilical.enabled else None
        sensors = SensorSuite(env.sensors, streams, env.seabed, g=model.g)
        return cls(model, dt=dt, control_period=control_period, current=current, umbilical=umbilical,
                   sensors=sensors, events=events, state=state, pitch=pitch, streams=streams)

    @property
    def t(self) -> float:
        return self.plant.t

    @property
    def model(self) -> VehicleModel:
        return self.plant.model

    @property
    def state(self) -> np.ndarray:
        return self.plant.state.copy()

    @property
    def acceleration(self) -> np.ndarray:
        """d(u, v, w)/dt over the last physics step [m/s^2], body axes."""
        return self._accel.copy()

    # -- run-time changes (scheduled events and the simulator's services) ----------
    def set_configuration(self, configuration: str | dict) -> None:
        """Switch the vehicle configuration in flight; the state carries over, and
        so do thruster efficiencies unless the new configuration sets its own."""
        cfg = load_vehicle_config(configuration) if isinstance(configuration, str) else configuration
        efficiency = self.model.thrusters.efficiency.copy()
        before = (self.model.inputs.kind, self.model.thrusters.kind, self.model.thrusters.count)
        after = VehicleModel(cfg)
        if (after.inputs.kind, after.thrusters.kind, after.thrusters.count) != before:
            raise ValueError(f"configuration {after.config_name!r} has other thrusters or inputs "
                             f"({after.thrusters.count} {after.thrusters.kind}, {after.inputs.kind} inputs) than the "
                             f"vehicle flying ({before[2]} {before[1]}, {before[0]} inputs): not switched in flight")
        self.model.configure(cfg)
        if "thruster_efficiency" not in cfg:
            self.model.thrusters.set_efficiency(efficiency)

    def set_thruster_efficiency(self, efficiency) -> None:
        """Fouling factors on the thrusters, one each (sec. 7.4.4)."""
        self.model.thrusters.set_efficiency(efficiency)

    def set_current(self, params: CurrentParams | None) -> None:
        """Change the current's statistics (it relaxes to the new mean with T_c, a step
        change of sec. 5.4.3), start one at its mean, or remove it (None)."""
        if params is None:
            self.current = None
        elif self.current is None:
            self.current = GaussMarkovCurrent(params, self.plant.dt, self._current_rng)
        else:
            self.current.set_params(params)

    def set_sensor_profile(self, profile: SensorProfile) -> None:
        """Another instrument fit; each instrument keeps its own random stream."""
        if self.sensors is None:
            raise ValueError("this simulation has no sensors")
        self.sensors.profile = profile

    def schedule(self, event: Event) -> None:
        """Add an event while running: it takes effect at the first step from ``event.time``
        (at once, before the next step, when that time has passed), as events given at construction."""
        pending = self.events[self._next_event:]
        bisect.insort(pending, event, key=lambda e: e.time)  # after any event of the same time: arrival order
        self.events = self.events[:self._next_event] + pending

    def _apply_events(self) -> None:
        while self._next_event < len(self.events) and self.events[self._next_event].time <= self.t + 1e-9:
            ev = self.events[self._next_event]
            self._next_event += 1
            if ev.kind == "configuration":
                self.set_configuration(ev.value)
            elif ev.kind == "thruster_efficiency":
                self.set_thruster_efficiency(ev.value)
            else:
                self.set_current(ev.value)

    # -- stepping ---------------------------------------------------------------------
    def _current_ned(self) -> np.ndarray:
        return self.current.velocity_ned() if self.current is not None else np.zeros(3)

    def sample(self) -> Sample:
        """Truth and sensor readings at the present control instant."""
        state = self.plant.state.copy()
        force = specific_force(state, self._accel, self.model.g)
        meas = (self.sensors.measure(self.t, state, force) if self.sensors is not None
                else Measurement(self.t))
        return Sample(self.t, state, meas, force, self._current_ned(), self._umbilical_wrench.copy())

    def advance(self, command) -> None:
        """Hold ``command`` [rad] for one control period.

        A compiled plant with no umbilical and no event due within the period takes the period's physics steps
        in one kernel call (:meth:`~seapup_sim.integrator.VehicleIntegrator.step_period`), the current's values
        for each step drawn first (it does not depend on the vehicle): the same steps as one at a time below,
        bit for bit (tested)."""
        plant = self.plant
        if self.umbilical is None and plant.compiled and (
                self._next_event >= len(self.events)
                or self.events[self._next_event].time > plant.t + self.control_period + 1e-9):
            current = self.current
            before = (plant.state, plant.pitch, plant.steps, plant.held,
                      None if current is None else (current.speed, current.direction,
                                                    current.rng.bit_generator.state))
            currents = None if current is None else current.velocities(self.substeps)
            try:
                self._accel = plant.step_period(command, self.substeps, currents)
                return
            except DivergenceError:
                # undone, then flown a step at a time: it fails at the same step, leaving the plant, the current
                # and the acceleration as the reference leaves them (the current stepped once per step taken)
                plant.state, plant.pitch, plant.steps, plant.held, saved = before
                if saved is not None:
                    current.speed, current.direction, current.rng.bit_generator.state = saved
        self._advance_steps(command)

    def _advance_steps(self, command) -> None:
        """:meth:`advance` a physics step at a time: events at each step, the umbilical's wrench, the current."""
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

    def run(self, controller: VelocityController, duration: float, reference=None,
            progress: Callable[[float], None] | None = None) -> SimulationLog:
        """Fly ``controller`` for ``duration`` [s]; return the log.

        Parameters
        ----------
        controller : VelocityController
            Reset first with the applied command (bumpless start), then updated
            every control period with the measurement and reference; its
            ``sample_period`` must equal the simulation's control period.
        reference : Reference, callable t -> Reference or (4,) array, optional
            The velocity reference (default: zero velocity).
        progress : callable, optional
            Called with the fraction done after every sample.
        """
        if not isinstance(controller, VelocityController):
            raise TypeError(f"{type(controller).__name__} is not a VelocityController "
                            "(needs sample_period, reset(applied) and update(t, measurement, reference))")
        if abs(controller.sample_period - self.control_period) > 1e-9:
            raise ValueError(f"the controller samples every {controller.sample_period} s, the simulation "
                             f"every {self.control_period} s")
        n = int(round(duration / self.control_period))
        log = SimulationLog.allocate(n + 1)
        controller.reset(Command(self.plant.applied, self.t))
        for k in range(n + 1):
            sample = self.sample()
            log.record(k, sample, self.plant.applied)
            if k == n:
                break
            ref = _reference_at(reference, sample.t)
            command = controller.update(sample.t, sample.measurement, ref)
            log.reference[k] = ref.velocity
            log.command[k] = command.blade_pitch
            self.advance(command.blade_pitch)
            if progress is not None:
                progress((k + 1) / n)
        return log
