"""Tests of seapup_common.contract: typed measurements, references and commands."""
import math

import numpy as np
import pytest

from seapup_common.blade_pitch import InvalidBladePitchError
from seapup_common.contract import (Command, ContractError, HoldCommand, Measurement, Reading, Reference,
                                    VelocityController)


def test_build_checks_shapes_and_marks_absent_fields_invalid():
    m = Measurement.build(1.0, velocity=[0.1, 0.0, 0.0], rates=[0, 0, 0.01], depth=3.0,
                          variances={"depth": 0.0025}, stamps={"depth": 0.9})
    assert m.velocity.valid and not m.position.valid and not m.altitude.valid
    assert m.depth.value == 3.0 and m.depth.stamp == 0.9 and m.depth.variance == 0.0025
    np.testing.assert_array_equal(m.body_velocity(), [0.1, 0.0, 0.0, 0.01])
    with pytest.raises(ValueError):
        m.velocity.value[0] = 5.0  # readings are read-only
    for bad in ({"velocity": [0.1, 0.0]}, {"depth": math.nan}, {"rates": [0, math.inf, 0]},
                {"depth": "3"}, {"heading": 1.0}):
        with pytest.raises(ContractError):
            Measurement.build(0.0, **bad)


def test_body_velocity_needs_valid_readings():
    with pytest.raises(ContractError, match="no valid velocity"):
        Measurement(2.0).body_velocity()
    assert not Reading.invalid().valid


def test_reference_and_command_validate():
    assert Reference().velocity.tolist() == [0, 0, 0, 0]
    with pytest.raises(ContractError):
        Reference([0.1, 0.0, 0.0])
    with pytest.raises(ContractError):
        Reference([math.nan, 0, 0, 0])
    assert Command([0.1, 0.2, 0.3, 0.4], 1.0).blade_pitch.tolist() == [0.1, 0.2, 0.3, 0.4]
    for bad in ([0.1] * 3, [0.1] * 5, [math.nan, 0, 0, 0]):
        with pytest.raises(InvalidBladePitchError):
            Command(bad)


def test_hold_command_is_a_velocity_controller():
    ctl = HoldCommand([0.1, 0.1, -0.2, -0.2], 0.2)
    assert isinstance(ctl, VelocityController)
    ctl.reset(Command([0.0] * 4, 0.0))
    out = ctl.update(3.0, Measurement(3.0), Reference())
    assert out.stamp == 3.0 and out.blade_pitch.tolist() == [0.1, 0.1, -0.2, -0.2]
    assert not isinstance(object(), VelocityController)
    with pytest.raises(ContractError):
        HoldCommand([0.0] * 4, 0.0)


def test_reference_schedule_applies_each_reference_at_its_time():
    from seapup_common.contract import StampedReferences
    schedule = StampedReferences(capacity=3)
    schedule.add(Reference([0.5, 0, 0, 0]), at=20.0)   # arrives first, due later
    schedule.add(Reference([0.3, 0, 0, 0]), at=10.0)
    schedule.add(Reference([0.4, 0, 0, 0]), at=10.0)   # same time: the later arrival wins
    with pytest.raises(ContractError, match="waiting"):
        schedule.add(Reference([0.9, 0, 0, 0]), at=30.0)
    assert schedule.at(9.8).velocity[0] == 0.0 and schedule.waiting == 3
    assert schedule.at(10.0).velocity[0] == 0.4 and schedule.waiting == 1
    assert schedule.at(15.0).velocity[0] == 0.4
    assert schedule.at(25.0).velocity[0] == 0.5 and schedule.waiting == 0
    schedule.add(Reference([0.1, 0, 0, 0]), at=40.0)
    schedule.add(Reference([0.2, 0, 0, 0]))              # no time: at once, and nothing stays scheduled
    assert schedule.at(25.2).velocity[0] == 0.2 and schedule.at(50.0).velocity[0] == 0.2
    with pytest.raises(ContractError, match="finite"):
        schedule.add(Reference(), at=float("nan"))
    assert schedule.waiting == 0


def test_variances_checked_once_give_the_readings_build_would():
    from seapup_common.contract import CheckedVariances
    given = {"velocity": [1e-4, 2e-4, 3e-4], "depth": 0.0025, "position": [0.25, 0.25, 0.5]}
    checked = CheckedVariances.of(given)
    values = {"velocity": [0.1, 0.0, 0.0], "rates": [0, 0, 0.01], "depth": 3.0, "position": [1.0, 2.0, 3.0]}
    a, b = Measurement.build(1.0, variances=given, **values), Measurement.build(1.0, variances=checked, **values)
    for name in ("velocity", "rates", "depth", "position", "altitude"):
        np.testing.assert_array_equal(getattr(a, name).variance, getattr(b, name).variance)
    assert b.rates.variance.tolist() == [0.0, 0.0, 0.0] and b.altitude.variance == 0.0
    with pytest.raises(ValueError):
        checked["velocity"][0] = 1.0   # shared by every measurement: read-only
    for bad in ({"depth": math.nan}, {"velocity": [1e-4, 2e-4]}, {"heading": 1.0}, {"position": [0, -math.inf, 0]}):
        with pytest.raises(ContractError):
            CheckedVariances.of(bad)
