"""The in-process runner and the run result (seapup_runs.runner, seapup_runs.result, seapup_runs.metrics).

Independent truth: the established simulation loop (``Simulation.run``, fig. 5.1) flying the same
controller objects; a JSON round trip that must give back every number.
"""
import math

import numpy as np
import pytest

from seapup_common.contract import HoldCommand
from seapup_common.controllers import ControllerSpec
from seapup_control.mfol import THESIS_POLES_5HZ, MFOLModel, design
from seapup_control.mfol_controller import MFOLController
from seapup_runs.metrics import MetricError, compute
from seapup_runs.result import RunResult, RunResultError, STATE_INDEX, jsonable
from seapup_runs.runner import run, start_pitch
from seapup_runs.spec import ReferenceSteps, RunEvent, RunSpec, RunSpecError
from seapup_sim.simulation import Simulation


def _mfol_document():
    """A decoupled two-term design (eq. 4.9-4.11) about hover, written as a self-test controller file."""
    model = MFOLModel(np.diag([0.01, 0.01, 0.01, 0.2]), np.diag([0.1, 0.1, 0.1, 2.0]), 0.2)
    gains = design(model, THESIS_POLES_5HZ)
    return {"kind": "seapup/mfol_controller", "sample_period": 0.2,
            "operating_points": [{"surge": 0.0, "K_int": gains.K_int.tolist(), "K_err": gains.K_err.tolist(),
                                  "u0": start_pitch(RunSpec()).tolist(), "y0": [0.0] * 4}]}


def test_a_held_setting_flies_exactly_as_the_simulation_loop_flies_it():
    hover = start_pitch(RunSpec())
    pitch = (hover + np.radians([5.0, 5.0, 0.0, 0.0])).tolist()
    spec = RunSpec(duration=6.0, controller=ControllerSpec("hold", {"blade_pitch": pitch}),
                   environment={"sensors": "baseline"}, seed=3)
    result = run(spec)
    loop = Simulation.from_config("baseline", {"sensors": "baseline"}, seed=3, control_period=0.2,
                                  state=spec.initial_state(), pitch=hover).run(HoldCommand(pitch, 0.2), 6.0)
    np.testing.assert_array_equal(result.series.t, loop.t)
    np.testing.assert_array_equal(result.series.states(), loop.state)
    np.testing.assert_array_equal(result.series.applied, loop.blade_pitch)
    np.testing.assert_array_equal(result.series.command[:-1], loop.command[:-1])
    np.testing.assert_array_equal(result.series.measured["u"], loop.measured["velocity"][:, 0])
    np.testing.assert_array_equal(result.series.measured["depth"], loop.measured["depth"])
    assert math.isnan(result.series.command[-1, 0]) and result.series.truth["u"][-1] > 0.05  # pushed ahead


def test_an_mfol_run_equals_the_simulation_loop_with_the_same_controller():
    document = _mfol_document()
    reference = ReferenceSteps.from_list([[0.0, 0.1, 0.0, 0.0, 0.0], [4.0, 0.1, 0.05, 0.0, 0.1]])
    spec = RunSpec(duration=8.0, controller=ControllerSpec("mfol", {"schedule": False}, document=document),
                   environment={"sensors": "ideal"}, reference=reference, metrics=("step_response",))
    result = run(spec)
    from seapup_control.mfol_controller import GainSchedule
    controller = MFOLController(GainSchedule.from_document(document))
    loop = Simulation.from_config("baseline", {"sensors": "ideal"}, control_period=0.2, state=spec.initial_state(),
                                  pitch=start_pitch(spec)).run(controller, 8.0, reference=lambda t: reference.at(t))
    np.testing.assert_array_equal(result.series.states(), loop.state)
    np.testing.assert_array_equal(result.series.reference_array()[:-1], loop.reference[:-1])
    assert result.metrics["outputs"]["u"]["reference"] == 0.1 and "rise95_s" in result.metrics["outputs"]["v"]


def test_a_controller_event_switches_on_its_sample_bumpless_from_the_applied_pitch():
    hover = start_pitch(RunSpec()).tolist()
    other = [0.1, 0.1, -0.2, -0.2]
    spec = RunSpec(duration=4.0, controller=ControllerSpec("hold", {"blade_pitch": hover}),
                   events=(RunEvent(2.0, "controller", {"type": "hold", "parameters": {"blade_pitch": other}}),))
    series = run(spec).series
    k = int(np.argmin(np.abs(series.t - 2.0)))
    np.testing.assert_array_equal(series.command[:k], np.tile(hover, (k, 1)))
    np.testing.assert_array_equal(series.command[k:-1], np.tile(other, (len(series.t) - 1 - k, 1)))
    assert series.events == [{"time": series.t[k], "kind": "controller", "detail": {"type": "hold"}}]


def test_plant_events_land_as_the_simulator_schedules_them():
    spec = RunSpec(duration=4.0, controller=ControllerSpec("hold", {"blade_pitch": start_pitch(RunSpec()).tolist()}),
                   events=(RunEvent(1.0, "current", {"mean_speed": 0.3, "speed_std": 0.0, "mean_direction": 0.0,
                                                     "direction_std": 0.0}),))
    series = run(spec).series
    before, after = series.t <= 1.0, series.t >= 3.0
    assert np.all(np.abs(series.truth["x"][before]) < 1e-12) and np.all(series.truth["x"][after] > 1e-3)  # carried north
    assert series.events[0]["kind"] == "current" and series.events[0]["time"] == 1.0


def test_a_result_round_trips_through_json_with_every_number():
    spec = RunSpec(duration=2.0, controller=ControllerSpec("hold", {"blade_pitch": [0.0, 0.0, 0.1, 0.1]}),
                   environment={"sensors": "baseline"}, metrics=("step_response",))
    result = run(spec)
    again = RunResult.from_json(result.to_json())
    assert again.spec == result.spec and again.transport == "in-process"
    for name in STATE_INDEX:
        np.testing.assert_array_equal(again.series.truth[name], result.series.truth[name])
    for name, values in result.series.measured.items():
        np.testing.assert_array_equal(again.series.measured[name], values)  # NaN (no fix) survives as null
    np.testing.assert_array_equal(again.series.command, result.series.command)
    assert np.isnan(again.series.measured["x"]).any()          # no acoustic fix every sample
    assert again.metrics == jsonable(result.metrics)            # NaN (no limit cycle period) as null
    with pytest.raises(RunResultError, match="not a seapup run result"):
        RunResult.from_json('{"format": "other"}')


def test_unknown_metrics_and_undesigned_controllers_are_refused():
    with pytest.raises(RunSpecError, match="needs a design document"):
        run(RunSpec(duration=1.0, controller=ControllerSpec("mfol")))
    result = run(RunSpec(duration=1.0, controller=ControllerSpec("hold")))
    result.spec = RunSpec(duration=1.0, metrics=("no_such_metric",))
    with pytest.raises(MetricError, match="unknown metric 'no_such_metric'"):
        compute(result)


def test_an_unknown_metric_is_refused_before_the_run_flies(monkeypatch):
    """Before issue 40 ``fly`` flew the whole run (and its self-test) and then refused the metric's name."""
    import seapup_runs.runner as runner
    monkeypatch.setattr(runner, "design", lambda *a, **k: pytest.fail("flew a run whose metric is unknown"))
    with pytest.raises(MetricError, match=r"unknown metric\(s\) \['no_such_metric'\]; known: step_response"):
        run(RunSpec(duration=1.0, metrics=("no_such_metric",)))


@pytest.mark.parametrize("event, message", [
    ({"time": 1.0, "kind": "configuration", "detail": "submarine"}, "configuration event at 1 s"),
    ({"time": 1.0, "kind": "current", "detail": {"mean_speed": 50.0, "speed_std": 0.0, "mean_direction": 0.0,
                                                 "direction_std": 0.0}}, "current event at 1 s"),
])
def test_an_event_that_cannot_happen_is_refused_before_anything_flies(event, message):
    spec = RunSpec(duration=2.0, controller=ControllerSpec("hold"), events=(event,))
    with pytest.raises(RunSpecError, match=message):
        run(spec)


def test_an_open_loop_schedule_is_a_registered_law_timed_from_its_start():
    """Table 3.2's surge test (both mains at +35 deg) after 2 s at hover: the schedule's time 0 is the
    sample the law takes over at, and the flight equals the simulation loop holding the same pitches."""
    from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
    surge = [BLADE_PITCH_LIMIT, BLADE_PITCH_LIMIT, 0.0, 0.0]
    law = {"type": "open_loop", "parameters": {"times": [0.0, 3.0], "pitches": surge + [0.0] * 4}}
    spec = RunSpec(duration=8.0, controller=ControllerSpec("hold"), events=(RunEvent(2.0, "controller", law),),
                   environment={"sensors": "ideal"})
    series = run(spec).series
    t = series.t
    hover = start_pitch(spec)
    np.testing.assert_array_equal(series.command[t < 2.0 - 1e-9], np.tile(hover, ((t < 2.0 - 1e-9).sum(), 1)))
    on = (t > 2.0 - 1e-9) & (t < 5.0 - 1e-9)
    np.testing.assert_array_equal(series.command[on], np.tile(surge, (on.sum(), 1)))
    np.testing.assert_array_equal(series.command[(t > 5.0 - 1e-9)][:-1], 0.0)
    assert series.truth["u"][on].max() > 0.3   # the surge test pushes ahead


@pytest.mark.unit
def test_a_reference_profile_longer_than_the_run_is_measured_on_the_steps_flown():
    """A run cut short of its profile (square-inspection's steps at 30, 40, 50 s, flown 24 s) is scored on
    the last step it flew (20 s), not refused for the steps after its end."""
    from seapup_runs.campaign import campaign_from_dict, expand
    spec = expand(campaign_from_dict({"name": "t", "base": {"scenario": "square-inspection"}}))[0]["spec"]
    from seapup_runs.spec import RunSpec
    short = run(RunSpec.from_dict({**spec, "duration": 24.0}))
    u = short.metrics["outputs"]["u"]
    assert u["reference"] == pytest.approx(0.2)     # the step at 20 s, to 0.2 m/s
    assert 0.0 < u["rise95_s"] < 4.0


def test_design_all_gives_each_spec_design_s_document_working_each_distinct_design_out_once(monkeypatch):
    """A campaign's rows mostly share one design: design_all reads the vehicle and keys the self-test once per
    distinct design, and every spec gets the document design() gives it alone."""
    from seapup_runs import runner
    from seapup_runs.runner import design, design_all
    from seapup_sim import vehicle_config

    def spec(seed, points):
        return RunSpec.from_dict({"name": f"r{seed}", "seed": seed, "duration": 1.0, "controller": {"type": "mfol"},
                                  "design": {"vehicle": "baseline", "operating_points": points}})
    specs = [spec(1, [0.0]), spec(2, [0.0]), spec(3, [0.0, 0.3]), spec(4, [0.0]),
             RunSpec(duration=1.0, controller=ControllerSpec("hold"))]
    alone = [design(s) for s in specs]
    reads = []
    load = vehicle_config.load_vehicle_config
    monkeypatch.setattr(vehicle_config, "load_vehicle_config", lambda name: reads.append(name) or load(name))
    together = design_all(specs)
    assert len(reads) == 2                                     # two distinct designs, not four designed runs
    for a, b in zip(alone, together):
        assert a.to_dict() == b.to_dict()
    assert together[0].controller.document is together[1].controller.document is together[3].controller.document
    assert together[2].controller.document != together[0].controller.document
    assert together[4] is specs[4]                             # nothing to design: the spec itself
    with pytest.raises(RunSpecError, match="needs a design document"):
        runner.design_all([RunSpec(duration=1.0, controller=ControllerSpec("mfol"))])
