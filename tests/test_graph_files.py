"""The shipped graph files are complete on their own (issue 40).

- ``self_test.launch.yaml`` then ``./seapup action send_goal`` (docs/command-line.md) runs the self-test with
  the graph's defaults: it aborted after 10 s with "no velocity data" unless a non-default
  ``wait_for_subscribers`` was passed (the simulator sent t_0 before the self-test heard the velocity).
- Every velocity controller of ``hierarchy.launch.yaml`` whose law needs a controller file gets one in the
  demo (``config/mission.yaml``): the controller manager configures every managed controller at each switch,
  and ``explicit``, left without a file, logged ``[ERROR] configure failed`` at each of the demo's three.
"""
import json
import subprocess
import sys
from pathlib import Path

from ament_index_python.packages import get_package_share_directory

from seapup_common.config import load_yaml
from seapup_common.controllers import controller_type
from seapup_common.ros.launch_graph import load_graph

SHARE = Path(get_package_share_directory("seapup_bringup"))


def _velocity_controllers(graph):
    """(node name, controller type) of every velocity_controller node of a graph, and the manager's list."""
    nodes = [n for n in graph if n.package == "seapup_control" and n.executable == "velocity_controller"]
    merged = [{k: v for p in n.parameters if isinstance(p, dict) for k, v in p.items()} for n in nodes]
    manager = next(n for n in graph if n.executable == "controller_manager")
    managed = {k: v for p in manager.parameters if isinstance(p, dict) for k, v in p.items()}["controllers"]
    return [(n.name, m["controller_type"]) for n, m in zip(nodes, merged)], list(managed)


def test_every_controller_of_the_demo_graph_gets_the_file_its_law_needs():
    mission = load_yaml(SHARE / "config" / "mission.yaml")
    graph = load_graph(SHARE / "launch" / "hierarchy.launch.yaml",
                       {k: str(v) for k, v in mission["graph"].items()})
    controllers, managed = _velocity_controllers(graph)
    assert sorted(name for name, _ in controllers) == sorted(managed)   # the manager configures each of them
    needing = {name for name, kind in controllers if controller_type(kind).needs_document}
    assert needing == {"mfol_fixed", "mfol_scheduled", "explicit", "gmv", "manual"}   # manual: the mission's pilot
    given = set()
    for leg in mission["mission"]:
        if leg["kind"] == "self_test":   # its result is set as controller_file of each node it lists
            given |= set(leg["configure"])
    assert needing - given == set()


def test_the_self_test_graph_runs_the_documented_goal_with_its_defaults(node_process, ros_env, tmp_path):
    graph = node_process([sys.executable, "-m", "seapup_bringup.cli", "launch", "seapup_bringup",
                          "self_test.launch.yaml", f"result_dir:={tmp_path}"], name="launch")
    run = subprocess.run([sys.executable, "-m", "seapup_bringup.cli", "action", "send_goal", "/seapup/self_test",
                          "seapup_msgs/action/SelfTest", "{operating_points: [0.0]}", "--json"], env=ros_env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, (run.stderr[-2000:], graph.log_text()[-3000:])
    result = json.loads(run.stdout)
    assert result["status"] == "succeeded" and result["result"]["success"] is True, result
    assert Path(result["result"]["controller_file"]).is_file()
    assert "[ERROR]" not in graph.log_text()
