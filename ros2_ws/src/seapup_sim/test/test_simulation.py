"""Tests of seapup_sim.simulation: the sampled-data loop of fig. 5.1."""
import math

import numpy as np
import pytest

from seapup_sim.current import CurrentParams
from seapup_sim.simulation import Event, Simulation, load_environment
from seapup_sim.verification import run_open_loop

HOVER = np.radians([-3.383, -3.383, -13.098, -13.098])
SURGE = np.radians([35.0, 35.0, 0.0, 0.0])


def test_open_loop_through_the_loop_equals_the_plain_integration():
    sim = Simulation.from_config("baseline", {"sensors": "ideal"}, pitch=SURGE)
    log = sim.run(lambda s: SURGE, 10.0)
    _, x, _ = run_open_loop(sim.plant.model, SURGE, 10.0, pitch0=SURGE)
    np.testing.assert_allclose(log.state, x[::2], atol=1e-12)
    assert log.t[-1] == pytest.approx(10.0) and len(log.t) == 51


def test_command_is_held_between_samples_and_seen_at_t_k():
    seen = []

    def controller(sample):
        seen.append(sample.t)
        return SURGE if sample.t < 1.0 else HOVER

    sim = Simulation.from_config("baseline", {"sensors": "ideal"}, control_period=0.5, pitch=HOVER)
    log = sim.run(controller, 2.0)
    np.testing.assert_allclose(seen, [0.0, 0.5, 1.0, 1.5])
    np.testing.assert_allclose(log.command[:2], [SURGE, SURGE])
    np.testing.assert_allclose(log.command[2:4], [HOVER, HOVER])
    with pytest.raises(ValueError, match="whole number"):
        Simulation.from_config("baseline", control_period=0.25)


def test_same_seed_same_history_other_seed_differs():
    env = {"current": {"enabled": True}, "sensors": "baseline"}
    a = Simulation.from_config("baseline", env, seed=4, pitch=HOVER).run(lambda s: HOVER, 20.0)
    b = Simulation.from_config("baseline", env, seed=4, pitch=HOVER).run(lambda s: HOVER, 20.0)
    c = Simulation.from_config("baseline", env, seed=5, pitch=HOVER).run(lambda s: HOVER, 20.0)
    np.testing.assert_array_equal(a.state, b.state)
    np.testing.assert_array_equal(a.measured_velocity, b.measured_velocity)
    assert not np.array_equal(a.state, c.state)


def test_a_hovering_vehicle_drifts_with_a_steady_current():
    env = {"current": {"enabled": True, "mean_speed": 0.2, "speed_std": 0.0, "direction_std": 0.0,
                       "mean_direction": math.pi / 2}, "sensors": "ideal"}
    log = Simulation.from_config("baseline", env, pitch=HOVER).run(lambda s: HOVER, 120.0)
    # drift velocity over ground approaches the current (relative velocity -> 0)
    v_ned = np.diff(log.state[-20:, :2], axis=0).mean(axis=0) / 0.2
    np.testing.assert_allclose(v_ned, [0.0, 0.2], atol=0.01)
    np.testing.assert_allclose(log.current_ned[-1], [0.0, 0.2, 0.0], atol=1e-12)


def test_events_switch_configuration_fouling_and_current():
    events = [Event(2.0, "thruster_efficiency", [0.5, 1.0, 1.0, 1.0]),
              Event(4.0, "configuration", "camera"),
              Event(6.0, "current", CurrentParams(0.3, 0.0, 0.0, 0.0, 10.0))]
    sim = Simulation.from_config("baseline", {"sensors": "ideal"}, events=events, pitch=SURGE)
    log = sim.run(lambda s: SURGE, 8.0)
    model = sim.plant.model
    assert model.config_name == "camera" and list(model.thrusters.efficiency) == [0.5, 1, 1, 1]
    assert np.all(log.current_ned[log.t <= 6.0 + 1e-9] == 0.0)
    assert log.current_ned[-1][0] > 0.0
    # fouled port main: the vehicle starts turning to port (negative yaw rate)
    assert log.state[np.isclose(log.t, 4.0)][0][11] < -0.05
    with pytest.raises(ValueError):
        Event(1.0, "teleport", None)


def test_umbilical_slows_the_vehicle_and_pulls_back():
    x0 = np.zeros(12)
    x0[2] = 50.0
    free = Simulation.from_config("baseline", {"sensors": "ideal"}, state=x0, pitch=SURGE).run(lambda s: SURGE, 20.0)
    tied = Simulation.from_config("baseline", {"sensors": "ideal", "umbilical": {"enabled": True}},
                                  state=x0, pitch=SURGE).run(lambda s: SURGE, 20.0)
    assert tied.state[:, 6].max() < 0.7 * free.state[:, 6].max()
    assert tied.umbilical_body[-1][0] < -50.0


def test_environment_defaults_load():
    env = load_environment()
    u = env["umbilical"]
    assert u["strumming_factor"] * u["still_water_drag_coefficient"] == pytest.approx(3.0)
    assert env["current"]["break_time"] == 10.0
