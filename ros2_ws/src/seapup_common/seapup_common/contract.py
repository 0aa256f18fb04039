"""The controller contract: what a velocity controller sees and returns.

A controller -- on the simulator, in a SIL test, or on the real vehicle --
sees *measurements* (what the sensors give, each reading with its stamp and
validity), a *reference* from the level above (body velocities, thesis
sec. 4.2), and returns a *command* (four blade pitches). It never sees the
simulator's true state.

A control law is a pure object with explicit state, like the update functions
of python-control's ``NonlinearIOSystem``: :meth:`VelocityController.reset`
initialises the state from the command presently applied (a bumpless start),
:meth:`VelocityController.update` advances it by one sample and returns the
command to hold until the next sample. Scheduling the calls (a simulation
loop, a ROS timer, a lockstep ``/clock``) is the caller's job; switching
between controllers is a manager's job, not the controller's.

Units SI and radians; vehicle quantities in NED (world, ``odom_ned``) and FRD
(body, ``base_link_frd``) as in the thesis.
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from seapup_common.blade_pitch import InvalidBladePitchError

__all__ = ["ContractError", "Reading", "Measurement", "Reference", "StampedReferences", "Command", "VelocityController",
           "HoldCommand", "MEASUREMENT_FIELDS", "NavigationEstimate", "MAX_AGE", "LatestReadings", "CheckedVariances",
           "INVALID_READING"]

#: Measurement fields, their sizes (0 = scalar) and meanings.
MEASUREMENT_FIELDS = {
    "velocity": (3, "u, v, w [m/s], base_link_frd (doppler log)"),
    "rates": (3, "p, q, r [rad/s], base_link_frd (rate gyros)"),
    "attitude": (3, "phi, theta, psi [rad] of base_link_frd in odom_ned (vertical gyro, compass)"),
    "depth": (0, "depth of the body origin [m], positive down (pressure gauge)"),
    "altitude": (0, "range to the seabed along body z [m] (altimeter)"),
    "position": (3, "x, y, z [m] in odom_ned (acoustic fix)"),
}


class ContractError(ValueError):
    """A measurement, reference or command that breaks the contract (shape, finiteness)."""


def _finite_array(value, size: int, what: str) -> np.ndarray | float:
    if size == 0:
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
            raise ContractError(f"{what} must be a number, got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise ContractError(f"{what} must be finite, got {value!r}")
        return value
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ContractError(f"{what} must be {size} numbers, got {value!r}") from None
    if arr.shape != (size,):
        raise ContractError(f"{what} needs exactly {size} values, got shape {arr.shape}")
    if not all(map(math.isfinite, arr.tolist())):  # a third of np.all(np.isfinite(arr))'s time on 3 or 4 values
        raise ContractError(f"{what} must be finite, got {arr.tolist()}")
    arr.setflags(write=False)
    return arr


class CheckedVariances(dict):
    """Every measurement field's variance checked as :meth:`Measurement.build` checks them (a read-only array
    of the field's size, or a float; 0 where not given): a sensor suite checks its profile's once, and
    ``build`` takes them as they are. Make one with :meth:`of`."""

    @classmethod
    def of(cls, variances: dict) -> "CheckedVariances":
        """``variances`` (field -> value) checked.

        Raises
        ------
        ContractError
            On an unknown field, a wrong shape or a non-finite value.
        """
        unknown = set(variances) - set(MEASUREMENT_FIELDS)
        if unknown:
            raise ContractError(f"unknown measurement field(s) {sorted(unknown)}; "
                                f"known: {', '.join(MEASUREMENT_FIELDS)}")
        return cls({name: _finite_array(variances.get(name, 0.0 if size == 0 else np.zeros(size)), size,
                                        f"{name} variance") for name, (size, _) in MEASUREMENT_FIELDS.items()})


@dataclass(frozen=True)
class Reading:
    """One sensor reading: its value, when it was taken, and its variance.

    A reading without a value is *invalid* (no fix this sample, seabed out of
    range, instrument lost); a value is always finite.

    Parameters
    ----------
    value : ndarray, float or None
        The reading (shape per :data:`MEASUREMENT_FIELDS`), None when invalid.
    stamp : float
        Time the reading was taken [s]; NaN when invalid.
    variance : ndarray or float
        Variance of each component (same shape as the value), 0 when unknown.
    """

    value: np.ndarray | float | None = None
    stamp: float = math.nan
    variance: np.ndarray | float = 0.0

    def __init__(self, value=None, stamp: float = math.nan, variance=0.0):
        # the fields written straight into the instance's dict: what the frozen dataclass's generated __init__
        # does through object.__setattr__, at half its cost (a mission flown in process makes ~15 a sample)
        d = self.__dict__
        d["value"], d["stamp"], d["variance"] = value, stamp, variance

    @property
    def valid(self) -> bool:
        return self.value is not None

    @classmethod
    def invalid(cls) -> "Reading":
        """A reading with no value."""
        return cls()


#: The reading of a field a measurement does not have (no value): one shared instance.
INVALID_READING = Reading()


@dataclass(frozen=True)
class Measurement:
    """What the sensors say at control instant ``t`` (never the true state).

    Every field is a :class:`Reading` (see :data:`MEASUREMENT_FIELDS`); use
    :meth:`build` to make one from plain values with shape checks.
    """

    t: float
    velocity: Reading = INVALID_READING
    rates: Reading = INVALID_READING
    attitude: Reading = INVALID_READING
    depth: Reading = INVALID_READING
    altitude: Reading = INVALID_READING
    position: Reading = INVALID_READING

    def __init__(self, t: float, velocity: Reading = INVALID_READING, rates: Reading = INVALID_READING,
                 attitude: Reading = INVALID_READING, depth: Reading = INVALID_READING, altitude: Reading = INVALID_READING,
                 position: Reading = INVALID_READING):
        # as Reading.__init__: the frozen fields written into the dict; an absent field is the one shared
        # invalid reading (a Reading is immutable, so sharing it is safe)
        d = self.__dict__
        d["t"], d["velocity"], d["rates"], d["attitude"] = t, velocity, rates, attitude
        d["depth"], d["altitude"], d["position"] = depth, altitude, position

    @classmethod
    def build(cls, t: float, stamps: dict | None = None, variances: dict | None = None,
              **values) -> "Measurement":
        """A measurement from plain values: ``Measurement.build(t, velocity=(u, v, w), depth=3.0)``.

        A field that is absent or None is invalid. Stamps default to ``t``,
        variances to 0 (unknown).

        Raises
        ------
        ContractError
            On an unknown field, a wrong shape or a non-finite value.
        """
        stamps, variances = stamps or {}, variances or {}
        unknown = set(values) - set(MEASUREMENT_FIELDS)
        if unknown:
            raise ContractError(f"unknown measurement field(s) {sorted(unknown)}; "
                                f"known: {', '.join(MEASUREMENT_FIELDS)}")
        t = float(t)
        readings = {}
        for name, (size, _) in MEASUREMENT_FIELDS.items():
            value = values.get(name)
            if value is None:
                readings[name] = Reading()
                continue
            if isinstance(variances, CheckedVariances):
                var = variances[name]
            else:
                var = _finite_array(variances.get(name, 0.0 if size == 0 else np.zeros(size)), size, f"{name} variance")
            readings[name] = Reading(_finite_array(value, size, name), float(stamps.get(name, t)), var)
        return cls(t, **readings)

    def body_velocity(self) -> np.ndarray:
        """(u, v, w, r): the four outputs of the velocity loop (thesis sec. 4.2, 5.1).

        Raises
        ------
        ContractError
            If the velocity or rate reading is invalid.
        """
        if not (self.velocity.valid and self.rates.valid):
            raise ContractError(f"no valid velocity/rate reading at t = {self.t:.3f} s")
        return np.concatenate((self.velocity.value, self.rates.value[2:]))


@dataclass(frozen=True)
class Reference:
    """Body-velocity reference of the velocity loop (thesis sec. 4.2, 5.1).

    Parameters
    ----------
    velocity : array_like, shape (4,)
        Surge u, sway v, heave w [m/s] and yaw rate r [rad/s], base_link_frd.
    """

    velocity: np.ndarray = field(default_factory=lambda: np.zeros(4))

    def __post_init__(self):
        object.__setattr__(self, "velocity", _finite_array(self.velocity, 4, "velocity reference"))


class StampedReferences:
    """References that take effect at their own time: what a controller uses at sample t_k.

    A reference stamped in the future waits; at each sample the latest one
    stamped at or before the sample is in force. A reference without a time
    (``None``) takes effect at once and drops everything scheduled. This is
    how a stamped setpoint (``TwistStamped`` with its header stamp) reaches a
    controller exactly at the sample it is meant for, whatever the transport
    delay, as long as it arrives before that sample.

    Parameters
    ----------
    capacity : int
        Most references waiting at once; more are refused (:class:`ContractError`).
    initial : object, optional
        What is in force before anything was added (default: a zero :class:`Reference`). The
        schedule holds any object: the position controller schedules pose setpoints with it.

    Examples
    --------
    >>> schedule = StampedReferences()
    >>> schedule.add(Reference([0.3, 0, 0, 0]), at=10.0)
    >>> float(schedule.at(9.8).velocity[0]), float(schedule.at(10.0).velocity[0])
    (0.0, 0.3)
    """

    _ZERO = object()

    def __init__(self, capacity: int = 1000, initial=_ZERO):
        self.capacity = int(capacity)
        self.current = Reference() if initial is StampedReferences._ZERO else initial
        self._waiting: list[tuple[float, int, Reference]] = []  # (time, arrival order, reference), sorted
        self._immediate: list = []  # added without a time since the last due()
        self._arrivals = 0

    def add(self, reference: Reference, at: float | None = None) -> None:
        """Schedule ``reference`` for time ``at`` [s] (None: now)."""
        if at is None:
            self._waiting.clear()
            self.current = reference
            self._immediate = [*self._immediate[-(self.capacity - 1):], reference]  # a caller that never asks keeps few
            return
        if not math.isfinite(at):
            raise ContractError(f"reference time must be finite, got {at!r}")
        if len(self._waiting) >= self.capacity:
            raise ContractError(f"{self.capacity} references are already waiting")
        self._arrivals += 1
        bisect.insort(self._waiting, (float(at), self._arrivals, reference), key=lambda item: item[:2])

    def at(self, t: float) -> Reference:
        """The reference in force at time ``t`` (those due by then are taken in time order)."""
        self.due(t)
        return self.current

    def due(self, t: float) -> list:
        """Take everything due by time ``t`` (in time order) and return it; the last becomes current.

        Also returns what was added without a time since the last call.
        """
        taken, self._immediate = self._immediate, []
        while self._waiting and self._waiting[0][0] <= t + 1e-9:
            taken.append(self._waiting.pop(0)[2])
        if taken:
            self.current = taken[-1]
        return taken

    @property
    def waiting(self) -> int:
        return len(self._waiting)


@dataclass(frozen=True)
class Command:
    """Four blade pitches [rad], ``seapup_msgs/BladePitch`` order, for time ``stamp`` [s].

    Finite and of length four (else :class:`InvalidBladePitchError`); pitches
    beyond the blade limits are allowed here and saturated by the vehicle.
    """

    blade_pitch: np.ndarray
    stamp: float = math.nan

    def __init__(self, blade_pitch, stamp: float = math.nan):
        try:
            pitch = _finite_array(blade_pitch, 4, "blade pitch")
        except ContractError as exc:
            raise InvalidBladePitchError(str(exc)) from None
        d = self.__dict__   # the frozen fields written into the dict (as Reading's)
        d["blade_pitch"], d["stamp"] = pitch, stamp


@runtime_checkable
class VelocityController(Protocol):
    """A sampled body-velocity control law (see the module docstring).

    Attributes
    ----------
    sample_period : float
        T [s] at which :meth:`update` must be called.
    """

    sample_period: float

    def reset(self, applied: Command) -> None:
        """Initialise the law's state from the command the vehicle applies now (bumpless start)."""

    def applied(self, t: float, command: Command) -> None:
        """Be told the blade pitch the vehicle reports applied at ``t`` [s], before :meth:`update` at ``t``.

        This is the input that really acted over the interval that ended at ``t``: the controller's
        own command after the vehicle's clipping and actuator lag, a watchdog's setting, or another
        controller's command before a switch -- what a self-tuner must estimate from (the
        identification's input convention, :func:`seapup_ident.online.held_inputs`). Transports
        call it whenever they know the applied pitch; a law that does not need it ignores it.
        """

    def update(self, t: float, measurement: Measurement, reference: Reference) -> Command:
        """Advance one sample at time ``t`` [s] and return the command to hold until t + T."""

    def diagnostics(self) -> dict:
        """The law's state after its last sample as plain values (lists, numbers, strings): what a
        node publishes on ``/diagnostics`` and a run logs. Empty before the first sample."""


class HoldCommand:
    """The simplest :class:`VelocityController`: it holds one blade-pitch setting.

    An open loop (e.g. a trim or hover setting held while something else is
    measured), and the reference implementation of the protocol.

    Parameters
    ----------
    blade_pitch : array_like, shape (4,), or None
        The setting [rad]; None: the command applied when it is started (:meth:`reset`), so a
        vehicle drifts at whatever setting it had.
    sample_period : float
        T [s], > 0.
    """

    def __init__(self, blade_pitch, sample_period: float):
        if not (math.isfinite(sample_period) and sample_period > 0):
            raise ContractError(f"sample period must be finite and > 0 s, got {sample_period!r}")
        self.sample_period = float(sample_period)
        self.from_applied = blade_pitch is None
        self.blade_pitch = None if blade_pitch is None else Command(blade_pitch).blade_pitch

    def reset(self, applied: Command) -> None:
        """Take the applied setting when none was given; otherwise nothing depends on the past."""
        if self.from_applied:
            self.blade_pitch = Command(applied.blade_pitch).blade_pitch

    def applied(self, t: float, command: Command) -> None:
        """Nothing to learn: the setting does not depend on what the vehicle did."""

    def update(self, t: float, measurement: Measurement, reference: Reference) -> Command:
        if self.blade_pitch is None:
            raise ContractError("a hold of the applied setting must be reset with it before its first sample")
        return Command(self.blade_pitch, stamp=t)

    def diagnostics(self) -> dict:
        return {} if self.blade_pitch is None else {"blade_pitch": self.blade_pitch.tolist()}


#: How old [s] a field's newest reading may be at a sample and still be used (default: 1 s for the velocity,
#: rates, attitude, depth and altitude; 5 s for the acoustic position fixes, which come at about 1 Hz).
MAX_AGE = {"velocity": 1.0, "rates": 1.0, "attitude": 1.0, "depth": 1.0, "altitude": 1.0, "position": 5.0}


class LatestReadings:
    """The newest valid reading of each measurement field, and the :class:`Measurement` at a sample from them.

    The one rule every reader of the sensors applies (the nodes' collectors, the in-process hierarchy): an
    invalid reading is not kept (the previous one stands); at sample ``t`` a reading is used when it is no
    older than its field's ``max_age`` (a dead sensor is not a reading) and not stamped after ``t`` (not yet).

    Parameters
    ----------
    max_age : dict, optional
        Per-field age limits [s] over :data:`MAX_AGE`.

    Examples
    --------
    >>> store = LatestReadings()
    >>> store.keep("depth", Reading(np.array(30.0), stamp=1.0))
    >>> store.measurement(1.8).depth.valid, store.measurement(2.2).depth.valid, store.measurement(0.5).depth.valid
    (True, False, False)
    """

    def __init__(self, max_age: dict | None = None):
        self.max_age = {**MAX_AGE, **(max_age or {})}
        self.latest: dict[str, Reading] = {}

    def keep(self, name: str, reading: Reading) -> None:
        """Keep ``reading`` as field ``name``'s newest if it is valid."""
        if reading.valid:
            self.latest[name] = reading

    def measurement(self, t: float) -> Measurement:
        """The measurement at time ``t`` [s] from the newest readings fresh at ``t``."""
        fields = {name: reading for name, reading in self.latest.items()
                  if -1e-9 <= t - reading.stamp <= self.max_age[name] + 1e-9}
        return Measurement(float(t), **fields)


@dataclass(frozen=True)
class NavigationEstimate:
    """The navigator's answer at time ``t``: pose, body velocity and uncertainty.

    ``position`` (x, y, z) [m] in odom_ned with covariance ``position_cov``
    (3x3); ``attitude`` (phi, theta, psi) [rad] and ``velocity`` (u, v, w)
    [m/s], ``rates`` (p, q, r) [rad/s] as last measured.
    """

    t: float
    position: np.ndarray
    position_cov: np.ndarray
    attitude: np.ndarray
    velocity: np.ndarray
    rates: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __init__(self, t: float, position: np.ndarray, position_cov: np.ndarray, attitude: np.ndarray,
                 velocity: np.ndarray, rates: np.ndarray | None = None):
        # as Reading.__init__: the frozen fields written into the dict (the navigator makes one a sample)
        d = self.__dict__
        d["t"], d["position"], d["position_cov"], d["attitude"] = t, position, position_cov, attitude
        d["velocity"], d["rates"] = velocity, np.zeros(3) if rates is None else rates

    @property
    def yaw(self) -> float:
        return float(self.attitude[2])

    @property
    def horizontal_std(self) -> float:
        """sqrt of the trace of the horizontal covariance [m]."""
        return float(math.sqrt(max(0.0, self.position_cov[0, 0] + self.position_cov[1, 1])))
