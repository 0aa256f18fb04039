"""./seapup launch through real processes: graphs start, stop cleanly, end on a required node's death,
respawn up to their limit, and the shipped graphs fly the simulator."""
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time

import pytest
import yaml

from seapup_bringup.ros2cli.launch import LaunchError, load_graph


class Launched:
    """A ``./seapup launch`` process whose stdout is read by a thread (to search it while it runs)."""

    def __init__(self, env, *args):
        self.proc = subprocess.Popen([sys.executable, "-m", "seapup_bringup.cli", "launch", *args], env=env,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                     start_new_session=True)
        self.lines: list[str] = []
        self.reader = threading.Thread(target=lambda: self.lines.extend(iter(self.proc.stdout.readline, "")),
                                       daemon=True)
        self.reader.start()
        self.pid = self.proc.pid

    @property
    def stdout(self) -> str:
        return "".join(self.lines)

    def wait_for(self, pattern, timeout=60.0):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            match = re.search(pattern, self.stdout)
            if match:
                return match
            if self.proc.poll() is not None and not self.reader.is_alive():
                break
            time.sleep(0.05)
        raise AssertionError(f"{pattern!r} not seen in:\n{self.stdout}")

    def finish(self, timeout=60.0):
        """Wait for the exit; (stdout, stderr)."""
        self.proc.wait(timeout)
        self.reader.join(5.0)
        return self.stdout, self.proc.stderr.read()

    @property
    def returncode(self):
        return self.proc.returncode


def alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as f:
        return f.read().split()[2] != "Z"


def graph(tmp_path, nodes, arguments=None):
    """A ROS 2 YAML launch file of ``nodes`` (their ``node:`` bodies) and ``arguments`` (name: default)."""
    path = tmp_path / "graph.launch.yaml"
    entries = [{"arg": {"name": k, "default": str(v)}} for k, v in (arguments or {}).items()]
    path.write_text(yaml.safe_dump({"launch": entries + [{"node": n} for n in nodes]}, sort_keys=False))
    return str(path)


def test_arguments_are_substituted_and_checked(tmp_path):
    path = graph(tmp_path, [{"pkg": "seapup_sim", "exec": "simulator", "param": [
        {"name": "real_time_factor", "value": "$(var rtf)"},
        {"name": "environment", "param": [{"name": "sensors", "value": "ideal"}]},
        {"name": "wait_for_subscribers", "value": "$(var topics)"}]},
        {"pkg": "seapup_live_view", "exec": "live_view", "if": "$(var view)"}],
        {"rtf": 2.0, "topics": "[/a, /b]", "view": "false"})
    (spec,) = load_graph(path, {"rtf": "3.5"})   # the view's condition is false: left out
    assert spec.parameters == [{"real_time_factor": 3.5, "environment.sensors": "ideal",   # typed after substitution
                                "wait_for_subscribers": ["/a", "/b"]}]
    assert [s.executable for s in load_graph(path, {"view": "True"})] == ["simulator", "live_view"]
    with pytest.raises(LaunchError, match="unknown argument 'rate'"):
        load_graph(path, {"rate": "1"})
    with pytest.raises(LaunchError, match="condition must be true or false"):
        load_graph(path, {"view": "maybe"})
    bad = tmp_path / "bad.launch.yaml"
    for text, error in [("launch:\n  - node: {pkg: seapup_sim, exec: simulator, colour: red}\n", "unknown key 'colour'"),
                        ("launch:\n  - include: {file: x.launch.yaml}\n", "'include' is not supported"),
                        ("launch:\n  - node: {pkg: seapup_sim, exec: $(eval 1+1)}\n", "not supported here"),
                        ("launch:\n  - node: {pkg: seapup_sim, exec: $(var nope)}\n", "not declared"),
                        ("nodes: []\n", "one mapping 'launch:'")]:
        bad.write_text(text)
        with pytest.raises(LaunchError, match=error):
            load_graph(bad)


@pytest.mark.parametrize("key, value, reason", [
    ("respawn_delay", ".nan", "respawn_delay must be a number of seconds in [0, 3600], got nan"),
    ("respawn_delay", ".inf", "respawn_delay must be a number of seconds in [0, 3600], got inf"),
    ("respawn_delay", "-0.5", "respawn_delay must be a number of seconds in [0, 3600], got -0.5"),
    ("respawn_delay", "1.0e+9", "respawn_delay must be a number of seconds in [0, 3600], got 1000000000.0"),
    ("respawn_delay", "soon", "respawn_delay must be a number of seconds in [0, 3600], got 'soon'"),
    ("respawn_delay", "true", "respawn_delay must be a number of seconds in [0, 3600], got True"),
    ("respawn_max_retries", "2.5", "respawn_max_retries must be an integer >= -1 (-1: no limit), got 2.5"),
    ("respawn_max_retries", ".nan", "respawn_max_retries must be an integer >= -1 (-1: no limit), got nan"),
    ("respawn_max_retries", "true", "respawn_max_retries must be an integer >= -1 (-1: no limit), got True"),
    ("respawn_max_retries", "-2", "respawn_max_retries must be an integer >= -1 (-1: no limit), got -2"),
])
def test_a_numeric_launch_attribute_out_of_range_is_refused_naming_the_file_and_node(tmp_path, key, value, reason):
    """Issue 40: ``respawn_delay: .nan`` was accepted, and the launcher then neither restarted the node
    nor ended. Every numeric attribute is finite and in its range, refused in one line naming file and node."""
    path = tmp_path / "g.launch.yaml"
    path.write_text(f"launch:\n  - node: {{pkg: seapup_sim, exec: simulator, name: sim, respawn: 'true', "
                    f"{key}: {value}}}\n")
    with pytest.raises(LaunchError) as refused:
        load_graph(path)
    assert str(refused.value) == f"{path}: node sim: {reason}"


def test_numeric_launch_attributes_in_range_are_read_as_numbers(tmp_path):
    path = tmp_path / "g.launch.yaml"
    path.write_text("launch:\n  - arg: {name: d, default: '0.25'}\n  - node: {pkg: seapup_sim, exec: simulator, "
                    "respawn: 'true', respawn_delay: $(var d), respawn_max_retries: 3.0}\n")
    (spec,) = load_graph(path)
    assert (spec.respawn_delay, spec.respawn_limit) == (0.25, 3) and isinstance(spec.respawn_limit, int)
    (spec,) = load_graph(path, {"d": "3600"})
    assert spec.respawn_delay == 3600.0


def test_a_launch_file_is_read_bounded_and_strictly(tmp_path):
    """Read through seapup_common.input_files: a duplicated key (PyYAML kept the last one silently) and an
    oversized file are refused in one line, before anything is started."""
    path = tmp_path / "g.launch.yaml"
    path.write_text("launch:\n  - node: {pkg: seapup_sim, exec: simulator, exec: controller}\n")
    with pytest.raises(LaunchError, match=r"duplicate key 'exec'"):
        load_graph(path)
    path.write_text("launch: []\n" + "#" * (1 << 20))
    with pytest.raises(LaunchError, match="larger than 1 MiB, the limit for a launch file"):
        load_graph(path)
    path.write_text("")
    with pytest.raises(LaunchError, match="is empty"):
        load_graph(path)


@pytest.mark.process
def test_launch_stop_grace_is_checked(tmp_path):
    """``--stop-grace nan`` (or negative) is refused before anything starts."""
    for value in ("nan", "-1", "1e9"):
        done = subprocess.run([sys.executable, "-m", "seapup_bringup.cli", "launch", "--stop-grace", value,
                               "seapup_bringup", "simulator.launch.yaml"], capture_output=True, text=True, timeout=60)
        assert done.returncode == 2 and "--stop-grace must be a number of seconds in [0, 60]" in done.stderr, done
        assert "Traceback" not in done.stderr and "started" not in done.stdout


def test_a_required_node_that_dies_stops_the_graph_and_is_named(tmp_path, ros_env):
    path = graph(tmp_path, [
        {"pkg": "seapup_sim", "exec": "simulator", "on_exit": "shutdown",
         "param": [{"name": "mode", "value": "realtime"}, {"name": "real_time_factor", "value": 1.0}]},
        {"pkg": "seapup_control", "exec": "open_loop", "name": "helper",
         "param": [{"name": "lockstep", "value": False}]}])
    proc = Launched(ros_env, path, "--json")
    sim = int(proc.wait_for(r"started simulator \(pid (\d+)\)").group(1))
    helper = int(proc.wait_for(r"started helper \(pid (\d+)\)").group(1))
    proc.wait_for(r"\[simulator\] .*simulator ready")
    os.kill(sim, signal.SIGKILL)
    stdout, stderr = proc.finish()
    assert proc.returncode == 1 and "required node simulator exited with -9" in stderr
    assert not alive(helper)  # the rest were stopped
    result = json.loads(stdout[stdout.index("{\n \"graph\""):])
    assert result["exit"] == 1 and [n["name"] for n in result["nodes"]] == ["simulator", "helper"]


def test_respawn_up_to_its_limit(tmp_path, ros_env):
    # a node that cannot start (an invalid mode) exits 1 at once: started 1 + 2 times, then the launch ends
    path = graph(tmp_path, [{"pkg": "seapup_sim", "exec": "simulator", "respawn": "true", "respawn_max_retries": 2,
                             "respawn_delay": 0.2, "param": [{"name": "mode", "value": "bogus"}]}])
    proc = Launched(ros_env, path, "--json")
    stdout, _ = proc.finish(120)
    assert proc.returncode == 1
    assert stdout.count("started simulator") == 3 and "respawn 2 of 2" in stdout
    result = json.loads(stdout[stdout.index('{\n "graph"'):])
    assert result["nodes"][0]["starts"] == 3 and result["nodes"][0]["exit"] == 1


def test_sigterm_stops_every_node_cleanly(tmp_path, ros_env):
    proc = Launched(ros_env, "seapup_bringup", "simulator.launch.yaml", "real_time_factor:=2.0")
    sim = int(proc.wait_for(r"started simulator \(pid (\d+)\)").group(1))
    proc.wait_for(r"simulator ready")
    os.kill(proc.pid, signal.SIGTERM)
    proc.finish(30)
    assert proc.returncode == 0 and not alive(sim)


@pytest.mark.parametrize("mode", ["lockstep", "realtime"])
def test_shipped_controller_graph_flies_the_simulator_in_either_mode(tmp_path, ros_env, mode):
    """One argument, ``mode``: in lockstep the simulator advances only because the controller answers
    every sample; in realtime (the default) the controller's commands carry the simulator's sample
    stamps, so the simulator takes them (wall-clock stamps were refused as "from the future" and the
    vehicle never flew) and the vehicle follows a surge reference."""
    from seapup_runs.self_test_flight import fly_self_test
    from seapup_control.self_test import result_document
    controller = tmp_path / "controller.yaml"
    controller.write_text(yaml.safe_dump(result_document(fly_self_test("baseline", {}).test), sort_keys=False))
    proc = Launched(ros_env, "seapup_bringup", "simulator_controller.launch.yaml", f"controller_file:={controller}",
                    f"mode:={mode}", "sensors:=ideal", "real_time_factor:=5.0")
    cli = [sys.executable, "-m", "seapup_bringup.cli"]
    publisher = None
    try:
        proc.wait_for(r"starting from the applied blade pitch")
        if mode == "realtime":
            publisher = subprocess.Popen([*cli, "topic", "pub", "/seapup/velocity_controller/reference",
                                          "geometry_msgs/msg/TwistStamped", "{twist: {linear: {x: 0.3}}}", "-r", "5"],
                                         env=ros_env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                         start_new_session=True)
            time.sleep(12.0)  # 60 s simulated at 5x: the surge settles
            echo = subprocess.run([*cli, "topic", "echo", "/seapup/truth/odometry", "--count", "5",
                                   "--field", "twist.twist.linear.x", "--csv"], env=ros_env,
                                  capture_output=True, text=True, timeout=60)
            speeds = [float(x) for x in echo.stdout.split()]
            assert len(speeds) == 5 and all(abs(u - 0.3) < 0.05 for u in speeds), echo.stdout + echo.stderr
        else:
            echo = subprocess.run([*cli, "topic", "echo", "/seapup/thrusters/command", "--count", "20",
                                   "--field", "header.stamp.sec", "--csv"], env=ros_env,
                                  capture_output=True, text=True, timeout=60)
            seconds = [int(x) for x in echo.stdout.split()]
            assert len(seconds) == 20 and seconds[-1] >= seconds[0]
    finally:
        if publisher is not None:
            os.killpg(publisher.pid, signal.SIGINT)
            publisher.wait(30)
        os.kill(proc.pid, signal.SIGINT)
        proc.finish(30)
    assert proc.returncode == 0


#: ROS 2 Jazzy's YAML launch format, as its frontends read it (launch: the arg action; launch_ros: the node
#: action's attributes; the substitutions by name), written out here independently of the reader under test.
ARG_KEYS = {"name", "default", "description"}
NODE_KEYS = {"pkg", "exec", "name", "namespace", "ros_args", "args", "param", "remap", "output", "respawn",
             "respawn_delay", "respawn_max_retries", "on_exit", "if", "unless", "launch-prefix", "emulate_tty"}
SUBSTITUTIONS = {"var", "find-pkg-share", "find-pkg-prefix", "env", "optenv", "dirname", "filename", "eval", "anon",
                 "command", "find-exec"}


def _strings(value):
    if isinstance(value, str):
        yield value
    elif isinstance(value, list):
        for v in value:
            yield from _strings(v)
    elif isinstance(value, dict):
        for v in value.values():
            yield from _strings(v)


def _check_params(params, where):
    assert isinstance(params, list), where
    for p in params:
        assert set(p) in ({"name", "value"}, {"name", "param"}, {"from"}), (where, p)
        if "param" in p:
            _check_params(p["param"], where)


def test_every_shipped_graph_is_a_ros2_yaml_launch_file_and_loads():
    from ament_index_python.packages import get_package_share_directory
    from pathlib import Path
    from seapup_common.processes import find_executable
    from seapup_common.ros.launch_graph import graph_arguments
    shipped = sorted((Path(get_package_share_directory("seapup_bringup")) / "launch").glob("*"))
    assert [p.name for p in shipped] == ["hierarchy.launch.yaml", "identification.launch.yaml",
                                         "identification_closed_loop.launch.yaml", "self_test.launch.yaml",
                                         "simulator.launch.yaml", "simulator_controller.launch.yaml"]
    for path in shipped:
        document = yaml.safe_load(path.read_text())
        assert list(document) == ["launch"] and isinstance(document["launch"], list), path.name
        declared = set()
        for entry in document["launch"]:
            (kind, body), = entry.items()
            assert kind in ("arg", "node"), (path.name, kind)
            if kind == "arg":
                assert set(body) <= ARG_KEYS and "name" in body and isinstance(body.get("default", ""), str), body
                declared.add(body["name"])
            else:
                assert set(body) <= NODE_KEYS and {"pkg", "exec"} <= set(body), (path.name, body)
                _check_params(body.get("param", []), path.name)
                assert all(set(r) == {"from", "to"} for r in body.get("remap", []))
                assert body.get("on_exit", "shutdown") == "shutdown"
            for text in _strings(body):
                for kind_, rest in re.findall(r"\$\(([a-z-]+)\s*([^)]*)\)", text):
                    assert kind_ in SUBSTITUTIONS, (path.name, text)
                    if kind_ == "var":
                        assert rest.strip() in declared, (path.name, f"$(var {rest}) before its arg")
        assert set(graph_arguments(path)) == declared
        arguments = {"controller_file": "/dev/null"} if "controller_file" in declared else {}
        for spec in load_graph(path, arguments):
            assert find_executable(spec.package, spec.executable).is_file(), spec.label
