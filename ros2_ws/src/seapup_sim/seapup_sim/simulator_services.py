"""The simulator node's service boundary: requests turned into core calls, refusals into answers.

:func:`answer` runs a request's action and fills the response (a ``ValueError``, ``TypeError`` or
``KeyError`` is a refusal with its reason; anything else an internal error, never a crash of the
executor); :func:`apply_current` carries out a ``SetCurrent`` request on the core.

The standard control surface (``simulation_interfaces``, :mod:`seapup_sim.ros.simulation_control`) in
plain numbers: the vehicle is one entity, :data:`ENTITY`; its state is given and set in the world frame
``odom`` (REP-103 ENU, the frame of the simulator's ``/odometry``), the twist and acceleration observed in
that frame (:func:`entity_state_enu`, :func:`state_from_enu`); :func:`set_plant_state` validates such a
state against ``environment/limits.yaml`` and puts it in the plant; :func:`reset_scope` reads a
``ResetSimulation`` scope.
"""
from __future__ import annotations

import math
import re

import numpy as np

from seapup_common import frames
from seapup_sim.current import CurrentParams

__all__ = ["answer", "apply_current", "current_said", "ENTITY", "InvalidPose", "entity_state_enu",
           "state_from_enu", "set_plant_state", "reset_scope", "matching_entities", "SCOPE_TIME", "SCOPE_STATE",
           "SCOPE_ALL"]

#: The simulation's one entity: the vehicle.
ENTITY = "seapup"
#: ``simulation_interfaces/srv/ResetSimulation`` scopes (bit field; 0: all).
SCOPE_TIME, SCOPE_STATE, SCOPE_ALL = 1, 2, 255
#: |q| may differ from 1 by this much (a quaternion typed with a few digits); it is normalised.
QUATERNION_TOLERANCE = 1e-3


class InvalidPose(ValueError):
    """A pose that is not one: a non-finite number, a quaternion that is not a unit one, a position or
    attitude outside ``environment/limits.yaml``."""


def answer(response, action, success_text, logger):
    """Run ``action()``; fill ``response.success``/``message`` (``success_text()`` on success) and log it."""
    try:
        action()
    except (ValueError, TypeError, KeyError) as exc:
        response.success, response.message = False, str(exc)[:500]
        logger.warn(f"service refused: {response.message}")
    except Exception as exc:  # noqa: BLE001 - the boundary: nothing may escape into the executor
        response.success = False
        response.message = f"internal error, request refused: {type(exc).__name__}: {str(exc)[:300]}"
        logger.error(response.message)
    else:
        response.success, response.message = True, success_text()
        logger.info(response.message)
    return response


def apply_current(simulator, request) -> None:
    """A ``SetCurrent`` request on ``simulator`` (a :class:`~seapup_sim.simulator_core.SimulatorCore`): the
    current now, or scheduled at ``request.at`` [s] when that is later; ``break_time`` 0 keeps the present T_c."""
    if not (math.isfinite(request.at) and request.at >= 0.0):
        raise ValueError(f"at must be a finite time >= 0 s, got {request.at!r}")
    params = None
    if request.enabled:
        tc = request.break_time or simulator.current_params().break_time
        params = CurrentParams(request.mean_speed, request.speed_std, request.mean_direction,
                               request.direction_std, tc)
    if request.at > simulator.t:
        simulator.schedule_current(params, request.at)
    else:
        simulator.set_current(params)


def current_said(simulator, request) -> str:
    """What a ``SetCurrent`` request did, for its response."""
    when = f" at t = {request.at:g} s" if request.at > simulator.t else ""
    return "current " + ("set" if request.enabled else "off") + when


def _rotation_of_quaternion(q) -> np.ndarray:
    """R (v_parent = R v_child) of a unit quaternion (x, y, z, w)."""
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def entity_state_enu(state, accel_body) -> dict:
    """The vehicle's truth in ``odom`` (ENU): pose, and twist and acceleration observed in that frame.

    v_enu = M R (u, v, w), omega_enu = M R (p, q, r), a_enu = M R (d(u, v, w)/dt + omega x (u, v, w)),
    with R body(FRD) -> NED of eq. 2.1 and M NED -> ENU. The angular acceleration is not computed (zero).

    Parameters
    ----------
    state : array_like, shape (12,)
        x, y, z (NED), phi, theta, psi, u, v, w, p, q, r (FRD) -- the thesis's order.
    accel_body : array_like, shape (3,)
        d(u, v, w)/dt over the last physics step [m/s^2].

    Returns
    -------
    dict
        ``position`` (3,), ``orientation`` (x, y, z, w) of ``base_link`` (FLU) in ``odom``, ``linear``,
        ``angular``, ``linear_acceleration`` (3,) each, ENU.
    """
    x = np.asarray(state, float)
    r_ned = frames.NED_TO_ENU @ frames.rotation_body_to_ned(*x[3:6])
    nu, omega = x[6:9], x[9:12]
    return {"position": frames.ned_to_enu(x[:3]),
            "orientation": frames.orientation_ned_frd_to_enu_flu(frames.euler_to_quaternion(*x[3:6])),
            "linear": r_ned @ nu, "angular": r_ned @ omega,
            "linear_acceleration": r_ned @ (np.asarray(accel_body, float) + np.cross(omega, nu))}


def state_from_enu(position, orientation, linear, angular) -> np.ndarray:
    """The 12-state of a pose and twist in ``odom`` (ENU, the twist observed in it): the inverse of
    :func:`entity_state_enu` (R_ned_frd = M R_enu_flu F with F = FRD -> FLU).

    Raises
    ------
    InvalidPose
        A non-finite position or orientation, or a quaternion whose norm is not 1 (within
        :data:`QUATERNION_TOLERANCE`).
    ValueError
        A non-finite twist.
    """
    p, q = np.asarray(position, float), np.asarray(orientation, float)
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(q))):
        raise InvalidPose(f"the pose must be finite, got position {p.tolist()} orientation {q.tolist()}")
    if abs(np.linalg.norm(q) - 1.0) > QUATERNION_TOLERANCE:
        raise InvalidPose(f"the orientation is not a unit quaternion: |q| = {np.linalg.norm(q):.6g}, q = {q.tolist()}")
    v, w = np.asarray(linear, float), np.asarray(angular, float)
    if not (np.all(np.isfinite(v)) and np.all(np.isfinite(w))):
        raise ValueError(f"the twist must be finite, got linear {v.tolist()} angular {w.tolist()}")
    r = frames.NED_TO_ENU @ _rotation_of_quaternion(q / np.linalg.norm(q)) @ frames.FRD_TO_FLU   # R_ned_frd
    phi, theta, psi = math.atan2(r[2, 1], r[2, 2]), -math.asin(max(-1.0, min(1.0, r[2, 0]))), math.atan2(r[1, 0], r[0, 0])
    to_body = r.T @ frames.NED_TO_ENU      # ENU world -> FRD body
    return np.concatenate([frames.NED_TO_ENU @ p, [phi, theta, psi], to_body @ v, to_body @ w])


def set_plant_state(simulator, state) -> None:
    """Put the 12-state ``state`` in the plant of ``simulator`` (a
    :class:`~seapup_sim.simulator_core.SimulatorCore`) now, time and everything else unchanged.

    Raises
    ------
    InvalidPose
        The position or attitude is outside ``environment/limits.yaml``.
    ValueError
        The velocities are; nothing changes either way.
    """
    x = np.asarray(state, float)
    try:
        checked = simulator.limits.check_state(x)
    except ValueError as exc:
        text = str(exc)
        pose = any(text.startswith(f"state {name} ") for name in ("x", "y", "z", "phi", "theta", "psi"))
        raise (InvalidPose if pose else ValueError)(text) from None
    simulator.simulation.plant.state = checked.copy()


def reset_scope(scope: int) -> tuple[bool, bool]:
    """(time, state): what a ``ResetSimulation`` of ``scope`` resets. ``SCOPE_DEFAULT`` (0) and
    :data:`SCOPE_ALL` reset both (nothing is ever spawned, so ``SCOPE_SPAWNED`` has nothing to do there).

    Raises
    ------
    ValueError
        A scope other than 0, TIME, STATE, TIME | STATE or ALL (e.g. SPAWNED alone: not supported).

    Examples
    --------
    >>> reset_scope(0), reset_scope(SCOPE_TIME), reset_scope(SCOPE_STATE)
    ((True, True), (True, False), (False, True))
    """
    if scope in (0, SCOPE_ALL, SCOPE_TIME | SCOPE_STATE):
        return True, True
    if scope in (SCOPE_TIME, SCOPE_STATE):
        return scope == SCOPE_TIME, scope == SCOPE_STATE
    raise ValueError(f"reset scope {scope} is not supported (0, TIME 1, STATE 2, TIME|STATE 3 or ALL 255)")


def matching_entities(pattern: str) -> list[str]:
    """The entities whose name matches ``pattern`` (a regular expression searched in the name; '': all).

    Raises
    ------
    ValueError
        ``pattern`` is not a regular expression.
    """
    try:
        regex = re.compile(pattern)
    except re.error as exc:
        raise ValueError(f"filter {pattern[:80]!r} is not a regular expression: {exc}") from None
    return [ENTITY] if regex.search(ENTITY) else []
