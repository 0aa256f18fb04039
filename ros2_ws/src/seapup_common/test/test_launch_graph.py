"""launch_document writes what load_graph reads: a graph written by a run or a harness starts the same commands."""
import yaml

from seapup_common.launch_format import NodeSpec, launch_document
from seapup_common.ros.launch_graph import _flatten, load_graph


def test_a_written_document_loads_back_to_the_same_nodes(tmp_path):
    nodes = [
        {"package": "seapup_sim", "executable": "simulator", "required": True,
         "parameters": [{"mode": "lockstep", "end_time": 12.5, "start_held": False, "seed": 7, "label": "true",
                         "environment": {"sensors": "ideal", "current": {"enabled": True}},
                         "wait_for_subscribers": ["/a", "/a", "/b"], "events": "[{time: 1.0, kind: current}]"}]},
        NodeSpec(package="seapup_control", executable="velocity_controller", name="toy", namespace="/x",
                 parameters=[{"gains": [1.0, 2.0]}], remappings={"thrusters/command": "/x/cmd"},
                 args=["--flag", "a b"], respawn=True, respawn_limit=3, respawn_delay=0.5)]
    path = tmp_path / "g.launch.yaml"
    path.write_text(yaml.safe_dump(launch_document(nodes, {"unused": 1.5}), sort_keys=False))
    simulator, toy = load_graph(path)
    assert (simulator.package, simulator.executable, simulator.required) == ("seapup_sim", "simulator", True)
    assert simulator.parameters == [_flatten(nodes[0]["parameters"][0])]   # the same values and types
    assert simulator.parameters[0]["label"] == "true" and simulator.parameters[0]["start_held"] is False
    assert (toy.name, toy.namespace, toy.remappings, toy.args) == ("toy", "/x", {"thrusters/command": "/x/cmd"},
                                                                   ["--flag", "a b"])
    assert (toy.respawn, toy.respawn_limit, toy.respawn_delay, toy.required) == (True, 3, 0.5, False)
    assert toy.parameters == [{"gains": [1.0, 2.0]}]
