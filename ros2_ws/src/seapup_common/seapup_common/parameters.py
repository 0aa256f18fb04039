"""Node parameter files: ROS 2 ``--params-file`` YAML read without ROS.

Parameters live in YAML (``config/<node>.yaml`` of each package), never in
code. A node declares each parameter with the default found in its package's
file, so ``./seapup run <pkg> <node>`` with no arguments runs with those values
and ``--ros-args --params-file`` or ``-p`` override them as usual.
"""
from __future__ import annotations

from pathlib import Path

__all__ = ["ParameterFileError", "load_node_parameters"]


class ParameterFileError(ValueError):
    """A parameter file that is missing, malformed or lacks the node's section."""


def load_node_parameters(path: str | Path, node_name: str) -> dict:
    """The ``ros__parameters`` mapping of ``node_name`` in a ROS 2 params file.

    Sections named ``/**`` apply to every node and are merged first, then the
    node's own section (matched by plain name or by any ``/namespace/name``).

    Parameters
    ----------
    path : str or Path
        The YAML file.
    node_name : str
        The node's name without namespace.

    Raises
    ------
    ParameterFileError
        If the file is unreadable, not a mapping, or has no section for the node.
    """
    from seapup_common.input_files import InputFileError, load_yaml_file
    path = Path(path)
    try:   # bounded and strict: at most 1 MiB, no duplicated key, safe tags only, not empty
        document = load_yaml_file(path, "config")
    except InputFileError as exc:
        raise ParameterFileError(f"cannot read parameter file {exc}") from None
    if not isinstance(document, dict):
        raise ParameterFileError(f"{path}: top level must be a mapping of node names")
    merged: dict = {}
    found = False
    for key, section in document.items():
        name = str(key).rstrip("/").split("/")[-1]
        if key == "/**" or name == node_name:
            if not isinstance(section, dict) or not isinstance(section.get("ros__parameters"), dict):
                raise ParameterFileError(f"{path}: section {key!r} has no 'ros__parameters' mapping")
            merged.update(section["ros__parameters"])
            found = found or key != "/**"
    if not found:
        raise ParameterFileError(f"{path}: no section for node {node_name!r}")
    return merged
