"""Starting the live view beside a graph (``--view`` of ``demo``, ``launch`` and ``replay``; ``./seapup view``).

The view is the ``live_view`` node (:mod:`seapup_bringup.live_view_node`) as one more node of the graph: the
same :class:`~seapup_common.ros.launch_graph.NodeSpec` a graph file would give it.
"""
from __future__ import annotations

import argparse
import os
import socket
import sys

from seapup_common.ros.launch_graph import NodeSpec

__all__ = ["DEFAULT_PORT", "view_node", "view_url", "check_port", "add_view_arguments", "ros_arguments",
           "view_parser", "view_command"]

#: Foxglove's usual WebSocket port.
DEFAULT_PORT = 8765


def check_port(port: int) -> None:
    """Refuse a port out of range or already taken on 127.0.0.1 (one line, before any node starts).

    The probe binds with ``SO_REUSEADDR``, as the view's own listener does
    (:class:`seapup_bringup.view_relay.Relay`, and the SDK's server, whose tokio listener sets it on Unix): a port
    whose last connection lingers in TIME_WAIT after the previous view closed is free to both, while a port
    another process listens on is refused by both.
    """
    if not 1 <= int(port) <= 65535:
        raise ValueError(f"--view-port must be 1..65535, got {port}")
    with socket.socket() as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind(("127.0.0.1", int(port)))
        except OSError:
            raise ValueError(f"port {port} on 127.0.0.1 is in use (another view?): choose --view-port") from None


def view_node(port: int = DEFAULT_PORT) -> NodeSpec:
    """The live view as a graph node (it reads the simulator's vehicle and seabed from the graph itself)."""
    return NodeSpec(package="seapup_bringup", executable="live_view", name="live_view",
                    parameters=[{"port": int(port)}])


def view_url(port: int) -> str:
    """What to open: the WebSocket, and the Foxglove app's link to it."""
    url = f"ws://127.0.0.1:{int(port)}"
    return f"{url} (Foxglove or Lichtblick: open connection -> Foxglove WebSocket; docs/live-view.md)"


def add_view_arguments(parser, rate_help: str) -> None:
    """``--view``, ``--view-port`` and ``--rate`` for a command that starts a graph."""
    parser.add_argument("--view", action="store_true", help="start the live view (docs/live-view.md) beside the "
                                                             "graph; the lockstep graph then runs at --rate")
    parser.add_argument("--view-port", type=int, default=DEFAULT_PORT, help=f"its port (default {DEFAULT_PORT})")
    parser.add_argument("--rate", type=float, default=None, help=rate_help)


def ros_arguments(argv: list[str]) -> list[str]:
    """``argv`` with every empty parameter override ``-p name:=`` written ``-p name:=''`` (an empty string).

    rcl refuses ``name:=`` with nothing after it ("Couldn't parse parameter override rule") before any node
    exists, so ``./seapup view`` without ``--environment-file`` (which passes ``environment_file:=``) could not
    start; the empty string is what it means.
    """
    out, in_ros_args, expect_rule = [], False, False
    for arg in argv:
        if arg == "--ros-args":
            in_ros_args = True
        elif arg == "--":
            in_ros_args = False
        elif in_ros_args and expect_rule and arg.endswith(":=") and arg.count(":=") == 1:
            arg += "''"
        expect_rule = in_ros_args and arg in ("-p", "--param")
        out.append(arg)
    return out


def view_parser() -> argparse.ArgumentParser:
    """``./seapup view``'s arguments."""
    from seapup_bringup.output import add_json_argument
    parser = argparse.ArgumentParser(prog="./seapup view", description="the live_view node on this domain "
                                     "(docs/live-view.md); Ctrl-C ends it")
    parser.add_argument("--port", type=int, default=DEFAULT_PORT, help=f"WebSocket port on 127.0.0.1 (default "
                                                                       f"{DEFAULT_PORT})")
    parser.add_argument("--vehicle", default="baseline", help="configuration drawn (the simulator's)")
    parser.add_argument("--environment-file", default="", help="the seabed drawn until the simulator's is read")
    parser.add_argument("--write-layout", metavar="FILE", help="write the Foxglove layout (3D, plots, services) to "
                                                               "FILE and exit: import it in Foxglove")
    add_json_argument(parser)
    return parser


def view_command(argv: list[str]) -> int:
    """``./seapup view``: the live_view node, in this process (exec), on this domain; or ``--write-layout``."""
    from seapup_bringup.output import emit_json
    from seapup_common.processes import find_executable
    parser = view_parser()
    args = parser.parse_args(argv)
    if args.write_layout:
        from pathlib import Path
        from seapup_bringup.view_layout import layout_json
        Path(args.write_layout).write_text(layout_json())
        print(f"seapup view: layout written to {args.write_layout}", file=sys.stderr)
        emit_json(args, {"layout": args.write_layout})
        return 0
    if not 1 <= args.port <= 65535:
        parser.error(f"--port must be 1..65535, got {args.port}")
    try:
        check_port(args.port)
    except ValueError as exc:
        print(f"seapup view: error: {str(exc).replace('--view-port', '--port')}", file=sys.stderr)
        return 1
    path = find_executable("seapup_bringup", "live_view")
    emit_json(args, {"url": f"ws://127.0.0.1:{args.port}", "port": args.port, "pid": os.getpid()})   # then serves
    rules = [f"port:={args.port}", f"vehicle:={args.vehicle}"]
    if args.environment_file:
        rules.append(f"environment_file:={args.environment_file}")
    os.execv(str(path), [str(path), "--ros-args", *[x for rule in rules for x in ("-p", rule)]])
    return 1  # not reached
