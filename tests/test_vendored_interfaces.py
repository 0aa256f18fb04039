"""The vendored ROS interface packages (vendor/ros/) are the upstream definitions: same files, same type hash.

``tf2_msgs`` is checked against rosbags' Jazzy type store. ``simulation_interfaces`` (absent from that store) is
checked against its upstream repository twice over: every vendored file against the checksum manifest written
from the upstream commit (``vendor/ros/simulation_interfaces.sha256``), and every type's RIHS01 hash compiled into
the built library against the hash rosbags computes from the definition text, with the implicit service and action
types put together as REP 2011 describes them. Then its constants import and a service and an action of it make a
round trip through rclpy and through ``./seapup service call`` / ``./seapup action send_goal``.
"""
import ctypes
import hashlib
import importlib
import json
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from ament_index_python.packages import get_package_prefix, get_package_share_directory
from rosbags.typesys import Stores, get_typestore, get_types_from_msg
from rosbags.typesys.base import Nodetype

ROOT = Path(__file__).resolve().parents[1]
VENDOR = ROOT / "vendor" / "ros"
VENDORED = sorted(p.name for p in VENDOR.iterdir() if (p / "package.xml").is_file())
SI = "simulation_interfaces"
SI_DIR = VENDOR / SI
MANIFEST = VENDOR / f"{SI}.sha256"
UPSTREAM_COMMIT = "a3c60ff2715dbe5e9d5cddce410d9a7ffe771960"  # tag 1.5.1, the jazzy branch's newest release


def _messages(package: str) -> list[str]:
    return sorted(p.stem for p in (VENDOR / package / "msg").glob("*.msg"))


@pytest.mark.parametrize("package", VENDORED)
def test_each_vendored_message_has_the_type_hash_of_ros_2_jazzy(package):
    """The installed description (generated from the vendored .msg, or the system's where one exists) must
    agree with the independent hash, else a bag or a viewer would see another type: rosbags' Jazzy type store
    where it has the package (definitions taken from the ROS 2 Jazzy release), else rosbags' hash of the
    upstream text."""
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    truth = jazzy if f"{package}/msg/{_messages(package)[0]}" in jazzy.fielddefs else _upstream_store()
    share = Path(get_package_share_directory(package))
    assert _messages(package)
    for name in _messages(package):
        described = json.loads((share / "msg" / f"{name}.json").read_text())
        ours = next(h["hash_string"] for h in described["type_hashes"] if h["type_name"] == f"{package}/msg/{name}")
        assert ours == truth.hash_rihs01(f"{package}/msg/{name}")
        assert importlib.import_module(f"{package}.msg")   # and it imports (its type support is built)


# -- simulation_interfaces: the files are upstream's ------------------------------------------------------------------
def _manifest() -> dict[str, str]:
    """``{path: sha256}`` of the manifest (``sha256sum`` lines, ``#`` comments)."""
    lines = [line for line in MANIFEST.read_text().splitlines() if line and not line.startswith("#")]
    return {path: digest for digest, path in (line.split("  ", 1) for line in lines)}


def test_the_manifest_names_the_upstream_commit_the_readme_and_tests_name():
    assert f"commit {UPSTREAM_COMMIT}" in MANIFEST.read_text()
    assert UPSTREAM_COMMIT in (VENDOR / "README.md").read_text()


def test_the_vendored_files_are_the_upstream_files_byte_for_byte():
    """Every file of vendor/ros/simulation_interfaces/ is in the manifest with its upstream checksum, and every
    interface upstream's CMakeLists.txt generates is there (nothing added, dropped or edited)."""
    manifest = _manifest()
    present = {p.relative_to(SI_DIR).as_posix() for p in SI_DIR.rglob("*") if p.is_file()}
    assert present == set(manifest)
    for path, digest in manifest.items():
        assert hashlib.sha256((SI_DIR / path).read_bytes()).hexdigest() == digest, path
    listed = {line.strip().strip('"') for line in (SI_DIR / "CMakeLists.txt").read_text().splitlines()
              if line.strip().startswith(('"msg/', '"srv/', '"action/'))}
    assert listed == {p for p in manifest if p.split("/")[0] in ("msg", "srv", "action")}


# -- simulation_interfaces: the type hashes are those of the upstream text ------------------------------------------
def _parts(path: Path) -> list[str]:
    """The sections of a .srv or .action file (split at the ``---`` lines)."""
    parts, current = [], []
    for line in path.read_text().splitlines():
        if line.strip() == "---":
            parts.append("\n".join(current))
            current = []
        else:
            current.append(line)
    return parts + ["\n".join(current)]


def _name(typ: str) -> tuple:
    return (Nodetype.NAME, typ)


def _service_types(name: str, request: list, response: list) -> dict:
    """The implicit types of service ``name`` (REP 2011): ``_Request``, ``_Response``, ``_Event`` and the
    service itself, whose fields are its three messages."""
    return {
        f"{name}_Request": ([], request), f"{name}_Response": ([], response),
        f"{name}_Event": ([], [("info", _name("service_msgs/msg/ServiceEventInfo")),
                               ("request", (Nodetype.SEQUENCE, (_name(f"{name}_Request"), 1))),
                               ("response", (Nodetype.SEQUENCE, (_name(f"{name}_Response"), 1)))]),
        name: ([], [("request_message", _name(f"{name}_Request")),
                    ("response_message", _name(f"{name}_Response")),
                    ("event_message", _name(f"{name}_Event"))]),
    }


def _fields(text: str) -> list:
    """The fields rosbags parses from one section of a .srv or .action (read as a message of package
    ``simulation_interfaces``, so its relative type names resolve into that package's msg/)."""
    return get_types_from_msg(text, f"{SI}/msg/_Section")[f"{SI}/msg/_Section"][1]


def _action_types(name: str, goal: list, result: list, feedback: list) -> dict:
    """The implicit types of action ``name`` (REP 2011; rosidl's action.idl): goal, result, feedback, the
    SendGoal and GetResult services, the feedback message, and the action whose fields are those six."""
    uuid, time = _name("unique_identifier_msgs/msg/UUID"), _name("builtin_interfaces/msg/Time")
    types = {f"{name}_Goal": ([], goal), f"{name}_Result": ([], result), f"{name}_Feedback": ([], feedback),
             f"{name}_FeedbackMessage": ([], [("goal_id", uuid), ("feedback", _name(f"{name}_Feedback"))])}
    types |= _service_types(f"{name}_SendGoal", [("goal_id", uuid), ("goal", _name(f"{name}_Goal"))],
                            [("accepted", (Nodetype.BASE, ("bool", 0))), ("stamp", time)])
    types |= _service_types(f"{name}_GetResult", [("goal_id", uuid)],
                            [("status", (Nodetype.BASE, ("int8", 0))), ("result", _name(f"{name}_Result"))])
    types[name] = ([], [("goal", _name(f"{name}_Goal")), ("result", _name(f"{name}_Result")),
                        ("feedback", _name(f"{name}_Feedback")),
                        ("send_goal_service", _name(f"{name}_SendGoal")),
                        ("get_result_service", _name(f"{name}_GetResult")),
                        ("feedback_message", _name(f"{name}_FeedbackMessage"))])
    return types


_STORE = []


def _jazzy_store_as_rosidl_reads_it():
    """rosbags' Jazzy type store with msg ``char`` read as rosidl reads it.

    rosidl maps a .msg ``char`` to IDL ``uint8`` (the ROS 2 field type table; Jazzy's installed
    ``service_msgs/msg/ServiceEventInfo.json`` gives ``char[16] client_gid`` the type id of a uint8 array), rosbags
    to the IDL ``char``. Of the types used here only ServiceEventInfo, inside every service's ``_Event``, has one.
    """
    store = get_typestore(Stores.ROS2_JAZZY)
    store.fielddefs = dict(store.fielddefs)
    name = "service_msgs/msg/ServiceEventInfo"
    constants, fields = store.fielddefs[name]
    char = (Nodetype.BASE, ("char", 0))
    store.fielddefs[name] = (constants, [
        (field, (Nodetype.ARRAY, ((Nodetype.BASE, ("uint8", 0)), desc[1][1])) if desc[0] == Nodetype.ARRAY
         and desc[1][0] == char else desc) for field, desc in fields])
    assert store.fielddefs[name] != (constants, fields)
    return store


def _upstream_store():
    """rosbags' Jazzy store plus every simulation_interfaces type built from the vendored (= upstream) text."""
    if not _STORE:
        store = _jazzy_store_as_rosidl_reads_it()
        for path in sorted((SI_DIR / "msg").glob("*.msg")):
            store.register(get_types_from_msg(path.read_text(), f"{SI}/msg/{path.stem}"))
        for path in sorted((SI_DIR / "srv").glob("*.srv")):
            request, response = (_fields(text) for text in _parts(path))
            store.register(_service_types(f"{SI}/srv/{path.stem}", request, response))
        for path in sorted((SI_DIR / "action").glob("*.action")):
            store.register(_action_types(f"{SI}/action/{path.stem}",
                                         *(_fields(text) for text in _parts(path))))
        _STORE.append(store)
    return _STORE[0]


def _all_si_types() -> list[str]:
    return sorted(t for t in _upstream_store().fielddefs if t.startswith(f"{SI}/"))


class _TypeHash(ctypes.Structure):
    _fields_ = [("version", ctypes.c_uint8), ("value", ctypes.c_uint8 * 32)]


def _compiled_hash(library: ctypes.CDLL, typ: str) -> str:
    """The hash the type support reports at runtime: ``<pkg>__<kind>__<Type>__get_type_hash`` of the generated
    C library (what rcl puts on the graph and into a bag's metadata)."""
    function = getattr(library, typ.replace("/", "__") + "__get_type_hash")
    function.restype = ctypes.POINTER(_TypeHash)
    function.argtypes = [ctypes.c_void_p]
    found = function(None).contents
    return f"RIHS{found.version:02d}_{bytes(found.value).hex()}"


def test_every_simulation_interfaces_type_hash_at_runtime_is_the_upstream_texts():
    """15 messages; 22 services of 4 types each (the service, request, response, event); the action of 13 (the
    action, goal, result, feedback, feedback message, and two services of 4): 116 types."""
    library = ctypes.CDLL(str(Path(get_package_prefix(SI)) / "lib" / f"lib{SI}__rosidl_generator_c.so"))
    store = _upstream_store()
    types = _all_si_types()
    assert len(types) == 15 + 22 * 4 + 1 * (5 + 2 * 4)
    mismatched = {t: (_compiled_hash(library, t), store.hash_rihs01(t)) for t in types
                  if _compiled_hash(library, t) != store.hash_rihs01(t)}
    assert not mismatched


def test_the_installed_descriptions_carry_the_same_hashes():
    """The type description JSON installed beside each interface (read by tools) agrees too."""
    share, store = Path(get_package_share_directory(SI)), _upstream_store()
    for path in sorted(p.relative_to(SI_DIR) for p in SI_DIR.glob("*/*") if p.suffix in (".msg", ".srv", ".action")):
        described = json.loads((share / path.with_suffix(".json")).read_text())
        for entry in described["type_hashes"]:
            assert entry["hash_string"] == store.hash_rihs01(entry["type_name"]), entry["type_name"]


def test_a_publisher_announces_the_upstream_hash_on_the_graph(ros_context, spin):
    """What other processes see: the endpoint's type hash as rclpy reports it."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from simulation_interfaces.msg import SimulationState
    node = rclpy.create_node("si_hash_probe", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    node.create_publisher(SimulationState, "/si_test/state", 1)
    assert spin(executor, lambda: node.get_publishers_info_by_topic("/si_test/state"), 10.0)
    announced = node.get_publishers_info_by_topic("/si_test/state")[0].topic_type_hash
    assert f"RIHS{announced.version:02d}_{announced.value.hex()}" == \
        _upstream_store().hash_rihs01(f"{SI}/msg/SimulationState")
    executor.shutdown()


# -- simulation_interfaces: constants, a service and an action over rclpy --------------------------------------------
@pytest.mark.parametrize("message", ["SimulationState", "Result"])
def test_the_constants_import_with_their_upstream_values(message):
    from simulation_interfaces import msg
    constants = get_types_from_msg((SI_DIR / "msg" / f"{message}.msg").read_text(), f"{SI}/msg/{message}")
    expected = {name: value for name, _, value in constants[f"{SI}/msg/{message}"][0]}
    assert expected  # STATE_STOPPED..STATE_LOADING_WORLD; RESULT_FEATURE_UNSUPPORTED..RESULT_OPERATION_FAILED
    assert {name: getattr(getattr(msg, message), name) for name in expected} == expected


def test_the_named_simulation_states_are_those_seapup_uses():
    from simulation_interfaces.msg import Result, SimulationState
    assert (SimulationState.STATE_STOPPED, SimulationState.STATE_PLAYING, SimulationState.STATE_PAUSED,
            SimulationState.STATE_QUITTING) == (0, 1, 2, 3)
    assert (Result.RESULT_FEATURE_UNSUPPORTED, Result.RESULT_OK, Result.RESULT_NOT_FOUND,
            Result.RESULT_INCORRECT_STATE, Result.RESULT_OPERATION_FAILED) == (0, 1, 2, 3, 4)


def _step_server(node, stepped: list):
    """A StepSimulation server that records the steps asked for and answers RESULT_OK."""
    from simulation_interfaces.msg import Result
    from simulation_interfaces.srv import StepSimulation

    def step(request, response):
        stepped.append(request.steps)
        response.result = Result(result=Result.RESULT_OK, error_message=f"stepped {request.steps}")
        return response
    return node.create_service(StepSimulation, "/si_test/step_simulation", step)


def _simulate_steps_server(node):
    """A SimulateSteps server: feedback after each step, then RESULT_OK."""
    from rclpy.action import ActionServer, CancelResponse
    from simulation_interfaces.action import SimulateSteps
    from simulation_interfaces.msg import Result

    async def execute(goal_handle):
        steps = goal_handle.request.steps
        for done in range(1, steps + 1):
            goal_handle.publish_feedback(SimulateSteps.Feedback(completed_steps=done, remaining_steps=steps - done))
        goal_handle.succeed()
        return SimulateSteps.Result(result=Result(result=Result.RESULT_OK))
    return ActionServer(node, SimulateSteps, "/si_test/simulate_steps", execute_callback=execute,
                        cancel_callback=lambda _: CancelResponse.ACCEPT)


def test_step_simulation_service_round_trip(ros_context, spin):
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from simulation_interfaces.msg import Result
    from simulation_interfaces.srv import StepSimulation
    server_node = rclpy.create_node("si_step_server", context=ros_context)
    client_node = rclpy.create_node("si_step_client", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(server_node)
    executor.add_node(client_node)
    stepped = []
    _step_server(server_node, stepped)
    client = client_node.create_client(StepSimulation, "/si_test/step_simulation")
    assert spin(executor, client.service_is_ready, 10.0)
    assert StepSimulation.Request().steps == 1  # upstream's default ("uint64 steps 1")
    future = client.call_async(StepSimulation.Request(steps=7))
    assert spin(executor, future.done, 10.0)
    assert future.result().result.result == Result.RESULT_OK
    assert future.result().result.error_message == "stepped 7" and stepped == [7]
    executor.shutdown()


def test_simulate_steps_action_round_trip(ros_context, spin):
    import rclpy
    from rclpy.action import ActionClient
    from rclpy.executors import SingleThreadedExecutor
    from simulation_interfaces.action import SimulateSteps
    from simulation_interfaces.msg import Result
    server_node = rclpy.create_node("si_steps_server", context=ros_context)
    client_node = rclpy.create_node("si_steps_client", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(server_node)
    executor.add_node(client_node)
    _simulate_steps_server(server_node)
    client = ActionClient(client_node, SimulateSteps, "/si_test/simulate_steps")
    assert spin(executor, client.server_is_ready, 10.0)
    # feedback is a volatile topic: lost until the client's feedback subscription has matched
    assert spin(executor, lambda: server_node.count_subscribers("/si_test/simulate_steps/_action/feedback") > 0,
                10.0)
    feedback = []
    send = client.send_goal_async(SimulateSteps.Goal(steps=3), feedback_callback=lambda m: feedback.append(m.feedback))
    assert spin(executor, send.done, 10.0) and send.result().accepted
    assert spin(executor, lambda: len(feedback) == 3, 10.0)  # rclpy drops feedback arriving after the result
    result = send.result().get_result_async()
    assert spin(executor, result.done, 10.0)
    assert result.result().result.result.result == Result.RESULT_OK
    assert [(f.completed_steps, f.remaining_steps) for f in feedback] == [(1, 2), (2, 1), (3, 0)]
    executor.shutdown()


# -- simulation_interfaces: the ros2cli substitute resolves the types -------------------------------------------------
def _cli(env, *args):
    return subprocess.run([sys.executable, "-m", "seapup_bringup.cli", *args], env=env, capture_output=True,
                          text=True, timeout=120)


@pytest.mark.process
def test_interface_show_prints_step_simulation():
    out = _cli(None, "interface", "show", f"{SI}/srv/StepSimulation")
    assert out.returncode == 0, out.stderr
    request, response = out.stdout.split("\n---\n")
    assert request.strip() == "uint64 steps"
    assert response.splitlines()[0] == "simulation_interfaces/Result result"
    assert "\tuint8 RESULT_OK=1" in response.splitlines() and response.splitlines()[-1] == "\tstring error_message"


def _serving(ros_context, start):
    """Run ``start(node)``'s server on a thread that spins until the returned event is set."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    node = rclpy.create_node("si_cli_server", context=ros_context)
    start(node)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    stop = threading.Event()

    def run():
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.05)
        executor.shutdown()
    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return stop, thread


def test_seapup_service_call_and_action_send_goal_resolve_simulation_interfaces(ros_context, ros_env):
    stepped = []
    stop, thread = _serving(ros_context, lambda node: (_step_server(node, stepped), _simulate_steps_server(node)))
    try:
        called = _cli(ros_env, "service", "call", "/si_test/step_simulation", f"{SI}/srv/StepSimulation",
                      "{steps: 4}", "--json")
        sent = _cli(ros_env, "action", "send_goal", "/si_test/simulate_steps", f"{SI}/action/SimulateSteps",
                    "{steps: 2}", "--json", "--result-timeout", "30")
    finally:
        stop.set()
        thread.join(10.0)
    assert called.returncode == 0, called.stderr
    assert json.loads(called.stdout)["response"]["result"] == {"result": 1, "error_message": "stepped 4"}
    assert stepped == [4]
    assert sent.returncode == 0, sent.stderr
    answer = json.loads(sent.stdout)
    assert answer["status"] == "succeeded" and answer["result"]["result"]["result"] == 1
