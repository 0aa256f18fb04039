"""Issue 45: a virtual-input vehicle (the BlueROV2 Heavy, eight fixed-pitch thrusters behind the mixer) flown
through the ROS graph in lockstep is the run flown in process: the four virtual inputs cross the graph on the
command topic as the Seapup's blade pitches do, the laws saturate at the vehicle's full scale on both sides.

Independent truth: the lockstep graph, whose simulator and controller nodes run in their own processes and
talk only through DDS, against the in-process runner sharing only the pure cores.
"""
import pytest

from seapup_runs.runner import run
from seapup_runs.spec import RunSpec
from tests.test_scenarios import assert_same_run


@pytest.mark.graph
def test_the_bluerov2_through_the_ros_graph_equals_the_in_process_run(tmp_path):
    from seapup_bringup.graph.graph_runner import run_on_graph

    spec = RunSpec.from_dict({
        "name": "bluerov2-graph", "vehicle": "bluerov2_heavy", "environment": {"sensors": "baseline"},
        "control_period": 0.2, "duration": 12.0, "start_depth": 20.0,
        "controller": {"type": "mfol", "parameters": {"schedule": False}},
        "design": {"vehicle": "bluerov2_heavy", "operating_points": [0.0]},
        "reference": [[0.0, 0.3, 0.0, 0.0, 0.0], [4.0, 0.0, 0.15, 0.0, 0.3], [8.0, 0.0, 0.0, 0.1, 0.0]],
        "events": [{"time": 6.0, "kind": "thruster_efficiency", "detail": [1.0, 0.5, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0]}],
        "seed": 4, "metrics": ["step_response"]})
    graph, process = run_on_graph(spec, out_dir=tmp_path), run(spec)
    assert_same_run(graph, process)
    from seapup_runs.run_graph import controller_nodes
    # the node's law saturates at the vehicle's full scale, as the in-process law does (not at +-35 deg)
    assert controller_nodes(spec, [""])[0]["parameters"][0]["blade_pitch_limit"] == 1.0


@pytest.fixture(scope="module")
def bluerov2_mission():
    from seapup_bringup.graph.hierarchy_config import hierarchy_config
    from seapup_bringup.graph.mission_graph import mission_config, mission_path
    from seapup_runs.mission import MissionSpec
    from seapup_runs.mission_flight import run_mission
    config = mission_config(mission_path("bluerov2_heavy"))
    spec = MissionSpec.load({"graph": config["graph"], "mission": config["mission"]})
    return config, run_mission(spec, hierarchy_config(spec.graph))


def test_the_demo_mission_shipped_for_the_bluerov2_flies_every_leg_in_process(bluerov2_mission):
    """``./seapup demo --vehicle bluerov2_heavy``'s mission: the self-test through the vehicle's own settings
    (the Seapup's poles would leave it oscillating about rest: docs/vehicles.md), then every leg of the demo;
    saturation measured against a virtual input's full scale."""
    config, flown = bluerov2_mission
    legs = flown["legs"]
    assert [leg["status"] for leg in legs] == ["succeeded"] * len(config["mission"]), \
        [leg.get("message") for leg in legs]
    assert abs(flown["logs"]["command"]).max() <= 1.0
    fouled = next(leg for leg in legs if leg["kind"] == "fouling")
    from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
    from seapup_runs.actuators import actuator_activity
    logs = flown["logs"]
    window = (logs["command_t"] >= fouled["t0"]) & (logs["command_t"] <= fouled["t1"])
    t, command = logs["command_t"][window], logs["command"][window]
    assert fouled["saturation_pct"] == actuator_activity(t, command, 1.0)["saturation_pct"] > 0.0
    assert actuator_activity(t, command, BLADE_PITCH_LIMIT)["saturation_pct"] > fouled["saturation_pct"]


def test_a_mission_names_one_efficiency_per_thruster_of_its_vehicle():
    from seapup_runs.mission import MissionError, MissionSpec
    from seapup_bringup.graph.mission_graph import mission_config, mission_path
    config = mission_config(mission_path("bluerov2_heavy"))
    index = next(i for i, leg in enumerate(config["mission"]) if leg["kind"] == "fouling")
    legs = list(config["mission"])
    legs[index] = dict(legs[index], foul={"after": 10.0, "efficiency": [1.0] * 33})
    with pytest.raises(MissionError, match="one value per thruster"):
        MissionSpec.load({"graph": config["graph"], "mission": legs})


@pytest.mark.graph
def test_the_bluerov2_demo_on_the_graph_is_the_mission_flown_in_process(tmp_path):
    """The self-test node with the launch's vehicle (its settings and input limit), the velocity controllers at
    the launch's input limit, the manager's swap, the simulator's eight-factor fouling service and the switch to
    GMV: the graph flies the BlueROV2's mission command for command as the process does. Flown on the graph:
    the legs that exercise what is this vehicle's own (the self-test, the hover with its swap, the fouled
    thruster); the others (goto, inspection, seabed, current) are the Seapup's leg kinds, whose graph equality
    ``tests/test_mission_flight.py`` proves, and the whole BlueROV2 mission flies in process above."""
    import io
    import numpy as np
    from seapup_bringup.graph.hierarchy_config import hierarchy_config
    from seapup_bringup.graph.mission_graph import fly_mission, mission_config, mission_path
    from seapup_runs.mission import MissionSpec
    from seapup_runs.mission_flight import run_mission
    config = mission_config(mission_path("bluerov2_heavy"))
    legs = [leg for leg in config["mission"] if leg["kind"] in ("self_test", "hover", "fouling")]
    assert [leg["kind"] for leg in legs] == ["self_test", "hover", "fouling"]
    spec = MissionSpec.load({"graph": config["graph"], "mission": legs})
    flown = run_mission(spec, hierarchy_config(spec.graph))
    on_graph = fly_mission(tmp_path, {"graph": dict(config["graph"]), "mission": legs}, io.StringIO())
    assert on_graph["stopped"] is None
    assert [leg["status"] for leg in on_graph["legs"]] == [leg["status"] for leg in flown["legs"]] \
        == ["succeeded"] * 3
    assert np.array_equal(np.round(on_graph["logs"]["command_t"], 6), np.round(flown["logs"]["command_t"], 6))
    assert np.abs(on_graph["logs"]["command"] - flown["logs"]["command"]).max() <= 1e-9
    # the fouling (T1 at half) and the swap to GMV happened on both sides at the same sample
    for key in ("foul_t", "switch_t"):
        assert on_graph["legs"][-1][key] == flown["legs"][-1][key], key
