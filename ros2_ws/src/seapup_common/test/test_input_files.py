"""Bounded, strict file reading (seapup_common.input_files): each refusal against the file that earns it."""
import math
import time

import pytest

from seapup_common.input_files import (LIMITS, MAX_DEPTH, InputFileError, limit_for, load_yaml_file, parse_yaml,
                                       read_text)


def test_read_text_refuses_an_endless_device_after_the_limit():
    t0 = time.process_time()
    with pytest.raises(InputFileError, match="larger than 1 MiB"):
        read_text("/dev/zero", "spec")
    assert time.process_time() - t0 < 1.0


def test_read_text_limit_is_exact(tmp_path):
    f = tmp_path / "a.yaml"
    f.write_text("x" * 100)
    assert read_text(f, limit=100) == "x" * 100
    with pytest.raises(InputFileError, match="larger than 99 bytes"):
        read_text(f, limit=99)


def test_environment_raises_every_limit(tmp_path, monkeypatch):
    f = tmp_path / "big.yaml"
    f.write_text("a: " + "1" * (LIMITS["spec"] + 10))
    with pytest.raises(InputFileError, match="SEAPUP_MAX_FILE_BYTES"):
        read_text(f, "spec")
    monkeypatch.setenv("SEAPUP_MAX_FILE_BYTES", str(LIMITS["spec"] * 2))
    assert limit_for("spec") == LIMITS["spec"] * 2
    assert len(read_text(f, "spec")) == LIMITS["spec"] + 13
    monkeypatch.setenv("SEAPUP_MAX_FILE_BYTES", "-3")
    with pytest.raises(InputFileError, match="positive number of bytes"):
        limit_for("spec")


@pytest.mark.parametrize("content, reason", [
    (b"\xff\xfe\x00", "not UTF-8"),
    (b"a: 1\x00", "NUL byte"),
])
def test_read_text_refuses_binary(tmp_path, content, reason):
    f = tmp_path / "bin"
    f.write_bytes(content)
    with pytest.raises(InputFileError, match=reason):
        read_text(f)


def test_read_text_refuses_directory_and_missing(tmp_path):
    with pytest.raises(InputFileError, match="is a directory"):
        read_text(tmp_path)
    with pytest.raises(InputFileError, match="no such file"):
        read_text(tmp_path / "nope.yaml")


def test_duplicate_keys_are_refused_with_both_lines():
    with pytest.raises(InputFileError, match=r"duplicate key 'a' \(first at line 1\).*line 3"):
        parse_yaml("a: 1\nb: 2\na: 3\n", "x.yaml")
    with pytest.raises(InputFileError, match="duplicate key 'k'"):
        parse_yaml("outer:\n  k: 1\n  k: 1\n")


def test_merge_keys_may_override():
    assert parse_yaml("base: &b {a: 1, c: 2}\nd:\n  <<: *b\n  a: 3\n") == {"base": {"a": 1, "c": 2},
                                                                         "d": {"a": 3, "c": 2}}


def test_python_tags_are_refused():
    with pytest.raises(InputFileError, match="not plain data"):
        parse_yaml("!!python/object/apply:os.system ['true']")


def test_billion_laughs_refused_before_construction():
    levels = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    levels += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]" for i in range(1, 9)]
    t0 = time.process_time()
    with pytest.raises(InputFileError, match="expands to more than"):
        parse_yaml("\n".join(levels))
    assert time.process_time() - t0 < 1.0
    # a few shared anchors are fine
    assert parse_yaml("a: &x [1, 2]\nb: *x\n") == {"a": [1, 2], "b": [1, 2]}


def test_deep_nesting_refused():
    with pytest.raises(InputFileError, match=f"deeper than {MAX_DEPTH}"):
        parse_yaml("[" * 100 + "]" * 100)
    with pytest.raises(InputFileError, match="nesting depth"):   # libyaml's own bound, reached first
        parse_yaml("[" * 5000 + "]" * 5000)
    assert parse_yaml("[" * 10 + "]" * 10) == [[[[[[[[[[]]]]]]]]]]


def test_syntax_error_is_one_line_with_its_place():
    with pytest.raises(InputFileError) as err:
        parse_yaml("a: [1, 2\nb: 3\n", "s.yaml")
    assert "\n" not in str(err.value) and "line" in str(err.value) and str(err.value).startswith("s.yaml")


def test_empty_and_comment_only_files(tmp_path):
    for text in ("", "# only a comment\n", "\n\n"):
        f = tmp_path / "e.yaml"
        f.write_text(text)
        with pytest.raises(InputFileError, match="is empty"):
            load_yaml_file(f, "spec")
        assert load_yaml_file(f, "spec", empty_ok=True) is None


def test_plain_documents_load_as_safe_load(tmp_path):
    import yaml
    text = "a: 1\nb: [1.5, .inf, .nan, true, null, 'x']\nc: {d: 2e3}\n"
    got, want = parse_yaml(text), yaml.safe_load(text)
    assert got.keys() == want.keys() and got["c"] == want["c"] and got["a"] == 1
    assert got["b"][:2] == [1.5, math.inf] and math.isnan(got["b"][2]) and got["b"][3:] == [True, None, "x"]


def test_a_pipe_is_refused_without_opening_it(tmp_path):
    import os
    fifo = tmp_path / "spec.yaml"
    os.mkfifo(fifo)   # no writer: an open() would block for ever
    with pytest.raises(InputFileError, match="is a pipe"):
        read_text(fifo, "spec")
