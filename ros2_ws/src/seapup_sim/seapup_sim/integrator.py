"""Fixed-step integration of the vehicle model with an exact actuator lag.

The thesis integrates the equations of motion with a fourth-order Runge-Kutta
scheme at 0.1 s (sec. 3.2: stable and accurate because the fastest pole is
-2.01 1/s and the fastest oscillation 0.40 Hz). :class:`VehicleIntegrator` does
the same, with two additions:

- blade pitch follows its command through a first-order lag of time constant
  tau (the pitch actuators are not instantaneous); with the command held
  constant over a step (zero-order hold, fig. 5.1) the lag is solved exactly,
  beta(t) = c + (beta_0 - c) exp(-t / tau), and evaluated at each Runge-Kutta
  stage, so a small tau never makes the integration stiff; tau = 0 applies
  commands at once;
- a state that becomes non-finite, or leaves the envelope in which the
  equations are valid, is never stored: :class:`DivergenceError` names the
  state variable, its value and the time.
"""
from __future__ import annotations

import numpy as np

from seapup_common.blade_pitch import check_blade_pitch
from seapup_sim.vehicle import STATE_NAMES, VehicleModel

__all__ = ["DivergenceError", "rk4_step", "VehicleIntegrator", "ENVELOPE"]

#: Largest magnitudes accepted for each state (the Euler kinematics are
#: singular at theta = 90 deg; speeds beyond these mean a diverged model).
ENVELOPE = np.array([1e5, 1e5, 1e4, np.inf, np.radians(85.0), np.inf,
                     20.0, 20.0, 20.0, 20.0, 20.0, 20.0])


class DivergenceError(FloatingPointError):
    """The integration produced a non-finite or out-of-envelope state."""


def rk4_step(f, t: float, x: np.ndarray, dt: float) -> np.ndarray:
    """One classical fourth-order Runge-Kutta step of x' = f(t, x)."""
    k1 = f(t, x)
    k2 = f(t + 0.5 * dt, x + 0.5 * dt * k1)
    k3 = f(t + 0.5 * dt, x + 0.5 * dt * k2)
    k4 = f(t + dt, x + dt * k3)
    return x + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


class VehicleIntegrator:
    """The vehicle's state, blade-pitch actuator state and time.

    Parameters
    ----------
    model : VehicleModel
    dt : float
        Integration step [s] (default 0.1 s, thesis sec. 3.2).
    state : array (12,), optional
        Initial state (default: at rest at the origin).
    pitch : array (4,), optional
        Initial applied blade pitches [rad] (default zero).
    """

    def __init__(self, model: VehicleModel, dt: float = 0.1, state=None, pitch=None):
        if not (np.isfinite(dt) and 0.0 < dt <= 1.0):
            raise ValueError(f"integration step must be in (0, 1] s, got {dt!r}")
        self.model = model
        self.dt = float(dt)
        self.steps = 0  # time is steps * dt: no drift from repeated addition
        self.state = np.zeros(12) if state is None else np.array(state, float)
        self.pitch = np.zeros(4) if pitch is None else np.array(pitch, float)
        self.thrusters_on = True
        self._check(self.state, 0.0)

    @property
    def t(self) -> float:
        """Simulated time [s]."""
        return self.steps * self.dt

    def _pitch_at(self, command: np.ndarray, elapsed: float) -> np.ndarray:
        tau = self.model.actuator_time_constant
        if tau <= 0.0:
            return command
        return command + (self.pitch - command) * np.exp(-elapsed / tau)

    def _check(self, state: np.ndarray, t: float) -> None:
        bad = ~np.isfinite(state) | (np.abs(state) > ENVELOPE)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise DivergenceError(
                f"state {STATE_NAMES[i]} = {state[i]!r} at t = {t:.3f} s is "
                f"{'not finite' if not np.isfinite(state[i]) else 'outside the valid envelope'} "
                f"(|{STATE_NAMES[i]}| <= {ENVELOPE[i]:.4g}); the state was not updated")

    def step(self, command, current_ned=None, external=None) -> np.ndarray:
        """Advance one step with ``command`` [rad] held; return the new state (copy)."""
        command, _ = check_blade_pitch(command, self.model.pitch_limit)
        t0 = self.t
        model, on = self.model, self.thrusters_on
        # the lagged pitch at rk4_step's three distinct stage times (computed the
        # same way, so the float keys match exactly)
        dt = self.dt
        stage_pitch = {t0: self._pitch_at(command, 0.0), t0 + 0.5 * dt: self._pitch_at(command, 0.5 * dt),
                       t0 + dt: self._pitch_at(command, dt)}

        def f(t, x):
            return model.derivatives(x, stage_pitch[t], current_ned, external, on)

        new = rk4_step(f, t0, self.state, self.dt)
        self._check(new, t0 + self.dt)
        new[3] = (new[3] + np.pi) % (2 * np.pi) - np.pi  # roll and yaw wrap to [-pi, pi)
        new[5] = (new[5] + np.pi) % (2 * np.pi) - np.pi
        self.pitch = stage_pitch[t0 + dt]
        self.state = new
        self.steps += 1
        return new.copy()
