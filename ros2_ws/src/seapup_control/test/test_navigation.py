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


def test_covariance_converges_to_the_discrete_riccati_solution():
    """Fixes every sample, constant Q and R: P tends to the DARE's a-posteriori covariance."""
    p = NavigatorParams(q_walk=1e-3, velocity_std=(0.01, 0.01, 0.01), fix_std=0.5, gate_probability=1.0)
    nav = Navigator(p)
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
