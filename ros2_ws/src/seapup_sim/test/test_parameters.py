"""Tests of seapup_sim.parameters (ROS 2 params files read without ROS)."""
import math
from pathlib import Path

import pytest
from ament_index_python.packages import get_package_share_directory

from seapup_sim.parameters import ParameterFileError, load_node_parameters


def test_wildcard_then_node_section(tmp_path):
    f = tmp_path / "p.yaml"
    f.write_text("/**:\n  ros__parameters: {a: 1, b: 2}\n"
                 "/seapup/sim:\n  ros__parameters: {b: 3}\n"
                 "other:\n  ros__parameters: {a: 9}\n")
    assert load_node_parameters(f, "sim") == {"a": 1, "b": 3}


@pytest.mark.parametrize("text", ["[1, 2]", "sim: 3", "sim:\n  params: {}", "other:\n  ros__parameters: {}", "a: [b"])
def test_malformed_files_are_refused(tmp_path, text):
    f = tmp_path / "p.yaml"
    f.write_text(text)
    with pytest.raises(ParameterFileError):
        load_node_parameters(f, "sim")


def test_missing_file_is_refused(tmp_path):
    with pytest.raises(ParameterFileError, match="cannot read"):
        load_node_parameters(tmp_path / "none.yaml", "sim")


def test_installed_simulator_defaults_are_the_thesis_blade_limit():
    path = Path(get_package_share_directory("seapup_sim")) / "config" / "simulator.yaml"
    params = load_node_parameters(path, "simulator")
    assert params["blade_pitch_limit"] == pytest.approx(math.radians(35.0), abs=1e-12)
