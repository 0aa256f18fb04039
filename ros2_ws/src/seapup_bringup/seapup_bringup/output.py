"""Output conventions shared by every ``./seapup`` command.

The command registry (:mod:`seapup_bringup.cli`) only dispatches; the command
modules import their output helpers from here, so nothing imports the registry
back (no import cycle). The conventions:

- ``--json [FILE]`` writes the command's result as JSON to FILE, or to
  standard output without FILE, and the human text then goes to standard
  error (:func:`add_json_argument`, :func:`emit_json`, :func:`text_stream`);
- JSON holds plain Python: numpy scalars and arrays become numbers and lists,
  non-finite floats become ``null`` (:func:`jsonable`);
- long work shows a progress bar on a terminal and a line per 10 % otherwise
  (:func:`progress`).

Standard library only, like the registry.
"""
from __future__ import annotations

import argparse
import json
import sys

from seapup_common.jsondata import jsonable

__all__ = ["add_json_argument", "jsonable", "emit_json", "text_stream", "progress", "SIGNALS", "stopped_by_signal"]

#: The signals (SIGINT, SIGTERM, SIGHUP) ``./seapup`` received while its command ran (``cli`` appends).
SIGNALS: list[int] = []


def stopped_by_signal(exc: BaseException) -> bool:
    """True if ``exc`` is how a signal surfaced: a KeyboardInterrupt, or any error raised while one
    was being handled (rclpy and pybind11 turn an interrupted wait into other exceptions)."""
    return isinstance(exc, KeyboardInterrupt) or bool(SIGNALS)


def add_json_argument(parser: argparse.ArgumentParser) -> None:
    """Add the ``--json [FILE]`` option to a command's parser.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The command's parser; gains ``args.json`` (None, ``"-"`` or a path).
    """
    parser.add_argument("--json", nargs="?", const="-", metavar="FILE",
                        help="write the result as JSON to FILE (stdout without FILE; text then goes to stderr)")


def emit_json(args, result: dict) -> None:
    """Write ``result`` where ``--json`` asked (nothing without it).

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments; ``args.json`` is None, ``"-"`` (standard output) or
        a file path.
    result : dict
        The command's result, passed through :func:`jsonable`.
    """
    target = getattr(args, "json", None)
    if not target:
        return
    text = json.dumps(jsonable(result), indent=1)
    if target == "-":
        sys.__stdout__.write(text + "\n")
    else:
        with open(target, "w") as f:
            f.write(text + "\n")
        print(f"wrote {target}")


def text_stream(args):
    """Return where human text goes: standard error when JSON goes to standard output.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments of a command with :func:`add_json_argument`.

    Returns
    -------
    io.TextIOBase
        ``sys.stderr`` for ``--json`` without a file, ``sys.stdout`` otherwise.
    """
    return sys.stderr if getattr(args, "json", None) == "-" else sys.stdout


def progress(label: str, fraction: float, width: int = 30, stream=None) -> None:
    """Show the progress of long work.

    On a terminal the bar is redrawn in place; elsewhere (logs, CI) a line is
    written each time another 10 % is done.

    Parameters
    ----------
    label : str
        What is progressing; also the key of the last printed decile.
    fraction : float
        Done fraction, clipped to [0, 1].
    width : int, optional
        Bar width in characters.
    stream : file-like, optional
        Where to write (standard error by default).

    Raises
    ------
    KeyboardInterrupt
        If ``./seapup`` has received a stop signal (:data:`SIGNALS`) that did not end the command: the handler's
        exception can land where a library swallows it (inside a ``__del__``, seen once in 50 Ctrl-Cs of a
        campaign, which then flew on to the end and exited 0). Long work stops at its next progress step instead
        (``signum``: the signal).
    """
    if SIGNALS:
        interrupt = KeyboardInterrupt()
        interrupt.signum = SIGNALS[0]
        raise interrupt
    stream = stream or sys.stderr
    fraction = min(max(fraction, 0.0), 1.0)
    done = int(width * fraction)
    bar = f"  {label:<12} [{'#' * done}{'.' * (width - done)}] {100 * fraction:5.1f}%"
    if stream.isatty():
        stream.write("\r" + bar + ("\n" if fraction >= 1.0 else ""))
    elif int(10 * fraction) != progress.last.get(label, -1):
        progress.last[label] = int(10 * fraction)
        stream.write(bar + "\n")
    stream.flush()


progress.last = {}
