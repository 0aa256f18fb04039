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
