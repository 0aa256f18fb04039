"""The self-test procedure on an exactly first-order plant: it must find the plant's own MFOL.

The plant ``y+ = Φ y + Δ (u - u_h)`` is an exact MFOL with B0^-1 = Δ and
B1^-1 = (I - Φ)^-1 Δ (eq. 4.18-4.19), every channel a first-order lag
(eq. 4.23), and holds still at the setting u_h; its
zero level (zero pitch) makes it drift, as the Seapup does (sec. 5.3).
"""
import math

import numpy as np
import pytest

from seapup_common.config import ConfigError
from seapup_common.contract import Command, ContractError, Measurement
from seapup_control.self_test import Phase, SelfTest, SelfTestConfig, fit_operating_point

T = 0.2
HOLD = np.radians([-3.4, -3.4, -13.1, -13.1])


def exact_plant(seed=2):
    """Decoupled dynamics (Φ diagonal), coupled inputs: every channel is exactly a first-order lag
    (eq. 4.23), so the per-channel fits must return B0^-1 = Δ and B1^-1 = (I - Φ)^-1 Δ exactly.
    Magnitudes like the Seapup's, per radian (eq. 5.3 x 180/pi)."""
    rng = np.random.default_rng(seed)
    phi = np.diag([0.88, 0.93, 0.80, 0.82])
    delta = np.diag([0.16, 0.034, 0.057, 0.33]) + 0.01 * rng.normal(size=(4, 4))
    return phi, delta, np.linalg.solve(np.eye(4) - phi, delta)


def fly(test, phi, delta, y=None, limit=3000):
    """Close the loop; an artificial reset puts the plant at rest at the requested surge speed,
    holding the setting that keeps it there (as the simulator's ~/reset with a trim)."""
    y = np.zeros(4) if y is None else y
    b1inv = np.linalg.solve(np.eye(4) - phi, delta)
    commands = []
    for k in range(limit):
        if test.finished:
            break
        u = test.update(k * T, Measurement.build(k * T, velocity=y[:3], rates=(0, 0, y[3]))).blade_pitch
        if test.reset_request is not None:
            y = np.array([test.reset_request, 0.0, 0.0, 0.0])
            test.plant_reset(Command(HOLD + np.linalg.lstsq(b1inv, y)[0]))  # (a dead input: lstsq)
            continue
        commands.append(u)
        y = phi @ y + delta @ (u - HOLD)
    return y, np.array(commands)


def test_artificial_quiescence_finds_the_exact_mfol_at_every_operating_point():
    phi, delta, b1inv = exact_plant()
    test = SelfTest(SelfTestConfig.load({"mode": "artificial", "operating_points": [0.0, 0.3]}))
    test.reset(Command(np.zeros(4)))
    fly(test, phi, delta)
    assert test.phase == Phase.DONE, test.reason
    assert [p.surge for p in test.points] == [0.0, 0.3] and len(test.tests) == 12
    for point in test.points:
        np.testing.assert_allclose(point.model.B0inv, delta, rtol=1e-6, atol=1e-12)
        np.testing.assert_allclose(point.model.B1inv, b1inv, rtol=1e-6, atol=1e-12)
        np.testing.assert_allclose(point.model.u0, HOLD + np.linalg.solve(b1inv, [point.surge, 0, 0, 0]),
                                   atol=1e-12)
        np.testing.assert_allclose(point.model.y0, [point.surge, 0, 0, 0])
    assert [t.cycle for t in test.tests] == [1] * 4 + [2] * 8 and test.progress == 1.0


def test_the_raw_fit_reads_the_operating_point_into_the_surge_row_as_the_thesis_s_table_5_2_does():
    """fit="raw" (eq. 4.30 on the raw outputs, y0 not subtracted): at 0 m/s, and in every row but surge at
    0.3 m/s, the same exact MFOL as eq. 5.5's fit; the surge row at 0.3 m/s reads the whole speed as the step's
    response: its final value (0.3 + du) / step for every thruster, the vectored ones included -- the pattern
    of Table 5.2's surge rows ((0.7 + du) / 8 deg: .105, .105, .096, .092 per deg)."""
    phi, delta, b1inv = exact_plant()
    runs = {}
    for fit in ("deviation", "raw"):
        test = SelfTest(SelfTestConfig.load({"mode": "artificial", "operating_points": [0.0, 0.3], "fit": fit}))
        test.reset(Command(np.zeros(4)))
        fly(test, phi, delta)
        assert test.phase == Phase.DONE, test.reason
        runs[fit] = {p.surge: p.model for p in test.points}
    step = SelfTestConfig.load().step
    raw, exact = runs["raw"], runs["deviation"]
    for m in ("B0inv", "B1inv"):
        np.testing.assert_allclose(getattr(raw[0.0], m), getattr(exact[0.0], m), rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(getattr(raw[0.3], m)[1:], getattr(exact[0.3], m)[1:], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(exact[0.3].B1inv, b1inv, rtol=1e-6, atol=1e-12)
    final = b1inv[0] * step                 # the surge each step adds, from 0.3 m/s
    np.testing.assert_allclose(raw[0.3].B1inv[0] * step, 0.3 + final, rtol=0.02)
    assert np.all(raw[0.3].B1inv[0, 1:] > 9.0 * np.abs(b1inv[0, 1:]))   # a surge response from every thruster
    with pytest.raises(ConfigError, match="fit"):
        SelfTestConfig.load({"fit": "prony"})


def test_realistic_quiescence_gets_the_dominant_channels_and_the_holding_setting():
    """Each test starts where quiescence was declared, not at rest: the initial transient biases the
    fits (sec. 5.3.3); the dominant channels stay within 10 % and the controller holds the plant."""
    phi, delta, b1inv = exact_plant()
    test = SelfTest(SelfTestConfig.load({"operating_points": [0.0, 0.3]}))
    test.reset(Command(np.zeros(4)))
    y, _ = fly(test, phi, delta)
    assert test.phase == Phase.DONE, test.reason
    assert test.threshold > 0.01 and len(test.tests) == 12
    assert [t.cycle for t in test.tests] == [1] * 4 + [2] * 8
    for point in test.points:
        np.testing.assert_allclose(np.diag(point.model.B0inv), np.diag(delta), rtol=0.1)
        np.testing.assert_allclose(np.diag(point.model.B1inv), np.diag(b1inv), rtol=0.1)
        np.testing.assert_allclose(point.model.u0, HOLD + np.linalg.solve(b1inv, [point.surge, 0, 0, 0]),
                                   atol=0.02)  # the controller found the holding setting
    for k in range(3000, 3300):  # done: it hovers under the scheduled controller
        u = test.update(k * T, Measurement.build(k * T, velocity=y[:3], rates=(0, 0, y[3]))).blade_pitch
        y = phi @ y + delta @ (u - HOLD)
    assert np.abs(y).max() < 1e-3


def test_refitting_the_logged_steps_gives_the_live_result():
    """What --from-bag will do: the raw step data alone reproduce the model and gains."""
    phi, delta, _ = exact_plant()
    test = SelfTest(SelfTestConfig.load({}))
    test.reset(Command(np.zeros(4)))
    fly(test, phi, delta)
    again = fit_operating_point([t for t in test.tests if t.cycle == 2], T, test.config.poles)
    np.testing.assert_array_equal(again.model.B0inv, test.points[0].model.B0inv)
    np.testing.assert_array_equal(again.gains.K_err, test.points[0].gains.K_err)


def test_a_decoupled_plant_gets_exact_zeros_off_the_diagonal():
    """Channels that do not respond at all are zero gains (not a failed fit)."""
    phi = np.diag([0.88, 0.93, 0.80, 0.82])
    delta = np.diag([0.16, 0.034, 0.057, 0.33])
    test = SelfTest(SelfTestConfig.load({"mode": "artificial"}))
    test.reset(Command(np.zeros(4)))
    fly(test, phi, delta)
    assert test.phase == Phase.DONE, test.reason
    np.testing.assert_allclose(test.points[0].model.B0inv, delta, rtol=1e-9, atol=0.0)
    np.testing.assert_allclose(test.points[0].model.B1inv, np.linalg.solve(np.eye(4) - phi, delta),
                               rtol=1e-9, atol=0.0)


@pytest.mark.parametrize("mode", ["artificial", "realistic"])
@pytest.mark.parametrize("dead", [0, 3])
def test_a_dead_input_makes_b0_singular_and_fails_naming_it(mode, dead):
    """|B0| != 0 (eq. 4.9) fails for a dead thruster: exactly with artificial quiescence, to the
    test's resolution in realistic mode, where the dead channel 'responds' with the drift."""
    phi, delta, _ = exact_plant()
    delta[:, dead] = 0.0
    test = SelfTest(SelfTestConfig.load({"mode": mode}))
    test.reset(Command(np.zeros(4)))
    _, commands = fly(test, phi, delta)
    assert test.phase == Phase.FAILED and "singular" in test.reason, test.reason
    assert f"thruster {dead}" in test.reason and test.points == [] and test.controller is None
    np.testing.assert_array_equal(commands[-1], np.zeros(4))  # no controller: back to the zero level


def test_failures_end_in_hover_with_a_reason():
    phi, delta, _ = exact_plant()
    # quiescence never reached: the plant drifts faster than the threshold allows
    test = SelfTest(SelfTestConfig.load({"quiescence_speed": 0.001, "max_wait": 5.0}))
    test.reset(Command(np.zeros(4)))
    _, commands = fly(test, phi, delta)
    assert test.phase == Phase.FAILED and "quiescence" in test.reason
    np.testing.assert_array_equal(commands[-1], np.zeros(4))  # no controller yet: the zero level
    # a step that would pass the blade limit is refused before it is made
    test = SelfTest(SelfTestConfig.load({"zero_level": [0.6, 0.0, 0.0, 0.0]}))
    test.reset(Command(np.zeros(4)))
    _, commands = fly(test, phi, delta)
    assert test.phase == Phase.FAILED and "saturate" in test.reason
    assert np.all(np.abs(commands) <= math.radians(35) + 1e-12)


def test_cancel_hovers_under_the_best_controller():
    phi, delta, _ = exact_plant()
    test = SelfTest(SelfTestConfig.load({}))
    test.reset(Command(np.zeros(4)))
    y = np.zeros(4)
    for k in range(5000):
        u = test.update(k * T, Measurement.build(k * T, velocity=y[:3], rates=(0, 0, y[3]))).blade_pitch
        y = phi @ y + delta @ (u - HOLD)
        if test.controller is not None and test.phase == Phase.STEP and test.tests[-1].cycle == 2:
            break
    test.cancel()
    assert test.phase == Phase.CANCELLED and test.progress < 1.0
    for k in range(k + 1, k + 600):  # hover: the controller brings the plant to rest
        u = test.update(k * T, Measurement.build(k * T, velocity=y[:3], rates=(0, 0, y[3]))).blade_pitch
        y = phi @ y + delta @ (u - HOLD)
    assert np.abs(y).max() < 1e-3


def test_settings_are_checked_and_bad_measurements_change_nothing():
    with pytest.raises(ConfigError, match="operating_points"):
        SelfTestConfig.load({"operating_points": [0.7]})
    with pytest.raises(ConfigError, match="samples"):
        SelfTestConfig.load({"samples": 2})
    with pytest.raises(ConfigError, match="mode"):
        SelfTestConfig.load({"mode": "sometimes"})
    fast = SelfTestConfig.load({"sample_period": 0.05})
    np.testing.assert_allclose(fast.poles.k, [0.94574, 0.96018, 0.93060, 0.89790], atol=5e-6)  # sec. 5.2
    test = SelfTest(SelfTestConfig.load({}))
    with pytest.raises(ContractError):
        test.update(0.0, Measurement.build(0.0, rates=(0, 0, 0)))
    assert test.start_time is None and test.phase == Phase.DRIFT


def test_a_run_rebuilt_from_its_sample_records_refits_to_the_same_result():
    """The --from-bag path: per-sample records (as the node publishes them) -> step tests -> the same models."""
    from seapup_control.self_test import refit, tests_from_samples

    phi, delta, _ = exact_plant()
    test = SelfTest(SelfTestConfig.load({"operating_points": [0.0, 0.3]}))
    test.reset(Command(np.zeros(4)))
    records, y = [], np.zeros(4)
    for k in range(3000):
        if test.finished:
            break
        u = test.update(k * T, Measurement.build(k * T, velocity=y[:3], rates=(0, 0, y[3]))).blade_pitch
        for index in test.last_logged:
            logged = test.tests[index]
            records.append({"t": k * T, "test_index": index, "cycle": logged.cycle, "surge": logged.surge,
                            "thruster": logged.thruster, "step": logged.step,
                            "quiescent_input": logged.quiescent_input.tolist(),
                            "equilibrium": logged.equilibrium.tolist(), "velocity": logged.outputs[-1].tolist()})
        y = phi @ y + delta @ (u - HOLD)
    rebuilt = tests_from_samples(reversed(records))  # any order
    assert len(rebuilt) == len(test.tests) == 12
    for mine, live in zip(rebuilt, test.tests):
        np.testing.assert_array_equal(mine.outputs, live.outputs)
    points = refit(rebuilt, T, test.config.poles)
    assert [p.surge for p in points] == [0.0, 0.3]
    for mine, live in zip(points, test.points):
        np.testing.assert_array_equal(mine.model.B1inv, live.model.B1inv)
        np.testing.assert_array_equal(mine.gains.K_err, live.gains.K_err)
    with pytest.raises(Exception, match="misses"):
        tests_from_samples([r for r in records if r["test_index"] != 3])
    assert len(tests_from_samples(records, T)) == 12   # every test's records one period apart
    inside = [i for i, r in enumerate(records) if r["test_index"] == 5][4]   # a sample inside test 5 lost
    with pytest.raises(Exception, match=r"step test 5: its records jump from t = .* \(samples lost"):
        tests_from_samples(records[:inside] + records[inside + 1:], T)


def drift_phase(speeds, variance):
    """Feed the drift phase a sequence of surge speeds with the log's stated variance; the time it settled."""
    test = SelfTest(SelfTestConfig.load({}))
    test.reset(Command(np.zeros(4)))
    for k, u in enumerate(speeds):
        test.update(k * T, Measurement.build(k * T, velocity=(u, 0, 0), rates=(0, 0, 0),
                                             variances={"velocity": np.full(3, variance)}))
        if test.phase != Phase.DRIFT:
            return (k * T if test.phase == Phase.QUIESCE else None), test  # FAILED after max_wait
    return None, test


def test_the_drift_settles_through_log_noise_but_not_through_a_real_drift():
    """sec. 6.5.1's log noise (0.02 kt, 3 sigma) is wider than the 2 mm/s tolerance: the reading's variance
    widens it by 5 sigma, so a steady drift under noise settles within seconds and its mean is taken."""
    rng = np.random.default_rng(4)
    sigma = 0.02 * 1852 / 3600 / 3
    noisy = 0.25 + sigma * rng.normal(size=1000)
    t, test = drift_phase(noisy, sigma ** 2)
    assert t is not None and t < 10.0
    assert test.threshold == pytest.approx(1.2 * 0.25 + 0.01, abs=1.2 * 3 * sigma)  # the window's mean
    # the same noise without its variance is never quiet enough (the thesis's noise-free tolerance)
    assert drift_phase(noisy, 0.0)[0] is None
    # a drift that still changes 10 sigma per window, or oscillates by that much, does not settle
    assert drift_phase(noisy + np.arange(1000) * 10 * sigma / 10, sigma ** 2)[0] is None
    assert drift_phase(noisy + 5 * sigma * np.sin(np.arange(1000) * 2 * np.pi / 8), sigma ** 2)[0] is None


def test_two_results_of_the_same_second_are_two_files(tmp_path):
    """Two self-tests finishing in the same second (two graphs of a test run side by side) once wrote one
    file, and one graph's controllers were configured from the other's result: each result is its own file,
    created exclusively, holding its own document."""
    import yaml
    from seapup_control.self_test import write_result_file
    first = write_result_file(tmp_path / "results", {"operating_points": [{"surge": 0.0}]}, now=1.8e9)
    second = write_result_file(tmp_path / "results", {"operating_points": [{"surge": 0.7}]}, now=1.8e9)
    assert first != second and first.parent == second.parent
    assert yaml.safe_load(first.read_text())["operating_points"][0]["surge"] == 0.0
    assert yaml.safe_load(second.read_text())["operating_points"][0]["surge"] == 0.7
    assert first.name.startswith("self_test_20270115_080000_") and second.stem.endswith("_2")
