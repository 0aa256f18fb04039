"""The MFOL velocity controller: Owens and Chotai's law flown through the controller contract.

A :class:`~seapup_common.contract.VelocityController` that runs the two-term
law of eq. 4.11 / 5.6 (gains from :func:`seapup_control.mfol.design`) on the
measured body velocities (u, v, w, r), with

- **gain scheduling** on surge speed (sec. 4.6, 5.3.1): the gains
  ``K_int``, ``K_err`` interpolated linearly between operating points at the
  *measured* surge speed, the offset ``u0(r)`` at the *reference* surge speed
  (eq. 5.6), both held constant beyond the first and last points;
- **anti-windup** (the thesis has none; ``anti_windup: false`` flies the thesis's
  law as written, ``q_{k+1} = q_k + e_k`` whatever the thrusters hold): every
  sample the integrator state
  is re-set so that the law reproduces the command the vehicle actually
  holds (saturated at the blade-pitch limit),
  ``q_k := K_int^-1 (u_sat,k - K_err e_k - u0)``, before ``q_{k+1} = q_k + e_k``.
  This is the incremental (velocity-form) realisation's anti-windup: while a
  thruster is saturated, the integrators cannot run away, and the command
  leaves the limit as soon as the error asks it to;
- **bumpless start**: :meth:`reset` sets ``q`` so that the first command
  equals the applied one when the error is zero (the same back-calculation).

The anti-windup uses the controller's own saturated command, as the thesis's
controller knows it; the blade pitch the vehicle reports applied
(:meth:`MFOLController.applied`: lagged by the actuators, or another setting
while a watchdog or another controller held the thrusters) is kept and shown
in :meth:`~MFOLController.diagnostics`, not integrated.

Registered as the controller type ``mfol`` (:data:`MFOL_TYPE`, entry point
``seapup.velocity_controllers``): parameters ``schedule`` (gain-schedule over
every operating point of the controller file, else only the zero-speed
point) and ``blade_pitch_limit`` [rad]; the design document is the
self-test's controller file (:func:`seapup_control.self_test.result_document`).

Bad measurements and references (non-finite, wrong length) never reach the
state: :meth:`update` raises :class:`~seapup_common.contract.ContractError`
and changes nothing.
"""
from __future__ import annotations

import bisect
import math
import types
from dataclasses import dataclass

import numpy as np
from scipy.linalg.lapack import dgesv as _dgesv

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT, INPUT_LIMIT_RANGE, VIRTUAL_INPUT_LIMIT
from seapup_common.contract import Command, ContractError, Measurement, Reference
from seapup_common.kernels import compiled_by_default
from seapup_common.controllers import ControllerType, Ranged
from seapup_control.mfol import DesignError, TwoTermGains

__all__ = ["GainSchedule", "MFOLController", "BatchMFOL", "ControllerState", "MFOL_TYPE", "create_mfol"]

SURGE = 0  # index of u among the outputs (u, v, w, r)


def solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.linalg.solve(a, b)`` for one square system by LAPACK's dgesv called directly (scipy's OpenBLAS build;
    numpy's solve calls the dgesv of its own build), without numpy's wrapping of every call (3 us of the law's
    sample, 0.7 us here). The two builds give the same numbers bit for bit here (tested over random systems, so
    a machine where they differ is told); were they to differ, the law would move at rounding level alike on
    the graph and in process, and a batch (``BatchMFOL``, numpy's stacked solve) equals its runs to 1e-9, not
    bit for bit. Raises ``np.linalg.LinAlgError`` for a singular ``a``, as numpy's does."""
    _, _, x, info = _dgesv(a, b)
    if info != 0:
        raise np.linalg.LinAlgError("Singular matrix" if info > 0 else f"dgesv: argument {-info} is invalid")
    return x


class GainSchedule:
    """Two-term gains at several surge speeds, linearly interpolated (sec. 4.6).

    Parameters
    ----------
    points : sequence of (float, TwoTermGains)
        (surge speed [m/s], gains designed about it), speeds strictly
        increasing; one point gives a fixed-gain controller.

    Raises
    ------
    DesignError
        On no points, unordered speeds, or gains of different sizes / sample periods.
    """

    def __init__(self, points):
        points = sorted(((float(s), g) for s, g in points), key=lambda p: p[0])
        if not points:
            raise DesignError("a gain schedule needs at least one operating point")
        speeds = np.array([s for s, _ in points])
        if not np.all(np.isfinite(speeds)) or np.any(np.diff(speeds) <= 0):
            raise DesignError(f"operating-point speeds must be finite and distinct, got {speeds.tolist()}")
        first = points[0][1]
        for _, g in points:
            if g.K_int.shape != first.K_int.shape or not math.isclose(g.sample_period, first.sample_period):
                raise DesignError("every operating point needs gains of the same size and sample period")
        self.speeds = speeds
        self.gains = [g for _, g in points]
        self.sample_period = first.sample_period
        self.size = first.K_int.shape[0]
        self._k_int = np.array([g.K_int for g in self.gains])
        self._k_err = np.array([g.K_err for g in self.gains])
        self._u0 = np.array([g.u0 for g in self.gains])
        self._both = np.stack([self._k_int, self._k_err], axis=1)   # (points, 2, n, n): one interpolation for both
        for table in (self._k_int, self._k_err, self._u0, self._both):   # gains_at hands out views of them
            table.setflags(write=False)
        self._speed_list = speeds.tolist()
        self.speeds_table = np.array(speeds)   # the operating points' speeds, read only (the compiled law's)
        self.speeds_table.setflags(write=False)

    @classmethod
    def from_document(cls, document) -> "GainSchedule":
        """The schedule of a controller file (:func:`seapup_control.self_test.result_document`).

        Raises
        ------
        DesignError
            If the document is not a seapup MFOL controller or its gains are malformed.
        """
        if not isinstance(document, dict) or document.get("kind") != "seapup/mfol_controller":
            raise DesignError("not a seapup MFOL controller file (kind: seapup/mfol_controller)")
        points = []
        try:
            period = float(document["sample_period"])
            for p in document["operating_points"]:
                gains = TwoTermGains(*(np.array(p[k], dtype=float) for k in ("K_int", "K_err", "u0", "y0")),
                                     period)
                if gains.K_int.shape != (4, 4) or gains.K_err.shape != (4, 4) or gains.u0.shape != (4,):
                    raise DesignError(f"operating point {p.get('surge')}: gains must be 4 x 4, u0 4 values")
                if not all(np.all(np.isfinite(a)) for a in (gains.K_int, gains.K_err, gains.u0)):
                    raise DesignError(f"operating point {p.get('surge')}: non-finite gains")
                points.append((float(p["surge"]), gains))
        except (KeyError, TypeError, ValueError) as exc:
            raise DesignError(f"malformed controller file: {exc}") from None
        return cls(points)

    def _weights(self, speed: float) -> tuple[int, int, float]:
        speeds = self._speed_list   # plain floats: the same comparisons and arithmetic as on the array's
        if len(speeds) == 1 or speed <= speeds[0]:
            return 0, 0, 0.0
        if speed >= speeds[-1]:
            last = len(speeds) - 1
            return last, last, 0.0
        j = bisect.bisect_left(speeds, speed) - 1   # np.searchsorted's (side "left") index
        return j, j + 1, (speed - speeds[j]) / (speeds[j + 1] - speeds[j])

    def gains_at(self, surge: float) -> tuple[np.ndarray, np.ndarray]:
        """(K_int, K_err) at a measured surge speed [m/s]."""
        i, j, w = self._weights(surge)
        if w == 0.0 and i == j:   # at an operating point or beyond the ends: (1 - 0) K + 0 K is K, bit for bit
            return self._k_int[i], self._k_err[i]
        both = (1 - w) * self._both[i] + w * self._both[j]   # each element as (1 - w) K_i + w K_j
        return both[0], both[1]

    def offset_at(self, surge_reference: float) -> np.ndarray:
        """u0(r): the inputs that hold a reference surge speed [rad] (eq. 5.6)."""
        i, j, w = self._weights(surge_reference)
        if w == 0.0 and i == j:
            return self._u0[i].copy()
        return (1 - w) * self._u0[i] + w * self._u0[j]


@dataclass(frozen=True)
class ControllerState:
    """What the controller did at its last sample (for diagnostics)."""

    t: float
    error: np.ndarray
    integrator: np.ndarray
    command_unsaturated: np.ndarray
    saturated: np.ndarray


class MFOLController:
    """Owens and Chotai's PI velocity controller (eq. 4.11, 5.6) with scheduling and anti-windup.

    Parameters
    ----------
    schedule : GainSchedule or TwoTermGains
        The gains (a single :class:`~seapup_control.mfol.TwoTermGains` is a fixed-gain controller).
    limit : float
        Blade-pitch limit [rad] the vehicle saturates at (default +/-35 deg).
    anti_windup : bool
        Back-calculated integrators (module docstring); False: the thesis's law as written.
    compiled : bool, optional
        The sample by the compiled kernel (:func:`seapup_control.compiled.mfol_sample`) or by the NumPy
        reference (False); default :func:`seapup_common.kernels.compiled_by_default`. The two give the same
        numbers (tested).

    Examples
    --------
    >>> from seapup_control.mfol import THESIS_POLES_5HZ, MFOLModel, design
    >>> model = MFOLModel(np.eye(4) * 0.01, np.eye(4) * 0.1, 0.2)   # decoupled, for the example
    >>> ctl = MFOLController(design(model, THESIS_POLES_5HZ))
    >>> ctl.reset(Command(np.zeros(4)))
    >>> at_rest = Measurement.build(0.0, velocity=(0.0, 0.0, 0.0), rates=(0.0, 0.0, 0.0))
    >>> ctl.update(0.0, at_rest, Reference([0.01, 0.0, 0.0, 0.0])).blade_pitch  # (100 * 0.4 - 10) * 0.01
    array([0.3, 0. , 0. , 0. ])
    """

    def __init__(self, schedule, limit: float = BLADE_PITCH_LIMIT, anti_windup: bool = True,
                 compiled: bool | None = None):
        self.schedule = schedule if isinstance(schedule, GainSchedule) else GainSchedule([(0.0, schedule)])
        if not (math.isfinite(limit) and limit > 0):
            raise DesignError(f"limit must be > 0 rad, got {limit!r}")
        self.limit = float(limit)
        self.anti_windup = bool(anti_windup)
        self.sample_period = self.schedule.sample_period
        m = self.schedule.size
        self.kernel = None   # seapup_control.compiled.mfol_sample, or None: the NumPy reference
        if m == 4 and (compiled_by_default() if compiled is None else compiled):
            from seapup_control.compiled import mfol_sample
            self.kernel = mfol_sample
            self._tables = (self.schedule.speeds_table, self.schedule._both, self.schedule._u0)
        # the compiled sample's work rows (seapup_control.compiled.mfol_sample): the integrators, the command to
        # start from, then the last sample's error, command before saturation, command and saturated flags
        self._work = np.zeros((6, m))
        self._starting = False       # reset() was called: the next sample starts bumpless
        self._last_t: float | None = None
        self.saturated_samples = np.zeros(m, dtype=int)
        self.last_applied: tuple[float, np.ndarray] | None = None  # (t, pitch) the vehicle reported

    @property
    def q(self) -> np.ndarray:
        """The integrators' state (a copy: what it is now)."""
        return self._work[0].copy()

    @q.setter
    def q(self, value) -> None:
        self._work[0] = value

    @property
    def state(self) -> ControllerState | None:
        """What the law did at its last sample (copies), None before the first sample after a reset."""
        if self._last_t is None:
            return None
        work = self._work
        return ControllerState(self._last_t, work[2].copy(), work[0].copy(), work[3].copy(), work[5] > 0.5)

    def reset(self, applied: Command) -> None:
        """Bumpless start: the integrator state that makes the first command the applied one at zero error.

        The state is set here for the zero-speed point and set again at the first :meth:`update`
        with the gains and offset scheduled for that sample, so a gain-scheduled controller
        switched in at speed does not step the thrusters by the schedule's difference from zero
        speed; the proportional term on that sample's error acts as it would have.
        """
        pitch = np.clip(np.asarray(applied.blade_pitch, float), -self.limit, self.limit)
        k_int, _ = self.schedule.gains_at(0.0)
        self.q = np.linalg.solve(k_int, pitch - self.schedule.offset_at(0.0))
        self._work[1] = pitch
        self._starting = True
        self._last_t = None
        self.saturated_samples[:] = 0
        self.last_applied = None

    def fallback_command(self) -> np.ndarray:
        """What to start from when no applied blade pitch is known: the zero-speed offset u0 [rad]."""
        return self.schedule.offset_at(0.0)

    def applied(self, t: float, command: Command) -> None:
        """Keep the blade pitch the vehicle reports applied at ``t`` (diagnostics only; see the module
        docstring: the anti-windup uses the controller's own saturated command)."""
        self.last_applied = (float(t), np.array(command.blade_pitch, dtype=float))

    def diagnostics(self) -> dict:
        """The last sample's error, integrator state, command before saturation, saturated thrusters,
        saturation counts, and the applied pitch last reported (empty before the first sample)."""
        state = self.state
        if state is None:
            return {}
        out = {"error": state.error.tolist(), "integrator": state.integrator.tolist(),
               "command_unsaturated": state.command_unsaturated.tolist(),
               "saturated": [bool(s) for s in state.saturated],
               "saturated_samples": self.saturated_samples.tolist()}
        if self.last_applied is not None:
            out["applied"] = self.last_applied[1].tolist()
        return out

    def update(self, t: float, measurement: Measurement, reference: Reference) -> Command:
        """One sample of eq. 5.6 with back-calculated integrators (see the module docstring): by the compiled
        kernel (:func:`seapup_control.compiled.mfol_sample`) or the NumPy reference (``compiled=False``).

        Raises
        ------
        ContractError
            If the measurement has no valid velocity/rate reading or the
            reference is not a :class:`Reference` (nothing changes).
        """
        velocity, rates = measurement.velocity.value, measurement.rates.value
        if velocity is None or rates is None:
            measurement.body_velocity()   # raises the contract's ContractError
        if not isinstance(reference, Reference):
            raise ContractError(f"reference must be a Reference, got {type(reference).__name__}")
        u, v, w = velocity.tolist()
        r = float(rates[2])
        if self.kernel is None or not math.isfinite(u + v + w + r):   # a reading the contract let through unchecked
            return self._update_numpy(t, np.concatenate((velocity, rates[2:])), reference.velocity)
        a, b, c, d = reference.velocity.tolist()
        work = self._work
        self.kernel(*self._tables, work, self.saturated_samples, u, v, w, r, a, b, c, d,
                    self._starting, self.limit, self.anti_windup)
        self._starting = False
        self._last_t = float(t)
        return Command(work[4], stamp=t)   # copied (and checked finite) by Command

    def _update_numpy(self, t: float, y: np.ndarray, r: np.ndarray) -> Command:
        """:meth:`update`'s sample in NumPy: the reference the compiled kernel is tested against."""
        error = r - y
        k_int, k_err = self.schedule.gains_at(float(y[SURGE]))
        u0 = self.schedule.offset_at(float(r[SURGE]))
        if self._starting:  # first sample after reset(): bumpless at this operating point
            self.q = solve(k_int, self._work[1] - u0)
            self._starting = False
        proportional = k_err @ error
        raw = k_int @ self.q + proportional + u0
        command = np.minimum(np.maximum(raw, -self.limit), self.limit)   # np.clip of finite values, at half its cost
        saturated = np.abs(raw) > self.limit
        if self.anti_windup:   # the state that reproduces the held command, then integrate
            self.q = solve(k_int, command - proportional - u0) + error
        else:                  # the thesis's law as written: q_{k+1} = q_k + e_k whatever the thrusters hold
            self.q = self.q + error
        self.saturated_samples += saturated
        work = self._work
        work[2], work[3], work[4], work[5] = error, raw, command, saturated
        self._last_t = float(t)
        return Command(command, stamp=t)


class BatchMFOL:
    """N :class:`MFOLController` flown together on (N, 4) arrays: for a campaign's batch of vehicles
    (:func:`seapup_runs.batch_runner.fly_batch`), where N controllers' Python would cost more than their
    plants.

    Each vehicle keeps its controller's schedule (any number of operating points), blade-pitch limit and
    anti-windup choice, and gets what :meth:`MFOLController.reset` / :meth:`MFOLController.update` would
    give it: the gains interpolated at its measured surge speed and the offset at its reference (sec. 4.6,
    eq. 5.6), the bumpless start at its first sample, the back-calculated integrators. The arithmetic is the
    single controller's with the per-vehicle products done as stacked ones (agreement to rounding;
    ``seapup_runs/test/test_batch_runner.py``).

    Parameters
    ----------
    controllers : sequence of MFOLController
        Their schedules, limits and anti-windup flags are read; the controllers themselves are not changed.
    """

    def __init__(self, controllers):
        controllers = list(controllers)
        if not controllers or not all(isinstance(c, MFOLController) for c in controllers):
            raise ValueError("a batch law needs at least one MFOLController")
        if len({c.schedule.size for c in controllers}) != 1 or controllers[0].schedule.size != 4:
            raise ValueError("every controller of a batch must have 4 outputs (u, v, w, r)")
        n, points = len(controllers), max(len(c.schedule.speeds) for c in controllers)
        self.n = n
        self.count = np.array([len(c.schedule.speeds) for c in controllers])
        self.speeds = np.full((n, points), np.inf)   # padding: never below a speed, never chosen
        self.k_int, self.k_err = np.zeros((n, points, 4, 4)), np.zeros((n, points, 4, 4))
        self.u0 = np.zeros((n, points, 4))
        for i, c in enumerate(controllers):
            m = self.count[i]
            self.speeds[i, :m] = c.schedule.speeds
            self.k_int[i, :m], self.k_err[i, :m], self.u0[i, :m] = c.schedule._k_int, c.schedule._k_err, c.schedule._u0
        self.limit = np.array([c.limit for c in controllers])[:, None]
        self.anti_windup = np.array([c.anti_windup for c in controllers])[:, None]
        self.q = np.zeros((n, 4))
        self._start_from: np.ndarray | None = None
        self._rows = np.arange(n)

    def _weights(self, speed: np.ndarray):
        """GainSchedule._weights of each vehicle: (i, j, w) arrays."""
        rows, last = self._rows, self.count - 1
        low = (self.count == 1) | (speed <= self.speeds[:, 0])
        high = ~low & (speed >= self.speeds[rows, last])
        j = np.clip((self.speeds < speed[:, None]).sum(axis=1) - 1, 0, None)
        mid = ~low & ~high
        i = np.where(low, 0, np.where(high, last, j))
        k = np.where(low, 0, np.where(high, last, np.minimum(j + 1, last)))
        w = np.zeros(self.n)
        w[mid] = (speed[mid] - self.speeds[rows[mid], j[mid]]) / (self.speeds[rows[mid], j[mid] + 1]
                                                                  - self.speeds[rows[mid], j[mid]])
        return i, k, w

    def _gains(self, surge: np.ndarray):
        i, k, w = self._weights(surge)
        a, b = (1 - w)[:, None, None], w[:, None, None]
        rows = self._rows
        return a * self.k_int[rows, i] + b * self.k_int[rows, k], a * self.k_err[rows, i] + b * self.k_err[rows, k]

    def _offset(self, surge_reference: np.ndarray):
        i, k, w = self._weights(surge_reference)
        return (1 - w)[:, None] * self.u0[self._rows, i] + w[:, None] * self.u0[self._rows, k]

    def reset(self, applied) -> None:
        """Bumpless start from the applied blade pitches (N, 4) [rad]: the first :meth:`update` makes them the
        command at zero error, at that sample's operating point."""
        self._start_from = np.clip(np.asarray(applied, dtype=float), -self.limit, self.limit)

    def update(self, y, reference) -> np.ndarray:
        """One sample of eq. 5.6 for every vehicle: measured (u, v, w, r) rows ``y``, reference rows; the
        commands (N, 4) [rad], saturated at each vehicle's limit."""
        y, r = np.asarray(y, dtype=float), np.asarray(reference, dtype=float)
        error = r - y
        k_int, k_err = self._gains(y[:, SURGE])
        u0 = self._offset(r[:, SURGE])
        if self._start_from is not None:
            self.q = np.linalg.solve(k_int, (self._start_from - u0)[..., None])[..., 0]
            self._start_from = None
        proportional = (k_err @ error[..., None])[..., 0]
        raw = (k_int @ self.q[..., None])[..., 0] + proportional + u0
        command = np.minimum(np.maximum(raw, -self.limit), self.limit)   # np.clip of finite values, at half its cost
        held = np.linalg.solve(k_int, (command - proportional - u0)[..., None])[..., 0] + error
        self.q = np.where(self.anti_windup, held, self.q + error)
        return command


def create_mfol(parameters: dict, document, sample_period: float | None) -> MFOLController:
    """The ``mfol`` controller type's factory (:class:`~seapup_common.controllers.ControllerType`).

    Parameters
    ----------
    parameters : dict
        ``schedule`` (bool): every operating point of the document as a gain schedule on surge
        speed (sec. 4.6), else only the first (zero-speed) point: fixed gains;
        ``blade_pitch_limit`` [rad], > 0.
    document : mapping
        A self-test controller file (``kind: seapup/mfol_controller``).
    sample_period : float or None
        Must equal the document's sample period when given.

    Raises
    ------
    DesignError
        On a malformed document or limit.
    """
    schedule = GainSchedule.from_document(document)
    if not parameters["schedule"]:
        schedule = GainSchedule([(schedule.speeds[0], schedule.gains[0])])
    if sample_period is not None and abs(schedule.sample_period - sample_period) > 1e-9:
        raise DesignError(f"the controller file's gains are for T = {schedule.sample_period:g} s, "
                          f"not {sample_period:g} s")
    return MFOLController(schedule, limit=float(parameters["blade_pitch_limit"]),
                          anti_windup=bool(parameters["anti_windup"]))


#: Owens and Chotai's two-term controller, fixed-gain or gain-scheduled (registered as ``mfol``).
MFOL_TYPE = ControllerType(
    "mfol", create_mfol, types.MappingProxyType({
        "schedule": True, "anti_windup": True,
        "blade_pitch_limit": Ranged(BLADE_PITCH_LIMIT, 0.01, VIRTUAL_INPUT_LIMIT, INPUT_LIMIT_RANGE)}),
    "Owens-Chotai two-term PI (eq. 4.11, 5.6) from a self-test's controller file; schedule: gain-scheduled on "
    "surge speed (sec. 4.6); anti_windup: false for the thesis's law as written (its integrators run on "
    "while a thruster saturates)", needs_document=True)
