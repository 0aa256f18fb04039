"""Many vehicles stepped together: the batch plant of Monte Carlo campaigns (issue 26).

:class:`BatchPlant` holds N vehicles on a leading batch axis -- states (N, 12), applied blade pitches
(N, 4) -- each with its own configuration (a :class:`~seapup_sim.vehicle.VehicleModel` built from any
configuration and overlay: baseline, camera, fouled, a perturbed hydrodynamic table), its own thruster
efficiencies, and its own current and external wrench at every step. One :meth:`BatchPlant.step` is one
physics step (eq. 2.1-2.3 by fourth-order Runge-Kutta with the exact blade-pitch lag, as
:class:`~seapup_sim.integrator.VehicleIntegrator`) of every vehicle, in one compiled call that runs the
single-vehicle kernel of :mod:`seapup_sim.compiled` on each: vehicle i of a batch equals the same vehicle
stepped alone, bit for bit (``test/test_batch.py``).

What differs from the single-vehicle integrator is what one vehicle's failure does. A vehicle whose step
would leave the envelope (or become non-finite) is not integrated: its state is kept, it is marked
inactive with the reason (:attr:`BatchPlant.errors`, the message :class:`DivergenceError` would carry) and
the others go on. Bad input -- a command, current or wrench of the wrong shape or not finite -- is refused
for the whole step with one line naming the vehicles, and nothing is integrated.
"""
from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from seapup_common.blade_pitch import InvalidBladePitchError
from seapup_sim import compiled
from seapup_sim.current import GaussMarkovCurrent
from seapup_sim.integrator import ENVELOPE, divergence
from seapup_sim.sensors import SensorSuite
from seapup_sim.thrusters import check_efficiency
from seapup_sim.vehicle import VehicleModel

__all__ = ["BatchPlant", "BatchCurrent", "BatchSensors"]


def _rows(name: str, value, n: int, width: int) -> np.ndarray:
    """``value`` as an (n, width) float array, or a one-line error naming what is wrong."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} is not numeric") from None
    if array.shape != (n, width):
        raise ValueError(f"{name} needs shape ({n}, {width}) (one row per vehicle), got {array.shape}")
    if np.isfinite(array).all():   # the usual case in one pass; the rows are named only when one is bad
        return np.ascontiguousarray(array)
    bad = ~np.isfinite(array).all(axis=1)
    if bad.any():
        shown = ", ".join(str(i) for i in np.flatnonzero(bad)[:8])
        raise ValueError(f"{name} is not finite for vehicle(s) {shown}{' ...' if bad.sum() > 8 else ''}")
    return np.ascontiguousarray(array)


class BatchPlant:
    """N vehicles, one physics step at a time.

    Parameters
    ----------
    models : sequence of VehicleModel
        One per vehicle (the same object may appear more than once). A model that overrides
        ``derivatives`` (the linearised plant) is refused: it has no compiled kernel.
    dt : float
        Physics step [s] (default 0.1 s, thesis sec. 3.2).
    states : array (N, 12), optional
        Initial states (default: at rest at the origin).
    pitches : array (N, 4), optional
        Initial applied blade pitches [rad] (default zero).
    threads : int
        Threads stepping the vehicles, each a contiguous part of the batch in the compiled kernel (which
        releases the GIL); default 1. The result is the same bits for any number. Leave it at 1 where
        processes already share the cores (a campaign's workers).
    """

    def __init__(self, models, dt: float = 0.1, states=None, pitches=None, threads: int = 1):
        self.models = list(models)
        n = len(self.models)
        if n == 0:
            raise ValueError("a batch needs at least one vehicle")
        for i, model in enumerate(self.models):
            if not isinstance(model, VehicleModel) or type(model).derivatives is not VehicleModel.derivatives:
                raise ValueError(f"vehicle {i}: a batch steps VehicleModel's equations only, "
                                 f"not {type(model).__name__}'s")
            if model.thrusters.kind != "controllable_pitch":
                raise ValueError(f"vehicle {i} ({model.config_name}): a batch steps four blade pitches per "
                                 "vehicle; its thrusters are "
                                 f"{model.thrusters.kind.replace('_', '-')} behind a mixer: fly it run by run")
        if not (np.isfinite(dt) and 0.0 < dt <= 1.0):
            raise ValueError(f"integration step must be in (0, 1] s, got {dt!r}")
        if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
            raise ValueError(f"threads must be a whole number >= 1, got {threads!r}")
        self.n = n
        self.threads = min(int(threads), n)
        self._pool = ThreadPoolExecutor(self.threads - 1, "batch-plant") if self.threads > 1 else None
        self._still = (np.zeros((n, 3)), np.zeros((n, 6)))   # a step's currents and wrenches when given none
        self.dt = float(dt)
        self.steps = 0
        self.state = np.zeros((n, 12)) if states is None else _rows("states", states, n, 12).copy()
        self.pitch = np.zeros((n, 4)) if pitches is None else _rows("pitches", pitches, n, 4).copy()
        self.thrusters_on = np.ones(n, dtype=bool)
        #: False once a vehicle's step diverged; it is not integrated again
        self.active = np.ones(n, dtype=bool)
        #: why each inactive vehicle stopped (None while it runs)
        self.errors: list[str | None] = [None] * n
        self._pack()

    @classmethod
    def from_configs(cls, configs, **kwargs) -> "BatchPlant":
        """A batch of one :class:`VehicleModel` per configuration dict (configurations that are the same
        object share one model)."""
        models, built = [], {}
        for config in configs:
            if id(config) not in built:
                built[id(config)] = VehicleModel(config)
            models.append(built[id(config)])
        return cls(models, **kwargs)

    @property
    def t(self) -> float:
        """Simulated time [s]."""
        return self.steps * self.dt

    def _pack(self) -> None:
        self._packed = compiled.pack_batch(self.models)
        self._taus = np.array([m.actuator_time_constant for m in self.models], dtype=float)
        self.efficiency = np.ascontiguousarray([m.thrusters.efficiency for m in self.models], dtype=float)
        self._limits = np.array([m.pitch_limit for m in self.models], dtype=float)

    def configure(self, index: int, config: dict) -> None:
        """Vehicle ``index`` switches to ``config`` (state and pitch kept, as ``Simulation``'s configuration
        events): it gets a model of its own, so vehicles that shared one are not changed with it."""
        efficiency = self.efficiency.copy()
        self.models[index] = VehicleModel(config)
        self._pack()
        self.efficiency[:] = efficiency   # a configuration change keeps the fouling (Simulation does too)

    def set_efficiency(self, index: int, efficiency) -> None:
        """Vehicle ``index``'s four thruster efficiencies (fouling, sec. 7.4.4): checked as
        ``ThrusterSet.set_efficiency`` checks them (4 finite factors in [0, 1.5])."""
        self.efficiency[index] = check_efficiency(efficiency)

    def step(self, commands, currents=None, externals=None) -> np.ndarray:
        """Advance every active vehicle one step with its ``commands`` row [rad] held (clipped to the blade
        limits); ``currents`` (N, 3) NED water velocities [m/s] and ``externals`` (N, 6) body wrenches, each
        held over the step. Returns the new states (a copy)."""
        try:
            commands = _rows("blade-pitch commands", commands, self.n, 4)
        except ValueError as exc:
            raise InvalidBladePitchError(str(exc)) from None
        commands = np.clip(commands, -self._limits[:, None], self._limits[:, None])
        use_current, use_external = currents is not None, externals is not None
        currents = _rows("currents", currents, self.n, 3) if use_current else self._still[0]
        externals = _rows("external wrenches", externals, self.n, 6) if use_external else self._still[1]
        new, pitch_end, status = np.empty((self.n, 12)), np.empty((self.n, 4)), np.empty(self.n, dtype=np.int64)
        ints, floats, which = self._packed
        per_vehicle = (self.state, self.pitch, commands, self._taus, currents, externals, self.thrusters_on,
                       self.efficiency, which, self.active, new, pitch_end, status)

        def part(lo, hi):
            (state, pitch, command, tau, current, external, on, efficiency, rows, active, new_, pitch_, status_) = \
                (a[lo:hi] for a in per_vehicle)
            compiled.rk4_batch(state, pitch, command, tau, self.dt, current, use_current, external, use_external, on,
                               efficiency, ints, floats, rows, ENVELOPE, active, new_, pitch_, status_)
        if self._pool is None:
            part(0, self.n)
        else:
            bounds = [self.n * k // self.threads for k in range(self.threads + 1)]
            others = [self._pool.submit(part, lo, hi) for lo, hi in zip(bounds[1:-1], bounds[2:])]
            part(bounds[0], bounds[1])   # the first part in this thread: one hand-over fewer
            for future in others:
                future.result()
        for i in np.flatnonzero(status >= 0):   # stepped out of the envelope: stopped, its last state kept
            self.errors[i] = divergence(new[i], self.t + self.dt)   # the single integrator's words
            self.active[i] = False
            new[i], pitch_end[i] = self.state[i], self.pitch[i]
        self.state[:] = new   # in place, as before (the kernel wrapped roll and yaw)
        self.pitch[:] = pitch_end
        self.steps += 1
        return self.state.copy()


class BatchCurrent:
    """N Gauss-Markov currents (eq. 2.25-2.33) advanced together, each from its own random stream.

    Built from N :class:`~seapup_sim.current.GaussMarkovCurrent` (each with its generator: a run's
    ``current`` stream, so vehicle i's current is the one its run alone would meet). The state and the
    coefficients are vectors; the noise comes from each vehicle's own generator, drawn ``block`` samples
    at a time (a generator's ``standard_normal(n)`` is its next n single draws), so the speeds and directions
    equal the single currents' bit for bit while the Python work per step does not grow with N.

    Parameters
    ----------
    currents : sequence of GaussMarkovCurrent
        Taken over: step them only through this object from now on.
    block : int
        Normal draws per generator refill.
    """

    def __init__(self, currents, block: int = 256):
        self.currents = list(currents)
        if not self.currents or not all(isinstance(c, GaussMarkovCurrent) for c in self.currents):
            raise ValueError("a batch current needs at least one GaussMarkovCurrent")
        if len({c.sample_time for c in self.currents}) != 1:
            raise ValueError("the currents of a batch share one sample time")
        if int(block) < 1:
            raise ValueError(f"block must be >= 1, got {block!r}")
        self.n, self.block = len(self.currents), int(block)
        self.speed = np.array([c.speed for c in self.currents], dtype=float)
        self.direction = np.array([c.direction for c in self.currents], dtype=float)
        self._noise = np.empty((self.n, self.block))
        self._used = np.full(self.n, self.block)   # draws taken from each row of _noise
        self._coefficients()

    def _coefficients(self) -> None:
        coef = [c.coef for c in self.currents]
        self._a_c = np.array([k.a_c for k in coef])
        self._a_alpha = np.array([k.a_alpha for k in coef])
        self._b = np.array([k.b for k in coef])
        self._d = np.array([k.d for k in coef])
        self._sigma_w = np.array([math.sqrt(k.var_w_c) if k.var_w_c > 0 else 0.0 for k in coef])
        self._ratio = np.array([k.w_alpha_per_w_c for k in coef])
        self._noisy = np.array([k.var_w_c > 0 for k in coef])

    def set_params(self, index: int, params, reset: bool = False) -> None:
        """Vehicle ``index``'s current statistics change (:meth:`GaussMarkovCurrent.set_params`)."""
        current = self.currents[index]
        current.speed, current.direction = float(self.speed[index]), float(self.direction[index])
        current.set_params(params, reset)
        self.speed[index], self.direction[index] = current.speed, current.direction
        self._coefficients()

    def step(self) -> None:
        """Advance every current one sample (eq. 2.25, 2.26, 2.33)."""
        empty = self._noisy & (self._used >= self.block)
        for i in np.flatnonzero(empty):
            self._noise[i] = self.currents[i].rng.standard_normal(self.block)
            self._used[i] = 0
        rows = np.arange(self.n)
        z = np.where(self._noisy, self._noise[rows, np.minimum(self._used, self.block - 1)], 0.0)
        self._used += self._noisy
        w_c = np.where(self._noisy, self._sigma_w * z, 0.0)
        w_a = self._ratio * w_c
        self.speed = self._a_c + self._b * self.speed + self._d * w_c
        self.direction = self._a_alpha + self._b * self.direction + self._d * w_a

    def velocity_ned(self) -> np.ndarray:
        """(N, 3) current velocities in NED [m/s] (horizontal), as each current's own ``velocity_ned``."""
        out = np.zeros((self.n, 3))
        compiled.polar_to_ned(self.speed, self.direction, out)
        return out


class _Draws:
    """One instrument's random draws for N vehicles: each vehicle's own generator, read ``block`` draws
    at a time (a generator's ``standard_normal(n)`` / ``random(n)`` is its next n single draws), ``k`` per
    reading, so every vehicle sees the sequence its instrument alone would draw."""

    def __init__(self, generators, k: int, uniform: bool = False, readings: int = 85, unused=None):
        self.generators, self.k, self.uniform = list(generators), k, uniform
        self.n, self.block = len(self.generators), k * readings
        self.buffer = np.empty((self.n, self.block))
        self.used = np.full(self.n, self.block)
        for i, left in enumerate(unused or ()):   # draws a single suite read and did not use come first
            if len(left):
                if len(left) % k or len(left) > self.block:
                    raise ValueError(f"vehicle {i}: {len(left)} unused draws are not whole readings of {k}")
                self.used[i] = self.block - len(left)
                self.buffer[i, self.used[i]:] = left

    def take(self, mask: np.ndarray) -> np.ndarray:
        """(N, k) draws: the next k of each vehicle in ``mask``, zeros for the others (who draw nothing)."""
        for i in np.flatnonzero(mask & (self.used >= self.block)):
            g = self.generators[i]
            self.buffer[i] = g.random(self.block) if self.uniform else g.standard_normal(self.block)
            self.used[i] = 0
        rows = np.flatnonzero(mask)
        out = np.zeros((self.n, self.k))
        out[rows] = self.buffer[rows[:, None], self.used[rows, None] + np.arange(self.k)]
        self.used[rows] += self.k
        return out


class BatchSensors:
    """The sensors of N vehicles read together: :meth:`SensorSuite.measure` of each, as arrays.

    Built from N :class:`~seapup_sim.sensors.SensorSuite` (taken over: read them only through this object
    from now on), each with its profile, seabed and random streams, so vehicle i's readings equal those its
    suite alone would give, bit for bit (``test/test_batch.py``): the same noise draws from the same
    streams, conditional draws (an altimeter echo, an acoustic fix that is not lost) only where the single
    suite draws, and the same arithmetic. Strapdown velocity (App. A.3) integrates each vehicle's own
    accelerometers and is left to the single suite: a profile with it enabled is refused.

    :meth:`measure` returns the readings as arrays with NaN where a reading is invalid (no echo, no fix):
    ``velocity`` (N, 3), ``rates`` (N, 3), ``attitude`` (N, 3), ``depth`` (N,), ``altitude`` (N,),
    ``position`` (N, 3).
    """

    def __init__(self, suites):
        self.suites = list(suites)
        if not self.suites or not all(isinstance(s, SensorSuite) for s in self.suites):
            raise ValueError("batch sensors need at least one SensorSuite")
        for i, suite in enumerate(self.suites):
            if suite.profile.strapdown_enabled:
                raise ValueError(f"vehicle {i}: strapdown velocity (profile {suite.profile.name!r}) is read by "
                                 "the single SensorSuite only")
        self.n = len(self.suites)
        profiles = [s.profile for s in self.suites]

        def column(name):
            return np.array([getattr(p, name) for p in profiles], dtype=float)
        self._std = {"velocity": column("velocity_std"), "rates": column("rate_std"),
                     "attitude": column("attitude_std"), "depth": column("depth_std")[:, None],
                     "altitude": column("altitude_std")[:, None], "position": np.repeat(column("position_std")[:, None], 3, 1)}
        self._noisy = {name: (std > 0).any(axis=1) for name, std in self._std.items()}
        self._draws = {name: _Draws([s.rng[name] for s in self.suites], std.shape[1],
                                    unused=[s.unused_normals(name) for s in self.suites])
                       for name, std in self._std.items()}
        self._dropout_draws = _Draws([s.rng["position_dropout"] for s in self.suites], 1, uniform=True)
        self._fix_period = 1.0 / column("position_rate_hz")
        self._dropout = column("position_dropout")
        self._alt_range = column("altimeter_min_range"), column("altimeter_max_range")
        self._next_fix = np.array([s._next_fix for s in self.suites], dtype=float)
        # vehicles over the same seabed (equal profiles, not only one object) are read together
        groups: dict = {}
        for i, suite in enumerate(self.suites):
            b = suite.seabed
            if b is not None:
                key = (b.kind, b.depth, b.gradient, b.direction, b.points.tobytes())
                groups.setdefault(key, (b, []))[1].append(i)
        self._seabed_groups = [(b, np.array(rows)) for b, rows in groups.values()]

    def _noise(self, name: str) -> np.ndarray:
        return self._std[name] * self._draws[name].take(self._noisy[name])

    def _altitude(self, states: np.ndarray) -> np.ndarray:
        out = np.full(self.n, np.nan)
        vertical = np.full(self.n, np.nan)
        for seabed, rows in self._seabed_groups:
            vertical[rows] = seabed.depth_at(states[rows, 0], states[rows, 1]) - states[rows, 2]
        tilt = np.empty(self.n)
        compiled.cos_product(np.ascontiguousarray(states[:, 3]), np.ascontiguousarray(states[:, 4]), tilt)
        echo = (vertical > 0) & (tilt > 0)   # seabed below, beam pointing down (NaN: no seabed)
        z = self._draws["altitude"].take(echo & self._noisy["altitude"])[:, 0]
        reading = vertical[echo] / tilt[echo] + self._std["altitude"][echo, 0] * z[echo]
        low, high = self._alt_range
        out[echo] = np.where((low[echo] <= reading) & (reading <= high[echo]), reading, np.nan)
        return out

    def measure(self, t: float, states) -> dict:
        """Every vehicle's readings at ``t`` for its true state (a row of ``states`` (N, 12))."""
        states = np.asarray(states, dtype=float)
        att = states[:, 3:6] + self._noise("attitude")
        att[:, 0] = (att[:, 0] + math.pi) % (2 * math.pi) - math.pi
        att[:, 2] = (att[:, 2] + math.pi) % (2 * math.pi) - math.pi
        out = {"velocity": states[:, 6:9] + self._noise("velocity"), "rates": states[:, 9:12] + self._noise("rates"),
               "attitude": att, "depth": states[:, 2] + self._noise("depth")[:, 0], "altitude": self._altitude(states),
               "position": np.full((self.n, 3), np.nan)}
        due = t + 1e-9 >= self._next_fix
        if due.any():
            self._next_fix[due] = t + self._fix_period[due]
            kept = due & (self._dropout_draws.take(due)[:, 0] >= self._dropout)
            noise = self._std["position"] * self._draws["position"].take(kept & self._noisy["position"])
            out["position"][kept] = states[kept, :3] + noise[kept]
        return out
