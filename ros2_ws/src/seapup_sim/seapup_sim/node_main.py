"""Shared ``main`` for seapup node executables (rclpy shell code only).

Gives every node the same life cycle: ``rclpy.init`` with the process's
arguments, a SingleThreadedExecutor (the events executor deadlocks with these
wheels), a clean exit on SIGINT/SIGTERM, and a non-zero exit code if the node
could not be constructed (e.g. a rejected parameter).
"""
from __future__ import annotations

import signal
import sys
from pathlib import Path

import rclpy
from ament_index_python.packages import get_package_share_directory
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

from seapup_sim.parameters import load_node_parameters

__all__ = ["run_node", "declare_from_package_file"]


def declare_from_package_file(node, package: str, file_name: str, descriptors: dict | None = None) -> dict:
    """Declare every parameter of ``share/<package>/config/<file_name>`` for ``node``;
    return their values (after overrides) by name.

    Defaults come from the package's YAML; overrides given on the command line
    (``-p``, ``--params-file``) win as usual. ``descriptors`` maps parameter
    names to ``ParameterDescriptor`` objects (ranges, read-only, description).
    """
    path = Path(get_package_share_directory(package)) / "config" / file_name
    defaults = load_node_parameters(path, node.get_name())
    descriptors = descriptors or {}
    for name, value in defaults.items():
        if name in descriptors:
            node.declare_parameter(name, value, descriptors[name])
        else:
            node.declare_parameter(name, value)
    return {name: node.get_parameter(name).value for name in defaults}


def run_node(make_node, args=None) -> int:
    """Construct a node with ``make_node()`` and spin it until shutdown."""
    rclpy.init(args=sys.argv if args is None else args)
    signal.signal(signal.SIGTERM, lambda *_: rclpy.try_shutdown())
    node = None
    try:
        node = make_node()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception as exc:  # construction or callback failure: report and exit non-zero
        name = node.get_name() if node is not None else getattr(make_node, "__name__", "node")
        print(f"[{name}] fatal: {exc}", file=sys.stderr)
        return 1
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
