"""Tests of seapup_sim.model_check: the shipped model is clean; broken ones are caught."""
import copy

import numpy as np
import pytest

from seapup_sim.model_check import check_model
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config

SPEEDS = [0.0, 0.3, 0.6]


def broken(edit):
    cfg = copy.deepcopy(load_vehicle_config("baseline"))
    edit(cfg)
    return check_model(VehicleModel(cfg), speeds=SPEEDS)


@pytest.mark.parametrize("name", ["baseline", "camera"])
def test_shipped_configurations_have_no_findings(name):
    report = check_model(VehicleModel(load_vehicle_config(name)))
    assert report.ok, [f.message for f in report.findings]
    assert len(report.sweep) == 11 and max(w for _, w in report.sweep) <= 1e-6


def test_positive_m_absw_q_is_a_negative_damper():
    # the term the thesis removed first (sec. 3.5)
    report = broken(lambda c: c["hydrodynamics"].update({"M_|w|q": 50.0}))
    assert [f.where for f in report.by_kind("negative-damping")] == ["M_|w|q"]


def test_negative_m_absw_q_is_fine():
    report = broken(lambda c: c["hydrodynamics"].update({"M_|w|q": -50.0}))
    assert not report.by_kind("negative-damping")


@pytest.mark.parametrize("term", ["X_r", "X_vrr", "X_vpp", "X_pq", "X_qr", "Y_vp", "Z_ur", "Z_vrr",
                                  "Z_pq", "L_vvw", "L_vp", "M_ur", "M_vvr", "M_vrr", "M_p", "M_qr",
                                  "N_vp"])
def test_every_term_the_thesis_removed_breaks_symmetry(term):
    report = broken(lambda c: c["hydrodynamics"].update({term: 1.0}))
    assert term in [f.where for f in report.by_kind("symmetry")]


@pytest.mark.parametrize("term", ["X_vv", "Z_ww", "M_u|u|", "Y_ur", "N_v", "K_v|v|", "M_pp", "N_uvw",
                                  "X_|v|", "Z_|r|", "Y_v|r|"])
def test_symmetric_terms_pass(term):
    report = broken(lambda c: c["hydrodynamics"].update({term: -1.0}))
    assert term not in [f.where for f in report.findings]


def test_asymmetric_mass_matrix_is_reported():
    def edit(c):
        c["added_mass"][0][4] = 5.0   # X_qdot without M_udot
    report = broken(edit)
    assert any(f.where == "added-mass matrix" for f in report.by_kind("mass-asymmetry"))


def test_thruster_asymmetry_is_reported():
    def edit(c):
        c["thrusters"]["installation"][0][0] = 0.3  # port main weaker than starboard
    report = broken(edit)
    wheres = [f.where for f in report.by_kind("symmetry")]
    assert "thrusters" in wheres and "linearised model at hover" in wheres


def test_instability_at_speed_is_reported():
    # roll damping that turns negative with speed: stable at rest, not when moving
    report = broken(lambda c: c["hydrodynamics"].update({"K_|u|p": 40.0}))
    unstable = report.by_kind("instability")
    assert [f.where for f in unstable] == ["u = 0.30 m/s", "u = 0.60 m/s"]
    assert report.sweep[0][1] <= 1e-9 < report.sweep[-1][1]
    # K_|u|p > 0 always has the sign of p: the term itself is flagged too
    assert [f.where for f in report.by_kind("negative-damping")] == ["K_|u|p"]
