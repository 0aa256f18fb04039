"""./seapup scenario: the thesis's closed-loop cases flown with the self-tested controller."""
import json
import math
import re

import numpy as np
import pytest

from seapup_bringup.scenarios import run_scenario, scenario_command, scenarios


def test_every_scenario_of_the_issue_is_defined():
    assert {"surge", "sway", "heave", "yaw", "inspection", "turn", "current-step", "station-keep",
            "fast"} <= set(scenarios())


def test_surge_step_is_tracked_and_measured(tmp_path):
    out = tmp_path / "surge.json"
    assert scenario_command(["surge", "--json", str(out), "--plots", str(tmp_path)]) == 0
    result = json.loads(out.read_text())
    u = result["outputs"]["u"]
    assert u["reference"] == 0.85 and abs(u["final"] - 0.85) < 0.01  # integral action
    assert 1.0 < u["rise95_s"] < 10.0 and u["overshoot_pct"] < 10.0  # thesis: ~5 s, 1.7 %
    assert result["outputs"]["v"]["max_interaction"] < 0.05           # decoupled (thesis: very low)
    assert 10.0 < result["pitch_deg"]["peak"] < 35.0                  # bow up (thesis: 26.2 deg peak)
    history = np.array(result["history"]["velocity"])
    assert history.shape == (51, 4) and list((tmp_path).glob("scenario_surge_*.png"))
    # final values are means over the last 1 s (6 samples at 5 Hz), with whether they settled: u has
    # (integral action), the pitch angle still swings there (its ~5.6 s oscillation has not died out)
    assert u["settled"] and u["window_s"] == 1.0 and u["final"] == pytest.approx(np.mean(history[-6:, 0]))
    pitch, angle = result["pitch_deg"], np.array(result["history"]["roll_pitch_deg"])[-6:, 1]
    assert not pitch["settled"] and pitch["window_s"] == 1.0 and pitch["final"] == pytest.approx(np.mean(angle))
    assert pitch["range"] == pytest.approx([angle.min(), angle.max()]) and pitch["range"][1] - pitch["range"][0] > 2.0


def test_the_text_says_when_a_final_value_has_not_settled(capsys):
    assert scenario_command(["surge"]) == 0
    text = capsys.readouterr().out
    assert "final = mean over the last 1 s" in text
    assert re.search(r"pitch peak .* \(not settled: \d+\.\d to \d+\.\d deg over the last 1 s\)", text), text
    assert "not settled over the last" not in text  # u, v, w and r have settled


def test_current_step_and_station_keeping_reject_the_current():
    step = run_scenario("current-step")
    assert step["u_peak_after_current"] > 0.2 + 0.01          # the current pushes surge up (thesis 0.2574)
    assert step["recovery_5pct_s"] < 10.0                     # and it is brought back (thesis 5.8 s)
    assert step["outputs"]["u"]["overshoot_pct"] < 10.0       # measured before the current, not because of it
    keep = run_scenario("station-keep")
    sk = keep["station_keep"]
    assert sk["max_abs_x"] < 1.0 and sk["max_abs_y"] < 0.3 and sk["max_abs_z"] < 0.3  # thesis 0.60, 0.06, 0.06 m
    assert sk["max_abs_yaw_deg"] < 10.0 and math.isfinite(keep["outputs"]["u"]["final"])


def test_at_20_hz_the_loops_are_no_slower_and_still_hold_station():
    """Sec. 5.4.5: the same continuous poles at 20 Hz (eq. 5.1) — surge no slower than at 5 Hz
    (thesis: faster, 0.35 % overshoot), station keeping of the same order."""
    fast, slow = run_scenario("surge", rate=20.0), run_scenario("surge", rate=5.0)
    u = fast["outputs"]["u"]
    assert fast["rate_hz"] == 20.0 and abs(u["final"] - 0.85) < 0.01 and u["overshoot_pct"] < 5.0
    assert u["rise95_s"] <= 1.05 * slow["outputs"]["u"]["rise95_s"]
    assert run_scenario("yaw", rate=20.0)["outputs"]["r"]["rise95_s"] < 2.6  # thesis 95 % within 2.6 s at 5 Hz
    sk = run_scenario("station-keep", rate=20.0)["station_keep"]
    assert sk["max_abs_x"] < 0.6 and sk["max_abs_y"] < 0.3 and sk["max_abs_z"] < 0.1 and sk["max_abs_yaw_deg"] < 5.0


def test_the_camera_vehicle_flown_with_the_baseline_controller_still_responds_well():
    """Sec. 5.5: the controller self-tested on the baseline flies the camera configuration."""
    surge = run_scenario("surge", vehicle="camera")
    u = surge["outputs"]["u"]
    assert surge["config"] == "camera" and abs(u["final"] - 0.85) < 0.015 and u["overshoot_pct"] < 10.0
    assert u["rise95_s"] < 10.0 and 5.0 < surge["pitch_deg"]["peak"] < 35.0  # bow up, as the baseline
    sway = run_scenario("sway", vehicle="camera")["outputs"]["v"]
    assert sway["final"] > 0.25  # 0.29 asked: a vectored thruster saturates first, as on the baseline
    yaw = run_scenario("yaw", vehicle="camera")["outputs"]["r"]
    assert yaw["rise95_s"] < 2.6 and yaw["overshoot_pct"] < 10.0 and abs(yaw["steady_error"]) < 0.5


@pytest.fixture(scope="module")
def self_test_0_07():
    from seapup_bringup.self_test_sil import fly_self_test
    return fly_self_test("baseline", {"operating_points": [0.0, 0.7]}).test


@pytest.mark.graph
@pytest.mark.parametrize("name", ["fast", "current-step", "station-keep"])
def test_a_scenario_through_the_ros_graph_equals_the_in_process_run(name, self_test_0_07, tmp_path):
    """Through simulator + mfol_velocity_controller nodes in lockstep: the same numbers, including the
    events after the start — a stamped reference step at 15 s (fast), a current the simulator
    switches on at 10 s (current-step), the controller connected at 10 s after drifting
    (station-keep, in a stochastic current)."""
    from seapup_bringup.scenarios import fly_scenario_graph

    graph = fly_scenario_graph(name, self_test=self_test_0_07, out=tmp_path)
    local = run_scenario(name, self_test=self_test_0_07)
    np.testing.assert_allclose(graph["history"]["velocity"], local["history"]["velocity"], rtol=1e-9, atol=1e-12)
    for key in ("u", "v", "w", "r"):
        for metric, value in local["outputs"][key].items():
            assert graph["outputs"][key][metric] == pytest.approx(value, rel=1e-6, abs=1e-9), (key, metric)
    assert graph.get("station_keep") == pytest.approx(local.get("station_keep"))
    assert graph["through"] == "ros graph (lockstep)"
