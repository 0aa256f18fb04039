"""Koivo's implicit GMV self-tuner (sec. 7.5) on known plants.

Truth: a coupled first-order MIMO plant y(t+1) = A y(t) + B u(t) + d (+ white noise), in the thesis's units.
With G0 fixed to the plant's B + lambda I, the estimate converges to the exact predictor of the generalised
output of eq. 7.5, and then (Koivo's design) the closed loop's characteristic polynomial is
det(B + lambda (1 - z^-1)(I - A z^-1)) with unit DC gain; with lambda = 0 the output error y(t+1) - r(t) is the
one-step prediction error, so its variance is the noise variance: minimum variance (Astrom's result for k = 1).
"""
import importlib

import numpy as np
import pytest

from seapup_common.contract import Command, ContractError, Measurement, Reference
from seapup_common.controllers import ControllerRegistryError
from seapup_control.self_tuning import TunerJacket
from seapup_control.gmv import GMV_TYPE, THESIS_SCALE_U, THESIS_SCALE_Y, GMVSelfTuner, create_gmv
from seapup_control.mfol import THESIS_POLES_5HZ, MFOLModel, design

pytestmark = pytest.mark.unit

T = 0.2
A = np.array([[0.90, 0.02, 0.00, 0.01],
              [0.01, 0.85, 0.00, 0.03],
              [0.00, 0.00, 0.80, 0.00],
              [0.02, 0.04, 0.00, 0.70]])
B = np.array([[0.80, 0.80, 0.08, 0.08],          # SI per rad; about the Seapup's eq. 5.3 in size
              [0.04, -0.04, 0.40, 0.48],
              [-0.08, -0.08, 0.60, -0.60],
              [2.40, -2.40, 1.20, -1.40]])
D = np.array([0.001, -0.0005, 0.002, 0.0])
NO_JACKET = TunerJacket(set_point_band=(0.0, 0.0, 0.0, 0.0), excitation=0.0, max_trace_growth=np.inf)


def _fixed():
    return design(MFOLModel.from_state_space(A, B * 1.3, np.eye(4), T), THESIS_POLES_5HZ)


def _squares(n, amplitude=(0.2, 0.1, 0.1, 0.3), periods=(40, 55, 70, 85)):
    k = np.arange(n)[:, None]
    return np.asarray(amplitude) * np.sign(np.sin(2 * np.pi * (k + 1) / np.asarray(periods)))


def _fly(tuner, references, noise=0.0, seed=0):
    rng = np.random.default_rng(seed)
    y, u = np.zeros(4), np.zeros(4)
    tuner.reset(Command(u))
    ys, us = [], []
    for k, r in enumerate(references):
        t = k * T
        if k:
            tuner.applied(t, Command(u))
        u = tuner.update(t, Measurement.build(t, velocity=tuple(y[:3]), rates=(0.0, 0.0, float(y[3]))),
                         Reference(r)).blade_pitch
        ys.append(y.copy()), us.append(u.copy())
        y = A @ y + B @ u + D + noise * rng.standard_normal(4) / THESIS_SCALE_Y
    return np.array(ys), np.array(us)


def _thesis_plant():
    """A and B in the thesis's units (outputs m/s and deg/s, inputs deg)."""
    s = np.diag(THESIS_SCALE_Y)
    return s @ A @ np.linalg.inv(s), s @ B / THESIS_SCALE_U


def _koivo_roots(lam):
    """Roots of det(z^2 (B + lam I) - z lam (A + I) + lam A) = z^8 det(B + lam (1 - z^-1)(I - A z^-1))."""
    a, b = _thesis_plant()
    m2, m1, m0 = b + lam * np.eye(4), -lam * (a + np.eye(4)), lam * a
    inv = np.linalg.inv(m2)
    companion = np.block([[np.zeros((4, 4)), np.eye(4)], [-inv @ m0, -inv @ m1]])
    return np.sort_complex(np.linalg.eigvals(companion))


def _closed_loop_roots(tuner):
    """The plant under the tuner's present law u(t) = -G0^-1 Theta^T (y(t), u(t-1), r(t), 1) (order 1)."""
    a, b = _thesis_plant()
    theta = tuner.estimator.theta
    k_y, k_u = -tuner.G0_inv @ theta[0:4].T, -tuner.G0_inv @ theta[4:8].T
    closed = np.block([[a + b @ k_y, b @ k_u], [k_y, k_u]])
    return np.sort_complex(np.linalg.eigvals(closed))


@pytest.mark.parametrize("lam", [0.001, 0.005])
def test_the_closed_loop_has_koivos_characteristic_polynomial_and_unit_dc_gain(lam):
    """(This plant's B has a negative eigenvalue, so with Q = lambda I Koivo's polynomial has a root outside
    the unit circle from lambda ~ 0.0075 on: the values flown keep it inside.)"""
    tuner = GMVSelfTuner(_fixed(), B, weighting=lam, order=1, p0=1e6, jacket=NO_JACKET)
    held = np.array([0.15, -0.05, 0.1, 0.2])
    ys, _ = _fly(tuner, np.vstack([_squares(1200), np.tile(held, (150, 1))]))
    assert tuner.mode == "adaptive" and tuner.counts["estimated"] > 1000
    np.testing.assert_allclose(_closed_loop_roots(tuner), _koivo_roots(lam), atol=1e-3)
    assert np.max(np.abs(_koivo_roots(lam))) < 1.0
    np.testing.assert_allclose(ys[-1], held, atol=1e-4)   # unit DC gain: the integrating form of eq. 7.5


def test_with_no_control_weighting_the_output_variance_is_the_minimum():
    """lambda = 0, white noise of 0.01 (m/s, deg/s) on every output: after convergence y(t+1) - r(t) has the
    noise's variance (Astrom's minimum for a one-step horizon); a fixed-gain loop on the same noise does worse."""
    sigma = 0.01
    references = _squares(4000, amplitude=(0.1, 0.05, 0.05, 0.1))
    tuner = GMVSelfTuner(_fixed(), B, weighting=0.0, order=1, forgetting=1.0, p0=1e4, jacket=NO_JACKET)
    ys, _ = _fly(tuner, references, noise=sigma, seed=3)
    error = (ys[1:] - references[:-1]) * THESIS_SCALE_Y
    variance = error[2000:].var(axis=0)
    np.testing.assert_allclose(variance, sigma ** 2, rtol=0.12)   # 2000 samples: chi-square +-~6 % (2 sigma)
    # the prediction of phi is the plant's one-step predictor: Theta -> the exact parameters
    a, b = _thesis_plant()
    np.testing.assert_allclose(tuner.estimator.theta[0:4].T, a, atol=0.02)
    fixed = GMVSelfTuner(_fixed(), B, weighting=0.0, order=1, commissioning_samples=10 ** 6, jacket=NO_JACKET)
    ys_fixed, _ = _fly(fixed, references, noise=sigma, seed=3)
    fixed_error = (ys_fixed[1:] - references[:-1]) * THESIS_SCALE_Y
    assert np.all(fixed_error[2000:].var(axis=0) > 1.2 * variance)


def test_the_second_order_law_also_converges_on_a_first_order_plant():
    """Order 2 (the default, sec. 7.6.1) over-parameterises a first-order plant: it must still hold the
    references (unit DC gain) and stay stable."""
    tuner = GMVSelfTuner(_fixed(), B, weighting=0.001, order=2, p0=1e6, jacket=NO_JACKET)
    held = np.array([0.1, 0.05, -0.05, 0.3])
    ys, us = _fly(tuner, np.vstack([_squares(1200), np.tile(held, (150, 1))]))
    np.testing.assert_allclose(ys[-1], held, atol=1e-3)
    assert np.all(np.isfinite(us)) and tuner.n_params == 21


def test_commissioning_then_the_law_and_a_wound_up_covariance_falls_back():
    tuner = GMVSelfTuner(_fixed(), B, weighting=0.001, order=1, forgetting=0.95,
                         jacket=TunerJacket(set_point_band=(0, 0, 0, 0), excitation=0.0, max_trace_growth=10.0))
    ys, us = _fly(tuner, np.vstack([_squares(150), np.zeros((500, 4))]))
    assert tuner.counts["commissioning"] == 5 and tuner.events[0]["mode"] == "commissioning"
    assert tuner.counts["fallback_trace"] > 0 and tuner.mode == "fallback"
    assert any("trace P" in e["reason"] for e in tuner.events)
    np.testing.assert_allclose(ys[-1], 0.0, atol=1e-3)


def test_bad_input_changes_nothing_and_the_registered_type_builds_from_a_controller_file():
    tuner = GMVSelfTuner(_fixed(), B, order=1)
    _fly(tuner, _squares(30))
    theta, counts = tuner.estimator.theta.copy(), dict(tuner.counts)
    with pytest.raises(ContractError):
        tuner.update(6.0, Measurement.build(6.0, rates=(0.0, 0.0, 0.0)), Reference(np.zeros(4)))
    np.testing.assert_array_equal(tuner.estimator.theta, theta)
    assert tuner.counts == counts
    fixed = _fixed()
    document = {"kind": "seapup/mfol_controller", "version": 1, "sample_period": T,
                "poles": {"k": [0.8] * 4, "c": [0.8] * 4},
                "operating_points": [{"surge": 0.0, "K_int": fixed.K_int.tolist(), "K_err": fixed.K_err.tolist(),
                                      "u0": fixed.u0.tolist(), "y0": fixed.y0.tolist(), "B0inv": B.tolist()}]}
    built = create_gmv(GMV_TYPE.complete({"lambda": 0.1, "order": 1}), document, T)
    assert built.weighting == 0.1 and built.order == 1 and built.n_params == 13
    np.testing.assert_allclose(built.G0, _thesis_plant()[1] + 0.1 * np.eye(4))
    with pytest.raises(ControllerRegistryError, match="weighting"):
        GMV_TYPE.complete({"weighting": 0.1})
    with pytest.raises(ValueError, match="lambda"):
        create_gmv(GMV_TYPE.complete({"lambda": -1.0}), document, T)
    singular = dict(document, operating_points=[dict(document["operating_points"][0], B0inv=np.zeros((4, 4)).tolist())])
    with pytest.raises(ValueError, match="singular"):
        create_gmv(GMV_TYPE.complete({"lambda": 0.0}), singular, T)


@pytest.mark.unit
@pytest.mark.parametrize("order", [1, 2])
def test_the_compiled_estimator_flies_the_numpy_reference_bit_for_bit(order):
    """GMVSelfTuner with its estimator's compiled square-root update (the default where numba is loaded) against
    compiled=False, with noise, the default jacket and a trace limit that engages: every command, count, event
    and estimate equal bit for bit."""
    importlib.import_module("numba")   # loaded, as in a process that flies a plant
    from seapup_ident.recursive import ud_update
    jacket = TunerJacket(max_trace_growth=1.5)
    tuners = {kind: GMVSelfTuner(_fixed(), B, weighting=0.01, order=order, forgetting=0.98, jacket=jacket,
                                 compiled=kind) for kind in (True, False)}
    assert tuners[True].estimator._ud is not ud_update and tuners[False].estimator._ud is ud_update
    flown = {kind: _fly(tuner, _squares(400), noise=0.002, seed=order) for kind, tuner in tuners.items()}
    for a, b in zip(flown[True], flown[False]):
        assert np.array_equal(a, b)
    assert tuners[True].counts == tuners[False].counts and tuners[True].events == tuners[False].events
    assert np.array_equal(tuners[True].estimate_matrix(), tuners[False].estimate_matrix())
    assert tuners[True].counts["adaptive"] > 100
