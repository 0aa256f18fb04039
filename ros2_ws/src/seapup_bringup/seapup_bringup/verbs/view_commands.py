"""``./seapup view``: the live view on this domain (the ``live_view`` node in this process), or its Foxglove
layout written to a file (docs/live-view.md)."""
from __future__ import annotations

import argparse
import os
import sys

from seapup_live_view.attach import DEFAULT_PORT, check_port

__all__ = ["view_parser", "view_command", "teleop_parser", "teleop_command"]


def view_parser() -> argparse.ArgumentParser:
    """``./seapup view``'s arguments."""
    from seapup_bringup.output import add_json_argument
    parser = argparse.ArgumentParser(prog="./seapup view", description="the live_view node on this domain "
                                     "(docs/live-view.md); Ctrl-C ends it")
    parser.add_argument("--port", type=int, default=DEFAULT_PORT, help=f"WebSocket port on 127.0.0.1 (default "
                                                                       f"{DEFAULT_PORT})")
    parser.add_argument("--vehicle", default="baseline", help="configuration drawn (the simulator's)")
    parser.add_argument("--environment-file", default="", help="the seabed drawn until the simulator's is read")
    parser.add_argument("--write-layout", metavar="FILE", help="write the Foxglove layout (3D, plots, services) for "
                                                               "--vehicle to FILE and exit: import it in Foxglove")
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
        from seapup_common.config import ConfigError
        from seapup_live_view.view_layout import layout_json
        try:
            text = layout_json(args.vehicle)
        except ConfigError as exc:
            print(f"seapup view: error: {exc}", file=sys.stderr)
            return 1
        try:
            Path(args.write_layout).write_text(text)
        except OSError as exc:
            print(f"seapup view: error: cannot write the layout to {args.write_layout}: "
                  f"{exc.strerror or exc}", file=sys.stderr)
            return 1
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
    path = find_executable("seapup_live_view", "live_view")
    emit_json(args, {"url": f"ws://127.0.0.1:{args.port}", "port": args.port, "pid": os.getpid()})   # then serves
    rules = [f"port:={args.port}", f"vehicle:={args.vehicle}"]
    if args.environment_file:
        rules.append(f"environment_file:={args.environment_file}")
    os.execv(str(path), [str(path), "--ros-args", *[x for rule in rules for x in ("-p", rule)]])
    return 1  # not reached


def teleop_parser() -> argparse.ArgumentParser:
    """``./seapup teleop``'s arguments."""
    from seapup_bringup.output import add_json_argument
    from seapup_control.manual import TELEOP_HELP
    from seapup_common.topics import PILOT
    parser = argparse.ArgumentParser(prog="./seapup teleop", description="the keyboard as the pilot's stick: a "
                                     f"geometry_msgs/Twist on {PILOT} (REP-103 base_link) at 10 Hz for "
                                     f"a manual velocity controller (docs/vehicles.md#manual-flight); {TELEOP_HELP}")
    for name, (default, low, high, what) in TELEOP_OPTIONS.items():
        parser.add_argument(f"--{name}", type=float, default=default, help=f"{what} ({low:g}-{high:g})")
    add_json_argument(parser)
    return parser


#: ``./seapup teleop``'s options: default, range and meaning (the node's own ranges: config/teleop.yaml)
TELEOP_OPTIONS = {"rate": (10.0, 1.0, 100.0, "messages a second [Hz]"),
                  "step": (0.05, 0.001, 1.0, "one key press [m/s, rad/s]")}


def teleop_command(argv: list[str]) -> int:
    """``./seapup teleop``: the teleop node in this process (exec), on this domain."""
    from seapup_bringup.output import emit_json
    from seapup_common.processes import find_executable
    parser = teleop_parser()
    args = parser.parse_args(argv)
    for name, (_, low, high, _) in TELEOP_OPTIONS.items():
        if not low <= getattr(args, name) <= high:
            parser.error(f"--{name} must be in [{low:g}, {high:g}], got {getattr(args, name)}")
    if not os.isatty(sys.stdin.fileno()):
        print("seapup teleop: error: it reads keys from a terminal, and stdin is not one", file=sys.stderr)
        return 1
    path = find_executable("seapup_control", "teleop")
    from seapup_common.topics import PILOT
    emit_json(args, {"topic": PILOT, "rate_hz": args.rate, "step": args.step, "pid": os.getpid()})
    rules = [f"rate:={args.rate}", f"linear_step:={args.step}", f"angular_step:={args.step}"]
    os.execv(str(path), [str(path), "--ros-args", *[x for rule in rules for x in ("-p", rule)]])
    return 1  # not reached
