"""The calibrated model against the thesis (Table 3.2 tests and linear analyses).

The measurements themselves (symmetry, the umbilical table's trend, the step gains' signs, the
crossover computed independently). Scoring against the thesis's targets (seapup_runs/data/
thesis_targets.yaml) is tested in seapup_runs/test/test_thesis_targets.py.
"""
import math

import numpy as np
import pytest

from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config
from seapup_sim.verification import verify

@pytest.fixture(scope="module")
def baseline_results():
    return verify(VehicleModel(load_vehicle_config("baseline")))


def test_umbilical_speed_and_drag_force_match_the_table(baseline_results):
    res, _ = baseline_results
    for depth, u, fx in (("50", 0.474, -148.0), ("100", 0.354, -163.0), ("200", 0.259, -172.0)):
        assert res["umbilical"][depth]["max_u"] == pytest.approx(u, rel=0.10)
        assert res["umbilical"][depth]["Fx"] == pytest.approx(fx, rel=0.15)
    # deeper means more cable, more drag, lower speed (the thesis's trend)
    speeds = [res["umbilical"][d]["max_u"] for d in ("50", "100", "200")]
    assert speeds[0] > speeds[1] > speeds[2]


def test_sway_tests_are_exact_mirror_images(baseline_results):
    res, hist = baseline_results
    assert res["sway_mirror_error"] <= 1e-9
    t, a = hist["sway_4a"]
    _, b = hist["sway_4b"]
    assert np.abs(a[:, 7]).max() > 0.3  # it really moved sideways
    np.testing.assert_allclose(a[:, 7], -b[:, 7], atol=1e-9)
    np.testing.assert_allclose(a[:, 3], -b[:, 3], atol=1e-9)


def test_step_gains_have_the_thesis_signs_and_mirror_structure(baseline_results):
    res, _ = baseline_results
    b1 = np.array(res["step_gains_5hz"]["B1inv"])
    # eq. 5.3b signs of the dominant entries (rows u v w r; cols main port,
    # main stbd, vect stbd, vect port)
    assert b1[0, 0] > 0 and b1[0, 1] > 0          # mains drive the vehicle ahead
    assert b1[2, 2] > 0 and b1[2, 3] > 0          # positive vectored pitch: down
    assert b1[1, 2] < 0 < b1[1, 3]                # vectored push-pull: sway
    assert b1[3, 0] > 0 > b1[3, 1]                # port main turns to starboard
    assert b1[2, 0] < 0                           # moving ahead the vehicle rises (sec. 3.1)
    # port/starboard mirror: symmetric outputs equal, asymmetric ones opposite
    np.testing.assert_allclose(b1[[0, 2], 0], b1[[0, 2], 1], atol=1e-12)
    np.testing.assert_allclose(b1[[1, 3], 0], -b1[[1, 3], 1], atol=1e-12)


def test_camera_rest_trim():
    res, _ = verify(VehicleModel(load_vehicle_config("camera")), loci_speeds=[0.0, 0.5])
    assert math.isclose(res["rest_trim_deg"], -6.3, abs_tol=1.0)


def _largest_zero_real_part(model, speed):
    """Transmission zeros (eq. 3.8-3.12) of the outputs u, v, w, r about the trim at ``speed``."""
    from seapup_sim.analysis import linearise, system_zeros, trim
    guess = None
    for s in np.linspace(0.0, speed, 6):
        tr = trim(model, float(s), guess, enforce_limits=False)
        guess = tr.unknowns
    a, b = linearise(model, tr.state, tr.blade_pitch)
    c = np.zeros((4, 12))
    c[[0, 1, 2, 3], [6, 7, 8, 11]] = 1.0
    return max(z.value.real for z in system_zeros(a, b, c) if z.kind == "transmission")


def test_the_baseline_turns_non_minimum_phase_between_0_6_and_0_8_m_s():
    """Sec. 3.7: the baseline crosses at ~0.7-0.75 m/s (issue 11's band 0.6-0.8), computed here from the
    linearisation directly (not from verify's sweep or the calibration script)."""
    model = VehicleModel(load_vehicle_config("baseline"))
    assert _largest_zero_real_part(model, 0.0) < -0.1   # minimum phase at rest
    assert _largest_zero_real_part(model, 0.6) < 0.0
    assert _largest_zero_real_part(model, 0.8) > 0.0


def test_full_yaw_input_turns_at_the_vehicles_measured_rate():
    """App. A.3: full push-pull of the mains from rest, vectored 0: 53.3 deg/s to starboard, 50.0 to port
    (gyro), within 15 %."""
    from seapup_common.blade_pitch import BLADE_PITCH_LIMIT as lim
    from seapup_sim.verification import run_open_loop
    model = VehicleModel(load_vehicle_config("baseline"))
    for command, measured in (([lim, -lim, 0, 0], 53.3), ([-lim, lim, 0, 0], -50.0)):
        _, x, _ = run_open_loop(model, np.array(command), 30.0)
        peak = math.degrees(x[np.argmax(np.abs(x[:, 11])), 11])
        assert peak == pytest.approx(measured, rel=0.15), (command, peak)


def test_the_climb_and_the_high_speed_turn_of_app_a_3(baseline_results):
    """Table A.1 rows 1 and 5 as the thesis orders them in both its trials and its simulation: the climb
    (full surge, full upward heave) pitches further bow-up than the impulsive start (c: 35.4 > 32.5 deg,
    a: 48 > 22) and rises; the full-speed turn on one main turns to starboard, slower than the zero-radius
    push-pull (b: 31.0 < 50.0-53.3, c: 25.9 < 45.0 deg/s), while going ahead."""
    res, _ = baseline_results
    climb, turn = res["climb"], res["fast_turn"]
    assert climb["max_pitch_deg"] > res["surge"]["max_pitch_deg"] and climb["max_rise_w"] > 0.05
    assert 0.0 < turn["max_r_dps"] < res["yaw_starboard"]["max_r_dps"] and turn["max_u"] > 0.1
