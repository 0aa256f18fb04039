"""Graph files: the YAML description of a set of nodes that ``./seapup launch`` and the SIL harness start.

A graph file lists nodes and their defaults (the format is documented in
:mod:`seapup_bringup.launch`); :func:`load_graph` reads one with its
``$(arg NAME)`` / ``$(find PACKAGE)`` substitutions into :class:`NodeSpec`
objects and :func:`command_line` turns a spec into the node's command
(executable, ``--ros-args`` with name, namespace, parameters, remappings).
Shared by the launcher (seapup_bringup) and the SIL harness
(:mod:`seapup_bringup.sil`), so both read the same files the same way.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import yaml

__all__ = ["LaunchError", "NodeSpec", "load_graph", "find_graph", "command_line", "graph_arguments"]

_SUBSTITUTION = re.compile(r"\$\((arg|find) ([A-Za-z0-9_./-]+)\)")


class LaunchError(ValueError):
    """A graph file that cannot be started (the reason names the node, argument or key)."""


@dataclass
class NodeSpec:
    """One node of a graph (see the module docstring for the keys)."""

    package: str
    executable: str
    name: str = ""
    namespace: str = ""
    parameters: list = field(default_factory=list)
    remappings: dict = field(default_factory=dict)
    args: list = field(default_factory=list)
    required: bool = False
    respawn: bool = False
    respawn_limit: int = 0
    respawn_delay: float = 1.0

    @property
    def label(self) -> str:
        return self.name or self.executable


def _share(package: str) -> str:
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    try:
        return get_package_share_directory(package)
    except PackageNotFoundError:
        raise LaunchError(f"$(find {package}): no package {package!r} on AMENT_PREFIX_PATH") from None


def find_graph(spec: str, file_name: str | None = None) -> Path:
    """A graph file: a path, or ``PACKAGE FILE`` in the package's ``share/<pkg>/launch`` (as ros2 launch)."""
    if file_name is None:
        path = Path(spec)
        if not path.is_file():
            raise LaunchError(f"no graph file {spec!r}")
        return path
    path = Path(_share(spec)) / "launch" / file_name
    if not path.is_file():
        raise LaunchError(f"package {spec} has no launch/{file_name}")
    return path


def graph_arguments(path) -> dict:
    """The arguments a graph file declares, with their defaults."""
    try:
        head = yaml.safe_load(_SUBSTITUTION.sub("0", Path(path).read_text())) or {}
    except yaml.YAMLError as exc:
        raise LaunchError(f"{path}: not YAML: {exc}") from None
    declared = head.get("arguments") or {}
    if not isinstance(declared, dict):
        raise LaunchError(f"{path}: 'arguments' must be a mapping of names to defaults")
    return declared


def load_graph(path, arguments: dict[str, str] | None = None) -> list[NodeSpec]:
    """The nodes of a graph file with its arguments substituted (``arguments`` override the defaults)."""
    text = Path(path).read_text()
    declared = graph_arguments(path)
    given = dict(arguments or {})
    unknown = sorted(set(given) - set(declared))
    if unknown:
        raise LaunchError(f"{path}: unknown argument {unknown[0]!r} (declared: {', '.join(declared) or 'none'})")
    values = {k: ("" if v is None else str(v)) for k, v in declared.items()}
    values.update(given)

    def substitute(match):
        kind, name = match.groups()
        if kind == "find":
            return _share(name)
        if name not in values:
            raise LaunchError(f"{path}: $(arg {name}) is not declared under 'arguments'")
        return values[name]
    body = "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("#"))
    graph = yaml.safe_load(_SUBSTITUTION.sub(substitute, body)) or {}
    nodes = graph.get("nodes")
    if not isinstance(nodes, list) or not nodes:
        raise LaunchError(f"{path}: 'nodes' must be a non-empty list")
    specs = []
    allowed = set(NodeSpec.__dataclass_fields__)
    for i, entry in enumerate(nodes):
        if not isinstance(entry, dict) or not {"package", "executable"} <= set(entry):
            raise LaunchError(f"{path}: node {i} needs 'package' and 'executable'")
        extra = sorted(set(entry) - allowed)
        if extra:
            raise LaunchError(f"{path}: node {i}: unknown key {extra[0]!r} (keys: {', '.join(sorted(allowed))})")
        spec = NodeSpec(**entry)
        if not isinstance(spec.parameters, list):
            spec.parameters = [spec.parameters]
        if spec.respawn_limit < 0 or spec.respawn_delay < 0:
            raise LaunchError(f"{path}: node {spec.label}: respawn_limit and respawn_delay must be >= 0")
        specs.append(spec)
    labels = [s.label for s in specs]
    if len(set(labels)) != len(labels):
        raise LaunchError(f"{path}: two nodes named {next(x for x in labels if labels.count(x) > 1)!r}")
    return specs


def _flatten(mapping: dict, prefix: str = "") -> dict:
    out = {}
    for key, value in mapping.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(_flatten(value, name + "."))
        else:
            out[name] = value
    return out


def command_line(spec: NodeSpec) -> list[str]:
    """The node's command: its executable, ``args``, then ``--ros-args`` with names, parameters, remappings."""
    from seapup_common.processes import find_executable
    try:
        exe = find_executable(spec.package, spec.executable)
    except FileNotFoundError as exc:
        raise LaunchError(f"node {spec.label}: {exc}") from None
    ros = []
    if spec.name:
        ros += ["-r", f"__node:={spec.name}"]
    if spec.namespace:
        ros += ["-r", f"__ns:={spec.namespace}"]
    for item in spec.parameters:
        if isinstance(item, dict):
            for name, value in _flatten(item).items():
                # ROS parameters are never null: an empty argument is an empty string
                text = "''" if value is None else yaml.safe_dump(value, default_flow_style=True).strip()
                ros += ["-p", f"{name}:={text.removesuffix(chr(10) + '...').removesuffix(' ...')}"]
        else:
            if not Path(str(item)).is_file():
                raise LaunchError(f"node {spec.label}: no parameter file {item!r}")
            ros += ["--params-file", str(item)]
    for source, target in (spec.remappings or {}).items():
        ros += ["-r", f"{source}:={target}"]
    return [str(exe), *[str(a) for a in spec.args], *(["--ros-args", *ros] if ros else [])]
