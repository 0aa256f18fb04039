"""The live view's geometry against the vehicle's configuration, eq. 2.1's rotation and the seabed model."""
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from seapup_live_view import view_scene
from seapup_common import frames
from seapup_common.ros import messages as conv
from seapup_sim.seabed import Seabed
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config


def _shape(name="baseline"):
    return view_scene.vehicle_shape(VehicleModel(load_vehicle_config(name)))


def test_the_frame_box_holds_every_thruster_and_the_camera_appears_only_when_fitted():
    shape, model = _shape(), VehicleModel(load_vehicle_config("baseline"))
    low, high = shape.frame_center - shape.frame_size / 2, shape.frame_center + shape.frame_size / 2
    for thruster, position in zip(shape.thrusters, model.thrusters.positions):
        np.testing.assert_array_equal(thruster.position, position)    # Table 3.2's positions, unchanged
        assert np.all(position - thruster.diameter >= low - 1e-12) and np.all(position + thruster.diameter <= high + 1e-12)
        assert math.isclose(np.linalg.norm(thruster.direction), 1.0)
    assert shape.payloads == ()
    camera = _shape("camera")
    (name, position, radius), = camera.payloads
    config = load_vehicle_config("camera")["payloads"][0]
    assert name == "camera" and radius == config["radius"]
    np.testing.assert_array_equal(position, config["position"])
    assert position[0] > 0.3   # at the bow (sec. 3.6)


def test_thrust_arrows_vanish_at_zero_thrust_pitch_reach_full_length_at_the_limit_and_turn_with_the_thrust():
    shape = _shape()
    beta0, limit = shape.zero_thrust_pitch, shape.pitch_limit
    assert math.isclose(limit, math.radians(35.0))
    arrows = view_scene.thrust_arrows(shape, [beta0, beta0 + limit, beta0 - 0.5 * limit, beta0 + 0.25 * limit])
    lengths = [length for _, _, length in arrows]
    assert lengths == pytest.approx([0.0, view_scene.ARROW_FULL_LENGTH, 0.5 * view_scene.ARROW_FULL_LENGTH,
                                     0.25 * view_scene.ARROW_FULL_LENGTH])
    np.testing.assert_allclose(arrows[1][1], shape.thrusters[1].direction)
    np.testing.assert_allclose(arrows[2][1], -shape.thrusters[2].direction)   # astern pitch: thrust reversed
    for (origin, _, _), thruster in zip(arrows, shape.thrusters):
        np.testing.assert_array_equal(origin, thruster.position)
    with pytest.raises(ValueError):
        view_scene.thrust_arrows(shape, [0.0, 0.0, 0.0])


def test_the_frame_tree_is_the_simulator_s_and_maps_body_points_as_eq_2_1():
    rng = np.random.default_rng(11)
    for _ in range(20):
        state = np.r_[rng.normal(0, 30, 3), rng.uniform(-1.3, 1.3, 3), rng.normal(0, 1, 6)]
        tree = {t.child: t for t in view_scene.frame_transforms(state)}
        assert {c: t.parent for c, t in tree.items()} == {"base_link": "odom", "odom_ned": "odom",
                                                          "base_link_frd": "base_link"}
        ros = conv.transforms_enu(state, 0).transforms[0].transform     # what /tf carries for the same state
        vehicle = tree["base_link"]
        assert vehicle.translation == (ros.translation.x, ros.translation.y, ros.translation.z)
        assert vehicle.rotation == (ros.rotation.x, ros.rotation.y, ros.rotation.z, ros.rotation.w)
        point = rng.normal(size=3)
        in_odom = Rotation.from_quat(vehicle.rotation).apply(
            Rotation.from_quat(tree["base_link_frd"].rotation).apply(point)) + vehicle.translation
        in_ned = Rotation.from_quat(tree["odom_ned"].rotation).inv().apply(in_odom)
        np.testing.assert_allclose(in_ned, frames.rotation_body_to_ned(*state[3:6]) @ point + state[:3], atol=1e-9)


def test_a_trail_keeps_points_a_spacing_apart_the_newest_last_in_constant_memory():
    trail = view_scene.Trail(capacity=5, spacing=1.0)
    assert trail.add([0, 0, 0]) and not trail.add([0.5, 0, 0]) and trail.add([1.0, 0, 0])
    assert not trail.add([np.nan, 0, 0]) and not trail.add([1, 2])
    for x in range(2, 10):
        trail.add([float(x), 0, 0])
    np.testing.assert_array_equal(trail.points()[:, 0], [5, 6, 7, 8, 9])
    with pytest.raises(ValueError):
        view_scene.Trail(capacity=1)


@pytest.mark.parametrize("seabed", [Seabed("flat", depth=40.0), Seabed("slope", depth=30.0, gradient=0.1, direction=0.7),
                                    Seabed("polyline", points=[(-50.0, 20.0), (0.0, 35.0), (60.0, 25.0)])])
def test_the_seabed_grid_lies_on_the_seabed_and_tiles_the_square(seabed):
    vertices, triangles = view_scene.seabed_grid(seabed, [5.0, -3.0, 10.0], half_width=10.0, cells=8)
    assert vertices.shape == (81, 3) and triangles.shape == (128, 3)
    for x, y, z in vertices:
        assert z == pytest.approx(seabed(x, y))
    assert vertices[:, 0].min() == -5.0 and vertices[:, 1].max() == 7.0
    corners = vertices[triangles]
    a, b = corners[:, 1, :2] - corners[:, 0, :2], corners[:, 2, :2] - corners[:, 0, :2]
    area = 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    assert np.all(area > 0) and area.sum() == pytest.approx(20.0 ** 2)   # the square, once over


def test_the_current_arrow_points_downstream_with_its_speed_and_is_absent_in_still_water():
    assert view_scene.current_arrow([0.0, 0.0, 0.0]) is None
    direction, length = view_scene.current_arrow([0.0, 0.514444, 0.0])   # one knot flowing east
    np.testing.assert_allclose(direction, [0, 1, 0])
    assert length == pytest.approx(2.0)


def test_a_virtual_input_vehicle_shows_each_of_its_thrusters_with_the_thrust_its_mixer_gives():
    """The BlueROV2 Heavy: eight arrows from the four applied inputs through the vehicle's own mixer and thrust
    curve (independent truth: the thrusters' wrench is the one the inputs ask for, so a surge input drives the
    four horizontal thrusters alike, the front pair forward and the aft pair astern along their axes)."""
    model = VehicleModel(load_vehicle_config("bluerov2_heavy"))
    shape = view_scene.vehicle_shape(model)
    assert len(shape.thrusters) == 8 and all(t.diameter == view_scene.FIXED_PITCH_DIAMETER for t in shape.thrusters)
    assert np.all(shape.frame_size > 0.25)   # a BlueROV2 Heavy is about 0.46 x 0.58 x 0.25 m
    arrows = view_scene.thrust_arrows(shape, [0.5, 0.0, 0.0, 0.0])
    thrust = model.thrusters.curve.thrust(model.inputs.to_actuators(np.array([0.5, 0.0, 0.0, 0.0])))
    lengths = np.array([length for _, _, length in arrows])
    np.testing.assert_allclose(lengths, view_scene.ARROW_FULL_LENGTH * np.abs(thrust) / model.thrusters.curve.max_forward)
    assert np.allclose(lengths[:4], lengths[0]) and lengths[0] > 0.3 * view_scene.ARROW_FULL_LENGTH
    for (origin, direction, _), thruster, t in zip(arrows, shape.thrusters, thrust):
        np.testing.assert_array_equal(origin, thruster.position)
        np.testing.assert_allclose(direction, np.sign(t) * thruster.direction if t else thruster.direction)
    # the summed arrows point forward: the front pair push forward-inward, the aft pair (reversed) likewise
    push = sum(length * direction for _, direction, length in arrows[:4])
    assert push[0] > 0 and abs(push[1]) < 1e-9 * abs(push[0])
    assert all(length == 0.0 for _, _, length in view_scene.thrust_arrows(shape, [0.0] * 4))
    with pytest.raises(ValueError, match="4 applied inputs"):
        view_scene.thrust_arrows(shape, [0.0] * 8)


def test_the_plot_shows_each_vehicle_s_inputs_in_their_own_unit_against_their_own_limit():
    """The Seapup's inputs are blade pitches: degrees against the +-35 deg of seapup_common/data/interface.yaml
    (and the layout's older fields alike); a virtual-input vehicle's are surge, sway, heave and yaw in
    fractions of full scale: percent against 100 %, and no blade pitches."""
    from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
    seapup = view_scene.plot_inputs(_shape(), [0.1, -0.2, 0.0, math.radians(35.0)])
    np.testing.assert_allclose(seapup["inputs"], np.degrees([0.1, -0.2, 0.0, math.radians(35.0)]))
    assert seapup["input_limit"] == pytest.approx(math.degrees(BLADE_PITCH_LIMIT)) == pytest.approx(35.0)
    assert seapup["input_unit"] == "deg" and seapup["input_names"][0] == "main_port"
    assert seapup["blade_pitch_deg"] == seapup["inputs"] and seapup["pitch_limit_deg"] == seapup["input_limit"]
    rov = view_scene.plot_inputs(_shape("bluerov2_heavy"), [0.25, -0.5, 1.0, 0.0])
    assert rov["inputs"] == [25.0, -50.0, 100.0, 0.0] and rov["input_limit"] == 100.0 and rov["input_unit"] == "%"
    assert rov["input_names"] == ["surge", "sway", "heave", "yaw"]
    assert "blade_pitch_deg" not in rov and "pitch_limit_deg" not in rov
