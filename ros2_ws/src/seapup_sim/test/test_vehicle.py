"""Tests of seapup_sim.vehicle against physics that does not depend on the model's data.

- energy and generalised momentum are conserved with hydrodynamics, thrusters
  and hydrostatics removed (Kirchhoff's equations of a body in ideal fluid);
- the hydrostatic restoring moment equals -BG B g sin(angle);
- payload composition reproduces the CG/CB shifts the thesis gives (sec. 3.6);
- kinematics: the rotation matrix is orthonormal and the Euler-rate matrix
  inverts the body-rate map.
"""
import copy
import math

import numpy as np
import pytest

from seapup_sim.integrator import VehicleIntegrator
from seapup_sim.vehicle import (VehicleModel, cross, euler_rate_matrix, rotation_body_to_ned,
                                skew)
from seapup_sim.vehicle_config import load_vehicle_config
from seapup_sim.verification import rest_trim


def ideal_fluid_config(cg=(0.05, 0.0, 0.1)):
    """Baseline mass data, but no hydrodynamic terms, W = B at the same point."""
    cfg = copy.deepcopy(load_vehicle_config("baseline"))
    cfg["hydrodynamics"] = {}
    cfg["rigid_body"]["buoyancy_mass"] = cfg["rigid_body"]["mass"]
    cfg["rigid_body"]["cg"] = list(cg)
    cfg["rigid_body"]["cb"] = list(cg)
    cfg["rigid_body"]["inertia_cg"] = [[6.0, 0.0, -0.4], [0.0, 15.0, 0.0], [-0.4, 0.0, 14.0]]
    return cfg


def world_impulse(model, state):
    """Linear impulse of body + fluid in world axes: R (M11 v + M12 w)."""
    m = model.m_total
    p_body = m[:3, :3] @ state[6:9] + m[:3, 3:] @ state[9:]
    return rotation_body_to_ned(*state[3:6]) @ p_body


def test_kinetic_energy_and_impulse_are_conserved_in_ideal_fluid():
    model = VehicleModel(ideal_fluid_config())
    x0 = np.zeros(12)
    x0[6:] = [0.4, -0.2, 0.1, 0.15, -0.1, 0.5]
    sim = VehicleIntegrator(model, dt=0.01, state=x0)
    sim.thrusters_on = False
    energy0 = 0.5 * x0[6:] @ model.m_total @ x0[6:]
    impulse0 = world_impulse(model, x0)
    for _ in range(1000):  # 10 s of tumbling
        sim.step(np.zeros(4))
    x = sim.state
    assert abs(0.5 * x[6:] @ model.m_total @ x[6:] - energy0) / energy0 < 1e-7
    np.testing.assert_allclose(world_impulse(model, x), impulse0, atol=1e-7)
    assert np.abs(x[9:]).max() > 0.1  # it really did rotate


def test_rigid_coriolis_equals_eq_2_8_and_2_17a_written_out():
    """The Kirchhoff form equals the thesis's component equations about an arbitrary origin."""
    model = VehicleModel(ideal_fluid_config(cg=(0.07, -0.02, 0.11)))
    m = model.mass_properties.mass
    x, y, z = model.mass_properties.cg
    inertia = model.mass_properties.inertia_origin
    rng = np.random.default_rng(4)
    for _ in range(20):
        u, v, w, p, q, r = rng.normal(size=6)
        # eq. 2.8 (velocity terms, moved to the right-hand side)
        fx = -m * ((q * w - r * v) - x * (q * q + r * r) + y * (p * q) + z * (p * r))
        fy = -m * ((r * u - p * w) - y * (p * p + r * r) + z * (q * r) + x * (q * p))
        fz = -m * ((p * v - q * u) - z * (p * p + q * q) + x * (r * p) + y * (r * q))
        # eq. 2.17a (velocity terms): h = I w about the origin
        hx, hy, hz = inertia @ np.array([p, q, r])
        gx = -((q * hz - r * hy) + m * (y * (p * v - q * u) - z * (r * u - p * w)))
        gy = -((r * hx - p * hz) + m * (z * (q * w - r * v) - x * (p * v - q * u)))
        gz = -((p * hy - q * hx) + m * (x * (r * u - p * w) - y * (q * w - r * v)))
        np.testing.assert_allclose(model.rigid_coriolis(np.array([u, v, w, p, q, r])),
                                   [fx, fy, fz, gx, gy, gz], rtol=1e-10, atol=1e-10)


def test_coriolis_terms_do_no_work():
    model = VehicleModel(ideal_fluid_config())
    rng = np.random.default_rng(1)
    for _ in range(20):
        nu = rng.normal(size=6)
        assert abs(nu @ model.rigid_coriolis(nu)) < 1e-10
        assert abs(nu @ model.added_mass_coriolis(nu)) < 1e-10


@pytest.mark.parametrize("angle", [0.1, 0.4, -0.7, 1.2])
def test_hydrostatic_moment_is_bg_times_buoyancy_sin_angle(angle):
    model = VehicleModel(load_vehicle_config("baseline"))
    bg = model.mass_properties.cg[2] - model.mass_properties.cb[2]
    assert bg == pytest.approx(0.05271317829457364)
    roll = model.hydrostatics(angle, 0.0)
    pitch = model.hydrostatics(0.0, angle)
    b = model.buoyancy  # origin at the CG: only buoyancy has an arm
    assert roll[3] == pytest.approx(-bg * b * math.sin(angle), rel=1e-12)
    assert pitch[4] == pytest.approx(-bg * b * math.sin(angle), rel=1e-12)
    # net vertical force is the weight in water, tilted with the body
    assert roll[2] == pytest.approx((model.weight - model.buoyancy) * math.cos(angle), rel=1e-12)


def test_camera_payload_shifts_cg_and_cb_as_the_thesis_says():
    base = VehicleModel(load_vehicle_config("baseline"))
    cam = VehicleModel(load_vehicle_config("camera"))
    np.testing.assert_allclose(cam.mass_properties.cg - base.mass_properties.cg, [0.046, 0.0, 0.014], atol=1e-12)
    np.testing.assert_allclose(cam.mass_properties.cb - base.mass_properties.cb, [0.043, 0.0, 0.019], atol=1e-12)
    assert cam.mass_properties.mass == pytest.approx(125.0)
    # added mass of a sphere is rho V / 2, so the total grows by that on the diagonal
    sphere = 0.5 * 1025.0 * 4.0 / 3.0 * math.pi * 0.1465009467420094 ** 3
    np.testing.assert_allclose(np.diag(cam.m_added - base.m_added)[:3], sphere, rtol=1e-12)
    assert sphere == pytest.approx(13.5 / 2)
    # the offset couples roll and yaw: "N_p and L_r ... become nonzero" (sec. 3.6)
    assert cam.m_added[3, 5] != 0.0 and cam.m_added[3, 5] == cam.m_added[5, 3]
    assert math.degrees(rest_trim(base)) == pytest.approx(0.0, abs=1e-9)
    assert math.degrees(rest_trim(cam)) == pytest.approx(-6.3, abs=1.0)


def test_rotation_and_euler_rate_matrices():
    rng = np.random.default_rng(2)
    for _ in range(20):
        phi, theta, psi = rng.uniform(-1.2, 1.2, 3)
        r = rotation_body_to_ned(phi, theta, psi)
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0)
        # z-y-x composition
        rz = rotation_body_to_ned(0, 0, psi)
        ry = rotation_body_to_ned(0, theta, 0)
        rx = rotation_body_to_ned(phi, 0, 0)
        np.testing.assert_allclose(r, rz @ ry @ rx, atol=1e-12)
        # body rates from Euler rates: w = [phi_dot,0,0] + Rx^T [0,theta_dot,0] + (Ry Rx)^T [0,0,psi_dot]
        eul_dot = rng.normal(size=3)
        w = (np.array([eul_dot[0], 0, 0]) + rx.T @ np.array([0, eul_dot[1], 0])
             + (ry @ rx).T @ np.array([0, 0, eul_dot[2]]))
        np.testing.assert_allclose(euler_rate_matrix(phi, theta) @ w, eul_dot, atol=1e-12)


def test_cross_and_skew_agree_with_numpy():
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=3), rng.normal(size=3)
    np.testing.assert_allclose(cross(a, b), np.cross(a, b), atol=1e-15)
    np.testing.assert_allclose(skew(a) @ b, np.cross(a, b), atol=1e-15)


def test_derivative_of_position_is_world_velocity():
    model = VehicleModel(load_vehicle_config("baseline"))
    x = np.zeros(12)
    x[3:6] = [0.1, -0.2, 1.0]
    x[6:9] = [0.5, 0.1, -0.05]
    xdot = model.derivatives(x, np.zeros(4))
    np.testing.assert_allclose(xdot[:3], rotation_body_to_ned(*x[3:6]) @ x[6:9], atol=1e-14)


def test_current_enters_as_relative_velocity_only():
    """A vehicle drifting with the current feels no hydrodynamic force."""
    model = VehicleModel(load_vehicle_config("baseline"))
    x = np.zeros(12)
    x[5] = 0.7  # heading
    current = np.array([0.3, -0.1, 0.0])
    x[6:9] = rotation_body_to_ned(*x[3:6]).T @ current
    nu_r = model.relative_velocity(x, current)
    np.testing.assert_allclose(nu_r, 0.0, atol=1e-15)
