"""Dependencies point one way, and pure cores never touch ROS.

    seapup_msgs <- seapup_common <- seapup_sim, seapup_ident <- seapup_control <- seapup_runs <- seapup_bringup
                                               seapup_sim <- seapup_live_view <------------------------'

seapup_control and seapup_ident must install and run on a real vehicle without
the simulator, so they never import seapup_sim (outside their tests); a
controller may use the recursive estimators of seapup_ident (the self-tuners of
ch. 7). seapup_runs (run specs, results, the in-process runner) sees the
simulator and the controllers but no ROS: rclpy drivers and the simulator's
node are bringup's and the tests' alone. Pure-core
modules import numpy/scipy/yaml/rosbags but never rclpy or ROS message
packages, directly or through another seapup module; rclpy shells are the
``*_node.py`` modules, each package's ``ros`` subpackage (``seapup_common.ros``,
``seapup_control.ros``) and the modules named in :data:`SHELLS` (bringup's verbs, graphs and SIL harness; the
live view's graph helpers): every other module of bringup and the live view is held to the pure rule too, and
every named shell must really reach ROS (a module that no longer does leaves the list).
"""
import ast
import functools
import re
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "ros2_ws" / "src"
LAYER = {"seapup_msgs": 0, "seapup_common": 1, "seapup_sim": 2, "seapup_ident": 2, "seapup_control": 3,
         "seapup_live_view": 3, "seapup_runs": 4, "seapup_bringup": 5}
# seapup_sim and seapup_ident share a layer: neither imports the other; nor do seapup_control and the live view
# (which draws the vehicle and the seabed from the simulator's configuration, and flies nothing)
#: The modules that are rclpy shells besides ``*_node.py`` and the ``ros`` subpackages, named one by one.
SHELLS = {
    # bringup: the command line and its verbs (each starts or talks to a graph, or imports one that does)
    "seapup_bringup.cli", "seapup_bringup.cli_usage",
    *(f"seapup_bringup.verbs.{verb}" for verb in (
        "autopilot_commands", "campaign_commands", "demo", "ident_commands", "model_commands", "report_commands",
        "run_commands", "scenario_commands", "view_commands")),
    # bringup: the ros2cli / launch / rosbag2 substitute
    "seapup_bringup.ros2cli.launch", "seapup_bringup.ros2cli.ros2_commands", "seapup_bringup.ros2cli.bag_commands",
    # bringup: the SIL harness, the graph runners (a run, a mission, an experiment), benchmarks; Dask campaigns
    # (their missions' hierarchies are read from the installed launch document); the report's runs
    *(f"seapup_bringup.graph.{name}" for name in (
        "sil", "sil_probe", "graph_stepper", "graph_runner", "mission_graph", "identification", "self_test_graph",
        "open_loop",
        "graph_bench", "hierarchy_config")),
    "seapup_bringup.campaign_runner", "seapup_bringup.report.reproduction",
    # the live view: the node beside a graph, and the layout of the node's topics
    "seapup_live_view.attach", "seapup_live_view.view_layout",
}
#: Bringup's sub-packages by job (docs/contributing.md): every module of bringup is in one of them but the
#: command line's front (its registry, usage lines and output conventions) and the Dask campaign runner.
BRINGUP_JOBS = ("verbs", "ros2cli", "graph", "report")
BRINGUP_TOP = {"seapup_bringup", "seapup_bringup.cli", "seapup_bringup.cli_usage", "seapup_bringup.output",
               "seapup_bringup.campaign_runner", "seapup_bringup.dask_worker_setup"}
ROS = re.compile(r"^(rclpy|rosidl\w*|ament_index_python|\w+_msgs|\w+_interfaces|rcl_\w+|rosgraph_msgs)(\.|$)")


def modules():
    """Every module of the Python packages (not their tests): name -> path."""
    out = {}
    for package in LAYER:
        root = SRC / package / package
        for path in sorted(root.rglob("*.py")) if root.is_dir() else []:
            rel = path.relative_to(SRC / package).with_suffix("")
            name = ".".join(rel.parts)
            out[name.removesuffix(".__init__")] = path
    return out


@functools.lru_cache(maxsize=None)
def imports_of(path: Path) -> frozenset[str]:
    """Every absolute import in ``path`` (module level or inside functions), as ``module`` and ``module.name``."""
    return frozenset(_imports_of(path))


def _imports_of(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            names.update(f"{node.module}.{a.name}" for a in node.names)
    return names


def is_shell(module: str) -> bool:
    package = module.split(".")[0]
    return (module in SHELLS or module.startswith(f"{package}.ros.") or module == f"{package}.ros"
            or module.split(".")[-1].endswith("_node"))


MODULES = modules()


def test_the_packages_exist_and_are_walked():
    assert {m.split(".")[0] for m in MODULES} == set(LAYER) - {"seapup_msgs"}
    assert len(MODULES) >= 35


@pytest.mark.parametrize("module", sorted(MODULES))
def test_imports_point_down_the_layers(module):
    mine = module.split(".")[0]
    for name in imports_of(MODULES[module]):
        other = name.split(".")[0]
        if other in LAYER and other != mine:
            assert LAYER[other] < LAYER[mine], f"{module} imports {name}: {other} is not below {mine}"


def _simulator_names(names) -> list[str]:
    return sorted(n for n in names if n.split(".")[0] == "seapup_sim")


def test_control_never_reaches_the_simulator():
    """Control runs on a real vehicle: not even through another module does it import seapup_sim."""
    for module in (m for m in MODULES if m.startswith("seapup_control")):
        sim = _simulator_names(_project_closure(module))
        assert not sim, f"{module} reaches {sim}"


@pytest.mark.parametrize("module", sorted(m for m in MODULES if m.startswith("seapup_runs")))
def test_the_run_layer_is_pure_and_never_starts_a_node(module):
    names = _project_closure(module)
    assert not [n for n in names if ROS.match(n)], f"{module} reaches ROS"
    assert not [n for n in names if n.endswith("_node") or ".ros." in n or n.endswith(".ros")], module


@functools.lru_cache(maxsize=None)
def _project_closure(module: str) -> frozenset[str]:
    """Every import of ``module``, following the project's own modules."""
    return frozenset(_closure(module, set()))


def _closure(module: str, seen: set) -> set[str]:
    out = set()
    for name in imports_of(MODULES[module]):
        out.add(name)
        target = next((m for m in (name, name.rsplit(".", 1)[0]) if m in MODULES), None)
        if target and target not in seen:
            seen.add(target)
            out |= _closure(target, seen)
    return out


def test_every_named_shell_exists_and_reaches_ros():
    """The list of shells is not a blanket: each is a module of the product, and each really reaches ROS."""
    assert SHELLS <= set(MODULES), sorted(SHELLS - set(MODULES))
    pure = sorted(m for m in SHELLS if not any(ROS.match(n) for n in _project_closure(m)))
    assert not pure, f"named as shells but pure: {pure} (take them off SHELLS: the pure rule then guards them)"


@pytest.mark.parametrize("module", sorted(m for m in MODULES if not is_shell(m)))
def test_pure_cores_never_reach_ros(module):
    ros = sorted(n for n in _project_closure(module) if ROS.match(n))
    assert not ros, f"pure-core module {module} reaches {ros}"


def test_package_manifests_declare_the_same_direction():
    for package, layer in LAYER.items():
        xml = (SRC / package / "package.xml").read_text()
        for dep in re.findall(r"<(?:exec_|build_)?depend>(seapup_\w+)</", xml):
            assert LAYER[dep] < layer, f"{package}/package.xml depends on {dep}"


def test_the_checker_catches_a_violation(tmp_path):
    """The walk really sees imports: a control module importing the simulator is flagged."""
    bad = tmp_path / "bad.py"
    bad.write_text("from seapup_sim.simulation import Simulation\nimport rclpy.node\n")
    names = imports_of(bad)
    assert "seapup_sim.simulation" in names and any(ROS.match(n) for n in names)
    assert _simulator_names(names) == ["seapup_sim.simulation", "seapup_sim.simulation.Simulation"]


def _is_verb(module: str) -> bool:
    return module.startswith("seapup_bringup.verbs.") or (module.startswith("seapup_bringup.ros2cli.")
                                                          and module.endswith("_commands"))


@pytest.mark.parametrize("module", sorted(m for m in MODULES if m not in ("seapup_bringup.cli", "seapup_bringup.cli_usage")))
def test_no_product_module_imports_a_verb(module):
    """Issue 44: a verb parses, calls the product and prints; what two verbs (or the report) share lives below
    them. Only the command registry (and its usage lines) imports a verb module."""
    verbs = sorted(n for n in imports_of(MODULES[module]) if _is_verb(n))
    assert not verbs, f"{module} imports the verb module(s) {verbs}"


def test_bringup_is_split_by_job():
    """Issue 44: bringup's modules live in sub-packages by job, but for the command line's front."""
    loose = sorted(m for m in MODULES if m.startswith("seapup_bringup") and m not in BRINGUP_TOP
                   and m.split(".")[1] not in BRINGUP_JOBS)
    assert not loose, f"modules of bringup outside {BRINGUP_JOBS}: {loose}"
    assert all(f"seapup_bringup.{job}" in MODULES for job in BRINGUP_JOBS)


def test_only_the_graph_runner_starts_a_graph():
    """Issue 44: every experiment on the graph (a run spec, a mission and the demo, the self-test in SIL, the
    identification experiment, the open-loop run, the hierarchy benchmark) is a GraphSpec flown by
    ``seapup_bringup.graph.graph_runner.fly_graph``: no other product module starts a SIL harness (the
    harness's own docstring shows a user how)."""
    starting = sorted(m for m, path in MODULES.items()
                      if m != "seapup_bringup.graph.sil"
                      and re.search(r"^(?!\s*(#|>>>)).*\bSilGraph\(", path.read_text(), re.M))
    assert starting == ["seapup_bringup.graph.graph_runner"], starting
    assert re.search(r"\bSilGraph\(", MODULES["seapup_bringup.graph.graph_runner"].read_text())


#: Issue 43: the node shells only execute the lockstep protocol's actions (seapup_common/lockstep): the classes
#: that drive a graph stay small, and any growth has to pass this line.
SHELL_CLASS_LINES = {("seapup_sim/seapup_sim/simulator_node.py", "SimulatorNode"): 300,
                     ("seapup_bringup/seapup_bringup/graph/sil.py", "SilGraph"): 350}


@pytest.mark.parametrize("where", sorted(SHELL_CLASS_LINES), ids=lambda where: where[1])
def test_the_lockstep_shells_stay_within_their_size(where):
    path, name = where
    found = [node for node in ast.parse((SRC / path).read_text()).body
             if isinstance(node, ast.ClassDef) and node.name == name]
    assert len(found) == 1, (path, name)
    lines = found[0].end_lineno - found[0].lineno + 1
    assert lines <= SHELL_CLASS_LINES[where], f"{name} is {lines} lines (at most {SHELL_CLASS_LINES[where]})"
