"""Tests of seapup_sim.vehicle_config: shipped configurations and overlays."""
import pytest
import yaml

from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import ConfigError, available_configs, load_vehicle_config


def test_shipped_configurations():
    assert {"baseline", "camera", "fouled_main_port"} <= set(available_configs())
    for name in available_configs():
        cfg = load_vehicle_config(name)
        assert cfg["name"] == name
        VehicleModel(cfg)


def test_overlay_merges_mappings_and_replaces_lists(tmp_path):
    base = load_vehicle_config("baseline")
    (tmp_path / "baseline.yaml").write_text(yaml.safe_dump(base))
    (tmp_path / "tweak.yaml").write_text(
        "extends: baseline\nhydrodynamics:\n  X_u: -7.5\nthruster_efficiency: [1, 1, 0.5, 1]\n")
    cfg = load_vehicle_config(tmp_path / "tweak.yaml")
    assert cfg["name"] == "tweak"
    assert cfg["hydrodynamics"]["X_u"] == -7.5
    assert cfg["hydrodynamics"]["X_u|u|"] == base["hydrodynamics"]["X_u|u|"]
    assert cfg["thruster_efficiency"] == [1, 1, 0.5, 1]
    assert base["hydrodynamics"]["X_u"] != -7.5  # the base was not modified


def test_fouling_overlay_halves_the_main_port_installation():
    base = VehicleModel(load_vehicle_config("baseline"))
    fouled = VehicleModel(load_vehicle_config("fouled_main_port"))
    assert list(fouled.thrusters.efficiency) == [0.5, 1.0, 1.0, 1.0]
    import numpy as np
    nu = np.zeros(6)
    pitch = np.radians([20.0, 20.0, -13.0, -13.0])
    tb = base.thrusters.wrench(nu, pitch)
    tf = fouled.thrusters.wrench(nu, pitch)
    thrust = base.thrusters.bollard_thrust(pitch)
    # the port main's contribution is exactly halved
    np.testing.assert_allclose(tb - tf, 0.5 * base.thrusters.matrix[:, 0] * thrust[0], atol=1e-9)


def test_missing_and_cyclic_configurations(tmp_path):
    with pytest.raises(ConfigError, match="no vehicle configuration 'nope'"):
        load_vehicle_config("nope")
    (tmp_path / "a.yaml").write_text("extends: b\n")
    (tmp_path / "b.yaml").write_text("extends: a\n")
    with pytest.raises(ConfigError, match="loops back"):
        load_vehicle_config(tmp_path / "a.yaml")


def test_model_can_be_reconfigured_in_place():
    model = VehicleModel(load_vehicle_config("baseline"))
    model.configure(load_vehicle_config("camera"))
    assert model.config_name == "camera" and model.mass_properties.mass == pytest.approx(125.0)


def test_unknown_keys_are_refused_with_the_file_and_the_nearest_name(tmp_path):
    """A misspelled key changed nothing before (the baseline value flew); now it names itself."""
    cases = {"rigid_body:\n  bouyancy_mass: 100.0\n": "unknown key rigid_body.bouyancy_mass (did you mean rigid_body.buoyancy_mass?)",
             "thruster_eficiency: [0.5, 1, 1, 1]\n": "unknown key thruster_eficiency (did you mean thruster_efficiency?)",
             "payloads:\n  - {name: cam, mass: 1.0, buoyancy_mass: 1.0, position: [0, 0, 0], raduis: 0.1}\n":
                 "unknown key payloads[0].raduis (did you mean radius?)"}
    from importlib import resources
    baseline = resources.files("seapup_sim") / "vehicles" / "baseline.yaml"
    for text, message in cases.items():
        path = tmp_path / "mine.yaml"
        path.write_text(f"extends: {baseline}\n{text}")
        with pytest.raises(ConfigError) as error:
            load_vehicle_config(path)
        assert str(error.value) == f"mine.yaml: {message}"
    # the open set: any derivative of the notation is a key (the term parser checks it)
    (tmp_path / "drag.yaml").write_text(f"extends: {baseline}\nhydrodynamics:\n  X_uuu: -1.0\n")
    assert load_vehicle_config(tmp_path / "drag.yaml")["hydrodynamics"]["X_uuu"] == -1.0
    for name in ("baseline", "camera", "fouled_main_port"):   # every shipped file passes its own schema
        assert load_vehicle_config(name)["name"] == name
