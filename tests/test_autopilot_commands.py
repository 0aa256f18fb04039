"""``./seapup selftest`` and ``./seapup closed-loop``: what they print as JSON matches what they compute."""
import json
import math

import numpy as np
import pytest

from seapup_bringup.verbs.autopilot_commands import closed_loop_command, selftest
from seapup_sim.analysis import hover_blade_pitch
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config


def test_selftest_json_has_the_operating_points_gains_time_and_space(tmp_path):
    out = tmp_path / "st.json"
    assert selftest(["--speeds", "0", "--in-process", "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    (point,) = result["operating_points"]
    hover = np.degrees(hover_blade_pitch(VehicleModel(load_vehicle_config("baseline"))))
    np.testing.assert_allclose(point["u0_deg"], hover, atol=0.2)
    assert np.array(point["B0inv"]).shape == (4, 4) and np.array(point["Ki"]).shape == (4, 4)
    # thesis units: u per degree of main pitch is ~0.024 m/s (eq. 5.3b: 0.0246)
    assert 0.015 < point["B1inv"][0][0] < 0.035
    assert 60 < result["duration_s"] < 240 and len(result["space_m"]) == 3


def test_closed_loop_json_has_sixteen_poles_per_speed_four_of_them_the_position_integrations(tmp_path):
    out = tmp_path / "cl.json"
    assert closed_loop_command(["--speeds", "0", "--json", str(out), "--plots", str(tmp_path / "plots")]) == 0
    result = json.loads(out.read_text())
    assert [row["surge"] for row in result["speeds"]] == [round(0.1 * k, 1) for k in range(11)]
    for row in result["speeds"]:
        assert len(row["z_poles"]) == 16  # 12 vehicle states + 4 integrators (sec. 5.4.1)
        assert len(row["modes"]["position"]) == 4
        assert row["stable"] and row["max_re_s"] < 0
        np.testing.assert_allclose([math.hypot(*p) for p in row["modes"]["position"]], 0.0, atol=1e-6)
        # eq. 5.15's structure: two eigenvalues per mode at every speed (a loop's pole and its integrator's,
        # an attitude's angle and rate), as each of figs 5.4-5.9 draws them
        assert {m: len(p) for m, p in row["modes"].items() if m != "position"} == dict.fromkeys(
            ("surge", "sway", "heave", "yaw", "roll", "pitch"), 2)
    assert len(list((tmp_path / "plots").glob("fig5_*.png"))) == 6


def test_modes_are_labelled_two_each_where_the_largest_component_would_crowd_one():
    """A constructed spectrum: six modes' eigenvectors, one of pitch's leaning more on surge (1.0) than on
    pitch (0.9). The largest component gives surge three eigenvalues and pitch one; the two-per-mode
    assignment gives the leaning one to pitch and keeps the pure integrations as position."""
    from seapup_runs.closed_loop_analysis import _label_modes, _mode_of
    states = {"surge": 6, "sway": 7, "heave": 8, "yaw": 11, "roll": 3, "pitch": 4}
    vectors, s_values = np.zeros((16, 16)), np.zeros(16, dtype=complex)
    for k, idx in enumerate((0, 1, 2, 5)):      # the four pure integrations (s = 0)
        vectors[idx, k] = 1.0
    k = 4
    for mode, idx in states.items():
        for _ in range(2):
            vectors[idx, k] = 1.0
            vectors[12 + k % 4, k] = 0.1
            s_values[k] = -0.5 - 0.1 * k
            k += 1
    leaning = [j for j in range(16) if vectors[4, j] == 1.0][1]
    vectors[4, leaning], vectors[6, leaning] = 0.9, 1.0
    crowded = [_mode_of(vectors[:, j], s_values[j]) for j in range(16)]
    assert crowded.count("surge") == 3 and crowded.count("pitch") == 1
    labels = _label_modes(vectors, s_values)
    assert labels[leaning] == "pitch" and labels[:4] == ["position"] * 4
    assert {m: labels.count(m) for m in states} == dict.fromkeys(states, 2)


@pytest.mark.graph
def test_selftest_through_the_action_records_a_bag_that_refits_to_the_same_result(tmp_path, ros_env, monkeypatch):
    """The default path: simulator + self_test action server + recorder on a leased domain; the JSON's
    matrices are the bag's refit, which the command checks against the action's live result."""
    for key, value in ros_env.items():
        monkeypatch.setenv(key, value)
    out = tmp_path / "st.json"
    assert selftest(["--speeds", "0", "--out", str(tmp_path / "run"), "--json", str(out)]) == 0
    live = json.loads(out.read_text())
    assert live["bag"] == str(tmp_path / "run" / "bag")
    again = tmp_path / "again.json"
    assert selftest(["--from-bag", live["bag"], "--json", str(again)]) == 0
    refit = json.loads(again.read_text())
    np.testing.assert_array_equal(refit["operating_points"][0]["B1inv"], live["operating_points"][0]["B1inv"])
    inproc = tmp_path / "inproc.json"
    assert selftest(["--speeds", "0", "--in-process", "--json", str(inproc)]) == 0
    local = json.loads(inproc.read_text())
    # the graph run starts at the hover setting, the in-process one at the zero level: close, not equal
    np.testing.assert_allclose(live["operating_points"][0]["u0_deg"], local["operating_points"][0]["u0_deg"],
                               atol=0.05)
    assert list((tmp_path / "run").glob("self_test_*.yaml"))  # the controller file


def test_a_goal_the_self_test_server_refuses_is_reported_with_its_reason(tmp_path, ros_env, monkeypatch, capsys):
    """Through ROS, a refused goal once said only "refused the goal"; the reason is the server's."""
    for key, value in ros_env.items():
        monkeypatch.setenv(key, value)
    assert selftest(["--speeds", "0.7", "--out", str(tmp_path / "run")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("seapup selftest: error: /seapup/self_test refused the goal: ")
    assert "operating_points must start with 0.0" in err[-1]


def test_what_stops_a_selftest_is_one_line_not_a_traceback(capsys):
    assert selftest(["--config", "submarine", "--in-process"]) == 1
    assert selftest(["--speeds", "0,fast", "--in-process"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(line.startswith("seapup selftest: error: ") for line in err), err
