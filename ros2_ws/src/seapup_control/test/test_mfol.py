"""Owens and Chotai's two-term law (eq. 4.9-4.16) and the closed-loop analysis (eq. 5.8-5.15).

Independent truths: an exactly first-order MIMO plant must get exactly the
designed poles and unit DC gain (eq. 4.13-4.15); a minimum-phase plant with
CB invertible approaches them as sampling gets faster (Owens and Chotai's
result, sec. 4.4); a non-minimum-phase plant goes unstable at fast sampling;
the closed-loop poles are checked against a time simulation of the same loop.
"""
import numpy as np
import pytest
import scipy.linalg

from seapup_control.closed_loop import closed_loop, closed_loop_discrete, discretise
from seapup_control.mfol import (THESIS_POLES_5HZ, DesignError, LoopPoles, MFOLModel, design,
                                 equilibrated_condition)


def random_mfol_plant(rng, m=4):
    """An exact MFOL plant y+ = (I - B0^-1 B1) y + B0^-1 u, stable."""
    while True:
        b0inv = rng.normal(size=(m, m)) * 0.1
        b1inv = rng.normal(size=(m, m))
        phi = np.eye(m) - b0inv @ np.linalg.inv(b1inv)
        if np.max(np.abs(np.linalg.eigvals(phi))) < 0.95:
            return b0inv, b1inv, phi


def test_exact_mfol_plant_gets_exactly_the_designed_poles_and_unit_dc_gain():
    rng = np.random.default_rng(4)
    b0inv, b1inv, phi = random_mfol_plant(rng)
    model = MFOLModel.from_state_space(phi, b0inv, np.eye(4), 0.2)
    np.testing.assert_allclose(model.B0inv, b0inv, atol=1e-12)
    np.testing.assert_allclose(model.B1inv, b1inv, rtol=1e-9)
    poles = LoopPoles([0.8, 0.85, 0.75, 0.3], [0.6, 0.85, 0.1, -0.2], 0.2)
    gains = design(model, poles)
    loop = closed_loop_discrete(phi, b0inv, np.eye(4), gains.K_int, gains.K_err, 0.2)
    expected = np.sort_complex(np.concatenate([poles.k, poles.c]).astype(complex))
    np.testing.assert_allclose(np.sort_complex(loop.z_poles), expected, atol=1e-6)
    np.testing.assert_allclose(loop.dc_gain(), np.eye(4), atol=1e-9)  # eq. 4.15


def test_continuous_first_order_plant_through_the_hold_is_an_exact_mfol():
    """dx/dt = A x + B u, y = x behind a ZOH is exactly eq. 4.9: the sampled-data analysis gives {k_j, c_j}."""
    a = np.array([[-1.0, 0.3], [0.1, -2.0]])
    b = np.array([[0.5, 0.1], [-0.2, 0.8]])
    phi, delta = discretise(a, b, 0.2)
    np.testing.assert_allclose(phi, scipy.linalg.expm(a * 0.2), atol=1e-12)
    model = MFOLModel.from_state_space(phi, delta, np.eye(2), 0.2)
    np.testing.assert_allclose(model.B1inv, -np.linalg.solve(a, b), rtol=1e-9)  # DC gain of the plant
    poles = LoopPoles([0.8, 0.85], [0.8, 0.85], 0.2)
    gains = design(model, poles)
    loop = closed_loop(a, b, np.eye(2), gains.K_int, gains.K_err, 0.2)
    np.testing.assert_allclose(np.sort(loop.z_poles.real), [0.8, 0.8, 0.85, 0.85], atol=2e-4)  # double poles
    np.testing.assert_allclose(loop.z_poles.imag, 0.0, atol=2e-4)
    np.testing.assert_allclose(loop.dc_gain(), np.eye(2), atol=1e-9)
    # the analysis agrees with a time simulation of the same loop (plant, hold, eq. 4.11)
    x, q, r = np.zeros(2), np.zeros(2), np.array([1.0, -0.5])
    for _ in range(200):
        e = r - x
        u = gains.K_int @ q + gains.K_err @ e
        x, q = phi @ x + delta @ u, q + e
    np.testing.assert_allclose(x, r, atol=1e-6)


def minimum_phase_plant(rng, n=6, m=2, nmp=False):
    """A stable plant with CB invertible whose transmission zeros are all in the left (or one in the right) half plane."""
    while True:
        a = rng.normal(size=(n, n))
        a -= (np.max(np.linalg.eigvals(a).real) + 0.5) * np.eye(n)
        b, c = rng.normal(size=(n, m)), rng.normal(size=(m, n))
        if abs(np.linalg.det(c @ b)) < 0.3:
            continue
        rosenbrock = np.block([[a, b], [c, np.zeros((m, m))]])
        zeros = scipy.linalg.eigvals(rosenbrock, np.block([[np.eye(n), np.zeros((n, m))],
                                                           [np.zeros((m, n + m))]]))
        zeros = zeros[np.isfinite(zeros)]
        right = np.sum(zeros.real > 0.05)
        if (right == 0 and np.all(zeros.real < -0.2)) if not nmp else right >= 1:
            return a, b, c, zeros


K, C = np.array([0.8, 0.6]), np.array([0.5, 0.4])  # discrete poles of the two loops


def designed_for(a, b, c, period):
    phi, delta = discretise(a, b, period)
    gains = design(MFOLModel.from_state_space(phi, delta, c, period), LoopPoles(K, C, period))
    return closed_loop(a, b, c, gains.K_int, gains.K_err, period)


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_minimum_phase_plant_approaches_the_designed_poles_as_sampling_gets_faster(seed):
    """Owens and Chotai: with k_j, c_j fixed, fast sampling (high gain) puts 2m poles at them (the
    others go to the sampled zeros near z = 1); seed 4 is unstable at slow sampling, stable fast."""
    a, b, c, _ = minimum_phase_plant(np.random.default_rng(seed))
    errors = []
    for period in (0.5, 0.02, 0.001):
        loop = designed_for(a, b, c, period)
        errors.append(max(np.min(np.abs(loop.z_poles - w)) for w in np.concatenate([K, C])))
    assert errors[-1] < 0.02 and errors[-1] < errors[1] < 0.15 and errors[-1] < errors[0] / 5, errors
    assert loop.stable


def test_non_minimum_phase_plant_is_found_unstable_by_the_analysis():
    a, b, c, zeros = minimum_phase_plant(np.random.default_rng(7), nmp=True)
    assert np.any(zeros.real > 0)
    for period in (0.02, 0.001):  # high gain: a closed-loop pole goes to the zero outside the unit circle
        loop = designed_for(a, b, c, period)
        assert not loop.stable and loop.spectral_radius > 1.0, period


def test_thesis_poles_map_to_20_hz_as_section_5_2_lists():
    fast = THESIS_POLES_5HZ.at_rate(0.05)
    np.testing.assert_allclose(fast.k, [0.94574, 0.96018, 0.93060, 0.89790], atol=5e-6)
    s5, _ = THESIS_POLES_5HZ.continuous()
    s20, _ = fast.continuous()
    np.testing.assert_allclose(s5, s20, rtol=1e-12)


def test_design_refuses_what_the_law_cannot_take():
    with pytest.raises(DesignError, match="eq. 4.16"):
        LoopPoles([0.8, 1.0], [0.5, 0.5], 0.2)
    with pytest.raises(DesignError, match="singular"):
        MFOLModel(np.ones((4, 4)), np.eye(4), 0.2)
    with pytest.raises(DesignError, match="shape"):
        MFOLModel(np.eye(4), np.eye(3), 0.2)
    with pytest.raises(DesignError, match="finite"):
        MFOLModel(np.full((2, 2), np.nan), np.eye(2), 0.2)
    with pytest.raises(DesignError, match="at_rate"):
        design(MFOLModel(np.eye(4), np.eye(4), 0.05), THESIS_POLES_5HZ)
    with pytest.raises(DesignError, match="span"):
        MFOLModel.from_responses(np.eye(2), np.eye(2), [[1, 2], [2, 4]], 0.2)


def test_step_tests_give_the_mfol_by_eq_4_20_4_21():
    rng = np.random.default_rng(5)
    b0inv, b1inv, phi = random_mfol_plant(rng, m=3)
    steps = np.diag([0.14, -0.14, 0.2]) + 0.01  # any spanning set of step vectors
    first, final = b0inv @ steps, b1inv @ steps
    model = MFOLModel.from_responses(first, final, steps, 0.2)
    np.testing.assert_allclose(model.B0inv, b0inv, atol=1e-12)
    np.testing.assert_allclose(model.B1inv, b1inv, atol=1e-10)
    thesis_b0, _ = model.in_thesis_units(yaw_row=2)
    np.testing.assert_allclose(thesis_b0[0], b0inv[0] * np.pi / 180)
    np.testing.assert_allclose(thesis_b0[2], b0inv[2])


def test_equilibrated_condition_ignores_units_and_finds_the_input_that_does_nothing():
    rng = np.random.default_rng(5)
    b0inv = rng.normal(size=(4, 4))
    units = np.diag([1.0, 1e-3, 1e2, 57.3])  # rescaling an output (m/s -> mm/s, rad -> deg) changes nothing
    assert equilibrated_condition(units @ b0inv)[0] == pytest.approx(equilibrated_condition(b0inv)[0], rel=1e-9)
    weak = b0inv.copy()
    weak[:, 2] *= 1e-3                       # input 2 barely acts on anything
    condition, weakest = equilibrated_condition(weak)
    assert weakest == 2 and condition > 100 * equilibrated_condition(b0inv)[0]
    weak[:, 2] = 0.0
    assert equilibrated_condition(weak) == (np.inf, 2)
    assert equilibrated_condition(np.zeros((2, 2)))[0] == np.inf
