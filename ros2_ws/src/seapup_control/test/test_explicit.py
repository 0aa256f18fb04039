"""The explicit self-tuner of sec. 7.3 on known plants.

Truth: a coupled first-order MIMO plant with an offset, y(t+1) = Phi y(t) + Gamma u(t) + d, whose exact
MFOL design places the closed-loop poles at the loop poles k_j, c_j (eq. 4.13); the estimate must converge
to (Phi, Gamma, d) and the closed loop of the true plant with the tuner's gains to the designed poles.
Jacketing: a plant left at rest with estimation forced on winds the covariance up (trace P grows as
lambda^-t, eq. 6.12), the trace rule falls back to the fixed gains without a bump; with the default jacket
estimation freezes instead.
"""
import importlib

import numpy as np
import pytest

from seapup_common.contract import Command, ContractError, Measurement, Reference
from seapup_common.controllers import ControllerRegistryError
from seapup_control.explicit import EXPLICIT_TYPE, ExplicitSelfTuner, create_explicit
from seapup_control.self_tuning import TunerJacket
from seapup_control.mfol import THESIS_POLES_5HZ, MFOLModel, design

pytestmark = pytest.mark.unit

T = 0.2
PHI = np.array([[0.90, 0.02, 0.00, 0.01],
                [0.01, 0.85, 0.00, 0.03],
                [0.00, 0.00, 0.80, 0.00],
                [0.02, 0.04, 0.00, 0.70]])
GAMMA = np.array([[0.020, 0.020, 0.002, 0.002],
                  [0.001, -0.001, 0.010, 0.012],
                  [-0.002, -0.002, 0.015, -0.015],
                  [0.060, -0.060, 0.030, -0.035]]) * 4.0   # the squares below need at most 28 deg of pitch
D = np.array([0.001, -0.0005, 0.002, 0.0])


def _measure(t, y):
    return Measurement.build(t, velocity=tuple(y[:3]), rates=(0.0, 0.0, float(y[3])))


def _fixed_gains(error=0.3):
    """The "self-test's" gains: a design from a model off by ``error`` in its gains (as a self-test is)."""
    wrong = MFOLModel.from_state_space(PHI, GAMMA * (1 + error), np.eye(4), T)
    return design(wrong, THESIS_POLES_5HZ)


def _fly(tuner, references, y0=None, u0=None, plant=(PHI, GAMMA, D)):
    phi, gamma, d = plant
    y = np.zeros(4) if y0 is None else y0.copy()
    u = np.zeros(4) if u0 is None else u0.copy()
    tuner.reset(Command(u))
    log = {"y": [], "u": [], "mode": []}
    for k, r in enumerate(references):
        t = k * T
        if k:
            tuner.applied(t, Command(u))
        u = tuner.update(t, _measure(t, y), Reference(r)).blade_pitch
        log["y"].append(y.copy()), log["u"].append(u.copy()), log["mode"].append(tuner.mode)
        y = phi @ y + gamma @ u + d
    return {k: np.array(v) if k != "mode" else v for k, v in log.items()}


def _squares(n, amplitude=(0.2, 0.1, 0.1, 0.3), periods=(40, 55, 70, 85)):
    k = np.arange(n)[:, None]
    return np.asarray(amplitude) * np.sign(np.sin(2 * np.pi * (k + 1) / np.asarray(periods)))


def _closed_loop_poles(gains):
    """Eq. 4.11's loop about the true plant: x = (y, q), q(t+1) = q(t) + e(t)."""
    a = np.block([[PHI - GAMMA @ gains.K_err, GAMMA @ gains.K_int], [-np.eye(4), np.eye(4)]])
    return np.sort_complex(np.linalg.eigvals(a))


def test_the_estimate_converges_to_the_plant_and_the_closed_loop_poles_to_the_designed_ones():
    # p0 = 1e6: noise-free data, so nothing is gained by trusting Theta(0) = 0; the designed poles are double
    # (k_j = c_j), so they split as the square root of the estimate's error, and 1e-3 needs it near 1e-6
    tuner = ExplicitSelfTuner(_fixed_gains(), THESIS_POLES_5HZ, forgetting=0.999, p0=1e6)
    held = np.array([0.15, -0.05, 0.1, 0.2])
    log = _fly(tuner, np.vstack([_squares(800), np.tile(held, (60, 1))]))
    est = tuner.estimate()
    np.testing.assert_allclose(est["Phi"], PHI, atol=1e-3)
    np.testing.assert_allclose(est["Gamma"], GAMMA, atol=1e-3 * np.abs(GAMMA).max())
    np.testing.assert_allclose(est["d"], D, atol=1e-4)
    designed = np.sort_complex(np.concatenate([THESIS_POLES_5HZ.k, THESIS_POLES_5HZ.c]).astype(complex))
    np.testing.assert_allclose(_closed_loop_poles(tuner.gains), designed, atol=1e-3)
    before = _closed_loop_poles(_fixed_gains())  # the fixed gains alone place them elsewhere
    assert np.max(np.abs(before - designed)) > 1e-2
    assert log["mode"][:5] == ["commissioning"] * 5 and log["mode"][-1] == "adaptive"
    assert tuner.counts["estimated"] > 50 and tuner.counts["frozen_at_set_point"] > 0
    # tracking: the reference held at the end is met (integral action, exact design)
    np.testing.assert_allclose(log["y"][-1], held, atol=1e-4)


def test_commissioning_flies_the_fixed_gains_for_five_samples_then_the_estimate():
    fixed = _fixed_gains()
    tuner = ExplicitSelfTuner(fixed, THESIS_POLES_5HZ)
    reference = _squares(8)
    _fly(tuner, reference[:5])
    assert tuner.mode == "commissioning" and tuner.gains is fixed
    assert tuner.counts["commissioning"] == 5
    first = tuner.events[0]
    assert first["mode"] == "commissioning" and "watches" in first["reason"]


def test_a_bumpless_start_from_the_applied_setting():
    tuner = ExplicitSelfTuner(_fixed_gains(), THESIS_POLES_5HZ)
    hover = np.radians([5.0, 5.0, -3.0, -3.0])
    tuner.reset(Command(hover))
    command = tuner.update(0.0, _measure(0.0, np.zeros(4)), Reference(np.zeros(4))).blade_pitch
    np.testing.assert_allclose(command, hover, atol=1e-12)


def test_a_covariance_wound_up_at_rest_falls_back_to_the_fixed_gains_without_a_bump_and_still_tracks():
    """No excitation (at rest, estimation forced on by a jacket without freezing), lambda = 0.95: trace P
    grows as 0.95^-t until the trace rule engages; then a step, flown on the fixed gains."""
    jacket = TunerJacket(set_point_band=(0.0, 0.0, 0.0, 0.0), excitation=0.0, max_trace_growth=10.0)
    tuner = ExplicitSelfTuner(_fixed_gains(), THESIS_POLES_5HZ, forgetting=0.95, jacket=jacket)
    rest, step = np.zeros((400, 4)), np.tile([0.1, 0.0, 0.05, 0.0], (150, 1))
    log = _fly(tuner, np.vstack([_squares(150), rest, step]))
    modes = log["mode"]
    engaged = next(k for k in range(150, len(modes)) if modes[k] == "fallback")
    assert engaged < 550 and tuner.counts["fallback_trace"] > 0 and tuner.counts["engagements"] >= 1
    assert any(e["mode"] == "fallback" and "trace P" in e["reason"] for e in tuner.events)
    du = np.abs(np.diff(log["u"], axis=0)).max(axis=1)
    assert du[engaged - 1] <= du[engaged - 76:engaged - 1].max() + 1e-12   # no bump at the switch
    assert all(m == "fallback" for m in modes[550:])
    np.testing.assert_allclose(log["y"][-1], [0.1, 0.0, 0.05, 0.0], atol=2e-3)  # the fixed gains track


def test_the_default_jacket_freezes_estimation_at_rest_so_the_covariance_does_not_wind_up():
    settled = ExplicitSelfTuner(_fixed_gains(), THESIS_POLES_5HZ, forgetting=0.95)
    _fly(settled, np.vstack([_squares(150), np.zeros((150, 4))]))
    tuner = ExplicitSelfTuner(_fixed_gains(), THESIS_POLES_5HZ, forgetting=0.95)
    _fly(tuner, np.vstack([_squares(150), np.zeros((400, 4))]))   # the same samples, then 250 more at rest
    assert tuner.counts["frozen_at_set_point"] + tuner.counts["frozen_no_excitation"] > 300
    # no wind-up at rest: 250 more samples at 0.95 unfrozen would multiply trace P by 0.95^-250 ~ 4e5
    assert tuner.estimator.trace[0] == pytest.approx(settled.estimator.trace[0], rel=1e-9)
    np.testing.assert_array_equal(tuner.estimator.theta, settled.estimator.theta)
    assert tuner.mode == "adaptive"


def test_a_nearly_singular_estimated_b0_falls_back():
    """A plant whose two main thrusters act alike (Gamma's first two columns equal): B0^-1 singular."""
    gamma = GAMMA.copy()
    gamma[:, 1] = gamma[:, 0]
    tuner = ExplicitSelfTuner(_fixed_gains(), THESIS_POLES_5HZ)
    _fly(tuner, _squares(200), plant=(PHI, gamma, D))
    assert tuner.counts["fallback_singular_b0"] > 0
    assert any("singular" in e["reason"] for e in tuner.events)


def test_bad_measurements_and_references_change_nothing():
    tuner = ExplicitSelfTuner(_fixed_gains(), THESIS_POLES_5HZ)
    _fly(tuner, _squares(20))
    theta, counts = tuner.estimator.theta.copy(), dict(tuner.counts)
    bad = Measurement.build(5.0, rates=(0.0, 0.0, 0.0))   # no velocity reading
    with pytest.raises(ContractError):
        tuner.update(5.0, bad, Reference(np.zeros(4)))
    with pytest.raises(ContractError):
        tuner.update(5.0, _measure(5.0, np.zeros(4)), [0.0, 0.0, 0.0, 0.0])
    np.testing.assert_array_equal(tuner.estimator.theta, theta)
    assert tuner.counts == counts


def _document():
    fixed = _fixed_gains()
    return {"kind": "seapup/mfol_controller", "version": 1, "sample_period": T,
            "poles": {"k": THESIS_POLES_5HZ.k.tolist(), "c": THESIS_POLES_5HZ.c.tolist()},
            "operating_points": [{"surge": 0.0, "K_int": fixed.K_int.tolist(), "K_err": fixed.K_err.tolist(),
                                  "u0": fixed.u0.tolist(), "y0": fixed.y0.tolist()}]}


def test_the_registered_type_builds_from_a_controller_file_and_refuses_what_it_cannot_use():
    tuner = create_explicit(EXPLICIT_TYPE.complete({"forgetting": 0.95}), _document(), T)
    assert tuner.forgetting == 0.95 and tuner.commissioning_samples == 5
    np.testing.assert_allclose(tuner.poles.k, THESIS_POLES_5HZ.k)
    assert EXPLICIT_TYPE.needs_applied and EXPLICIT_TYPE.needs_document
    with pytest.raises(ControllerRegistryError, match="lambda"):
        EXPLICIT_TYPE.complete({"lambda": 0.95})
    with pytest.raises(ValueError, match="forgetting"):
        create_explicit(EXPLICIT_TYPE.complete({"forgetting": 1.5}), _document(), T)
    with pytest.raises(ValueError, match="T = 0.2 s"):
        create_explicit(EXPLICIT_TYPE.complete({}), _document(), 0.05)


@pytest.mark.parametrize("case", ["tracking", "fallbacks"])
def test_the_compiled_redesign_and_estimator_fly_the_numpy_reference_bit_for_bit(case):
    """ExplicitSelfTuner with its compiled redesign and square-root update (the default where numba is loaded)
    against compiled=False along the same closed loop: every command, mode, reason, count and estimate equal bit
    for bit -- while tracking squares on all four axes, and on a plant whose estimate goes through the jacket's
    refusals (a nearly singular B0^-1, poles beyond max_pole, the trace rule) so that the compiled design's
    failures are explained by the reference's words."""
    importlib.import_module("numba")   # loaded, as in a process that flies a plant
    references = _squares(400)
    plant, jacket = (PHI, GAMMA, D), TunerJacket()
    if case == "fallbacks":
        gamma = GAMMA.copy()
        gamma[:, 3] = gamma[:, 2] * 1.0001   # two thrusters that nearly do the same: B0^-1 nearly singular
        plant, jacket = (PHI * 1.05, gamma, D), TunerJacket(min_rcond=1e-3, max_pole=0.99, max_trace_growth=3.0)
    tuners = {kind: ExplicitSelfTuner(_fixed_gains(), THESIS_POLES_5HZ, forgetting=0.97, jacket=jacket,
                                      compiled=kind) for kind in (True, False)}
    assert tuners[True].kernel is not None and tuners[False].kernel is None
    logs = {kind: _fly(tuner, references, plant=plant) for kind, tuner in tuners.items()}
    assert np.array_equal(logs[True]["u"], logs[False]["u"]) and logs[True]["mode"] == logs[False]["mode"]
    assert tuners[True].events == tuners[False].events and tuners[True].counts == tuners[False].counts
    np.testing.assert_array_equal(tuners[True].estimate_matrix(), tuners[False].estimate_matrix())
    counts = tuners[True].counts
    if case == "tracking":
        assert counts["adaptive"] > 300
    else:
        assert counts["fallback"] > 20 and counts["adaptive"] > 20, counts
