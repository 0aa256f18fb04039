"""Issue 45: a vehicle of N fixed-pitch thrusters flown through four virtual inputs (seapup_sim.thrusters,
seapup_sim.inputs), and the BlueROV2 Heavy described from von Benzon et al. 2022 ([vB]).

Independent truth: [vB]'s published numbers (Table A1, eq. 18) evaluated here by hand; the wrench of thrusts
summed by hand from positions and directions; the allocation's defining property (the thrusters give the
wrench the inputs ask for, or that wrench scaled down along its direction); the mirror symmetry of a
symmetric frame; Newton's second law for the first sample of a step.
"""
import math

import numpy as np
import pytest

from seapup_common.config import ConfigError
from seapup_sim.analysis import trim
from seapup_sim.integrator import VehicleIntegrator
from seapup_sim.model_check import check_model, thruster_mirror
from seapup_sim.thrusters import FixedPitchThrusters, ThrustCurve
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config

pytestmark = pytest.mark.unit

#: [vB] eq. 18: T(c) = -140.3 c^9 + 389.9 c^7 - 404.1 c^5 + 176.0 c^3 + 8.9 c [N]
def eq18(c):
    c = np.asarray(c, float)
    return -140.3 * c ** 9 + 389.9 * c ** 7 - 404.1 * c ** 5 + 176.0 * c ** 3 + 8.9 * c


@pytest.fixture(scope="module")
def rov():
    return VehicleModel(load_vehicle_config("bluerov2_heavy"))


def test_the_polynomial_curve_is_eq18_where_it_rises_and_its_peak_beyond():
    curve = ThrustCurve(polynomial=[0.0, 8.9, 0.0, 176.0, 0.0, -404.1, 0.0, 389.9, 0.0, -140.3])
    c = np.linspace(-0.9, 0.9, 37)
    np.testing.assert_allclose(curve.thrust(c), eq18(c), rtol=0, atol=1e-9)
    grid = np.linspace(0.0, 1.0, 100001)
    peak = float(eq18(grid).max())   # eq. 18 droops by 0.2 N just short of full command: the peak is kept there
    assert curve.max_forward == pytest.approx(peak, abs=1e-3) and curve.max_reverse == pytest.approx(-peak, abs=1e-3)
    assert curve.thrust(1.0) == pytest.approx(peak, abs=1e-3) and eq18(1.0) < peak - 0.1
    assert np.all(np.diff(curve.thrust(np.linspace(-1, 1, 4001))) >= 0.0)
    thrusts = np.linspace(-30.0, 30.0, 121)
    np.testing.assert_allclose(curve.thrust(curve.command_for(thrusts)), thrusts, atol=1e-9)


def test_a_table_curve_interpolates_and_its_deadband_is_continuous():
    table = [[-1.0, -40.0], [-0.5, -10.0], [0.0, 0.0], [0.5, 12.0], [1.0, 51.0]]   # reverse weaker than forward
    curve = ThrustCurve(table=table, deadband=0.1)
    assert curve.thrust([0.0, 0.05, 0.1, -0.1])[:4].tolist() == [0.0, 0.0, 0.0, 0.0]
    # beyond the band the command range is mapped onto the table: c = 0.55 -> 0.5 of the table
    assert curve.thrust(0.55) == pytest.approx(12.0) and curve.thrust(-1.0) == -40.0 and curve.thrust(1.0) == 51.0
    edge = curve.thrust(np.array([0.1 + 1e-9, -0.1 - 1e-9]))
    assert np.all(np.abs(edge) < 1e-6)
    np.testing.assert_allclose(curve.thrust(curve.command_for([5.0, -5.0, 51.0, -40.0])), [5.0, -5.0, 51.0, -40.0])
    assert curve.command_for(0.0) == 0.0


@pytest.mark.parametrize("kwargs, reason", [
    ({"polynomial": [1.0, 2.0]}, "no thrust at zero"),
    ({"polynomial": [0.0, -5.0]}, "increase with the command"),
    ({"table": [[-1, 0.0], [0, 0.0], [1, 5.0]]}, "push both ways"),
    ({"polynomial": [0.0, 10.0, 0.0, -30.0]}, "increase with the command"),
    ({"table": [[-1, -1], [1, 1]]}, "3 to 1000"),
    ({"table": [[-1, -1], [0.5, 0], [0, 0], [1, 1]]}, "increase from -1 to 1"),
    ({"polynomial": [0.0, 1.0], "deadband": 0.6}, "deadband"),
    ({"polynomial": [0.0, math.nan]}, "finite"),
    ({}, "exactly one"),
])
def test_bad_curves_are_refused_with_the_reason(kwargs, reason):
    with pytest.raises(ValueError, match=reason):
        ThrustCurve(**kwargs)


def test_the_wrench_is_each_thrust_along_its_axis_at_its_position():
    rng = np.random.default_rng(4)
    positions, directions = rng.normal(0, 0.2, (6, 3)), rng.normal(0, 1, (6, 3))
    curve = ThrustCurve(table=[[-1, -20.0], [0, 0], [1, 30.0]])
    thrusters = FixedPitchThrusters(positions, directions, curve)
    thrusters.set_efficiency([1, 1, 0.5, 1, 1, 0.0])
    command = rng.uniform(-1, 1, 6)
    expected = np.zeros(6)
    for p, d, c, e in zip(positions, directions, command, [1, 1, 0.5, 1, 1, 0.0]):
        d = d / np.linalg.norm(d)
        t = e * (30.0 * c if c > 0 else 20.0 * c)
        expected[:3] += t * d
        expected[3:] += np.cross(p, t * d)
    np.testing.assert_allclose(thrusters.wrench(np.zeros(6), command), expected, atol=1e-12)
    with pytest.raises(ValueError, match="6 finite factors"):
        thrusters.set_efficiency([1, 1, 1, 1])


def test_the_bluerov2_is_von_benzon_s_table_a1(rov):
    np.testing.assert_allclose(np.diag(rov.m_rigid), [13.5, 13.5, 13.5, 0.26, 0.23, 0.37])
    np.testing.assert_allclose(rov.m_added, np.diag([6.36, 7.12, 18.68, 0.189, 0.135, 0.222]))
    assert rov.weight - rov.buoyancy == pytest.approx(13.5 * 9.82 - 1000.0 * 0.0134 * 9.82)   # 0.98 N heavy
    assert rov.thrusters.count == 8 and rov.inputs.kind == "virtual" and rov.pitch_limit == 1.0
    # [vB]'s R_z(5.05) (0.156, 0.111, 0.085) is the mirror of T1 to 0.6 mm: the file writes the mirror
    a = 5.05
    rotated = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]]) @ [0.156, 0.111, 0.085]
    assert np.abs(rotated - rov.thrusters.positions[1]).max() < 1e-3
    assert thruster_mirror(rov.thrusters) == [1, 0, 3, 2, 5, 4, 7, 6]


def test_the_seapup_keeps_its_direct_inputs_and_its_mirror():
    seapup = VehicleModel(load_vehicle_config("baseline"))
    command = np.array([0.1, 0.2, -0.1, 0.0])
    assert seapup.inputs.kind == "direct" and seapup.inputs.to_actuators(command) is command
    assert thruster_mirror(seapup.thrusters) == [1, 0, 3, 2]


def test_the_virtual_inputs_ask_the_thrusters_for_their_wrench_and_nothing_else(rov):
    thrusters, inputs = rov.thrusters, rov.inputs
    scale = inputs.full_scale[:, 0]
    # full scale along each axis alone is what the thrusters can give: the horizontal four at 45 deg for
    # surge and sway, the vertical four for heave, the horizontal four's arms for yaw
    peak = thrusters.curve.max_forward
    arm = abs(0.156 * math.sqrt(0.5) + 0.111 * math.sqrt(0.5))
    np.testing.assert_allclose(scale, [4 * peak * math.sqrt(0.5), 4 * peak * math.sqrt(0.5), 4 * peak, 4 * peak * arm],
                               rtol=1e-6)
    rng = np.random.default_rng(2)
    for _ in range(20):
        v = rng.uniform(-0.25, 0.25, 4)
        wrench = thrusters.wrench(np.zeros(6), inputs.to_actuators(v))
        np.testing.assert_allclose(wrench, [v[0] * scale[0], v[1] * scale[1], v[2] * scale[2], 0.0, 0.0, v[3] * scale[3]],
                                   atol=1e-6)
    # beyond what the thrusters give together: scaled down along the demand's own direction
    v = np.array([0.8, 0.8, 0.0, 0.8])
    wrench = thrusters.wrench(np.zeros(6), inputs.to_actuators(v))
    demand = np.array([v[0] * scale[0], v[1] * scale[1], 0.0, 0.0, 0.0, v[3] * scale[3]])
    fraction = wrench[0] / demand[0]
    assert 0.3 < fraction < 1.0
    np.testing.assert_allclose(wrench, fraction * demand, atol=1e-6 * np.abs(demand).max())
    # the mirror: sway and yaw inputs of opposite sign drive each thruster's mirror image alike
    v = np.array([0.2, 0.1, -0.05, 0.15])
    mirror = thruster_mirror(thrusters)
    np.testing.assert_allclose(inputs.to_actuators(v * [1, -1, 1, -1]), inputs.to_actuators(v)[mirror], atol=1e-9)


#: Blue Robotics, "T200 Thruster Public Performance Data 10-20 V" (Sept. 2019), sheet "16 V": bollard thrust
#: [kgf] at the ESC's pulse width [us], read from the maker's data (independent of the file's [c, N] pairs)
MAKER_16V = {1100: -4.07, 1200: -2.71, 1300: -1.44, 1400: -0.48, 1468: -0.04, 1472: 0.0, 1500: 0.0, 1528: 0.0,
             1532: 0.04, 1600: 0.60, 1700: 1.82, 1800: 3.42, 1852: 4.51, 1900: 5.25}


def test_the_maker_s_t200_curve_is_its_bollard_data_asymmetric_with_the_esc_s_band():
    rov = VehicleModel(load_vehicle_config("bluerov2_heavy_t200"))
    curve = rov.thrusters.curve
    assert curve.table is not None and curve.coefficients is None   # the overlay replaced [vB]'s polynomial
    pwm = np.array(sorted(MAKER_16V))
    command = (pwm - 1500.0) / 400.0
    np.testing.assert_allclose(curve.thrust(command), [MAKER_16V[p] * 9.80665 for p in pwm], atol=6e-4)
    assert (curve.max_forward, curve.max_reverse) == (pytest.approx(5.25 * 9.80665, abs=6e-4),
                                                      pytest.approx(-4.07 * 9.80665, abs=6e-4))
    # the inverse through the ESC's flat band: no thrust, no command; the least thrust either way at its edge
    np.testing.assert_array_equal(curve.command_for(np.zeros(3)), 0.0)
    small = curve.command_for(np.array([0.01, -0.01]))
    assert 0.07 < small[0] < 0.071 and -0.071 < small[1] < -0.07
    thrust = np.linspace(curve.max_reverse, curve.max_forward, 401)
    np.testing.assert_allclose(curve.thrust(curve.command_for(thrust)), thrust, atol=1e-9)
    # the mixer's full scale follows it: heave is the vertical four pushing one way or the other (4 x 5.25 kgf
    # against 4 x 4.07 kgf); surge the horizontal four at 45 deg, two forward and two in reverse either way
    forward, reverse = curve.max_forward, -curve.max_reverse
    np.testing.assert_allclose(sorted(rov.inputs.full_scale[2]), [4 * reverse, 4 * forward], rtol=1e-9)
    np.testing.assert_allclose(rov.inputs.full_scale[0], 2 * (forward + reverse) * math.sqrt(0.5), rtol=1e-9)
    # and every other number is bluerov2_heavy's
    vb = VehicleModel(load_vehicle_config("bluerov2_heavy"))
    np.testing.assert_array_equal(rov.m_rigid, vb.m_rigid)
    np.testing.assert_array_equal(rov.thrusters.matrix, vb.thrusters.matrix)
    assert rov.actuator_time_constant == vb.actuator_time_constant
    report = check_model(rov)
    assert report.ok, report.findings


def test_it_hovers_level_and_check_model_notes_what_the_description_declares(rov):
    hover = trim(rov, 0.0)
    assert abs(hover.pitch_angle) < 1e-9 and hover.residual < 1e-9
    # the heave input that holds 0.98 N of excess weight
    w_minus_b = rov.weight - rov.buoyancy
    assert hover.blade_pitch[2] == pytest.approx(-w_minus_b / rov.inputs.full_scale[2, 1], rel=1e-6)
    report = check_model(rov)
    assert report.ok, report.findings
    assert any("sway-yaw" in n for n in report.notes) and any("heave-pitch" in n for n in report.notes)
    assert any(n.startswith("top speed about 0.70") for n in report.notes)
    undeclared = load_vehicle_config("bluerov2_heavy")
    undeclared.pop("open_loop_unstable")
    findings = check_model(VehicleModel(undeclared)).findings
    assert findings and {f.kind for f in findings} == {"instability"}
    assert any("sway-yaw mode, not declared" in f.message for f in findings)


@pytest.mark.parametrize("backend", ["compiled", "numpy"])
def test_the_thrusters_lag_behind_the_mixer_and_applied_is_the_input_held(rov, backend):
    plant = VehicleIntegrator(rov, dt=0.1, backend=backend)
    assert plant.compiled == (backend == "compiled")   # the kernels step fixed-pitch thrusters too
    command = np.array([0.3, 0.0, 0.0, 0.0])
    plant.step(command)
    target = rov.inputs.to_actuators(command)
    tau = rov.actuator_time_constant
    np.testing.assert_allclose(plant.pitch, target * (1.0 - math.exp(-0.1 / tau)), rtol=1e-12)
    np.testing.assert_allclose(plant.applied, command)


@pytest.mark.parametrize("change, reason", [
    (lambda c: c["thrusters"].update(shaft_speed=25.0), "unknown key thrusters.shaft_speed"),
    (lambda c: c["thrusters"]["thrust_curve"].update(poly=[0, 1]), "unknown key thrusters.thrust_curve.poly"),
    (lambda c: c.update(inputs={"kind": "direct"}), "fixed-pitch thrusters are flown through inputs: {kind: virtual}"),
    (lambda c: c.update(inputs={"kind": "virtual", "wieghts": [1] * 8}), "unknown key inputs.wieghts"),
    (lambda c: c.update(thruster_efficiency=[1.0] * 4), "8 finite factors"),
    (lambda c: c["thrusters"].update(kind="magnetohydrodynamic"), "thrusters.kind must be one of"),
])
def test_a_bad_description_is_refused_naming_the_key(tmp_path, change, reason):
    import yaml
    config = load_vehicle_config("bluerov2_heavy")
    change(config)
    path = tmp_path / "mine.yaml"
    path.write_text(yaml.safe_dump(config))
    with pytest.raises(ConfigError, match=reason.replace("{", r"\{").replace("}", r"\}")):
        VehicleModel(load_vehicle_config(path))
