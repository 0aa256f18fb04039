"""Controllers by name (seapup_common.controllers): the registry, entry points and specs."""
import pickle
import textwrap

import numpy as np
import pytest
import yaml

from seapup_common import controllers
from seapup_common.contract import Command, HoldCommand, Measurement, Reference, VelocityController
from seapup_common.controllers import (ControllerRegistryError, ControllerSpec, ControllerType, available_controllers,
                                       controller_type, create_controller, register_controller)


def test_installed_packages_register_hold_and_mfol_through_entry_points():
    names = available_controllers()
    assert {"hold", "mfol"} <= set(names)
    assert controller_type("hold") is controllers.HOLD_TYPE
    assert controller_type("mfol").needs_document


def test_a_hold_without_a_setting_holds_what_is_applied_when_it_starts():
    controller = create_controller("hold", 0.2)
    controller.reset(Command([0.1, 0.1, -0.2, -0.2]))
    assert controller.update(0.0, Measurement(0.0), Reference()).blade_pitch.tolist() == [0.1, 0.1, -0.2, -0.2]


def test_a_hold_spec_makes_a_controller_that_holds_its_setting():
    controller = create_controller({"type": "hold", "parameters": {"blade_pitch": [0.1, 0.2, -0.1, 0.0]}}, 0.2)
    assert isinstance(controller, HoldCommand) and isinstance(controller, VelocityController)
    controller.reset(Command(np.zeros(4)))
    controller.applied(0.2, Command(np.ones(4) * 0.3))  # told what happened: changes nothing
    command = controller.update(0.2, Measurement(0.2), Reference())
    np.testing.assert_array_equal(command.blade_pitch, [0.1, 0.2, -0.1, 0.0])
    assert controller.diagnostics() == {"blade_pitch": [0.1, 0.2, -0.1, 0.0]}


@pytest.mark.parametrize("spec, message", [
    ({"type": "no_such_law"}, "no controller type 'no_such_law'; available: .*hold"),
    ({"type": "hold", "parameters": {"blade_pich": [0, 0, 0, 0]}}, r"no parameter\(s\) \['blade_pich'\]"),
    ({"type": "hold", "parameters": {"blade_pitch": [0, 0, 0]}}, "exactly 4 values"),
    ({"type": "hold", "parameters": {"blade_pitch": [0, float("nan"), 0, 0]}}, "must be finite"),
    ({"type": "hold", "parameters": {"blade_pitch": "up"}}, "list of numbers"),
    ({"type": "mfol"}, "needs a design document"),
    ({"type": "mfol", "parameters": {"schedule": "yes"}, "document": {}}, "true or false"),
    ({"type": "mfol", "document": {"kind": "something else"}}, "not a seapup MFOL controller file"),
    ({"type": "hold", "surprise": 1}, r"unknown controller key\(s\) \['surprise'\]"),
    ({"parameters": {}}, "needs its 'type'"),
])
def test_bad_specs_are_refused_with_a_reason(spec, message):
    with pytest.raises(ControllerRegistryError, match=message):
        create_controller(spec, 0.2)


def test_a_missing_controller_file_is_named(tmp_path):
    with pytest.raises(ControllerRegistryError, match="controller file .*nope.yaml"):
        create_controller(ControllerSpec("mfol", file=str(tmp_path / "nope.yaml")))


def _mfol_document(period=0.2):
    eye = np.eye(4).tolist()
    point = {"surge": 0.0, "K_int": eye, "K_err": eye, "u0": [0.0, 0.0, 0.1, 0.1], "y0": [0.0] * 4}
    fast = {**point, "surge": 0.7, "u0": [0.2, 0.2, 0.1, 0.1]}
    return {"kind": "seapup/mfol_controller", "sample_period": period, "operating_points": [point, fast]}


def test_mfol_from_a_file_is_scheduled_or_fixed_by_its_parameter(tmp_path):
    path = tmp_path / "controller.yaml"
    path.write_text(yaml.safe_dump(_mfol_document()))
    scheduled = create_controller(ControllerSpec("mfol", file=path))
    fixed = create_controller(ControllerSpec("mfol", {"schedule": False}, file=path), sample_period=0.2)
    assert scheduled.schedule.speeds.tolist() == [0.0, 0.7] and fixed.schedule.speeds.tolist() == [0.0]
    assert fixed.diagnostics() == {}                           # before its first sample
    fixed.reset(Command(np.zeros(4)))
    at_rest = Measurement.build(0.0, velocity=(0.0, 0.0, 0.0), rates=(0.0, 0.0, 0.0))
    fixed.applied(0.0, Command(np.full(4, 0.05)))
    fixed.update(0.0, at_rest, Reference([0.1, 0, 0, 0]))
    assert fixed.diagnostics()["error"] == [0.1, 0.0, 0.0, 0.0]
    assert fixed.diagnostics()["applied"] == [0.05] * 4
    with pytest.raises(ControllerRegistryError, match="gains are for T = 0.2 s, not 0.05 s"):
        create_controller(ControllerSpec("mfol", document=_mfol_document()), sample_period=0.05)


class _Doubling:
    """A toy law for the registry test: twice the surge error on every thruster."""

    def __init__(self, gain, sample_period):
        self.gain, self.sample_period = gain, sample_period

    def reset(self, applied):
        pass

    def applied(self, t, command):
        pass

    def update(self, t, measurement, reference):
        error = reference.velocity[0] - measurement.body_velocity()[0]
        return Command(np.full(4, self.gain * error), stamp=t)

    def diagnostics(self):
        return {"gain": self.gain}


def test_a_law_registered_in_process_is_created_by_name_and_names_cannot_be_taken_twice():
    kind = ControllerType("doubling_test", lambda p, d, T: _Doubling(p["gain"], T), {"gain": 2.0})
    register_controller(kind)
    try:
        assert "doubling_test" in available_controllers()
        law = create_controller(ControllerSpec("doubling_test", {"gain": 3}), sample_period=0.1)
        assert law.gain == 3.0 and isinstance(law.gain, float)
        with pytest.raises(ControllerRegistryError, match="already registered"):
            register_controller(ControllerType("doubling_test", lambda p, d, T: None))
        with pytest.raises(ControllerRegistryError, match="not a VelocityController"):
            register_controller(ControllerType("doubling_test", lambda p, d, T: object(), {"gain": 2.0}), replace=True)
            create_controller("doubling_test", 0.1)
    finally:
        controllers._REGISTERED.pop("doubling_test", None)


def test_an_entry_point_of_another_distribution_registers_a_law(tmp_path, monkeypatch):
    """A package registers a law with an entry point alone: nothing of seapup is edited."""
    (tmp_path / "toy_law.py").write_text(textwrap.dedent("""
        from seapup_common.contract import HoldCommand
        from seapup_common.controllers import ControllerType
        TOY = ControllerType("toy_entry_law", lambda p, d, T: HoldCommand([p["level"]] * 4, T), {"level": 0.0})
    """))
    info = tmp_path / "toy_law-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: toy-law\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[seapup.velocity_controllers]\ntoy_entry_law = toy_law:TOY\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        assert "toy_entry_law" in available_controllers()
        law = create_controller(ControllerSpec("toy_entry_law", {"level": 0.25}), sample_period=0.2)
        np.testing.assert_array_equal(law.update(0.0, Measurement(0.0), Reference()).blade_pitch, [0.25] * 4)
    finally:
        controllers._REGISTERED.pop("toy_entry_law", None)


def test_specs_are_plain_data():
    spec = ControllerSpec("mfol", {"schedule": False}, document=_mfol_document())
    again = ControllerSpec.from_dict(yaml.safe_load(yaml.safe_dump(spec.to_dict())))
    assert again == spec and pickle.loads(pickle.dumps(spec)) == spec
    assert ControllerSpec.from_dict("hold") == ControllerSpec("hold")


def test_a_controller_file_is_read_bounded_and_strictly(tmp_path):
    """Issue 40: ``file: /dev/zero`` ended in a bare MemoryError; a duplicated key kept the last value."""
    with pytest.raises(ControllerRegistryError, match="controller file /dev/zero: larger than 1 MiB"):
        ControllerSpec("hold", file="/dev/zero").load_document()
    doc = tmp_path / "design.yaml"
    doc.write_text("gains: 1\ngains: 2\n")
    with pytest.raises(ControllerRegistryError, match="duplicate key 'gains'"):
        ControllerSpec("hold", file=str(doc)).load_document()


@pytest.mark.parametrize("value", ["[0.1, 0.1, 0.0, 0.0]", "0.1000", [True, 0.0, 0.0, 0.0], [10**400, 0, 0, 0]])
def test_a_list_parameter_takes_numbers_only(value):
    """A string was iterated character by character into floats; a bool counted as 1.0."""
    with pytest.raises(ControllerRegistryError, match="blade_pitch"):
        controllers.controller_type("hold").complete({"blade_pitch": value})
