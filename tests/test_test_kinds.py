"""The suite's kinds of test (``conftest.py``): a ``unit`` test starts no process, whatever it does with the error.

Truth: an inner pytest session with this repository's ``conftest.py`` and ``pytest.ini`` over tests that start a
process each way -- ``subprocess``, ``multiprocessing`` (spawn and fork), ``os.system``, and one that swallows
the refusal -- plus a module-scoped fixture that starts one, each unmarked (so ``unit``): every one must fail;
the same tests marked ``process`` pass, and a pure test passes.
"""
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

SPAWNING = '''
import multiprocessing, os, subprocess, sys
import pytest

@pytest.fixture(scope="module")
def started():
    return subprocess.run([sys.executable, "-c", "print(1)"], capture_output=True).stdout

def _noop():
    pass

MARK
def test_subprocess():
    subprocess.run([sys.executable, "-c", "pass"])

MARK
def test_spawn():
    p = multiprocessing.get_context("spawn").Process(target=_noop); p.start(); p.join()

MARK
def test_fork():
    p = multiprocessing.get_context("fork").Process(target=_noop); p.start(); p.join()

MARK
def test_system():
    os.system("true")

MARK
def test_swallowed():
    try:
        subprocess.run(["true"])
    except Exception:
        pass

MARK
def test_fixture(started):
    pass

def test_pure():
    assert sum(range(4)) == 6
'''


def _session(tmp_path: Path, mark: str) -> str:
    shutil.copy(REPO / "conftest.py", tmp_path / "conftest.py")
    shutil.copy(REPO / "pytest.ini", tmp_path / "pytest.ini")
    (tmp_path / "pytest.ini").write_text((tmp_path / "pytest.ini").read_text().replace(
        "testpaths = ros2_ws/src tests", "testpaths = ."))
    (tmp_path / "test_inner.py").write_text(SPAWNING.replace("MARK", mark))
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-rA"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=300)
    return run.stdout + run.stderr


@pytest.mark.process
def test_a_unit_test_that_starts_a_process_fails_and_a_marked_one_passes(tmp_path):
    (tmp_path / "unit").mkdir()
    (tmp_path / "marked").mkdir()
    unit = _session(tmp_path / "unit", "")
    for name in ("subprocess", "spawn", "fork", "system", "swallowed", "fixture"):
        assert f"test_inner.py::test_{name} - " in unit and "started a process" in unit, (name, unit[-3000:])
        assert f"PASSED test_inner.py::test_{name}\n" not in unit or f"ERROR test_inner.py::test_{name}" in unit, \
            (name, unit[-3000:])
    assert "PASSED test_inner.py::test_pure" in unit, unit[-3000:]
    marked = _session(tmp_path / "marked", "@pytest.mark.process")
    assert "7 passed" in marked and "failed" not in marked and "error" not in marked, marked[-3000:]


@pytest.mark.process
def test_a_test_of_two_kinds_is_refused_at_collection(tmp_path):
    """A module's ``pytestmark = pytest.mark.unit`` with one test marked ``sweep`` made that test both, and ``-m
    unit`` ran it (a 22 s convergence sweep among the unit tests): the session refuses it, naming the test."""
    shutil.copy(REPO / "conftest.py", tmp_path / "conftest.py")
    shutil.copy(REPO / "pytest.ini", tmp_path / "pytest.ini")
    (tmp_path / "pytest.ini").write_text((tmp_path / "pytest.ini").read_text().replace(
        "testpaths = ros2_ws/src tests", "testpaths = ."))
    (tmp_path / "test_inner.py").write_text("import pytest\npytestmark = pytest.mark.unit\n\n"
                                            "@pytest.mark.sweep\ndef test_long():\n    pass\n\n"
                                            "def test_short():\n    pass\n")
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--co"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=300)
    said = run.stdout + run.stderr
    assert run.returncode != 0 and "marked unit and also sweep" in said and "test_inner.py::test_long" in said, said
    assert "test_inner.py::test_short" not in said.split("marked unit and also sweep")[1], said
    (tmp_path / "test_inner.py").write_text("import pytest\n\n@pytest.mark.sweep\ndef test_long():\n    pass\n\n"
                                            "def test_short():\n    pass\n")
    unit = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--co", "-m", "unit"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert unit.returncode == 0 and "test_short" in unit.stdout and "test_long" not in unit.stdout, unit.stdout
