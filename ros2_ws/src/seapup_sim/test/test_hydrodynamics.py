"""Tests of seapup_sim.hydrodynamics: SNAME names parse to the right products."""
import numpy as np
import pytest

from seapup_sim.hydrodynamics import HydroTable, HydroTermError, parse_term

NU = np.array([0.5, -0.3, 0.2, -0.1, 0.4, -0.6])
u, v, w, p, q, r = NU


@pytest.mark.parametrize("name,axis,expected", [
    ("X_u|u|", 0, u * abs(u)),
    ("X_u", 0, u),
    ("Z_uu", 2, u * u),
    ("M_|w|q", 4, abs(w) * q),
    ("L_vp", 3, v * p),           # L is the thesis's name for the roll moment K
    ("K_v|v|", 3, v * abs(v)),
    ("X_vrr", 0, v * r * r),
    ("N_|u|r", 5, abs(u) * r),
    ("Y_|v||r|", 1, abs(v) * abs(r)),
])
def test_term_value_is_the_product_its_name_spells(name, axis, expected):
    term = parse_term(name, 2.5)
    assert term.axis == axis
    assert term.evaluate(NU) == pytest.approx(2.5 * expected)


@pytest.mark.parametrize("name", ["Q_u", "X_", "X_uz", "Xu", "X_|u", "X_u||", "X_ u"])
def test_malformed_names_are_refused(name):
    with pytest.raises(HydroTermError):
        parse_term(name, 1.0)


def test_non_finite_coefficient_is_refused():
    with pytest.raises(HydroTermError, match="not finite"):
        parse_term("X_u", float("nan"))


def test_table_sums_terms_per_axis_like_a_loop():
    coefs = {"X_u|u|": -90.0, "X_u": -5.0, "Z_uu": -40.0, "M_|w|q": -3.0, "M_u|u|": 28.0,
             "K_v|v|": 20.0, "N_r|r|": -10.0, "Y_vrr": 7.0}
    table = HydroTable(coefs)
    rng = np.random.default_rng(0)
    for _ in range(50):
        nu = rng.normal(size=6)
        expected = np.zeros(6)
        for t in table.terms:
            expected[t.axis] += t.evaluate(nu)
        np.testing.assert_allclose(table.forces(nu), expected, rtol=1e-12, atol=1e-12)


def test_duplicates_and_empty_table():
    assert np.all(HydroTable({}).forces(NU) == 0.0)
    with pytest.raises(HydroTermError, match="duplicate"):
        HydroTable({"K_p": 1.0, "L_p": 2.0})
