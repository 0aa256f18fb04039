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


def test_a_self_test_design_keeps_its_fit_and_refuses_an_unknown_one():
    raw = SelfTestDesign("baseline", (0.0, 0.7), fit="raw")
    assert raw.to_dict()["fit"] == "raw" and SelfTestDesign.from_dict(raw.to_dict()) == raw
    assert "fit" not in SelfTestDesign().to_dict()     # the default: the keys (and run caches) as before
    for bad in ("prony", ["raw"], 7, None):
        with pytest.raises(RunSpecError, match="self-test fit must be one of deviation, raw"):
            SelfTestDesign(fit=bad)


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


# -- strict values and bounded sizes (issue 40) ------------------------------------------------------------
@pytest.mark.parametrize("change, message", [
    ({"control_period": "0.2"}, r"control_period must be a number, got '0.2' \(text, not a number"),
    ({"duration": "2e7"}, r"duration must be a number, got '2e7' \(text.*1.0e\+8"),
    ({"duration": True}, "duration must be a number, got True"),
    ({"start_depth": [50.0]}, "start_depth must be a number"),
    ({"duration": 10**400}, "duration must be a finite number"),
    ({"name": ["a"]}, "name must be a non-empty string"),
    ({"vehicle": {"a": 1}}, "vehicle must be a non-empty string"),
    ({"dynamics": ["nonlinear"]}, "dynamics must be nonlinear or linearised"),
    ({"events": 5}, "events must be a list of events"),
    ({"metrics": 5}, "metrics must be a list of metric names"),
    ({"start_state": "000000000000"}, "start_state must be a list of numbers"),
    ({"start_pitch": [1e308, 0.0, 0.0, 0.0]}, "start_pitch must be within"),
    ({"reference": [[0.0, "1", 0, 0, 0]]}, "reference step 0 value must be a number"),
    ({"reference": 7}, "a reference profile is a list"),
    ({"design": {"operating_points": 5}}, "operating point must be a list of numbers"),
    ({"design": {"operating_points": [0.0] * 17}}, "1 to 16 operating points"),
    ({"events": [{"time": "1", "kind": "configuration", "detail": "camera"}]}, "event time must be a number"),
    ({"events": [{"time": 1.0, "kind": ["current"]}]}, "unknown event kind"),
    ({"events": [{"time": 1.0, "kind": "thruster_efficiency", "detail": "1111"}]}, "must be a list of numbers"),
    ({"physics_step": "abc"}, "physics_step must be a number"),
])
def test_a_number_must_be_a_yaml_number_and_every_value_its_type(change, message):
    """Before issue 40 a string '0.2' was converted, a list or a dict reached a format string (TypeError), and
    an unknown metric was found only after the run had flown."""
    data = {**full_spec().to_dict(), **change}
    with pytest.raises(RunSpecError, match=message) as caught:
        RunSpec.from_dict(data)
    assert "\n" not in str(caught.value) and len(str(caught.value)) < 400


@pytest.mark.parametrize("duration, period, what", [
    (2e7, 0.2, r"1e\+08 control samples, more than the 1,000,000"),       # the 2e7: 1.3 GB before
    (1e9, 0.2, "control samples"),                                        # the bare MemoryError
    (1e300, 0.2, "control samples"),                                      # inf samples: OverflowError before
    (1.0, 1e-300, "control samples"),                                     # 'Maximum allowed dimension exceeded'
    (2e7, 20.0, r"2e\+08 physics steps of 0.1 s, more than the 10,000,000"),
    (1e-8, 0.2, "shorter than one control period"),                       # 0 samples: a run of nothing
])
def test_a_run_s_size_is_refused_above_its_caps_before_anything_is_allocated(monkeypatch, duration, period, what):
    import seapup_runs.runner as runner
    monkeypatch.setattr(runner.np, "full", lambda *a, **k: pytest.fail("allocated for a refused run"))
    with pytest.raises(RunSpecError, match=what):
        runner.run(RunSpec(duration=duration, control_period=period))


def test_the_run_size_caps_are_stated_and_can_be_raised(monkeypatch):
    from seapup_runs import spec as module
    assert module.MAX_RUN_SAMPLES == 10**6 and module.MAX_PHYSICS_STEPS == 10**7
    RunSpec(duration=0.2 * 10**6, control_period=0.2)                  # exactly the cap: a spec, nothing flown
    with pytest.raises(RunSpecError, match="SEAPUP_MAX_RUN_SAMPLES"):
        RunSpec(duration=0.2 * (10**6 + 1), control_period=0.2)
    monkeypatch.setenv("SEAPUP_MAX_RUN_SAMPLES", "2000000")
    assert RunSpec(duration=0.2 * (10**6 + 1), control_period=0.2).samples == 10**6 + 1
    monkeypatch.setenv("SEAPUP_MAX_RUN_SAMPLES", "lots")
    with pytest.raises(RunSpecError, match="SEAPUP_MAX_RUN_SAMPLES must be a positive integer, got 'lots'"):
        RunSpec()


def test_a_long_reference_profile_costs_a_search_per_sample_not_a_scan():
    """Independent truth: the linear scan the lookup replaced, over a long random profile."""
    rng = np.random.default_rng(3)
    times = np.cumsum(rng.uniform(0.01, 1.0, 5000))
    profile = ReferenceSteps.from_list([[t, *rng.normal(size=4)] for t in times])

    def scan(t):
        value = profile.steps[0][1]
        for start, v in profile.steps:
            if t >= start - 1e-9:
                value = v
        return value
    for t in rng.uniform(-1.0, times[-1] + 1.0, 300).tolist() + times[:50].tolist():
        assert tuple(profile.at(t).velocity) == scan(t)
