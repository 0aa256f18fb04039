"""What a viewer may ask of the live view: its service payloads and parameter sets, checked before anything is sent.

Pure (no ROS, no server): each function takes what the Foxglove server handed the view (a service call's payload
bytes, a ``setParameters`` request's names and values) and returns the typed request the node sends to the graph,
or raises :class:`ViewRequestError` with one line naming the reason. The node (``live_view_node.py``) says that
line on ``/events``, counts it and answers the viewer with it; nothing reaches the graph.

The rules (``docs/live-view.md``):

- a payload is at most :data:`MAX_PAYLOAD_BYTES` of UTF-8 JSON holding one object; unknown keys are refused;
- a boolean is a JSON ``true`` or ``false`` (no ``"false"``, ``0`` or ``[0]``);
- a number is a JSON number (not a boolean, not a string), finite and within the range given per key;
- a name is a non-empty string of at most :data:`MAX_NAME_LENGTH` printable characters (no NUL, no control
  character: ROS strings end at a NUL, so ``"haslar\\u0000x"`` would reach the graph as ``"haslar"``);
- a ``setParameters`` request names at most :data:`MAX_PARAMETERS_PER_REQUEST` parameters, each once, each one
  of :data:`VIEW_PARAMETERS`.
"""
from __future__ import annotations

import json
import math

from seapup_common.values import finite_real

__all__ = ["ViewRequestError", "MAX_PAYLOAD_BYTES", "MAX_NAME_LENGTH", "MAX_PARAMETERS_PER_REQUEST",
           "VIEW_PARAMETERS", "CURRENT_KEYS", "GOTO_KEYS", "LOCKSTEP_PACE_RANGE", "parse_payload", "switch_request",
           "current_request", "profile_request", "goto_request", "parameter_request"]

#: The largest service payload read [bytes]: the longest valid request (``goto`` with every key) is ~250.
MAX_PAYLOAD_BYTES = 4096
#: The longest controller or sensor-profile name taken (the shipped ones are under 20 characters).
MAX_NAME_LENGTH = 64
#: The view's parameters: the simulator's lockstep pace and the active velocity controller.
VIEW_PARAMETERS = ("lockstep_pace", "controller")
#: A ``setParameters`` request sets each of the view's parameters at most once.
MAX_PARAMETERS_PER_REQUEST = len(VIEW_PARAMETERS)
#: The simulator's declared range of ``lockstep_pace`` (``simulator_node.py``: 0 = unpaced) [x real time].
LOCKSTEP_PACE_RANGE = (0.0, 1e4)
#: ``set_current``'s keys: ``enabled`` (boolean) and the current's statistics (seapup_msgs/srv/SetCurrent).
CURRENT_KEYS = ("enabled", "mean_speed", "mean_direction", "speed_std", "direction_std", "break_time")
#: A goto request's keys (seapup_msgs/action/Goto's goal; all but x, y, z optional).
GOTO_KEYS = ("x", "y", "z", "yaw", "speed", "tolerance", "yaw_tolerance", "timeout", "preempt")

_ANY = (-math.inf, math.inf)
_NON_NEGATIVE = (0.0, math.inf)
#: The ranges of set_current's numbers: the simulator's CurrentParams rules (speeds and standard deviations >= 0;
#: break_time 0 keeps the present T_c, so >= 0 here).
_CURRENT_RANGES = {"mean_speed": _NON_NEGATIVE, "mean_direction": _ANY, "speed_std": _NON_NEGATIVE,
                   "direction_std": _NON_NEGATIVE, "break_time": _NON_NEGATIVE}
#: The ranges of a goto goal's numbers (0 = the task controller's default for the last four; it checks the rest).
_GOTO_RANGES = {"x": _ANY, "y": _ANY, "z": _ANY, "yaw": _ANY, "speed": _NON_NEGATIVE, "tolerance": _NON_NEGATIVE,
                "yaw_tolerance": _NON_NEGATIVE, "timeout": _NON_NEGATIVE}


class ViewRequestError(ValueError):
    """A viewer's request refused before it reached the graph (one line: what, the value and what is allowed)."""


def _shown(value, limit: int = 40) -> str:
    """``value`` as JSON, cut to ``limit`` characters (a refusal stays one short line)."""
    try:
        text = json.dumps(value)
    except (TypeError, ValueError):
        text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def parse_payload(payload: bytes, service: str, allowed) -> dict:
    """A service call's payload as a JSON object with only ``allowed`` keys.

    Parameters
    ----------
    payload : bytes
        The call's payload as the server received it (an empty payload is the empty object).
    service : str
        The service's name (for the message).
    allowed : iterable of str
        The keys the service takes.

    Returns
    -------
    dict
        The object.

    Raises
    ------
    ViewRequestError
        More than :data:`MAX_PAYLOAD_BYTES`, not UTF-8, not JSON (its reason), not an object, or a key not in
        ``allowed``.
    """
    payload = bytes(payload)
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise ViewRequestError(f"{service}: payload of {len(payload)} bytes, at most {MAX_PAYLOAD_BYTES} taken")
    try:
        text = payload.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ViewRequestError(f"{service}: payload is not UTF-8 (byte {exc.start})") from None
    try:
        body = json.loads(text or "{}", parse_constant=_no_constant)
    except json.JSONDecodeError as exc:
        raise ViewRequestError(f"{service}: payload is not JSON: {exc.msg} at line {exc.lineno} column {exc.colno}") \
            from None
    except ViewRequestError as exc:   # NaN, Infinity
        raise ViewRequestError(f"{service}: payload is not JSON: {exc}") from None
    except RecursionError:
        raise ViewRequestError(f"{service}: payload is not JSON: nested too deeply") from None
    if not isinstance(body, dict):
        raise ViewRequestError(f"{service}: payload must be a JSON object, got {_shown(body)}")
    allowed = tuple(allowed)
    unknown = sorted(set(body) - set(allowed))
    if unknown:
        raise ViewRequestError(f"{service}: unknown keys {_shown(unknown)} (allowed: {', '.join(allowed)})")
    return body


def _no_constant(name: str):
    raise ViewRequestError(f"{name} is not a JSON number")


def _number(context: str, key: str, value, bounds: tuple[float, float]) -> float:
    """``value`` as a finite float within ``bounds`` (closed), or refused."""
    lo, hi = bounds
    number = finite_real(value)
    if number is None:
        raise ViewRequestError(f"{context}: {key} must be a finite number, got {_shown(value)}")
    if not lo <= number <= hi:
        allowed = f">= {lo:g}" if hi == math.inf else f"in [{lo:g}, {hi:g}]"
        raise ViewRequestError(f"{context}: {key} must be {allowed}, got {number:g}")
    return number


def _boolean(context: str, key: str, value) -> bool:
    if not isinstance(value, bool):
        raise ViewRequestError(f"{context}: {key} must be true or false (a JSON boolean), got {_shown(value)}")
    return value


def _name(context: str, key: str, value) -> str:
    if not isinstance(value, str) or not value:
        raise ViewRequestError(f"{context}: {key} must be a non-empty string, got {_shown(value)}")
    if len(value) > MAX_NAME_LENGTH:
        raise ViewRequestError(f"{context}: {key} is {len(value)} characters long, at most {MAX_NAME_LENGTH} taken")
    bad = next((c for c in value if not c.isprintable()), None)
    if bad is not None:
        raise ViewRequestError(f"{context}: {key} holds the unprintable character U+{ord(bad):04X} "
                               f"(a name is printable text)")
    return value


def switch_request(payload: bytes) -> str:
    """``switch_controller``: ``{"activate": "<controller>"}`` -> the controller's name."""
    body = parse_payload(payload, "switch_controller", ("activate",))
    if "activate" not in body:
        raise ViewRequestError('switch_controller needs {"activate": "<controller name>"}')
    return _name("switch_controller", "activate", body["activate"])


def current_request(payload: bytes) -> dict:
    """``set_current``: the current on (``enabled``, default true) with its statistics (each default 0), or off.

    Returns
    -------
    dict
        Every key of :data:`CURRENT_KEYS`: ``enabled`` a bool, the others floats in their ranges.
    """
    body = parse_payload(payload, "set_current", CURRENT_KEYS)
    request = {"enabled": _boolean("set_current", "enabled", body.get("enabled", True))}
    for key, bounds in _CURRENT_RANGES.items():
        request[key] = _number("set_current", key, body.get(key, 0.0), bounds)
    return request


def profile_request(payload: bytes) -> str:
    """``set_sensor_profile``: ``{"name": "haslar"}`` -> the profile's name (the simulator knows which exist)."""
    body = parse_payload(payload, "set_sensor_profile", ("name",))
    if "name" not in body:
        raise ViewRequestError('set_sensor_profile needs {"name": "ideal|baseline|haslar"}')
    return _name("set_sensor_profile", "name", body["name"])


def goto_request(payload: bytes) -> dict:
    """``goto``: a goal of the task controller (odom_ned [m], yaw [rad]); x, y and z required.

    Returns
    -------
    dict
        The keys given: floats, and ``preempt`` a bool.
    """
    body = parse_payload(payload, "goto", GOTO_KEYS)
    missing = [k for k in ("x", "y", "z") if k not in body]
    if missing:
        raise ViewRequestError(f"goto needs x, y, z (odom_ned, m); missing {', '.join(missing)}")
    return {key: _boolean("goto", key, value) if key == "preempt" else _number("goto", key, value, _GOTO_RANGES[key])
            for key, value in body.items()}


def parameter_request(parameters) -> list[tuple[str, object]]:
    """A ``setParameters`` request's (name, value) pairs, checked.

    Parameters
    ----------
    parameters : sequence of (str, object)
        The names and the values as the server decoded them (a float64 parameter is a float, an integer an int).
        Its length is checked before any pair is read.

    Returns
    -------
    list of (str, object)
        ``lockstep_pace`` as a float in :data:`LOCKSTEP_PACE_RANGE`, ``controller`` as a name.

    Raises
    ------
    ViewRequestError
        More than :data:`MAX_PARAMETERS_PER_REQUEST` parameters, none, a name twice, a name not in
        :data:`VIEW_PARAMETERS`, or a value of the wrong type or out of range.
    """
    if len(parameters) > MAX_PARAMETERS_PER_REQUEST:
        raise ViewRequestError(f"setParameters: {len(parameters)} parameters in one request, at most "
                               f"{MAX_PARAMETERS_PER_REQUEST} ({', '.join(VIEW_PARAMETERS)}, each once)")
    checked, seen = [], set()
    for name, value in parameters:
        if name not in VIEW_PARAMETERS:
            raise ViewRequestError(f"setParameters: no parameter {_shown(name)} (parameters: "
                                   f"{', '.join(VIEW_PARAMETERS)})")
        if name in seen:
            raise ViewRequestError(f"setParameters: {name} named twice in one request")
        seen.add(name)
        if name == "lockstep_pace":
            checked.append((name, _number("setParameters", name, value, LOCKSTEP_PACE_RANGE)))
        else:
            checked.append((name, _name("setParameters", name, value)))
    if not checked:
        raise ViewRequestError("setParameters: no parameter named")
    return checked


#: The pilot's channel a viewer may publish on (Foxglove's Teleop or Publish panel): a ``geometry_msgs/Twist`` in
#: JSON, REP-103 ``base_link``; its schema named either way Foxglove names it.
PILOT_SCHEMAS = ("geometry_msgs/msg/Twist", "geometry_msgs/Twist")
#: The largest velocity component a pilot message may carry [m/s, rad/s] (the manual law bounds it again).
PILOT_BOUND = 10.0


def pilot_channel(topic: str, encoding: str, schema_name: str, pilot_topic: str) -> None:
    """A viewer's advertised channel, taken only as the pilot's: ``pilot_topic``, JSON, a Twist.

    Raises
    ------
    ViewRequestError
        Any other channel (its topic, encoding or schema named).
    """
    if topic != pilot_topic or encoding != "json" or schema_name not in PILOT_SCHEMAS:
        raise ViewRequestError(f"client channel {_shown(topic)} ({_shown(encoding)}, {_shown(schema_name)}): only "
                               f"{pilot_topic} as JSON geometry_msgs/Twist is taken")


def pilot_twist(payload: bytes) -> tuple[tuple, tuple]:
    """A viewer's pilot message (JSON ``{"linear": {x, y, z}, "angular": {x, y, z}}``, missing components
    zero) as (linear, angular) floats, each within +-:data:`PILOT_BOUND`.

    Raises
    ------
    ViewRequestError
        As :func:`parse_payload`, or a component that is not a finite number within the bound.
    """
    body = parse_payload(payload, "pilot", ("linear", "angular"))
    out = []
    for part in ("linear", "angular"):
        vector = body.get(part, {})
        if not isinstance(vector, dict) or set(vector) - {"x", "y", "z"}:
            raise ViewRequestError(f"pilot: {part} must be an object of x, y, z, got {_shown(vector)}")
        out.append(tuple(_number(f"pilot {part}", key, vector.get(key, 0.0), (-PILOT_BOUND, PILOT_BOUND))
                         for key in ("x", "y", "z")))
    return out[0], out[1]


def switch_lists(name: str, active: str) -> tuple[list, list]:
    """The controller manager's switch to velocity controller ``name`` from ``active`` (the one flying, '' for
    none): (activate, deactivate). The manager activates nothing while another controller is active unless the
    same request deactivates it (exactly one commands the thrusters), so a viewer's switch names both.

    >>> switch_lists("manual", "mfol_fixed"), switch_lists("gmv", "")
    ((['manual'], ['mfol_fixed']), (['gmv'], []))
    """
    return [name], ([active] if active and active != name else [])

