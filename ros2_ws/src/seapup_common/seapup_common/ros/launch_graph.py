"""Graph files in ROS 2's YAML launch format: what ``./seapup launch`` and the SIL harness start.

The shipped graphs (``seapup_bringup/launch/*.launch.yaml``) are ordinary ROS 2 launch files, so on a system
ROS 2 ``ros2 launch seapup_bringup hierarchy.launch.yaml`` starts the same nodes. Without the ``launch``
wheels, :func:`load_graph` reads the subset of the format they use, by the format's rules::

    launch:
      - arg: {name: mode, default: lockstep, description: "..."}   # a string; NAME:=VALUE overrides it
      - node:
          pkg: seapup_sim
          exec: simulator
          name: simulator                 # optional (__node)
          namespace: /seapup              # optional (__ns)
          args: "--flag value"            # optional: the node's own arguments, before --ros-args
          param:
            - {name: mode, value: $(var mode)}
            - {name: environment, param: [{name: sensors, value: baseline}]}   # nested: environment.sensors
            - {from: $(find-pkg-share seapup_sim)/config/simulator.yaml}
          remap:
            - {from: thrusters/command, to: /seapup/mfol_fixed/thrusters/command}
          on_exit: shutdown               # its exit stops the graph (launch's Shutdown action)
          respawn: "true"                 # restart it when it exits ...
          respawn_delay: 1.0              # ... after this many seconds ...
          respawn_max_retries: 3          # ... at most this many times (launch's ExecuteProcess, Iron and later;
                                          # -1 or left out: no limit)
          if: $(var view)                 # (or unless:) started only if the condition is true

Substitutions in any string: ``$(var NAME)``, ``$(find-pkg-share PACKAGE)``, ``$(env NAME [DEFAULT])`` and
``$(dirname)``; a parameter value that holds a substitution is read as YAML once substituted (``true``,
``5.0`` and ``[a, b]`` keep their types), as launch_ros does. Conditions take ``true``/``false`` (and ``1``/``0``),
case-insensitively. Anything else of the format (``include``, ``group``, ``let``, ``executable``, other
substitutions) is refused with a one-line :class:`LaunchError` naming it: it starts nothing.

Each :class:`NodeSpec` becomes a command by :func:`command_line` (executable, ``--ros-args`` with the
name, namespace, parameters and remappings). Shared by the launcher (seapup_bringup) and the SIL harness
(:mod:`seapup_bringup.graph.sil`), so both read the same files the same way.
"""
from __future__ import annotations

import os
import re
import shlex
from pathlib import Path

import yaml

from seapup_common.input_files import InputFileError, load_yaml_file
from seapup_common.launch_format import NodeSpec, argument_text, argument_value, launch_document

__all__ = ["LaunchError", "NodeSpec", "load_graph", "find_graph", "command_line", "graph_arguments",
           "argument_value", "launch_document"]

_SUBSTITUTION = re.compile(r"\$\(([a-z-]+)((?:\s+[^()\s]+)*)\s*\)")
_NODE_KEYS = {"pkg", "exec", "name", "namespace", "param", "remap", "args", "on_exit", "respawn", "respawn_delay",
              "respawn_max_retries", "if", "unless", "output"}


class LaunchError(ValueError):
    """A graph file that cannot be started (the reason names the node, argument or key)."""


def _share(package: str) -> str:
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    try:
        return get_package_share_directory(package)
    except PackageNotFoundError:
        raise LaunchError(f"$(find-pkg-share {package}): no package {package!r} on AMENT_PREFIX_PATH") from None


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


def _entries(path) -> list[tuple[str, dict]]:
    """The file's ``launch:`` list as (kind, body) pairs."""
    try:   # bounded and strict: duplicate keys, unsafe tags and alias bombs refused
        document = load_yaml_file(path, "launch")
    except InputFileError as exc:
        raise LaunchError(str(exc)) from None
    if not isinstance(document, dict) or set(document) != {"launch"} or not isinstance(document["launch"], list):
        raise LaunchError(f"{path}: a ROS 2 YAML launch file is one mapping 'launch:' holding a list")
    entries = []
    for i, entry in enumerate(document["launch"]):
        if not isinstance(entry, dict) or len(entry) != 1:
            raise LaunchError(f"{path}: launch entry {i} must be a mapping of one action (arg, node)")
        (kind, body), = entry.items()
        if kind not in ("arg", "node"):
            raise LaunchError(f"{path}: launch entry {i}: the action {kind!r} is not supported here (arg, node)")
        if not isinstance(body, dict):
            raise LaunchError(f"{path}: launch entry {i}: {kind} must be a mapping")
        entries.append((kind, body))
    return entries


def graph_arguments(path) -> dict:
    """The arguments a graph file declares (``arg``), with their defaults as strings (None: no default)."""
    declared = {}
    for kind, body in _entries(path):
        if kind == "arg":
            if "name" not in body or set(body) - {"name", "default", "description"}:
                raise LaunchError(f"{path}: arg {body.get('name', '?')!r}: keys are name, default, description")
            default = body.get("default")
            declared[str(body["name"])] = None if default is None else argument_text(default)
    return declared


class _Substituter:
    def __init__(self, path: Path, values: dict):
        self.path, self.values = path, values

    def __call__(self, value):
        """``value`` with its substitutions made; a string that held one comes back as text (``typed``: read it
        as YAML when a parameter's value)."""
        if isinstance(value, list):
            return [self(v) for v in value]
        if isinstance(value, dict):
            return {k: self(v) for k, v in value.items()}
        if not isinstance(value, str) or "$(" not in value:
            return value
        text = _SUBSTITUTION.sub(self._one, value)
        if "$(" in text:
            raise LaunchError(f"{self.path}: cannot read the substitution in {value!r}")
        return text

    def _one(self, match) -> str:
        kind, words = match.group(1), match.group(2).split()
        if kind == "var" and len(words) == 1:
            if words[0] not in self.values:
                raise LaunchError(f"{self.path}: $(var {words[0]}) is not declared by an arg")
            if self.values[words[0]] is None:
                raise LaunchError(f"{self.path}: argument {words[0]!r} has no default: give {words[0]}:=VALUE")
            return self.values[words[0]]
        if kind == "find-pkg-share" and len(words) == 1:
            return _share(words[0])
        if kind == "env" and len(words) in (1, 2):
            if words[0] in os.environ:
                return os.environ[words[0]]
            if len(words) == 2:
                return words[1]
            raise LaunchError(f"{self.path}: $(env {words[0]}): not set and no default")
        if kind == "dirname" and not words:
            return str(self.path.resolve().parent)
        raise LaunchError(f"{self.path}: the substitution $({kind}{' ' if words else ''}{' '.join(words)}) is not "
                          f"supported here (var, find-pkg-share, env, dirname)")


def _condition(value, what: str) -> bool:
    text = argument_text(value).strip().lower()
    if text in ("true", "1"):
        return True
    if text in ("false", "0"):
        return False
    raise LaunchError(f"{what}: a condition must be true or false, got {value!r}")


def _parameters(items, substitute, what: str, prefix: str = "") -> list:
    """``param:`` entries as NodeSpec parameters: one mapping of (dotted) names, and the files in order."""
    if not isinstance(items, list):
        raise LaunchError(f"{what}: param must be a list")
    values, out = {}, []
    for item in items:
        if not isinstance(item, dict):
            raise LaunchError(f"{what}: each param is a mapping (name and value, name and param, or from)")
        if set(item) == {"from"}:
            if prefix:
                raise LaunchError(f"{what}: a parameter file cannot be nested under {prefix[:-1]!r}")
            out.append(substitute(item["from"]))
        elif set(item) == {"name", "value"}:
            value = substitute(item["value"])
            typed = isinstance(item["value"], str) and "$(" in item["value"]
            values[prefix + str(item["name"])] = argument_value(value) if typed else value
        elif set(item) == {"name", "param"}:
            nested = _parameters(item["param"], substitute, what, f"{prefix}{item['name']}.")
            values.update(nested[0] if nested else {})
        else:
            raise LaunchError(f"{what}: param keys are name and value, name and param, or from; got {sorted(item)}")
    return ([values] if values else []) + out


def _node(body: dict, substitute, path, index: int) -> NodeSpec | None:
    what = f"{path}: node {body.get('name') or body.get('exec') or index}"
    unknown = sorted(set(body) - _NODE_KEYS)
    if unknown:
        raise LaunchError(f"{what}: unknown key {unknown[0]!r} (keys: {', '.join(sorted(_NODE_KEYS))})")
    if "pkg" not in body or "exec" not in body:
        raise LaunchError(f"{what}: a node needs pkg and exec")
    if "if" in body and not _condition(substitute(body["if"]), what):
        return None
    if "unless" in body and _condition(substitute(body["unless"]), what):
        return None
    remaps = body.get("remap") or []
    if not isinstance(remaps, list) or not all(isinstance(r, dict) and set(r) == {"from", "to"} for r in remaps):
        raise LaunchError(f"{what}: remap is a list of {{from, to}}")
    on_exit = substitute(body.get("on_exit", ""))
    if on_exit not in ("", "shutdown"):
        raise LaunchError(f"{what}: on_exit {on_exit!r} is not supported (shutdown)")
    try:
        spec = NodeSpec(package=str(substitute(body["pkg"])), executable=str(substitute(body["exec"])),
                        name=str(substitute(body.get("name", ""))), namespace=str(substitute(body.get("namespace", ""))),
                        parameters=_parameters(body.get("param") or [], substitute, what),
                        remappings={str(substitute(r["from"])): str(substitute(r["to"])) for r in remaps},
                        args=shlex.split(str(substitute(body.get("args", "")))), required=on_exit == "shutdown",
                        respawn=_condition(substitute(body.get("respawn", False)), what),
                        respawn_limit=substitute(body.get("respawn_max_retries", -1)),
                        respawn_delay=substitute(body.get("respawn_delay", 1.0)))
    except (TypeError, ValueError) as exc:   # NodeSpec checks its numbers (finite, in range)
        if isinstance(exc, LaunchError):
            raise
        raise LaunchError(f"{what}: {exc}") from None
    return spec


def load_graph(path, arguments: dict[str, str] | None = None) -> list[NodeSpec]:
    """The nodes of a graph file with its arguments substituted (``arguments`` override the defaults);
    nodes whose condition is false are left out."""
    path = Path(path)
    declared = graph_arguments(path)
    given = {k: argument_text(v) for k, v in (arguments or {}).items()}
    unknown = sorted(set(given) - set(declared))
    if unknown:
        raise LaunchError(f"{path}: unknown argument {unknown[0]!r} (declared: {', '.join(declared) or 'none'})")
    substitute = _Substituter(path, {**declared, **given})
    specs = [spec for i, (kind, body) in enumerate(_entries(path)) if kind == "node"
             for spec in [_node(body, substitute, path, i)] if spec is not None]
    if not specs:
        raise LaunchError(f"{path}: no node to start")
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
