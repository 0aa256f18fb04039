"""``./seapup launch``: start a graph of nodes from a ROS 2 YAML launch file (what ``ros2 launch`` does).

There is no launch wheel: the file is read by :mod:`seapup_common.ros.launch_graph` (the format's rules
and the part of it supported are in its docstring), so the shipped ``*.launch.yaml`` graphs start the same
way here and under ``ros2 launch`` on a system ROS 2. Arguments are given as ``name:=value``; an argument
without a default and not given, or one given that the file does not declare, is an error that starts
nothing. A node with ``on_exit: shutdown`` is required: its exit stops the graph, exit 1 naming it;
``respawn`` restarts a node after ``respawn_delay`` s, at most ``respawn_max_retries`` times (-1 or left out:
no limit, as launch).

**Lockstep roster.** Before a graph starts, the launcher fills the counts of the lockstep handshake from
the graph itself (:mod:`seapup_common.lockstep.roster`): the simulator's ``wait_for_subscribers`` (each
per-sample topic once per node that must hear it from t_0 on) and each commander's subscriber counts
(``wait_for_command_subscribers`` of a velocity controller, the controller manager and ``open_loop``, ``wait_for_reference_subscribers`` of
``reference_schedule``; the self-test's ``wait_for_command_subscribers`` and ``wait_for_sample_subscribers``),
each executable's role declared once in its package's ``config/lockstep.yaml``. A node whose parameter the
file gives keeps it. Subscribers outside the file -- a harness's probe, a recorder -- are *extra
listeners*: ``--listener /topic[,/topic...]`` (once per listener) on the command line, ``listeners=`` of
:func:`graph_nodes` in Python (the SIL harness passes its probe and recorder that way).

Each node runs in its own process group on the current ROS domain (loopback
discovery), its output prefixed with ``[name]``. Ctrl-C or SIGTERM stops every
node: SIGINT, then SIGTERM after ``stop_grace`` s, then SIGKILL. The launch
ends when every node has ended: exit 0 if all ended cleanly, else 1.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time

from seapup_bringup.output import add_json_argument, emit_json
from seapup_common.lockstep.roster import Listener, RosterError, fill, role_book, roster
from seapup_common.processes import spawn
from seapup_common.ros.launch_graph import LaunchError, NodeSpec, command_line, find_graph, graph_arguments, load_graph

__all__ = ["LaunchError", "NodeSpec", "load_graph", "find_graph", "command_line", "Launch", "STOP_GRACE_MAX",
           "graph_nodes", "with_roster", "installed_share", "Listener"]

#: The longest wait between two stop signals a user may ask for [s] (``--stop-grace``).
STOP_GRACE_MAX = 60.0


def installed_share(package: str) -> str | None:
    """A package's share directory on ``AMENT_PREFIX_PATH`` (None: not installed)."""
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    try:
        return get_package_share_directory(package)
    except PackageNotFoundError:
        return None


def with_roster(specs: list[NodeSpec], listeners=()) -> list[NodeSpec]:
    """``specs`` with the lockstep handshake's counts filled from their roster (module docstring).

    Parameters
    ----------
    specs : list of NodeSpec
        Every node started together (the graph's and any extra ones, such as the live view).
    listeners : iterable of Listener
        Subscribers outside the graph (a probe, a recorder).

    Raises
    ------
    LaunchError
        Saying why the roster cannot be derived (an executable without a declared role, a node that must
        hear a topic the simulator does not publish).
    """
    try:
        return fill(specs, roster(specs, listeners, roles=role_book(installed_share)))
    except RosterError as exc:
        raise LaunchError(f"lockstep roster: {exc}") from None


def graph_nodes(path, arguments: dict | None = None, listeners=(), extra=()) -> list[NodeSpec]:
    """The nodes a graph file starts -- its own with ``arguments`` and the ``extra`` ones -- with the lockstep
    handshake's counts filled for them and the extra ``listeners`` (:func:`with_roster`)."""
    return with_roster([*load_graph(path, arguments), *extra], listeners)


def _listener(text: str) -> Listener:
    topics = [t for t in text.split(",") if t]
    if not topics or not all(t.startswith("/") for t in topics):
        raise LaunchError(f"--listener takes absolute topics separated by commas, got {text!r}")
    return Listener(f"listener {text}", tuple(topics))


class _Running:
    def __init__(self, spec: NodeSpec):
        self.spec = spec
        self.popen: subprocess.Popen | None = None
        self.starts = 0
        self.thread: threading.Thread | None = None
        self.restart_at: float | None = None
        self.reported = False  # its exit has been handled


class Launch:
    """Start, watch and stop a graph's nodes (see the module docstring).

    Parameters
    ----------
    specs : list of NodeSpec
    env : dict, optional
        The nodes' environment (default: this process's, loopback discovery).
    out : file, optional
        Where the prefixed output goes (default stdout).
    stop_grace : float
        Seconds after SIGINT before SIGTERM (and again before SIGKILL).
    """

    def __init__(self, specs: list[NodeSpec], env: dict | None = None, out=None, stop_grace: float = 5.0):
        self.specs = specs
        self.env = dict(os.environ if env is None else env)
        self.env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        self.env["PYTHONUNBUFFERED"] = "1"
        self.out = out or sys.stdout
        self.stop_grace = float(stop_grace)
        self.nodes = [_Running(s) for s in specs]
        self.commands = {s.label: command_line(s) for s in specs}  # LaunchError before anything starts
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self.reason = ""

    def say(self, label: str, line: str) -> None:
        with self._lock:
            self.out.write(f"[{label}] {line}\n")
            self.out.flush()

    def _start(self, node: _Running) -> None:
        node.popen = spawn(self.commands[node.spec.label], env=self.env, stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        node.starts += 1
        node.restart_at = None
        self.say("launch", f"started {node.spec.label} (pid {node.popen.pid})"
                 + (f", respawn {node.starts - 1} of "
                    f"{node.spec.respawn_limit if node.spec.respawn_limit >= 0 else 'no limit'}" if node.starts > 1 else ""))

        def pump(popen=node.popen, label=node.spec.label):
            for raw in iter(popen.stdout.readline, b""):
                self.say(label, raw.decode(errors="replace").rstrip("\n"))
        node.thread = threading.Thread(target=pump, daemon=True)
        node.thread.start()

    def request_stop(self, reason: str = "") -> None:
        if reason and not self.reason:
            self.reason = reason
        self._stop.set()

    def run(self) -> int:
        """Start every node and supervise until all have ended; the exit status."""
        handlers = {}
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
                handlers[sig] = signal.signal(sig, lambda s, _f: self.request_stop(f"{signal.Signals(s).name}"))
        failed = []
        try:
            for node in self.nodes:
                if self._stop.is_set():   # stopped while starting: the rest are not started
                    break
                self._start(node)
            while not self._stop.is_set():
                alive = False
                for node in self.nodes:
                    code = node.popen.poll() if node.popen else None
                    if node.popen is not None and code is None:
                        alive = True
                        continue
                    if node.restart_at is not None:
                        alive = True
                        if time.monotonic() >= node.restart_at:
                            self._start(node)
                        continue
                    if node.popen is None or node.reported:
                        continue
                    node.reported = True
                    node.thread.join(1.0)
                    self.say("launch", f"{node.spec.label} exited with {code}")
                    if node.spec.required:
                        self.request_stop(f"required node {node.spec.label} exited with {code}")
                        failed.append(node.spec.label)
                        break
                    if node.spec.respawn and (node.spec.respawn_limit < 0 or node.starts <= node.spec.respawn_limit):
                        node.reported = False
                        node.restart_at = time.monotonic() + node.spec.respawn_delay
                        alive = True
                    elif code != 0:
                        failed.append(node.spec.label)
                if not alive:
                    break
                self._stop.wait(0.05)
        finally:
            self._stop_all()
            for sig, handler in handlers.items():
                signal.signal(sig, handler)
        if self.reason:
            self.say("launch", f"stopped: {self.reason}")
        if self.reason.startswith("required"):
            return 1
        return 0 if self.reason else (1 if failed else 0)  # stopped by a signal: a clean stop

    def _stop_all(self) -> None:
        from seapup_common.processes import stop_process_groups
        stop_process_groups([n.popen for n in self.nodes if n.popen is not None], self.stop_grace, self.stop_grace)
        for n in self.nodes:
            if n.thread is not None:
                n.thread.join(1.0)


def launch_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup launch`` (its usage line in ``./seapup help`` is generated from it)."""
    import argparse
    from seapup_live_view.attach import add_view_arguments
    parser = argparse.ArgumentParser(prog="./seapup launch", description="start a graph of nodes, as 'ros2 launch'",
                                     epilog="Graphs shipped (ROS 2 YAML launch files): seapup_bringup "
                                            "simulator.launch.yaml, "
                                            "seapup_bringup simulator_controller.launch.yaml. --json [FILE] writes the "
                                            "nodes started and how they ended.")
    parser.add_argument("graph", nargs="+", help="GRAPH.yaml, or PACKAGE FILE, then name:=value arguments")
    parser.add_argument("--show-args", action="store_true", help="print the graph's arguments and exit")
    parser.add_argument("--stop-grace", type=float, default=5.0, help="seconds between SIGINT, SIGTERM, SIGKILL")
    parser.add_argument("--listener", action="append", default=[], metavar="/TOPIC[,/TOPIC...]",
                        help="a subscriber outside the graph (a recorder started first): the lockstep graph's first "
                             "messages on these topics wait for it too (once per listener)")
    add_view_arguments(parser, "a lockstep graph at this many times real time (its lockstep_pace argument; "
                               "default: unpaced, or 1 with --view)")
    add_json_argument(parser)
    return parser


def launch(argv: list[str]) -> int:
    """``./seapup launch GRAPH.yaml [name:=value ...]`` or ``./seapup launch PACKAGE FILE [name:=value ...]``."""
    from seapup_live_view.attach import check_port, view_node, view_url
    parser = launch_parser()
    args = parser.parse_args(argv)
    if args.view:
        try:
            check_port(args.view_port)
        except ValueError as exc:
            parser.error(str(exc))
    if not 0.0 <= args.stop_grace <= STOP_GRACE_MAX:   # NaN fails this too
        parser.error(f"--stop-grace must be a number of seconds in [0, {STOP_GRACE_MAX:g}], got {args.stop_grace}")
    words = [w for w in args.graph if ":=" not in w]
    given = dict(w.split(":=", 1) for w in args.graph if ":=" in w)
    try:
        if len(words) not in (1, 2):
            raise LaunchError("give GRAPH.yaml or PACKAGE FILE")
        path = find_graph(*words)
        if args.show_args:
            for name, default in graph_arguments(path).items():
                print(f"    '{name}': default '{default}'")
            return 0
        rate = args.rate if args.rate is not None else (1.0 if args.view else None)
        if rate is not None:
            if "lockstep_pace" not in graph_arguments(path):
                raise LaunchError(f"--rate: {path.name} has no lockstep_pace argument to pace")
            if not 0 <= rate < 1e4:
                raise LaunchError(f"--rate must be >= 0 (0: unpaced) and < 10000, got {rate}")
            given.setdefault("lockstep_pace", repr(float(rate)))
        specs = graph_nodes(path, given, [_listener(text) for text in args.listener],
                            [view_node(args.view_port)] if args.view else [])
        runner = Launch(specs, stop_grace=args.stop_grace)
        if args.view:
            print(f"seapup launch: live view at {view_url(args.view_port)}", file=sys.stderr)
    except LaunchError as exc:
        print(f"seapup: error: {exc}", file=sys.stderr)
        return 1
    code = runner.run()
    emit_json(args, {"graph": str(path), "exit": code, "reason": runner.reason,
                     "nodes": [{"name": n.spec.label, "starts": n.starts,
                                "exit": None if n.popen is None else n.popen.returncode} for n in runner.nodes]})
    if code and runner.reason:
        print(f"seapup: launch stopped: {runner.reason}", file=sys.stderr)
    return code
