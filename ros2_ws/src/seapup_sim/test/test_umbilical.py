"""Tests of seapup_sim.umbilical: the closed form against independent solutions."""
import math

import numpy as np
import pytest

from dataclasses import replace

from seapup_sim.environment_config import load_environment
from seapup_sim.umbilical import (Umbilical, UmbilicalError, UmbilicalParams, shedding_frequency,
                                  solve_cable, solve_numeric, strumming_drag_coefficient,
                                  wake_stability_parameter)

P = load_environment().umbilical.params  # the thesis's cable: 2.5 cm, C_D 2.5, weightless, L = 1.4 x chord
VEHICLE = np.array([0.0, 0.0, 50.0])
SHIP = np.zeros(3)


@pytest.mark.parametrize("flow", [[-0.47, 0.0, 0.0], [-0.3, 0.2, 0.05], [0.1, -0.4, 0.0], [0.0, 0.3, -0.1]])
def test_closed_form_matches_numerical_integration_of_the_3d_odes(flow):
    closed = solve_cable(VEHICLE, SHIP, 70.0, flow, P)
    force, s, r, f = solve_numeric(VEHICLE, SHIP, 70.0, flow, P)
    np.testing.assert_allclose(closed.force_on_vehicle, force, rtol=1e-6, atol=1e-6)
    # the whole shape, not only the end force
    shape = closed.shape(len(s))
    np.testing.assert_allclose(shape, r, atol=1e-5)
    # tension is constant along a weightless cable with normal loading only
    tension = np.linalg.norm(f, axis=1)
    assert np.ptp(tension) < 1e-6 * tension.mean()
    assert closed.tension == pytest.approx(tension.mean(), rel=1e-6)


def test_force_balance_of_the_returned_shape():
    """The distributed load integrated along the shape equals F(L) - F(0)."""
    flow = np.array([-0.4, 0.1, 0.0])
    sol = solve_cable(VEHICLE, SHIP, 70.0, flow, P)
    pts = sol.shape(4001)
    tau = np.gradient(pts, axis=0)
    tau /= np.linalg.norm(tau, axis=1, keepdims=True)
    un = flow - (tau @ flow)[:, None] * tau
    q = P.k * np.linalg.norm(un, axis=1)[:, None] * un
    ds = sol.length / (len(pts) - 1)
    load = np.trapezoid(q, dx=ds, axis=0)
    f0 = sol.force_on_vehicle
    f_l = sol.tension * tau[-1]
    np.testing.assert_allclose(f_l - f0, -load, rtol=2e-3, atol=1e-2)
    # and the shape ends at the ship with the given length
    assert np.linalg.norm(pts[-1] - SHIP) < 1e-9
    assert np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)) == pytest.approx(70.0, rel=1e-5)


def test_zero_flow_weighted_cable_is_a_catenary():
    """No flow, weight w: the numerical solver reproduces the catenary's tension."""
    params = replace(P, weight_per_length=2.0)
    span, length = 40.0, 50.0
    a_end, b_end = np.array([0.0, 0.0, 10.0]), np.array([span, 0.0, 10.0])
    # catenary: L = 2 a sinh(S / 2a), horizontal tension H = w a, sag = a (cosh(S/2a) - 1)
    from scipy.optimize import brentq
    a = brentq(lambda a: 2 * a * math.sinh(span / (2 * a)) - length, 1.0, 1e4)
    force, s, r, f = solve_numeric(a_end, b_end, length, [0.0, 0.0, 0.0], params,
                                   force_guess=np.array([20.0, 0.0, -50.0]))
    assert force[0] == pytest.approx(2.0 * a, rel=1e-6)            # horizontal tension
    assert force[2] == pytest.approx(2.0 * length / 2, rel=1e-6)     # each end carries half the weight (down, +z NED)
    assert r[:, 2].max() - 10.0 == pytest.approx(a * (math.cosh(span / (2 * a)) - 1), rel=1e-4)


def test_nearly_taut_cable_tends_to_the_straight_line():
    sol = solve_cable(VEHICLE, SHIP, 50.0 * 1.0001, [-0.5, 0.0, 0.0], P)
    direction = sol.force_on_vehicle / np.linalg.norm(sol.force_on_vehicle)
    np.testing.assert_allclose(direction, [0.0, 0.0, -1.0], atol=0.03)
    assert sol.tension > 50 * solve_cable(VEHICLE, SHIP, 70.0, [-0.5, 0.0, 0.0], P).tension


def test_force_scales_with_flow_speed_squared():
    f1 = solve_cable(VEHICLE, SHIP, 70.0, [-0.2, 0.0, 0.0], P).force_on_vehicle
    f2 = solve_cable(VEHICLE, SHIP, 70.0, [-0.4, 0.0, 0.0], P).force_on_vehicle
    np.testing.assert_allclose(f2, 4.0 * f1, rtol=1e-9)


def test_bypass_when_loading_is_too_small_for_the_assumptions(caplog):
    assert solve_cable(VEHICLE, SHIP, 70.0, [0.001, 0.0, 0.0], P).bypassed.startswith("relative flow")
    heavy = replace(P, weight_per_length=10.0)
    sol = solve_cable(VEHICLE, SHIP, 70.0, [-0.3, 0.0, 0.0], heavy)  # w / K U^2 = 10 / 3.5 > 0.1
    assert sol.bypassed.startswith("weight/hydrodynamic") and not np.any(sol.force_on_vehicle)
    assert "parallel" in solve_cable(VEHICLE, SHIP, 70.0, [0.0, 0.0, 0.3], P).bypassed
    cable = Umbilical(P, SHIP)
    import logging
    with caplog.at_level(logging.INFO, logger="seapup_sim.umbilical"):
        cable.solve(np.concatenate([VEHICLE, np.zeros(9)]))
    assert "umbilical bypassed" in caplog.text


def test_cable_shorter_than_the_distance_is_an_error():
    with pytest.raises(UmbilicalError, match="shorter than the distance"):
        solve_cable(VEHICLE, SHIP, 40.0, [-0.3, 0.0, 0.0], P)


def test_strumming_relations():
    assert shedding_frequency(0.5, 0.025) == pytest.approx(4.0)                 # eq. 2.20, S = 0.2
    assert wake_stability_parameter(0.0125, 0.025, 4.0, 2.0) == pytest.approx(4.0)  # eq. 2.21
    assert strumming_drag_coefficient(1.2, 1.0) == pytest.approx(1.2)            # no strumming
    # eq. 2.22 spans 1.0-3.0 C_D0 "for relevant W_r values" (sec. 2.3.4): W_r ~ 4.6 gives 3
    assert strumming_drag_coefficient(1.0, 1.0 + (2.0 / 1.16) ** (1 / 0.65)) == pytest.approx(3.0)
    with pytest.raises(ValueError):
        strumming_drag_coefficient(1.0, 0.5)


def test_vehicle_wrench_is_the_body_axis_force_at_the_attachment():
    params = replace(P, attachment=(0.1, 0.0, -0.2))
    cable = Umbilical(params, SHIP)
    state = np.zeros(12)
    state[2], state[4], state[6] = 50.0, 0.2, 0.5
    w = cable.wrench(state)
    from seapup_sim.vehicle import rotation_body_to_ned
    f_ned = rotation_body_to_ned(0, 0.2, 0) @ w[:3]
    np.testing.assert_allclose(f_ned, cable.solution.force_on_vehicle, atol=1e-9)
    np.testing.assert_allclose(w[3:], np.cross([0.1, 0.0, -0.2], w[:3]), atol=1e-12)
    assert cable.solution.length == pytest.approx(1.4 * np.linalg.norm(
        state[:3] + rotation_body_to_ned(0, 0.2, 0) @ np.array([0.1, 0.0, -0.2])))


def test_the_drawn_cable_runs_from_the_vehicle_s_attachment_to_the_ship_with_the_solved_length():
    from seapup_sim.vehicle import rotation_body_to_ned
    params = replace(P, attachment=(0.1, 0.0, -0.2))
    cable = Umbilical(params, SHIP)
    state = np.zeros(12)
    state[2], state[5] = 50.0, 0.4
    end = state[:3] + rotation_body_to_ned(0.0, 0.0, 0.4) @ np.array([0.1, 0.0, -0.2])
    straight = cable.shape(state, 11)   # nothing solved yet: the chord
    np.testing.assert_allclose(straight[[0, -1]], [end, SHIP], atol=1e-12)
    cable.wrench(state, current_ned=[0.5, 0.0, 0.0])   # a current: the cable bows (eq. 2.25-2.27)
    bowed = cable.shape(state, 400)
    np.testing.assert_allclose(bowed[[0, -1]], [end, SHIP], atol=1e-6)   # its end conditions
    arc = np.sum(np.linalg.norm(np.diff(bowed, axis=0), axis=1))
    assert arc == pytest.approx(cable.solution.length, rel=1e-4)          # the solved length, 1.4 x the chord
    assert arc > 1.3 * np.linalg.norm(end - SHIP)
    with pytest.raises(ValueError):
        cable.shape(state, 1)
