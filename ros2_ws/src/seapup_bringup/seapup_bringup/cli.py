"""The ``./seapup`` command registry: one function per command.

``./seapup`` (bash) only bootstraps (``setup``, ``env``, ``lock``) and hands
every other command to :func:`main`. A command is a function registered with
:func:`command`; its help line comes from the registry, so a new command is a
new function here, not an edit to the bash script. This module imports only
the standard library at the top, so ``help`` and unknown commands answer on
a fresh clone before any bootstrap (``--check``).

Conventions for every command: ``--help`` explains it; ``--json [FILE]``
writes its result as JSON to FILE (to standard output with no FILE, and the
human text then goes to standard error); long work shows a progress bar on a
terminal (a line per 10 % otherwise); exit 0 on success, 1 on failure, 2 on
bad usage. :func:`main` holds what every command shares: Ctrl-C (or SIGTERM,
or SIGHUP from a closed terminal) ends a command with one line,
``seapup: interrupted``, and exit 128 + the signal (130 for Ctrl-C), after
the command's own clean-up ran (its context managers stop its nodes); a
closed output pipe (``| head``) ends it quietly; an unexpected error is one
line naming it (the traceback only with ``--debug`` before the command, or
``SEAPUP_DEBUG=1``); and ``ROS_DOMAIN_ID`` is checked before DDS sees it.
The helpers for these conventions live in
:mod:`seapup_bringup.output`; command modules import them from there and never
import this registry back.
"""
from __future__ import annotations

import os
import signal
import sys
from dataclasses import dataclass
from typing import Callable

__all__ = ["command", "COMMANDS", "main"]


@dataclass(frozen=True)
class Entry:
    """One ``./seapup`` command.

    ``parser`` names the function that builds the command's ``argparse`` parser (``"module:function"``):
    :mod:`seapup_bringup.cli_usage` imports it to generate the usage lines of ``./seapup help``
    (``cli_usage.json``) and the command tables of README.md and docs/command-line.md, so they cannot
    drift from what the command accepts. ``run`` is None for the commands the bash script carries out
    (``setup``, ``env``, ``lock``) and for ``help``; ``doc`` is the page (under docs/) that explains it.
    """
    name: str
    summary: str
    parser: str
    run: Callable[[list[str]], int] | None   # None: implemented by the bash script (or help)
    bootstrap: bool
    doc: str = ""


COMMANDS: dict[str, Entry] = {}

#: The generated usage lines (``python -m seapup_bringup.cli_usage --write`` regenerates it).
USAGE_FILE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "cli_usage.json")


def command(name: str, summary: str, parser: str = "", *, bootstrap: bool = True, doc: str = ""):
    """Register ``fn(argv) -> exit code`` as ``./seapup <name>``; ``parser`` names its parser's builder."""
    def register(fn):
        COMMANDS[name] = Entry(name, summary, parser, fn, bootstrap, doc)
        return fn
    return register


def _shell(name: str, summary: str, parser: str, doc: str) -> None:
    COMMANDS[name] = Entry(name, summary, parser, None, name not in ("lock", "help"), doc)


# -- the parsers of the commands that answer before the bootstrap (standard library only) ----------
def _stdlib_parser(name: str, description: str, epilog: str = "", **kwargs):
    import argparse
    return argparse.ArgumentParser(prog=f"./seapup {name}", description=description, epilog=epilog or None,
                                   **kwargs)


def setup_parser():
    """``./seapup setup``: no arguments."""
    return _stdlib_parser("setup", "Bootstrap only: create .venv from requirements/lock.txt when the lock "
                          "changed, colcon-build the packages whose sources changed, then say so.",
                          "Idempotent; docs/building.md explains each step.")


def env_parser():
    """``./seapup env``: no arguments."""
    return _stdlib_parser("env", "Bootstrap, then print the environment as export lines: "
                          "eval \"$(./seapup env)\" makes this shell a seapup workspace.")


def lock_parser():
    """``./seapup lock``: no arguments."""
    return _stdlib_parser("lock", "Resolve requirements/seapup.in in a scratch virtual environment (removed "
                          "afterwards, also when interrupted) and write the exact pins to requirements/lock.txt.",
                          "Needs network access to PyPI; the next command then rebuilds .venv.")


def help_parser():
    """``./seapup help [COMMAND]``."""
    parser = _stdlib_parser("help", "The commands and their usage (from cli_usage.json, generated from each "
                            "command's parser); answers before any bootstrap.")
    parser.add_argument("command", nargs="?", help="only this command's usage line")
    return parser


def test_parser():
    """``./seapup test [pytest args...]``: every argument goes to pytest (``--help`` shows pytest's help)."""
    import argparse
    parser = _stdlib_parser("test", "Run the test suite with pytest from the checkout; every argument is "
                            "pytest's (so ./seapup test --help shows pytest's help).",
                            "Needs Chromium (the report page is rendered in it; SEAPUP_CHROMIUM names another "
                            "binary). Ends with pytest's summary line.", add_help=False,
                            usage="%(prog)s [pytest args...] (--help: pytest's help)")
    parser.add_argument("pytest_args", nargs=argparse.REMAINDER, metavar="PYTEST_ARG")
    return parser


def run_parser():
    """``./seapup run PKG EXE [args...]``."""
    import argparse
    parser = _stdlib_parser("run", "Start one node of the workspace, like 'ros2 run' on a ROS install.",
                            "Example: ./seapup run seapup_sim simulator --ros-args -p mode:=realtime")
    parser.add_argument("package", help="the package, e.g. seapup_sim")
    parser.add_argument("executable", help="its executable, e.g. simulator")
    rest = parser.add_argument("args", nargs=argparse.REMAINDER, help="passed to the node (e.g. --ros-args ...)")
    rest.required = False   # argparse counts a REMAINDER as required, and would name it when the others are missing
    return parser


#: The commands whose arguments ``--check`` parses before the bootstrap (their parsers are above).
_PARSED_BEFORE_BOOTSTRAP = ("setup", "env", "lock", "help", "run")


# -- the commands ----------------------------------------------------------------------
_shell("setup", "only bootstrap: .venv, wheel fix, colcon build", "seapup_bringup.cli:setup_parser",
       "building.md#what-the-bootstrap-does")
_shell("env", "print the exports; use: eval \"$(./seapup env)\"", "seapup_bringup.cli:env_parser",
       "building.md#the-environment")
_shell("lock", "regenerate requirements/lock.txt from seapup.in", "seapup_bringup.cli:lock_parser",
       "building.md#the-lock")


@command("demo", "the main demonstration: the self-tested Seapup flies a mission through the supervisory "
         "hierarchy (self-test, hover + controller swap, goto, inspection, seabed following, station keeping "
         "in current, a fouled thruster and the switch to a self-tuner), recorded, with a table and plots",
         "seapup_bringup.verbs.demo:demo_parser", doc="hierarchy.md#the-demo-mission")
def _demo(argv: list[str]) -> int:
    from seapup_bringup.verbs.demo import main as demo
    return demo(argv)


@command("open-loop", "open-loop manoeuvres through the graph, recorded (the plant alone; bags/demo_120s)",
         "seapup_bringup.graph.open_loop:open_loop_parser", doc="recording.md#reference-bags")
def _open_loop(argv: list[str]) -> int:
    from seapup_bringup.graph.open_loop import main as open_loop
    return open_loop(argv)


@command("ident", "system identification (ch. 6): experiment in SIL or in process, fit / orders / compare / "
         "residuals from a bag, a run result or CSV", "seapup_bringup.verbs.ident_commands:ident_parser",
         doc="identification.md")
def _ident(argv: list[str]) -> int:
    from seapup_bringup.verbs.ident_commands import main as ident
    return ident(argv)


@command("test", "run every test; ends with pytest's summary line (-m unit: pure cores only; arguments and "
         "--help are pytest's)", "seapup_bringup.cli:test_parser", doc="building.md#tests")
def _test(argv: list[str]) -> int:
    root = os.environ.get("SEAPUP_ROOT", ".")
    os.chdir(root)
    os.execvp(sys.executable, [sys.executable, "-m", "pytest", *pytest_arguments(argv)])
    return 1  # not reached


#: Options with which pytest runs in this process only: given one, ./seapup test adds no workers.
SERIAL_OPTIONS = ("-n", "--numprocesses", "--dist", "-h", "--help", "--co", "--collect-only", "--version",
                  "--pdb", "--trace", "--fixtures", "--markers", "-x", "--exitfirst", "--maxfail", "--lf", "--sw")


def pytest_arguments(argv: list[str], cpus: int | None = None) -> list[str]:
    """``./seapup test``'s pytest arguments: the given ones, and -- unless they choose for themselves (an option
    of :data:`SERIAL_OPTIONS`, or ``-p no:xdist``) -- one pytest-xdist worker per CPU, whole files to a worker
    (``--dist loadfile``: a file's fixtures are set up once and its graph tests never run beside each other).

    The graph tests wait on discovery, pacing and timers: with a worker per CPU the two CPUs of the reference
    machine were busy 78 % of the suite's time (14 min 7 s), and one worker more took 13 min 3 - 13 min 28 s
    (``-n 3 --dist loadfile`` asks for it). It is not the default: its load showed defects a worker per CPU
    rarely meets (a paced hierarchy flown beside two burners left its quiet twin at t = 10.8 s: a goal's first
    setpoint could reach the position controller after the next estimate, mended by the stream-start
    acknowledgements), and its graph tests' wall-clock bounds were measured at a worker per CPU.

    Examples
    --------
    >>> pytest_arguments(["-m", "unit"], cpus=2)
    ['-n', '2', '--dist', 'loadfile', '-m', 'unit']
    >>> pytest_arguments(["-x", "tests/test_demo.py"], cpus=2)
    ['-x', 'tests/test_demo.py']
    >>> pytest_arguments(["-m", "unit"], cpus=1)
    ['-m', 'unit']
    """
    cpus = cpus if cpus is not None else len(os.sched_getaffinity(0))
    chosen = any(a.split("=", 1)[0] in SERIAL_OPTIONS or (a.startswith("-n") and a[2:].isdigit()) for a in argv)
    if chosen or cpus < 2 or "no:xdist" in " ".join(argv):
        return list(argv)
    return ["-n", str(cpus), "--dist", "loadfile", *argv]


@command("run", "start one node, like 'ros2 run' on a ROS install", "seapup_bringup.cli:run_parser",
         doc="command-line.md#the-ros-2-verbs")
def _run(argv: list[str]) -> int:
    from seapup_common.processes import find_executable
    args = run_parser().parse_args(argv)   # bad usage: one line and exit 2 (argparse)
    try:
        path = find_executable(args.package, args.executable)
    except FileNotFoundError as exc:
        print(f"seapup: error: {exc}", file=sys.stderr)
        return 1
    os.execv(str(path), [str(path), *args.args])
    return 1  # not reached


@command("view", "watch the running graph (this domain) in Foxglove or Lichtblick: a WebSocket server on "
         "127.0.0.1 with the vehicle, its frames, track, current, seabed and plots", "seapup_bringup.verbs.view_commands:view_parser",
         doc="live-view.md")
def _view(argv: list[str]) -> int:
    from seapup_bringup.verbs.view_commands import view_command
    return view_command(argv)


@command("teleop", "fly the vehicle by hand from the keyboard: the pilot's Twist for a manual velocity controller", "seapup_bringup.verbs.view_commands:teleop_parser", doc="vehicles.md#manual-flight")
def _teleop(argv: list[str]) -> int:
    from seapup_bringup.verbs.view_commands import teleop_command
    return teleop_command(argv)


@command("verify", "open-loop verification of the vehicle model against the thesis",
         "seapup_bringup.verbs.model_commands:verify_parser", doc="model.md#verification-against-the-thesis")
def _verify(argv: list[str]) -> int:
    from seapup_bringup.verbs.model_commands import verify
    return verify(argv)


@command("report", "the thesis's targets scored against runs of this code (flown fresh, or taken from the run "
         "cache: the page and the summary say which): report.json and one HTML page (chapters, figures, "
         "deviation register)", "seapup_bringup.verbs.report_commands:report_parser", doc="reproduction.md#the-report")
def _report(argv: list[str]) -> int:
    from seapup_bringup.verbs.report_commands import report_command
    return report_command(argv)


@command("check-model", "model checker (symmetry, damping, stability)", "seapup_bringup.verbs.model_commands:check_model_parser",
         doc="model.md#the-equations-seapup_sim")
def _check_model(argv: list[str]) -> int:
    from seapup_bringup.verbs.model_commands import check_model
    return check_model(argv)


@command("bench", "benchmarks (model, umbilical, verify, report, control laws, ROS graph)",
         "seapup_bringup.verbs.model_commands:bench_parser", doc="model.md#benchmarks")
def _bench(argv: list[str]) -> int:
    from seapup_bringup.verbs.model_commands import bench
    return bench(argv)


@command("selftest", "the self-test through the action in SIL (recorded), in process, or refitted from a bag",
         "seapup_bringup.verbs.autopilot_commands:selftest_parser", doc="autopilot.md#the-self-test")
def _selftest(argv: list[str]) -> int:
    from seapup_bringup.verbs.autopilot_commands import selftest
    return selftest(argv)


@command("closed-loop", "closed-loop eigenvalues over surge speed under the self-tested controller (sec. 5.4.1)",
         "seapup_bringup.verbs.autopilot_commands:closed_loop_parser", doc="autopilot.md#closed-loop-eigenvalues")
def _closed_loop(argv: list[str]) -> int:
    from seapup_bringup.verbs.autopilot_commands import closed_loop_command
    return closed_loop_command(argv)


@command("scenario", "a closed-loop case of the thesis (sec. 5.4, 7.4) flown by a registered controller "
         "(default the self-tested one)", "seapup_bringup.verbs.scenario_commands:scenario_parser",
         doc="autopilot.md#scenarios-sec-54")
def _scenario(argv: list[str]) -> int:
    from seapup_bringup.verbs.scenario_commands import scenario_command
    return scenario_command(argv)


@command("fly", "fly a run specification (YAML/JSON: vehicle, controller by name, reference, events) in process "
         "or through the ROS graph; the run-result JSON", "seapup_bringup.verbs.run_commands:fly_parser",
         doc="run-result.md#the-run-specification")
def _fly(argv: list[str]) -> int:
    from seapup_bringup.verbs.run_commands import fly
    return fly(argv)


@command("campaign", "a Monte Carlo campaign: a run spec x a grid and random draws x seeds, flown on Dask "
         "(a LocalCluster or --scheduler ADDRESS); a Parquet table and a page of distributions and worst runs",
         "seapup_bringup.verbs.campaign_commands:_parser", doc="campaigns.md")
def _campaign(argv: list[str]) -> int:
    from seapup_bringup.verbs.campaign_commands import campaign_command
    return campaign_command(argv)


@command("controllers", "the registered velocity controllers (control laws by name) and their parameters",
         "seapup_bringup.verbs.run_commands:controllers_parser", doc="run-result.md#controllers-by-name")
def _controllers(argv: list[str]) -> int:
    from seapup_bringup.verbs.run_commands import controllers
    return controllers(argv)


@command("record", "record topics into a rosbag2/MCAP bag (Ctrl-C finalises it)",
         "seapup_bringup.ros2cli.bag_commands:record_parser", doc="recording.md")
def _record(argv: list[str]) -> int:
    from seapup_bringup.ros2cli.bag_commands import record
    return record(argv)


@command("bag", "bag info DIR (what ros2 bag info shows) | bag recover DIR (after a crash)",
         "seapup_bringup.ros2cli.bag_commands:bag_parser", doc="recording.md")
def _bag(argv: list[str]) -> int:
    from seapup_bringup.ros2cli.bag_commands import bag
    return bag(argv)


@command("replay", "publish a bag's messages with their recorded QoS and timing, or lockstep into a node",
         "seapup_bringup.ros2cli.bag_commands:replay_parser", doc="recording.md#replay")
def _replay(argv: list[str]) -> int:
    from seapup_bringup.ros2cli.bag_commands import replay
    return replay(argv)


def _ros2_verb(name: str, summary: str):
    def run(argv: list[str]) -> int:
        from seapup_bringup.ros2cli import ros2_commands
        return getattr(ros2_commands, name)(argv)
    command(name, summary, f"seapup_bringup.ros2cli.ros2_commands:{name}_parser", doc="command-line.md#the-ros-2-verbs")(run)


@command("launch", "start a graph from a ROS 2 YAML launch file, as 'ros2 launch' (Ctrl-C stops them all)",
         "seapup_bringup.ros2cli.launch:launch_parser", doc="command-line.md#launch-graphs")
def _launch(argv: list[str]) -> int:
    from seapup_bringup.ros2cli.launch import launch
    return launch(argv)


_ros2_verb("topic", "topics, as 'ros2 topic'")
_ros2_verb("node", "nodes, as 'ros2 node'")
_ros2_verb("param", "parameters, as 'ros2 param'")
_ros2_verb("service", "services, as 'ros2 service'")
_ros2_verb("action", "actions, as 'ros2 action'")
_ros2_verb("interface", "interface definitions, as 'ros2 interface show'")
_shell("help", "this list, from the registry (answers before any bootstrap)", "seapup_bringup.cli:help_parser",
       "command-line.md")


def usage_lines() -> dict:
    """The generated usage line of each command (``cli_usage.json``); {} when the file is missing or unreadable."""
    import json
    try:
        with open(USAGE_FILE, encoding="utf-8") as f:
            data = json.load(f)
        return {str(k): str(v) for k, v in data.get("usage", {}).items()} if isinstance(data, dict) else {}
    except (OSError, ValueError):
        return {}


def usage(only: str | None = None) -> str:
    """``./seapup help``: every command (or ``only``) with its generated usage line and its summary."""
    import textwrap
    synopsis = usage_lines()
    entries = [COMMANDS[only]] if only else list(COMMANDS.values())
    lines = [] if only else ["usage: ./seapup <command> [args...]", ""]
    for e in entries:
        head = f"./seapup {e.name} {synopsis.get(e.name, '')}".rstrip()
        lines += textwrap.wrap(head, 110, initial_indent="  ", subsequent_indent="      ", break_on_hyphens=False)
        lines += textwrap.wrap(e.summary, 110, initial_indent="      ", subsequent_indent="      ",
                               break_on_hyphens=False)
    if not only:
        lines += ["", "Every command takes --help (test passes it to pytest); most write their result as JSON "
                  "with --json [FILE];", "exit 0 on success, 1 on failure, 2 on bad usage; Ctrl-C: one line, "
                  "'seapup: interrupted', exit 130.", "--debug before the command shows an error's traceback. "
                  "Environment: SEAPUP_PYTHON (default python3.11), ROS_DOMAIN_ID (default 0).",
                  "Every process runs with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST."]
    return "\n".join(lines)


def nearest_commands(name: str) -> list[str]:
    """The registered commands nearest to a mistyped ``name`` (at most three, nearest first)."""
    import difflib
    near = difflib.get_close_matches(name, list(COMMANDS), n=3, cutoff=0.5)
    return near or [n for n in COMMANDS if name and n.startswith(name[:2])][:3]


def unknown_command(name: str) -> str:
    """The one line for an unknown command: the nearest commands, or where the list is."""
    near = nearest_commands(name)
    hint = f"did you mean {' or '.join(near)}?" if near else "./seapup help lists the commands"
    return f"seapup: unknown command '{name}': {hint}"


def _parse_before_bootstrap(name: str, argv: list[str]) -> int | None:
    """Parse the arguments of a command whose parser is in this module: 3 after printing its help, 2 on
    bad usage (argparse's two lines), None when they are fine. ``help [COMMAND]`` prints here."""
    parser = globals()[f"{name}_parser"]()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        return 3 if exc.code in (0, None) else 2
    if name == "help":
        if args.command is not None and args.command not in COMMANDS:
            print(unknown_command(args.command), file=sys.stderr)
            return 2
        print(usage(args.command), flush=True)
        return 3
    return None


#: The largest ROS_DOMAIN_ID DDS can map to ports (ROS 2 documents 0-232; 0-101 avoid the Linux
#: ephemeral port range with the default participant limits).
MAX_DOMAIN_ID = 232


def domain_problem(value: str | None) -> str:
    """Why ``value`` (``$ROS_DOMAIN_ID``) cannot be used, or "" (unset or empty means domain 0)."""
    if value is None or value.strip() == "":
        return ""
    try:
        domain = int(value.strip())
    except ValueError:
        domain = -1
    if not 0 <= domain <= MAX_DOMAIN_ID:
        return (f"ROS_DOMAIN_ID must be an integer 0-{MAX_DOMAIN_ID} (0-101 is safe on Linux), got {value!r}; "
                "unset it for domain 0")
    return ""


class Interrupted(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised where the command is, so its clean-up runs as for Ctrl-C."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _closed_pipe() -> int:
    """The reader of our output is gone (``| head``): nothing more to say, and no error when Python
    flushes standard output at exit either (it now points at /dev/null)."""
    try:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    return 128 + signal.SIGPIPE


def _quiet_teardown() -> None:
    """After the user's interrupt, the command's clean-up says nothing of the libraries' own teardown noise:
    objects collected half-built ("Exception ignored in: <function Future.__del__ ...>", a Dask future made as
    the Ctrl-C came) and warnings (rclpy's "coroutine 'await_or_execute' was never awaited", a callback cut
    short) went to the terminal before ``seapup: interrupted`` on a loaded machine. ``--debug`` keeps them."""
    import warnings
    warnings.simplefilter("ignore")
    sys.unraisablehook = lambda unraisable: None


def error_reason(exc: BaseException) -> str:
    """An unexpected error's one line: a file's reason and name for an ``OSError`` ("No such file or directory:
    /x/y"), else the exception's type and first line (an error no verb foresaw, named for a bug report).

    Examples
    --------
    >>> error_reason(FileNotFoundError(2, "No such file or directory", "/x/y"))
    'No such file or directory: /x/y'
    >>> error_reason(ValueError("bad\\nmore"))
    'ValueError: bad'
    """
    if isinstance(exc, OSError) and exc.strerror:
        return f"{exc.strerror}: {exc.filename}" if exc.filename else exc.strerror
    return f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"


def _dispatch(entry: Entry, argv: list[str], debug: bool) -> int:
    """Run a command under the shared conventions (module docstring)."""
    from seapup_bringup.output import SIGNALS

    def on_signal(signum, frame):
        SIGNALS.append(signum)
        if not debug:
            _quiet_teardown()
        raise KeyboardInterrupt if signum == signal.SIGINT else Interrupted(signum)
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, on_signal)
    try:
        code = int(entry.run(argv) or 0)
        if not SIGNALS:
            return code
        signum = SIGNALS[0]   # a stop signal whose exception a library swallowed: the command was still asked to stop
    except KeyboardInterrupt as exc:
        signum = getattr(exc, "signum", signal.SIGINT)
    except BrokenPipeError:
        return _closed_pipe()
    except Exception as exc:
        if not SIGNALS:
            if debug:
                raise
            print(f"seapup {entry.name}: error: {error_reason(exc)} (./seapup --debug {entry.name} ... shows where)",
                  file=sys.stderr)
            return 1
        signum = SIGNALS[0]  # a signal surfaced inside a library as another error (rclpy, pybind11)
    print("seapup: interrupted", file=sys.stderr)
    return 128 + int(signum)


def main(argv: list[str] | None = None) -> int:
    """Dispatch ``argv`` (command first).

    ``--check CMD [ARGS...]`` answers the bash script before its bootstrap: exit 0 if CMD is to run
    (after the bootstrap), 3 if help was printed (``help``, or ``--help`` of a command the script runs
    itself), 2 for an unknown command or bad usage of such a command (one line on standard error).
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    check = bool(argv) and argv[0] == "--check"
    if check:
        argv = argv[1:]
    debug = os.environ.get("SEAPUP_DEBUG", "") not in ("", "0")
    while argv and argv[0] == "--debug":
        debug, argv = True, argv[1:]
    name = argv[0] if argv else "help"
    if name in ("-h", "--help"):
        name, argv = "help", ["help", *argv[1:]]
    entry = COMMANDS.get(name)
    if entry is None:
        print(unknown_command(name), file=sys.stderr)
        return 2
    try:
        if name in _PARSED_BEFORE_BOOTSTRAP:
            parsed = _parse_before_bootstrap(name, argv[1:])
            if parsed is not None:
                return parsed if check or parsed == 2 else 0
    except BrokenPipeError:
        return _closed_pipe()
    if check:
        return 0
    if entry.run is None:
        print(f"seapup: '{name}' is carried out by the ./seapup script", file=sys.stderr)
        return 2
    problem = "" if name == "test" else domain_problem(os.environ.get("ROS_DOMAIN_ID"))
    if problem:
        print(f"seapup: error: {problem}", file=sys.stderr)
        return 2
    return _dispatch(entry, argv[1:], debug)


def run_main() -> None:
    """``python -m seapup_bringup.cli``: :func:`main`, then exit with its status.

    Interrupted, the command's clean-up has run when :func:`main` returns; the process then leaves at
    once (``os._exit`` after flushing) rather than wait at interpreter exit for threads a library left
    behind (Dask's client and cluster threads once hung an interrupted campaign there)."""
    code = main()
    output = sys.modules.get("seapup_bringup.output")
    if output is not None and output.SIGNALS:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os._exit(code)
    sys.exit(code)


if __name__ == "__main__":
    run_main()
