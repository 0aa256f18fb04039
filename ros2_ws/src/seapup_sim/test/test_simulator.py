"""Tests of seapup_sim.simulator: the node's logic without ROS."""
import math

import numpy as np
import pytest

from seapup_sim.simulation import Simulation
from seapup_sim.simulator import HOVER_PITCH_DEG, Simulator, SimulatorConfig

LIM = math.radians(35.0)


def make(**kw):
    return Simulator(SimulatorConfig(sensor_profile="ideal", **kw))


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
    before = sim.sim.plant.state.copy(), sim.command.copy()
    for bad in ([math.nan, 0, 0, 0], [0, math.inf, 0, 0], [0, 0, 0], [0] * 5):
        assert sim.submit(bad, 0, lockstep=True)[0] is False
    np.testing.assert_array_equal(sim.command, before[1])
    np.testing.assert_array_equal(sim.sim.plant.state, before[0])
    assert sim.counters["rejected_invalid"] == 4
    ok, reason = sim.submit([1e300, -1e300, 0, 0], 0, lockstep=True)
    assert ok and reason == "saturated" and sim.counters["saturated"] == 2
    np.testing.assert_array_equal(sim.command, [LIM, -LIM, 0, 0])


@pytest.mark.parametrize("action,expected", [("hover", np.radians(HOVER_PITCH_DEG)), ("neutral", np.zeros(4))])
def test_watchdog_returns_to_the_fallback_setting(action, expected):
    sim = make(watchdog_timeout=1.0, watchdog_action=action)
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


def test_same_as_the_pure_core_loop():
    """Stepping the Simulator equals Simulation.run with the same controller."""
    cmd = np.radians([20.0, 10.0, -5.0, -15.0])
    sim = make(seed=3)
    for _ in range(50):
        sim.submit(cmd, sim.t_ns, lockstep=True)
        sim.step()
    ref = Simulation.from_config("baseline", {"sensors": "ideal"}, seed=3,
                                 pitch=np.radians(HOVER_PITCH_DEG)).run(lambda s: cmd, 10.0)
    np.testing.assert_array_equal(sim.sim.plant.state, ref.state[-1])


def test_outputs_are_finite_si_and_complete():
    sim = Simulator(SimulatorConfig(sensor_profile="baseline"))
    sim.submit(np.radians([35, 35, 0, 0]), 0, lockstep=True)
    sim.step()
    out = sim.outputs()
    sim.check_finite(out)
    assert out["t"] == pytest.approx(0.2)
    assert np.linalg.norm(out["quaternion_truth"]) == pytest.approx(1.0)
    # at rest-ish and level the accelerometer feels -g along body z (specific force)
    assert out["specific_force"][2] == pytest.approx(-9.81, abs=0.5)
    with pytest.raises(FloatingPointError, match="depth"):
        sim.check_finite({"depth": math.nan})


def test_runtime_changes_and_reset():
    sim = make()
    sim.set_configuration("camera")
    assert sim.sim.plant.model.config_name == "camera"
    sim.set_thruster_efficiency([0.5, 1, 1, 1])
    with pytest.raises(ValueError):
        sim.set_thruster_efficiency([2.0, 1, 1, 1])
    from seapup_sim.current import CurrentParams
    sim.set_current(CurrentParams(0.3, 0.0, 0.0, 0.0, 10.0))
    assert sim.sim.current is not None
    sim.set_current(None)
    assert sim.sim.current is None
    sim.set_sensor_profile("haslar")
    with pytest.raises(ValueError):
        sim.set_sensor_profile("nope")
    state = np.zeros(12)
    state[2] = 42.0
    sim.step()
    sim.reset(9, state)
    assert sim.t == 0.0 and sim.sim.plant.state[2] == 42.0 and sim.config.seed == 9


def test_bad_configuration_is_refused():
    for kw in ({"control_period": 0.25}, {"watchdog_action": "panic"}, {"blade_pitch_limit": 1.0},
               {"watchdog_timeout": 0.0}):
        with pytest.raises(ValueError):
            Simulator(SimulatorConfig(**kw))
