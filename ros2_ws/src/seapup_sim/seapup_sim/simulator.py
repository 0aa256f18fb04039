"""What the simulator node computes, without ROS.

:class:`Simulator` wraps a :class:`seapup_sim.simulation.Simulation` with the
node's contract:

- commands pass the :class:`~seapup_sim.blade_pitch.CommandGate` (wrong length
  or non-finite: rejected; beyond +/-35 deg: saturated) and, in lockstep, must
  carry the stamp of the present sample t_k (older: stale, newer: future --
  both rejected); every outcome is counted;
- a watchdog replaces the command with the hover (or neutral) setting when no
  valid command has arrived for ``watchdog_timeout`` simulated seconds;
- :meth:`outputs` returns everything the node publishes at t_k, in SI units,
  NED/FRD, ready to be copied into messages.

Nothing here sleeps, spins or publishes; the node decides when to step.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from seapup_sim.blade_pitch import CommandGate
from seapup_sim.current import CurrentParams, GaussMarkovCurrent
from seapup_sim.frames import euler_to_quaternion
from seapup_sim.sensors import load_sensor_profile
from seapup_sim.simulation import Simulation
from seapup_sim.vehicle import cross, rotation_body_to_ned
from seapup_sim.vehicle_config import load_vehicle_config

__all__ = ["SimulatorConfig", "Simulator", "HOVER_PITCH_DEG"]

#: the hover setting of eq. 5.2 [deg], the watchdog's default fallback
HOVER_PITCH_DEG = (-3.383, -3.383, -13.098, -13.098)


@dataclass
class SimulatorConfig:
    """The node's simulation parameters (SI)."""

    vehicle: str = "baseline"
    sensor_profile: str = "baseline"
    seed: int = 0
    physics_step: float = 0.1
    control_period: float = 0.2
    blade_pitch_limit: float = math.radians(35.0)
    watchdog_timeout: float = 1.0          # simulated seconds without a valid command
    watchdog_action: str = "hover"         # hover | neutral
    stamp_tolerance: float = 1e-6          # [s] for matching a command to t_k
    environment: dict = field(default_factory=dict)

    def validate(self) -> None:
        steps = self.control_period / self.physics_step
        if not (self.physics_step > 0 and self.control_period > 0):
            raise ValueError("physics_step and control_period must be > 0")
        if abs(steps - round(steps)) > 1e-9 or round(steps) < 1:
            raise ValueError(f"control_period {self.control_period} s must be a whole number of "
                             f"physics steps {self.physics_step} s")
        if self.watchdog_action not in ("hover", "neutral"):
            raise ValueError(f"watchdog_action must be hover or neutral, got {self.watchdog_action!r}")
        if not (0.0 < self.blade_pitch_limit <= math.radians(35.0) + 1e-12):
            raise ValueError("blade_pitch_limit must be in (0, 35 deg]")
        if not self.watchdog_timeout > 0:
            raise ValueError("watchdog_timeout must be > 0 s")


class Simulator:
    """The simulator's state machine (see module docstring)."""

    COUNTERS = ("accepted", "saturated", "rejected_invalid", "rejected_stale", "rejected_future",
                "rejected_malformed", "watchdog_trips", "lockstep_timeouts", "steps")

    def __init__(self, config: SimulatorConfig, state=None):
        config.validate()
        self.config = config
        self.counters = dict.fromkeys(self.COUNTERS, 0)
        self.last_error = ""
        self.reset(config.seed, state)

    # -- lifecycle -------------------------------------------------------------
    def reset(self, seed: int, state=None) -> None:
        """Time to 0, a new seed, the given (or rest) state, hover command."""
        c = self.config
        c.seed = int(seed)
        hover = np.radians(HOVER_PITCH_DEG)
        env = dict(c.environment)
        env["sensors"] = c.sensor_profile
        self.sim = Simulation.from_config(c.vehicle, env, seed=c.seed, dt=c.physics_step,
                                          control_period=c.control_period, state=state, pitch=hover)
        self.gate = CommandGate(limit=c.blade_pitch_limit)
        self.command = hover.copy()
        self.last_valid_time = 0.0
        self.watchdog_active = False

    @property
    def t(self) -> float:
        return self.sim.t

    @property
    def t_ns(self) -> int:
        return int(round(self.sim.t * 1e9))

    # -- commands ----------------------------------------------------------------
    def reject_malformed(self, reason: str) -> None:
        """Count a message that could not even be decoded."""
        self.counters["rejected_malformed"] += 1
        self.last_error = reason

    def submit(self, pitch, stamp_ns: int | None, lockstep: bool) -> tuple[bool, str]:
        """Offer a command; returns (accepted, reason)."""
        if stamp_ns is not None:
            dt = (stamp_ns - self.t_ns) * 1e-9
            if lockstep and dt < -self.config.stamp_tolerance:
                self.counters["rejected_stale"] += 1
                self.last_error = f"stale command stamped {stamp_ns * 1e-9:.3f} s at t = {self.t:.3f} s"
                return False, self.last_error
            horizon = self.config.stamp_tolerance if lockstep else self.config.control_period
            if dt > horizon:
                self.counters["rejected_future"] += 1
                self.last_error = f"command from the future: stamped {stamp_ns * 1e-9:.3f} s at t = {self.t:.3f} s"
                return False, self.last_error
        clipped_before = self.gate.saturated
        value = self.gate.submit(pitch)
        if value is None:
            self.counters["rejected_invalid"] += 1
            self.last_error = self.gate.last_error
            return False, self.last_error
        self.counters["accepted"] += 1
        if self.gate.saturated > clipped_before:
            self.counters["saturated"] += self.gate.saturated - clipped_before
        self.command = value
        self.last_valid_time = self.t
        self.watchdog_active = False
        return True, "saturated" if self.gate.saturated > clipped_before else "ok"

    def _effective_command(self) -> np.ndarray:
        if self.t - self.last_valid_time > self.config.watchdog_timeout + 1e-9:
            if not self.watchdog_active:
                self.watchdog_active = True
                self.counters["watchdog_trips"] += 1
            self.command = (np.radians(HOVER_PITCH_DEG) if self.config.watchdog_action == "hover"
                            else np.zeros(4))
        return self.command

    def step(self) -> None:
        """Integrate one control period with the held (or watchdog) command."""
        self.sim.advance(self._effective_command())
        self.counters["steps"] += 1
        self._effective_command()  # watchdog state for the interval that starts now

    def lockstep_timeout(self) -> None:
        """The command for t_k did not come in time: count it, keep the last one."""
        self.counters["lockstep_timeouts"] += 1

    # -- run-time changes (services) ------------------------------------------
    def set_configuration(self, name: str) -> None:
        cfg = load_vehicle_config(name)
        efficiency = self.sim.plant.model.thrusters.efficiency.copy()
        self.sim.plant.model.configure(cfg)
        if "thruster_efficiency" not in cfg:
            self.sim.plant.model.thrusters.set_efficiency(efficiency)
        self.config.vehicle = name

    def set_thruster_efficiency(self, efficiency) -> None:
        self.sim.plant.model.thrusters.set_efficiency(efficiency)

    def set_current(self, params: CurrentParams | None) -> None:
        if params is None:
            self.sim.current = None
        elif self.sim.current is None:
            self.sim.current = GaussMarkovCurrent(params, self.sim.plant.dt, self.sim.rng)
        else:
            self.sim.current.set_params(params)

    def set_sensor_profile(self, name: str) -> None:
        profile = load_sensor_profile(name)
        self.sim.sensors.profile = profile
        self.config.sensor_profile = name

    # -- outputs ---------------------------------------------------------------
    def outputs(self) -> dict:
        """Everything published at t_k (SI; NED world, FRD body)."""
        s = self.sim.sample()
        x = s.state
        m = s.measurement
        p = self.sim.sensors.profile
        rot = rotation_body_to_ned(*x[3:6])
        specific_force = self.sim.acceleration + cross(x[9:12], x[6:9]) - self.sim.plant.model.g * rot[2]
        return {
            "t": s.t,
            "state": x,
            "applied_pitch": self.sim.plant.pitch.copy(),
            "quaternion_truth": euler_to_quaternion(*x[3:6]),
            "velocity": m["velocity"], "velocity_var": np.square(p.velocity_std),
            "rates": m["rates"], "rates_var": np.square(p.rate_std),
            "attitude_quaternion": euler_to_quaternion(*m["attitude"]),
            "attitude_var": np.square(p.attitude_std),
            "specific_force": specific_force,
            "depth": m["depth"], "depth_var": p.depth_std ** 2,
            "altitude": m["altitude"], "altitude_var": p.altitude_std ** 2,
            "position": m["position"], "position_var": p.position_std ** 2,
            "current_ned": s.current_ned,
            "umbilical_body": s.umbilical_body,
            "watchdog_active": self.watchdog_active,
        }

    def check_finite(self, outputs: dict) -> None:
        """Raise if any published number is not finite (never publish NaN)."""
        for key, value in outputs.items():
            if value is None or isinstance(value, (bool, str)):
                continue
            if not np.all(np.isfinite(np.asarray(value, float))):
                raise FloatingPointError(f"output {key} is not finite: {value!r}")

