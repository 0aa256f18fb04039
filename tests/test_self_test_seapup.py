"""The self-test flown on the Seapup model (pure cores in lockstep, no ROS; the driver is
seapup_runs.self_test_flight, which performs the artificial resets at the trim): sec. 5.3.

Independent truths: the model's own hover trim (eq. 5.2) and trim at 0.7 m/s
(the settings the controller must find), and the noise-free 8 deg step
responses from rest at hover ("chosen by a human observer", sec. 5.3.1).
"""
import numpy as np
import pytest

from seapup_runs.self_test_flight import fly_self_test
from seapup_common.contract import Reference
from seapup_control.self_test import Phase, SelfTest, SelfTestConfig
from seapup_sim.analysis import hover_blade_pitch, trim
from seapup_sim.simulation import Simulation
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config

MODEL = VehicleModel(load_vehicle_config("baseline"))
HOVER = hover_blade_pitch(MODEL)
START = np.r_[0.0, 0.0, 50.0, np.zeros(9)]


def simulation(state=START, pitch=np.zeros(4)):
    return Simulation.from_config("baseline", {"sensors": "ideal"}, state=state, pitch=pitch)


def run_self_test(overrides):
    run = fly_self_test("baseline", overrides)
    return run.test, run.space


@pytest.fixture(scope="module")
def velocity_log():
    """B0^-1 (response at T_s) and B1^-1 (after 10 s) of 8 deg steps from rest at hover, per rad."""
    step = np.radians(8.0)
    first, final = np.zeros((4, 4)), np.zeros((4, 4))
    for j in range(4):
        sim = simulation(pitch=HOVER)
        command = HOVER.copy()
        command[j] += step
        outputs = []
        for _ in range(51):
            outputs.append(sim.sample().measurement.body_velocity())
            sim.advance(command)
        first[:, j], final[:, j] = outputs[1] / step, outputs[-1] / step
    return first, final


DOMINANT = [(0, 0), (0, 1), (1, 2), (1, 3), (2, 2), (2, 3), (3, 0), (3, 1)]  # u-mains, v/w-vectored, r-mains


@pytest.mark.parametrize("mode", ["realistic", "artificial"])
def test_self_test_at_zero_speed_recovers_the_noise_free_steps(mode, velocity_log):
    test, box = run_self_test({"mode": mode})
    assert test.phase == Phase.DONE, test.reason
    (point,) = test.points
    first, final = velocity_log
    for i, j in DOMINANT:
        assert point.model.B1inv[i, j] == pytest.approx(final[i, j], rel=0.1), (i, j)
        # B0^-1 is a first-order fit of the whole response, not the first sample (eq. 4.24a):
        # the thrust lag makes the real onset slower than the fitted lag's
        assert point.model.B0inv[i, j] == pytest.approx(first[i, j], rel=0.5), (i, j)
    # the setting the controller holds the vehicle still with is the model's hover trim (eq. 5.2)
    np.testing.assert_allclose(point.model.u0, HOVER, atol=np.radians(0.2))
    if mode == "realistic":  # sec. 5.3.3: 119.2 s and 9.4 x 5.2 x 5.7 m for the thesis's model
        assert 60.0 < test.duration < 240.0
        assert np.all(box < 20.0)


def test_under_the_baseline_log_noise_the_dominant_channels_stay_within_20_percent(velocity_log):
    """sec. 6.5.1's instrument fit (log 0.02 kt, gyro 0.005 deg/s, 3 sigma): the self-test still finishes
    in about the noise-free time and its steady-state gains agree with the noise-free steps."""
    run = fly_self_test("baseline", {}, environment={"sensors": "baseline"}, seed=1)
    assert run.test.phase == Phase.DONE, run.test.reason
    (point,) = run.test.points
    _, final = velocity_log
    for i, j in DOMINANT:
        assert point.model.B1inv[i, j] == pytest.approx(final[i, j], rel=0.2), (i, j)
    np.testing.assert_allclose(point.model.u0, HOVER, atol=np.radians(0.5))
    assert 60.0 < run.test.duration < 240.0


def test_a_second_operating_point_at_0_7_m_s(velocity_log):
    test, box = run_self_test({"operating_points": [0.0, 0.7]})
    assert test.phase == Phase.DONE, test.reason
    fast = test.points[1]
    held = trim(MODEL, 0.7)
    np.testing.assert_allclose(fast.model.u0, held.blade_pitch, atol=np.radians(0.3))  # eq. 5.6's offset u0(0.7)
    np.testing.assert_allclose(fast.model.y0, [0.7, 0, 0, 0])
    # faster: the surge steady-state gain falls (drag grows with speed; Table 5.2's 0.0151 < 0.0246)
    assert fast.model.B1inv[0, 0] < 0.6 * test.points[0].model.B1inv[0, 0]
    assert test.duration > 150.0 and len(test.tests) == 12


def test_the_self_tested_controller_flies_a_surge_step():
    """The scheduled controller it leaves behind tracks 0.5 m/s with no steady-state error."""
    test, _ = run_self_test({})
    controller = test.controller
    sim = simulation(pitch=HOVER)
    log = sim.run(controller, 40.0, reference=Reference([0.5, 0.0, 0.0, 0.0]))
    u = log.state[:, 6]
    assert abs(u[-1] - 0.5) < 0.01 and np.abs(log.state[-25:, 7]).max() < 0.02


def with_efficiency(efficiency):
    config = load_vehicle_config("baseline")
    config["thruster_efficiency"] = list(efficiency)
    return config


@pytest.mark.parametrize("mode", ["realistic", "artificial"])
@pytest.mark.parametrize("dead", [0, 3])
def test_a_dead_thruster_fails_the_self_test_naming_it(mode, dead):
    """|B0| != 0 (eq. 4.9): with one thruster dead the design is refused and the vehicle is left at the
    zero level, not flown by a controller that would put its largest gains on the dead thruster."""
    efficiency = np.ones(4)
    efficiency[dead] = 0.0
    run = fly_self_test(with_efficiency(efficiency), {"mode": mode})
    test = run.test
    assert test.phase == Phase.FAILED, test.reason
    if mode == "artificial" and dead >= 2:  # no vectored thruster setting holds the trim
        assert "cannot be reset" in test.reason
    else:
        assert "singular" in test.reason and f"thruster {dead}" in test.reason, test.reason
    assert test.controller is None


def test_a_half_fouled_thruster_still_gets_a_controller():
    """Fouling (sec. 7.4.4) weakens a column but leaves B0 invertible: the test passes and the
    fouled thruster's surge gain is about half the healthy one's."""
    run = fly_self_test("fouled_main_port", {})
    assert run.test.phase == Phase.DONE, run.test.reason
    b1inv = run.test.points[0].model.B1inv
    assert 0.35 < b1inv[0, 0] / b1inv[0, 1] < 0.7
