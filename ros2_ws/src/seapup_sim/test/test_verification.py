"""The calibrated model against the thesis (Table 3.2 tests and linear analyses).

The targets and tolerances are the thesis's numbers (seapup_sim.verification.
TARGETS, from issue #3); this test fails whenever a primary target is missed.
"""
import math
import re
from pathlib import Path

import numpy as np
import pytest

from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config
from seapup_sim.verification import CAMERA_NMP_DEVIATION, UMBILICAL_FZ_DEVIATION, check_targets, summary, verify

ROOT = Path(__file__).resolve().parents[4]   # ros2_ws/src/seapup_sim/test -> the repository


@pytest.fixture(scope="module")
def baseline_results():
    return verify(VehicleModel(load_vehicle_config("baseline")))


def test_every_primary_target_passes(baseline_results):
    res, _ = baseline_results
    rows = check_targets(res, "baseline")
    failed = [(r["label"], r["value"], r["thesis"]) for r in rows if r["primary"] and not r["pass"]]
    assert failed == [] and summary(rows)["ok"]


def test_the_umbilical_f_z_rows_are_documented_deviations(baseline_results):
    """Issue 11 decided: the exact cable solution stays; sec. 3.8's F_z is shown as DEV with its reason,
    and only the F_z rows are deviations (top speeds and F_x stay primary)."""
    res, _ = baseline_results
    rows = check_targets(res, "baseline")
    dev = [r for r in rows if r["deviation"]]
    assert {r["label"] for r in dev} == {f"umbilical {d} m: F_z [N]" for d in (50, 100, 200)}
    assert all(r["status"] == "DEV" and not r["primary"] and r["deviation"] == UMBILICAL_FZ_DEVIATION for r in dev)
    assert all(r["value"] < 0 for r in dev)  # still measured and reported: the cable pulls up
    assert summary(rows)["deviations"] == 3
    assert all(r["primary"] for r in rows if r["key"].startswith("umbilical.") and not r["key"].endswith("Fz"))


@pytest.mark.parametrize("deviation", [UMBILICAL_FZ_DEVIATION, CAMERA_NMP_DEVIATION])
def test_each_deviation_points_at_its_entry_in_the_deviation_register(deviation):
    """The one-line reason names the page and anchor that explain it (docs/decisions.md#...)."""
    match = re.search(r"(docs/[\w/.-]+\.md)#([\w-]+)", deviation)
    assert match, f"no docs/<page>.md#<anchor> in {deviation!r}"
    page = ROOT / match.group(1)
    assert page.is_file(), f"{match.group(1)} does not exist"
    assert f'id="{match.group(2)}"' in page.read_text(), f"{match.group(1)} has no anchor {match.group(2)!r}"


def test_umbilical_speed_and_drag_force_match_the_table(baseline_results):
    res, _ = baseline_results
    for depth, u, fx in (("50", 0.474, -148.0), ("100", 0.354, -163.0), ("200", 0.259, -172.0)):
        assert res["umbilical"][depth]["max_u"] == pytest.approx(u, rel=0.10)
        assert res["umbilical"][depth]["Fx"] == pytest.approx(fx, rel=0.15)
    # deeper means more cable, more drag, lower speed (the thesis's trend)
    speeds = [res["umbilical"][d]["max_u"] for d in ("50", "100", "200")]
    assert speeds[0] > speeds[1] > speeds[2]


def test_current_section(baseline_results):
    res, _ = baseline_results
    rows = [r for r in check_targets(res, "baseline") if r["key"].startswith("current.")]
    assert len(rows) == 7 and all(r["pass"] for r in rows), rows


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
    rows = {r["label"]: r for r in check_targets(res, "camera")}
    assert rows["rest trim [deg]"]["pass"], rows["rest trim [deg]"]
    assert math.isclose(res["rest_trim_deg"], -6.3, abs_tol=1.0)


def test_only_a_failing_primary_decides_the_outcome(baseline_results):
    res, _ = baseline_results
    rows = check_targets(res, "baseline")
    worse = {**res, "umbilical": {**res["umbilical"], "50": {**res["umbilical"]["50"], "Fz": 0.0}}}
    assert summary(check_targets(worse, "baseline"))["ok"]          # a deviation further off: still ok
    worse = {**res, "surge": {**res["surge"], "max_u": 0.5}}
    bad = check_targets(worse, "baseline")
    assert not summary(bad)["ok"] and summary(bad)["primary_passed"] == summary(rows)["primary_passed"] - 1
    assert [r["status"] for r in bad if r["key"] == "surge.max_u"] == ["FAIL"]


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
