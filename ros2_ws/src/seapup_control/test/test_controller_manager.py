"""The controller manager's switch planning, forwarding and failover detection."""
import pytest

from seapup_control.controller_manager import BEST_EFFORT, ControllerManagerCore, SwitchError


def manager(active="a"):
    core = ControllerManagerCore(["a", "b"], fallback="a")
    if active:
        core.set_state(active, "active")
    return core


def test_two_active_controllers_are_refused():
    with pytest.raises(SwitchError, match="deactivate it in the same request"):
        manager().plan_switch(["b"], [])
    plan = manager().plan_switch(["b"], ["a"])
    assert plan.deactivate == ["a"] and plan.activate == ["b"]


def test_strict_refuses_and_best_effort_skips_what_cannot_be_done():
    with pytest.raises(SwitchError, match="unknown controller 'x'"):
        manager().plan_switch(["x"], ["a"])
    plan = manager().plan_switch(["x", "b"], ["a"], BEST_EFFORT)
    assert plan.activate == ["b"] and "unknown controller 'x'" in plan.skipped[0]
    with pytest.raises(SwitchError, match="already active"):
        manager().plan_switch(["a"], [])


def test_only_the_active_controller_is_forwarded_once_per_sample():
    core = manager()
    assert core.accept_command("a", 100)
    assert not core.accept_command("a", 100)   # the same sample twice
    assert not core.accept_command("b", 300)   # not active
    core.handover("b")
    assert not core.accept_command("b", 100)   # a sample already answered
    assert core.accept_command("b", 300)
    assert core.controllers["b"].commands_dropped == 2 and core.controllers["a"].commands_dropped == 1


def test_overdue_only_when_the_active_controller_misses_its_deadline():
    core = manager()
    core.accept_command("a", 100)
    assert not core.overdue(100, 10.0, 0.5)  # answered
    assert not core.overdue(300, 0.2, 0.5)   # still within the deadline
    assert core.overdue(300, 0.6, 0.5)
    assert not manager(active=None).overdue(300, 10.0, 0.5)  # nobody is supposed to answer
