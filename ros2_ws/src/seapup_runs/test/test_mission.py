"""Missions as data (seapup_runs.mission): the demo's mission checked, and every way a mission file is refused."""
import copy
import math

import pytest
import yaml

from seapup_runs.mission import LEG_KINDS, MAX_LEGS, MissionError, MissionSpec, load_mission


def a_mission() -> dict:
    """A mission written here, not shipped: one leg of every kind."""
    return {"graph": {"seed": 3, "sensors": "ideal", "current": False, "start_depth": 40.0},
            "mission": [
                {"name": "tune", "kind": "self_test", "goal": {"operating_points": [0.0, 0.7]},
                 "configure": ["mfol_fixed", "gmv"], "activate": "mfol_fixed", "expected": 150},
                {"name": "hold", "kind": "hover", "goal": {"hold_current": True, "duration": 20.0},
                 "switch": {"after": 10.0, "request": {"activate": ["gmv"], "deactivate": ["mfol_fixed"]}}},
                {"name": "over", "kind": "goto", "offset": [5.0, 0.0, 1.0], "turn": math.pi / 2,
                 "goal": {"tolerance": 0.5}},
                {"name": "creep", "kind": "inspection", "body_velocity": [0.2, 0.0, 0.0], "seconds": 10.0},
                {"name": "seabed", "kind": "follow_seabed",
                 "goal": {"altitude": 5.0, "yaw": 0.0, "speed": 0.1, "duration": 30.0}, "hold_from": 10.0},
                {"name": "stream", "kind": "current", "current": {"enabled": True, "mean_speed": 0.2, "speed_std": 0.0,
                                                                  "mean_direction": 0.0, "direction_std": 0.0},
                 "goal": {"duration": 30.0}, "face": 0.0},
                {"name": "by hand", "kind": "manual", "controller": "manual", "hand_back": "mfol_fixed",
                 "pilot": [[0.0, 0.2, 0.0, 0.0, 0.0], [10.0, 0.0, 0.1, 0.0, 0.1]], "seconds": 20.0,
                 "goal": {"duration": 10.0}},
                {"name": "foul", "kind": "fouling", "body_velocity": [0.2, 0.1, 0.1], "fouled_seconds": 20.0,
                 "foul": {"after": 5.0, "efficiency": [0.5, 1, 1, 1]},
                 "switch": {"activate": ["gmv"], "deactivate": ["mfol_fixed"]}, "adaptive_seconds": 20.0}]}


def test_a_mission_with_every_kind_of_leg_is_taken_as_written():
    spec = MissionSpec.load(a_mission())
    assert [leg["kind"] for leg in spec.legs] == list(LEG_KINDS)
    assert spec.to_dict() == a_mission()
    assert spec.graph["seed"] == 3 and isinstance(spec.graph["seed"], int)   # a launch argument stays an integer
    assert spec.expected_seconds == 150 + 7 * 60.0


def test_the_shipped_demo_mission_is_valid(tmp_path):
    from pathlib import Path
    path = Path(__file__).parents[2] / "seapup_bringup" / "config" / "mission.yaml"
    spec = load_mission(path)
    assert spec.to_dict() == yaml.safe_load(path.read_text())
    assert {leg["kind"] for leg in spec.legs} == set(LEG_KINDS)


def refused(change, match: str):
    document = a_mission()
    change(document)
    with pytest.raises(MissionError, match=match):
        MissionSpec.load(document)


@pytest.mark.parametrize("change, match", [
    (lambda d: d["mission"][2].update(offest=[1, 2, 3]),
     r"unknown mission leg 3 \('over', goto\) key\(s\) \['offest'\]; known: .*offset"),
    (lambda d: d["mission"][3].update(seconds="10"), r"seconds must be a number, got '10' \(text, not a number"),
    (lambda d: d["mission"][3].update(seconds=True), "seconds must be a number, got True"),
    (lambda d: d["mission"][3].update(seconds=float("nan")), "seconds must be a finite number"),
    (lambda d: d["mission"][3].update(seconds=0.0), r"seconds must be in \(0, 86400\]"),
    (lambda d: d["mission"][3].update(body_velocity=[0.2, 0.0]), "body_velocity needs 3 values, got 2"),
    (lambda d: d["mission"][3].update(body_velocity=[50.0, 0.0, 0.0]), r"body_velocity must be within \+-5 m/s"),
    (lambda d: d["mission"][1]["switch"].update(after=20.0), "switch after 20 s is not within the hover's 20 s"),
    (lambda d: d["mission"][7]["foul"].update(after=20.0), r"foul after 20 s is not within fouled_seconds \(20 s\)"),
    (lambda d: d["mission"][7]["foul"].update(efficiency=[1.5, 1, 1, 1]), r"efficiency must be values in \[0, 1\], one per thruster"),
    (lambda d: d["mission"][6].update(pilot=[]), r"mission leg 7 \('by hand', manual\) pilot needs at least one"),
    (lambda d: d["mission"][6].update(pilot=[[0.0, 0.2, 0.0, 0.0]]), "pilot row needs 5 values"),
    (lambda d: d["mission"][6].update(pilot=[[5.0, 0.2, 0, 0, 0], [1.0, 0, 0, 0, 0]]), "pilot rows need times >= 0 s, rising"),
    (lambda d: d["mission"][6].update(pilot=[[0.0, 9.0, 0, 0, 0]]), r"speeds must be within 5 m/s"),
    (lambda d: d["mission"][6].update(pilot=[[0.0, math.inf, 0, 0, 0]]), "finite"),
    (lambda d: d["mission"][6].update(seconds=10.0), r"the pilot's last row at 10 s comes after its last send \(9.5 s"),
    (lambda d: d["mission"][6].update(hand_back="manual"), "hand_back must be another controller than 'manual'"),
    (lambda d: d["mission"][6].pop("goal"), r"mission leg 7 \('by hand', manual\) needs goal"),
    (lambda d: d["mission"][6]["goal"].update(hold_current=True), r"unknown .*goal key\(s\) \['hold_current'\]"),
    (lambda d: d["mission"][1]["switch"].update(request={}), "activates or deactivates nothing"),
    (lambda d: d["mission"][0].pop("activate"), r"mission leg 1 \('tune', self_test\) needs activate"),
    (lambda d: d["mission"][0].update(configure=[]), "configure must be a non-empty list"),
    (lambda d: d["mission"][0]["goal"].update(samples=2.5), "samples must be a whole number"),
    (lambda d: d["mission"][4]["goal"].pop("altitude"), "goal needs altitude"),
    (lambda d: d["mission"][5]["current"].pop("mean_speed"), "an enabled current needs mean_speed"),
    (lambda d: d["mission"][5].update(face=100.0), r"face must be in \[-12.5664, 12.5664\]"),
    (lambda d: d["mission"][4].update(kind="orbit"), "kind must be one of self_test, hover, goto, inspection"),
    (lambda d: d["mission"].append(copy.deepcopy(d["mission"][3])), "leg names must be unique; repeated: 'creep'"),
    (lambda d: d["mission"].__setitem__(2, "goto"), "mission leg 3 must be a mapping"),
    (lambda d: d.update(mission=[]), "mission must be a non-empty list of legs"),
    (lambda d: d.pop("mission"), "a mission document needs mission"),
    (lambda d: d.update(legs=[]), r"unknown mission document key\(s\) \['legs'\]"),
    (lambda d: d["graph"].update(seed=[1, 2]), "graph seed must be a number"),
    (lambda d: d.update(graph=[1]), "graph must be a mapping of launch arguments"),
])
def test_a_mission_that_cannot_be_flown_is_refused_in_one_line(change, match):
    refused(change, match)


def test_the_legs_are_counted_before_one_is_checked():
    document = {"mission": [{"kind": "nonsense"}] * (MAX_LEGS + 1)}
    with pytest.raises(MissionError, match=f"mission has {MAX_LEGS + 1} legs; at most {MAX_LEGS}"):
        MissionSpec.load(document)


def test_a_mission_file_is_read_within_bounds_and_named_in_the_error(tmp_path):
    good = tmp_path / "good.yaml"
    good.write_text(yaml.safe_dump(a_mission()))
    assert load_mission(good).to_dict() == a_mission()
    twice = tmp_path / "twice.yaml"
    twice.write_text("mission: []\nmission: []\n")
    with pytest.raises(MissionError, match="twice.yaml.*duplicate|duplicate.*twice.yaml"):
        load_mission(twice)
    empty = tmp_path / "empty.yaml"
    empty.write_text("# nothing\n")
    with pytest.raises(MissionError, match="empty.yaml"):
        load_mission(empty)
    bad = tmp_path / "bad.yaml"
    document = a_mission()
    document["mission"][3]["seconds"] = -1.0
    bad.write_text(yaml.safe_dump(document))
    with pytest.raises(MissionError, match=r"^.*bad.yaml: mission leg 4 \('creep', inspection\) seconds must be in"):
        load_mission(bad)
    with pytest.raises(MissionError, match="no such|not found|does not exist|cannot"):
        load_mission(tmp_path / "missing.yaml")
