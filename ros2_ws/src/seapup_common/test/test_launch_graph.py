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


def test_respawn_without_a_limit_reads_as_launch_reads_it(tmp_path):
    """launch's respawn_max_retries defaults to -1, no limit: a node with respawn alone restarts for ever (it
    read as 0, never restarted, while `ros2 launch` would restart it); -1 says the same, below -1 is refused."""
    import pytest

    from seapup_common.ros.launch_graph import LaunchError

    def loaded(**extra):
        path = tmp_path / "r.launch.yaml"
        path.write_text(yaml.safe_dump({"launch": [{"node": {"pkg": "seapup_sim", "exec": "simulator",
                                                             "respawn": "true", **extra}}]}))
        return load_graph(path)[0]
    assert loaded().respawn_limit == -1 and loaded(respawn_max_retries=-1).respawn_limit == -1
    assert loaded(respawn_max_retries=0).respawn_limit == 0
    with pytest.raises(LaunchError, match="respawn_max_retries must be an integer >= -1"):
        loaded(respawn_max_retries=-2)
    # written back: no key for no limit (launch's default), the number otherwise
    for limit in (-1, 0, 2):
        spec = NodeSpec(package="seapup_sim", executable="simulator", respawn=True, respawn_limit=limit)
        body = launch_document([spec])["launch"][0]["node"]
        assert body.get("respawn_max_retries", -1) == limit
        path = tmp_path / "w.launch.yaml"
        path.write_text(yaml.safe_dump(launch_document([spec])))
        assert load_graph(path)[0].respawn_limit == limit
