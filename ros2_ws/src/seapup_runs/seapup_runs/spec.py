"""A run as data: what is flown, from where, by which controller, with which reference and events.

A :class:`RunSpec` is frozen, picklable and JSON-able (:meth:`RunSpec.to_dict`
/ :meth:`RunSpec.from_dict`, unknown keys refused): the same object is flown
in this process (:func:`seapup_runs.runner.run`) or through the ROS graph
(``seapup_bringup.graph.graph_runner.run_on_graph``, whose node parameters come from
:func:`seapup_runs.run_graph.graph_nodes`), and both give a
:class:`~seapup_runs.result.RunResult` that holds the spec it came from.

Settings derived from others are derived here, once: the physics step is
``min(0.1 s, T)`` (sec. 3.2's 0.1 s RK4 step, smaller only when the control
period is), the start pitch is the hover setting of the flown vehicle unless
given, and a controller whose design document is missing gets it from the
run's :class:`SelfTestDesign` (the self-test flown first, as the thesis
designs once on the baseline vehicle and then changes the vehicle, sec. 5.5).

A spec is checked strictly and at once, before anything is allocated for it: numbers must be numbers
(a YAML string such as ``'0.2'`` is refused, and a bool is not a number), finite and in range; unknown
keys are refused; and a run's size is bounded -- at most :data:`MAX_RUN_SAMPLES` control samples and
:data:`MAX_PHYSICS_STEPS` physics steps (``docs/limits.md``; ``$SEAPUP_MAX_RUN_SAMPLES`` and
``$SEAPUP_MAX_PHYSICS_STEPS`` raise them), computed from the duration and the periods before a sample
is flown or a row of its log allocated.

Units SI and radians; positions in ``odom_ned``, velocities in ``base_link_frd``.
"""
from __future__ import annotations

import bisect
import functools
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_common.contract import Reference
from seapup_common.controllers import ControllerSpec
from seapup_common.input_files import InputFileError, env_limit
from seapup_common.values import finite_real, is_real

__all__ = ["RunSpecError", "PHYSICS_STEP", "ReferenceSteps", "RunEvent", "SelfTestDesign", "RunSpec",
           "EVENT_KINDS", "CURRENT_FIELDS", "MAX_RUN_SAMPLES", "MAX_PHYSICS_STEPS", "MAX_OPERATING_POINTS",
           "MAX_NAME_LENGTH", "max_run_samples", "max_physics_steps", "number_hint", "vehicle_thrusters"]

#: The RK4 physics step of the thesis's simulation [s] (sec. 3.2).
PHYSICS_STEP = 0.1
#: Event kinds: the simulator's scheduled changes and a controller switch.
EVENT_KINDS = ("current", "configuration", "thruster_efficiency", "controller")
#: The Gauss-Markov current's parameters (eq. 2.30-2.33) a current event or override carries.
CURRENT_FIELDS = ("mean_speed", "speed_std", "mean_direction", "direction_std", "break_time")
#: The most control samples a run may have (duration / control period). A run's log holds about 40
#: float64 values a sample (truth, measured, reference, command, applied), so 10^6 samples are about
#: 0.3 GB of arrays (and several times that as JSON) and a few minutes of CPU in this process
#: (~0.1 ms a sample); that is 55 hours at 5 Hz, far beyond the thesis's longest run (minutes).
#: ``$SEAPUP_MAX_RUN_SAMPLES`` raises it.
MAX_RUN_SAMPLES = 10**6
#: The most RK4 physics steps a run may have (duration / physics step): 10^6 samples of the 0.1 s step
#: at 1 Hz control. ``$SEAPUP_MAX_PHYSICS_STEPS`` raises it.
MAX_PHYSICS_STEPS = 10**7
#: The most operating points a self-test design flies (one self-test each; the thesis uses two).
MAX_OPERATING_POINTS = 16
#: The most thrusters a thruster_efficiency event may name (a vehicle description's limit).
MAX_THRUSTERS = 32
#: The longest name or vehicle configuration name (a name is used in file names and on plots).
MAX_NAME_LENGTH = 200
ENV_MAX_RUN_SAMPLES = "SEAPUP_MAX_RUN_SAMPLES"
ENV_MAX_PHYSICS_STEPS = "SEAPUP_MAX_PHYSICS_STEPS"


class RunSpecError(ValueError):
    """A run specification that cannot be flown (the message names the key and what is allowed)."""


def max_run_samples() -> int:
    """:data:`MAX_RUN_SAMPLES`, or ``$SEAPUP_MAX_RUN_SAMPLES`` when set."""
    return _env_cap(ENV_MAX_RUN_SAMPLES, MAX_RUN_SAMPLES)


def max_physics_steps() -> int:
    """:data:`MAX_PHYSICS_STEPS`, or ``$SEAPUP_MAX_PHYSICS_STEPS`` when set."""
    return _env_cap(ENV_MAX_PHYSICS_STEPS, MAX_PHYSICS_STEPS)


def _env_cap(name: str, default: int) -> int:
    try:
        return env_limit(name, default)
    except InputFileError as exc:
        raise RunSpecError(str(exc)) from None


def _short(value) -> str:
    """``repr(value)`` cut to 60 characters (a message quotes what was given, not a megabyte of it)."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _finite(value, what: str) -> float:
    """``value`` as a float if it is a finite number: a YAML/JSON number (int or float), never a string
    (``'0.2'``) or a bool."""
    if not is_real(value):
        raise RunSpecError(f"{what} must be a number, got {_short(value)}{number_hint(value)}")
    number = finite_real(value)
    if number is None:
        raise RunSpecError(f"{what} must be a finite number, got {_short(value)}")
    return number


def number_hint(value) -> str:
    """Why a string that reads as a number is not one: quoted, or YAML 1.1's exponent rule (``1e8`` and
    ``1.0e8`` are text; ``1.0e+8`` is a number)."""
    if not isinstance(value, str):
        return ""
    try:
        float(value)
    except ValueError:
        return ""
    return " (text, not a number: unquote it; YAML reads an exponent as a number only with a dot and a sign, 1.0e+8)"


def _numbers(values, what: str, size: int | None = None) -> tuple:
    """A list (or tuple or 1-D array) of finite numbers, of ``size`` when given (the length checked first)."""
    if isinstance(values, np.ndarray):
        values = values.tolist() if values.ndim == 1 else values
    if not isinstance(values, (list, tuple)):
        raise RunSpecError(f"{what} must be a list of numbers, got {_short(values)}")
    if size is not None and len(values) != size:
        raise RunSpecError(f"{what} needs {size} values, got {len(values)}")
    return tuple(_finite(v, what) for v in values)


def _pilot_steps(value) -> tuple:
    """A scripted pilot's rows (t, x, y, z, yaw), checked: finite, times from 0 rising, at most 1000."""
    if value is None:
        return ()
    if not isinstance(value, (list, tuple)) or len(value) > 1000:
        raise RunSpecError(f"pilot must be a list of at most 1000 [t, x, y, z, yaw] rows, got {_short(value)}")
    rows = tuple(_numbers(row, "pilot row", 5) for row in value)
    times = [row[0] for row in rows]
    if any(t < 0 for t in times) or any(b <= a for a, b in zip(times, times[1:])):
        raise RunSpecError(f"pilot rows need times >= 0 s, rising, got {times[:10]}")
    return rows


@functools.lru_cache(maxsize=64)
def vehicle_thrusters(vehicle: str) -> tuple[str, int] | None:
    """(kind, count) of ``vehicle``'s thrusters, read once per process (None when it cannot be read: refused
    where it is flown)."""
    from seapup_sim.vehicle_config import ConfigError, load_vehicle_config
    try:
        thrusters = load_vehicle_config(vehicle)["thrusters"]
        return str(thrusters.get("kind", "controllable_pitch")), len(thrusters["positions"])
    except (ConfigError, KeyError, TypeError, OSError):
        return None


def _name(value, what: str) -> str:
    if not isinstance(value, str) or not value or len(value) > MAX_NAME_LENGTH:
        raise RunSpecError(f"{what} must be a non-empty string of at most {MAX_NAME_LENGTH} characters, "
                           f"got {_short(value)}")
    return value


def _refuse_unknown(data: Mapping, known, what: str) -> None:
    if not isinstance(data, Mapping):
        raise RunSpecError(f"{what} must be a mapping, got {_short(data)}")
    unknown = sorted(map(str, set(data) - set(known)))
    if unknown:
        raise RunSpecError(f"unknown {what} key(s) {unknown}; known: {', '.join(known)}")


@dataclass(frozen=True)
class ReferenceSteps:
    """Piecewise-constant body-velocity reference: ``(time, (u, v, w, r))`` steps held until the next.

    Before the first step's time the first step's value holds (a profile starts at its first value).

    Examples
    --------
    >>> profile = ReferenceSteps.from_list([[0.0, 0.7, 0, 0, 0], [15.0, 0.8, 0, 0, 0]])
    >>> float(profile.at(14.9).velocity[0]), float(profile.at(15.0).velocity[0])
    (0.7, 0.8)
    """

    steps: tuple = ((0.0, (0.0, 0.0, 0.0, 0.0)),)

    def __post_init__(self):
        if not isinstance(self.steps, (list, tuple)):
            raise RunSpecError(f"a reference profile is a list of steps, got {_short(self.steps)}")
        steps = []
        for i, step in enumerate(self.steps):
            if not isinstance(step, (list, tuple)) or len(step) != 2:
                raise RunSpecError(f"reference step {i} must be (time, (u, v, w, r)), got {_short(step)}")
            t, value = step
            if isinstance(value, (list, tuple)) and len(value) != 4:
                raise RunSpecError(f"reference step {i} needs 4 values (u, v, w, r), got {len(value)}")
            value = _numbers(value, f"reference step {i} value", 4)
            steps.append((_finite(t, f"reference step {i} time"), value))
        if not steps:
            raise RunSpecError("a reference profile needs at least one step")
        times = [t for t, _ in steps]
        if times != sorted(times) or len(set(times)) != len(times):
            raise RunSpecError(f"reference step times must be strictly increasing, got {times}")
        object.__setattr__(self, "steps", tuple(steps))
        object.__setattr__(self, "_times", tuple(t - 1e-9 for t in times))

    def at(self, t: float) -> Reference:
        """The reference in force at time ``t`` [s] (a binary search: a long profile costs a log per sample)."""
        k = bisect.bisect_right(self._times, t)
        return Reference(self.steps[max(k - 1, 0)][1])

    def to_list(self) -> list:
        return [[t, *v] for t, v in self.steps]

    @classmethod
    def from_list(cls, rows) -> "ReferenceSteps":
        """From ``[[t, u, v, w, r], ...]``."""
        if not isinstance(rows, (list, tuple)) or not all(isinstance(row, (list, tuple)) and row for row in rows):
            raise RunSpecError(f"a reference profile is a list of [t, u, v, w, r] rows, got {_short(rows)}")
        return cls(tuple((row[0], tuple(row[1:])) for row in rows))


def _current_detail(detail) -> dict | None:
    if detail is None:
        return None
    _refuse_unknown(detail, CURRENT_FIELDS, "current")
    missing = [k for k in CURRENT_FIELDS[:4] if k not in detail]
    if missing:
        raise RunSpecError(f"a current needs {', '.join(missing)}")
    return {k: _finite(v, f"current {k}") for k, v in detail.items()}


@dataclass(frozen=True)
class RunEvent:
    """A change at ``time`` [s] of the run.

    ``kind`` is one of :data:`EVENT_KINDS`; ``detail``: for ``current`` a mapping of
    :data:`CURRENT_FIELDS` (``break_time`` optional) or None (no current); for ``configuration``
    a vehicle configuration name; for ``thruster_efficiency`` a factor per thruster; for ``controller`` the
    :class:`~seapup_common.controllers.ControllerSpec` that takes over at that sample (bumpless,
    from the applied blade pitch).
    """

    time: float
    kind: str
    detail: object = None

    def __post_init__(self):
        time = _finite(self.time, "event time")
        if time < 0:
            raise RunSpecError(f"event time must be >= 0 s, got {time}")
        object.__setattr__(self, "time", time)
        if not isinstance(self.kind, str) or self.kind not in EVENT_KINDS:
            raise RunSpecError(f"unknown event kind {_short(self.kind)}; known: {', '.join(EVENT_KINDS)}")
        detail = self.detail
        if self.kind == "current":
            detail = _current_detail(detail)
        elif self.kind == "configuration":
            if not isinstance(detail, str) or not detail or len(detail) > MAX_NAME_LENGTH:
                raise RunSpecError(f"a configuration event names a vehicle configuration, got {_short(detail)}")
        elif self.kind == "thruster_efficiency":
            if isinstance(detail, (list, tuple)) and not 1 <= len(detail) <= MAX_THRUSTERS:
                raise RunSpecError(f"a thruster_efficiency event needs a factor per thruster (1 to {MAX_THRUSTERS}), "
                                   f"got {len(detail)}")
            detail = _numbers(detail, "thruster efficiency")   # as many as the vehicle has: checked as it flies
        else:
            detail = detail if isinstance(detail, ControllerSpec) else ControllerSpec.from_dict(detail)
        object.__setattr__(self, "detail", detail)

    def to_dict(self) -> dict:
        detail = self.detail
        if isinstance(detail, ControllerSpec):
            detail = detail.to_dict()
        elif isinstance(detail, tuple):
            detail = list(detail)
        return {"time": self.time, "kind": self.kind, "detail": detail}

    @classmethod
    def from_dict(cls, data: Mapping) -> "RunEvent":
        _refuse_unknown(data, ("time", "kind", "detail"), "event")
        if "time" not in data or "kind" not in data:
            raise RunSpecError(f"an event needs 'time' and 'kind', got {dict(data)}")
        return cls(data["time"], data["kind"], data.get("detail"))


@dataclass(frozen=True)
class SelfTestDesign:
    """A self-test (sec. 4.5.2, 5.3) flown before the run to design the controller(s) that lack gains.

    Flown in this process on ``vehicle`` with noise-free sensors and no current (sec. 5.3.2),
    starting at rest ``start_depth`` deep, at the run's control period; each step fitted as ``fit`` says
    (``deviation``: eq. 5.5, the default; ``raw``: the thesis's Table 5.2 procedure,
    :meth:`seapup_control.self_test.StepTest.column`). On the run's own vehicle, ``coefficients`` and all (the
    self-test needs no model: it steps the vehicle as it is), unless ``nominal``: then on the description as
    written, a design from the model for comparison.
    """

    vehicle: str = "baseline"
    operating_points: tuple = (0.0, 0.7)
    mode: str = "realistic"
    start_depth: float = 50.0
    fit: str = "deviation"
    nominal: bool = False

    def __post_init__(self):
        _name(self.vehicle, "self-test vehicle")
        if not isinstance(self.nominal, bool):
            raise RunSpecError(f"design nominal must be true or false, got {_short(self.nominal)}")
        if isinstance(self.operating_points, (list, tuple)) and not 1 <= len(self.operating_points) <= MAX_OPERATING_POINTS:
            raise RunSpecError(f"a self-test needs 1 to {MAX_OPERATING_POINTS} operating points (one self-test each), "
                               f"got {len(self.operating_points)}")
        points = _numbers(self.operating_points, "operating point")
        object.__setattr__(self, "operating_points", points)
        if not isinstance(self.mode, str) or self.mode not in ("realistic", "artificial"):
            raise RunSpecError(f"self-test mode must be realistic or artificial, got {_short(self.mode)}")
        object.__setattr__(self, "start_depth", _finite(self.start_depth, "self-test start depth"))
        from seapup_control.self_test import FITS
        if not isinstance(self.fit, str) or self.fit not in FITS:
            raise RunSpecError(f"self-test fit must be one of {', '.join(FITS)}, got {_short(self.fit)}")

    def to_dict(self) -> dict:
        out = {"vehicle": self.vehicle, "operating_points": list(self.operating_points), "mode": self.mode,
               "start_depth": self.start_depth}
        out = {**out, "fit": self.fit} if self.fit != "deviation" else out   # the default: keys as before
        return {**out, "nominal": True} if self.nominal else out

    @classmethod
    def from_dict(cls, data: Mapping) -> "SelfTestDesign":
        _refuse_unknown(data, ("vehicle", "operating_points", "mode", "start_depth", "fit", "nominal"), "design")
        return cls(**dict(data))


def _frozen_mapping(value, what: str) -> dict:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise RunSpecError(f"{what} must be a mapping, got {_short(value)}")
    return {str(k): (_frozen_mapping(v, what) if isinstance(v, Mapping) else v) for k, v in value.items()}


@dataclass(frozen=True)
class RunSpec:
    """One run (see the module docstring).

    Parameters
    ----------
    name : str
        What the run is called (a scenario's name, ...).
    vehicle : str
        Vehicle configuration flown (``baseline``, ``camera``, ...).
    dynamics : str
        ``nonlinear`` (ch. 2) or ``linearised`` (eq. 3.2 about hover).
    environment : mapping
        Overrides over ``environment/default.yaml`` (sensors, current, seabed, umbilical).
    control_period : float
        T [s] of the controller (0.2 s: 5 Hz; 0.05 s: 20 Hz).
    duration : float
        Simulated seconds flown (samples at 0, T, ..., duration).
    start_depth : float
        Depth of the start [m] (at rest, level), unless ``start_state`` is given.
    start_state : tuple of 12 floats, optional
        The start state in thesis order (x, y, z, phi, theta, psi, u, v, w, p, q, r).
    start_pitch : tuple of 4 floats, optional
        Blade pitch applied at the start [rad]; None: the hover setting of ``vehicle``.
    controller : ControllerSpec
        The velocity controller from t = 0 (``controller`` events switch it later).
    design : SelfTestDesign, optional
        Designs every controller of the run that needs a document and has none.
    reference : ReferenceSteps
        The body-velocity reference.
    events : tuple of RunEvent
        Scheduled changes (current, configuration, thruster efficiency, controller).
    seed : int
        Seed of the run's random streams (current, sensors).
    metrics : tuple of str
        Named metric extractors (:data:`seapup_runs.metrics.METRICS`) computed on the result.
    pilot : tuple of (t, x, y, z, yaw), optional
        A scripted pilot (a manual controller's stick, seapup_control.manual): from each time [s] the
        ``Twist`` demand in ``base_link`` (REP-103: x forward, y left, z up [m/s]; yaw counter-clockwise
        [rad/s]), held until the next; sent to a controller that flies a pilot (``manual``), ignored by others.
    coefficients : mapping, optional
        The flown vehicle's uncertain coefficients scaled (``damping``, ``added_mass``: factors in [0.1, 10],
        :func:`seapup_sim.vehicle_config.scaled`); in process only.
    """

    name: str = "run"
    vehicle: str = "baseline"
    dynamics: str = "nonlinear"
    environment: Mapping = field(default_factory=dict)
    control_period: float = 0.2
    duration: float = 10.0
    start_depth: float = 50.0
    start_state: tuple | None = None
    start_pitch: tuple | None = None
    controller: ControllerSpec = field(default_factory=lambda: ControllerSpec("hold"))
    design: SelfTestDesign | None = None
    reference: ReferenceSteps = field(default_factory=ReferenceSteps)
    events: tuple = ()
    seed: int = 0
    metrics: tuple = ()
    coefficients: Mapping = field(default_factory=dict)
    pilot: tuple = ()

    def __post_init__(self):
        _name(self.name, "name")
        _name(self.vehicle, "vehicle")
        coefficients = _frozen_mapping(self.coefficients, "coefficients")
        from seapup_sim.vehicle_config import COEFFICIENT_SCALES
        _refuse_unknown(coefficients, COEFFICIENT_SCALES, "coefficients")
        for key, value in coefficients.items():
            factor = _finite(value, f"coefficients {key}")
            if not 0.1 <= factor <= 10.0:
                raise RunSpecError(f"coefficients {key} must be a factor in [0.1, 10], got {factor}")
            coefficients[key] = factor
        object.__setattr__(self, "coefficients", coefficients)
        object.__setattr__(self, "pilot", _pilot_steps(self.pilot))
        period = _finite(self.control_period, "control_period")
        if period <= 0:
            raise RunSpecError(f"control_period must be > 0 s, got {period}")
        steps = period / min(PHYSICS_STEP, period)
        if not steps < 2**53 or abs(steps - round(steps)) > 1e-9:
            raise RunSpecError(f"control_period {period} s must be a whole number of {PHYSICS_STEP} s physics steps "
                               "(or shorter than one)")
        duration = _finite(self.duration, "duration")
        if duration <= 0:
            raise RunSpecError(f"duration must be > 0 s, got {duration}")
        _check_size(duration, period)
        if abs(duration / period - round(duration / period)) > 1e-6:
            raise RunSpecError(f"duration {duration} s must be a whole number of control periods ({period} s)")
        if not isinstance(self.dynamics, str) or self.dynamics not in ("nonlinear", "linearised"):
            raise RunSpecError(f"dynamics must be nonlinear or linearised, got {_short(self.dynamics)}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or not 0 <= self.seed < 2**31:
            raise RunSpecError(f"seed must be an integer in [0, 2^31), got {_short(self.seed)}")
        object.__setattr__(self, "control_period", period)
        object.__setattr__(self, "duration", duration)
        object.__setattr__(self, "seed", int(self.seed))
        object.__setattr__(self, "start_depth", _finite(self.start_depth, "start_depth"))
        object.__setattr__(self, "environment", _frozen_mapping(self.environment, "environment"))
        for name, size in (("start_state", 12), ("start_pitch", 4)):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, _numbers(value, name, size))
        if self.start_pitch is not None and max(abs(v) for v in self.start_pitch) > BLADE_PITCH_LIMIT:
            raise RunSpecError(f"start_pitch must be within +-{BLADE_PITCH_LIMIT:.4g} rad (the blade pitch limit), "
                               f"got {list(self.start_pitch)}")
        if not isinstance(self.controller, ControllerSpec):
            object.__setattr__(self, "controller", ControllerSpec.from_dict(self.controller))
        if not isinstance(self.reference, ReferenceSteps):
            object.__setattr__(self, "reference", ReferenceSteps.from_list(self.reference))
        if self.design is not None and not isinstance(self.design, SelfTestDesign):
            object.__setattr__(self, "design", SelfTestDesign.from_dict(self.design))
        if not isinstance(self.events, (list, tuple)):
            raise RunSpecError(f"events must be a list of events, got {_short(self.events)}")
        events = tuple(e if isinstance(e, RunEvent) else RunEvent.from_dict(e) for e in self.events)
        thrusters = vehicle_thrusters(self.vehicle)
        count = None if thrusters is None else thrusters[1]
        for event in events:
            if event.kind == "thruster_efficiency" and count is not None and len(event.detail) != count:
                raise RunSpecError(f"a thruster_efficiency event needs {count} factors ({self.vehicle} has {count} "
                                   f"thrusters), got {len(event.detail)}")
        object.__setattr__(self, "events", tuple(sorted(events, key=lambda e: e.time)))
        object.__setattr__(self, "metrics", _metric_names(self.metrics))

    # -- derived, once -----------------------------------------------------------------------
    @property
    def physics_step(self) -> float:
        """The RK4 step [s]: sec. 3.2's 0.1 s, or the control period when that is shorter."""
        return min(PHYSICS_STEP, self.control_period)

    @property
    def samples(self) -> int:
        """Control samples flown after the start (the result has one more row: t = 0 and the end)."""
        return int(round(self.duration / self.control_period))

    def initial_state(self) -> np.ndarray:
        """The 12-state at t = 0."""
        if self.start_state is not None:
            return np.array(self.start_state, float)
        state = np.zeros(12)
        state[2] = self.start_depth
        return state

    def controller_timeline(self) -> list[tuple[float, ControllerSpec]]:
        """``[(from time, controller), ...]``: the controller at 0 and each ``controller`` event's."""
        return [(0.0, self.controller)] + [(e.time, e.detail) for e in self.events if e.kind == "controller"]

    def plant_events(self) -> tuple:
        """The events the simulator carries out (all but controller switches)."""
        return tuple(e for e in self.events if e.kind != "controller")

    def with_controllers(self, documents: Mapping[int, Mapping]) -> "RunSpec":
        """A copy whose timeline entries ``i`` carry the design ``documents[i]`` inline."""
        timeline = self.controller_timeline()

        def filled(i, spec):
            return replace(spec, document=documents[i]) if i in documents else spec
        controller = filled(0, timeline[0][1])
        events, i = [], 0
        for event in self.events:
            if event.kind == "controller":
                i += 1
                event = replace(event, detail=filled(i, event.detail))
            events.append(event)
        return replace(self, controller=controller, events=tuple(events))

    # -- data ------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """Plain data (JSON/YAML), the inverse of :meth:`from_dict`."""
        return {"name": self.name, "vehicle": self.vehicle, "dynamics": self.dynamics,
                "environment": self.environment, "control_period": self.control_period,
                "physics_step": self.physics_step, "duration": self.duration, "start_depth": self.start_depth,
                "start_state": None if self.start_state is None else list(self.start_state),
                "start_pitch": None if self.start_pitch is None else list(self.start_pitch),
                "controller": self.controller.to_dict(),
                "design": None if self.design is None else self.design.to_dict(),
                "reference": self.reference.to_list(), "events": [e.to_dict() for e in self.events],
                "seed": self.seed, "metrics": list(self.metrics),
                **({"coefficients": dict(self.coefficients)} if self.coefficients else {}),   # keys as before
                **({"pilot": [list(row) for row in self.pilot]} if self.pilot else {})}

    def pilot_at(self, t: float) -> tuple | None:
        """The scripted pilot's demand in force at ``t`` [s]: (x, y, z [m/s], yaw [rad/s]) of a ``Twist`` in
        ``base_link`` (REP-103), or None before its first step."""
        k = bisect.bisect_right(self._pilot_times, t + 1e-9)   # a binary search, as ReferenceSteps.at
        return self.pilot[k - 1][1:] if k else None

    @functools.cached_property
    def _pilot_times(self) -> tuple:
        return tuple(row[0] for row in self.pilot)

    def vehicle_config(self) -> dict:
        """The flown vehicle's configuration: ``vehicle``'s, its coefficients scaled as ``coefficients`` say."""
        from seapup_sim.vehicle_config import load_vehicle_config, scaled
        config = load_vehicle_config(self.vehicle)
        return scaled(config, **self.coefficients) if self.coefficients else config

    @classmethod
    def from_dict(cls, data: Mapping) -> "RunSpec":
        """A spec from plain data; unknown keys are refused (``physics_step`` is derived: if given it
        must agree)."""
        known = [f for f in cls.__dataclass_fields__] + ["physics_step"]
        _refuse_unknown(data, known, "run spec")
        values = {k: v for k, v in data.items() if k != "physics_step"}
        for name in ("events", "metrics"):
            if values.get(name) is None and name in values:
                values[name] = ()
        spec = cls(**values)
        if "physics_step" in data and abs(_finite(data["physics_step"], "physics_step") - spec.physics_step) > 1e-12:
            raise RunSpecError(f"physics_step {data['physics_step']} disagrees with the derived "
                               f"{spec.physics_step} s (min(0.1 s, T))")
        return spec


def _check_size(duration: float, period: float) -> None:
    """Refuse a run of more than :func:`max_run_samples` control samples or :func:`max_physics_steps`
    physics steps, or of less than one sample: arithmetic on the two numbers, before anything is allocated."""
    samples = duration / period
    physics = duration / min(PHYSICS_STEP, period)
    if samples < 0.5:
        raise RunSpecError(f"duration {duration:g} s is shorter than one control period ({period:g} s)")
    cap = max_run_samples()
    if not samples <= cap:
        raise RunSpecError(f"duration {duration:g} s at a {period:g} s control period is {samples:.3g} control samples, "
                           f"more than the {cap:,} a run may have (docs/limits.md; set "
                           f"{ENV_MAX_RUN_SAMPLES} to allow more)")
    cap = max_physics_steps()
    if not physics <= cap:
        raise RunSpecError(f"duration {duration:g} s is {physics:.3g} physics steps of {min(PHYSICS_STEP, period):g} s, "
                           f"more than the {cap:,} a run may have (docs/limits.md; set "
                           f"{ENV_MAX_PHYSICS_STEPS} to allow more)")


def _metric_names(names) -> tuple:
    """The metric extractors' names, typed (a list of strings); the names themselves are checked against the
    registry (:func:`seapup_runs.metrics.check_names`, which imports this module) before a run flies."""
    if not isinstance(names, (list, tuple)) or not all(isinstance(n, str) for n in names):
        raise RunSpecError(f"metrics must be a list of metric names, got {_short(names)}")
    return tuple(names)
