"""Manual flight (seapup_control.manual): the pilot's Twist as the velocity reference -- bounded, slewed,
zeroed when the pilot goes silent, taken over and handed back without a bump.

Independent truth: REP-103's base_link (forward-left-up) against the thesis's FRD body axes; the ramp of a
rate limit (the reference after t seconds of a held demand is min(demand, a t)); the self-tested law flying a
simulated Seapup to the pilot's demand (the plant's truth)."""
import math

import numpy as np
import pytest

from seapup_common.contract import ContractError
from seapup_common.controllers import ControllerSpec, available_controllers, create_controller
from seapup_control.manual import ManualPilot, twist_to_body_velocity

pytestmark = pytest.mark.unit


def test_a_ros_twist_is_the_thesis_s_body_velocity():
    # forward, left, up and counter-clockwise in base_link are +u, -v, -w and -r in base_link_frd
    np.testing.assert_array_equal(twist_to_body_velocity((0.2, 0.1, 0.05), (0.0, 0.0, 0.3)), [0.2, -0.1, -0.05, -0.3])
    for bad in (((math.nan, 0, 0), (0, 0, 0)), ((0, 0), (0, 0, 0)), ((0, 0, "x"), (0, 0, 0)), ((0, 0, 0), (0, 0, math.inf))):
        with pytest.raises(ContractError):
            twist_to_body_velocity(*bad)


def test_the_demand_is_bounded_slewed_and_fades_when_the_pilot_is_silent():
    pilot = ManualPilot(max_speed=(0.3, 0.15, 0.15), max_yaw_rate=0.26, acceleration=(0.05, 0.05, 0.05, 0.1),
                        silence_timeout=1.0)
    pilot.reset(0.0, [0.0, 0.0, 0.0, 0.0])
    seen = []
    for k in range(1, 101):   # 20 s at 5 Hz; the pilot holds full stick forward and right for 8 s, then lets go
        t = 0.2 * k
        if t <= 8.0:
            pilot.pilot(t, [1.0, 1.0, 0.0, 0.0])   # beyond the limits: bounded to 0.3 and 0.15
        seen.append(pilot.reference(t).velocity.copy())
    seen = np.array(seen)
    t = 0.2 * np.arange(1, 101)
    # while held: a ramp at the acceleration limit up to the speed limit
    np.testing.assert_allclose(seen[t <= 8.0, 0], np.minimum(0.05 * t[t <= 8.0], 0.3), atol=1e-12)
    np.testing.assert_allclose(seen[t <= 8.0, 1], np.minimum(0.05 * t[t <= 8.0], 0.15), atol=1e-12)
    # silent from 9 s on (1 s after the last demand): ramps down to rest at the same rate
    assert seen[t == 9.0, 0][0] == pytest.approx(0.3) and seen[-1, 0] == 0.0 and seen[-1, 1] == 0.0
    falling = seen[(t > 9.0) & (t < 14.0), 0]
    assert np.allclose(np.diff(falling), -0.05 * 0.2)


def test_a_bad_demand_changes_nothing_and_is_counted():
    pilot = ManualPilot()
    pilot.reset(0.0, [0.1, 0.0, 0.0, 0.0])
    pilot.pilot(0.0, [0.2, 0.0, 0.0, 0.0])
    with pytest.raises(ContractError):
        pilot.pilot(0.2, [math.nan, 0.0, 0.0, 0.0])
    assert pilot.refused == 1 and pilot.demand.tolist() == [0.2, 0.0, 0.0, 0.0] and pilot.demand_t == 0.0


def test_the_manual_law_flies_the_seapup_to_the_pilot_s_demand_and_takes_over_without_a_bump():
    """Registered as ``manual``: the self-test's fixed gains fly the pilot's reference (not the task's). Taken
    over from a vehicle moving at 0.2 m/s, the first reference is that speed (no bump); the vehicle then holds
    the pilot's 0.25 m/s surge and 0.1 m/s sway, and comes to rest when the pilot goes silent."""
    from seapup_runs.runner import design
    from seapup_runs.spec import RunSpec
    from seapup_sim.simulation import Simulation
    from seapup_common.contract import Command, Reference
    assert "manual" in available_controllers()
    spec = design(RunSpec.from_dict({"name": "m", "controller": {"type": "mfol"}, "duration": 1.0,
                                     "design": {"vehicle": "baseline", "operating_points": [0.0]}}))
    law = create_controller(ControllerSpec("manual", {}, document=spec.controller.document), 0.2)
    sim = Simulation.from_config("baseline", {"sensors": "ideal"}, control_period=0.2)
    state = sim.plant.state.copy()
    state[6] = 0.2   # moving ahead when the pilot takes over
    sim.plant.state = state
    law.reset(Command(sim.plant.applied, 0.0))
    first = None
    for k in range(400):
        t = 0.2 * k
        sample = sim.sample()
        if t <= 50.0:
            law.pilot(t, (0.25, -0.1, 0.0), (0.0, 0.0, 0.0))   # forward and right (y left: -0.1)
        command = law.update(t, sample.measurement, Reference([0.0, 0.0, 0.0, 0.0]))   # the task's: not flown
        first = law.manual.output.copy() if first is None else first
        sim.advance(command.blade_pitch)
        if k == 240:
            held = sample.state[6:9].copy()
    assert first[0] == pytest.approx(0.2, abs=1e-9)   # bumpless: from the measured speed
    np.testing.assert_allclose(held[:2], [0.25, 0.1], atol=0.01)
    assert np.abs(sim.sample().state[6:9]).max() < 0.02   # silent since 50 s: at rest


def test_a_stick_held_when_the_pilot_takes_over_counts_and_a_silent_one_does_not():
    """The teleop tool's stick sent at the sample the manual controller comes in is flown from the next sample
    (the take-over starts from the measured velocity, then ramps toward it); one older than the silence
    timeout is not."""
    pilot = ManualPilot(acceleration=(0.05, 0.05, 0.05, 0.1), silence_timeout=1.0)
    pilot.pilot(10.0, [0.2, 0.0, 0.0, 0.0])
    pilot.reset(10.0, [0.05, 0.0, 0.0, 0.0])
    assert pilot.reference(10.0).velocity.tolist() == [0.05, 0.0, 0.0, 0.0]
    assert pilot.reference(10.2).velocity[0] == pytest.approx(0.05 + 0.05 * 0.2)
    stale = ManualPilot(silence_timeout=1.0)
    stale.pilot(0.0, [0.2, 0.0, 0.0, 0.0])
    stale.reset(5.0, [0.0, 0.0, 0.0, 0.0])
    assert stale.reference(5.2).velocity.tolist() == [0.0, 0.0, 0.0, 0.0]
