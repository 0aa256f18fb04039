"""A mission flown on the ROS graph: the hierarchy's launch document in lockstep, driven leg by leg through ROS.

:func:`fly_mission` starts ``seapup_bringup/launch/hierarchy.launch.yaml`` with a mission's ``graph``
arguments under :class:`seapup_bringup.graph.sil.SilGraph` (every node its own process, plus the recorder) and
flies the legs through ROS only: the self-test through its action, task goals through the task
controller's actions, controller switches through the manager, the current and a fouling through the
simulator's services -- each made while the graph is held at one sample. The result has the shape of
:func:`seapup_runs.mission_flight.run_mission`'s, which flies the same mission in one process
(``./seapup fly MISSION`` / ``--graph``; ``./seapup demo`` flies the shipped one here).
"""
from __future__ import annotations

import time
from pathlib import Path

from seapup_bringup.output import progress, stopped_by_signal
from seapup_common import topics
from seapup_runs.mission import fouling_creep, fouling_result, leg_goal, leg_numbers_of, manual_result, pilot_sends
from seapup_runs.mission_metrics import mission_numbers

__all__ = ["MISSION", "GRAPH", "RECORDED", "mission_path", "mission_config", "fly_mission"]

#: The graph's arguments and the mission (seapup_bringup/config/mission.yaml).
MISSION = "mission.yaml"
#: The graph a mission is flown on (its ``graph`` section: this launch document's arguments).
GRAPH = "seapup_bringup hierarchy.launch.yaml"

#: What the demo's bag holds. Every per-sample topic is typed, so the recorder subscribes before the graph
#: starts and is an extra listener of the graph's lockstep roster: the simulator's first sample waits for it
#: as for the graph's own readers, and the bag holds every sample from t_0 on (docs/recording.md).
#: ``/tf_static`` is untyped: the recorder then matches its publisher's latched QoS and gets the fixed frames
#: sent before it subscribed; ``/tf`` (odom -> base_link) makes the bag show an upright vehicle in any ROS viewer.
RECORDED = [topics.TF_STATIC] + topics.typed(
    topics.CLOCK, topics.TF, topics.COMMAND, topics.APPLIED, topics.TRUTH_ODOMETRY, topics.VELOCITY, topics.IMU,
    topics.DEPTH, topics.POSITION, topics.ALTITUDE, topics.NAVIGATION_ODOMETRY, topics.VELOCITY_REFERENCE,
    topics.POSITION_REFERENCE, topics.SELF_TEST_SAMPLES, topics.DIAGNOSTICS)


def mission_path(vehicle: str = "baseline") -> Path:
    """The shipped mission of ``vehicle``: ``seapup_bringup/config/mission.yaml`` as installed for the Seapup,
    ``mission_<vehicle>.yaml`` for another vehicle that has one (:func:`shipped_missions`).

    Raises
    ------
    MissionError
        For a vehicle no shipped mission is written for.
    """
    from ament_index_python.packages import get_package_share_directory
    config = Path(get_package_share_directory("seapup_bringup")) / "config"
    if vehicle == "baseline":
        return config / MISSION
    missions = shipped_missions()
    if vehicle not in missions:
        from seapup_runs.mission import MissionError
        raise MissionError(f"no shipped mission for the vehicle {vehicle[:60]!r} (shipped for: "
                           f"{', '.join(missions)}); fly your own with --mission FILE")
    return missions[vehicle]


def shipped_missions() -> dict[str, Path]:
    """Vehicle -> its shipped mission file (``baseline``: ``mission.yaml``, others ``mission_<vehicle>.yaml``)."""
    from ament_index_python.packages import get_package_share_directory
    config = Path(get_package_share_directory("seapup_bringup")) / "config"
    return {"baseline": config / MISSION, **{p.stem.removeprefix("mission_"): p
                                              for p in sorted(config.glob("mission_*.yaml"))}}


def mission_config(path: Path | None = None, document=None) -> dict:
    """A mission document (default the shipped one; ``document``: the file ``path`` already read, bounded),
    checked strictly (:mod:`seapup_runs.mission`), its graph arguments among those the hierarchy's launch
    document declares.

    Raises
    ------
    MissionError
        The first thing wrong, in one line naming the file.
    """
    from seapup_common.ros.launch_graph import find_graph, graph_arguments, load_graph
    from seapup_runs.mission import MissionError, load_mission
    path = path or mission_path()
    config = load_mission(path, document).to_dict()
    graph = find_graph(*GRAPH.split())
    declared = graph_arguments(graph)
    unknown = sorted(set(config["graph"]) - set(declared))
    if unknown:
        raise MissionError(f"{path}: graph argument {unknown[0]!r} is not one of {GRAPH}'s: "
                           f"{', '.join(sorted(declared))}")
    arguments = {k: (str(v).lower() if isinstance(v, bool) else str(v)) for k, v in config["graph"].items()}
    controllers = sorted(n.name for n in load_graph(graph, arguments) if n.executable == "velocity_controller")
    for leg in config["mission"]:
        request = leg.get("switch", {})
        request = request.get("request", request)   # a hover's switch has its request inside
        named = [*leg.get("configure", []), *([leg["activate"]] if "activate" in leg else []),
                 *request.get("activate", []), *request.get("deactivate", []),
                 *[leg[key] for key in ("controller", "hand_back") if key in leg]]
        strangers = [name for name in named if name not in controllers]
        if strangers:
            raise MissionError(f"{path}: leg {leg['name']!r} names {strangers[0]!r}, not a velocity controller of "
                               f"{GRAPH} ({', '.join(controllers)})")
    return config


def _set_parameter(sil, node: str, name: str, value: str) -> None:
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    parameter = Parameter(name=name, value=ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value))
    response = sil.call(f"{topics.NAMESPACE}/{node}/set_parameters", "rcl_interfaces/srv/SetParameters", {"parameters": [parameter]})
    if not response.results[0].successful:
        raise RuntimeError(f"{node}: {name} refused: {response.results[0].reason}")


def fly_mission(out: Path, config: dict, text, extra_nodes=()) -> dict:
    """Fly the mission in a SIL graph (with ``extra_nodes``: the live view); the per-leg numbers (and the logs
    as arrays under ``logs``)."""
    from seapup_bringup.graph.graph_runner import GraphSpec, fly_graph
    from seapup_bringup.graph.hierarchy_config import hierarchy_config

    from seapup_runs.mission_flight import check_manual_legs
    graph = config["graph"]
    hierarchy = hierarchy_config(graph)
    check_manual_legs(config["mission"], hierarchy)   # before the graph starts
    simulator = hierarchy.simulator
    seabed = simulator["environment"]["seabed"]
    from seapup_sim.vehicle import VehicleModel
    from seapup_sim.vehicle_config import load_vehicle_config
    limit = VehicleModel(load_vehicle_config(simulator["vehicle"])).pitch_limit   # the inputs' (numbers' saturation)
    legs, swap = [], {}
    plan = [dict(leg, index=i) for i, leg in enumerate(config["mission"])]
    total = sum(leg.get("expected", 60.0) for leg in plan)
    stopped = None  # the signal that ended the mission early (Ctrl-C, SIGTERM, SIGHUP)
    logs, bag, held, ended = {}, out / "bag", None, {}

    def flight(sil) -> None:
        nonlocal stopped
        done = 0.0
        for leg in plan:
            start, wall = sil.t, time.monotonic()
            progress(f"{leg['name']:<18}", done / total)
            try:
                numbers = _fly_leg(sil, leg, swap, laws=hierarchy.velocity_controllers)
            except BaseException as exc:  # interrupted: the legs flown so far still get their numbers
                if not stopped_by_signal(exc):
                    raise
                stopped = exc
                print(f"\nseapup demo: interrupted in leg {leg['name']}; reporting the {len(legs)} legs flown",
                      file=text)
                break
            numbers.setdefault("t0", start)
            numbers.setdefault("t1", sil.t)
            done += leg.get("expected", 60.0)
            legs.append({"name": leg["name"], "kind": leg["kind"], "goal": leg.get("goal", {}),
                         "hold_from": float(leg.get("hold_from", 0.0)),
                         "wall_s": time.monotonic() - wall, **numbers})
            print(f"seapup demo: {leg['name']}: {numbers.get('status', 'done')} in "
                  f"{numbers['t1'] - numbers['t0']:.1f} s simulated ({time.monotonic() - wall:.1f} s wall)",
                  file=text)
        if stopped is None:
            progress("mission", 1.0)
    spec = GraphSpec("mission", GRAPH, graph, record=tuple(RECORDED), ready_status="", start_at=0.0,
                     extra_nodes=tuple(extra_nodes),
                     banner="seapup demo: ROS domain {domain} (loopback only), output in {out}")
    try:
        flown = fly_graph(spec, out, flight, text=text)
        logs, bag, held, ended = flown.logs, flown.bag, flown.held, flown.ended_waits
        if ended:
            print("seapup demo: wall-clock limits ended lockstep waits (a loaded machine?), so this flight may "
                  "differ from a quieter one: " + "; ".join(f"{node} {counts}" for node, counts in ended.items()),
                  file=text)
    except BaseException as exc:  # interrupted while the graph started or stopped: nothing (more) flown
        if stopped is not None or not stopped_by_signal(exc):
            raise
        stopped = exc
        print(f"\nseapup demo: interrupted; reporting the {len(legs)} legs flown", file=text)
    mission_numbers(legs, logs, seabed, swap, limit)
    # held: the sample [s] the paced graph was held at when it stopped
    # ended_waits: which nodes went on without what a lockstep wait waited for (empty: deterministic)
    return {"transport": "graph", "legs": legs, "bag": str(bag), "held": held, "logs": logs, "stopped": stopped,
            "ended_waits": ended}


def _set_current(sil, detail: dict) -> None:
    """The simulator's current (``seapup_msgs/srv/SetCurrent`` fields), or why not."""
    reply = sil.call(topics.SET_CURRENT_SERVICE, "seapup_msgs/srv/SetCurrent", detail)
    if not reply.success:
        raise RuntimeError(f"set_current: {reply.message}")


def _fly_fouling(sil, leg: dict, swap: dict) -> dict:
    """The fouled-thruster leg: an inspection creep whose thruster fouls ``foul.after`` s in under the active
    (self-tested) controller, then, held at its end, the switch to the self-tuner and a second creep."""
    marks = {}
    if "current" in leg:   # the station keeping's current off: the fouling, not the current, is the test
        _set_current(sil, leg["current"])

    def foul():
        marks["foul_t"] = sil.t
        reply = sil.call(topics.SET_THRUSTER_EFFICIENCY_SERVICE, "seapup_msgs/srv/SetThrusterEfficiency",
                         {"efficiency": [float(v) for v in leg["foul"]["efficiency"]]})
        if not reply.success:
            raise RuntimeError(f"set_thruster_efficiency: {reply.message}")
        return reply
    fixed = _fly_leg(sil, fouling_creep(leg, leg["fouled_seconds"]), swap, during=(leg["foul"]["after"], foul))
    marks["switch_t"] = sil.t
    reply = sil.switch(**leg["switch"])
    if not reply.ok:
        raise RuntimeError(f"{leg['name']}: switch refused: {reply.message}")
    adaptive = _fly_leg(sil, fouling_creep(leg, leg["adaptive_seconds"]), swap)
    return fouling_result(leg, fixed, adaptive, marks)


def _fly_manual(sil, leg: dict, laws: dict) -> dict:
    """A manual leg (:func:`seapup_runs.mission_flight._fly_manual` flies it in process): the pilot's controller
    in, its stick published as a teleop tool publishes it, at holds, while the task controller follows the
    vehicle; ``seconds`` in (or at once should the following end earlier), held there, the hand-back: the task's
    controller in and the following cancelled (the task controller hovers where the vehicle is from the next
    estimate); then a hover where the vehicle is. Each switch from whichever law flies (best effort: a law that
    is not active is not deactivated, one already active is left as it is), as the process's."""
    from seapup_bringup.graph.sil import send_pilot
    marks = {"take_t": sil.t}
    _switch(sil, leg, [leg["controller"]], [name for name in laws if name != leg["controller"]], strict=False)
    sends = pilot_sends(leg)
    if sends and sends[0][0] == 0.0:   # the first stick at the hold the pilot takes over at
        send_pilot(sil, sends.pop(0)[1], leg["controller"])

    def hand_back():
        marks["hand_back_t"] = sil.t
        _switch(sil, leg, [leg["hand_back"]], [name for name in laws if name != leg["hand_back"]], strict=False)
    acts = [*((after, lambda demand=demand: send_pilot(sil, demand, leg["controller"])) for after, demand in sends),
            (float(leg["seconds"]), hand_back)]
    piloted = _goal(sil, leg, "hover", {"follow": True}, acts=acts, cancel_after=float(leg["seconds"]))
    if "hand_back_t" not in marks:   # the following ended before its time: handed back where it ended
        hand_back()
    held = _goal(sil, leg, "hover", {"hold_current": True, "duration": float(leg["goal"]["duration"])})
    return manual_result(leg, piloted, held, marks)


def _switch(sil, leg: dict, activate: list, deactivate: list, strict: bool = True) -> None:
    reply = sil.switch(activate=activate, deactivate=deactivate, strict=strict)
    if not reply.ok:
        raise RuntimeError(f"{leg['name']}: switch refused: {reply.message}")


def _goal(sil, leg: dict, kind: str, goal: dict, acts=(), cancel_after: float | None = None) -> dict:
    result = sil.goal(kind, timeout=600.0, acts=acts, cancel_after=cancel_after, **goal)
    if not result["accepted"]:
        raise RuntimeError(f"{leg['name']}: goal rejected: {result['rejection']}")
    return leg_numbers_of(result, None, goal)


def _fly_leg(sil, leg: dict, swap: dict, during: tuple | None = None, laws: dict | None = None) -> dict:
    kind = leg["kind"]
    if kind == "fouling":
        return _fly_fouling(sil, leg, swap)
    if kind == "manual":
        return _fly_manual(sil, leg, laws or {})
    if kind == "self_test":
        t0 = sil.t
        fields = {k: [float(x) for x in v] if isinstance(v, list) else v for k, v in leg.get("goal", {}).items()}
        result = sil.action(topics.SELF_TEST_ACTION, "seapup_msgs/action/SelfTest", fields)
        t1 = sil.t
        if not result.success:
            raise RuntimeError(f"self-test failed: {result.message}")
        for node in leg["configure"]:
            _set_parameter(sil, node, "controller_file", result.controller_file)
        reply = sil.switch(activate=[leg["activate"]])
        if not reply.ok:
            raise RuntimeError(f"activating {leg['activate']}: {reply.message}")
        return {"status": "succeeded", "t0": t0, "t1": t1, "controller_file": result.controller_file,
                "self_test_duration": result.duration}
    if kind == "current":
        _set_current(sil, leg["current"])
    _, here, attitude = sil.estimate()
    kind, goal, target = leg_goal(leg, here, float(attitude[2]))
    if "switch" in leg:
        def do_switch():
            swap["t"] = sil.t
            return sil.switch(**leg["switch"]["request"])
        during = (leg["switch"]["after"], do_switch)
    result = sil.goal(kind, timeout=600.0, during=during, **goal)
    if not result["accepted"]:
        raise RuntimeError(f"{leg['name']}: goal rejected: {result['rejection']}")
    if "switch" in leg:
        swap["leg"] = leg["index"]
        result["switch_ok"] = bool(result["during"].ok)
    return leg_numbers_of(result, target, goal)
