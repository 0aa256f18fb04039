"""The lockstep roster (seapup_common.lockstep.roster) against independent truth: the counts the shipped launch
files spelled by hand before they were derived (git 1ba1677: hierarchy.launch.yaml listed the velocity six
times and the applied pitch five times), and the formulas seapup_runs.run_graph used for run graphs
(simulator: [velocity, applied] x controllers + the run's topics x listeners; each controller 1 + listeners;
the reference publisher controllers + listeners)."""
from collections import Counter
from pathlib import Path

import pytest
import yaml

from seapup_common import topics
from seapup_common.launch_format import NodeSpec
from seapup_common.lockstep.roster import (Listener, NotPublishedError, Role, RoleFileError, Roster,
                                           UnknownRoleError, fill, nodes_of_document, package_roles, parse_roles,
                                           resolve, role_book)
from seapup_common.lockstep.roster import roster as derive
from seapup_common.ros.launch_graph import find_graph, graph_arguments, load_graph

def installed(package):
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    try:
        return get_package_share_directory(package)
    except PackageNotFoundError:
        return None


INSTALLED = role_book(installed)


def roster(nodes, listeners=(), roles=INSTALLED):
    """The roster with the installed packages' roles (those the launcher uses)."""
    return derive(nodes, listeners, roles=roles)


V, A, IMU, DEPTH, POS = topics.VELOCITY, topics.APPLIED, topics.IMU, topics.DEPTH, topics.POSITION
TRUTH, ALT, MANIFEST, COMMAND = topics.TRUTH_ODOMETRY, topics.ALTITUDE, topics.SAMPLE_MANIFEST, topics.COMMAND


def shipped(name: str, **arguments):
    """A shipped graph's nodes (a required controller_file given a placeholder where the graph declares it)."""
    path = find_graph("seapup_bringup", name)
    if "controller_file" in graph_arguments(path):
        arguments.setdefault("controller_file", "c.yaml")
    return load_graph(path, {k: str(v) for k, v in arguments.items()})


def awaited(plan: Roster, label: str = "simulator") -> Counter:
    return Counter(plan.settings.get(label, {}).get("wait_for_subscribers", []))


# -- the shipped launch files: what they spelled by hand --------------------------------------------
def test_hierarchy_velocity_six_and_applied_pitch_five():
    """hierarchy.launch.yaml listed the velocity 6 times (navigator, self-test, four controllers), the applied
    pitch 5 times (manager, four controllers), IMU, depth, position fix, manifest (navigator) and altitude
    (task controller) once; the manager's and self-test's first command waited for 1 (the simulator)."""
    plan = roster(shipped("hierarchy.launch.yaml"))
    assert awaited(plan) == Counter({V: 6, A: 5, IMU: 1, DEPTH: 1, POS: 1, MANIFEST: 1, ALT: 1})
    controllers = {"mfol_fixed", "mfol_scheduled", "explicit", "gmv"}
    assert set(plan.listeners[V]) == {"navigator", "self_test"} | controllers
    assert set(plan.listeners[A]) == {"controller_manager"} | controllers
    assert plan.settings["controller_manager"] == {"wait_for_command_subscribers": 1}
    assert plan.settings["self_test"] == {"wait_for_command_subscribers": 1, "wait_for_sample_subscribers": 0}
    # a controller's remapped command is heard by nobody the graph names (today's default, 0)
    assert all(plan.settings[c] == {"wait_for_command_subscribers": 0} for c in controllers)
    assert set(plan.answerers) == controllers | {"self_test"}


def test_without_an_initial_controller_the_unconfigured_controllers_are_not_waited_for():
    """The demo (initial_controller ''): the velocity controllers are configured only after the self-test, so
    t_0 waits for the navigator and the self-test on the velocity and the manager on the applied pitch
    (config/mission.yaml spelled these, before the harness's probe and recorder)."""
    plan = roster(shipped("hierarchy.launch.yaml", initial_controller="''"))
    assert awaited(plan) == Counter({V: 2, A: 1, IMU: 1, DEPTH: 1, POS: 1, MANIFEST: 1, ALT: 1})
    assert plan.answerers == ("self_test",)


def test_the_demo_harness_adds_its_probe_and_recorder():
    """mission.yaml's hand count (probe and recorder on the truth and altitude, the probe on the applied pitch,
    3 command subscribers), plus what the recorder now hears typed from the start (issue 43)."""
    from seapup_bringup.graph.mission_graph import RECORDED
    from seapup_bringup.graph.sil import INSTRUMENTS, TOPICS
    probe = Listener("probe", tuple(t for name, (t, _) in TOPICS.items() if name not in INSTRUMENTS))
    plan = roster(shipped("hierarchy.launch.yaml", initial_controller="''"),
                  [probe, Listener.recorder("recorder", RECORDED)])
    counts = awaited(plan)
    assert {t: counts[t] for t in (V, A, IMU, DEPTH, POS, MANIFEST, ALT, TRUTH)} == \
        {V: 3, A: 3, IMU: 2, DEPTH: 2, POS: 2, MANIFEST: 1, ALT: 3, TRUTH: 2}
    assert plan.settings["controller_manager"] == {"wait_for_command_subscribers": 3}
    assert plan.settings["self_test"] == {"wait_for_command_subscribers": 3, "wait_for_sample_subscribers": 1}


@pytest.mark.parametrize("name, expected, commands", [
    ("identification.launch.yaml", {V: 1, IMU: 1, A: 1}, {"open_loop": {"wait_for_command_subscribers": 1}}),
    ("identification_closed_loop.launch.yaml", {V: 2, IMU: 1, A: 2},
     {"velocity_controller": {"wait_for_command_subscribers": 1}, "reference_schedule": {"wait_for_reference_subscribers": 1}}),
    ("self_test.launch.yaml", {V: 1},
     {"self_test": {"wait_for_command_subscribers": 1, "wait_for_sample_subscribers": 0}}),
    ("simulator_controller.launch.yaml", {V: 1, A: 1}, {"velocity_controller": {"wait_for_command_subscribers": 1}}),
    ("simulator.launch.yaml", {}, {}),
])
def test_each_shipped_graph_waits_for_what_it_spelled(name, expected, commands):
    """identification: the identifier (velocity, IMU, applied pitch); closed loop: and the controller
    (velocity, applied pitch); the self-test graph: its velocity; simulator_controller: the controller's
    velocity and applied pitch; the first command for the simulator (command_subscribers '1'), the first
    reference for the controller (reference_schedule.yaml's 1)."""
    plan = roster(shipped(name))
    assert awaited(plan) == Counter(expected)
    assert {k: v for k, v in plan.settings.items() if k != "simulator"} == commands


# -- generated run graphs: seapup_runs.run_graph's former formulas ---------------------------------------
def _run_spec(controllers: int):
    from seapup_common.controllers import ControllerSpec
    from seapup_runs.spec import RunEvent, RunSpec
    events = tuple(RunEvent(2.0 * i, "controller", ControllerSpec("hold")) for i in range(1, controllers))
    return RunSpec(controller=ControllerSpec("hold"), events=events, duration=6.0)


@pytest.mark.parametrize("controllers", [1, 2])
@pytest.mark.parametrize("listeners", [0, 1])
def test_run_graphs_wait_as_the_former_formulas(controllers, listeners):
    from seapup_runs.run_graph import LISTENED_TOPICS, graph_document
    document = yaml.safe_load(yaml.safe_dump(graph_document(_run_spec(controllers), [""] * controllers)))
    extra = [Listener(f"listener {i}", tuple(LISTENED_TOPICS)) for i in range(listeners)]
    plan = roster(nodes_of_document(document), extra)
    simulator_topics = [V, A] * controllers + [TRUTH, V, IMU, DEPTH, POS, ALT, A] * listeners
    assert awaited(plan) == Counter(simulator_topics)
    for i in range(controllers):
        assert plan.settings[f"controller_{i}"] == {"wait_for_command_subscribers": 1 + listeners}
    assert plan.settings["reference_schedule"] == {"wait_for_reference_subscribers": controllers + listeners}
    assert plan.count(COMMAND) == 1 + listeners


# -- names, fill, errors ----------------------------------------------------------------------------
BOOK = {"simulator": Role(samples=("sensors/velocity", "thrusters/applied"), sample_gate="wait_for_subscribers",
                          listens=("thrusters/command",)),
        "law": Role(hears=("sensors/velocity",), answers=True, gates={"wait_for_command_subscribers": "thrusters/command"})}


def book(package, executable):
    return BOOK.get(executable)


def test_a_remapping_is_followed():
    """A controller whose command is remapped away from the simulator's topic is heard by nobody; one whose
    velocity is remapped to a topic the simulator does not publish is refused."""
    nodes = [NodeSpec("p", "simulator"), NodeSpec("p", "law", name="a"),
             NodeSpec("p", "law", name="b", remappings={"thrusters/command": "/seapup/b/thrusters/command"})]
    plan = roster(nodes, roles=book)
    assert plan.settings["a"] == {"wait_for_command_subscribers": 1} and plan.settings["b"] == {"wait_for_command_subscribers": 0}
    assert plan.settings["simulator"] == {"wait_for_subscribers": [V, V]}
    moved = NodeSpec("p", "law", name="c", remappings={"sensors/velocity": "/seapup/other/velocity"})
    with pytest.raises(NotPublishedError, match="node c .* must hear /seapup/other/velocity"):
        roster([nodes[0], moved], roles=book)
    assert resolve("sensors/velocity", "/ns") == "/ns/sensors/velocity"
    assert resolve("/seapup/sensors/velocity", "", {"/seapup/sensors/velocity": "x"}) == "/seapup/x"


def test_an_executable_without_a_role_is_refused():
    with pytest.raises(UnknownRoleError, match="node stranger: p declares no lockstep role for the executable"):
        roster([NodeSpec("p", "simulator"), NodeSpec("p", "stranger")], roles=book)
    with pytest.raises(UnknownRoleError, match="seapup_control declares no lockstep role"):
        roster([NodeSpec("seapup_control", "no_such_node")])


def test_fill_keeps_what_the_document_gives_and_adds_the_rest():
    nodes = [NodeSpec("p", "simulator", parameters=[{"wait_for_subscribers": ["/seapup/sensors/velocity"] * 5}]),
             NodeSpec("p", "law", parameters=[{"lockstep": True}])]
    plan = roster(nodes, [Listener("probe", (V, COMMAND, "/diagnostics"))], roles=book)
    simulator, law = fill(nodes, plan)
    assert simulator.parameters == nodes[0].parameters   # given by hand: kept
    assert law.parameters == [{"lockstep": True}, {"wait_for_command_subscribers": 2}]
    assert plan.listeners == {V: ("law", "probe"), COMMAND: ("simulator", "probe")}


def test_role_files_are_checked():
    with pytest.raises(RoleFileError, match="unknown key 'heard'"):
        parse_roles({"x": {"heard": ["a"]}})
    with pytest.raises(RoleFileError, match="like names another executable"):
        parse_roles({"x": {"like": "y"}})
    with pytest.raises(RoleFileError, match="samples and sample_gate go together"):
        parse_roles({"x": {"samples": ["a"]}})
    with pytest.raises(RoleFileError, match="hears: a list of topic names"):
        parse_roles({"x": {"hears": "sensors/velocity"}})
    control = package_roles(Path(installed("seapup_control")) / "config")
    assert control["mfol_velocity_controller"] == control["velocity_controller"]
    assert control["velocity_controller"].defaults["autostart"] is False   # from config/velocity_controller.yaml


def test_a_recorder_in_the_document_counts_its_typed_topics():
    nodes = [*shipped("self_test.launch.yaml"),
             NodeSpec("seapup_common", "recorder", parameters=[{"topics": topics.typed(V, COMMAND) + [IMU]}])]
    plan = roster(nodes)
    assert awaited(plan) == Counter({V: 2})
    assert plan.settings["self_test"]["wait_for_command_subscribers"] == 2
