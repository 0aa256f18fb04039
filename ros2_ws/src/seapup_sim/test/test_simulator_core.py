"""Tests of seapup_sim.simulator_core: the node's logic without ROS, and what each setter changes."""
import math

import numpy as np
import pytest

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT as LIM
from seapup_common.contract import HoldCommand
from seapup_sim.analysis import hover_blade_pitch, trim
from seapup_sim.current import CurrentParams
from seapup_sim.simulation import Simulation
from seapup_sim.simulator_core import SimulatorCore, SimulatorConfig
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config


def make(sensors="ideal", **kw):
    return SimulatorCore(SimulatorConfig(environment={"sensors": sensors}, **kw))


def fly(sim, command, seconds):
    for _ in range(int(round(seconds / sim.config.control_period))):
        sim.submit(command, sim.t_ns, lockstep=True)
        sim.step()


def test_lockstep_stamps_must_be_t_k():
    sim = make()
    ok, _ = sim.submit([0.1, 0.1, 0.0, 0.0], 0, lockstep=True)
    assert ok
    sim.step()
    assert sim.t_ns == 200_000_000
    assert sim.submit([0.1] * 4, 0, lockstep=True) == (False, pytest.approx(sim.last_error))
    assert sim.submit([0.1] * 4, 400_000_000, lockstep=True)[0] is False
    assert sim.counters["rejected_stale"] == 1 and sim.counters["rejected_future"] == 1
    assert sim.submit([0.1] * 4, 200_000_000, lockstep=True)[0]


def test_bad_commands_never_reach_the_plant():
    sim = make()
    before = sim.simulation.plant.state.copy(), sim.command.copy()
    for bad in ([math.nan, 0, 0, 0], [0, math.inf, 0, 0], [0, 0, 0], [0] * 5):
        assert sim.submit(bad, 0, lockstep=True)[0] is False
    np.testing.assert_array_equal(sim.command, before[1])
    np.testing.assert_array_equal(sim.simulation.plant.state, before[0])
    assert sim.counters["rejected_invalid"] == 4 and sim.counters["accepted"] == 0
    ok, reason = sim.submit([1e300, -1e300, 0, 0], 0, lockstep=True)
    assert ok and reason == "saturated" and sim.counters["saturated"] == 2 and sim.counters["accepted"] == 1
    np.testing.assert_array_equal(sim.command, [LIM, -LIM, 0, 0])


@pytest.mark.parametrize("action", ["hover", "neutral"])
def test_watchdog_returns_to_the_fallback_setting(action):
    sim = make(watchdog_timeout=1.0, watchdog_action=action)
    expected = hover_blade_pitch(VehicleModel(load_vehicle_config("baseline"))) if action == "hover" else np.zeros(4)
    sim.submit([LIM, LIM, 0, 0], 0, lockstep=True)
    for _ in range(5):  # 1.0 s: still the last command
        sim.step()
    assert not sim.watchdog_active
    np.testing.assert_array_equal(sim.command, [LIM, LIM, 0, 0])
    sim.step()  # t = 1.2 s > 1.0 s since the last valid command
    assert sim.watchdog_active and sim.counters["watchdog_trips"] == 1
    np.testing.assert_allclose(sim.command, expected)
    for _ in range(10):
        sim.step()
    assert sim.counters["watchdog_trips"] == 1  # one trip per episode
    assert sim.submit([0.2] * 4, sim.t_ns, lockstep=True)[0] and not sim.watchdog_active


def test_hover_follows_the_active_configuration():
    """The watchdog's hover is the trim of the vehicle flying now, not the baseline's eq. 5.2."""
    sim = make(watchdog_timeout=0.2)
    np.testing.assert_allclose(np.degrees(sim.hover), [-3.383, -3.383, -13.098, -13.098], atol=2e-3)  # eq. 5.2
    sim.set_configuration("camera")
    camera = trim(VehicleModel(load_vehicle_config("camera")), 0.0).blade_pitch
    np.testing.assert_allclose(sim.hover, camera)
    assert np.degrees(camera[2]) == pytest.approx(-17.65, abs=0.05)  # heavier in water: more vectored thrust
    fly(sim, [0.0] * 4, 0.2)
    for _ in range(3):
        sim.step()  # no command: the watchdog takes over with the camera's hover
    assert sim.watchdog_active
    np.testing.assert_allclose(sim.command, camera)
    # and it really hovers: heave rate settles near zero with the camera fitted
    for _ in range(100):
        sim.step()
    assert abs(sim.simulation.state[8]) < 0.01


def test_same_as_the_pure_core_loop():
    """Stepping the SimulatorCore equals Simulation.run with the same controller."""
    cmd = np.radians([20.0, 10.0, -5.0, -15.0])
    sim = make(seed=3)
    fly(sim, cmd, 10.0)
    ref = Simulation.from_config("baseline", {"sensors": "ideal"}, seed=3,
                                 pitch=sim.hover).run(HoldCommand(cmd, 0.2), 10.0)
    np.testing.assert_array_equal(sim.simulation.plant.state, ref.state[-1])


def test_outputs_are_finite_si_and_complete():
    sim = make("baseline")
    sim.submit(np.radians([35, 35, 0, 0]), 0, lockstep=True)
    sim.step()
    out = sim.outputs()
    sim.check_finite(out)
    sample = out["sample"]
    assert sample.t == pytest.approx(0.2) and sample.measurement.t == pytest.approx(0.2)
    # at rest-ish and level the accelerometer feels -g along body z (specific force)
    assert sample.specific_force[2] == pytest.approx(-9.81, abs=0.5)
    bad = dict(out, applied_blade_pitch=np.array([math.nan, 0, 0, 0]))
    with pytest.raises(FloatingPointError, match="blade pitch"):
        sim.check_finite(bad)


def test_thruster_efficiency_scales_the_thrust():
    full, fouled = make(), make()
    fouled.set_thruster_efficiency([0.5, 0.5, 1.0, 1.0])
    for sim in (full, fouled):
        fly(sim, [LIM, LIM, 0.0, 0.0], 4.0)
    u_full, u_fouled = full.simulation.state[6], fouled.simulation.state[6]
    assert 0.3 < u_fouled / u_full < 0.85  # half the surge force: clearly slower (drag ~ u|u|)
    with pytest.raises(ValueError):
        fouled.set_thruster_efficiency([2.0, 1, 1, 1])
    np.testing.assert_array_equal(fouled.simulation.model.thrusters.efficiency, [0.5, 0.5, 1, 1])


def test_efficiency_survives_a_configuration_change():
    sim = make()
    sim.set_thruster_efficiency([0.5, 1.0, 1.0, 1.0])
    sim.set_configuration("camera")
    assert sim.simulation.model.config_name == "camera"
    np.testing.assert_array_equal(sim.simulation.model.thrusters.efficiency, [0.5, 1, 1, 1])
    # the fouled port main turns the vehicle to port under equal commands
    fly(sim, [LIM, LIM, 0.0, 0.0], 3.0)
    assert sim.simulation.state[11] < -0.05


def test_configuration_change_changes_the_dynamics():
    a, b = make(), make()
    b.set_configuration("camera")
    for sim in (a, b):
        fly(sim, [LIM, LIM, 0.0, 0.0], 20.0)
    # the camera's drag and trim change the steady surge (sec. 3.6: steady pitch 20.8 vs 27.4 deg)
    assert math.degrees(b.simulation.state[4]) < math.degrees(a.simulation.state[4]) - 3.0


def test_sensor_profile_changes_the_noise():
    sim = make("ideal")
    fly(sim, sim.hover, 0.2)

    def noise_std():
        errs = []
        for _ in range(200):
            s = sim.simulation.sample()
            errs.append(s.measurement.velocity.value - s.state[6:9])
        return np.std(errs, axis=0)

    np.testing.assert_array_equal(noise_std(), 0.0)
    sim.set_sensor_profile("haslar")
    np.testing.assert_allclose(noise_std(), 0.0172, rtol=0.2)  # sigma_u,v,w at Haslar
    # the readings' variances follow the new profile too (the suite checks each profile's once)
    np.testing.assert_array_equal(sim.simulation.sample().measurement.velocity.variance,
                                  np.square(sim.sensor_profile.velocity_std))
    assert sim.simulation.sample().measurement.velocity.variance[0] > 0
    assert sim.sensor_profile.name == "haslar"
    with pytest.raises(ValueError):
        sim.set_sensor_profile("nope")
    assert sim.sensor_profile.name == "haslar"


def test_current_setter_changes_the_water():
    sim = make()
    sim.set_current(CurrentParams(0.3, 0.0, math.pi / 2, 0.0, 10.0))
    fly(sim, sim.hover, 0.4)
    np.testing.assert_allclose(sim.outputs()["sample"].current_ned, [0.0, 0.3, 0.0], atol=1e-12)
    assert sim.current_params().mean_speed == 0.3
    # a step change of an existing current (sec. 5.4.3): it relaxes to the new mean with T_c = 10 s
    sim.set_current(CurrentParams(0.1, 0.0, math.pi / 2, 0.0, 10.0))
    fly(sim, sim.hover, 10.0)
    expected = 0.1 + 0.2 * math.exp(-10.0 / 10.0)
    assert sim.outputs()["sample"].current_ned[1] == pytest.approx(expected, abs=0.005)
    sim.set_current(None)
    fly(sim, sim.hover, 0.2)
    np.testing.assert_array_equal(sim.outputs()["sample"].current_ned, 0.0)
    assert sim.current_params().mean_speed == pytest.approx(0.26)  # back to the environment's statistics


def test_reset_restarts_time_state_counters_and_noise():
    sim = make("baseline", seed=1)
    fly(sim, [LIM, LIM, 0, 0], 1.0)
    sim.submit([math.nan] * 4, sim.t_ns, lockstep=True)
    first = sim.simulation.sample().measurement.velocity.value
    state = np.zeros(12)
    state[2] = 42.0
    sim.reset(9, state)
    assert sim.t == 0.0 and sim.simulation.plant.state[2] == 42.0 and sim.config.seed == 9
    assert all(v == 0 for v in sim.counters.values())
    np.testing.assert_allclose(sim.command, sim.hover)
    again = make("baseline", seed=9)
    again.reset(9, state)
    np.testing.assert_array_equal(sim.simulation.sample().measurement.velocity.value,
                                  again.simulation.sample().measurement.velocity.value)
    assert not np.array_equal(first, sim.simulation.sample().measurement.velocity.value)


def test_bad_configuration_is_refused():
    for kw in ({"control_period": 0.25}, {"watchdog_action": "panic"}, {"blade_pitch_limit": 1.0},
               {"watchdog_timeout": 0.0}):
        with pytest.raises(ValueError):
            SimulatorCore(SimulatorConfig(**kw))


def test_refused_requests_leave_the_plant_as_it_was():
    sim = make("baseline", seed=4)
    sim.set_current(CurrentParams(0.2, 0.0, 0.0, 0.0, 10.0))
    fly(sim, sim.hover, 1.0)
    before = (sim.t, sim.simulation.state, sim.current_params(), sim.config.seed)
    for bad in (CurrentParams(100.0, 0.0, 0.0, 0.0, 10.0), CurrentParams(0.2, 1e300, 0.0, 0.0, 10.0),
                CurrentParams(0.2, 0.0, 0.0, 1e300, 10.0), CurrentParams(0.2, 0.0, 0.0, 0.0, 1e16)):
        with pytest.raises(ValueError, match="maximum|allowed range"):
            sim.set_current(bad)
    state = np.zeros(12)
    for index, value in ((4, 1.6), (6, 25.0), (0, 2e5), (2, -1e5), (2, -0.5), (11, 19.9)):
        bad_state = state.copy()
        bad_state[index] = value
        with pytest.raises(ValueError, match="outside the allowed range"):
            sim.reset(7, bad_state)
    with pytest.raises(ValueError, match="seed"):
        sim.reset(-1)
    after = (sim.t, sim.simulation.state, sim.current_params(), sim.config.seed)
    assert after[0] == before[0] and after[2] == before[2] and after[3] == before[3]
    np.testing.assert_array_equal(after[1], before[1])
    with pytest.raises(ValueError) as err:
        sim.set_thruster_efficiency(np.float64(7.0) * np.ones(4))
    assert "np.float64" not in str(err.value) and "7, 7, 7, 7" in str(err.value)
