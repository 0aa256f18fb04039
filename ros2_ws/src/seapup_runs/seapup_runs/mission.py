"""A mission as data: the supervisory hierarchy's legs (sec. 4.2, fig. 4.3), checked strictly and at once.

A mission document (``seapup_bringup/config/mission.yaml`` is the demo's) has two sections:

``graph``
    the arguments of the hierarchy's launch document (vehicle, sensors, seabed, seed, ...): names and
    scalar values only here (text, a number, a bool); which names the graph takes is the launcher's
    business (``./seapup demo`` refuses one its launch document does not declare).
``mission``
    the legs, flown in order. Every leg has a unique ``name``, a ``kind`` (:data:`LEG_KINDS`), an
    ``expected`` simulated duration [s] (for the progress bar) and ``hold_from`` [s] (hold and altitude
    numbers from this far into the leg). The kinds and what each takes:

    - ``self_test`` -- the self-test (sec. 4.5.2, 5.3) through its action (``goal``: the
      ``seapup_msgs/action/SelfTest`` fields given), then its controller file set on the ``configure``
      controllers and ``activate`` activated;
    - ``hover`` -- hold station (``goal``: ``hold_current``, ``duration``), optionally swapping the
      velocity controller ``switch.after`` s in (``switch.request``: ``activate`` / ``deactivate``);
    - ``goto`` -- to ``offset`` [m, odom_ned] from where it is, turned by ``turn`` [rad] (``goal``:
      ``tolerance``, ``speed``);
    - ``inspection`` -- sec. 5.4.2's body-velocity run (``body_velocity`` [m/s] for ``seconds``) as a
      creeping goto;
    - ``follow_seabed`` -- ``goal``: ``altitude`` [m], ``yaw`` [rad], ``speed`` [m/s], ``duration`` [s];
    - ``current`` -- the current set (``current``: ``enabled`` and sec. 3.9's Gauss-Markov fields), then
      station keeping (``goal.duration``) facing ``face`` [rad] if given;
    - ``manual`` -- flown by hand, then handed back to a task (:mod:`seapup_control.manual`): the velocity
      controller ``controller`` (a ``manual`` one) is activated and flies the scripted ``pilot`` (rows
      ``[t, x, y, z, yaw]``: from ``t`` s into the leg a ``Twist``'s linear x, y, z [m/s] and angular z [rad/s] in
      REP-103's ``base_link``, sent every :data:`PILOT_PERIOD` s as a teleop tool sends it) for ``seconds``
      while the task controller follows the vehicle (a hover with ``follow``); then, at once, ``hand_back`` is
      activated and the following cancelled (the task controller hovers where the vehicle is), and a hover holds
      where the vehicle is (``goal.duration``) from the next hold;
    - ``fouling`` -- sec. 7.4.4: a creep (``body_velocity``) whose thrusters' efficiencies become
      ``foul.efficiency`` ``foul.after`` s in, ``fouled_seconds`` long; then, held, the ``switch``
      (``activate`` / ``deactivate``) and a second creep of ``adaptive_seconds``, its tracking counted
      from ``tune_in`` s after the switch (``current`` optional, set first).

Numbers must be numbers (a quoted ``'0.2'`` and a bool are refused), finite and in range; unknown keys
are refused with the known ones named; a leg's times must fit in it (a switch or a fouling inside its
leg). The size is bounded before anything is flown: at most :data:`MAX_LEGS` legs, each timed part at
most :data:`MAX_SECONDS`. Units SI and radians.
"""
from __future__ import annotations

import bisect
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from seapup_runs.spec import (CURRENT_FIELDS, MAX_THRUSTERS, RunSpecError, _finite, _name, _numbers,
                              _pilot_steps, _refuse_unknown, _short)

__all__ = ["MissionSpec", "MissionError", "LEG_KINDS", "MAX_LEGS", "MAX_SECONDS", "PILOT_PERIOD", "load_mission",
           "leg_goal", "fouling_creep", "fouling_result", "leg_numbers_of", "pilot_sends", "manual_result"]

#: At most this many legs in a mission (the demo has 7).
MAX_LEGS = 1000
#: Any timed part of a leg (a duration, a creep, an expected time) [s]: a day of simulated time.
MAX_SECONDS = 86_400.0
#: [s] how often a manual leg's scripted pilot sends its stick (a teleop tool's 2 Hz; a manual controller's
#: ``silence_timeout`` must be longer, :mod:`seapup_control.manual`).
PILOT_PERIOD = 0.5
#: The largest offset of a goto and the largest body velocity a leg may ask for [m, m/s]: the vehicle's
#: tether is 100 m class and its top speed about 0.7 m/s (sec. 5.3.1); these are generous bounds, not limits.
MAX_OFFSET = 10_000.0
MAX_SPEED = 5.0
#: The graph section's size.
MAX_GRAPH_ARGUMENTS = 100


class MissionError(RunSpecError):
    """A mission document that cannot be flown: the message says where and why."""


def _number(value, what: str, low: float, high: float, *, above: bool = False) -> float:
    number = _finite(value, what)
    if number < low or number > high or (above and number <= low):
        bound = f"({low:g}, {high:g}]" if above else f"[{low:g}, {high:g}]"
        raise MissionError(f"{what} must be in {bound}, got {_short(value)}")
    return number


def _seconds(value, what: str) -> float:
    return _number(value, what, 0.0, MAX_SECONDS, above=True)


def _bool(value, what: str) -> bool:
    if not isinstance(value, bool):
        raise MissionError(f"{what} must be true or false, got {_short(value)}")
    return value


def _names(value, what: str, *, empty_ok: bool = True) -> list[str]:
    if not isinstance(value, list) or len(value) > 100 or (not value and not empty_ok):
        raise MissionError(f"{what} must be a {'' if empty_ok else 'non-empty '}list of at most 100 names, "
                           f"got {_short(value)}")
    return [_name(v, what) for v in value]


def _count(value, what: str, low: int, high: int) -> int:
    number = _number(value, what, low, high)
    if not number.is_integer():
        raise MissionError(f"{what} must be a whole number, got {_short(value)}")
    return int(number)


def _vector(value, what: str, bound: float, unit: str) -> list[float]:
    """Three finite numbers, each within +-``bound``."""
    vector = list(_numbers(value, what, 3))
    if max(map(abs, vector)) > bound:
        raise MissionError(f"{what} must be within +-{bound:g} {unit}, got {_short(value)}")
    return vector


def _offset(value, what: str) -> list[float]:
    return _vector(value, what, MAX_OFFSET, "m")


def _angle(value, what: str) -> float:
    return _number(value, what, -4 * math.pi, 4 * math.pi)


def _mapping(value, what: str, checks: dict, required=()) -> dict:
    """``value`` checked key by key against ``checks`` (name -> check(value, what)), ``required`` present."""
    _refuse_unknown(value, list(checks), what)
    missing = [k for k in required if k not in value]
    if missing:
        raise MissionError(f"{what} needs {', '.join(missing)}")
    return {k: checks[k](v, f"{what} {k}") for k, v in value.items()}


def _current(value, what: str) -> dict:
    checks = {"enabled": _bool, "mean_speed": lambda v, w: _number(v, w, 0.0, MAX_SPEED),
              "speed_std": lambda v, w: _number(v, w, 0.0, MAX_SPEED), "mean_direction": _angle,
              "direction_std": lambda v, w: _number(v, w, 0.0, 4 * math.pi), "break_time": _seconds}
    detail = _mapping(value, what, checks, required=("enabled",))
    if detail["enabled"]:
        missing = [k for k in CURRENT_FIELDS[:4] if k not in detail]
        if missing:
            raise MissionError(f"{what}: an enabled current needs {', '.join(missing)}")
    return detail


def _body_velocity(value, what: str) -> list[float]:
    return _vector(value, what, MAX_SPEED, "m/s")


def _switch_request(value, what: str) -> dict:
    request = _mapping(value, what, {"activate": _names, "deactivate": _names})
    if not request.get("activate") and not request.get("deactivate"):
        raise MissionError(f"{what} activates or deactivates nothing")
    return request


_DURATION = {"duration": _seconds}
_GOALS = {
    "self_test": {"sample_period": lambda v, w: _number(v, w, 0.0, 10.0, above=True),
                  "step": lambda v, w: _number(v, w, 0.0, math.radians(70.0), above=True),
                  "samples": lambda v, w: _count(v, w, 1, 100_000),
                  "quiescence_speed": lambda v, w: _number(v, w, 0.0, MAX_SPEED),
                  "closed_loop_divisor": lambda v, w: _number(v, w, 0.0, 1e6, above=True),
                  "operating_points": lambda v, w: list(_numbers(v, w)),
                  "max_wait": _seconds, "poles_k": lambda v, w: _poles(v, w), "poles_c": lambda v, w: _poles(v, w)},
    "hover": {"hold_current": _bool, **_DURATION},
    "goto": {"tolerance": lambda v, w: _number(v, w, 0.0, MAX_OFFSET, above=True),
             "speed": lambda v, w: _number(v, w, 0.0, MAX_SPEED)},
    "follow_seabed": {"altitude": lambda v, w: _number(v, w, 0.0, MAX_OFFSET, above=True), "yaw": _angle,
                      "speed": lambda v, w: _number(v, w, 0.0, MAX_SPEED), **_DURATION},
    "current": _DURATION,
}
_COMMON = {"name": _name, "kind": None, "expected": _seconds,
           "hold_from": lambda v, w: _number(v, w, 0.0, MAX_SECONDS)}
#: Per kind: the keys it takes beyond the common ones (name -> check) and those it needs.
LEG_KINDS: dict[str, tuple[dict, tuple]] = {
    "self_test": ({"goal": lambda v, w: _mapping(v, w, _GOALS["self_test"]),
                   "configure": lambda v, w: _names(v, w, empty_ok=False), "activate": _name},
                  ("configure", "activate")),
    "hover": ({"goal": lambda v, w: _mapping(v, w, _GOALS["hover"], required=("duration",)),
               "switch": lambda v, w: _mapping(v, w, {"after": lambda x, y: _number(x, y, 0.0, MAX_SECONDS),
                                                      "request": _switch_request}, required=("after", "request"))},
              ("goal",)),
    "goto": ({"offset": _offset, "turn": _angle,
              "goal": lambda v, w: _mapping(v, w, _GOALS["goto"])}, ("offset",)),
    "inspection": ({"body_velocity": _body_velocity, "seconds": _seconds}, ("body_velocity", "seconds")),
    "follow_seabed": ({"goal": lambda v, w: _mapping(v, w, _GOALS["follow_seabed"],
                                                     required=("altitude", "speed", "duration"))}, ("goal",)),
    "current": ({"current": _current, "face": _angle,
                 "goal": lambda v, w: _mapping(v, w, _GOALS["current"], required=("duration",))},
                ("current", "goal")),
    "manual": ({"controller": _name, "hand_back": _name, "pilot": lambda v, w: _pilot(v, w), "seconds": _seconds,
                "goal": lambda v, w: _mapping(v, w, _DURATION, required=("duration",))},
               ("controller", "hand_back", "pilot", "seconds", "goal")),
    "fouling": ({"current": _current, "body_velocity": _body_velocity, "fouled_seconds": _seconds,
                 "foul": lambda v, w: _mapping(v, w, {"after": lambda x, y: _number(x, y, 0.0, MAX_SECONDS),
                                                      "efficiency": _efficiency}, required=("after", "efficiency")),
                 "switch": _switch_request, "adaptive_seconds": _seconds,
                 "tune_in": lambda v, w: _number(v, w, 0.0, MAX_SECONDS)},
                ("body_velocity", "fouled_seconds", "foul", "switch", "adaptive_seconds")),
}


def _pilot(value, what: str) -> list[list[float]]:
    """A manual leg's scripted pilot: rows [t, x, y, z, yaw] (:func:`seapup_runs.spec._pilot_steps`: finite,
    times from 0 rising, at most 1000), each speed within :data:`MAX_SPEED`."""
    try:
        rows = _pilot_steps(value)
    except RunSpecError as exc:
        raise MissionError(f"{what}: {exc}") from None
    if not rows:
        raise MissionError(f"{what} needs at least one [t, x, y, z, yaw] row")
    if any(abs(v) > MAX_SPEED for row in rows for v in row[1:]):
        raise MissionError(f"{what}: speeds must be within {MAX_SPEED:g} m/s (rad/s), got {_short(value)}")
    return [list(row) for row in rows]


def _poles(value, what: str) -> list[float]:
    """Four desired closed-loop poles (loops u, v, w, r at 5 Hz) inside the unit circle's positive half."""
    poles = list(_numbers(value, what, 4))
    if not all(0.0 <= p < 1.0 for p in poles):
        raise MissionError(f"{what} must be four poles in [0, 1) (loops u, v, w, r at 5 Hz), got {_short(value)}")
    return poles


def _efficiency(value, what: str) -> list[float]:
    """One factor in [0, 1] per thruster, in the vehicle description's order (the Seapup's: main port, main
    starboard, vectored starboard, vectored port); that the count is the vehicle's is checked as it flies."""
    if isinstance(value, (list, tuple)) and not 1 <= len(value) <= MAX_THRUSTERS:
        raise MissionError(f"{what} needs one value per thruster (1 to {MAX_THRUSTERS}), got {len(value)}")
    efficiency = list(_numbers(value, what))
    if min(efficiency) < 0.0 or max(efficiency) > 1.0:
        raise MissionError(f"{what} must be values in [0, 1], one per thruster in the vehicle description's order "
                           f"(the Seapup's: main port, main starboard, vectored starboard, vectored port), got "
                           f"{_short(value)}")
    return efficiency


def _leg(value, index: int) -> dict:
    if not isinstance(value, Mapping):
        raise MissionError(f"mission leg {index + 1} must be a mapping, got {_short(value)}")
    kind = value.get("kind")
    if kind not in LEG_KINDS:
        raise MissionError(f"mission leg {index + 1}: kind must be one of {', '.join(LEG_KINDS)}, got {_short(kind)}")
    checks, required = LEG_KINDS[kind]
    label = f"mission leg {index + 1} ({_short(value.get('name'))}, {kind})"
    leg = _mapping(value, label, {**_COMMON, "kind": lambda v, w: v, **checks}, required=("name", *required))
    # its times fit in it
    if kind == "hover" and "switch" in leg and leg["switch"]["after"] >= leg["goal"]["duration"]:
        raise MissionError(f"{label}: switch after {leg['switch']['after']:g} s is not within the hover's "
                           f"{leg['goal']['duration']:g} s")
    if kind == "manual" and leg["pilot"][-1][0] > (_sends(leg["seconds"]) - 1) * PILOT_PERIOD + 1e-9:
        raise MissionError(f"{label}: the pilot's last row at {leg['pilot'][-1][0]:g} s comes after its last send "
                           f"({(_sends(leg['seconds']) - 1) * PILOT_PERIOD:g} s: the stick goes every "
                           f"{PILOT_PERIOD:g} s within the leg's {leg['seconds']:g} s), so it would never be flown")
    if kind == "manual" and leg["controller"] == leg["hand_back"]:
        raise MissionError(f"{label}: hand_back must be another controller than {leg['controller']!r}")
    if kind == "fouling" and leg["foul"]["after"] >= leg["fouled_seconds"]:
        raise MissionError(f"{label}: foul after {leg['foul']['after']:g} s is not within fouled_seconds "
                           f"({leg['fouled_seconds']:g} s)")
    return leg


def _graph(value) -> dict:
    if not isinstance(value, Mapping):
        raise MissionError(f"graph must be a mapping of launch arguments, got {_short(value)}")
    if len(value) > MAX_GRAPH_ARGUMENTS:
        raise MissionError(f"graph has {len(value)} arguments; at most {MAX_GRAPH_ARGUMENTS}")
    graph = {}
    for key, item in value.items():
        name = _name(key, "graph argument name")
        if isinstance(item, bool) or (isinstance(item, int) and abs(item) < 2**63):
            graph[name] = item
        elif isinstance(item, str) and len(item) <= 4096:
            graph[name] = item
        else:
            graph[name] = _finite(item, f"graph {name}")
    return graph


@dataclass(frozen=True)
class MissionSpec:
    """A checked mission (module docstring): the graph's arguments and the legs, in order (plain dicts
    with every number a float and every key known)."""

    graph: dict
    legs: tuple

    @classmethod
    def load(cls, document) -> "MissionSpec":
        """A mission from its document (a mapping with ``graph`` and ``mission``).

        Raises
        ------
        MissionError
            The first thing wrong, in one line.
        """
        try:
            return cls._load(document)
        except MissionError:
            raise
        except RunSpecError as exc:   # the run specification's checks, shared
            raise MissionError(str(exc)) from None

    @classmethod
    def _load(cls, document) -> "MissionSpec":
        _refuse_unknown(document, ("graph", "mission"), "mission document")
        if "mission" not in document:
            raise MissionError("a mission document needs mission: a list of legs")
        legs = document["mission"]
        if not isinstance(legs, list) or not legs:
            raise MissionError(f"mission must be a non-empty list of legs, got {_short(legs)}")
        if len(legs) > MAX_LEGS:
            raise MissionError(f"mission has {len(legs)} legs; at most {MAX_LEGS}")
        checked = tuple(_leg(leg, i) for i, leg in enumerate(legs))
        names = [leg["name"] for leg in checked]
        repeated = sorted({n for n in names if names.count(n) > 1})
        if repeated:
            raise MissionError(f"leg names must be unique; repeated: {', '.join(map(repr, repeated))}")
        return cls(_graph(document.get("graph", {})), checked)

    def to_dict(self) -> dict:
        return {"graph": dict(self.graph), "mission": [dict(leg) for leg in self.legs]}

    @property
    def expected_seconds(self) -> float:
        """The legs' expected simulated time [s] (60 s for a leg that gives none)."""
        return sum(leg.get("expected", 60.0) for leg in self.legs)


def load_mission(path: str | Path, document=None) -> MissionSpec:
    """A mission file read within the size limit of a specification, duplicate keys refused
    (:mod:`seapup_common.input_files`), and checked (:meth:`MissionSpec.load`); ``document``: the file's
    content already read that way (not read again).

    Raises
    ------
    MissionError
        A file that cannot be read or parsed, or a mission that cannot be flown; the message names the file.
    """
    from seapup_common.input_files import InputFileError, load_yaml_file
    try:
        document = load_yaml_file(path, "spec") if document is None else document
    except InputFileError as exc:
        raise MissionError(str(exc)) from None
    try:
        return MissionSpec.load(document)
    except MissionError as exc:
        raise MissionError(f"{path}: {exc}") from None


# -- how a leg is flown: what the graph and the in-process runner share ------------------------------------------
#: [m] an inspection creep's arrival radius (the task controller's default)
CREEP_TOLERANCE = 0.5


def leg_goal(leg: dict, position, yaw: float) -> tuple[str, dict, list | None]:
    """The task goal a leg flies, from where the vehicle is when it is accepted (the navigation estimate's
    ``position`` [m, odom_ned] and ``yaw`` [rad]): (the task controller's action -- ``hover``, ``goto`` or
    ``follow_seabed`` --, the goal's fields, the target [m] of a leg that has one or None).

    An inspection (sec. 5.4.2) is a creeping goto along its body velocity, turned into odom_ned by the yaw, for
    its ``seconds``; a current leg holds where it is, facing ``face`` when given; a goto's target is ``offset``
    from here and its yaw ``turn`` from the present one.

    Examples
    --------
    >>> leg_goal({"kind": "goto", "offset": [3.0, 4.0, 0.0], "turn": 0.5}, [1.0, 1.0, 30.0], 0.25)
    ('goto', {'x': 4.0, 'y': 5.0, 'z': 30.0, 'yaw': 0.75}, [4.0, 5.0, 30.0])
    """
    import numpy as np
    kind = "hover" if leg["kind"] == "current" else leg["kind"]
    here = np.asarray(position, dtype=float)
    goal = dict(leg.get("goal", {}))
    target = None
    if kind == "inspection":
        body = np.asarray(leg["body_velocity"], dtype=float)
        c, s = math.cos(yaw), math.sin(yaw)
        target = here + np.array([c * body[0] - s * body[1], s * body[0] + c * body[1], body[2]]) * leg["seconds"]
        goal = {"x": target[0], "y": target[1], "z": target[2], "yaw": yaw,
                "speed": float(np.linalg.norm(body)), "tolerance": CREEP_TOLERANCE}
        kind = "goto"
    elif "face" in leg:  # hold where it is, turned to this heading (e.g. into the current)
        goal.update(hold_current=False, x=here[0], y=here[1], z=here[2], yaw=float(leg["face"]))
    elif "offset" in leg:
        target = here + np.asarray(leg["offset"], dtype=float)
        goal.update(x=target[0], y=target[1], z=target[2], yaw=float(yaw + leg.get("turn", 0.0)))
    fields = {k: v if isinstance(v, bool) else float(v) for k, v in goal.items()}
    return kind, fields, None if target is None else [float(v) for v in target]


def leg_numbers_of(result: dict, target: list | None, goal: dict) -> dict:
    """A goal leg's entry from its goal's result (status, the task's numbers, ``accepted_t``, ``end_t``): the
    numbers with ``t0``/``t1`` (accepted, held after), and a leg's target and its tolerance."""
    out = {k: v for k, v in result.items() if k not in ("during", "accepted_t", "end_t")}
    out.update(t0=result["accepted_t"], t1=result["end_t"])
    if target is not None:
        out["target"] = target
        out["tolerance"] = float(goal.get("tolerance", CREEP_TOLERANCE))  # the task controller's default radius
    return out


def fouling_creep(leg: dict, seconds: float) -> dict:
    """One of a fouling leg's two creeps (sec. 7.4.4): an inspection along its body velocity for ``seconds``."""
    return {"kind": "inspection", "name": leg["name"], "body_velocity": leg["body_velocity"], "index": leg["index"],
            "seconds": seconds}


def fouling_result(leg: dict, fixed: dict, adaptive: dict, marks: dict) -> dict:
    """A fouling leg's entry from its creeps' (under the fixed gains, then the self-tuner): succeeded when both
    did, else the first that did not; its window from the first creep's start to the second's hold; the times of
    the fouling and the switch (``marks``), the incoming controller and ``tune_in``."""
    status = "succeeded" if fixed.get("status") == adaptive.get("status") == "succeeded" else \
        adaptive.get("status") if fixed.get("status") == "succeeded" else fixed.get("status")
    return {**adaptive, "status": status, "t0": fixed["t0"], "t1": adaptive["t1"], **marks,
            "controller": leg["switch"]["activate"][0], "tune_in": float(leg.get("tune_in", 0.0))}


def pilot_sends(leg: dict) -> list[tuple[float, tuple]]:
    """A manual leg's stick as a teleop tool sends it: (time into the leg [s], (x, y, z, yaw) of the row in force)
    every :data:`PILOT_PERIOD` s from 0 to before ``seconds`` (none before the first row: the pilot is silent).

    >>> pilot_sends({"pilot": [[0.0, 0.2, 0, 0, 0], [1.0, 0, 0, 0, 0.1]], "seconds": 1.5})
    [(0.0, (0.2, 0, 0, 0)), (0.5, (0.2, 0, 0, 0)), (1.0, (0, 0, 0, 0.1))]
    """
    rows, out = leg["pilot"], []
    times = [row[0] for row in rows]
    for k in range(_sends(leg["seconds"])):
        t = k * PILOT_PERIOD
        in_force = bisect.bisect_right(times, t + 1e-9)   # rows at or before t
        if in_force:
            out.append((t, tuple(rows[in_force - 1][1:])))
    return out


def _sends(seconds: float) -> int:
    """How many sends a manual leg of ``seconds`` makes (at 0, :data:`PILOT_PERIOD`, ... before ``seconds``)."""
    return int(math.ceil(seconds / PILOT_PERIOD - 1e-9))


def manual_result(leg: dict, piloted: dict, held: dict, marks: dict) -> dict:
    """A manual leg's entry from its two goals' (the followed hover the pilot flew, cancelled at the hand-back,
    then the hover after it): succeeded when the first was cancelled and the second succeeded, else the first
    that did not; its window from the pilot's start to the
    hold's end; the times the pilot took over and handed back (``marks``) and the two controllers."""
    piloted_ok = piloted.get("status") == "canceled"   # the following ends by the hand-back's cancel
    status = "succeeded" if piloted_ok and held.get("status") == "succeeded" else \
        held.get("status") if piloted_ok else piloted.get("status")
    return {**held, "status": status, "t0": piloted["t0"], "t1": held["t1"], **marks,
            "controller": leg["controller"], "hand_back": leg["hand_back"], "piloted_s": float(leg["seconds"])}

