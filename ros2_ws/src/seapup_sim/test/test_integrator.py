"""Tests of seapup_sim.integrator: RK4 order, exact actuator lag, divergence guard."""
import copy
import math

import numpy as np
import pytest

from seapup_sim.integrator import DivergenceError, VehicleIntegrator, rk4_step
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config


def test_rk4_is_fourth_order_on_a_known_ode():
    # x' = t x, exact x(t) = exp(t^2 / 2) for x(0) = 1 (non-autonomous: the
    # stage times matter)
    exact = math.exp(0.5)
    errors = []
    for n in (8, 16, 32, 64):
        x, dt = np.array([1.0]), 1.0 / n
        for k in range(n):
            x = rk4_step(lambda t, y: t * y, k * dt, x, dt)
        errors.append(abs(x[0] - exact))
    orders = [math.log2(errors[i] / errors[i + 1]) for i in range(3)]
    assert orders[-1] == pytest.approx(4.0, abs=0.15), orders


def model():
    return VehicleModel(load_vehicle_config("baseline"))


def test_actuator_lag_is_the_exact_first_order_response():
    m = model()
    tau = m.actuator_time_constant
    assert tau > 0
    sim = VehicleIntegrator(m, dt=0.1, pitch=np.zeros(4))
    cmd = np.radians([10.0, -5.0, 20.0, 0.0])
    sim.step(cmd)
    np.testing.assert_allclose(sim.pitch, cmd * (1 - math.exp(-0.1 / tau)), rtol=1e-12)
    for _ in range(9):
        sim.step(cmd)
    np.testing.assert_allclose(sim.pitch, cmd * (1 - math.exp(-1.0 / tau)), rtol=1e-9)


def test_commands_are_saturated_and_invalid_ones_refused():
    m = model()
    sim = VehicleIntegrator(m, dt=0.1)
    sim.step([2.0, -2.0, 0.0, 0.0])
    lim = math.radians(35.0)
    assert np.all(np.abs(sim.pitch) <= lim + 1e-12)
    before = sim.state.copy(), sim.t
    with pytest.raises(ValueError):
        sim.step([math.nan, 0, 0, 0])
    np.testing.assert_array_equal(sim.state, before[0])
    assert sim.t == before[1]


def test_divergence_names_the_state_and_time_and_keeps_the_old_state():
    cfg = copy.deepcopy(load_vehicle_config("baseline"))
    cfg["hydrodynamics"]["M_q"] = 400.0   # a strong negative damper: pitch blows up
    m = VehicleModel(cfg)
    x0 = np.zeros(12)
    x0[10] = 0.05
    sim = VehicleIntegrator(m, dt=0.1, state=x0)
    sim.thrusters_on = False
    with pytest.raises(DivergenceError, match=r"state (theta|q) = .* at t = \d+\.\d+ s"):
        for _ in range(2000):
            last_good = sim.state.copy()
            sim.step(np.zeros(4))
    np.testing.assert_array_equal(sim.state, last_good)


def test_bad_step_size_is_refused():
    with pytest.raises(ValueError, match="integration step"):
        VehicleIntegrator(model(), dt=0.0)


def test_step_halving_converges_on_the_surge_test():
    """The thesis found 0.1 s and 0.05 s nearly identical (sec. 3.2)."""
    m = model()
    cmd = np.radians([35.0, 35.0, 0.0, 0.0])
    finals = []
    for dt in (0.1, 0.05, 0.025):
        sim = VehicleIntegrator(m, dt=dt, pitch=cmd)
        for _ in range(int(round(10.0 / dt))):
            sim.step(cmd)
        finals.append(sim.state.copy())
    assert np.abs(finals[0] - finals[2]).max() < 1e-3
    assert np.abs(finals[1] - finals[2]).max() < np.abs(finals[0] - finals[2]).max()


def test_configuration_switch_mid_run_keeps_the_state_and_changes_the_dynamics():
    """Sec. 7.4.4 adds the camera at t = 65 s in flight: the state carries over."""
    cmd = np.radians([35.0, 35.0, 0.0, 0.0])
    base = VehicleIntegrator(model(), dt=0.1, pitch=cmd)
    switched = VehicleIntegrator(model(), dt=0.1, pitch=cmd)
    for _ in range(50):
        base.step(cmd)
        switched.step(cmd)
    np.testing.assert_array_equal(base.state, switched.state)
    before = switched.state.copy()
    switched.model.configure(load_vehicle_config("camera"))
    np.testing.assert_array_equal(switched.state, before)  # nothing jumps
    for _ in range(100):
        base.step(cmd)
        switched.step(cmd)
    # the bow-heavy camera trims the vehicle further bow-down (sec. 3.6: 20.8 vs 27.4 deg)
    assert switched.state[4] < base.state[4] - np.radians(3.0)
