"""What every ``./seapup`` command shares: one line and exit 128 + signal when interrupted (after the
command's own clean-up), quiet on a closed pipe, one line for an unexpected error (a traceback only with
``--debug``), and ``ROS_DOMAIN_ID`` checked before DDS sees it."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from seapup_bringup import cli, output

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def fake_command(monkeypatch):
    """Register a throw-away command ``probe`` whose body the test supplies; restore the handlers."""
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    monkeypatch.setattr(output, "SIGNALS", [])

    def register(body):
        monkeypatch.setitem(cli.COMMANDS, "probe", cli.Entry("probe", "test", "", body, True))
    yield register
    for s, handler in saved.items():
        signal.signal(s, handler)


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143), (signal.SIGHUP, 129)])
def test_a_signal_runs_the_commands_clean_up_then_says_interrupted(fake_command, capsys, sig, code):
    cleaned = []

    def body(argv):
        try:
            os.kill(os.getpid(), sig)
            time.sleep(5)  # the handler raises here
            return 0
        finally:
            cleaned.append(True)
    fake_command(body)
    assert cli.main(["probe"]) == code
    assert cleaned == [True]
    assert capsys.readouterr().err == "seapup: interrupted\n"


@pytest.mark.parametrize("then_progress", [True, False])
def test_a_stop_signal_a_library_swallowed_still_stops_the_command(fake_command, capsys, then_progress):
    """The handler's KeyboardInterrupt can land where a library swallows it (inside a ``__del__``: a campaign
    once flew on to its end and exited 0 after a Ctrl-C). Long work stops at its next progress step, and a
    command that returns anyway still says it was interrupted -- never exit 0 after a Ctrl-C."""
    steps = []

    def body(argv):
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5)
        except KeyboardInterrupt:
            pass   # swallowed, as by a library
        if then_progress:
            for k in range(10):
                output.progress("work", k / 10)
                steps.append(k)
        return 0
    fake_command(body)
    assert cli.main(["probe"]) == 130
    assert steps == []   # the first progress step stopped it
    assert capsys.readouterr().err.splitlines()[-1] == "seapup: interrupted"


def test_an_error_raised_while_a_signal_is_handled_still_counts_as_interrupted(fake_command, capsys):
    """rclpy/pybind11 may turn an interrupted wait into another exception ("Unable to convert call
    argument"): it is the interruption, not a failure, that the user is told about."""
    def body(argv):
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5)
        except KeyboardInterrupt:
            raise TypeError("Unable to convert call argument") from None
    fake_command(body)
    assert cli.main(["probe"]) == 130
    assert capsys.readouterr().err == "seapup: interrupted\n"


def test_an_unexpected_error_is_one_line_and_a_traceback_only_with_debug(fake_command, capsys, monkeypatch):
    def body(argv):
        raise ValueError("the sea is dry\nsecond line")
    fake_command(body)
    monkeypatch.delenv("SEAPUP_DEBUG", raising=False)
    assert cli.main(["probe"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "ValueError: the sea is dry" in err and "--debug" in err
    with pytest.raises(ValueError, match="the sea is dry"):
        cli.main(["--debug", "probe"])


def test_a_closed_pipe_ends_the_command_quietly(fake_command, capsys, monkeypatch):
    def body(argv):
        raise BrokenPipeError(32, "Broken pipe")
    fake_command(body)
    assert cli.main(["probe"]) == 128 + signal.SIGPIPE
    assert capsys.readouterr().err == ""
    monkeypatch.setattr(sys, "stdout", sys.__stdout__)


@pytest.mark.process
@pytest.mark.parametrize("value", ["233", "300", "-1", "abc", "1.5"])
def test_a_bad_domain_id_is_refused_before_dds_sees_it(value):
    run = subprocess.run([str(ROOT / "seapup"), "topic", "list"], capture_output=True, text=True, timeout=300,
                         env={**os.environ, "ROS_DOMAIN_ID": value})
    assert run.returncode == 2
    assert run.stderr.strip().splitlines()[-1].startswith("seapup: error: ROS_DOMAIN_ID must be an integer 0-232")
    assert "Traceback" not in run.stderr and "rmw" not in run.stderr.lower()


def test_domain_ids_that_ros_accepts_pass():
    assert all(cli.domain_problem(v) == "" for v in (None, "", " ", "0", "101", "232"))


def test_ctrl_c_in_the_demo_reports_what_was_flown_and_leaves_no_node(tmp_path, ros_env):
    """Interrupted while its graph runs, the demo stops every node, writes its summary (legs flown so
    far, ``interrupted``) and ends with one line and exit 130."""
    from tests.test_process_ownership import descendants, gone_within
    demo = subprocess.Popen([str(ROOT / "seapup"), "demo", "--out", str(tmp_path / "demo"), "--no-plots"],
                            env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and not (tmp_path / "demo" / "self_test.log").is_file() and demo.poll() is None:
        time.sleep(0.2)  # the graph is starting: its nodes exist
    time.sleep(3.0)
    assert demo.poll() is None, demo.communicate()[1][-2000:]   # still flying (not failed at its start)
    nodes = descendants(demo.pid)
    assert len(nodes) >= 5, nodes
    os.kill(demo.pid, signal.SIGINT)
    _, err = demo.communicate(timeout=120)
    assert demo.returncode == 130, err[-2000:]
    assert err.rstrip().splitlines()[-1] == "seapup: interrupted" and "Traceback" not in err
    assert gone_within(nodes, 2.0)
    summary = json.loads((tmp_path / "demo" / "summary.json").read_text())
    assert summary["interrupted"] is True and isinstance(summary["legs"], list)


def test_an_unknown_command_is_one_line_with_the_nearest_commands(capsys):
    """Before: the whole usage (56 lines) followed the unknown name."""
    assert cli.main(["--check", "campain"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("seapup: unknown command 'campain': did you mean campaign")
    assert cli.main(["qqqqqq"]) == 2
    assert capsys.readouterr().err == "seapup: unknown command 'qqqqqq': ./seapup help lists the commands\n"


@pytest.mark.parametrize("name", ["setup", "env", "lock", "help", "run"])
def test_help_of_the_commands_parsed_before_the_bootstrap_prints_only_help(capsys, name):
    """--check answers 3 (help printed: the script stops there), and a direct call exits 0."""
    assert cli.main(["--check", name, "--help"]) == 3
    out = capsys.readouterr()
    assert out.out.startswith(f"usage: ./seapup {name}") and out.err == ""
    assert cli.main([name, "--help"]) == 0


@pytest.mark.parametrize("argv", [["setup", "x"], ["env", "--bogus"], ["lock", "now"], ["run"], ["run", "pkg"],
                                  ["help", "nosuchcommand"]])
def test_bad_usage_exits_2(capsys, argv):
    """Before: ./seapup run without arguments exited 1, and setup/env/lock ignored their arguments."""
    assert cli.main(["--check", *argv]) == 2
    assert cli.main(argv) == 2
    assert "Traceback" not in capsys.readouterr().err


def test_run_passes_everything_after_the_executable_to_the_node():
    args = cli.run_parser().parse_args(["seapup_sim", "simulator", "--ros-args", "-p", "mode:=realtime", "--help"])
    assert (args.package, args.executable) == ("seapup_sim", "simulator")
    assert args.args == ["--ros-args", "-p", "mode:=realtime", "--help"]


def _interrupt_after(argv, started: str, workers: int = 0):
    """Start ``./seapup ARGV`` (the registry, in its own process group), wait for the line ``started`` (its
    work has begun), then press Ctrl-C: SIGINT to the whole group, as a terminal does. Its processes at that
    moment, its exit status and everything it wrote after the line. With ``workers``, wait for that many
    processes below it first."""
    from tests.test_process_ownership import descendants
    proc = subprocess.Popen([sys.executable, "-m", "seapup_bringup.cli", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, start_new_session=True)
    before = []
    for line in proc.stdout:
        before.append(line)
        if started in line:
            break
    assert proc.poll() is None, "".join(before)
    deadline = time.monotonic() + 60   # and its worker processes have started (when it has some)
    while len(descendants(proc.pid)) < workers and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    children = descendants(proc.pid)
    assert len(children) >= workers, "".join(before)
    assert proc.poll() is None, f"{argv[0]} ended before its Ctrl-C (make its work longer): {''.join(before)[-500:]}"
    os.killpg(proc.pid, signal.SIGINT)
    try:
        after, _ = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        raise AssertionError(f"{argv[0]} did not stop after Ctrl-C: {proc.communicate()[0][-2000:]}") from None
    return children, proc.returncode, after


@pytest.mark.process
def test_an_interrupted_command_does_not_wait_for_threads_a_library_left(tmp_path):
    """A library thread that never ends (Dask's, once) kept an interrupted campaign from exiting after
    'seapup: interrupted': the process leaves once the command's clean-up has run."""
    probe = tmp_path / "probe.py"
    probe.write_text(
        "import sys, threading, time\n"
        "from seapup_bringup import cli\n"
        "def body(argv):\n"
        "    threading.Thread(target=threading.Event().wait, daemon=False).start()\n"
        "    print('started', flush=True)\n"
        "    time.sleep(60)\n"
        "    return 0\n"
        "cli.COMMANDS['probe'] = cli.Entry('probe', 'test', '', body, True)\n"
        "sys.argv = ['cli', 'probe']\n"
        "cli.run_main()\n")
    proc = subprocess.Popen([sys.executable, str(probe)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True)
    assert proc.stdout.readline() == "started\n"
    os.killpg(proc.pid, signal.SIGINT)
    try:
        out, _ = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        raise AssertionError("the interrupted command waited for a leftover thread") from None
    assert proc.returncode == 130 and out == "seapup: interrupted\n"


def _lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("campaign  ")
            and not line.lstrip().startswith("report  ")]   # progress bars aside


@pytest.mark.process
def test_ctrl_c_on_a_campaign_stops_its_dask_workers_with_one_line(tmp_path):
    """Before: every Dask worker got the Ctrl-C too and printed a screen of KeyboardInterrupt and
    CancelledError tracebacks (about 90 lines), and the command waited for the tasks in flight."""
    from tests.test_process_ownership import gone_within
    # all 108 runs (about 80 s of a loaded suite uninterrupted): 48 were once all flown, in 17.6 s, before the
    # Ctrl-C of a loaded suite came; interrupted, it ends within a second or two as before
    children, code, after = _interrupt_after(["campaign", "controller-robustness", "--workers", "2",
                                              "--out", str(tmp_path / "c")], "flying on", workers=2)
    assert code == 130 and _lines(after) == ["seapup: interrupted"], after
    assert gone_within(children, 5.0)


def _dask_workers(pid: int) -> set[int]:
    """The Dask worker processes below ``pid`` (multiprocessing's spawned children, its trackers aside)."""
    from tests.test_process_ownership import descendants
    found = set()
    for child in descendants(pid):
        try:
            if b"spawn_main" in Path(f"/proc/{child}/cmdline").read_bytes():
                found.add(child)
        except OSError:
            continue
    return found


def _ignores_sigint(pid: int) -> bool:
    try:
        fields = dict(line.split(":", 1) for line in Path(f"/proc/{pid}/status").read_text().splitlines())
    except OSError:
        return False
    return bool(int(fields["SigIgn"], 16) & (1 << (signal.SIGINT - 1)))


@pytest.mark.process
def test_ctrl_c_is_the_command_s_alone_even_for_a_worker_the_nanny_restarts(tmp_path):
    """The campaign's Dask workers ignore SIGINT -- those started with the cluster (they inherit it ignored)
    and one the nanny starts after a worker died (its preload): a SIGINT that reaches only them changes
    nothing -- the same workers fly to the end, none is started in place of one -- and the campaign ends as
    if none came. Before: the workers took it (SIGINT neither blocked nor ignored in them, whatever the
    command's mask), finished the task in hand and left, the nanny started none in their place, and the
    command waited for ever (seen about once in ten Ctrl-Cs, when the command's own SIGKILL came late)."""
    proc = subprocess.Popen([sys.executable, "-m", "seapup_bringup.cli", "campaign", "controller-robustness",
                             "--limit", "48", "--workers", "2", "--out", str(tmp_path / "c")],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        for line in proc.stdout:
            if "flying on" in line:
                break
        deadline = time.monotonic() + 30
        while len(_dask_workers(proc.pid)) < 2 and time.monotonic() < deadline:
            time.sleep(0.05)
        first = _dask_workers(proc.pid)
        assert len(first) == 2 and proc.poll() is None, first
        for pid in first:
            os.kill(pid, signal.SIGINT)
        os.kill(min(first), signal.SIGKILL)    # the nanny starts another: it must ignore SIGINT too
        while not _dask_workers(proc.pid) - first and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.05)
        restarted = _dask_workers(proc.pid) - first
        assert restarted, "the nanny started no worker in place of the killed one"
        while not all(map(_ignores_sigint, restarted)) and time.monotonic() < deadline:
            time.sleep(0.05)   # its preload runs while it starts
        assert all(map(_ignores_sigint, restarted)), "the restarted worker takes SIGINT"
        for pid in restarted:
            os.kill(pid, signal.SIGINT)
        after, _ = proc.communicate(timeout=90)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 0 and "48 of 48 runs flown (0 failed)" in after, after[-2000:]
    assert "Traceback" not in after and "KeyboardInterrupt" not in after, after[-2000:]


@pytest.mark.process
def test_ctrl_c_on_a_report_drops_the_runs_in_flight_with_one_line(tmp_path):
    """Before: the pool's workers finished every run first (25-45 s of silence) and wrote them to the cache."""
    cache = tmp_path / "cache"
    children, code, after = _interrupt_after(["report", "--no-cache", "--cache", str(cache), "--out",
                                              str(tmp_path / "r"), "--chapters", "5", "--jobs", "2"], "report:", workers=2)
    assert code == 130 and _lines(after) == ["seapup: interrupted"], after
    assert list(cache.rglob("run.json")) == [], "runs went on after Ctrl-C"


@pytest.mark.process
def test_ctrl_c_on_a_graph_run_stops_its_nodes_at_once_with_one_line(tmp_path):
    """``fly --graph`` interrupted: the graph's nodes get SIGTERM (a prompt stop: no drain, no waiting for
    acknowledgements) and the command says one line. Before: SIGINT and its 5 s grace, 2-3 s per Ctrl-C, and
    an interrupt that rclpy turned into another exception stopped the graph as if nothing had happened."""
    from tests.test_process_ownership import gone_within
    spec = tmp_path / "long.yaml"
    spec.write_text("name: long\nvehicle: baseline\ncontrol_period: 0.2\nduration: 400.0\ncontroller: {type: hold}\n"
                    "reference: [[0.0, 0.0, 0.0, 0.0, 0.0]]\n")
    children, code, after = _interrupt_after(["fly", str(spec), "--graph", "--out", str(tmp_path / "run")],
                                             "10.0%", workers=2)
    assert code == 130 and [line for line in _lines(after) if "long  " not in line] == ["seapup: interrupted"], after
    assert gone_within(children, 5.0)
    logs = "".join(p.read_text(errors="replace") for p in (tmp_path / "run").glob("*.log"))
    assert "Traceback" not in logs, logs[-2000:]


#: A command whose clean-up, after the Ctrl-C, drops an object whose finaliser fails and a coroutine never
#: awaited -- what Dask's futures and rclpy's executor left behind when a campaign or a graph run was interrupted.
_NOISY_TEARDOWN = """
import os, signal, sys, time
from types import SimpleNamespace
from seapup_bringup import cli

class HalfBuilt:
    def __del__(self):
        raise AttributeError("'Future' object has no attribute '_cleared'")

async def callback():
    pass

def run(argv):
    left = [HalfBuilt(), callback()]
    try:
        print("started", flush=True)
        time.sleep(30)
    finally:
        left.clear()
    return 0

sys.exit(cli._dispatch(SimpleNamespace(name="noisy", run=run), [], debug=len(sys.argv) > 1))
"""


@pytest.mark.process
def test_an_interrupted_command_says_one_line_whatever_its_libraries_leave_behind():
    """Ctrl-C: the libraries' teardown noise (an unraisable exception in a finaliser, a coroutine never awaited)
    does not reach the user -- only ``seapup: interrupted``, exit 130 (seen on a fresh clone: a Dask future's
    ``__del__`` traceback, rclpy's RuntimeWarning); with ``--debug`` they still show."""
    import signal
    for debug in (False, True):
        popen = subprocess.Popen([sys.executable, "-c", _NOISY_TEARDOWN, *(["debug"] if debug else [])],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=dict(os.environ))
        assert popen.stdout.readline().strip() == "started"
        popen.send_signal(signal.SIGINT)
        out, err = popen.communicate(timeout=30)
        assert popen.returncode == 130, err
        if debug:
            assert "Exception ignored in" in err and "never awaited" in err, err
        else:
            assert err.splitlines() == ["seapup: interrupted"], err
