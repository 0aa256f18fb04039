"""Tests of seapup_sim.sensors: noise statistics match the profiles over long runs."""
import math

import numpy as np
import pytest

from dataclasses import replace

from seapup_common.random_streams import RandomStreams
from seapup_sim.seabed import Seabed
from seapup_sim.sensors import SensorSuite, load_sensor_profile, sensor_profiles
from seapup_sim.vehicle import specific_force

KT = 1852.0 / 3600.0


def test_profiles_carry_the_thesis_numbers():
    assert {"ideal", "baseline", "haslar"} <= set(sensor_profiles())
    base = load_sensor_profile("baseline")
    assert 3 * base.velocity_std[0] == pytest.approx(0.02 * KT)              # doppler 0.02 kt at 3 sigma
    assert math.degrees(3 * base.rate_std[2]) == pytest.approx(0.005)       # yaw gyro 0.005 deg/s
    assert math.degrees(3 * base.attitude_std[0]) == pytest.approx(0.25)    # roll/pitch 0.25 deg
    has = load_sensor_profile("haslar")
    assert has.velocity_std == (0.0172, 0.0172, 0.0172)
    assert math.degrees(has.rate_std[2]) == pytest.approx(0.0083)
    with pytest.raises(ValueError, match="no sensor profile"):
        load_sensor_profile("sonar-x")


@pytest.mark.sweep   # 20 000 samples of every instrument per profile: ~4 s each
@pytest.mark.parametrize("name", ["baseline", "haslar"])
def test_long_run_noise_statistics(name):
    profile = load_sensor_profile(name)
    suite = SensorSuite(profile, RandomStreams(5), Seabed("flat", 80.0))
    state = np.array([1.0, 2.0, 30.0, 0.1, -0.05, 1.0, 0.5, 0.1, -0.05, 0.01, 0.02, 0.03])
    n = 20000
    vel, rates, att = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    for k in range(n):
        m = suite.measure(0.2 * k, state)
        vel[k], rates[k], att[k] = m.velocity.value, m.rates.value, m.attitude.value
    for data, truth, std in ((vel, state[6:9], profile.velocity_std), (rates, state[9:], profile.rate_std),
                             (att, state[3:6], profile.attitude_std)):
        np.testing.assert_allclose(data.mean(axis=0), truth, atol=5 * np.max(std) / math.sqrt(n))
        np.testing.assert_allclose(data.std(axis=0), std, rtol=0.03)
        # white: no correlation between successive samples
        x = data - data.mean(axis=0)
        rho = (x[1:] * x[:-1]).mean(axis=0) / x.var(axis=0)
        assert np.all(np.abs(rho) < 4 / math.sqrt(n))


@pytest.mark.sweep   # 20 000 samples (4 000 s at 5 Hz): ~3.5 s
def test_acoustic_fix_rate_and_dropouts():
    profile = load_sensor_profile("baseline")  # 1 Hz, 10 % dropouts
    suite = SensorSuite(profile, RandomStreams(1))
    state = np.zeros(12)
    fixes = [suite.measure(0.2 * k, state).position for k in range(5 * 4000)]  # 4000 s at 5 Hz
    got = [f.value for f in fixes if f.valid]
    assert all(not f.valid for k, f in enumerate(fixes) if k % 5)  # only on the 1 Hz instants
    assert len(got) / 4000 == pytest.approx(0.9, abs=0.02)
    assert np.std(np.array(got)) == pytest.approx(0.5, rel=0.05)


def test_ideal_profile_is_exact_and_altitude_is_slant_range():
    suite = SensorSuite(load_sensor_profile("ideal"), RandomStreams(0), Seabed("flat", 80.0))
    state = np.zeros(12)
    state[2], state[3] = 30.0, math.radians(10.0)
    m = suite.measure(0.0, state)
    np.testing.assert_array_equal(m.velocity.value, state[6:9])
    assert m.depth.value == 30.0 and m.depth.stamp == 0.0
    assert m.altitude.value == pytest.approx(50.0 / math.cos(math.radians(10.0)))
    np.testing.assert_allclose(m.position.value, state[:3])
    # beyond the altimeter's range (200 m) or with the seabed above: no reading
    deep = SensorSuite(load_sensor_profile("ideal"), RandomStreams(0), Seabed("flat", 400.0))
    assert not deep.measure(0.0, state).altitude.valid
    assert not SensorSuite(load_sensor_profile("ideal"), RandomStreams(0), Seabed("flat", 20.0)).measure(
        0.0, state).altitude.valid


def test_strapdown_gravity_leak_matches_haslar():
    """App. A.3: a 0.1 deg roll error gives a 0.17 m/s sway error after 10 s."""
    profile = load_sensor_profile("haslar")
    sd = dict(profile.strapdown, enabled=True, bias_random_walk=0.0, accel_std=0.0)
    suite = SensorSuite(replace(profile, strapdown=sd), RandomStreams(0))
    state = np.zeros(12)  # at rest, level
    force = specific_force(state, np.zeros(3), 9.81)
    for k in range(101):
        m = suite.measure(0.1 * k, state, force)
    assert abs(m.velocity.value[1]) == pytest.approx(9.81 * math.sin(math.radians(0.1)) * 10.0, rel=1e-6)
    assert abs(m.velocity.value[1]) == pytest.approx(0.17, abs=0.005)
    with pytest.raises(ValueError, match="specific force"):
        suite.measure(11.0, state)


def test_switching_to_a_strapdown_profile_takes_effect():
    """The strapdown mode is read from the profile at every reading, not cached."""
    haslar = load_sensor_profile("haslar")
    strap = replace(haslar, strapdown=dict(haslar.strapdown, enabled=True, bias_random_walk=0.0, accel_std=0.0))
    suite = SensorSuite(load_sensor_profile("ideal"), RandomStreams(0))
    state = np.zeros(12)
    force = specific_force(state, np.zeros(3), 9.81)
    assert suite.measure(0.0, state, force).velocity.value[1] == 0.0
    suite.profile = strap
    for k in range(1, 102):
        m = suite.measure(0.1 * k, state, force)
    assert abs(m.velocity.value[1]) == pytest.approx(0.17, abs=0.005)  # the gravity leak: strapdown is on
    suite.profile = load_sensor_profile("ideal")
    assert suite.measure(20.0, state, force).velocity.value[1] == 0.0  # and off again


def test_angles_wrap_and_variances_are_squared_standard_deviations():
    profile = load_sensor_profile("baseline")
    suite = SensorSuite(profile, RandomStreams(4), Seabed("flat", 80.0))
    state = np.zeros(12)
    state[3], state[5] = math.pi - 1e-4, -math.pi + 1e-4   # roll and yaw at the wrap
    psi = np.array([suite.measure(0.2 * k, state).attitude.value[2] for k in range(500)])
    assert np.all(np.abs(psi) <= math.pi)
    assert np.any(psi > 0) and np.any(psi < 0)  # noise crosses the wrap: both ends appear
    m = suite.measure(100.0, state)
    assert m.depth.variance == pytest.approx(profile.depth_std ** 2)
    np.testing.assert_allclose(m.velocity.variance, np.square(profile.velocity_std))
    np.testing.assert_allclose(m.rates.variance, np.square(profile.rate_std))


def test_each_instrument_has_its_own_random_stream():
    """More noise on one instrument leaves the others' draws unchanged."""
    base = load_sensor_profile("baseline")
    noisy = replace(base, velocity_std=(1.0, 1.0, 1.0), position_dropout=0.5)
    state = np.zeros(12)
    a = [SensorSuite(p, RandomStreams(8), Seabed("flat", 80.0)).measure(0.0, state) for p in (base, noisy)]
    np.testing.assert_array_equal(a[0].rates.value, a[1].rates.value)
    np.testing.assert_array_equal(a[0].attitude.value, a[1].attitude.value)
    assert a[0].depth.value == a[1].depth.value
    assert not np.array_equal(a[0].velocity.value, a[1].velocity.value)


def test_bad_profiles_are_refused():
    from seapup_sim.sensors import SensorProfile
    with pytest.raises(ValueError):
        SensorProfile("x", velocity_std=(-1.0, 0.0, 0.0))
    with pytest.raises(ValueError):
        SensorProfile("x", position_rate_hz=2.0)
    with pytest.raises(TypeError):
        SensorSuite(SensorProfile("x"), np.random.default_rng(0))
