"""What the simulator node computes, without ROS.

:class:`SimulatorCore` wraps a :class:`seapup_sim.simulation.Simulation` with the
node's contract:

- commands pass the :class:`~seapup_common.blade_pitch.CommandGate` (wrong length
  or non-finite: rejected; beyond +/-35 deg: saturated) and, in lockstep, must
  carry the stamp of the present sample t_k (older: stale, newer: future --
  both rejected); every outcome is counted;
- a watchdog replaces the command with the hover (or neutral) setting when no
  valid command has arrived for ``watchdog_timeout`` simulated seconds; the
  hover setting is the trim of the *active* configuration (eq. 5.2 for the
  baseline; the camera-fitted vehicle needs more vectored thrust);
- :meth:`outputs` returns everything the node publishes at t_k, in SI units,
  NED/FRD, ready to be copied into messages.

Nothing here sleeps, spins or publishes; the node decides when to step.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT, CommandGate
from seapup_sim.current import CurrentParams
from seapup_sim.environment_config import load_environment, load_limits
from seapup_sim.hover import hover_of
from seapup_sim.linearised import DYNAMICS
from seapup_sim.sensors import load_sensor_profile
from seapup_sim.simulation import Event, Simulation, events_from_data
from seapup_sim.vehicle_config import load_vehicle_config

__all__ = ["SimulatorConfig", "SimulatorCore"]

#: Points of the published cable shape (``umbilical/shape``).
CABLE_POINTS = 20


@dataclass
class SimulatorConfig:
    """The node's simulation parameters (SI).

    ``environment`` is a mapping of overrides over ``environment/default.yaml``
    (see :func:`seapup_sim.environment_config.load_environment`); the sensor
    profile is its ``sensors`` key.
    """

    vehicle: str = "baseline"
    seed: int = 0
    physics_step: float = 0.1
    control_period: float = 0.2
    blade_pitch_limit: float = BLADE_PITCH_LIMIT
    watchdog_timeout: float = 1.0          # simulated seconds without a valid command
    watchdog_action: str = "hover"         # hover | neutral
    stamp_tolerance: float = 1e-6          # [s] for matching a command to t_k
    environment: dict = field(default_factory=dict)
    dynamics: str = "nonlinear"            # nonlinear (ch. 2) | linearised (eq. 3.2 about hover)
    events: list = field(default_factory=list)  # scheduled changes as data (events_from_data), replayed on reset

    def validate(self) -> None:
        steps = self.control_period / self.physics_step
        if not (self.physics_step > 0 and self.control_period > 0):
            raise ValueError("physics_step and control_period must be > 0")
        if abs(steps - round(steps)) > 1e-9 or round(steps) < 1:
            raise ValueError(f"control_period {self.control_period} s must be a whole number of "
                             f"physics steps {self.physics_step} s")
        if self.watchdog_action not in ("hover", "neutral"):
            raise ValueError(f"watchdog_action must be hover or neutral, got {self.watchdog_action!r}")
        if not (0.0 < self.blade_pitch_limit <= BLADE_PITCH_LIMIT + 1e-12):
            raise ValueError(f"blade_pitch_limit must be in (0, {BLADE_PITCH_LIMIT:.4f}] rad "
                             f"(+/-{math.degrees(BLADE_PITCH_LIMIT):g} deg), got {self.blade_pitch_limit}")
        if not self.watchdog_timeout > 0:
            raise ValueError("watchdog_timeout must be > 0 s")
        if self.dynamics not in DYNAMICS:
            raise ValueError(f"dynamics must be one of {', '.join(DYNAMICS)}, got {self.dynamics!r}")
        limits = None
        for event in events_from_data(self.events):  # raises ValueError on a malformed one
            if event.kind == "configuration":
                load_vehicle_config(event.value)   # an unknown configuration is refused now, not at its time
            elif event.kind == "current" and event.value is not None:
                limits = limits or load_limits()
                limits.check_current(event.value)


class SimulatorCore:
    """The simulator's state machine (see module docstring)."""

    COUNTERS = ("accepted", "saturated", "rejected_invalid", "rejected_stale", "rejected_future",
                "rejected_malformed", "watchdog_trips", "lockstep_timeouts", "steps")

    def __init__(self, config: SimulatorConfig, state=None):
        config.validate()
        self.config = config
        self.limits = load_limits()
        self._hover_cache: dict[str, np.ndarray] = {}
        self.reset(config.seed, state)

    # -- lifecycle -------------------------------------------------------------
    def reset(self, seed: int, state=None) -> None:
        """Time to 0, a new seed, the given (or rest) state, the hover command of
        the active configuration; every counter back to zero.

        Atomic: a seed or state outside ``environment/limits.yaml`` raises
        ``ValueError`` and nothing changes."""
        c = self.config
        if isinstance(seed, bool) or not 0 <= int(seed) < 2**31:
            raise ValueError(f"seed must be in [0, 2^31), got {seed}")
        if state is not None:
            state = self.limits.check_state(state)
        simulation = Simulation.from_config(c.vehicle, c.environment, seed=int(seed), dt=c.physics_step,
                                            control_period=c.control_period, state=state,
                                            pitch=self._hover_of(c.vehicle), dynamics=c.dynamics,
                                            events=events_from_data(c.events))
        c.seed = int(seed)
        self.simulation = simulation
        model = simulation.model
        # the Seapup's blade pitches within the node's limit; a virtual-input vehicle's inputs within full scale
        self.gate = CommandGate(limit=c.blade_pitch_limit if model.inputs.kind == "direct" else model.pitch_limit)
        self._counters = dict.fromkeys(("rejected_stale", "rejected_future", "rejected_malformed",
                                        "watchdog_trips", "lockstep_timeouts", "steps"), 0)
        self.last_error = ""
        self.command = self.hover.copy()
        self.last_valid_time = 0.0
        self.watchdog_active = False

    def _hover_of(self, vehicle: str) -> np.ndarray:
        if vehicle not in self._hover_cache:
            self._hover_cache[vehicle] = hover_of(load_vehicle_config(vehicle))
        return self._hover_cache[vehicle].copy()

    @property
    def hover(self) -> np.ndarray:
        """The hover setting (eq. 5.2) of the active configuration [rad]."""
        return self._hover_of(self.config.vehicle)

    @property
    def counters(self) -> dict[str, int]:
        """Every outcome counted since the last reset (the gate's counts included)."""
        return {"accepted": self.gate.accepted, "saturated": self.gate.saturated,
                "rejected_invalid": self.gate.rejected, **self._counters}

    @property
    def t(self) -> float:
        return self.simulation.t

    @property
    def t_ns(self) -> int:
        return int(round(self.simulation.t * 1e9))

    # -- commands ----------------------------------------------------------------
    def reject_malformed(self, reason: str) -> None:
        """Count a message that could not even be decoded."""
        self.reject("rejected_malformed", reason)

    def reject(self, counter: str, reason: str) -> None:
        """Count a command refused before it reached the gate (``rejected_*`` counters)."""
        if counter not in self._counters or not counter.startswith("rejected_"):
            raise KeyError(f"no rejection counter {counter!r}")
        self._counters[counter] += 1
        self.last_error = reason

    def submit(self, pitch, stamp_ns: int | None, lockstep: bool) -> tuple[bool, str]:
        """Offer a command; returns (accepted, reason)."""
        if stamp_ns is not None:
            dt = (stamp_ns - self.t_ns) * 1e-9
            if lockstep and dt < -self.config.stamp_tolerance:
                self._counters["rejected_stale"] += 1
                self.last_error = f"stale command stamped {stamp_ns * 1e-9:.3f} s at t = {self.t:.3f} s"
                return False, self.last_error
            horizon = self.config.stamp_tolerance if lockstep else self.config.control_period
            if dt > horizon:
                self._counters["rejected_future"] += 1
                self.last_error = f"command from the future: stamped {stamp_ns * 1e-9:.3f} s at t = {self.t:.3f} s"
                return False, self.last_error
        clipped_before = self.gate.saturated
        value = self.gate.submit(pitch)
        if value is None:
            self.last_error = self.gate.last_error
            return False, self.last_error
        self.command = value
        self.last_valid_time = self.t
        self.watchdog_active = False
        return True, "saturated" if self.gate.saturated > clipped_before else "ok"

    def _effective_command(self) -> np.ndarray:
        if self.t - self.last_valid_time > self.config.watchdog_timeout + 1e-9:
            if not self.watchdog_active:
                self.watchdog_active = True
                self._counters["watchdog_trips"] += 1
            self.command = self.hover if self.config.watchdog_action == "hover" else np.zeros(4)
        return self.command

    def step(self) -> None:
        """Integrate one control period with the held (or watchdog) command."""
        self.simulation.advance(self._effective_command())
        self._counters["steps"] += 1
        self._effective_command()  # watchdog state for the interval that starts now

    def lockstep_timeout(self) -> None:
        """The command for t_k did not come in time: count it, keep the last one."""
        self._counters["lockstep_timeouts"] += 1

    # -- run-time changes (services) ------------------------------------------
    def set_configuration(self, name: str) -> None:
        """Switch configuration in flight (state and efficiencies carry over)."""
        self.simulation.set_configuration(name)
        self.config.vehicle = name

    def set_thruster_efficiency(self, efficiency) -> None:
        self.simulation.set_thruster_efficiency(efficiency)

    def set_current(self, params: CurrentParams | None) -> None:
        """Change the current (None: off); statistics beyond ``environment/limits.yaml`` are refused."""
        if params is not None:
            self.limits.check_current(params)
        self.simulation.set_current(params)

    def schedule_current(self, params: CurrentParams | None, at: float) -> None:
        """:meth:`set_current` at simulated time ``at`` [s] (exactly at that step, whatever the transport
        delay of the request; at once when it has passed)."""
        if params is not None:
            self.limits.check_current(params)
        if not (math.isfinite(at) and at >= 0.0):
            raise ValueError(f"the time of a change must be finite and >= 0 s, got {at!r}")
        self.simulation.schedule(Event(max(float(at), self.simulation.t), "current", params))

    def current_params(self) -> CurrentParams:
        """The present current's statistics, or the environment's when there is no current."""
        if self.simulation.current is not None:
            return self.simulation.current.params
        return load_environment(self.config.environment).current.params

    def set_sensor_profile(self, name: str) -> None:
        self.simulation.set_sensor_profile(load_sensor_profile(name))
        self.config.environment = {**self.config.environment, "sensors": name}

    @property
    def sensor_profile(self):
        return self.simulation.sensors.profile

    # -- outputs ---------------------------------------------------------------
    def cable_shape(self, points: int = CABLE_POINTS):
        """The umbilical drawn at the present sample ((points, 3) NED, vehicle to ship:
        :meth:`seapup_sim.umbilical.Umbilical.shape`), or None without one."""
        umbilical = self.simulation.umbilical
        return None if umbilical is None else umbilical.shape(self.simulation.plant.state, points)

    def outputs(self) -> dict:
        """Everything published at t_k (SI; NED world, FRD body): the
        :class:`~seapup_sim.simulation.Sample` and the applied blade pitch."""
        return {"sample": self.simulation.sample(), "applied_blade_pitch": self.simulation.plant.applied,
                "watchdog_active": self.watchdog_active}

    @staticmethod
    def check_finite(outputs: dict) -> None:
        """Raise FloatingPointError if any number to be published is not finite (never publish NaN)."""
        sample = outputs["sample"]
        arrays = [sample.state, sample.specific_force, sample.current_ned, sample.umbilical_body,
                  outputs["applied_blade_pitch"]]
        for name, array in zip(("state", "specific_force", "current", "umbilical", "blade pitch"), arrays):
            if not np.all(np.isfinite(array)):
                raise FloatingPointError(f"output {name} is not finite: {np.asarray(array).tolist()}")
