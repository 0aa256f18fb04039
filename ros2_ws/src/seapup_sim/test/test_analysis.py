"""Tests of seapup_sim.analysis against systems with known answers."""
import math

import numpy as np
import pytest
import scipy.signal

from seapup_sim.analysis import linearise, output_matrix, system_zeros, transmission_zeros, trim
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config


def test_textbook_mimo_zero():
    # Skogestad & Postlethwaite ex. 4.11: G(s) = [[s-1, 4], [4.5, 2(s-1)]] / (s+2) has a
    # RHP transmission zero at s = 4. This 2-state realisation is not minimal:
    # C is singular, so one pole at -2 is unobservable and appears as an
    # output-decoupling zero of the system matrix.
    a = -2.0 * np.eye(2)
    b = np.eye(2)
    c = np.array([[-3.0, 4.0], [4.5, -6.0]])
    d = np.diag([1.0, 2.0])
    np.testing.assert_allclose(transmission_zeros(a, b, c, d), [4.0], atol=1e-9)
    kinds = {round(z.value.real, 9): z.kind for z in system_zeros(a, b, c, d)}
    assert kinds == {-2.0: "output-decoupling", 4.0: "transmission"}


def test_siso_zero_matches_scipy():
    num, den = [1.0, 2.0], np.polymul([1.0, 1.0], [1.0, 3.0])
    a, b, c, d = scipy.signal.tf2ss(num, den)
    np.testing.assert_allclose(transmission_zeros(a, b, c, d), [-2.0], atol=1e-9)


def test_decoupling_zeros_are_classified():
    # state 3 is an uncontrollable mode at -5 (input-decoupling), state 4 an
    # unobservable mode at -7 (output-decoupling), state 1-2 a minimum-phase plant
    a = np.diag([-1.0, -3.0, -5.0, -7.0])
    b = np.array([[1.0], [1.0], [0.0], [1.0]])
    c = np.array([[1.0, 1.0, 1.0, 0.0]])
    kinds = {round(z.value.real, 6): z.kind for z in system_zeros(a, b, c)}
    assert kinds[-5.0] == "input-decoupling"
    assert kinds[-7.0] == "output-decoupling"
    assert kinds[-2.0] == "transmission"  # 1/(s+1) + 1/(s+3) = (2s+4)/((s+1)(s+3))


def test_eq_3_3_is_fourth_order_and_matches_the_model():
    model = VehicleModel(load_vehicle_config("baseline"))
    hover = trim(model, 0.0)
    # every velocity non-zero: terms like N_r|r| have a kink at r = 0 where any
    # finite-difference stencil is biased by O(h)
    x = hover.state.copy()
    x[3:] = [0.05, 0.2, 0.3, 0.4, -0.05, 0.1, 0.03, -0.02, 0.04]
    a1, b1 = linearise(model, x, hover.blade_pitch, h_state=np.full(12, 1e-3), h_input=np.full(4, 1e-3))
    a2, b2 = linearise(model, x, hover.blade_pitch, h_state=np.full(12, 2e-3), h_input=np.full(4, 2e-3))
    # an independent second-order central difference with a tiny step
    h = 1e-6
    a_ref = np.column_stack([(model.derivatives(x + h * e, hover.blade_pitch)
                              - model.derivatives(x - h * e, hover.blade_pitch)) / (2 * h)
                             for e in np.eye(12)])
    assert np.abs(a1 - a_ref).max() < 1e-6
    # halving h shrinks the truncation error ~16x (it is already tiny here)
    assert np.abs(a1 - a_ref).max() <= np.abs(a2 - a_ref).max() + 1e-9
    assert np.all(np.isfinite(b1)) and np.abs(b1 - b2).max() < 1e-6


def test_four_zero_eigenvalues_and_output_decoupling_zeros_at_rest():
    """Sec. 3.2/3.7: X, Y, Z, psi integrate u, v, w, r: four poles and four
    output-decoupling zeros at 0; 16 generalised eigenvalues, 8 at infinity."""
    model = VehicleModel(load_vehicle_config("baseline"))
    hover = trim(model, 0.0)
    a, b = linearise(model, hover.state, hover.blade_pitch)
    ev = np.linalg.eigvals(a)
    assert np.sum(np.abs(ev) < 1e-6) == 4
    zeros = system_zeros(a, b, output_matrix())
    at_zero = [z for z in zeros if abs(z.value) < 1e-6]
    assert len(at_zero) == 4 and all(z.output_decoupling for z in at_zero)
    assert len(zeros) == 8  # 16 - 8 infinite


def test_trim_is_an_equilibrium_and_hover_matches_eq_5_2():
    model = VehicleModel(load_vehicle_config("baseline"))
    hover = trim(model, 0.0)
    np.testing.assert_allclose(np.degrees(hover.blade_pitch), [-3.383, -3.383, -13.098, -13.098], atol=0.01)
    tr = trim(model, 0.5)
    assert np.abs(model.derivatives(tr.state, tr.blade_pitch)[6:]).max() < 1e-7
    assert tr.state[6] == 0.5 and math.isfinite(tr.pitch_angle)
