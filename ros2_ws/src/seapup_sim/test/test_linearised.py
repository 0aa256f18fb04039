"""The linearised Seapup as a plant (seapup_sim.linearised; thesis eq. 3.2, sec. 6.5.1).

Truths: the nonlinear model itself for small perturbations about hover (the linearisation's error
is second order), the exact zero-order-hold discretisation of (A, B) by scipy.signal.cont2discrete
(a matrix exponential, not our RK4), and the trim of a fouled vehicle.
"""
import copy

import numpy as np
import pytest
import scipy.signal

from seapup_sim.analysis import trim
from seapup_sim.linearised import LinearisedVehicleModel, vehicle_model
from seapup_sim.simulation import Simulation
from seapup_sim.simulator_core import SimulatorCore, SimulatorConfig
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config

pytestmark = pytest.mark.unit


@pytest.fixture(scope="module")
def models():
    config = load_vehicle_config("baseline")
    return VehicleModel(config), LinearisedVehicleModel(config)


def test_small_perturbations_about_hover_match_the_nonlinear_model_to_second_order(models):
    nonlinear, linear = models
    rng = np.random.default_rng(1)
    direction = rng.normal(size=12) * np.r_[0, 0, 0, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.05, 0.05, 0.05]
    pitch_direction = rng.normal(size=4) * 0.1
    errors = []
    for scale in (1e-2, 5e-3):
        x = linear.x0 + scale * direction
        p = linear.pitch0 + scale * pitch_direction
        errors.append(np.abs(linear.derivatives(x, p) - nonlinear.derivatives(x, p)).max())
    assert errors[0] < 1e-4
    assert errors[1] < 0.3 * errors[0]          # halving the perturbation quarters the error: second order
    assert np.abs(linear.derivatives(linear.x0, linear.pitch0)).max() < 1e-9   # hover is its equilibrium


def test_a_simulated_step_equals_the_exact_zoh_discretisation():
    config = copy.deepcopy(load_vehicle_config("baseline"))
    config["thrusters"]["actuator_time_constant"] = 0.0     # a pure zero-order hold on the blade pitch
    sim = Simulation.from_config(config, {"sensors": "ideal"}, dynamics="linearised",
                                 pitch=LinearisedVehicleModel(config).pitch0)
    model = sim.model
    dynamic = [3, 4, 6, 7, 8, 9, 10, 11]
    phi, delta, *_ = scipy.signal.cont2discrete((model.a[np.ix_(dynamic, dynamic)], model.b[dynamic],
                                                 np.eye(8), np.zeros((8, 4))), 0.2, method="zoh")
    step = np.radians([5.0, -3.0, 4.0, -6.0])
    x = np.zeros(8)
    for _ in range(50):
        sim.advance(model.pitch0 + step)
        x = phi @ x + delta @ step
    np.testing.assert_allclose(sim.state[dynamic] - model.x0[dynamic], x, atol=1e-6)


def test_fouling_linearises_again_about_the_new_trim(models):
    _, linear = models
    fouled = LinearisedVehicleModel(load_vehicle_config("baseline"))
    b_before = fouled.b.copy()
    fouled.thrusters.set_efficiency([0.5, 1.0, 1.0, 1.0])
    fouled.derivatives(fouled.x0, fouled.pitch0)            # notices the change
    reference = VehicleModel(load_vehicle_config("baseline"))
    reference.thrusters.set_efficiency([0.5, 1.0, 1.0, 1.0])
    np.testing.assert_allclose(fouled.pitch0, trim(reference, 0.0, enforce_limits=False).blade_pitch, atol=1e-9)
    assert not np.allclose(fouled.b, b_before)
    assert np.abs(fouled.derivatives(fouled.x0, fouled.pitch0)).max() < 1e-9


def test_the_simulator_flies_either_model_and_refuses_others():
    assert type(SimulatorCore(SimulatorConfig(dynamics="linearised")).simulation.model) is LinearisedVehicleModel
    assert type(SimulatorCore(SimulatorConfig()).simulation.model) is VehicleModel
    with pytest.raises(ValueError, match="dynamics must be one of nonlinear, linearised"):
        SimulatorCore(SimulatorConfig(dynamics="quadratic"))
    with pytest.raises(ValueError, match="dynamics"):
        vehicle_model(load_vehicle_config("baseline"), "")
