"""Run specifications as data (seapup_runs.spec): derived settings, validation, round trips."""
import json
import pickle

import numpy as np
import pytest

from seapup_common.controllers import ControllerSpec
from seapup_runs.spec import (PHYSICS_STEP, ReferenceSteps, RunEvent, RunSpec, RunSpecError, SelfTestDesign)


def full_spec() -> RunSpec:
    return RunSpec(name="everything", vehicle="camera", environment={"sensors": "haslar", "current": {"enabled": True}},
                   control_period=0.05, duration=20.0, start_depth=30.0,
                   controller=ControllerSpec("hold", {"blade_pitch": [0.1, 0.1, 0.0, 0.0]}),
                   design=SelfTestDesign("baseline", (0.0, 0.7)),
                   reference=ReferenceSteps.from_list([[0.0, 0.2, 0, 0, 0], [5.0, 0.3, 0, 0, 0.1]]),
                   events=(RunEvent(10.0, "controller", {"type": "mfol", "parameters": {"schedule": False}}),
                           RunEvent(2.0, "current", {"mean_speed": 0.26, "speed_std": 0.0, "mean_direction": 0.0,
                                                     "direction_std": 0.0}),
                           RunEvent(3.0, "thruster_efficiency", [1.0, 0.5, 1.0, 1.0]),
                           RunEvent(4.0, "configuration", "baseline")),
                   seed=7, metrics=("step_response",))


def test_the_physics_step_rule_is_derived_once():
    assert RunSpec(control_period=0.2).physics_step == PHYSICS_STEP == 0.1   # sec. 3.2
    assert RunSpec(control_period=0.05, duration=1.0).physics_step == 0.05    # 20 Hz: one step a sample
    assert RunSpec(control_period=0.2, duration=10.0).samples == 50


def test_a_spec_round_trips_through_json_and_pickle():
    spec = full_spec()
    again = RunSpec.from_dict(json.loads(json.dumps(spec.to_dict())))
    assert again == spec and pickle.loads(pickle.dumps(spec)) == spec
    assert [e.time for e in spec.events] == [2.0, 3.0, 4.0, 10.0]             # kept in time order
    assert spec.controller_timeline()[1] == (10.0, ControllerSpec("mfol", {"schedule": False}))
    assert [e.kind for e in spec.plant_events()] == ["current", "thruster_efficiency", "configuration"]


@pytest.mark.parametrize("change, message", [
    ({"control_period": 0.15}, "whole number of 0.1 s physics steps"),
    ({"control_period": -1.0}, "must be > 0"),
    ({"duration": 10.01}, "whole number of control periods"),
    ({"duration": float("nan")}, "finite"),
    ({"dynamics": "quantum"}, "nonlinear or linearised"),
    ({"seed": -1}, "seed"),
    ({"seed": True}, "seed"),
    ({"start_state": [0.0] * 11}, "needs 12 values"),
    ({"start_pitch": [0.0, 0.0, float("inf"), 0.0]}, "finite"),
    ({"reference": [[0.0, 1.0, 0.0]]}, "needs 4 values"),
    ({"reference": [[1.0, 0, 0, 0, 0], [0.5, 0, 0, 0, 0]]}, "strictly increasing"),
    ({"events": [{"time": 1.0, "kind": "teleport"}]}, "unknown event kind 'teleport'"),
    ({"events": [{"time": -1.0, "kind": "configuration", "detail": "camera"}]}, ">= 0"),
    ({"events": [{"time": 1.0, "kind": "current", "detail": {"mean_sped": 0.2}}]}, r"unknown current key"),
    ({"events": [{"time": 1.0, "kind": "thruster_efficiency", "detail": [1, 1]}]}, "4 factors"),
    ({"events": [{"time": 1.0, "kind": "configuration", "detail": "camera", "when": 3}]}, "unknown event key"),
    ({"controller": {"type": "mfol", "paramters": {}}}, "unknown controller key"),
])
def test_bad_specs_are_refused_naming_the_key(change, message):
    data = {**full_spec().to_dict(), **change}
    with pytest.raises((RunSpecError, ValueError), match=message):
        RunSpec.from_dict(data)


def test_unknown_spec_keys_and_a_disagreeing_physics_step_are_refused():
    with pytest.raises(RunSpecError, match=r"unknown run spec key\(s\) \['duraton'\]"):
        RunSpec.from_dict({"duraton": 5.0})
    with pytest.raises(RunSpecError, match="disagrees"):
        RunSpec.from_dict({"control_period": 0.2, "physics_step": 0.05})


def test_a_reference_profile_holds_each_step_and_starts_at_its_first_value():
    profile = ReferenceSteps.from_list([[2.0, 0.1, 0, 0, 0], [4.0, 0.2, 0, 0, 0]])
    assert [float(profile.at(t).velocity[0]) for t in (0.0, 1.999, 2.0, 3.9, 4.0 - 1e-12, 100.0)] == \
        [0.1, 0.1, 0.1, 0.1, 0.2, 0.2]


def test_documents_fill_the_timeline_entries_they_are_given_for():
    spec = full_spec()
    filled = spec.with_controllers({1: {"kind": "seapup/mfol_controller"}})
    assert filled.controller_timeline()[1][1].document == {"kind": "seapup/mfol_controller"}
    assert filled.controller.document is None and filled.events[:3] == spec.events[:3]
    np.testing.assert_array_equal(filled.initial_state(), [0, 0, 30.0] + [0] * 9)
