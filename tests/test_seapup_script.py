"""The ./seapup entry script: usage, exit codes, environment, idempotent bootstrap."""
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SEAPUP = str(REPO / "seapup")


def run(*args, env=None):
    return subprocess.run([SEAPUP, *args], capture_output=True, text=True, cwd=REPO, env=env)


def test_unknown_command_prints_usage_and_exits_2():
    r = run("frobnicate")
    assert r.returncode == 2
    assert "unknown command: frobnicate" in r.stderr and "usage: ./seapup" in r.stderr


def test_help_lists_the_subcommands():
    r = run("help")
    assert r.returncode == 0
    for cmd in ("demo", "test", "run", "setup", "env", "help"):
        assert f"\n  {cmd} " in r.stdout


def test_run_without_arguments_explains_itself():
    r = run("run")
    assert r.returncode == 1 and "run needs a package and an executable" in r.stderr


def test_env_exports_a_loopback_only_workspace():
    r = run("env")
    assert r.returncode == 0, r.stderr
    exports = dict(line[len("export "):].split("=", 1) for line in r.stdout.splitlines())
    assert exports["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert "ros2_ws/install/seapup_msgs" in exports["AMENT_PREFIX_PATH"]
    assert "ros2_ws/install/seapup_msgs/lib" in exports["LD_LIBRARY_PATH"]
    # the environment works in a fresh shell
    probe = subprocess.run(["bash", "-c", r.stdout + "\npython -c 'import rclpy, seapup_msgs.msg, seapup_sim'"],
                           capture_output=True, text=True)
    assert probe.returncode == 0, probe.stderr


def test_second_bootstrap_neither_reinstalls_nor_rebuilds():
    r = run("setup")
    assert r.returncode == 0, r.stderr
    assert "installing" not in r.stderr and "building" not in r.stderr
