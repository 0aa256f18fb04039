"""The batch runner (seapup_runs.batch_runner): N runs flown together give each run's own result.

Truth: ``runner.run(spec)`` of each spec alone (itself tested against the thesis and the ROS graph runner).
"""
import copy

import numpy as np
import pytest

from seapup_runs.batch_runner import batch_reason, fly_batch
from seapup_runs.campaign import campaign_from_dict, expand
from seapup_runs.runner import run
from seapup_runs.spec import RunSpec


def _base() -> dict:
    rows = expand(campaign_from_dict({"name": "t", "base": {"scenario": "square-inspection"}}))
    spec = copy.deepcopy(rows[0]["spec"])
    spec["duration"] = 24.0
    return spec


def _variants() -> list[RunSpec]:
    """Vehicles, sensors, currents with a change of statistics, fouling and configuration events, gains
    fixed or scheduled, the thesis's law without anti-windup: each with its own seed."""
    base, out = _base(), []
    current = {"enabled": True, "mean_speed": 0.2, "speed_std": 0.06, "mean_direction": 1.0, "direction_std": 0.3}
    cases = [
        {"vehicle": "baseline", "environment": {"sensors": "ideal"}},
        {"vehicle": "camera", "environment": {"sensors": "baseline", "current": current}},
        {"environment": {"sensors": "haslar", "current": current},
         "events": [{"time": 6.0, "kind": "current", "detail": {"mean_speed": 0.05, "speed_std": 0.01,
                                                                 "mean_direction": -2.0, "direction_std": 0.1}}]},
        {"events": [{"time": 5.0, "kind": "thruster_efficiency", "detail": [0.4, 1.0, 1.0, 1.0]},
                    {"time": 9.0, "kind": "configuration", "detail": "camera"}]},
        {"controller": {"type": "mfol", "parameters": {"schedule": False}}},
        {"controller": {"type": "mfol", "parameters": {"anti_windup": False}},
         "reference": [[0.0, 0.9, 0.3, 0.2, 0.3], [12.0, -0.4, 0.0, 0.0, -0.2]]},
    ]
    for k, case in enumerate(cases):
        spec = copy.deepcopy(base)
        spec.update(copy.deepcopy(case))
        spec["seed"] = 1000 + k
        out.append(RunSpec.from_dict(spec))
    return out


@pytest.mark.unit
def test_each_run_of_a_batch_is_the_run_flown_alone():
    specs = _variants()
    assert all(batch_reason(s) is None for s in specs)
    batched = fly_batch(specs)
    for spec, mine in zip(specs, batched):
        alone = run(spec)
        a, b = alone.series, mine.series
        assert np.array_equal(a.t, b.t)
        assert np.allclose(a.states(), b.states(), rtol=0, atol=1e-9), spec.to_dict()
        assert np.allclose(a.command, b.command, rtol=0, atol=1e-9, equal_nan=True)
        assert np.allclose(a.applied, b.applied, rtol=0, atol=1e-9)
        for name, values in a.measured.items():
            assert np.allclose(values, b.measured[name], rtol=0, atol=1e-9, equal_nan=True), name
            assert np.array_equal(np.isnan(values), np.isnan(b.measured[name])), name   # the same fixes lost
        assert a.events == b.events
        assert alone.metrics.keys() == mine.metrics.keys()
        flat_a, flat_b = _flat(alone.metrics), _flat(mine.metrics)
        assert flat_a.keys() == flat_b.keys()
        for key, value in flat_a.items():
            if isinstance(value, float):
                assert flat_b[key] == pytest.approx(value, rel=1e-6, abs=1e-9, nan_ok=True), key
            else:
                assert flat_b[key] == value, key
    # and the runs differ from each other: the variants were flown, not one run six times
    finals = np.array([r.series.states()[-1, 6] for r in batched])
    assert np.ptp(finals) > 0.05


def _flat(value, prefix=""):
    out = {}
    if isinstance(value, dict):
        for k, v in value.items():
            out.update(_flat(v, f"{prefix}{k}."))
    elif isinstance(value, np.ndarray):
        out.update(_flat(value.tolist(), prefix))
    elif isinstance(value, (list, tuple)):
        for k, v in enumerate(value):
            out.update(_flat(v, f"{prefix}{k}."))
    else:
        out[prefix] = float(value) if isinstance(value, (int, float, np.floating)) and not isinstance(value, bool) \
            else value
    return out


@pytest.mark.unit
def test_what_a_batch_cannot_fly_is_named_and_refused():
    base = _base()
    hold = RunSpec.from_dict({**base, "controller": {"type": "hold"}})
    assert "mfol, explicit, gmv" in batch_reason(hold)
    switched = RunSpec.from_dict({**base, "events": [{"time": 4.0, "kind": "controller", "detail": {"type": "gmv"}}]})
    assert "no switches" in batch_reason(switched)
    assert batch_reason(RunSpec.from_dict({**base, "controller": {"type": "gmv"}})) is None
    cable = RunSpec.from_dict({**base, "environment": {"umbilical": {"enabled": True}}})
    assert "umbilical" in batch_reason(cable)
    with pytest.raises(ValueError, match="cannot fly in a batch"):
        fly_batch([RunSpec.from_dict(base), hold])
    with pytest.raises(ValueError, match="one control period"):
        fly_batch([RunSpec.from_dict(base), RunSpec.from_dict({**base, "duration": 10.0})])


@pytest.mark.unit
def test_the_self_tuners_in_a_batch_are_the_runs_flown_alone_bit_for_bit():
    """Explicit and GMV runs (ch. 7's randomised cases: fouling, the camera fitted mid-run, currents, the three
    sensor profiles, the laws' settings) flown as one batch with MFOL runs among them: each self-tuner run's
    series -- states, commands, readings, estimate traces, mode events -- and metrics with the jacket's counts
    are those of the run flown alone, bit for bit; what each law logged is filed under its own run."""
    from seapup_runs.batch_runner import RUN_INDEX, batch_key
    from seapup_runs.campaign import run_log
    from seapup_runs.randomised import random_adaptive_spec
    candidates = [random_adaptive_spec(number) for number in range(60)]
    grid = batch_key(candidates[0])
    tuners = [s for s in candidates if batch_key(s) == grid and batch_reason(s) is None][:6]
    assert {s.controller.type for s in tuners} == {"explicit", "gmv"}
    mfol = RunSpec.from_dict({**tuners[0].to_dict(), "controller": {"type": "mfol"}, "name": "mfol"})
    specs = [tuners[0], mfol, *tuners[1:]]
    with run_log() as lines:
        batched = fly_batch(specs)
    assert RUN_INDEX.get() is None
    engaged = 0
    for position, (spec, mine) in enumerate(zip(specs, batched)):
        if spec is mfol:
            continue
        with run_log() as alone_lines:
            alone = run(spec)
        a, b = alone.series, mine.series
        for left, right in ((a.t, b.t), (a.states(), b.states()), (a.command, b.command), (a.applied, b.applied),
                            (a.estimate["values"], b.estimate["values"])):
            np.testing.assert_array_equal(left, right)
        assert a.estimate["names"] == b.estimate["names"] and a.events == b.events
        for name, values in a.measured.items():
            np.testing.assert_array_equal(values, b.measured[name])
        flat_a, flat_b = _flat(alone.metrics), _flat(mine.metrics)
        assert flat_a.keys() == flat_b.keys()
        for key, value in flat_a.items():
            assert value == flat_b[key] or (value != value and flat_b[key] != flat_b[key]), key   # NaN: NaN
        assert mine.metrics["jacket"]["samples"] == spec.samples
        assert lines.by_run.get(position, []) == list(alone_lines)
        engaged += mine.metrics["jacket"]["engagements"] + mine.metrics["jacket"]["adaptive"]
    assert engaged > 0
