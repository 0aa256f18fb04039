"""Tests of seapup_common.parameters (ROS 2 params files read without ROS)."""
import math
import re
from pathlib import Path

import pytest
from ament_index_python.packages import get_package_share_directory

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_common.parameters import ParameterFileError, load_node_parameters


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


def test_blade_limit_has_one_place():
    """+/-35 deg (thesis sec. 3.1) lives in seapup_common/data/interface.yaml only."""
    assert BLADE_PITCH_LIMIT == pytest.approx(math.radians(35.0), abs=1e-15)
    src = Path(__file__).resolve().parents[2]
    offenders = []
    for path in src.rglob("*"):
        if path.suffix not in (".py", ".yaml") or "test" in path.parts or path.name == "interface.yaml":
            continue
        text = path.read_text()
        # (respawn_limit of a launch graph is another limit; so is input_limit, a virtual-input vehicle's full
        # scale, 0 standing for the blade pitch's)
        if re.search(r"0\.61086|radians\(35|(?<!respawn_)(?<!input_)limit(_deg)?:\s*[0-9.]+\s*(#|$)", text,
                     re.MULTILINE):
            offenders.append(str(path.relative_to(src)))
    assert offenders == []
    for package, node in (("seapup_sim", "simulator"), ("seapup_control", "open_loop")):
        path = Path(get_package_share_directory(package)) / "config" / f"{node}.yaml"
        assert "blade_pitch_limit" not in load_node_parameters(path, node)


def test_a_parameter_file_is_read_bounded_and_strictly(tmp_path):
    """Issue 40: a duplicated parameter kept the last value; /dev/zero was read without a limit."""
    f = tmp_path / "p.yaml"
    f.write_text("n:\n  ros__parameters: {a: 1, a: 2}\n")
    with pytest.raises(ParameterFileError, match=r"duplicate key 'a'"):
        load_node_parameters(f, "n")
    with pytest.raises(ParameterFileError, match="larger than 1 MiB"):
        load_node_parameters("/dev/zero", "n")
    f.write_text("# nothing\n")
    with pytest.raises(ParameterFileError, match="is empty"):
        load_node_parameters(f, "n")
