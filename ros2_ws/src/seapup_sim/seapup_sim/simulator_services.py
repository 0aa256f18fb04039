"""The simulator node's service boundary: requests turned into core calls, refusals into answers.

:func:`answer` runs a request's action and fills the response (a ``ValueError``, ``TypeError`` or
``KeyError`` is a refusal with its reason; anything else an internal error, never a crash of the
executor); :func:`apply_current` carries out a ``SetCurrent`` request on the core.
"""
from __future__ import annotations

import math

from seapup_sim.current import CurrentParams

__all__ = ["answer", "apply_current", "current_said"]


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
