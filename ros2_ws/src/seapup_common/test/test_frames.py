"""Tests of seapup_common.frames: NED/FRD <-> ENU/FLU (REP-103/105, REP-156 draft)."""
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from seapup_common.frames import (covariance6_to_enu_flu, euler_through_quaternion, euler_to_quaternion, frd_to_flu,
                               ned_to_enu, orientation_ned_frd_to_enu_flu, quaternion_to_euler)
from seapup_sim.vehicle import rotation_body_to_ned


def test_quaternion_is_the_vehicle_rotation_matrix():
    rng = np.random.default_rng(0)
    for _ in range(50):
        phi, theta, psi = rng.uniform(-1.4, 1.4, 3)
        q = euler_to_quaternion(phi, theta, psi)
        np.testing.assert_allclose(Rotation.from_quat(q).as_matrix(), rotation_body_to_ned(phi, theta, psi),
                                   atol=1e-12)
        np.testing.assert_allclose(quaternion_to_euler(q), [phi, theta, psi], atol=1e-12)


def test_the_hand_written_quaternions_agree_with_scipy_everywhere():
    """The conversions are written out (no scipy.spatial import in every node): scipy's Rotation is the
    oracle over the whole sphere, at gimbal lock and for unnormalised quaternions of either sign."""
    rng = np.random.default_rng(1)
    for _ in range(500):
        euler = rng.uniform([-math.pi, -math.pi / 2, -math.pi], [math.pi, math.pi / 2, math.pi])
        q = euler_to_quaternion(*euler)
        assert q[3] >= 0.0 and np.linalg.norm(q) == pytest.approx(1.0)
        np.testing.assert_allclose(Rotation.from_quat(q).as_matrix(),
                                   Rotation.from_euler("ZYX", euler[::-1]).as_matrix(), atol=1e-12)
        raw = rng.normal(size=4) * rng.uniform(0.1, 10.0)
        back = quaternion_to_euler(raw)
        np.testing.assert_allclose(Rotation.from_euler("ZYX", back[::-1]).as_matrix(),
                                   Rotation.from_quat(raw).as_matrix(), atol=1e-9)
        np.testing.assert_allclose(Rotation.from_quat(orientation_ned_frd_to_enu_flu(raw)).as_matrix(),
                                   np.diag([1.0, 1.0, -1.0])[[1, 0, 2]] @ Rotation.from_quat(raw).as_matrix()
                                   @ np.diag([1.0, -1.0, -1.0]), atol=1e-12)
    for theta in (math.pi / 2, -math.pi / 2):       # gimbal lock: roll and yaw share one axis
        for phi, psi in ((0.0, 0.3), (0.5, -2.0), (-1.0, 3.0)):
            back = quaternion_to_euler(euler_to_quaternion(phi, theta, psi))
            assert back[0] == 0.0 and back[1] == pytest.approx(theta)
            np.testing.assert_allclose(Rotation.from_euler("ZYX", back[::-1]).as_matrix(),
                                       rotation_body_to_ned(phi, theta, psi), atol=1e-9)


def test_known_poses():
    # facing north in NED is yaw +90 deg in ENU (x east, y north)
    q = orientation_ned_frd_to_enu_flu(euler_to_quaternion(0.0, 0.0, 0.0))
    roll, pitch, yaw = quaternion_to_euler(q)
    assert (roll, pitch, yaw) == pytest.approx((0.0, 0.0, math.pi / 2))
    # facing east (NED yaw 90 deg) is ENU yaw 0
    assert quaternion_to_euler(orientation_ned_frd_to_enu_flu(euler_to_quaternion(0, 0, math.pi / 2)))[2] \
        == pytest.approx(0.0, abs=1e-12)
    # bow up is bow up: the forward axis points up in both conventions
    q_up = orientation_ned_frd_to_enu_flu(euler_to_quaternion(0.0, 0.3, 0.0))
    forward_enu = Rotation.from_quat(q_up).apply([1.0, 0.0, 0.0])
    assert forward_enu[2] == pytest.approx(math.sin(0.3))
    np.testing.assert_allclose(ned_to_enu([1.0, 2.0, 3.0]), [2.0, 1.0, -3.0])
    np.testing.assert_allclose(frd_to_flu([1.0, 2.0, 3.0]), [1.0, -2.0, -3.0])


def test_vectors_and_orientation_agree():
    """A body vector mapped to the world gives the same physical vector either way."""
    rng = np.random.default_rng(1)
    for _ in range(50):
        eul = rng.uniform(-1.4, 1.4, 3)
        v_frd = rng.normal(size=3)
        q_ned = euler_to_quaternion(*eul)
        world_ned = Rotation.from_quat(q_ned).apply(v_frd)
        q_enu = orientation_ned_frd_to_enu_flu(q_ned)
        world_enu = Rotation.from_quat(q_enu).apply(frd_to_flu(v_frd))
        np.testing.assert_allclose(world_enu, ned_to_enu(world_ned), atol=1e-12)


def test_covariance_transform():
    cov = np.diag([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    cov[0, 1] = cov[1, 0] = 0.5
    pose = covariance6_to_enu_flu(cov, world_first=True)
    np.testing.assert_allclose(np.diag(pose), [2.0, 1.0, 3.0, 4.0, 5.0, 6.0])
    assert pose[0, 1] == 0.5
    twist = covariance6_to_enu_flu(cov.ravel(), world_first=False)
    assert twist[0, 1] == -0.5 and np.allclose(np.diag(twist), np.diag(cov))


def test_wrap_angle_of_a_number_is_the_array_rule_bit_for_bit():
    """The scalar path (Python's float %) gives numpy's mod exactly, the edges and non-finite values included."""
    from seapup_common.frames import wrap_angle
    rng = np.random.default_rng(7)
    angles = [*rng.uniform(-50.0, 50.0, 5000), *(k * math.pi for k in range(-9, 10)), 0.0, -0.0, 1e-300,
              math.nextafter(math.pi, 0.0), math.nextafter(-math.pi, 0.0), 1e17, -1e17]
    by_array = wrap_angle(np.array(angles))
    for angle, expected in zip(angles, by_array):
        got = wrap_angle(angle)
        assert type(got) is float and (got == expected and math.copysign(1, got) == math.copysign(1, expected)), angle
        assert wrap_angle(np.float64(angle)) == got
    assert wrap_angle(-math.pi) == math.pi and wrap_angle(math.pi) == math.pi
    for bad in (math.nan, math.inf, -math.inf):
        assert math.isnan(wrap_angle(bad))


def test_a_quaternion_that_is_no_rotation_gives_nan_angles_not_an_error():
    """A zero or non-finite quaternion (a hostile bag's odometry) reads as NaN angles, as numpy's 0 / 0 does."""
    for q in ([0.0, 0.0, 0.0, 0.0], [math.nan, 0.0, 0.0, 1.0], [math.inf, 0.0, 0.0, 1.0]):
        assert np.isnan(quaternion_to_euler(q)).all(), q
    with pytest.raises(ValueError):
        quaternion_to_euler([0.0, 0.0, 1.0])


def test_the_float_round_trip_is_the_message_round_trip_bit_for_bit():
    """euler_through_quaternion (the in-process hierarchy's message round trip) gives the bits a receiver gets
    from the array functions: with ``q / np.linalg.norm(q)`` first, as an IMU's reader does, or without, as the
    odometry's and the setpoint's do -- over the sphere, at gimbal lock, at tiny angles and at +-pi."""
    rng = np.random.default_rng(7)
    angles = rng.uniform([-math.pi, -math.pi / 2, -math.pi], [math.pi, math.pi / 2, math.pi], (3000, 3))
    angles[::5, 1] = rng.choice([math.pi / 2, -math.pi / 2, 0.0], len(angles[::5]))
    angles[1::7] *= 1e-9
    angles[2::11] = [math.pi, 0.0, -math.pi]
    differ = 0
    for euler in angles:
        q = euler_to_quaternion(*euler)
        normalised = quaternion_to_euler(q / np.linalg.norm(q))
        plain = quaternion_to_euler(q)
        differ += not np.array_equal(np.array(euler_through_quaternion(*euler)), normalised)
        differ += not np.array_equal(np.array(euler_through_quaternion(*euler, normalise=False)), plain)
    assert differ == 0
    assert euler_through_quaternion(0.1, 0.2, 0.3) == pytest.approx((0.1, 0.2, 0.3), abs=1e-15)


@pytest.mark.unit
def test_the_compiled_round_trip_is_the_float_one_bit_for_bit():
    """seapup_common.compiled_frames (the in-process mission's round trips, compiled) against
    euler_through_quaternion, both ways of normalising: the same bits over the sphere, beyond it (angles a
    simulator may hold unwrapped), at gimbal lock, at tiny angles, at +-pi and for the zero rotation's NaN; and
    rows() is the scalar function row by row."""
    from seapup_common import compiled_frames
    rng = np.random.default_rng(8)
    angles = rng.uniform(-4.0, 4.0, (4000, 3))
    angles[::5, 1] = rng.choice([math.pi / 2, -math.pi / 2, 0.0], len(angles[::5]))
    angles[1::7] *= 1e-9
    angles[2::11] = [math.pi, 0.0, -math.pi]
    angles[3::13, 1] = math.pi / 2 + rng.uniform(-1e-7, 1e-7, len(angles[3::13]))
    angles[4] = [2 * math.pi, 0.0, 0.0]   # w = 0: the sign of the first non-zero component decides
    for normalise in (True, False):
        expected = np.array([euler_through_quaternion(*row, normalise=normalise) for row in angles.tolist()])
        got = np.array([compiled_frames.euler_through_quaternion(*row, normalise) for row in angles.tolist()])
        np.testing.assert_array_equal(got, expected)
        np.testing.assert_array_equal(compiled_frames.rows(angles, normalise), expected)
    # a genuine round trip: small angles come back, a yaw beyond pi comes back wrapped
    np.testing.assert_allclose(compiled_frames.rows(np.array([[0.1, 0.2, 0.3], [0.1, -0.2, 3.5]]), True),
                               [[0.1, 0.2, 0.3], [0.1, -0.2, 3.5 - 2 * math.pi]], atol=1e-14)
