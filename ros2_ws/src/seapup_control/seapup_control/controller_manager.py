"""The controller manager's logic: which velocity controller commands the thrusters, and when that changes.

Modelled on ros2_control's controller manager: a controller's life cycle
(configure, activate, deactivate) is separate from its control law, and
switching is the manager's job. Every velocity controller publishes its
blade pitches on a topic of its own; the manager forwards those of the one
*active* controller to the vehicle, so exactly one controller commands the
thrusters at any time, whatever the others do. Per control sample t_k at
most one command is forwarded, stamps strictly increasing, so a switch takes
effect on a tick boundary: the samples up to the switch come from the
outgoing controller, the ones after from the incoming.

This module is pure: :class:`ControllerManagerCore` plans switches
(:meth:`~ControllerManagerCore.plan_switch`, refusing with a reason what
would leave two controllers active or names an unknown one), decides what
to forward (:meth:`~ControllerManagerCore.accept_command`) and detects a
controller that stopped producing commands
(:meth:`~ControllerManagerCore.overdue`) so the node can fail over to the
fallback controller. The node (``controller_manager_node``) runs the
lifecycle transitions and the topics.
"""
from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["SwitchError", "ManagedController", "SwitchPlan", "ControllerManagerCore", "BEST_EFFORT", "STRICT"]

BEST_EFFORT, STRICT = 1, 2


class SwitchError(ValueError):
    """A switch request that cannot be carried out (the message says why)."""


@dataclass
class ManagedController:
    """One velocity controller: its name, lifecycle state (label) and counters."""

    name: str
    type: str = ""
    state: str = "unknown"
    commands_forwarded: int = 0
    commands_dropped: int = 0
    last_forwarded_ns: int | None = None


@dataclass
class SwitchPlan:
    """What a switch will do: deactivate these, then activate these (in order)."""

    deactivate: list[str] = field(default_factory=list)
    activate: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)  # best effort: what was left out, and why

    @property
    def empty(self) -> bool:
        return not (self.deactivate or self.activate)


class ControllerManagerCore:
    """Switch planning, command forwarding and failover detection (module docstring).

    Parameters
    ----------
    names : list of str
        The managed controllers (node names).
    fallback : str
        The controller to fail over to (one of ``names``).
    types : dict, optional
        name -> type string (for listing).
    """

    def __init__(self, names, fallback: str, types: dict | None = None):
        names = list(names)
        if not names or len(set(names)) != len(names):
            raise ValueError(f"controller manager: controllers must be distinct and at least one, got {names}")
        if fallback not in names:
            raise ValueError(f"controller manager: fallback {fallback!r} is not one of {names}")
        types = types or {}
        self.controllers = {n: ManagedController(n, types.get(n, "")) for n in names}
        self.fallback = fallback
        self.active: str | None = None
        self.last_forwarded_ns: int | None = None
        self.failovers: list[dict] = []

    # -- switching ----------------------------------------------------------------------------
    def plan_switch(self, activate, deactivate, strictness: int = STRICT) -> SwitchPlan:
        """Check a request against the present states; the plan, or :class:`SwitchError` with the reason.

        Strict refuses the whole request if any name is unknown, activates a
        controller already active or deactivates one that is not; best
        effort skips those parts. Either way the result must leave at most
        one controller active.
        """
        if strictness not in (0, BEST_EFFORT, STRICT):
            raise SwitchError(f"strictness {strictness} unknown: {BEST_EFFORT} (best effort) or {STRICT} (strict)")
        strict = strictness != BEST_EFFORT
        activate, deactivate = list(dict.fromkeys(activate)), list(dict.fromkeys(deactivate))
        plan = SwitchPlan()
        both = set(activate) & set(deactivate)
        if both:
            raise SwitchError(f"{sorted(both)} both activated and deactivated")
        for names, bucket, wrong in ((deactivate, plan.deactivate, lambda n: None if self.active == n else "is not active"),
                                     (activate, plan.activate, lambda n: "is already active" if self.active == n else None)):
            for name in names:
                problem = self._unknown(name) or (f"{name} {wrong(name)}" if wrong(name) else None)
                if problem and strict:
                    raise SwitchError(problem)
                (plan.skipped if problem else bucket).append(problem or name)
        if len(plan.activate) > 1:
            raise SwitchError(f"exactly one velocity controller may be active: asked to activate {plan.activate}")
        remaining = None if (self.active is None or self.active in plan.deactivate) else self.active
        if plan.activate and remaining is not None:
            raise SwitchError(f"{remaining} is active: deactivate it in the same request to activate "
                              f"{plan.activate[0]} (exactly one velocity controller commands the thrusters)")
        return plan

    def _unknown(self, name: str) -> str | None:
        if name in self.controllers:
            return None
        return f"unknown controller {name!r} (managed: {', '.join(self.controllers)})"

    def set_state(self, name: str, state: str) -> None:
        """Record a controller's lifecycle state (after a transition or a query)."""
        self.controllers[name].state = state
        if state == "active":
            self.active = name
        elif self.active == name:
            self.active = None

    def handover(self, name: str | None) -> None:
        """From now on forward only ``name``'s commands (None: nobody's), whatever the recorded states.

        A switch hands over *before* the incoming controller's activation
        returns, because its answer to the waiting sample may arrive first.
        """
        if name is not None and name not in self.controllers:
            raise SwitchError(self._unknown(name))
        self.active = name

    # -- forwarding ---------------------------------------------------------------------------
    def accept_command(self, name: str, stamp_ns: int) -> bool:
        """Forward this command of ``name`` for sample ``stamp_ns``? (only the active's, once per sample)."""
        controller = self.controllers.get(name)
        if controller is None:
            return False
        if name != self.active or (self.last_forwarded_ns is not None and stamp_ns <= self.last_forwarded_ns):
            controller.commands_dropped += 1
            return False
        controller.commands_forwarded += 1
        controller.last_forwarded_ns = stamp_ns
        self.last_forwarded_ns = stamp_ns
        return True

    def overdue(self, latest_sample_ns: int | None, waited: float, deadline: float) -> bool:
        """True when the active controller has not answered sample ``latest_sample_ns`` for ``deadline`` s.

        ``waited`` is how long [s] that sample has been waiting (in the
        clock the deadline is in: wall seconds for a lockstep graph, where
        simulated time stands still while it waits; graph time otherwise).
        """
        if self.active is None or latest_sample_ns is None:
            return False
        answered = self.last_forwarded_ns is not None and self.last_forwarded_ns >= latest_sample_ns
        return not answered and waited > deadline

    def record_failover(self, failed: str, sample_ns: int, reason: str) -> None:
        self.failovers.append({"failed": failed, "to": self.fallback, "sample_ns": sample_ns, "reason": reason})
