"""The in-process runner: a :class:`~seapup_runs.spec.RunSpec` flown in this process, no ROS.

:func:`run` builds the simulation the spec describes (vehicle, dynamics,
environment, physics step, start, the simulator's scheduled events), makes
each controller of the spec's timeline by name
(:func:`seapup_common.controllers.create_controller`), and flies fig. 5.1's
loop in lockstep: at every sample t_k the controller is told the blade pitch
the vehicle has (:meth:`~seapup_common.contract.VelocityController.applied`,
what the simulator node publishes on ``thrusters/applied``), sees the
measurement and the reference in force and returns the command held until
t_k+1. A controller taking over at a ``controller`` event starts bumpless
from the applied pitch at that sample, as the graph's lifecycle node does.
An estimating controller's ``named_estimate()`` (the self-tuners of ch. 7)
is logged each sample as the series' ``estimate``; its mode changes (jacketing) become
``controller_mode`` events and its counts ``metrics.jacket``.

:func:`design` first fills the design documents the spec leaves to its
:class:`~seapup_runs.spec.SelfTestDesign` (the self-test flown in this
process; cached per design and period, since one self-test serves many runs).
The ROS graph runner (``seapup_bringup.graph.graph_runner.run_on_graph``) flies the
same designed spec and gives the same :class:`~seapup_runs.result.RunResult`.
"""
from __future__ import annotations

import dataclasses
import importlib
import json
from typing import Callable

import numpy as np

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_common.contract import Command, MEASUREMENT_FIELDS
from seapup_common.controllers import ControllerSpec, at_input_limit, controller_type, create_controller
from seapup_runs.metrics import check_names, compute
from seapup_runs.result import RunResult, Series
from seapup_runs.spec import RunEvent, RunSpec, RunSpecError

__all__ = ["run", "design", "design_all", "simulation_events", "start_pitch", "DesignFailed"]


class DesignFailed(RuntimeError):
    """The self-test that was to design a run's controller did not finish (its reason says why)."""


_DESIGNS: dict[str, dict] = {}


def design(spec: RunSpec, progress: Callable[[float], None] | None = None) -> RunSpec:
    """The spec with every controller that needs a design document and has none designed by its
    :class:`~seapup_runs.spec.SelfTestDesign` (a self-test flown in this process at the run's period).

    Raises
    ------
    RunSpecError
        If a controller needs a document and the spec has no design.
    DesignFailed
        If the self-test does not finish.
    """
    missing = _undesigned(spec)
    if not missing:
        return spec
    document = _design_document(spec, progress)
    return spec.with_controllers({i: document for i in missing})


def design_all(specs) -> list[RunSpec]:
    """:func:`design` of each of ``specs``, each distinct design worked out once: a campaign's rows mostly
    share one (the same self-test settings, period, vehicle and coefficients), whose document :func:`design`
    would otherwise look up per row -- reading the vehicle's description and keying it, about a third of a
    millisecond a run."""
    documents: dict = {}
    out = []
    for spec in specs:
        missing = _undesigned(spec)
        if missing:
            share = (None if spec.design is None else json.dumps(spec.design.to_dict(), sort_keys=True, default=str),
                     spec.control_period, spec.vehicle, json.dumps(spec.coefficients, sort_keys=True, default=str))
            if share not in documents:
                documents[share] = _design_document(spec)
            spec = spec.with_controllers({i: documents[share] for i in missing})
        out.append(spec)
    return out


def _undesigned(spec: RunSpec) -> list[int]:
    """The controllers of ``spec``'s timeline that need a design document and have none."""
    from seapup_common.controllers import controller_type
    return [i for i, (_, c) in enumerate(spec.controller_timeline())
            if c.document is None and not c.file and controller_type(c.type).needs_document]


def _design_document(spec: RunSpec, progress: Callable[[float], None] | None = None) -> dict:
    """The design document of ``spec``'s :class:`~seapup_runs.spec.SelfTestDesign` (:func:`design`)."""
    if spec.design is None:
        raise RunSpecError(f"controller {spec.controller_timeline()[_undesigned(spec)[0]][1].type!r} needs a design "
                           "document: give its file/document or the run's 'design' (a self-test)")
    from seapup_sim.vehicle_config import load_vehicle_config, scaled
    d = spec.design
    # on the run's own vehicle, its coefficients as flown (the self-test needs no model), unless nominal
    vehicle = load_vehicle_config(d.vehicle)
    if spec.coefficients and d.vehicle == spec.vehicle and not d.nominal:
        vehicle = scaled(vehicle, **spec.coefficients)
    # the vehicle's own self-test settings (its description's self_test) are part of what is designed
    key = json.dumps([d.to_dict(), spec.control_period, vehicle], sort_keys=True, default=str)
    if key not in _DESIGNS:
        from seapup_control.self_test import result_document
        from seapup_runs.self_test_flight import fly_self_test
        flown = fly_self_test(vehicle, {"sample_period": spec.control_period,
                                          "operating_points": list(d.operating_points), "mode": d.mode,
                                          "fit": d.fit},
                              start_depth=d.start_depth, progress=progress)
        if flown.test.phase.value != "done":
            raise DesignFailed(f"the self-test designing {spec.name!r} {flown.test.phase.value}: {flown.test.reason}")
        _DESIGNS[key] = result_document(flown.test)
    return _DESIGNS[key]


def simulation_events(spec: RunSpec) -> list:
    """The spec's plant events as :class:`seapup_sim.simulation.Event` objects (the parser the simulator
    node's ``events`` parameter uses too), checked before anything flies: an unknown configuration or a
    current beyond the environment's limits is refused now, not when its time comes.

    Raises
    ------
    RunSpecError
        Naming the event and why.
    """
    from seapup_sim.environment_config import load_limits
    from seapup_sim.simulation import events_from_data
    from seapup_sim.vehicle_config import ConfigError, load_vehicle_config
    events = events_from_data([e.to_dict() for e in spec.plant_events()])
    for event in events:
        try:
            if event.kind == "configuration":
                load_vehicle_config(event.value)
            elif event.kind == "current" and event.value is not None:
                load_limits().check_current(event.value)
        except (ConfigError, ValueError) as exc:
            raise RunSpecError(f"{event.kind} event at {event.time:g} s: {exc}") from None
    return events


def start_pitch(spec: RunSpec) -> np.ndarray:
    """The blade pitch at t = 0: the spec's, or the hover setting of its vehicle (eq. 5.2 for the baseline)."""
    if spec.start_pitch is not None:
        return np.array(spec.start_pitch, float)
    from seapup_sim.hover import hover_of
    config = spec.vehicle_config()
    key = json.dumps(config, sort_keys=True, default=str)   # the trim is solved once per configuration
    if key not in _HOVER:
        _HOVER[key] = hover_of(config)
    return _HOVER[key].copy()


_HOVER: dict[str, np.ndarray] = {}


def at_vehicle_limit(controller: ControllerSpec, limit: float) -> ControllerSpec:
    """``controller`` with its input limit (``blade_pitch_limit``) at the vehicle's when the spec leaves it at
    the default and the vehicle's differs (a virtual-input vehicle's full scale, :mod:`seapup_sim.inputs`):
    the law then saturates, and winds back, where the vehicle does."""
    if "blade_pitch_limit" in controller.parameters or limit == BLADE_PITCH_LIMIT:
        return controller
    return dataclasses.replace(controller, parameters=at_input_limit(controller_type(controller.type),
                                                                     controller.parameters, limit))


def run(spec: RunSpec, progress: Callable[[float], None] | None = None, wrap: Callable | None = None) -> RunResult:
    """Fly ``spec`` in this process (see the module docstring).

    Parameters
    ----------
    spec : RunSpec
    progress : callable, optional
        Called with the fraction done (the self-test's, then the run's).
    wrap : callable, optional
        ``wrap(controller) -> controller``: each controller made is flown through it (to time or probe the
        law's calls; the benchmark of sec. 7.7's computing cost).

    Returns
    -------
    RunResult
        The designed spec, the series (one row per sample, t = 0 ... duration) and the spec's metrics.
    """
    from seapup_sim.simulation import Simulation

    check_names(spec.metrics)   # before the self-test and the flight, not after them
    spec = design(spec)
    simulation = Simulation.from_config(spec.vehicle_config(), spec.environment, seed=spec.seed, dt=spec.physics_step,
                                 control_period=spec.control_period, events=simulation_events(spec),
                                 state=spec.initial_state(), pitch=start_pitch(spec), dynamics=spec.dynamics)
    if simulation.plant.compiled:   # its kernels loaded before the laws are made: a run's laws then take theirs
        importlib.import_module("seapup_sim.compiled")   # (compiled_by_default) whatever the process flew before
    timeline = spec.controller_timeline()
    n = spec.samples
    t = np.full(n + 1, np.nan)
    states, reference, command, applied = (np.full((n + 1, k), np.nan) for k in (12, 4, 4, 4))
    measured = {name: np.full(n + 1, np.nan) for name in ("u", "v", "w", "p", "q", "r", "roll", "pitch", "yaw",
                                                          "x", "y", "z", "depth", "altitude")}
    events = [{"time": e.time, "kind": e.kind, "detail": RunEvent.to_dict(e)["detail"]} for e in spec.plant_events()]
    controller, next_switch = None, 0
    estimates: dict[str, np.ndarray] = {}
    used = []
    for k in range(n + 1):
        sample = simulation.sample()
        t[k], states[k], applied[k] = sample.t, sample.state, simulation.plant.applied
        _record_measurement(measured, k, sample.measurement)
        if k == n:
            break
        while next_switch < len(timeline) and timeline[next_switch][0] <= sample.t + 1e-9:
            controller = create_controller(at_vehicle_limit(timeline[next_switch][1], simulation.model.pitch_limit),
                                           spec.control_period)
            used.append(controller)
            if wrap is not None:
                controller = wrap(controller)
            controller.reset(Command(simulation.plant.applied, sample.t))  # bumpless from the applied pitch
            if next_switch > 0:
                events.append({"time": sample.t, "kind": "controller",
                               "detail": {"type": timeline[next_switch][1].type}})
            next_switch += 1
        controller.applied(sample.t, Command(simulation.plant.applied, sample.t))
        demand = spec.pilot_at(sample.t) if spec.pilot else None
        if demand is not None and callable(getattr(controller, "pilot", None)):   # a scripted pilot's stick
            controller.pilot(sample.t, demand[:3], (0.0, 0.0, demand[3]))
        ref = spec.reference.at(sample.t)
        out = controller.update(sample.t, sample.measurement, ref)
        reference[k], command[k] = ref.velocity, out.blade_pitch
        named = getattr(controller, "named_estimate", None)   # an estimating controller's parameters
        if named is not None:
            for name, value in named().items():
                if name not in estimates:   # (not setdefault: its default would be made every sample)
                    estimates[name] = np.full(n + 1, np.nan)
                estimates[name][k] = value
        simulation.advance(out.blade_pitch)
        if progress is not None and (k % 25 == 0 or k == n - 1):
            progress((k + 1) / n)
    estimate = ({"names": list(estimates), "values": np.column_stack(list(estimates.values()))}
                if estimates else None)
    jacket = _jacket(used, events)
    series = Series.from_states(t, states, measured, reference, command, applied, sorted(events, key=lambda e: e["time"]),
                                estimate)
    result = RunResult(spec, series)
    result.metrics = compute(result)
    if jacket:
        result.metrics["jacket"] = jacket
    return result


def _jacket(controllers: list, events: list) -> dict:
    """A self-tuner's mode changes (commissioning, adaptive, fallback with the jacket rule's reason) as
    ``controller_mode`` events, and its counts summed over the run (``metrics.jacket``)."""
    counts: dict[str, int] = {}
    for controller in controllers:
        if not isinstance(getattr(controller, "counts", None), dict) or not hasattr(controller, "events"):
            continue
        for event in controller.events:
            events.append({"time": event["t"], "kind": "controller_mode",
                           "detail": {"mode": event["mode"], "reason": event["reason"]}})
        for key, value in controller.counts.items():
            counts[key] = counts.get(key, 0) + int(value)
    return counts


_MEASURED = {"velocity": ("u", "v", "w"), "rates": ("p", "q", "r"), "attitude": ("roll", "pitch", "yaw"),
             "position": ("x", "y", "z"), "depth": ("depth",), "altitude": ("altitude",)}
assert set(_MEASURED) == set(MEASUREMENT_FIELDS)


def _record_measurement(measured: dict, k: int, measurement) -> None:
    for field_name, names in _MEASURED.items():
        reading = getattr(measurement, field_name)
        if reading.valid:
            values = np.atleast_1d(reading.value)
            for name, value in zip(names, values):
                measured[name][k] = value
