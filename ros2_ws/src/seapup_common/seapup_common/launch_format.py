"""ROS 2's YAML launch format as data, without ROS: the node description (:class:`NodeSpec`) and the launch
document a run or a harness writes (:func:`launch_document`), which :mod:`seapup_common.ros.launch_graph`
reads back (and ``ros2 launch`` on a system ROS 2 starts). Pure: the run layer builds its graphs with it."""
from __future__ import annotations

import math
import shlex
from dataclasses import dataclass, field

import yaml

__all__ = ["NodeSpec", "launch_document", "argument_value", "argument_text", "RESPAWN_DELAY_MAX",
           "respawn_delay_value", "respawn_limit_value"]

#: The longest respawn delay a graph may ask for [s]: an hour (launch sets no bound; a delay beyond it is a
#: typo, and ``.inf`` would leave a node never restarted and the launcher never done).
RESPAWN_DELAY_MAX = 3600.0


def respawn_delay_value(value) -> float:
    """``respawn_delay`` as seconds: a finite number in [0, :data:`RESPAWN_DELAY_MAX`].

    Raises
    ------
    ValueError
        Naming the value and the range (``.nan`` once was accepted: the node was then neither restarted
        nor the launch ended).
    """
    if isinstance(value, str):
        value = argument_value(value)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"respawn_delay must be a number of seconds in [0, {RESPAWN_DELAY_MAX:g}], got {value!r}")
    delay = float(value)
    if not math.isfinite(delay) or not 0.0 <= delay <= RESPAWN_DELAY_MAX:
        raise ValueError(f"respawn_delay must be a number of seconds in [0, {RESPAWN_DELAY_MAX:g}], got {value!r}")
    return delay


def respawn_limit_value(value) -> int:
    """``respawn_max_retries`` as an integer >= -1 (-1: no limit).

    Raises
    ------
    ValueError
        For a non-integer (``2.5``, ``true``, ``.nan``) or one below -1, naming it.
    """
    if isinstance(value, str):
        value = argument_value(value)
    if isinstance(value, float) and math.isfinite(value) and value == int(value):
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int) or value < -1:
        raise ValueError(f"respawn_max_retries must be an integer >= -1 (-1: no limit), got {value!r}")
    return value


@dataclass
class NodeSpec:
    """One node of a graph: its package, executable and how to start it."""

    package: str
    executable: str
    name: str = ""
    namespace: str = ""
    parameters: list = field(default_factory=list)   # mappings (nested: dotted names) and parameter files
    remappings: dict = field(default_factory=dict)
    args: list = field(default_factory=list)
    required: bool = False      # on_exit: shutdown
    respawn: bool = False
    respawn_limit: int = -1     # respawn_max_retries (-1, launch's default: no limit)
    respawn_delay: float = 1.0

    def __post_init__(self):
        self.respawn_delay = respawn_delay_value(self.respawn_delay)
        self.respawn_limit = respawn_limit_value(self.respawn_limit)

    @property
    def label(self) -> str:
        return self.name or self.executable

    def given_parameters(self) -> dict:
        """The parameters the document gives the node: its mappings, nested ones flattened to dotted names,
        later ones winning (parameter files are the node's business)."""
        given: dict = {}
        for item in self.parameters if isinstance(self.parameters, list) else [self.parameters]:
            if isinstance(item, dict):
                given.update(flat_parameters(item))
        return given


def argument_value(text: str):
    """An argument's string as the value it stands for (YAML: ``[a, b]`` a list, ``2.0`` a float)."""
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return text


def argument_text(value) -> str:
    """A scalar as launch holds it: a string (YAML booleans lower-case, as written in ROS files)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, dict)):
        return yaml.safe_dump(value, default_flow_style=True).strip()
    return str(value)


def launch_document(nodes, arguments: dict | None = None) -> dict:
    """A ROS 2 YAML launch document (dump it with ``yaml.safe_dump``) of ``nodes`` -- :class:`NodeSpec` objects or
    mappings of their fields -- and ``arguments`` (name: default): what a run or a harness writes for
    :func:`load_graph` (and ``ros2 launch``) to start; nested parameter mappings become nested ``param``."""
    def entries(mapping: dict) -> list:
        return [{"name": str(k), "param": entries(v)} if isinstance(v, dict) else {"name": str(k), "value": v}
                for k, v in mapping.items()]
    document = [{"arg": {"name": str(k), "default": argument_text(v)}} for k, v in (arguments or {}).items()]
    for node in nodes:
        spec = node if isinstance(node, NodeSpec) else NodeSpec(**node)
        body: dict = {"pkg": spec.package, "exec": spec.executable}
        if spec.name:
            body["name"] = spec.name
        if spec.namespace:
            body["namespace"] = spec.namespace
        params = []
        for item in spec.parameters if isinstance(spec.parameters, list) else [spec.parameters]:
            params += entries(item) if isinstance(item, dict) else [{"from": str(item)}]
        if params:
            body["param"] = params
        if spec.remappings:
            body["remap"] = [{"from": str(a), "to": str(b)} for a, b in spec.remappings.items()]
        if spec.args:
            body["args"] = shlex.join(str(a) for a in spec.args)
        if spec.required:
            body["on_exit"] = "shutdown"
        if spec.respawn:
            body.update({"respawn": "true", "respawn_delay": float(spec.respawn_delay)})
            if spec.respawn_limit >= 0:   # left out: no limit, as launch reads it
                body["respawn_max_retries"] = int(spec.respawn_limit)
        document.append({"node": body})
    return {"launch": document}


def flat_parameters(mapping: dict, prefix: str = "") -> dict:
    """Nested parameter mappings as dotted names: ``{"a": {"b": 1}}`` -> ``{"a.b": 1}``."""
    out = {}
    for key, value in mapping.items():
        if isinstance(value, dict):
            out.update(flat_parameters(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out
