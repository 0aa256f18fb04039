"""What a user or a hostile file hands ``./seapup fly`` and ``./seapup campaign`` (issue 40): refused in one line
``seapup: error: <reason>`` with exit 1, in bounded memory and CPU, before anything is expanded or allocated.

Truth: the process's own resource usage (``os.wait4``), not wall time; each case is one short process (under a
second of CPU), so only the cases the pure tests of ``seapup_runs`` cannot reach are here: the command's reading
of the file and its exit.
"""
import os
import resource
import subprocess
import sys
import threading

import pytest

#: Far above what a refusing process needs (~35-150 MB: Python, numpy and the command's imports), far below the
#: gigabytes an unbounded read or expansion reaches.
RSS_BOUND_MB = 600
#: A refusal is arithmetic on a few numbers after the imports (~1 s of CPU); a loaded machine does not add CPU.
CPU_BOUND_S = 20.0


def _limits():
    # a safety net for a regression: an unbounded read stops at 4 GB of address space instead of the machine's
    resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))
    resource.setrlimit(resource.RLIMIT_CPU, (60, 60))


def _seapup(tmp_path, *argv):
    """Run ``seapup_bringup.cli *argv``; (exit code, stderr lines, max RSS in MB, CPU seconds) of that process."""
    out, err = tmp_path / "stdout", tmp_path / "stderr"
    with open(out, "wb") as o, open(err, "wb") as e:
        proc = subprocess.Popen([sys.executable, "-m", "seapup_bringup.cli", *map(str, argv)], stdout=o, stderr=e,
                                stdin=subprocess.DEVNULL, env=dict(os.environ), preexec_fn=_limits)
    timer = threading.Timer(120.0, proc.kill)
    timer.start()
    try:
        _, status, usage = os.wait4(proc.pid, 0)
    finally:
        timer.cancel()
    proc.returncode = os.waitstatus_to_exitcode(status)   # reaped here: Popen must not wait for it again
    lines = err.read_text().strip().splitlines()
    return proc.returncode, lines, usage.ru_maxrss / 1024, usage.ru_utime + usage.ru_stime


@pytest.mark.process
def test_fly_refuses_dev_zero_after_reading_past_the_limit_not_the_memory(tmp_path):
    """Before issue 40 ``fly /dev/zero`` read until the OOM killer ended it (23.6 GB)."""
    code, lines, rss_mb, cpu_s = _seapup(tmp_path, "fly", "/dev/zero")
    assert code == 1 and len(lines) == 1, lines
    assert lines[0] == ("seapup: error: /dev/zero: larger than 1 MiB, the limit for a spec file "
                        "(set SEAPUP_MAX_FILE_BYTES to allow more)")
    assert rss_mb < RSS_BOUND_MB and cpu_s < CPU_BOUND_S, (rss_mb, cpu_s)


@pytest.mark.parametrize("text, reason", [
    ("", "is empty (no YAML document in it)"),                        # flew a default 10 s run, exit 0
    ("# only a comment\n\n", "is empty (no YAML document in it)"),
    ("duration: 4\nduration: 2\n", "duplicate key 'duration' (first at line 1) at line 2"),   # kept the last
    ("control_period: '0.2'\n", "control_period must be a number, got '0.2'"),    # converted and flown
    ("duration: 2.0e+7\n", "is 1e+08 control samples, more than the 1,000,000 a run may have"),   # 1.3 GB+
    ("name: [1, 2]\n", "name must be a non-empty string"),           # 'TypeError: unsupported format string'
])
@pytest.mark.process
def test_fly_refuses_a_bad_spec_file_in_one_line_and_flies_nothing(tmp_path, text, reason):
    spec = tmp_path / "spec.yaml"
    spec.write_text(text)
    code, lines, rss_mb, _ = _seapup(tmp_path, "fly", spec)
    assert code == 1 and len(lines) == 1, lines
    assert lines[0].startswith(f"seapup: error: {spec}: ") and reason in lines[0], lines
    assert "Error:" not in lines[0] and rss_mb < RSS_BOUND_MB


@pytest.mark.process
def test_a_campaign_of_ten_million_runs_is_refused_from_its_counts(tmp_path):
    """Before issue 40 a 7-key grid of 10^7 runs gave no answer in 30-120 s and grew past 1.5-2.6 GB."""
    grid = "\n".join(f"  {key}: [0, 1, 2, 3, 4, 5, 6, 7, 8, 9]" for key in "abcdefg")
    path = tmp_path / "huge.yaml"
    path.write_text(f"name: huge\nbase: {{spec: {{duration: 2.0}}}}\ngrid:\n{grid}\n")
    code, lines, rss_mb, cpu_s = _seapup(tmp_path, "campaign", path, "--out", tmp_path / "out")
    assert code == 1 and len(lines) == 1, lines
    assert lines[0].startswith("seapup: error: huge: 1e+07 runs (10 a x 10 b x 10 c") and "100,000" in lines[0]
    assert rss_mb < RSS_BOUND_MB and cpu_s < CPU_BOUND_S, (rss_mb, cpu_s)
    assert not (tmp_path / "out").exists()


@pytest.mark.process
def test_fly_of_a_start_outside_the_envelope_says_why_not_the_exception_s_name(tmp_path):
    """Before issue 40: 'seapup fly: error: DivergenceError: state z = ...'."""
    spec = tmp_path / "deep.yaml"
    spec.write_text("start_state: [0, 0, 100000.0, 0, 0, 0, 0, 0, 0, 0, 0, 0]\nduration: 1.0\n")
    code, lines, _, _ = _seapup(tmp_path, "fly", spec)
    assert code == 1 and len(lines) == 1, lines
    assert lines[0].startswith("seapup: error: state z = ") and "outside the valid envelope" in lines[0]
