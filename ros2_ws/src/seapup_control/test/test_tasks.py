"""Tasks: goal checks with reasons, the moving setpoint of goto, arrival, seabed depth."""
import math

import numpy as np
import pytest

from seapup_common.contract import NavigationEstimate, Reading
from seapup_control.tasks import FollowSeabed, Goto, Hover, TaskLimits, TaskRejected

LIMITS = TaskLimits()


def estimate(position=(0.0, 0.0, 30.0), yaw=0.0, t=0.0, std=0.1):
    return NavigationEstimate(t, np.array(position, float), np.eye(3) * std ** 2, np.array([0, 0, yaw]),
                              np.zeros(3))


@pytest.mark.parametrize("kwargs, reason", [
    ({"target": (500, 0, 30)}, "max_distance"),
    ({"target": (5, 0, -1)}, "z -1 m is outside"),
    ({"target": (math.nan, 0, 30)}, "x must be finite"),
    ({"target": (5, 0, 30), "speed": 1.0}, "speed 1 m/s is outside"),
    ({"target": (50, 0, 30), "speed": 0.1, "timeout": 60.0}, "shorter than"),
])
def test_goals_that_cannot_be_met_are_refused_with_the_reason(kwargs, reason):
    target = kwargs.pop("target")
    with pytest.raises(TaskRejected, match=reason):
        Goto(LIMITS, estimate(), target, 0.0, **kwargs)


def test_no_navigation_or_too_uncertain_navigation_is_refused():
    with pytest.raises(TaskRejected, match="no navigation"):
        Hover(LIMITS, None)
    with pytest.raises(TaskRejected, match="too uncertain"):
        Hover(LIMITS, estimate(std=5.0))


def test_goto_setpoint_moves_along_the_line_at_its_speed_and_arrival_needs_settling():
    task = Goto(LIMITS, estimate(), (6.0, 8.0, 30.0), 1.0, speed=0.2)
    step = task.step(0.0, estimate())
    np.testing.assert_allclose(step.setpoint.position, [0, 0, 30])
    step = task.step(10.0, estimate((1.08, 1.44, 30.0), t=10.0))   # the vehicle 1.8 m along, following
    np.testing.assert_allclose(step.setpoint.position, [1.2, 1.6, 30])  # 2 m along the 3-4-5 line
    stuck = Goto(LIMITS, estimate(), (6.0, 8.0, 30.0), 1.0, speed=0.2)
    stuck.step(0.0, estimate())
    step = stuck.step(10.0, estimate(t=10.0))                      # the vehicle has not moved
    np.testing.assert_allclose(step.setpoint.position, [0.3, 0.4, 30])  # waits max_lead (0.5 m) ahead
    there = estimate((6.0, 8.0, 30.0), 1.0)
    assert not task.step(50.0, there).done                 # inside, not yet settled
    done = task.step(50.0 + LIMITS.settle_time, there)
    assert done.done and done.success and done.result["distance"] == 0.0


def test_seabed_depth_is_depth_plus_altitude_along_the_vertical():
    pitched = NavigationEstimate(0.0, np.array([0, 0, 30.0]), np.eye(3) * 0.01, np.array([0, 0.2, 0]), np.zeros(3))
    task = FollowSeabed(LIMITS, pitched, Reading(10.0, 0.0, 0.0), height=5.0, yaw=0.0, speed=0.2, duration=10)
    assert math.isclose(task.seabed, 30.0 + 10.0 * math.cos(0.2))
    with pytest.raises(TaskRejected, match="sees no seabed"):
        FollowSeabed(LIMITS, pitched, Reading.invalid(), height=5.0, yaw=0.0, speed=0.2, duration=10)


def test_a_moving_setpoint_waits_for_a_vehicle_that_falls_behind():
    from seapup_control.tasks import advance_along
    # free running: speed x dt
    assert advance_along(2.0, 0.2, 0.3, vehicle_along=1.9, lead=0.5, end=10.0) == pytest.approx(2.06)
    # the vehicle 0.5 m behind already: the setpoint does not run further ahead
    assert advance_along(2.0, 0.2, 0.3, vehicle_along=1.5, lead=0.5, end=10.0) == pytest.approx(2.0)
    # never back (a fix pulling the estimate back does not pull the setpoint), never past the end
    assert advance_along(2.0, 0.2, 0.3, vehicle_along=0.0, lead=0.5, end=10.0) == 2.0
    assert advance_along(9.99, 0.2, 0.3, vehicle_along=9.9, lead=0.5, end=10.0) == 10.0


def test_a_followed_hover_sets_the_vehicle_s_own_pose_and_measures_its_excursion():
    """Hover(follow=True), the task controller's part of a manual flight: each setpoint is the estimate's pose at
    that sample (so the position controller's feed-forward is the vehicle's own velocity), its errors the distance
    from where it started; it ends only by its duration (0: when cancelled)."""
    task = Hover(LIMITS, estimate((1.0, 2.0, 30.0), yaw=0.3), follow=True, duration=0.0)
    for k in range(50):
        here = (1.0 + 0.04 * k, 2.0 - 0.02 * k, 30.0 + 0.01 * k)
        step = task.step(0.2 * k, estimate(here, yaw=0.3 + 0.01 * k, t=0.2 * k))
        np.testing.assert_array_equal(step.setpoint.position, here)
        assert step.setpoint.yaw == pytest.approx(0.3 + 0.01 * k) and step.setpoint.t == 0.2 * k
        assert step.feedback["horizontal_error"] == pytest.approx(math.hypot(0.04 * k, 0.02 * k))
        assert not step.done
    held = Hover(LIMITS, estimate((1.0, 2.0, 30.0)), duration=0.0)   # not followed: the start is held
    assert held.step(1.0, estimate((3.0, 2.0, 30.0), t=1.0)).setpoint.position.tolist() == [1.0, 2.0, 30.0]


@pytest.mark.unit
def test_the_tasks_float_norms_and_dots_are_numpy_s_bit_for_bit():
    """The tasks' 3-vector arithmetic in plain floats (norm3, the along-track dot product) against np.linalg.norm
    and numpy's dot over random vectors from millimetres to kilometres: the same bits, so a goto's distance,
    cross-track error and arrival are those the array code computed (a machine whose BLAS sums otherwise is told
    here)."""
    from seapup_control.tasks import norm3
    rng = np.random.default_rng(12)
    for _ in range(20000):
        v, d = rng.normal(size=3) * rng.choice([1e-3, 1.0, 30.0, 1e4]), rng.normal(size=3)
        (x, y, z), (a, b, c) = v.tolist(), d.tolist()
        assert norm3(x, y, z) == float(np.linalg.norm(v))
        assert x * a + y * b + z * c == float(v @ d)
    assert norm3(3.0, 4.0, 12.0) == 13.0
