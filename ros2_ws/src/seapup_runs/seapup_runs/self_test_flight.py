"""The self-test flown on the simulated Seapup in one process (pure cores in lockstep, no ROS).

The software-in-the-loop driver of :class:`seapup_control.self_test.SelfTest`:
it builds a :class:`~seapup_sim.simulation.Simulation` of a vehicle
configuration, feeds the self-test the simulated *measurements* every
sample, holds its commands, performs the plant resets of the artificial
mode (rest, or the trim of the operating point, held by its blade pitches),
and measures what the thesis reports about the run from the simulation's
truth: the time taken and the box of water used (sec. 5.3.3).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from seapup_common.contract import Command
from seapup_control.self_test import SelfTest, SelfTestConfig, vehicle_self_test
from seapup_sim.analysis import TrimError, trim
from seapup_sim.simulation import Simulation
from seapup_runs.spec import PHYSICS_STEP

__all__ = ["SelfTestRun", "fly_self_test", "self_test_config_for"]


def self_test_config_for(vehicle, overrides=None) -> SelfTestConfig:
    """The self-test settings for ``vehicle`` (a configuration name, a file path or a configuration mapping):
    its description's ``self_test`` with ``overrides`` over them (:func:`seapup_control.self_test.vehicle_self_test`),
    within its inputs' limit (the Seapup's blade pitches, a virtual-input vehicle's full scale).

    Raises
    ------
    ConfigError
        An unknown vehicle, a malformed description or setting.
    """
    from seapup_sim.vehicle import VehicleModel
    from seapup_sim.vehicle_config import load_vehicle_config
    config = vehicle if isinstance(vehicle, dict) else load_vehicle_config(vehicle)
    model = VehicleModel(config)
    return SelfTestConfig.load(vehicle_self_test(model.config, overrides), limit=model.pitch_limit)


@dataclass
class SelfTestRun:
    """A finished self-test run and what it used."""

    test: SelfTest
    space: np.ndarray          # extent of x, y, z [m] (sec. 5.3.3's box of water)
    depth_range: tuple[float, float]  # shallowest and deepest z relative to the start [m, down positive]
    truth: np.ndarray          # (n, 13): t and the 12 states at each sample


def fly_self_test(vehicle: str = "baseline", overrides=None, environment=None, seed: int = 0,
                  start_depth: float = 50.0, start_pitch=None, max_time: float = 3600.0,
                  progress=None) -> SelfTestRun:
    """Fly a self-test in lockstep with the simulated vehicle.

    Parameters
    ----------
    vehicle : str
        Vehicle configuration (``baseline``, ``camera``, ...).
    overrides : mapping, optional
        Self-test settings over ``seapup_control/data/self_test.yaml``.
    environment : mapping, optional
        Environment overrides (default: noise-free sensors, no current, as sec. 5.3.2).
    start_depth : float
        Depth of the start [m].
    start_pitch : array_like, optional
        Blade pitch applied at the start [rad] (default: the self-test's zero level).
    max_time : float
        Simulated seconds after which the run is cancelled.
    progress : callable, optional
        Called with the fraction done.
    """
    environment = {"sensors": "ideal"} if environment is None else environment
    start = np.zeros(12)
    start[2] = start_depth

    def new_simulation(state, pitch, period):
        return Simulation.from_config(vehicle, environment, seed=seed, control_period=period,
                                      dt=min(PHYSICS_STEP, period), state=state, pitch=pitch)

    # the inputs' limit is the vehicle's: the Seapup's blade pitches, a virtual-input vehicle's full scale
    config = self_test_config_for(vehicle, overrides)
    pitch = config.zero_level if start_pitch is None else np.asarray(start_pitch, float)
    simulation = new_simulation(start, pitch, config.sample_period)
    test = SelfTest(config)
    test.reset(Command(pitch))
    truth, offset = [], 0.0
    while not test.finished:
        sample = simulation.sample()
        t = sample.t + offset
        truth.append(np.r_[t, sample.state])
        if t >= max_time:
            test.cancel(f"not finished within {max_time:g} s")
            break
        command = test.update(t, sample.measurement)
        if test.reset_request is not None:  # artificial quiescence: restart at the operating point
            try:
                held = trim(simulation.model, test.reset_request)
            except TrimError as exc:  # e.g. a dead thruster: no setting holds the operating point
                test.abort(f"the plant cannot be reset to {test.reset_request:g} m/s: {exc}")
                continue
            state = start.copy()
            state[:3] = sample.state[:3]
            state[3:12] = held.state[3:12]
            offset = t
            simulation = new_simulation(state, held.blade_pitch, config.sample_period)
            test.plant_reset(Command(held.blade_pitch))
            continue
        simulation.advance(command.blade_pitch)
        if progress is not None and len(truth) % 25 == 0:
            progress(test.progress)
    if progress is not None:
        progress(1.0)
    truth = np.array(truth)
    position = truth[:, 1:4]
    depth = position[:, 2] - start_depth
    return SelfTestRun(test, position.max(axis=0) - position.min(axis=0), (float(depth.min()), float(depth.max())),
                       truth)
