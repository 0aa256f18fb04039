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
    name: str
    summary: str
    usage: str
    run: Callable[[list[str]], int] | None   # None: implemented by the bash script
    bootstrap: bool


COMMANDS: dict[str, Entry] = {}


def command(name: str, summary: str, usage: str = "", *, bootstrap: bool = True):
    """Register ``fn(argv) -> exit code`` as ``./seapup <name>``."""
    def register(fn):
        COMMANDS[name] = Entry(name, summary, usage, fn, bootstrap)
        return fn
    return register


def _shell(name: str, summary: str, usage: str = "") -> None:
    COMMANDS[name] = Entry(name, summary, usage, None, name != "lock")


# -- the commands ----------------------------------------------------------------------
_shell("setup", "only bootstrap: .venv, wheel fix, colcon build")
_shell("env", "print the exports; use: eval \"$(./seapup env)\"")
_shell("lock", "regenerate requirements/lock.txt from seapup.in")


@command("demo", "the main demonstration: the self-tested Seapup flies a mission through the supervisory "
         "hierarchy (self-test, hover + controller swap, goto, inspection, seabed following, station keeping "
         "in current, a fouled thruster and the switch to a self-tuner), recorded, with a table and plots", "[--out DIR] [--json [F]] [--no-plots]")
def _demo(argv: list[str]) -> int:
    from seapup_bringup.demo import main as demo
    return demo(argv)


@command("open-loop", "open-loop manoeuvres through the graph, recorded (the plant alone; bags/demo_120s)",
         "[--duration S] [--out DIR] [--bag DIR] [--json [F]]")
def _open_loop(argv: list[str]) -> int:
    from seapup_bringup.open_loop import main as open_loop
    return open_loop(argv)


@command("ident", "system identification (ch. 6): experiment in SIL, fit / orders / compare from a bag or CSV",
         "experiment [--duration S] [--clock N] [--amplitude DEG] [--current] | fit SOURCE [--method ls|els|rpem] "
         "[--orders na,nb,nc] [--lambda0 L --alpha A | --forgetting F] [--passes N] | orders SOURCE | "
         "compare SOURCE  [--json [F]]")
def _ident(argv: list[str]) -> int:
    from seapup_bringup.ident_commands import main as ident
    return ident(argv)


@command("test", "run every test; ends with pytest's summary line (-m unit: pure cores only)",
         "[pytest args...]")
def _test(argv: list[str]) -> int:
    root = os.environ.get("SEAPUP_ROOT", ".")
    os.chdir(root)
    os.execvp(sys.executable, [sys.executable, "-m", "pytest", *argv])
    return 1  # not reached


@command("run", "start one node, like 'ros2 run' on a ROS install", "<pkg> <exe> [args...]")
def _run(argv: list[str]) -> int:
    from seapup_common.processes import find_executable
    if len(argv) < 2:
        print("seapup: error: run needs a package and an executable: ./seapup run seapup_sim simulator",
              file=sys.stderr)
        return 1
    package, executable = argv[:2]
    try:
        path = find_executable(package, executable)
    except FileNotFoundError as exc:
        print(f"seapup: error: {exc}", file=sys.stderr)
        return 1
    os.execv(str(path), [str(path), *argv[2:]])
    return 1  # not reached


@command("view", "watch the running graph (this domain) in Foxglove or Lichtblick: a WebSocket server on "
         "127.0.0.1 with the vehicle, its frames, track, current, seabed and plots", "[--port P] [--vehicle V] "
         "[--environment-file F] [--write-layout FILE] [--json [F]]")
def _view(argv: list[str]) -> int:
    import argparse
    from seapup_common.processes import find_executable
    parser = argparse.ArgumentParser(prog="./seapup view", description="the live_view node on this domain "
                                     "(docs/live-view.md); Ctrl-C ends it")
    parser.add_argument("--port", type=int, default=8765, help="WebSocket port on 127.0.0.1 (default 8765)")
    parser.add_argument("--vehicle", default="baseline", help="configuration drawn (the simulator's)")
    parser.add_argument("--environment-file", default="", help="the seabed drawn until the simulator's is read")
    parser.add_argument("--write-layout", metavar="FILE", help="write the Foxglove layout (3D, plots, services) to "
                                                               "FILE and exit: import it in Foxglove")
    from seapup_bringup.output import add_json_argument, emit_json
    add_json_argument(parser)
    args = parser.parse_args(argv)
    if args.write_layout:
        from pathlib import Path
        from seapup_bringup.view_layout import layout_json
        Path(args.write_layout).write_text(layout_json())
        print(f"seapup view: layout written to {args.write_layout}", file=sys.stderr)
        emit_json(args, {"layout": args.write_layout})
        return 0
    if not 0 <= args.port <= 65535:
        parser.error(f"--port must be 0..65535, got {args.port}")
    path = find_executable("seapup_bringup", "live_view")
    emit_json(args, {"url": f"ws://127.0.0.1:{args.port}", "port": args.port, "pid": os.getpid()})   # then serves
    os.execv(str(path), [str(path), "--ros-args", "-p", f"port:={args.port}", "-p", f"vehicle:={args.vehicle}",
                         "-p", f"environment_file:={args.environment_file}"])
    return 1  # not reached


@command("verify", "open-loop verification of the vehicle model against the thesis",
         "[--config C] [--json [F]] [--plots DIR]")
def _verify(argv: list[str]) -> int:
    from seapup_bringup.commands import verify
    return verify(argv)


@command("report", "the thesis's targets scored against fresh runs: report.json and one HTML page (chapters, "
         "figures, deviation register)", "[--out DIR] [--chapters 3,5,A] [--jobs N] [--no-cache] [--json [F]]")
def _report(argv: list[str]) -> int:
    from seapup_bringup.report import report_command
    return report_command(argv)


@command("check-model", "model checker (symmetry, damping, stability)", "[--config C] [--json [F]]")
def _check_model(argv: list[str]) -> int:
    from seapup_bringup.commands import check_model
    return check_model(argv)


@command("bench", "benchmarks (model, umbilical, verify, report, control laws, ROS graph)",
         "[--json [F]] [--no-graph] [--no-report] [--recording-minutes M]")
def _bench(argv: list[str]) -> int:
    from seapup_bringup.commands import bench
    return bench(argv)


@command("selftest", "the self-test through the action in SIL (recorded), in process, or refitted from a bag",
         "[--config C] [--rate 5|20] [--speeds 0,0.7] [--mode realistic|artificial] [--in-process] "
         "[--from-bag BAG] [--out DIR] [--bag DIR] [--json [F]]")
def _selftest(argv: list[str]) -> int:
    from seapup_bringup.autopilot_commands import selftest
    return selftest(argv)


@command("closed-loop", "closed-loop eigenvalues over surge speed under the self-tested controller (sec. 5.4.1)",
         "[--rate 5|20] [--schedule] [--config C] [--plots DIR] [--json [F]]")
def _closed_loop(argv: list[str]) -> int:
    from seapup_bringup.autopilot_commands import closed_loop_command
    return closed_loop_command(argv)


@command("scenario", "a closed-loop case of the thesis (sec. 5.4, 7.4) flown by a registered controller (default the self-tested one)",
         "NAME [--controller mfol|explicit|gmv] [--param K=V ...] [--sensors S] [--rate 5|20] [--config C] "
         "[--schedule] [--design self-test|eq-5.3|table-5.1] [--graph] [--plots DIR] [--json [F]] | --list")
def _scenario(argv: list[str]) -> int:
    from seapup_bringup.scenarios import scenario_command
    return scenario_command(argv)


@command("fly", "fly a run specification (YAML/JSON: vehicle, controller by name, reference, events) in process "
         "or through the ROS graph; the run-result JSON", "SPEC [--graph] [--out DIR] [--plots DIR] [--json [F]]")
def _fly(argv: list[str]) -> int:
    from seapup_bringup.run_commands import fly
    return fly(argv)


@command("campaign", "a Monte Carlo campaign: a run spec x a grid and random draws x seeds, flown on Dask "
         "(a LocalCluster or --scheduler ADDRESS); a Parquet table and a page of distributions and worst runs",
         "SPEC.yaml [--scheduler ADDRESS] [--workers N] [--out DIR] [--resume] [--limit N] [--json [F]]")
def _campaign(argv: list[str]) -> int:
    from seapup_bringup.campaign_commands import campaign_command
    return campaign_command(argv)


@command("controllers", "the registered velocity controllers (control laws by name) and their parameters",
         "[--json [F]]")
def _controllers(argv: list[str]) -> int:
    from seapup_bringup.run_commands import controllers
    return controllers(argv)


@command("record", "record topics into a rosbag2/MCAP bag (Ctrl-C finalises it)",
         "[-o DIR] [--topics T...|--all] [--exclude RE] [--max-duration S] [--use-sim-time|--wall-time]")
def _record(argv: list[str]) -> int:
    from seapup_bringup.bag_commands import record
    return record(argv)


@command("bag", "bag info DIR (what ros2 bag info shows) | bag recover DIR (after a crash)", "info|recover DIR")
def _bag(argv: list[str]) -> int:
    from seapup_bringup.bag_commands import bag
    return bag(argv)


@command("replay", "publish a bag's messages with their recorded QoS and timing, or lockstep into a node",
         "DIR [--rate R] [--topics T...] [--clock] [--loop] [--start-offset S] [--lockstep TOPIC]")
def _replay(argv: list[str]) -> int:
    from seapup_bringup.bag_commands import replay
    return replay(argv)


def _ros2_verb(name: str, summary: str, usage_text: str):
    def run(argv: list[str]) -> int:
        from seapup_bringup import ros2_commands
        return getattr(ros2_commands, name)(argv)
    command(name, summary, usage_text)(run)


@command("launch", "start a graph from a ROS 2 YAML launch file, as 'ros2 launch' (Ctrl-C stops them all)",
         "GRAPH.launch.yaml|PKG FILE [name:=value ...] [--show-args] [--view [--view-port P]] [--rate R]")
def _launch(argv: list[str]) -> int:
    from seapup_bringup.launch import launch
    return launch(argv)


_ros2_verb("topic", "topics, as 'ros2 topic'", "list [-t] | info T [-v] | echo T [--once] [--field F] [--csv] | "
           "pub T TYPE 'YAML' [-1|-r HZ] | hz T")
_ros2_verb("node", "nodes, as 'ros2 node'", "list | info NODE")
_ros2_verb("param", "parameters, as 'ros2 param'", "list|dump NODE | get NODE NAME | set NODE NAME VALUE")
_ros2_verb("service", "services, as 'ros2 service'", "list [-t] | call SERVICE TYPE 'YAML'")
_ros2_verb("action", "actions, as 'ros2 action'", "list [-t] | send_goal ACTION TYPE 'YAML' [--feedback]")
_ros2_verb("interface", "interface definitions, as 'ros2 interface show'", "show TYPE")


def usage() -> str:
    lines = ["usage: ./seapup <command> [args...]", ""]
    width = min(max(len(f"{e.name} {e.usage}".strip()) for e in COMMANDS.values()) + 2, 34)
    for e in COMMANDS.values():
        head = f"{e.name} {e.usage}".strip()
        lines.append(f"  {head:<{width}} {e.summary}" if len(head) < width else f"  {head}\n  {'':<{width}} {e.summary}")
    lines.append(f"  {'help':<{width}} this text")
    lines += ["", "Every command takes --help; results as JSON with --json [FILE]; --debug before the command "
              "shows an error's traceback.",
              "Environment: SEAPUP_PYTHON (default python3.11), ROS_DOMAIN_ID (default 0).",
              "Every process runs with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST."]
    return "\n".join(lines)


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


def _dispatch(entry: Entry, argv: list[str], debug: bool) -> int:
    """Run a command under the shared conventions (module docstring)."""
    from seapup_bringup.output import SIGNALS

    def on_signal(signum, frame):
        SIGNALS.append(signum)
        raise KeyboardInterrupt if signum == signal.SIGINT else Interrupted(signum)
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, on_signal)
    try:
        return int(entry.run(argv) or 0)
    except KeyboardInterrupt as exc:
        signum = getattr(exc, "signum", signal.SIGINT)
    except BrokenPipeError:
        return _closed_pipe()
    except Exception as exc:
        if not SIGNALS:
            if debug:
                raise
            print(f"seapup {entry.name}: error: {type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
                  f" (./seapup --debug {entry.name} ... shows where)", file=sys.stderr)
            return 1
        signum = SIGNALS[0]  # a signal surfaced inside a library as another error (rclpy, pybind11)
    print("seapup: interrupted", file=sys.stderr)
    return 128 + int(signum)


def main(argv: list[str] | None = None) -> int:
    """Dispatch ``argv`` (command first). ``--check CMD`` answers the bash script:
    exit 0 if CMD needs the bootstrap, 3 if it is help (printed), 2 if unknown."""
    argv = list(sys.argv[1:] if argv is None else argv)
    check = bool(argv) and argv[0] == "--check"
    if check:
        argv = argv[1:]
    debug = os.environ.get("SEAPUP_DEBUG", "") not in ("", "0")
    while argv and argv[0] == "--debug":
        debug, argv = True, argv[1:]
    name = argv[0] if argv else "help"
    if name in ("help", "-h", "--help"):
        try:
            print(usage(), flush=True)
        except BrokenPipeError:
            return _closed_pipe()
        return 3 if check else 0
    entry = COMMANDS.get(name)
    if entry is None:
        print(f"seapup: unknown command: {name}\n\n{usage()}", file=sys.stderr)
        return 2
    if check:
        return 0
    if entry.run is None:
        print(f"seapup: '{name}' is handled by the ./seapup script", file=sys.stderr)
        return 2
    problem = "" if name == "test" else domain_problem(os.environ.get("ROS_DOMAIN_ID"))
    if problem:
        print(f"seapup: error: {problem}", file=sys.stderr)
        return 2
    return _dispatch(entry, argv[1:], debug)


if __name__ == "__main__":
    sys.exit(main())
