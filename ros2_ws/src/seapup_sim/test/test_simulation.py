"""Tests of seapup_sim.simulation: the sampled-data loop of fig. 5.1."""
import math

import numpy as np
import pytest

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_common.contract import Command, HoldCommand, Measurement, Reference
from seapup_sim.analysis import hover_blade_pitch
from seapup_sim.current import CurrentParams
from seapup_sim.environment_config import load_environment
from seapup_sim.simulation import Event, Simulation
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config
from seapup_sim.verification import run_open_loop

HOVER = hover_blade_pitch(VehicleModel(load_vehicle_config("baseline")))
SURGE = np.array([BLADE_PITCH_LIMIT, BLADE_PITCH_LIMIT, 0.0, 0.0])


def hold(pitch, period=0.2):
    return HoldCommand(pitch, period)


class Recorder:
    """A controller that remembers what it was given and switches from SURGE to HOVER at 1 s."""

    def __init__(self, sample_period):
        self.sample_period = sample_period
        self.calls, self.resets = [], []

    def reset(self, applied):
        self.resets.append(applied)

    def applied(self, t, command):
        pass

    def update(self, t, measurement, reference):
        self.calls.append((t, measurement, reference))
        return Command(SURGE if t < 1.0 else HOVER, t)

    def diagnostics(self):
        return {"calls": len(self.calls)}


def test_open_loop_through_the_loop_equals_the_plain_integration():
    sim = Simulation.from_config("baseline", {"sensors": "ideal"}, pitch=SURGE)
    log = sim.run(hold(SURGE), 10.0)
    _, x, _ = run_open_loop(sim.plant.model, SURGE, 10.0, pitch0=SURGE)
    np.testing.assert_allclose(log.state, x[::2], atol=1e-12)
    assert log.t[-1] == pytest.approx(10.0) and len(log.t) == 51


def test_controller_gets_measurements_and_references_never_truth():
    ctl = Recorder(0.5)
    sim = Simulation.from_config("baseline", {"sensors": "ideal"}, control_period=0.5, pitch=HOVER)
    log = sim.run(ctl, 2.0, reference=lambda t: Reference([0.1 * t, 0.0, 0.0, 0.0]))
    assert [c[0] for c in ctl.calls] == pytest.approx([0.0, 0.5, 1.0, 1.5])
    # bumpless start: reset once, with the applied blade pitch
    assert len(ctl.resets) == 1
    np.testing.assert_array_equal(ctl.resets[0].blade_pitch, HOVER)
    for t, meas, ref in ctl.calls:
        assert isinstance(meas, Measurement) and not hasattr(meas, "state")
        np.testing.assert_array_equal(ref.velocity, [0.1 * t, 0, 0, 0])
    # ideal sensors: the measurement equals the logged truth at each instant
    for k, (t, meas, _) in enumerate(ctl.calls):
        np.testing.assert_array_equal(meas.velocity.value, log.state[k, 6:9])
    np.testing.assert_allclose(log.command[:2], [SURGE, SURGE])
    np.testing.assert_allclose(log.command[2:4], [HOVER, HOVER])
    np.testing.assert_allclose(log.reference[:4, 0], [0.0, 0.05, 0.1, 0.15])
    assert np.all(np.isnan(log.reference[-1]))


def test_log_keeps_every_measurement_with_invalid_readings_as_nan():
    sim = Simulation.from_config("baseline", {"sensors": "baseline"}, seed=2, pitch=HOVER)
    log = sim.run(hold(HOVER), 10.0)
    fixes = ~np.isnan(log.measured["position"][:, 0])
    # acoustic fixes at <= 1 Hz, some lost: between 1 and 11 of the 51 instants
    assert 1 <= fixes.sum() <= 11 and np.all(~np.isnan(log.measured["velocity"]))
    assert np.all(np.abs(log.measured["depth"] - log.state[:, 2]) < 0.5)
    assert log.measured["altitude"].shape == (51,)


def test_run_refuses_what_is_not_a_controller():
    sim = Simulation.from_config("baseline", {"sensors": "ideal"})
    with pytest.raises(TypeError, match="not a VelocityController"):
        sim.run(lambda s: SURGE, 1.0)
    with pytest.raises(ValueError, match="samples every 0.5 s"):
        sim.run(hold(SURGE, 0.5), 1.0)
    with pytest.raises(ValueError, match="whole number"):
        Simulation.from_config("baseline", control_period=0.25)


def test_same_seed_same_history_other_seed_differs():
    env = {"current": {"enabled": True}, "sensors": "baseline"}
    a = Simulation.from_config("baseline", env, seed=4, pitch=HOVER).run(hold(HOVER), 20.0)
    b = Simulation.from_config("baseline", env, seed=4, pitch=HOVER).run(hold(HOVER), 20.0)
    c = Simulation.from_config("baseline", env, seed=5, pitch=HOVER).run(hold(HOVER), 20.0)
    np.testing.assert_array_equal(a.state, b.state)
    np.testing.assert_array_equal(a.measured["velocity"], b.measured["velocity"])
    assert not np.array_equal(a.state, c.state)


def test_current_realisation_does_not_depend_on_the_sensors():
    """One random stream per component: the sensor profile leaves the current alone."""
    runs = {}
    for profile in ("ideal", "baseline", "haslar"):
        env = {"current": {"enabled": True}, "sensors": profile}
        runs[profile] = Simulation.from_config("baseline", env, seed=11, pitch=HOVER).run(hold(HOVER), 30.0)
    np.testing.assert_array_equal(runs["ideal"].current_ned, runs["baseline"].current_ned)
    np.testing.assert_array_equal(runs["ideal"].current_ned, runs["haslar"].current_ned)
    np.testing.assert_array_equal(runs["ideal"].state, runs["haslar"].state)  # the plant never sees noise
    assert np.ptp(runs["ideal"].current_ned[:, 0]) > 0.01  # and the current is really random


def test_sensor_noise_does_not_depend_on_the_current():
    logs = [Simulation.from_config("baseline", {"current": {"enabled": on}, "sensors": "baseline"},
                                   seed=3, pitch=HOVER).run(hold(HOVER), 5.0) for on in (False, True)]
    noise = [log.measured["rates"] - log.state[:, 9:12] for log in logs]
    np.testing.assert_allclose(noise[0], noise[1], atol=1e-15)


def test_a_hovering_vehicle_drifts_with_a_steady_current():
    env = {"current": {"enabled": True, "mean_speed": 0.2, "speed_std": 0.0, "direction_std": 0.0,
                       "mean_direction": math.pi / 2}, "sensors": "ideal"}
    log = Simulation.from_config("baseline", env, pitch=HOVER).run(hold(HOVER), 120.0)
    # drift velocity over ground approaches the current (relative velocity -> 0)
    v_ned = np.diff(log.state[-20:, :2], axis=0).mean(axis=0) / 0.2
    np.testing.assert_allclose(v_ned, [0.0, 0.2], atol=0.01)
    np.testing.assert_allclose(log.current_ned[-1], [0.0, 0.2, 0.0], atol=1e-12)


def test_events_switch_configuration_fouling_and_current():
    events = [Event(2.0, "thruster_efficiency", [0.5, 1.0, 1.0, 1.0]),
              Event(4.0, "configuration", "camera"),
              Event(6.0, "current", CurrentParams(0.3, 0.0, 0.0, 0.0, 10.0))]
    sim = Simulation.from_config("baseline", {"sensors": "ideal"}, events=events, pitch=SURGE)
    log = sim.run(hold(SURGE), 8.0)
    model = sim.plant.model
    assert model.config_name == "camera" and list(model.thrusters.efficiency) == [0.5, 1, 1, 1]
    assert np.all(log.current_ned[log.t <= 6.0 + 1e-9] == 0.0)
    assert log.current_ned[-1][0] > 0.0
    # fouled port main: the vehicle starts turning to port (negative yaw rate)
    assert log.state[np.isclose(log.t, 4.0)][0][11] < -0.05
    with pytest.raises(ValueError):
        Event(1.0, "teleport", None)


def test_an_event_scheduled_while_running_equals_one_given_at_construction():
    current = CurrentParams(0.3, 0.0, 0.0, 0.0, 10.0)
    given = Simulation.from_config("baseline", {"sensors": "ideal"}, events=[Event(3.0, "current", current)],
                                   pitch=SURGE)
    later = Simulation.from_config("baseline", {"sensors": "ideal"}, pitch=SURGE)
    a = given.run(hold(SURGE), 1.0)
    b = later.run(hold(SURGE), 1.0)
    later.schedule(Event(3.0, "current", current))  # scheduled at t = 1 s for t = 3 s
    a, b = given.run(hold(SURGE), 5.0), later.run(hold(SURGE), 5.0)
    np.testing.assert_array_equal(a.state, b.state)
    assert np.all(b.current_ned[b.t < 3.0 - 1e-9] == 0.0) and b.current_ned[-1][0] > 0.0


def test_umbilical_slows_the_vehicle_and_pulls_back():
    x0 = np.zeros(12)
    x0[2] = 50.0
    free = Simulation.from_config("baseline", {"sensors": "ideal"}, state=x0, pitch=SURGE).run(hold(SURGE), 20.0)
    tied = Simulation.from_config("baseline", {"sensors": "ideal", "umbilical": {"enabled": True}},
                                  state=x0, pitch=SURGE).run(hold(SURGE), 20.0)
    assert tied.state[:, 6].max() < 0.7 * free.state[:, 6].max()
    assert tied.umbilical_body[-1][0] < -50.0


def test_environment_defaults_load():
    env = load_environment()
    assert env.umbilical.params.drag_coefficient == pytest.approx(3.0)
    assert env.current.params.break_time == 10.0 and env.sensors.name == "baseline"


def test_references_may_be_constant_arrays_references_or_functions():
    for reference in ([0.2, 0.0, 0.0, 0.1], Reference([0.2, 0.0, 0.0, 0.1]),
                      lambda t: [0.2, 0.0, 0.0, 0.1], lambda t: Reference([0.2, 0.0, 0.0, 0.1])):
        ctl = Recorder(0.5)
        Simulation.from_config("baseline", {"sensors": "ideal"}, control_period=0.5, pitch=HOVER).run(
            ctl, 1.0, reference=reference)
        assert [list(ref.velocity) for _, _, ref in ctl.calls] == [[0.2, 0.0, 0.0, 0.1]] * 2


def test_a_misspelled_environment_key_is_refused_not_ignored(tmp_path):
    """``current: {enabeld: true}`` once ran no current without a word: now the key is named."""
    import pytest
    from seapup_common.config import ConfigError
    from seapup_sim.environment_config import load_environment
    with pytest.raises(ConfigError, match=r"unknown key current.enabeld \(did you mean current.enabled\?\)"):
        load_environment({"current": {"enabeld": True}})
    path = tmp_path / "sea.yaml"
    path.write_text("curent:\n  enabled: true\n")
    with pytest.raises(ConfigError, match=r"sea.yaml over environment/default.yaml: unknown key curent \(did you mean current\?\)"):
        load_environment(path)
