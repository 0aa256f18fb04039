"""Tests of seapup_sim.current against the thesis's numbers and Gauss-Markov theory."""
import math
from dataclasses import replace

import numpy as np
import pytest
import scipy.signal

from seapup_sim.environment_config import load_environment
from seapup_sim.current import CurrentParams, GaussMarkovCurrent, coefficients, noise_power_eq_2_31

THESIS = load_environment().current.params  # sec. 3.9: 0.26 m/s, 0.086 m/s, 0 deg, 20 deg, 10 s


def sig6(x):
    return float(f"{x:.6g}")


def test_coefficients_reproduce_eq_3_13_and_3_14():
    c = coefficients(THESIS, 0.2)
    assert sig6(c.b) == 0.980199 and round(c.b, 7) == 0.9801987
    assert sig6(c.d) == 0.0198013
    assert sig6(c.a_c) == 0.00514834 and round(c.a_c, 7) == 0.0051483
    assert c.a_alpha == 0.0


def test_noise_power_and_correlation_from_the_formulas():
    c = coefficients(THESIS, 0.2)
    # The thesis prints E{w_c^2} = 0.739269 and w_alpha = 232.546 w_c; its own
    # eq. 2.31 and 2.33 give 0.739625 and 232.558 (deg per m/s). The formulas
    # rule; the printed values differ by 0.048 % and 0.005 % (rounding in the
    # original computation).
    assert c.var_w_c == pytest.approx(0.739625, abs=5e-7)
    assert c.var_w_c == pytest.approx(0.739269, rel=1e-3)
    assert math.degrees(c.w_alpha_per_w_c) == pytest.approx(232.558, abs=5e-4)
    assert math.degrees(c.w_alpha_per_w_c) == pytest.approx(232.546, rel=1e-3)
    # eq. 2.32 is eq. 2.31 scaled by (sigma_alpha / sigma_c)^2: 2.33 is consistent
    assert c.var_w_alpha == pytest.approx(c.w_alpha_per_w_c ** 2 * c.var_w_c, rel=1e-12)
    # the simplified form used equals eq. 2.31 as printed
    assert c.var_w_c == pytest.approx(noise_power_eq_2_31(0.086, 0.26, c.b), rel=1e-9)
    assert c.var_w_alpha == pytest.approx(noise_power_eq_2_31(math.radians(20), 0.0, c.b), rel=1e-12)


def realisations(params, sample_time, n_real, n_samples, seed):
    rng = np.random.default_rng(seed)
    out = np.empty((n_real, n_samples, 2))
    for k in range(n_real):
        cur = GaussMarkovCurrent(params, sample_time, rng, start_at_mean=False)
        out[k] = cur.sample(n_samples)
    return out


def correlation_time(x, dt):
    """T_c from the lag-1 autocorrelation of many realisations (rows)."""
    x = x - x.mean()
    rho1 = (x[:, 1:] * x[:, :-1]).mean() / (x * x).mean()
    return -dt / math.log(rho1)


@pytest.fixture(scope="module")
def thesis_runs():
    return realisations(THESIS, 0.2, 200, 1500, seed=7)  # 200 x 300 s


def test_long_run_mean_std_and_correlation_time(thesis_runs):
    speed, direction = thesis_runs[..., 0], thesis_runs[..., 1]
    # standard error of the mean of a GM process: sigma * sqrt(2 T_c / T_total)
    se = THESIS.speed_std * math.sqrt(2 * 10.0 / (300.0 * 200))
    assert abs(speed.mean() - 0.26) < 4 * se
    assert speed.std() == pytest.approx(0.086, rel=0.02)
    assert abs(direction.mean()) < 4 * math.radians(20.0) * math.sqrt(2 * 10.0 / 60000)
    assert direction.std() == pytest.approx(math.radians(20.0), rel=0.02)
    assert correlation_time(speed, 0.2) == pytest.approx(10.0, rel=0.05)
    # eq. 2.33: direction is a scaled copy of speed
    np.testing.assert_allclose((direction - 0.0) / math.radians(20.0), (speed - 0.26) / 0.086, atol=1e-9)


def test_spectrum_corner_frequency_is_one_over_t_c(thesis_runs):
    speed = thesis_runs[..., 0]
    f, pxx = scipy.signal.welch(speed - 0.26, fs=5.0, nperseg=1024, axis=1)
    pxx = pxx.mean(axis=0)
    omega = 2 * math.pi * f[1:]
    # fit the first-order (Lorentzian) spectrum S = S0 / (1 + (omega / w_c)^2)
    def model(w, s0, wc):
        return s0 / (1.0 + (w / wc) ** 2)
    from scipy.optimize import curve_fit
    (s0, wc), _ = curve_fit(model, omega[omega < 2.0], pxx[1:][omega < 2.0], p0=[pxx[1], 0.2])
    assert wc == pytest.approx(0.1, rel=0.15)  # 1 / T_c rad/s (sec. 3.9: "0.1 rad/s")


@pytest.mark.parametrize("sample_time", [0.05, 1.0])
def test_statistics_do_not_depend_on_the_sample_time(sample_time):
    n = int(round(300.0 / sample_time))
    runs = realisations(THESIS, sample_time, 60, n, seed=11)
    assert runs[..., 0].std() == pytest.approx(0.086, rel=0.05)
    assert correlation_time(runs[..., 0], sample_time) == pytest.approx(10.0, rel=0.12)


def test_seeded_realisations_repeat_and_differ_by_seed():
    a = GaussMarkovCurrent(THESIS, 0.2, np.random.default_rng(3)).sample(100)
    b = GaussMarkovCurrent(THESIS, 0.2, np.random.default_rng(3)).sample(100)
    c = GaussMarkovCurrent(THESIS, 0.2, np.random.default_rng(4)).sample(100)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_constant_current_and_step_change():
    cur = GaussMarkovCurrent.constant(0.3, math.pi / 2, 0.2, np.random.default_rng(0))
    np.testing.assert_allclose(cur.sample(10)[:, 0], 0.3)
    np.testing.assert_allclose(cur.velocity_ned(), [0.0, 0.3, 0.0], atol=1e-15)
    # step change of the mean (sec. 5.4.3): relaxes with time constant T_c
    cur.set_params(CurrentParams(0.5, 0.0, math.pi / 2, 0.0, 10.0))
    after = cur.sample(50)[:, 0]  # 10 s = one time constant
    assert after[-1] == pytest.approx(0.5 - 0.2 * math.exp(-1.0), rel=1e-9)


def test_bad_parameters_are_refused():
    for kwargs in ({"mean_speed": -1.0}, {"speed_std": math.nan}, {"break_time": 0.0}):
        with pytest.raises(ValueError):
            replace(THESIS, **kwargs)
    with pytest.raises(ValueError):
        coefficients(THESIS, 0.0)
    with pytest.raises(TypeError):
        GaussMarkovCurrent(THESIS, 0.2, rng=np.random)  # global state is not accepted


@pytest.mark.unit
@pytest.mark.parametrize("params", [CurrentParams(0.26, 0.086, 0.3, math.radians(20.0), 10.0),
                                    CurrentParams(0.3, 0.0, -1.0, 0.0, 5.0)])
def test_a_period_s_velocities_are_the_sample_by_sample_ones_bit_for_bit(params):
    """velocities(n) (the simulator's control period drawn at once) against n calls of velocity_ned() then step()
    on a twin from the same seed: the same rows and the same state after, bit for bit, over periods of 0 to 5
    steps, for a random current and a steady one (no draws)."""
    one, twin = (GaussMarkovCurrent(params, 0.1, np.random.default_rng(3)) for _ in range(2))
    for n in [2, 2, 0, 5, 1, 3] * 20:
        rows = one.velocities(n)
        expected = []
        for _ in range(n):
            expected.append(twin.velocity_ned())
            twin.step()
        assert rows.shape == (n, 3)
        np.testing.assert_array_equal(rows, np.reshape(expected, (n, 3)))
        assert (one.speed, one.direction) == (twin.speed, twin.direction)
    assert one.rng.standard_normal() == twin.rng.standard_normal()   # the streams read as far
