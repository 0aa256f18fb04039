"""The hierarchy's launch document and its nodes' parameter files as plain data, for a mission flown in process.

:func:`hierarchy_config` reads ``seapup_bringup/launch/hierarchy.launch.yaml`` with a mission's ``graph``
arguments and each node's installed ``config/<node>.yaml``, and returns the
:class:`~seapup_runs.mission_flight.HierarchyConfig` :func:`seapup_runs.mission_flight.run_mission` flies:
so the graph and the process read one source, the launch document, for which nodes there are and how
each is set.
"""
from __future__ import annotations

from pathlib import Path

from seapup_common.launch_format import flat_parameters
from seapup_runs.mission_flight import HierarchyConfig

__all__ = ["hierarchy_config", "HIERARCHY"]

#: The launch document a mission's ``graph`` section gives the arguments of.
HIERARCHY = ("seapup_bringup", "hierarchy.launch.yaml")


def _defaults(package: str, file: str, section: str) -> dict:
    from ament_index_python.packages import get_package_share_directory

    from seapup_common.parameters import load_node_parameters
    return load_node_parameters(Path(get_package_share_directory(package)) / "config" / file, section)


def _bool(value) -> bool:
    return value if isinstance(value, bool) else str(value).strip().lower() in ("true", "1", "yes")


def _design(node: str, kind: str, path: str) -> dict:
    """The design document of velocity controller ``node``'s ``controller_file``, read as the node reads it
    (:meth:`~seapup_common.controllers.ControllerSpec.load_document`: bounded, strict YAML, a mapping)."""
    from seapup_common.controllers import ControllerRegistryError, ControllerSpec
    from seapup_common.ros.launch_graph import LaunchError
    try:
        return dict(ControllerSpec(kind, {}, file=path).load_document())
    except ControllerRegistryError as exc:
        raise LaunchError(f"{node}: {exc}") from None


def hierarchy_config(graph: dict, launch: tuple[str, str] = HIERARCHY) -> HierarchyConfig:
    """The nodes of ``launch`` with ``graph``'s arguments, as :class:`HierarchyConfig`.

    Raises
    ------
    LaunchError
        An argument the document refuses, or a controller file that cannot be read (one line, naming it).
    """
    from seapup_common.ros.launch_graph import find_graph, load_graph
    arguments = {k: (str(v).lower() if isinstance(v, bool) else str(v)) for k, v in graph.items()}
    nodes = load_graph(find_graph(*launch), arguments)
    by_exec: dict = {}
    for node in nodes:
        by_exec.setdefault(node.executable, []).append(node)
    sim = {**flat_parameters(_defaults("seapup_sim", "simulator.yaml", "simulator")),
           **by_exec["simulator"][0].given_parameters()}
    environment = {"sensors": str(sim["environment.sensors"]),
                   "current": {"enabled": _bool(sim["environment.current.enabled"])},
                   "seabed": {"kind": str(sim["environment.seabed.kind"]),
                              "depth": float(sim["environment.seabed.depth"]),
                              "gradient": float(sim["environment.seabed.gradient"]),
                              "direction": float(sim["environment.seabed.direction"])}}
    simulator = {"vehicle": str(sim["vehicle"]), "seed": int(sim["seed"]), "start_depth": float(sim["start_depth"]),
                 "environment": environment, "physics_step": float(sim["physics_step"]),
                 "control_period": float(sim["control_period"]), "dynamics": str(sim["dynamics"]),
                 "watchdog_timeout": float(sim["watchdog_timeout"]), "watchdog_action": str(sim["watchdog_action"])}

    def node(executable: str, file: str) -> dict:
        return {**_defaults("seapup_control", file, executable), **by_exec[executable][0].given_parameters()}
    velocity_defaults = _defaults("seapup_control", "velocity_controller.yaml", "velocity_controller")
    controllers = {n.name: HierarchyConfig.controller({**velocity_defaults, **n.given_parameters()})
                   for n in by_exec.get("velocity_controller", [])}
    # what the nodes are given to configure from (the file's document, read now: a campaign's worker on another
    # machine flies it without the file), and the manager's initial controller (activated at the start)
    designs = {n.name: _design(n.name, controllers[n.name][0], str(n.given_parameters()["controller_file"]))
               for n in by_exec.get("velocity_controller", [])
               if str(n.given_parameters().get("controller_file", "") or "")}
    managers = by_exec.get("controller_manager", [])
    initial = str(managers[0].given_parameters().get("initial", "") or "") if managers else ""
    return HierarchyConfig(simulator, node("navigator", "navigator.yaml"),
                           node("task_controller", "task_controller.yaml"),
                           node("position_controller", "position_controller.yaml"), controllers, designs, initial)
