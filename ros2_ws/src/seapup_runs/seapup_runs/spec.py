"""A run as data: what is flown, from where, by which controller, with which reference and events.

A :class:`RunSpec` is frozen, picklable and JSON-able (:meth:`RunSpec.to_dict`
/ :meth:`RunSpec.from_dict`, unknown keys refused): the same object is flown
in this process (:func:`seapup_runs.runner.run`) or through the ROS graph
(``seapup_bringup.graph_runner.run_on_graph``, whose node parameters come from
:func:`seapup_runs.graph.graph_nodes`), and both give a
:class:`~seapup_runs.result.RunResult` that holds the spec it came from.

Settings derived from others are derived here, once: the physics step is
``min(0.1 s, T)`` (sec. 3.2's 0.1 s RK4 step, smaller only when the control
period is), the start pitch is the hover setting of the flown vehicle unless
given, and a controller whose design document is missing gets it from the
run's :class:`SelfTestDesign` (the self-test flown first, as the thesis
designs once on the baseline vehicle and then changes the vehicle, sec. 5.5).

Units SI and radians; positions in ``odom_ned``, velocities in ``base_link_frd``.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from seapup_common.contract import Reference
from seapup_common.controllers import ControllerSpec

__all__ = ["RunSpecError", "PHYSICS_STEP", "ReferenceSteps", "RunEvent", "SelfTestDesign", "RunSpec",
           "EVENT_KINDS", "CURRENT_FIELDS"]

#: The RK4 physics step of the thesis's simulation [s] (sec. 3.2).
PHYSICS_STEP = 0.1
#: Event kinds: the simulator's scheduled changes and a controller switch.
EVENT_KINDS = ("current", "configuration", "thruster_efficiency", "controller")
#: The Gauss-Markov current's parameters (eq. 2.30-2.33) a current event or override carries.
CURRENT_FIELDS = ("mean_speed", "speed_std", "mean_direction", "direction_std", "break_time")


class RunSpecError(ValueError):
    """A run specification that cannot be flown (the message names the key and what is allowed)."""


def _finite(value, what: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise RunSpecError(f"{what} must be a number, got {value!r}") from None
    if isinstance(value, bool) or not math.isfinite(number):
        raise RunSpecError(f"{what} must be a finite number, got {value!r}")
    return number


def _refuse_unknown(data: Mapping, known, what: str) -> None:
    if not isinstance(data, Mapping):
        raise RunSpecError(f"{what} must be a mapping, got {data!r}")
    unknown = sorted(set(data) - set(known))
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
        steps = []
        for i, step in enumerate(self.steps):
            try:
                t, value = step
                value = tuple(_finite(v, f"reference step {i} value") for v in value)
            except (TypeError, ValueError) as exc:
                raise RunSpecError(f"reference step {i} must be (time, (u, v, w, r)): {exc}") from None
            if len(value) != 4:
                raise RunSpecError(f"reference step {i} needs 4 values (u, v, w, r), got {len(value)}")
            steps.append((_finite(t, f"reference step {i} time"), value))
        if not steps:
            raise RunSpecError("a reference profile needs at least one step")
        times = [t for t, _ in steps]
        if times != sorted(times) or len(set(times)) != len(times):
            raise RunSpecError(f"reference step times must be strictly increasing, got {times}")
        object.__setattr__(self, "steps", tuple(steps))

    def at(self, t: float) -> Reference:
        """The reference in force at time ``t`` [s]."""
        value = self.steps[0][1]
        for start, v in self.steps:
            if t >= start - 1e-9:
                value = v
        return Reference(value)

    def to_list(self) -> list:
        return [[t, *v] for t, v in self.steps]

    @classmethod
    def from_list(cls, rows) -> "ReferenceSteps":
        """From ``[[t, u, v, w, r], ...]``."""
        try:
            return cls(tuple((row[0], tuple(row[1:])) for row in rows))
        except (TypeError, IndexError, KeyError):
            raise RunSpecError(f"a reference profile is a list of [t, u, v, w, r] rows, got {rows!r}") from None


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
    a vehicle configuration name; for ``thruster_efficiency`` four factors; for ``controller`` the
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
        if self.kind not in EVENT_KINDS:
            raise RunSpecError(f"unknown event kind {self.kind!r}; known: {', '.join(EVENT_KINDS)}")
        detail = self.detail
        if self.kind == "current":
            detail = _current_detail(detail)
        elif self.kind == "configuration":
            if not isinstance(detail, str) or not detail:
                raise RunSpecError(f"a configuration event names a vehicle configuration, got {detail!r}")
        elif self.kind == "thruster_efficiency":
            detail = tuple(_finite(v, "thruster efficiency") for v in (detail or ()))
            if len(detail) != 4:
                raise RunSpecError(f"a thruster_efficiency event needs 4 factors, got {len(detail)}")
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
    starting at rest ``start_depth`` deep, at the run's control period.
    """

    vehicle: str = "baseline"
    operating_points: tuple = (0.0, 0.7)
    mode: str = "realistic"
    start_depth: float = 50.0

    def __post_init__(self):
        points = tuple(_finite(v, "operating point") for v in self.operating_points)
        if not points:
            raise RunSpecError("a self-test needs at least one operating point")
        object.__setattr__(self, "operating_points", points)
        if self.mode not in ("realistic", "artificial"):
            raise RunSpecError(f"self-test mode must be realistic or artificial, got {self.mode!r}")
        object.__setattr__(self, "start_depth", _finite(self.start_depth, "self-test start depth"))

    def to_dict(self) -> dict:
        return {"vehicle": self.vehicle, "operating_points": list(self.operating_points), "mode": self.mode,
                "start_depth": self.start_depth}

    @classmethod
    def from_dict(cls, data: Mapping) -> "SelfTestDesign":
        _refuse_unknown(data, ("vehicle", "operating_points", "mode", "start_depth"), "design")
        return cls(**{k: (tuple(v) if k == "operating_points" else v) for k, v in data.items()})


def _frozen_mapping(value, what: str) -> dict:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise RunSpecError(f"{what} must be a mapping, got {value!r}")
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

    def __post_init__(self):
        period = _finite(self.control_period, "control_period")
        if period <= 0:
            raise RunSpecError(f"control_period must be > 0 s, got {period}")
        steps = period / min(PHYSICS_STEP, period)
        if abs(steps - round(steps)) > 1e-9:
            raise RunSpecError(f"control_period {period} s must be a whole number of {PHYSICS_STEP} s physics steps "
                               "(or shorter than one)")
        duration = _finite(self.duration, "duration")
        if duration <= 0:
            raise RunSpecError(f"duration must be > 0 s, got {duration}")
        if abs(duration / period - round(duration / period)) > 1e-6:
            raise RunSpecError(f"duration {duration} s must be a whole number of control periods ({period} s)")
        if self.dynamics not in ("nonlinear", "linearised"):
            raise RunSpecError(f"dynamics must be nonlinear or linearised, got {self.dynamics!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or not 0 <= self.seed < 2**31:
            raise RunSpecError(f"seed must be an integer in [0, 2^31), got {self.seed!r}")
        object.__setattr__(self, "control_period", period)
        object.__setattr__(self, "duration", duration)
        object.__setattr__(self, "seed", int(self.seed))
        object.__setattr__(self, "start_depth", _finite(self.start_depth, "start_depth"))
        object.__setattr__(self, "environment", _frozen_mapping(self.environment, "environment"))
        for name, size in (("start_state", 12), ("start_pitch", 4)):
            value = getattr(self, name)
            if value is not None:
                value = tuple(_finite(v, name) for v in value)
                if len(value) != size:
                    raise RunSpecError(f"{name} needs {size} values, got {len(value)}")
                object.__setattr__(self, name, value)
        if not isinstance(self.controller, ControllerSpec):
            object.__setattr__(self, "controller", ControllerSpec.from_dict(self.controller))
        if not isinstance(self.reference, ReferenceSteps):
            object.__setattr__(self, "reference", ReferenceSteps.from_list(self.reference))
        events = tuple(e if isinstance(e, RunEvent) else RunEvent.from_dict(e) for e in self.events)
        object.__setattr__(self, "events", tuple(sorted(events, key=lambda e: e.time)))
        object.__setattr__(self, "metrics", tuple(self.metrics))

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
                "seed": self.seed, "metrics": list(self.metrics)}

    @classmethod
    def from_dict(cls, data: Mapping) -> "RunSpec":
        """A spec from plain data; unknown keys are refused (``physics_step`` is derived: if given it
        must agree)."""
        known = [f for f in cls.__dataclass_fields__] + ["physics_step"]
        _refuse_unknown(data, known, "run spec")
        values = {k: v for k, v in data.items() if k != "physics_step"}
        if values.get("design") is not None:
            values["design"] = SelfTestDesign.from_dict(values["design"])
        for name in ("events", "metrics"):
            if name in values:
                values[name] = tuple(values[name] or ())
        spec = cls(**values)
        if "physics_step" in data and abs(float(data["physics_step"]) - spec.physics_step) > 1e-12:
            raise RunSpecError(f"physics_step {data['physics_step']} disagrees with the derived "
                               f"{spec.physics_step} s (min(0.1 s, T))")
        return spec
