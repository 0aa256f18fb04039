"""./seapup scenario: the thesis's closed-loop cases flown with the self-tested controller."""
import json
import math

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


def test_current_step_and_station_keeping_reject_the_current():
    step = run_scenario("current-step")
    assert step["u_peak_after_current"] > 0.2 + 0.01          # the current pushes surge up (thesis 0.2574)
    assert step["recovery_5pct_s"] < 10.0                     # and it is brought back (thesis 5.8 s)
    assert step["outputs"]["u"]["overshoot_pct"] < 10.0       # measured before the current, not because of it
    keep = run_scenario("station-keep")
    sk = keep["station_keep"]
    assert sk["max_abs_x"] < 1.0 and sk["max_abs_y"] < 0.3 and sk["max_abs_z"] < 0.3  # thesis 0.60, 0.06, 0.06 m
    assert sk["max_abs_yaw_deg"] < 10.0 and math.isfinite(keep["outputs"]["u"]["final"])


@pytest.mark.graph
def test_a_scenario_through_the_ros_graph_equals_the_in_process_run(tmp_path):
    """surge through simulator + mfol_velocity_controller nodes in lockstep: the same numbers."""
    from seapup_bringup.scenarios import fly_scenario_graph
    from seapup_bringup.self_test_sil import fly_self_test

    test = fly_self_test("baseline", {"operating_points": [0.0, 0.7]}).test
    graph = fly_scenario_graph("surge", self_test=test, out=tmp_path)
    local = run_scenario("surge", self_test=test)
    # the node starts bumpless from the applied hover if it heard it by activation, else from u0
    if not np.allclose(graph["history"]["velocity"], local["history"]["velocity"], atol=1e-9):
        local = run_scenario("surge", self_test=test, start_from_offset=True)
    for key in ("u", "w", "r"):
        for name, value in local["outputs"][key].items():
            assert graph["outputs"][key][name] == pytest.approx(value, rel=1e-6, abs=1e-9), (key, name)
    np.testing.assert_allclose(graph["history"]["velocity"], local["history"]["velocity"], atol=1e-9)
    assert graph["through"] == "ros graph (lockstep)"
