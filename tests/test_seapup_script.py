"""The ./seapup entry script: usage, exit codes, environment, idempotent bootstrap."""
import pytest
import subprocess
from pathlib import Path

pytestmark = pytest.mark.graph  # runs ./seapup, a build or subprocesses: not a seconds-fast unit test

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


def scratch_copy(tmp_path, lock_text):
    """A copy of the entry script with its own (empty) workspace and a given lock."""
    import shutil
    root = tmp_path / "repo"
    (root / "requirements").mkdir(parents=True)
    (root / "cmake").mkdir()
    shutil.copy(SEAPUP, root / "seapup")
    shutil.copy(REPO / "cmake" / "fix_ros_wheel_paths.cmake", root / "cmake")
    (root / "requirements" / "lock.txt").write_text(lock_text)
    return root


def clean_env(**extra):
    import os
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "AMENT_PREFIX_PATH", "VIRTUAL_ENV", "LD_LIBRARY_PATH")}
    env.update(extra)
    return env


def test_wrong_python_version_is_named(tmp_path):
    fake = tmp_path / "python3.10"
    fake.write_text("#!/bin/sh\necho 3.10\n")
    fake.chmod(0o755)
    root = scratch_copy(tmp_path, "numpy==2.4.6\n")
    r = subprocess.run([str(root / "seapup"), "setup"], capture_output=True, text=True,
                       env=clean_env(SEAPUP_PYTHON=str(fake)))
    assert r.returncode == 1
    assert "is Python 3.10; seapup needs exactly Python 3.11" in r.stderr
    assert not (root / ".venv").exists()


def test_missing_python_says_what_to_install(tmp_path):
    root = scratch_copy(tmp_path, "numpy==2.4.6\n")
    r = subprocess.run([str(root / "seapup"), "setup"], capture_output=True, text=True,
                       env=clean_env(SEAPUP_PYTHON="no-such-python3.11"))
    assert r.returncode == 1 and "apt-get install python3.11" in r.stderr


def test_failed_pip_install_explains_and_keeps_nothing(tmp_path):
    root = scratch_copy(tmp_path, "seapup-no-such-distribution==0.0.1\n")
    r = subprocess.run([str(root / "seapup"), "setup"], capture_output=True, text=True,
                       env=clean_env(PIP_NO_INDEX="1", PIP_FIND_LINKS=str(tmp_path)))
    assert r.returncode == 1
    assert "pip could not install requirements/lock.txt" in r.stderr
    assert "PyPI is reachable" in r.stderr
    assert not (root / ".venv").exists()
