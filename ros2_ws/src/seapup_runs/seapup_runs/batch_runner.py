"""Many runs flown together: the batch runner of campaigns (issue 26).

:func:`fly_batch` flies N :class:`~seapup_runs.spec.RunSpec` at once -- the plants as one
:class:`~seapup_sim.batch.BatchPlant`, their currents as one :class:`~seapup_sim.batch.BatchCurrent`, their
sensors as one :class:`~seapup_sim.batch.BatchSensors` and their MFOL laws (eq. 4.11, 5.6; fixed-gain or
scheduled) as one :class:`~seapup_control.mfol_controller.BatchMFOL` -- in fig. 5.1's lockstep loop: at each
sample every vehicle's sensors are read, its law gives the command held over the control period, and the
plants step with the scheduled events (configuration, fouling, current statistics) of each run at their
times. Each vehicle is built by :class:`~seapup_sim.simulation.Simulation` exactly as
:func:`seapup_runs.runner.run` builds it (the same model, random streams and events), so its
:class:`~seapup_runs.result.RunResult` is the one ``run(spec)`` gives, to rounding (the plant, current and
sensors bit for bit; the laws' stacked products to the last bits: ``test/test_batch_runner.py``).

The self-tuners of ch. 7 (``explicit``, ``gmv``) fly in the same batch: the plants, currents and sensors
batched with the rest, each run's law its own object (its estimator and jacket, with compiled kernels where
they exist: :func:`seapup_ident.compiled.ud_update`, :func:`seapup_control.compiled.explicit_design`), told the
applied blade pitch and given the run's readings at each sample as :func:`seapup_runs.runner.run` tells and
gives them -- so each such run is the one flown alone bit for bit, its estimate traces, mode events and jacket
counts included (``test/test_batch_runner.py``). What a law logs is filed under its run (:data:`RUN_INDEX`).

What the batch does not fly (:func:`batch_reason` says why, and :func:`seapup_runs.campaign.fly_rows` flies
those runs one by one): other controllers, controller switches, the linearised plant, the umbilical, strapdown
velocity, and a current switched on or off during a run. A vehicle that diverges stops alone: its entry is the
:class:`~seapup_sim.integrator.DivergenceError` the single run would raise.
"""
from __future__ import annotations

import contextvars

import numpy as np

from seapup_runs.metrics import compute_all
from seapup_runs.result import RunResult, Series
from seapup_runs.spec import RunEvent, RunSpec

__all__ = ["batch_reason", "fly_batch", "batch_key", "environments_of", "RUN_INDEX", "BATCHED_LAWS"]

#: Which run of a batch the code running now serves (its index in :func:`fly_batch`'s specs; None: the batch as a
#: whole): a log handler files a law's records under its run (:func:`seapup_runs.campaign.run_log`).
RUN_INDEX: contextvars.ContextVar = contextvars.ContextVar("seapup_batch_run", default=None)
#: The control laws a batch flies: MFOL stacked (BatchMFOL), the self-tuners run by run.
BATCHED_LAWS = ("mfol", "explicit", "gmv")

_MEASURED = {"velocity": ("u", "v", "w"), "rates": ("p", "q", "r"), "attitude": ("roll", "pitch", "yaw"),
             "position": ("x", "y", "z"), "depth": ("depth",), "altitude": ("altitude",)}


def batch_reason(spec: RunSpec, environment=None) -> str | None:
    """Why ``spec`` cannot fly in a batch (None: it can). ``environment``: the spec's
    :class:`~seapup_sim.environment_config.EnvironmentConfig` when the caller has it already."""
    from seapup_sim.environment_config import load_environment
    if spec.dynamics != "nonlinear":
        return f"the {spec.dynamics} plant has no compiled kernel"
    if len(spec.controller_timeline()) != 1 or spec.controller.type not in BATCHED_LAWS:
        return f"only a run of one law of {', '.join(BATCHED_LAWS)} is batched (no switches)"
    if spec.coefficients:
        return "a vehicle with scaled coefficients flies run by run"
    from seapup_runs.spec import vehicle_thrusters
    if (vehicle_thrusters(spec.vehicle) or ("controllable_pitch",))[0] != "controllable_pitch":
        return "a batch flies four blade pitches per vehicle: a virtual-input vehicle's mixer flies run by run"
    env = environment if environment is not None else load_environment(spec.environment)
    if env.umbilical.enabled:
        return "the umbilical's wrench is solved per vehicle"
    if env.sensors.strapdown_enabled:
        return "strapdown velocity is read by the single sensor suite"
    for event in spec.plant_events():
        if event.kind == "current" and (event.detail is None or not env.current.enabled):
            return "a current switched on or off during the run"
    return None


def batch_key(spec: RunSpec) -> tuple:
    """Runs with the same key can share a batch: the same sample grid and physics step."""
    return (spec.control_period, spec.physics_step, spec.samples)


def fly_batch(specs, threads: int = 1) -> list:
    """Fly ``specs`` together (see the module docstring): for each, its :class:`RunResult` or the exception its
    single run would raise (a diverged plant).

    Raises
    ------
    ValueError
        If a spec cannot be batched (:func:`batch_reason`) or the specs do not share one :func:`batch_key`.
    """
    from seapup_common.contract import Command, Measurement, Reading
    from seapup_common.controllers import create_controller
    from seapup_control.mfol_controller import BatchMFOL
    from seapup_sim.batch import BatchCurrent, BatchPlant, BatchSensors
    from seapup_sim.integrator import DivergenceError
    from seapup_sim.linearised import vehicle_model
    from seapup_sim.simulation import Simulation
    from seapup_sim.vehicle_config import load_vehicle_config
    from seapup_runs.runner import _jacket, at_vehicle_limit, design_all, simulation_events, start_pitch

    specs = design_all(specs)
    environments = environments_of(specs)
    for i, spec in enumerate(specs):
        reason = batch_reason(spec, environments[i])
        if reason is not None:
            raise ValueError(f"run {i} ({spec.name}) cannot fly in a batch: {reason}")
    if len({batch_key(s) for s in specs}) != 1:
        raise ValueError("the runs of a batch need one control period, physics step and duration")
    spec0 = specs[0]
    trims: dict = {}   # the hover trim, once per vehicle (start_pitch reads and keys its configuration)
    pitches = []
    for s in specs:
        if s.start_pitch is None and s.vehicle not in trims:
            trims[s.vehicle] = start_pitch(s)
        pitches.append(start_pitch(s) if s.start_pitch is not None else trims[s.vehicle])
    # one model per vehicle, shared by its runs: the batch plant steps its own copy of the state, pitch and
    # efficiency of each, and a configuration event gives that run a model of its own (BatchPlant.configure)
    models: dict = {}
    for s in specs:
        if (s.vehicle, s.dynamics) not in models:
            models[s.vehicle, s.dynamics] = vehicle_model(load_vehicle_config(s.vehicle), s.dynamics)
    sims = [Simulation.from_config(s.vehicle, environments[i], seed=s.seed, dt=s.physics_step,
                                   control_period=s.control_period, events=simulation_events(s),
                                   state=s.initial_state(), pitch=pitches[i].copy(), dynamics=s.dynamics,
                                   model=models[s.vehicle, s.dynamics])
            for i, s in enumerate(specs)]
    n, dt, substeps, samples = len(specs), spec0.physics_step, sims[0].substeps, spec0.samples
    plant = BatchPlant([sim.model for sim in sims], dt=dt, states=[sim.plant.state for sim in sims],
                       pitches=[sim.plant.pitch for sim in sims], threads=threads)
    for i, sim in enumerate(sims):
        plant.set_efficiency(i, sim.model.thrusters.efficiency)
    with_current = [i for i, sim in enumerate(sims) if sim.current is not None]
    slot = {i: k for k, i in enumerate(with_current)}
    currents = BatchCurrent([sims[i].current for i in with_current]) if with_current else None
    sensors = BatchSensors([sim.sensors for sim in sims])
    laws = [create_controller(at_vehicle_limit(s.controller, sims[i].model.pitch_limit), s.control_period)
            for i, s in enumerate(specs)]
    stacked = [i for i, s in enumerate(specs) if s.controller.type == "mfol"]   # one BatchMFOL
    alone = [i for i, s in enumerate(specs) if s.controller.type != "mfol"]     # each its own law
    law = BatchMFOL([laws[i] for i in stacked]) if stacked else None
    variances = [sim.sensors.reading_variances() for sim in sims]   # as each suite's readings carry them
    estimates: list[dict] = [{} for _ in specs]
    pending = [list(sim.events) for sim in sims]
    next_event = min((e.time for events in pending for e in events), default=np.inf)
    references = {}
    for i, s in enumerate(specs):
        references.setdefault(s.reference, []).append(i)

    t = np.full(samples + 1, np.nan)
    states, applied = np.full((samples + 1, n, 12), np.nan), np.full((samples + 1, n, 4), np.nan)
    reference, command = np.full((samples + 1, n, 4), np.nan), np.full((samples + 1, n, 4), np.nan)
    measured = {name: np.full((samples + 1, n), np.nan) for names in _MEASURED.values() for name in names}
    velocity = np.zeros((n, 3))
    for k in range(samples + 1):
        now = plant.t
        t[k], states[k], applied[k] = now, plant.state, plant.pitch
        read = sensors.measure(now, plant.state)
        for field, names in _MEASURED.items():
            values = read[field].reshape(n, -1)
            for j, name in enumerate(names):
                measured[name][k] = values[:, j]
        if k == samples:
            break
        if k == 0 and law is not None:
            law.reset(plant.pitch[stacked])
        ref, in_force = np.empty((n, 4)), {}
        for profile, rows in references.items():
            in_force[profile] = profile.at(now)
            ref[rows] = in_force[profile].velocity
        out = np.empty((n, 4))
        if law is not None:
            out[stacked] = law.update(np.column_stack([read["velocity"][stacked], read["rates"][stacked, 2]]),
                                      ref[stacked])
        for i in alone:   # as runner.run: told the applied pitch, then the sample's readings and reference
            if not plant.active[i]:   # its plant diverged: its run ended there, as the single run's raise ends it
                out[i] = plant.pitch[i]
                continue
            token = RUN_INDEX.set(i)
            try:
                controller = laws[i]
                if k == 0:
                    controller.reset(Command(plant.pitch[i], now))
                controller.applied(now, Command(plant.pitch[i], now))
                velocity_i, rates_i = read["velocity"][i].copy(), read["rates"][i].copy()
                velocity_i.setflags(write=False)
                rates_i.setflags(write=False)
                measurement = Measurement(now, Reading(velocity_i, now, variances[i]["velocity"]),
                                          Reading(rates_i, now, variances[i]["rates"]))
                out[i] = controller.update(now, measurement, in_force[specs[i].reference]).blade_pitch
                if not estimates[i]:   # the law's named traces (SelfTuner.estimate_names), a row a sample
                    names = controller.estimate_names()
                    estimates[i] = {"names": list(names), "values": np.full((samples + 1, len(names)), np.nan)}
                estimates[i]["values"][k] = controller.estimate_values()
            finally:
                RUN_INDEX.reset(token)
        reference[k], command[k] = ref, out
        for _ in range(substeps):
            if plant.t + 1e-9 >= next_event:
                next_event = _apply_events(plant, currents, slot, pending)
            if currents is not None:
                velocity[with_current] = currents.velocity_ned()
            plant.step(out, velocity)
            if currents is not None:
                currents.step()

    results, jackets = [], []
    for i, spec in enumerate(specs):
        if not plant.active[i]:
            results.append(DivergenceError(plant.errors[i]))
            jackets.append({})
            continue
        events = [{"time": e.time, "kind": e.kind, "detail": RunEvent.to_dict(e)["detail"]}
                  for e in spec.plant_events()]
        jacket = _jacket([laws[i]], events) if i in alone else {}   # a self-tuner's mode events and counts
        estimate = estimates[i] or None
        series = Series.from_states(t, states[:, i], {name: v[:, i] for name, v in measured.items()},
                                    reference[:, i], command[:, i], applied[:, i],
                                    sorted(events, key=lambda e: e["time"]), estimate)
        results.append(RunResult(spec, series))
        jackets.append(jacket)
    flown = [(r, jacket) for r, jacket in zip(results, jackets) if isinstance(r, RunResult)]
    for (result, jacket), metrics in zip(flown, compute_all([r for r, _ in flown])):   # over the batch at once
        result.metrics = metrics
        if jacket:
            result.metrics["jacket"] = jacket
    return results


def environments_of(specs, cache: dict | None = None) -> list:
    """Each spec's environment, read once per distinct overrides and water density: a campaign's rows mostly
    share a few (:class:`~seapup_sim.environment_config.EnvironmentConfig` is frozen, so sharing is safe).
    ``cache``: a dict to share the readings between calls."""
    import json
    from seapup_sim.environment_config import load_environment
    from seapup_sim.linearised import vehicle_model
    from seapup_sim.vehicle_config import load_vehicle_config
    cache = {} if cache is None else cache
    rho, built, out = cache.setdefault("rho", {}), cache.setdefault("environment", {}), []
    for spec in specs:
        if spec.vehicle not in rho:
            rho[spec.vehicle] = vehicle_model(load_vehicle_config(spec.vehicle), spec.dynamics).rho
        key = (json.dumps(spec.environment, sort_keys=True, default=repr), rho[spec.vehicle])
        if key not in built:
            built[key] = load_environment(spec.environment, rho=key[1])
        out.append(built[key])
    return out


def _apply_events(plant, currents, slot: dict, pending: list) -> float:
    """Carry out every event due at the plant's time (as ``Simulation._apply_events``); the next one's time."""
    from seapup_sim.vehicle_config import load_vehicle_config
    for i, events in enumerate(pending):
        while events and events[0].time <= plant.t + 1e-9:
            event = events.pop(0)
            if event.kind == "configuration":
                config = load_vehicle_config(event.value) if isinstance(event.value, str) else event.value
                plant.configure(i, config)
                if "thruster_efficiency" in config:   # a configuration that sets its own fouling
                    plant.set_efficiency(i, plant.models[i].thrusters.efficiency)
            elif event.kind == "thruster_efficiency":
                plant.set_efficiency(i, event.value)
            else:
                currents.set_params(slot[i], event.value)
    return min((events[0].time for events in pending if events), default=np.inf)
