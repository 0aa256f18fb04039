"""The global position controller (sec. 4.2): frames, wrap-around, limits, feed-forward."""
import math

import numpy as np
import pytest

from seapup_common.frames import rotation_body_to_ned, wrap_angle
from seapup_control.position_control import PoseReference, PositionController, PositionControllerParams

T = 0.2
FAST = PositionControllerParams(acceleration_limits=(100, 100, 100, 100))


def settled(controller, position, attitude, n=50):
    for _ in range(n):
        out = controller.update(position, attitude)
    return out.velocity


def test_a_north_error_is_a_sway_demand_when_heading_east():
    c = PositionController(FAST, T)
    c.set_reference(PoseReference([1.0, 0.0, 30.0], math.pi / 2))
    v = settled(c, [0.0, 0.0, 30.0], [0.0, 0.0, math.pi / 2])
    # body y points south when heading east: the north error is to port (negative sway)
    np.testing.assert_allclose(v[:3], [0.0, -0.15, 0.0], atol=1e-12)  # 0.2 x -1 clipped to the 0.15 limit


def test_yaw_takes_the_short_way_round():
    c = PositionController(FAST, T)
    c.set_reference(PoseReference([0, 0, 30], math.radians(10)))
    r = settled(c, [0, 0, 30], [0, 0, math.radians(350)])[3]
    assert r > 0 and math.isclose(r, 0.5 * math.radians(20), rel_tol=1e-9)


def test_speed_limits_scale_the_horizontal_pair_and_keep_its_direction_heave_on_its_own():
    c = PositionController(FAST, T)
    c.set_reference(PoseReference([10.0, 5.0, 30.0], 0.0))
    u, v, w, _ = settled(c, [0, 0, 30], [0, 0, 0])
    assert math.isclose(u, 0.3) and abs(v) <= 0.15 + 1e-12
    assert math.isclose(v / u, 0.5)  # same direction as the 10:5 error
    # a surge demand at its limit does not slow a climb: w gets its own K_p e_z (0.3 x -0.2 m)
    c = PositionController(FAST, T)
    c.set_reference(PoseReference([10.0, 0.0, 29.8], 0.0))
    u, v, w, _ = settled(c, [0, 0, 30], [0, 0, 0])
    assert math.isclose(u, 0.3) and math.isclose(w, FAST.gains[2] * -0.2)
    c.set_reference(PoseReference([10.0, 0.0, 20.0], 0.0))  # and a large depth error: w at its own limit
    assert math.isclose(settled(c, [0, 0, 30], [0, 0, 0])[2], -0.15)


def test_reference_changes_are_slew_limited():
    c = PositionController(PositionControllerParams(), T)
    c.set_reference(PoseReference([10.0, 0.0, 30.0], 0.0))
    first = c.update([0, 0, 30], [0, 0, 0]).velocity
    assert math.isclose(first[0], 0.05 * T) and c.limited[0]


def test_a_moving_setpoint_is_followed_without_lag_and_a_step_gives_no_feedforward():
    c = PositionController(FAST, T)
    for k in range(3):
        c.set_reference(PoseReference([0.2 * k * T, 0.0, 30.0], 0.0, k * T))
    u = settled(c, [0.2 * 2 * T, 0.0, 30.0], [0, 0, 0])[0]
    assert math.isclose(u, 0.2, rel_tol=1e-9)  # on the setpoint, moving with it
    c.set_reference(PoseReference([50.0, 0.0, 30.0], 0.0, 3 * T))  # a jump: no feed-forward
    np.testing.assert_array_equal(c._feedforward, 0.0)


def test_the_law_is_the_module_docstrings_matrix_formula():
    """The controller's plain-float arithmetic against the docstring's formula written with numpy matrices
    (e_body = R^T e_ned, v_ff = R^T dp/dt, the horizontal pair scaled, heave and yaw rate clipped, each reference
    slewed by at most its limit), at random poses, setpoints and setpoint rates."""
    rng = np.random.default_rng(3)
    params = PositionControllerParams(gains=(0.3, 0.25, 0.4), yaw_gain=0.7, speed_limits=(0.4, 0.2, 0.15),
                                      max_yaw_rate=0.3, acceleration_limits=(0.2, 0.1, 0.15, 0.2))
    for _ in range(200):
        c = PositionController(params, T)
        last = rng.uniform(-0.2, 0.2, 4)
        c.reset(last)
        a, b = rng.uniform(-5, 5, 3), rng.uniform(-0.04, 0.04, 3)
        yaw0, dyaw = rng.uniform(-math.pi, math.pi), rng.uniform(-0.05, 0.05)
        c.set_reference(PoseReference(a, yaw0, 1.0))
        c.set_reference(PoseReference(a + b, wrap_angle(yaw0 + dyaw), 1.0 + T))
        position, attitude = rng.uniform(-5, 5, 3), rng.uniform([-0.5, -0.5, -math.pi], [0.5, 0.5, math.pi])
        R = rotation_body_to_ned(*attitude)
        rate = np.array([*(b / T), wrap_angle(dyaw) / T])
        trajectory = np.hypot(*rate[:2]) <= 0.4 and abs(rate[2]) <= 0.15 and abs(rate[3]) <= 0.3
        feedforward = rate if trajectory else np.zeros(4)   # a jump faster than the limits is a step
        v = np.array(params.gains) * (R.T @ (a + b - position)) + R.T @ feedforward[:3]
        v[:2] /= max(1.0, np.max(np.abs(v[:2]) / params.speed_limits[:2]))
        v[2] = np.clip(v[2], -0.15, 0.15)
        r = np.clip(0.7 * wrap_angle(wrap_angle(yaw0 + dyaw) - attitude[2]) + feedforward[3], -0.3, 0.3)
        step = np.array(params.acceleration_limits) * T
        expected = last + np.clip(np.array([*v, r]) - last, -step, step)
        np.testing.assert_allclose(c.update(position, attitude).velocity, expected, rtol=0, atol=1e-13)


@pytest.mark.unit
def test_the_compiled_sample_is_the_python_one_bit_for_bit():
    """PositionController's compiled sample (seapup_control.compiled.position_sample, the default where numba is
    installed) against the plain-float reference (compiled=False) along a random flight of setpoints: steps,
    trajectories (feed-forward), yaw across +-pi, the horizontal pair scaled, heave and yaw rate clipped, the slew
    limit active, no setpoint at first -- every reference and limited flag equal, zeros' signs included."""
    rng = np.random.default_rng(21)
    params = PositionControllerParams(gains=(0.2, 0.25, 0.3), yaw_gain=0.6, speed_limits=(0.3, 0.15, 0.15),
                                      max_yaw_rate=0.26, acceleration_limits=(0.05, 0.04, 0.05, 0.1))
    laws = {kind: PositionController(params, 0.2, compiled=kind) for kind in (True, False)}
    assert laws[True].kernel is not None and laws[False].kernel is None
    setpoint, limited = np.zeros(3), 0
    for k in range(3000):
        position = setpoint + rng.normal(size=3) * rng.choice([0.01, 1.0, 20.0])
        attitude = np.array([rng.normal() * 0.1, rng.normal() * 0.1, rng.uniform(-math.pi, math.pi)])
        if k == 5 or (k > 5 and rng.random() < 0.3):
            setpoint = setpoint + (rng.normal(size=3) * 0.02 if rng.random() < 0.6 else rng.normal(size=3) * 5)
            reference = PoseReference(setpoint, float(rng.uniform(-4, 4)), 0.2 * k)
            for law in laws.values():
                law.set_reference(reference)
        if k == 1500:
            for law in laws.values():
                law.reset([0.1, -0.0, 0.0, -0.2])
        got, expected = (laws[kind].update(position, attitude).velocity for kind in (True, False))
        assert got.tobytes() == expected.tobytes(), k
        assert np.array_equal(laws[True].limited, laws[False].limited)
        limited += bool(laws[True].limited.any())
    assert limited > 100
