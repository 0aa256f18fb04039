"""Tests of seapup_common.config: extends chains, deep merge, errors that name the key."""
import math

import numpy as np
import pytest

from seapup_common.config import ConfigError, ConfigView, load_yaml, merge, parsed_yaml


def test_merge_is_deep_and_copies():
    base = {"a": {"b": 1, "c": 2}, "l": [1]}
    out = merge(base, {"a": {"c": 3}, "l": [2]})
    assert out == {"a": {"b": 1, "c": 3}, "l": [2]}
    out["a"]["b"] = 9
    assert base["a"]["b"] == 1


def test_extends_chain_merges_overlays(tmp_path):
    (tmp_path / "base.yaml").write_text("x: 1\nsub: {a: 1, b: 2}\n")
    (tmp_path / "mid.yaml").write_text("extends: base\nsub: {b: 3}\n")
    (tmp_path / "top.yaml").write_text("extends: mid.yaml\ny: 4\n")
    assert load_yaml(tmp_path / "top.yaml") == {"x": 1, "sub": {"a": 1, "b": 3}, "y": 4}


@pytest.mark.parametrize("files,match", [
    ({"a.yaml": "extends: b\n", "b.yaml": "extends: a\n"}, "loops back"),
    ({"a.yaml": "extends: missing\n"}, "does not exist"),
    ({"a.yaml": "[1, 2]\n"}, "must be a mapping"),
    ({"a.yaml": "a: [b\n"}, "cannot read"),
])
def test_bad_files_are_named(tmp_path, files, match):
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    with pytest.raises(ConfigError, match=match):
        load_yaml(tmp_path / "a.yaml")


def test_view_names_the_missing_key_with_its_path():
    v = ConfigView({"rigid_body": {"mass": 110.0}}, "baseline.yaml")
    assert v["rigid_body"]["mass"] == 110.0
    with pytest.raises(ConfigError, match=r"baseline.yaml: missing key rigid_body\.cg"):
        v["rigid_body"]["cg"]
    with pytest.raises(ConfigError):
        v.section("thrusters")
    assert v.get("thrusters") is None and v["rigid_body"].get("cg", 3) == 3
    assert isinstance(v, dict) is False and dict(v)["rigid_body"] == {"mass": 110.0}


@pytest.mark.parametrize("value,kw,match", [
    (math.nan, {}, "outside the allowed range"), (-1.0, {"lo": 0.0}, r"\[0, inf\]"),
    (0.0, {"lo": 0.0, "lo_open": True}, r"\(0, inf\]"), ("3", {}, "must be a number"),
    (True, {}, "must be a number"), (1e308 * 10, {}, "outside"),
])
def test_number_checks_type_finiteness_and_range(value, kw, match):
    with pytest.raises(ConfigError, match=match):
        ConfigView({"k": value}, "f.yaml", "sec").number("k", **kw)


def test_vector_flag_choice_integer():
    v = ConfigView({"v": [1, 2, 3], "f": True, "c": "hover", "i": 4, "s": "yes"}, "f.yaml")
    np.testing.assert_array_equal(v.vector("v", 3), [1.0, 2.0, 3.0])
    with pytest.raises(ConfigError, match="needs 4 numbers"):
        v.vector("v", 4)
    assert v.flag("f") is True
    with pytest.raises(ConfigError, match="true or false"):
        v.flag("s")
    assert v.choice("c", ("hover", "neutral")) == "hover"
    with pytest.raises(ConfigError, match="not one of"):
        v.choice("s", ("hover", "neutral"))
    assert v.integer("i", lo=0, hi=10) == 4
    assert v.number("absent", 2.5) == 2.5


def test_a_strict_merge_names_an_unknown_key_its_path_and_the_nearest_valid_one():
    base = {"current": {"enabled": False, "mean_speed": 0.0}, "sensors": "baseline"}
    assert merge(base, {"current": {"enabled": True}}, strict="x.yaml")["current"]["enabled"] is True
    with pytest.raises(ConfigError, match=r"^x.yaml: unknown key current.enabeld \(did you mean current.enabled\?\)$"):
        merge(base, {"current": {"enabeld": True}}, strict="x.yaml")
    with pytest.raises(ConfigError, match=r"unknown key zzz \(valid: current, sensors\)"):
        merge(base, {"zzz": 1}, strict="x.yaml")
    assert merge(base, {"zzz": 1})["zzz"] == 1  # not strict: carried along


def test_a_parsed_file_is_read_once_per_version_and_handed_out_as_a_copy(tmp_path):
    """parsed_yaml caches by (path, mtime, size): a caller mutating its copy changes nothing for the next,
    and an edited file is parsed again."""
    import os
    f = tmp_path / "a.yaml"
    f.write_text("k: [1, 2]\n")
    first = parsed_yaml(f)
    first["k"].append(3)
    assert parsed_yaml(f) == {"k": [1, 2]}
    f.write_text("k: [1, 2, 3, 4]\n")
    os.utime(f, ns=(f.stat().st_atime_ns, f.stat().st_mtime_ns + 1_000_000))
    assert parsed_yaml(f) == {"k": [1, 2, 3, 4]}
    f.write_text("k: [\n")
    with pytest.raises(ConfigError, match="cannot read configuration"):
        parsed_yaml(f)
    with pytest.raises(ConfigError, match="cannot read configuration"):
        parsed_yaml(tmp_path / "missing.yaml")


# -- bounded and strict reading (issue 40) -------------------------------------------------------------------
@pytest.mark.parametrize("text, match", [
    ("mass: 1\nmass: 2\n", r"duplicate key 'mass' \(first at line 1\)"),              # kept the last one
    ("x: !!python/object/apply:os.system [echo]\n", "a tag that is not plain data"),
    ("[" * 200 + "]" * 200 + "\n", "nested deeper than 64 levels"),
])
def test_a_configuration_file_is_parsed_strictly(tmp_path, text, match):
    path = tmp_path / "vehicle.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=f"cannot read configuration {path}: .*{match}") as caught:
        parsed_yaml(path)
    assert "\n" not in str(caught.value)


def test_a_configuration_file_is_read_with_a_bound(tmp_path):
    for path, why in (("/dev/zero", "larger than 1 MiB"), (tmp_path, "is a directory"),
                      (tmp_path / "none.yaml", "No such file")):
        with pytest.raises(ConfigError, match=why):
            parsed_yaml(path)


def test_numbers_in_a_configuration_are_yaml_numbers_not_text():
    view = ConfigView({"v": ["1", "2", "3"], "b": [True, 0, 0], "n": 10**400, "w": [10**400, 0.0]}, "f.yaml")
    with pytest.raises(ConfigError, match="f.yaml: v: must be a list of numbers, got \\['1'"):
        view.vector("v", 3)                                        # was converted to [1.0, 2.0, 3.0]
    with pytest.raises(ConfigError, match="b: must be a list of numbers"):
        view.vector("b", 3)
    with pytest.raises(ConfigError, match="outside the allowed range"):
        view.number("n")                                           # was an OverflowError
    with pytest.raises(ConfigError, match="outside the allowed range"):
        view.vector("w", 2)
