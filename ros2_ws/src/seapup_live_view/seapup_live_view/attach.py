"""Starting the live view beside a graph (``--view`` of ``demo``, ``launch`` and ``replay``; ``./seapup view``).

The view is the ``live_view`` node (:mod:`seapup_live_view.live_view_node`) as one more node of the graph: the
same :class:`~seapup_common.ros.launch_graph.NodeSpec` a graph file would give it.
"""
from __future__ import annotations

import socket

from seapup_common.ros.launch_graph import NodeSpec

__all__ = ["DEFAULT_PORT", "view_node", "view_url", "check_port", "add_view_arguments", "ros_arguments"]

#: Foxglove's usual WebSocket port.
DEFAULT_PORT = 8765


def check_port(port: int) -> None:
    """Refuse a port out of range or already taken on 127.0.0.1 (one line, before any node starts).

    The probe binds with ``SO_REUSEADDR``, as the view's own listener does
    (:class:`seapup_live_view.view_relay.Relay`, and the SDK's server, whose tokio listener sets it on Unix): a port
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
    return NodeSpec(package="seapup_live_view", executable="live_view", name="live_view",
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

