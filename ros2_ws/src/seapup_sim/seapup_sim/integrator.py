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

The step is taken by compiled kernels (:mod:`seapup_sim.compiled`) when numba
is available and the model is a plain :class:`VehicleModel`; the NumPy code of
:meth:`VehicleModel.derivatives` and :func:`rk4_step` is the reference they
are tested against, and the path of any model that overrides ``derivatives``
(the linearised model) or of ``backend="numpy"`` / ``SEAPUP_PLANT=numpy``.
"""
from __future__ import annotations

import functools
import os

import numpy as np

from seapup_common.blade_pitch import check_blade_pitch, within_limits
from seapup_common.kernels import numba_installed
from seapup_sim.vehicle import STATE_NAMES, VehicleModel

__all__ = ["DivergenceError", "rk4_step", "VehicleIntegrator", "ENVELOPE", "BACKENDS", "default_backend", "divergence"]

#: How a step is taken: numba kernels or the NumPy reference.
BACKENDS = ("compiled", "numpy")

#: Largest magnitudes accepted for each state (the Euler kinematics are
#: singular at theta = 90 deg; speeds beyond these mean a diverged model).
ENVELOPE = np.array([1e5, 1e5, 1e4, np.inf, np.radians(85.0), np.inf,
                     20.0, 20.0, 20.0, 20.0, 20.0, 20.0])


def default_backend() -> str:
    """``compiled`` unless ``SEAPUP_PLANT=numpy`` asks for the reference or numba is not installed."""
    choice = os.environ.get("SEAPUP_PLANT", "").strip().lower() or "compiled"
    if choice not in BACKENDS:
        raise ValueError(f"SEAPUP_PLANT must be one of {', '.join(BACKENDS)}, got {choice!r}")
    return "compiled" if choice == "compiled" and numba_installed() else "numpy"


_NONE3, _NONE6 = np.zeros(3), np.zeros(6)
_KERNELS = []   # seapup_sim.compiled once loaded (numba with it): a step does not pay for an import statement


def _kernels():
    """:mod:`seapup_sim.compiled`, imported on the first call."""
    if not _KERNELS:
        from seapup_sim import compiled
        _KERNELS.append(compiled)
    return _KERNELS[0]


@functools.lru_cache(maxsize=8)
def _still_water(steps: int) -> np.ndarray:
    """(steps, 3) zeros: the currents of a period with no current (the kernel reads none of them). Writable, as
    the arrays :func:`seapup_sim.compiled.warm` compiles the kernel for: a read-only one is another numba type,
    compiled on its first call -- seconds in which a lockstep simulator answers nobody."""
    return np.zeros((steps, 3))


def _command(command, limit: float) -> np.ndarray:
    """A blade-pitch command for the kernels: :func:`~seapup_common.blade_pitch.check_blade_pitch`'s result, with
    a fast path for the usual case (:func:`~seapup_common.blade_pitch.within_limits`: returned as it is, not
    copied)."""
    if within_limits(command, limit):
        return command if command.flags.c_contiguous else np.ascontiguousarray(command)
    return check_blade_pitch(command, limit)[0]


def divergence(state: np.ndarray, t: float) -> str:
    """Why ``state`` (12,) at time ``t`` must not be stored (non-finite or outside :data:`ENVELOPE`), or ''."""
    bad = ~np.isfinite(state) | (np.abs(state) > ENVELOPE)
    if not bad.any():
        return ""
    i = int(np.flatnonzero(bad)[0])
    return (f"state {STATE_NAMES[i]} = {state[i]!r} at t = {t:.3f} s is "
            f"{'not finite' if not np.isfinite(state[i]) else 'outside the valid envelope'} "
            f"(|{STATE_NAMES[i]}| <= {ENVELOPE[i]:.4g}); the state was not updated")


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
    backend : {"compiled", "numpy"}, optional
        How steps are taken (default :func:`default_backend`); a model that
        overrides ``derivatives`` always steps with the NumPy reference.
    """

    def __init__(self, model: VehicleModel, dt: float = 0.1, state=None, pitch=None, backend: str | None = None):
        if not (np.isfinite(dt) and 0.0 < dt <= 1.0):
            raise ValueError(f"integration step must be in (0, 1] s, got {dt!r}")
        backend = default_backend() if backend is None else backend
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
        self.backend = backend
        self._packed = (None, None)  # ((the model, its revision) it was packed from, the packed arrays)
        self.model = model
        self.dt = float(dt)
        self.steps = 0  # time is steps * dt: no drift from repeated addition
        self.state = np.zeros(12) if state is None else np.array(state, float)
        #: the four inputs held (the gate's last command; zero at the start)
        self.held = np.zeros(4) if pitch is None else np.array(pitch, float)
        #: the actuators' state: the Seapup's blade pitches [rad], a fixed-pitch thruster's lagged command
        self.pitch = np.array(model.inputs.to_actuators(self.held), float)
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
        reason = divergence(state, t)
        if reason:
            raise DivergenceError(reason)

    @property
    def compiled(self) -> bool:
        """Whether the next step runs the compiled kernels."""
        return self.backend == "compiled" and type(self.model).derivatives is VehicleModel.derivatives

    def _compiled_arrays(self):
        """The model packed for the kernels, re-packed when it was reconfigured (its ``revision``: configure()
        rebuilds its parts) or replaced; the thrusters' efficiency is read at every step."""
        model = self.model
        key = (model, model.revision)
        if self._packed[0] != key:
            compiled = _kernels()
            self._packed = (key, compiled.flatten(compiled.pack(model)))
        return self._packed[1]

    @property
    def applied(self) -> np.ndarray:
        """The four inputs presently applied (a copy): the blade pitches the Seapup's actuators have reached,
        or a virtual-input vehicle's command held (its thrusters' lag is behind the mixer)."""
        return (self.pitch if self.model.inputs.kind == "direct" else self.held).copy()

    def step(self, command, current_ned=None, external=None) -> np.ndarray:
        """Advance one step with the four inputs ``command`` held (blade pitches [rad], or virtual inputs
        mixed onto the thrusters: :mod:`seapup_sim.inputs`); return the new state (copy)."""
        if self.compiled:
            command = _command(command, self.model.pitch_limit)
            self.held = command
            return self._step_compiled(self.model.inputs.to_actuators(command), current_ned, external)
        command, _ = check_blade_pitch(command, self.model.pitch_limit)
        self.held = command
        command = self.model.inputs.to_actuators(command)
        t0 = self.t
        model, on = self.model, self.thrusters_on
        # the lagged pitch at rk4_step's three distinct stage times (computed the
        # same way, so the float keys match exactly)
        dt = self.dt
        stage_pitch = {t0: self._pitch_at(command, 0.0), t0 + 0.5 * dt: self._pitch_at(command, 0.5 * dt),
                       t0 + dt: self._pitch_at(command, dt)}

        def f(t, x):
            return model.derivatives(x, stage_pitch[t], current_ned, external, on)

        return self._accept(rk4_step(f, t0, self.state, self.dt), stage_pitch[t0 + dt])

    def _step_compiled(self, command: np.ndarray, current_ned, external) -> np.ndarray:
        """:meth:`step` by one kernel call (:func:`seapup_sim.compiled.rk4_checked`: the step, its check and the
        angle wrap), the same arithmetic as the reference's step then :meth:`_accept`."""
        new, pitch = np.empty(12), np.empty(len(command))
        bad = _kernels().rk4_checked(
            np.ascontiguousarray(self.state, dtype=np.float64), np.ascontiguousarray(self.pitch, dtype=np.float64),
            command, float(self.model.actuator_time_constant), self.dt,
            _NONE3 if current_ned is None else np.ascontiguousarray(current_ned, dtype=np.float64),
            current_ned is not None,
            _NONE6 if external is None else np.ascontiguousarray(external, dtype=np.float64), external is not None,
            bool(self.thrusters_on), np.ascontiguousarray(self.model.thrusters.efficiency, dtype=np.float64),
            *self._compiled_arrays(), ENVELOPE, new, pitch)
        if bad >= 0:
            raise DivergenceError(divergence(new, self.t + self.dt))
        self.pitch = pitch
        self.state = new
        self.steps += 1
        return new.copy()

    def step_period(self, command, steps: int, currents: np.ndarray | None = None) -> np.ndarray:
        """``steps`` physics steps with ``command`` held, step i in the current ``currents[i]`` (NED, (steps, 3);
        None: no current), by one kernel call (:func:`seapup_sim.compiled.rk4_period`): the steps of
        :meth:`step` one after another, bit for bit (tested), for a compiled plant with no external wrench.
        Returns d(u, v, w)/dt over the last step [m/s^2]."""
        from seapup_sim import compiled
        if not self.compiled:
            raise RuntimeError("step_period needs the compiled plant (the reference steps one at a time)")
        command = _command(command, self.model.pitch_limit)
        self.held = command
        use_current = currents is not None
        if currents is None:
            currents = _still_water(steps)
        elif currents.shape != (steps, 3):
            raise ValueError(f"step_period: {steps} steps need currents of shape ({steps}, 3), got {currents.shape}")
        command = self.model.inputs.to_actuators(command)
        states, pitches, accel = np.empty((steps, 12)), np.empty((steps, len(command))), np.empty(3)
        bad = compiled.rk4_period(
            self.state, self.pitch, command, float(self.model.actuator_time_constant), self.dt, currents,
            use_current, _NONE6, False, bool(self.thrusters_on), self.model.thrusters.efficiency,
            *self._compiled_arrays(), ENVELOPE, states, pitches, accel)
        if bad >= 0:
            good = bad // 12
            if good:   # the steps before the bad one are taken, as step() one at a time takes them
                self.state, self.pitch = states[good - 1], pitches[good - 1]
                self.steps += good
            raise DivergenceError(divergence(states[good], self.t + self.dt))
        self.state, self.pitch = states[-1], pitches[-1]
        self.steps += steps
        return accel

    def _accept(self, new: np.ndarray, pitch: np.ndarray) -> np.ndarray:
        self._check(new, self.t + self.dt)
        new[3] = (new[3] + np.pi) % (2 * np.pi) - np.pi  # roll and yaw wrap to [-pi, pi)
        new[5] = (new[5] + np.pi) % (2 * np.pi) - np.pi
        self.pitch = pitch
        self.state = new
        self.steps += 1
        return new.copy()
