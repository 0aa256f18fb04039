"""The navigation filter against the Kalman filter's own theory and a noise-free vehicle."""
import math

import numpy as np
import pytest
from scipy import linalg

from seapup_common.contract import ContractError, Measurement
from seapup_control.navigation import Navigator, NavigatorParams

T = 0.2


def test_noise_free_dead_reckoning_follows_a_turning_vehicle_exactly():
    nav = Navigator(NavigatorParams(q_walk=1e-6))
    position, psi = np.array([1.0, 2.0, 30.0]), 0.0
    nav.update(Measurement.build(0.0, velocity=(0.3, 0.1, 0.0), attitude=(0, 0, psi), position=position))
    for k in range(1, 200):
        step = np.array([0.3 * math.cos(psi) - 0.1 * math.sin(psi), 0.3 * math.sin(psi) + 0.1 * math.cos(psi), 0])
        position, psi = position + T * step, psi + 0.01
        estimate = nav.update(Measurement.build(k * T, velocity=(0.3, 0.1, 0.0), attitude=(0, 0, psi)))
    np.testing.assert_allclose(estimate.position, position, atol=1e-9)


@pytest.mark.parametrize("compiled", [True, False])
def test_covariance_converges_to_the_discrete_riccati_solution(compiled):
    """Fixes every sample, constant Q and R: P tends to the DARE's a-posteriori covariance (the compiled
    kernels and the NumPy reference)."""
    p = NavigatorParams(q_walk=1e-3, velocity_std=(0.01, 0.01, 0.01), fix_std=0.5, gate_probability=1.0)
    nav = Navigator(p, compiled=compiled)
    for k in range(400):
        nav.update(Measurement.build(k * T, velocity=(0, 0, 0), attitude=(0, 0, 0), position=(0, 0, 30)))
    Q = (T * T * 0.01 ** 2 + p.q_walk * T) * np.eye(3)
    R = 0.25 * np.eye(3)
    prior = linalg.solve_discrete_are(np.eye(3), np.eye(3), Q, R)  # filter form: A^T = I, C^T = I
    posterior = prior - prior @ np.linalg.solve(prior + R, prior)
    np.testing.assert_allclose(nav.P, posterior, rtol=1e-6)


def test_an_outlier_fix_is_rejected_and_counted_never_fused():
    nav = Navigator()
    for k in range(50):
        nav.update(Measurement.build(k * T, velocity=(0, 0, 0), attitude=(0, 0, 0), position=(0, 0, 30),
                                     depth=30.0))
    before = nav.x.copy()
    nav.update(Measurement.build(50 * T, velocity=(0, 0, 0), attitude=(0, 0, 0), position=(40, 0, 30), depth=30.0))
    assert nav.counts["fixes_rejected"] == 1
    np.testing.assert_allclose(nav.x[:2], before[:2], atol=1e-3)


def test_time_going_backwards_is_refused_and_changes_nothing():
    nav = Navigator()
    nav.update(Measurement.build(1.0, velocity=(0, 0, 0), attitude=(0, 0, 0), position=(0, 0, 30)))
    state = nav.x.copy()
    with pytest.raises(ContractError, match="before the last"):
        nav.update(Measurement.build(0.5, velocity=(1, 0, 0), attitude=(0, 0, 0)))
    np.testing.assert_array_equal(nav.x, state)
    assert nav.t == 1.0


def test_no_estimate_before_the_first_fix():
    nav = Navigator()
    assert nav.update(Measurement.build(0.0, velocity=(0, 0, 0), attitude=(0, 0, 0), depth=30.0)) is None


def _hover(nav, k0, k1, position=(0.0, 0.0, 30.0), fix=True, **readings):
    """Samples k0..k1-1 of a vehicle at rest at ``position``; the last estimate."""
    estimate = None
    for k in range(k0, k1):
        fields = dict(velocity=(0, 0, 0), attitude=(0, 0, 0), depth=position[2])
        fields.update(readings)
        if fix:
            fields["position"] = position
        estimate = nav.update(Measurement.build(k * T, **fields))
    return estimate


def test_a_depth_or_log_reading_no_vehicle_can_give_is_refused_not_fused():
    """Hostile run: one 1e12 m depth was fused; one 1e6 m/s log reading put the estimate 1e5 m off."""
    nav = Navigator()
    _hover(nav, 0, 50)
    before = nav.x.copy()
    nav.update(Measurement.build(50 * T, velocity=(0, 0, 0), attitude=(0, 0, 0), depth=1e12))
    assert nav.counts["depths_rejected"] == 1
    nav.update(Measurement.build(51 * T, velocity=(1e6, 0, 0), attitude=(0, 0, 0), depth=30.0))
    nav.update(Measurement.build(52 * T, velocity=(0, 0, 0), attitude=(0, 0, 0), depth=30.0))
    assert nav.counts["velocities_rejected"] == 1
    np.testing.assert_allclose(nav.x, before, atol=0.01)


def test_a_diverged_estimate_reacquires_the_fix_but_sporadic_outliers_do_not_move_it():
    """Fixes that agree with each other but not with the estimate (here: the estimate was started 9 m
    off, as in the demo whose navigation sat 9 m from the truth) re-initialise it after
    ``reacquire_after`` of them; multipath outliers scattered among good fixes never do."""
    nav = Navigator(NavigatorParams(reacquire_after=5))
    _hover(nav, 0, 30, position=(9.0, 0.0, 30.0))       # believes it is at x = 9 m
    estimate = _hover(nav, 30, 34, position=(0.0, 0.0, 30.0))
    assert nav.counts["fixes_rejected"] == 4 and estimate.position[0] > 8.0
    estimate = _hover(nav, 34, 40, position=(0.0, 0.0, 30.0))
    assert nav.counts["reacquisitions"] == 1
    assert abs(estimate.position[0]) < 0.5
    rng = np.random.default_rng(3)
    for k in range(40, 200):  # one outlier in five, each somewhere else 20-40 m away
        wild = k % 5 == 0
        offset = rng.uniform(20, 40) * np.array([math.cos(k), math.sin(k), 0.0]) if wild else np.zeros(3)
        nav.update(Measurement.build(k * T, velocity=(0, 0, 0), attitude=(0, 0, 0), depth=30.0,
                                     position=tuple(np.array([0.0, 0.0, 30.0]) + offset)))
    assert nav.counts["reacquisitions"] == 1 and nav.counts["fixes_rejected"] >= 4 + 30
    assert np.linalg.norm(nav.x[:2]) < 0.5


def test_the_gates_chi_square_quantile_is_scipy_stats_own():
    """The gate's quantile equals scipy.stats.chi2.ppf, bit for bit, over the gate probabilities a user may set
    (the navigator computes it from scipy.special so that its node need not import scipy.stats)."""
    from scipy import stats

    from seapup_control.navigation import chi2_quantile
    for dof in (1, 3):
        for p in (1e-6, 0.05, 0.5, 0.9, 0.95, 0.99, 0.997, 0.999, 0.9999, 1 - 1e-9):
            assert chi2_quantile(p, dof) == float(stats.chi2.ppf(p, dof)), (p, dof)
    assert abs(chi2_quantile(0.95, 3) - 7.814727903251178) < 1e-12   # the textbook table's 7.815


@pytest.mark.parametrize("compiled", [True, False])
def test_a_depth_is_fused_as_the_matrix_kalman_update_would_fuse_it(compiled):
    """The scalar depth update against the textbook matrix form (H = [0 0 1], K = P H^T S^-1, Joseph form),
    on a correlated covariance; a depth the gate refuses changes nothing (compiled kernel and reference)."""
    nav = Navigator(NavigatorParams(gate_probability=0.999), compiled=compiled)
    rng = np.random.default_rng(3)
    A = rng.normal(size=(3, 3))
    outcomes = set()
    for k in range(60):
        nav.x, nav.P = rng.normal(size=3) + [0, 0, 30], A @ A.T + 0.1 * np.eye(3)
        x0, P0, r = nav.x.copy(), nav.P.copy(), 0.01 * rng.uniform(0.5, 2.0)
        y = 30.0 + rng.normal() * (1.0 if k % 2 else 30.0)   # every other depth far off: refused
        H, R = np.array([[0.0, 0.0, 1.0]]), np.array([[r]])
        S = H @ P0 @ H.T + R
        innovation = np.array([y]) - H @ x0
        fused = nav._fuse_component(2, y, r, nav.chi2_gate_depth)
        outcomes.add(fused)
        assert fused == (float(innovation @ np.linalg.solve(S, innovation)) <= nav.chi2_gate_depth)
        if not fused:
            np.testing.assert_array_equal(nav.x, x0)
            np.testing.assert_array_equal(nav.P, P0)
            continue
        K = P0 @ H.T @ np.linalg.inv(S)
        I_KH = np.eye(3) - K @ H
        np.testing.assert_allclose(nav.x, x0 + K @ innovation, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(nav.P, I_KH @ P0 @ I_KH.T + K @ R @ K.T, rtol=1e-10, atol=1e-12)
        np.testing.assert_array_equal(nav.P, nav.P.T)
    assert outcomes == {True, False}


def test_the_compiled_filter_flies_a_whole_run_as_the_numpy_reference_does():
    """seapup_control.compiled against Navigator's NumPy code along 1500 samples of a turning, pitching
    vehicle with noisy log, depth and 1 Hz fixes -- dropouts, multipath outliers (rejected), a lost log
    (coasting) and a diverged estimate re-acquired: the same decisions, the estimates equal to rounding."""
    rng = np.random.default_rng(7)
    navs = [Navigator(compiled=True), Navigator(compiled=False)]
    assert navs[0].kernels is not None and navs[1].kernels is None
    position, attitude = np.array([0.0, 0.0, 40.0]), np.zeros(3)
    for k in range(1500):
        attitude = attitude + [0.002 * rng.normal(), 0.003 * math.sin(0.01 * k), 0.01]
        velocity = np.array([0.5, 0.1 * math.sin(0.02 * k), 0.05 * math.cos(0.03 * k)])
        position = position + T * (_rotation(attitude) @ velocity)
        fields = {"attitude": attitude + 0.001 * rng.normal(size=3), "depth": position[2] + 0.05 * rng.normal()}
        if not 600 <= k < 620:   # the log lost for 4 s: the prediction coasts
            fields["velocity"] = velocity + 0.003 * rng.normal(size=3)
        if k % 5 == 0 and rng.random() > 0.2:
            fix = position + 0.5 * rng.normal(size=3)
            if k % 45 == 0:
                fix = fix + [30.0, 0.0, 0.0]        # multipath: rejected
            if 900 <= k < 930:
                fix = fix + [25.0, -10.0, 0.0]      # consistently elsewhere: re-acquired
            fields["position"] = fix
        measurement = Measurement.build(k * T, variances={"position": np.full(3, 0.25), "depth": 0.0025,
                                                          "velocity": np.full(3, 0.003 ** 2)}, **fields)
        estimates = [nav.update(measurement) for nav in navs]
        if estimates[0] is None:
            assert estimates[1] is None
            continue
        np.testing.assert_allclose(estimates[0].position, estimates[1].position, rtol=1e-11, atol=1e-9)
        np.testing.assert_allclose(estimates[0].position_cov, estimates[1].position_cov, rtol=1e-9, atol=1e-13)
    assert navs[0].counts == navs[1].counts
    counts = navs[0].counts
    assert counts["fixes_rejected"] > 0 and counts["reacquisitions"] >= 1 and counts["coasting_samples"] == 20


def _rotation(attitude):
    from seapup_common.frames import rotation_body_to_ned
    return rotation_body_to_ned(*attitude)
