"""cmake/fix_ros_wheel_paths.cmake: repairs the wheels' hard-coded include dirs.

A scratch CMake project imports targets carrying the exact paths found in the
Jazzy wheels' export files and prints what the deferred hook made of them.
"""
import subprocess
import sysconfig
from pathlib import Path

import numpy
import pytest

pytestmark = pytest.mark.graph  # runs ./seapup, a build or subprocesses: not a seconds-fast unit test

REPO = Path(__file__).resolve().parents[1]
HOOK = REPO / "cmake" / "fix_ros_wheel_paths.cmake"

PROJECT = """
cmake_minimum_required(VERSION 3.22)
project(probe NONE)
add_library(wheel_target INTERFACE IMPORTED)
set_target_properties(wheel_target PROPERTIES INTERFACE_INCLUDE_DIRECTORIES
  "/opt/python/cp311-cp311/include/python3.11;@EXTRA@;/keep/me")
add_library(clean_target INTERFACE IMPORTED)
set_target_properties(clean_target PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "/usr/include")
cmake_language(DEFER DIRECTORY "${CMAKE_SOURCE_DIR}" CALL report)
function(report)
  get_target_property(d wheel_target INTERFACE_INCLUDE_DIRECTORIES)
  message(STATUS "WHEEL=${d}")
  get_target_property(c clean_target INTERFACE_INCLUDE_DIRECTORIES)
  message(STATUS "CLEAN=${c}")
endfunction()
"""


def configure(tmp_path, extra, hook=True):
    src = tmp_path / "src"
    src.mkdir()
    (src / "CMakeLists.txt").write_text(PROJECT.replace("@EXTRA@", extra))
    args = ["cmake", "-S", str(src), "-B", str(tmp_path / "build"),
            f"-DPython3_EXECUTABLE={Path(sysconfig.get_paths()['scripts']) / 'python'}"]
    if hook:
        args.append(f"-DCMAKE_PROJECT_INCLUDE={HOOK}")
    return subprocess.run(args, capture_output=True, text=True)


def reported(out, key):
    line = next(l for l in out.splitlines() if l.startswith(f"-- {key}="))
    return line.split("=", 1)[1].split(";")


def test_rewrites_python_and_numpy_include_dirs(tmp_path):
    numpy_dir = "/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include"
    run = configure(tmp_path, numpy_dir)
    assert run.returncode == 0, run.stderr
    assert reported(run.stdout, "WHEEL") == [sysconfig.get_paths()["include"], numpy.get_include(), "/keep/me"]
    assert reported(run.stdout, "CLEAN") == ["/usr/include"]
    assert "repaired include dirs of 1 imported targets" in run.stdout


def test_without_the_hook_the_foreign_paths_stay(tmp_path):
    run = configure(tmp_path, "/opt/python/cp311-cp311/include/python3.11", hook=False)
    assert run.returncode == 0
    assert reported(run.stdout, "WHEEL")[0].startswith("/opt/python/cp311-cp311")


def test_unknown_wheel_build_path_fails_loudly(tmp_path):
    run = configure(tmp_path, "/opt/python/cp312-cp312/include/somethingelse")
    assert run.returncode != 0
    assert "The ROS wheels changed" in run.stderr


@pytest.mark.parametrize("pkg", ["seapup_msgs"])
def test_the_workspace_build_used_the_repaired_paths(pkg):
    cache = (REPO / "ros2_ws" / "build" / pkg / "CMakeCache.txt").read_text()
    assert f"CMAKE_PROJECT_INCLUDE:UNINITIALIZED={HOOK}" in cache or f"CMAKE_PROJECT_INCLUDE:FILEPATH={HOOK}" in cache
