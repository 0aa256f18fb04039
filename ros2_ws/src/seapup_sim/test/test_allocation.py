"""Thrust allocation (seapup_sim.allocation) against analytic cases and numpy's own pseudo-inverse."""
import math

import numpy as np
import pytest

from seapup_sim.allocation import AllocationError, ThrustAllocator


def parallel(n, low=-1.0, high=1.0, weights=None):
    """n thrusters all pushing surge: one output, B = [1 ... 1]."""
    return ThrustAllocator(np.ones((1, n)), [low] * n, [high] * n, weights)


def vectored_horizontal(a=0.15, b=0.11):
    """Four horizontal thrusters at +-45 deg at (+-a, +-b), a BlueROV2's layout: outputs X, Y, N."""
    angles = np.radians([45.0, -45.0, 135.0, -135.0])      # front-left ... as directions of thrust
    positions = [(a, -b), (a, b), (-a, -b), (-a, b)]
    B = np.array([[math.cos(t) for t in angles], [math.sin(t) for t in angles],
                  [x * math.sin(t) - y * math.cos(t) for t, (x, y) in zip(angles, positions)]])
    return B


def test_as_many_thrusters_as_outputs_is_the_inverse():
    """A square configuration (the Seapup's four inputs for four outputs): the allocation is B^-1 tau."""
    rng = np.random.default_rng(1)
    B = rng.normal(size=(4, 4)) + 3 * np.eye(4)
    allocator = ThrustAllocator(B, [-100.0] * 4, [100.0] * 4)
    for _ in range(20):
        tau = rng.normal(size=4)
        result = allocator.allocate(tau)
        np.testing.assert_allclose(result.efforts, np.linalg.solve(B, tau), rtol=1e-12, atol=1e-12)
        assert result.scale == 1.0 and not result.saturated.any()


def test_more_thrusters_take_the_least_effort_numpy_s_pseudo_inverse_gives():
    """Over-actuated, unit weights, within the limits: f = B^+ tau (numpy's SVD pseudo-inverse), the demand met
    exactly, and f has no part in B's null space (any other solution costs more effort)."""
    B = vectored_horizontal()
    allocator = ThrustAllocator(B, [-50.0] * 4, [50.0] * 4)
    rng = np.random.default_rng(2)
    null = np.linalg.svd(B)[2][-1]
    for _ in range(20):
        tau = rng.normal(size=3) * [20.0, 20.0, 3.0]
        f = allocator.allocate(tau).efforts
        np.testing.assert_allclose(f, np.linalg.pinv(B) @ tau, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(B @ f, tau, atol=1e-10)
        assert abs(f @ null) < 1e-10
        other = f + 0.3 * null   # the same forces, more effort
        assert np.allclose(B @ other, tau) and other @ other > f @ f


def test_weights_share_a_demand_in_inverse_proportion():
    """Three parallel thrusters with costs w_i: f_i = X (1/w_i) / sum(1/w_j) (Lagrange)."""
    w = np.array([1.0, 2.0, 4.0])
    result = parallel(3, weights=w, low=-10.0, high=10.0).allocate([3.5])
    np.testing.assert_allclose(result.efforts, 3.5 * (1 / w) / np.sum(1 / w), rtol=1e-12)
    assert result.scale == 1.0


def test_a_saturated_thruster_is_held_and_the_rest_redistributed_meeting_the_demand():
    """Weights (1, 1, 4), limits +-1, X = 2.5: the least-effort split (1.11, 1.11, 0.28) is over the limit; the two
    cheap thrusters are held at 1 and the third gives the remaining 0.5 -- the demand met, not scaled."""
    result = parallel(3, weights=[1.0, 1.0, 4.0]).allocate([2.5])
    np.testing.assert_allclose(result.efforts, [1.0, 1.0, 0.5], atol=1e-12)
    assert result.scale == 1.0 and result.saturated.tolist() == [True, True, False]
    np.testing.assert_allclose(result.achieved, [2.5], atol=1e-12)


def test_a_demand_beyond_the_thrusters_is_scaled_down_along_its_own_direction():
    """Two mains at +-d (surge X = f1 + f2, yaw N = d (f2 - f1)), limits +-1: for (X, N) = (1.0, 0.4) the exact
    efforts are (-0.5, 1.5): the largest feasible fraction is 1 / 1.5, and every output gets it -- where
    clipping the efforts to (-0.5, 1) would give X 0.5, N 0.3: yaw 60 % of the surge instead of 40 %."""
    d = 0.2
    allocator = ThrustAllocator([[1.0, 1.0], [-d, d]], [-1.0, -1.0], [1.0, 1.0])
    tau = np.array([1.0, 0.4])
    result = allocator.allocate(tau)
    assert result.scale == pytest.approx(1 / 1.5, rel=1e-6)
    np.testing.assert_allclose(result.achieved, result.scale * tau, rtol=1e-9)
    np.testing.assert_allclose(result.efforts, np.array([-0.5, 1.5]) / 1.5, rtol=1e-6)
    assert result.saturated.tolist() == [False, True]
    naive = allocator.B @ np.clip(np.linalg.solve(allocator.B, tau), -1, 1)
    np.testing.assert_allclose(naive, [0.5, 0.3], atol=1e-12)                       # clipping turns it


def test_a_weaker_reverse_limits_the_scale_of_a_reverse_demand():
    """Reverse thrust half the forward (low -0.5, high 1), three parallel thrusters: X = 2 is met, X = -2 is
    scaled to -1.5 (alpha 0.75); the capacity along +X is 3, along -X 1.5."""
    allocator = parallel(3, low=-0.5, high=1.0)
    assert allocator.allocate([2.0]).scale == 1.0
    reverse = allocator.allocate([-2.0])
    assert reverse.scale == pytest.approx(0.75, rel=1e-6) and reverse.achieved[0] == pytest.approx(-1.5, rel=1e-6)
    assert reverse.saturated.all()
    assert allocator.capacity([1.0]) == pytest.approx(3.0, rel=1e-6)
    assert allocator.capacity([-1.0]) == pytest.approx(1.5, rel=1e-6)


def test_an_over_actuated_vehicle_at_its_limits_keeps_the_direction_in_every_output():
    """The four vectored thrusters, limits +-1, random demands up to three times what they can give: each
    result within the limits, achieved = alpha tau, alpha = 1 exactly when the programme says it is feasible."""
    B = vectored_horizontal()
    allocator = ThrustAllocator(B, [-1.0] * 4, [1.0] * 4)
    rng = np.random.default_rng(5)
    scaled = met = 0
    for _ in range(40):
        tau = rng.normal(size=3) * [2.0, 2.0, 0.3] * rng.uniform(0.2, 3.0)
        result = allocator.allocate(tau)
        assert np.all(result.efforts <= 1.0 + 1e-9) and np.all(result.efforts >= -1.0 - 1e-9)
        np.testing.assert_allclose(result.achieved, result.scale * tau, rtol=1e-6, atol=1e-9)
        capacity = allocator.capacity(tau)
        assert result.scale == pytest.approx(min(1.0, capacity), rel=1e-6)
        scaled += result.scale < 1.0
        met += result.scale == 1.0
    assert scaled > 5 and met > 5


@pytest.mark.parametrize("args, demand, reason", [
    (([[1.0, 1.0]], [-1, -1], [1, 1]), [math.nan], "finite"),
    (([[1.0, 1.0]], [-1, -1], [1, 1]), [1.0, 2.0], "shape"),
    (([[1.0, 1.0]], [-1, -1], [1, 1]), ["x"], "numbers"),
])
def test_a_bad_demand_is_refused_naming_why(args, demand, reason):
    with pytest.raises(AllocationError, match=reason):
        ThrustAllocator(*args).allocate(demand)


@pytest.mark.parametrize("configuration, low, high, weights, reason", [
    ([[1.0, 1.0], [2.0, 2.0]], [-1, -1], [1, 1], None, "cannot move every output"),   # parallel: no yaw
    ([[1.0, 1.0]], [0.5, -1], [1, 1], None, "include zero"),
    ([[1.0, 1.0]], [-1, -1], [1, 1], [1.0, 0.0], "weights must be > 0"),
    ([[1.0, math.inf]], [-1, -1], [1, 1], None, "finite"),
    ([[1.0], [0.0]], [-1], [1], None, "at least as many thrusters"),
    ([1.0, 1.0], [-1, -1], [1, 1], None, "m x N"),
])
def test_a_bad_configuration_is_refused_naming_why(configuration, low, high, weights, reason):
    with pytest.raises(AllocationError, match=reason):
        ThrustAllocator(configuration, low, high, weights)
