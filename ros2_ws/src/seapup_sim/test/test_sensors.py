"""Tests of seapup_sim.sensors: noise statistics match the profiles over long runs."""
import math

import numpy as np
import pytest

from seapup_sim.seabed import Seabed
from seapup_sim.sensors import SensorSuite, load_sensor_profile, sensor_profiles

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


@pytest.mark.parametrize("name", ["baseline", "haslar"])
def test_long_run_noise_statistics(name):
    profile = load_sensor_profile(name)
    suite = SensorSuite(profile, np.random.default_rng(5), Seabed("flat", 80.0))
    state = np.array([1.0, 2.0, 30.0, 0.1, -0.05, 1.0, 0.5, 0.1, -0.05, 0.01, 0.02, 0.03])
    n = 20000
    vel, rates, att = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    for k in range(n):
        m = suite.measure(0.2 * k, state)
        vel[k], rates[k], att[k] = m["velocity"], m["rates"], m["attitude"]
    for data, truth, std in ((vel, state[6:9], profile.velocity_std), (rates, state[9:], profile.rate_std),
                             (att, state[3:6], profile.attitude_std)):
        np.testing.assert_allclose(data.mean(axis=0), truth, atol=5 * np.max(std) / math.sqrt(n))
        np.testing.assert_allclose(data.std(axis=0), std, rtol=0.03)
        # white: no correlation between successive samples
        x = data - data.mean(axis=0)
        rho = (x[1:] * x[:-1]).mean(axis=0) / x.var(axis=0)
        assert np.all(np.abs(rho) < 4 / math.sqrt(n))


def test_acoustic_fix_rate_and_dropouts():
    profile = load_sensor_profile("baseline")  # 1 Hz, 10 % dropouts
    suite = SensorSuite(profile, np.random.default_rng(1))
    state = np.zeros(12)
    fixes = [suite.measure(0.2 * k, state)["position"] for k in range(5 * 4000)]  # 4000 s at 5 Hz
    got = [f for f in fixes if f is not None]
    assert all(f is None for k, f in enumerate(fixes) if k % 5)  # only on the 1 Hz instants
    assert len(got) / 4000 == pytest.approx(0.9, abs=0.02)
    assert np.std(np.array(got)) == pytest.approx(0.5, rel=0.05)


def test_ideal_profile_is_exact_and_altitude_is_slant_range():
    suite = SensorSuite(load_sensor_profile("ideal"), np.random.default_rng(0), Seabed("flat", 80.0))
    state = np.zeros(12)
    state[2], state[3] = 30.0, math.radians(10.0)
    m = suite.measure(0.0, state)
    np.testing.assert_array_equal(m["velocity"], state[6:9])
    assert m["depth"] == 30.0
    assert m["altitude"] == pytest.approx(50.0 / math.cos(math.radians(10.0)))
    np.testing.assert_allclose(m["position"], state[:3])


def test_strapdown_gravity_leak_matches_haslar():
    """App. A.3: a 0.1 deg roll error gives a 0.17 m/s sway error after 10 s."""
    profile = load_sensor_profile("haslar")
    sd = dict(profile.strapdown, enabled=True, bias_random_walk=0.0, accel_std=0.0)
    from dataclasses import replace
    suite = SensorSuite(replace(profile, strapdown=sd), np.random.default_rng(0))
    state = np.zeros(12)  # at rest, level
    for k in range(101):
        m = suite.measure(0.1 * k, state, accel_body=np.zeros(3))
    assert abs(m["velocity"][1]) == pytest.approx(9.81 * math.sin(math.radians(0.1)) * 10.0, rel=1e-6)
    assert abs(m["velocity"][1]) == pytest.approx(0.17, abs=0.005)
    with pytest.raises(ValueError, match="body accelerations"):
        suite.measure(11.0, state)


def test_bad_profiles_are_refused():
    from seapup_sim.sensors import SensorProfile
    with pytest.raises(ValueError):
        SensorProfile("x", velocity_std=(-1.0, 0.0, 0.0))
    with pytest.raises(ValueError):
        SensorProfile("x", position_rate_hz=2.0)
    with pytest.raises(TypeError):
        SensorSuite(SensorProfile("x"), rng=None)
