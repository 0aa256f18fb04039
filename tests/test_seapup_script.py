"""The ./seapup entry script: usage, exit codes, environment, idempotent bootstrap."""
import pytest
import subprocess
from pathlib import Path

pytestmark = pytest.mark.graph  # runs ./seapup, a build or subprocesses: not a seconds-fast unit test

REPO = Path(__file__).resolve().parents[1]
SEAPUP = str(REPO / "seapup")


def run(*args, env=None):
    return subprocess.run([SEAPUP, *args], capture_output=True, text=True, cwd=REPO, env=env)


def test_an_unknown_command_is_one_line_naming_the_nearest_commands():
    r = run("demp")
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr == "seapup: unknown command 'demp': did you mean demo or node or help?\n"


def test_help_lists_the_subcommands():
    r = run("help")
    assert r.returncode == 0
    for cmd in ("demo", "test", "run", "setup", "env", "help"):
        assert f"\n  ./seapup {cmd}" in r.stdout


def test_run_without_arguments_is_bad_usage():
    r = run("run")
    assert r.returncode == 2 and "the following arguments are required: package, executable" in r.stderr
    r = run("run", "--help")
    assert r.returncode == 0 and r.stdout.startswith("usage: ./seapup run") and r.stderr == ""


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
    (root / "requirements" / "seapup.in").write_text("numpy\n")
    registry = root / "ros2_ws/src/seapup_bringup/seapup_bringup"
    registry.mkdir(parents=True)
    for name in ("cli.py", "cli_usage.json"):
        shutil.copy(REPO / "ros2_ws/src/seapup_bringup/seapup_bringup" / name, registry / name)
    return root


def fake_python(tmp_path, venv_body="exit 1"):
    """A "python3.11" that reports version 3.11, runs ``venv_body`` for ``-m venv DIR`` ($3 is DIR) and is the
    real interpreter otherwise (it runs the registry)."""
    import sys
    fake = tmp_path / "python3.11"
    fake.write_text(f'#!/bin/sh\ncase "$1" in\n  -c) echo 3.11 ;;\n  -m) {venv_body} ;;\n'
                    f'  *) exec {sys.executable} "$@" ;;\nesac\n')
    fake.chmod(0o755)
    return fake


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


@pytest.mark.parametrize("verb", ["setup", "env", "lock", "help", "run"])
def test_help_of_the_bootstrap_commands_prints_and_does_nothing_else(tmp_path, verb):
    """Before: setup --help and env --help bootstrapped, lock --help regenerated the lock."""
    root = scratch_copy(tmp_path, "numpy==2.4.6\n")
    (tmp_path / "tmp").mkdir()
    r = subprocess.run([str(root / "seapup"), verb, "--help"], capture_output=True, text=True, timeout=60,
                       env=clean_env(SEAPUP_PYTHON=str(fake_python(tmp_path)), TMPDIR=str(tmp_path / "tmp")))
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(f"usage: ./seapup {verb}") and r.stderr == ""
    assert sorted(p.name for p in root.iterdir()) == ["cmake", "requirements", "ros2_ws", "seapup"]
    assert (root / "requirements" / "lock.txt").read_text() == "numpy==2.4.6\n"
    assert list((tmp_path / "tmp").iterdir()) == []


@pytest.mark.parametrize("args", [["setup", "--bogus"], ["env", "extra"], ["lock", "-x"], ["help", "nonsense"]])
def test_bad_usage_of_the_bootstrap_commands_exits_2_before_anything(tmp_path, args):
    root = scratch_copy(tmp_path, "numpy==2.4.6\n")
    r = subprocess.run([str(root / "seapup"), *args], capture_output=True, text=True, timeout=60,
                       env=clean_env(SEAPUP_PYTHON=str(fake_python(tmp_path))))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert not (root / ".venv").exists()


def test_only_the_tests_need_chromium(tmp_path):
    """The bootstrap of setup (and so demo) goes on without Chromium; ./seapup test names it."""
    root = scratch_copy(tmp_path, "numpy==2.4.6\n")
    env = clean_env(SEAPUP_PYTHON=str(fake_python(tmp_path)), SEAPUP_CHROMIUM="no-such-chromium")
    r = subprocess.run([str(root / "seapup"), "setup"], capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == 1 and "chromium" not in r.stderr.lower()
    assert "could not create" in r.stderr   # it went on to make the venv (the fake python cannot)
    r = subprocess.run([str(root / "seapup"), "test"], capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == 1 and "chromium not found; ./seapup test needs it" in r.stderr


def test_an_interrupted_lock_removes_its_scratch_venv(tmp_path):
    """Before: Ctrl-C while pip resolved left the scratch venv (931 MB) in $TMPDIR."""
    import os
    import signal
    root = scratch_copy(tmp_path, "numpy==2.4.6\n")
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    python = fake_python(tmp_path, 'mkdir -p "$3/bin"; head -c 100000 /dev/zero > "$3/bin/blob"; '
                                   'echo "fake venv made" >&2; exec sleep 120')
    lock = subprocess.Popen([str(root / "seapup"), "lock"], stderr=subprocess.PIPE, text=True,
                            start_new_session=True, env=clean_env(SEAPUP_PYTHON=str(python), TMPDIR=str(scratch)))
    lines = []
    for line in lock.stderr:   # waits on the state: the venv exists once this line is written
        lines.append(line)
        if "fake venv made" in line:
            break
    assert any(scratch.rglob("blob")), lines
    os.killpg(lock.pid, signal.SIGINT)   # Ctrl-C at a terminal: the whole foreground group
    rest = lock.stderr.read()
    assert lock.wait(timeout=30) == 130
    assert list(scratch.iterdir()) == [], "the scratch venv was left behind"
    assert "Traceback" not in rest and (root / "requirements" / "lock.txt").read_text() == "numpy==2.4.6\n"


def _sha_of_files(root, *names):
    """The entry script's own ``sha_of_files`` (what decides a rebuild), run on files under ``root``."""
    function = subprocess.run(["sed", "-n", "/^sha_of_files()/,/^}/p", SEAPUP], capture_output=True, text=True,
                              check=True).stdout
    assert function.startswith("sha_of_files()")
    script = function + '\nROOT="$1"; shift; files=(); for f in "$@"; do files+=("$ROOT/$f"); done\n' \
                        'sha_of_files "${files[@]}"\n'
    out = subprocess.run(["bash", "-c", script, "sha", str(root), *names], capture_output=True, text=True,
                         check=True, timeout=30)
    return out.stdout.strip()


def test_a_package_is_rebuilt_when_a_file_changes_is_renamed_or_moves_content(tmp_path):
    """The stamp is a hash of the files' names (relative to the checkout) and contents: a changed byte, a
    renamed file or content moved from one file to another changes it; another checkout of the same files
    does not (a fresh clone elsewhere is not rebuilt for its path)."""
    def tree(root, files):
        for name, text in files.items():
            (root / name).parent.mkdir(parents=True, exist_ok=True)
            (root / name).write_text(text)
        return root
    base = {"p/a.py": "x = 1\n", "p/b.py": "y = 2\n"}
    one = _sha_of_files(tree(tmp_path / "one", base), *sorted(base))
    assert len(one) == 64
    assert _sha_of_files(tree(tmp_path / "elsewhere" / "two", base), *sorted(base)) == one
    changed = dict(base, **{"p/b.py": "y = 3\n"})
    assert _sha_of_files(tree(tmp_path / "three", changed), *sorted(changed)) != one
    renamed = {"p/a.py": "x = 1\n", "p/c.py": "y = 2\n"}
    assert _sha_of_files(tree(tmp_path / "four", renamed), *sorted(renamed)) != one
    moved = {"p/a.py": "x = 1\ny = 2\n", "p/b.py": ""}
    assert _sha_of_files(tree(tmp_path / "five", moved), *sorted(moved)) != one


def test_every_installed_module_has_the_byte_code_of_its_installed_source():
    """The build byte-compiles what colcon installed (setuptools skips it under PYTHONDONTWRITEBYTECODE, which this
    machine's environment sets): every module of every installed package has a cache file whose header names its
    source's size and modification time, so an import loads it instead of compiling the source at every start of a
    node or command (Python checks exactly these two fields, PEP 552's default timestamp mode)."""
    import importlib.util
    import struct
    install = REPO / "ros2_ws" / "install"
    sources = [p for p in install.glob("*/lib/python*/site-packages/**/*.py") if "__pycache__" not in p.parts]
    assert len(sources) > 100, len(sources)
    stale = []
    for source in sources:
        cache = Path(importlib.util.cache_from_source(str(source)))
        if not cache.is_file():
            stale.append(f"{source.relative_to(install)}: no byte-code")
            continue
        flags, mtime, size = struct.unpack("<III", cache.read_bytes()[4:16])
        stat = source.stat()
        if flags != 0 or mtime != int(stat.st_mtime) & 0xFFFFFFFF or size != stat.st_size & 0xFFFFFFFF:
            stale.append(f"{source.relative_to(install)}: byte-code of another source")
    assert stale == [], stale[:10]
