"""Campaign files (seapup_runs.campaign): what a file expands into, what it refuses, and a task's rows.

Truth: the run specs built by hand from the same base and values, the randomised specs of
seapup_runs.randomised, and runs flown directly by seapup_runs.runner.
"""
import math
from pathlib import Path

import numpy as np
import pytest

from seapup_runs import campaign as cp
from seapup_runs.randomised import random_adaptive_spec
from seapup_runs.runner import run
from seapup_runs.spec import RunSpec

BASE = {"spec": {"name": "short", "duration": 2.0, "controller": {"type": "hold"},
                 "reference": [[0.0, 0.0, 0.0, 0.0, 0.0]], "metrics": ["step_response"]}}
FOUL = {"time": 1.0, "kind": "thruster_efficiency", "detail": [0.5, 1.0, 1.0, 1.0]}


def _doc(**changes):
    doc = {"name": "trial", "base": BASE, "grid": {"vehicle": ["baseline", "camera"],
                                                   "control_period": [0.2, 0.1, 0.05]},
           "random": {"count": 2, "seed": 4, "draws": {
               "environment.current": {"choice": [{"enabled": False}, {"enabled": True, "mean_speed": 0.2}]},
               "environment.current.mean_direction": {"uniform": [-1.0, 1.0]},
               "events+": {"choice": [[], [FOUL]]}}},
           "seeds": 2, "runs_per_task": 5}
    doc.update(changes)
    return doc


@pytest.mark.unit
def test_a_campaign_expands_into_every_combination_draw_and_seed_in_order():
    campaign = cp.campaign_from_dict(_doc())
    rows = cp.expand(campaign)
    assert len(rows) == 2 * 3 * 2 * 2 and [r["index"] for r in rows] == list(range(24))
    assert rows == cp.expand(cp.campaign_from_dict(_doc()))          # the same file, the same runs
    for row in rows:
        p, spec = row["parameters"], RunSpec.from_dict(row["spec"])
        assert spec.vehicle == p["vehicle"] and spec.control_period == p["control_period"] and spec.seed == p["seed"]
        current = dict(spec.environment.get("current") or {})
        assert current["mean_direction"] == p["environment.current.mean_direction"]
        assert current["enabled"] == p["environment.current"]["enabled"]
        assert [e.to_dict() for e in spec.events] == [FOUL] * len(p["events+"])
        assert -1.0 <= p["environment.current.mean_direction"] <= 1.0
    # two seeds per point, the same two everywhere, and another campaign's are others
    seeds = {r["parameters"]["seed"] for r in rows}
    assert len(seeds) == 2
    assert seeds.isdisjoint({r["parameters"]["seed"] for r in cp.expand(cp.campaign_from_dict(_doc(name="other")))})
    # the draws differ between the points of a grid, and both choices occur
    assert len({r["parameters"]["environment.current.mean_direction"] for r in rows}) == 12
    assert {len(r["parameters"]["events+"]) for r in rows} == {0, 1}
    # tasks: every run once, at most five a task, each task in index order, the runs of one sample grid side by side
    groups = cp.tasks(rows, 5)
    assert len(groups) == 5 and max(len(g) for g in groups) == 5
    assert sorted(r["index"] for g in groups for r in g) == list(range(len(rows)))
    assert all([r["index"] for r in g] == sorted(r["index"] for r in g) for g in groups)
    keys = [cp.batch_group(r) for g in groups for r in sorted(g, key=cp.batch_group)]
    assert keys == sorted(keys) and len(set(keys)) > 1   # grouped, and there were several grids to group


@pytest.mark.unit
def test_another_law_starts_from_its_defaults_and_its_parameters_are_checked_before_flying():
    """The shipped scenario's mfol carries schedule: false; switching the law must not hand it to explicit."""
    doc = {"name": "laws", "base": {"scenario": "square-inspection"},
           "grid": {"controller.parameters.forgetting": [0.98], "controller.type": ["explicit", "gmv"]}}
    rows = cp.expand(cp.campaign_from_dict(doc))
    assert [r["spec"]["controller"] for r in rows] == [{"type": "explicit", "parameters": {"forgetting": 0.98}},
                                                       {"type": "gmv", "parameters": {"forgetting": 0.98}}]
    kept = cp.expand(cp.campaign_from_dict({**doc, "grid": {"controller.type": ["mfol"]}}))
    assert kept[0]["spec"]["controller"]["parameters"] == {"schedule": False}   # the same law keeps them
    with pytest.raises(cp.CampaignError, match="has no parameter"):
        cp.campaign_from_dict({**doc, "grid": {"controller.parameters.lambda": [0.1], "controller.type": ["explicit"]}})


@pytest.mark.unit
def test_randomised_campaigns_are_the_randomised_runs():
    campaign = cp.campaign_from_dict({"name": "r", "randomised": {"count": 4, "first": 10}})
    rows = cp.expand(campaign)
    assert [r["parameters"]["number"] for r in rows] == [10, 11, 12, 13]
    assert all(r["spec"] == random_adaptive_spec(r["parameters"]["number"]).to_dict() for r in rows)
    assert all(r["parameters"]["controller.type"] == r["spec"]["controller"]["type"] for r in rows)


@pytest.mark.unit
@pytest.mark.parametrize("change, message", [
    ({"colour": "red"}, "unknown key"),
    ({"name": "a b"}, "name must be"),
    ({"runs_per_task": 0}, "runs_per_task"),
    ({"grid": {"vehicle": []}}, "non-empty list"),
    ({"random": {"count": 1, "draws": {"seed": {"gaussian": [0, 1]}}}}, "a draw is one of"),
    ({"random": {"count": 1, "draws": {"duration": {"loguniform": [0, 1]}}}}, "positive"),
    ({"grid": {"control_period": [0.13]}}, "run 0 .*control_period"),
    ({"grid": {"vehicle": ["submarine"]}}, "run 0"),
    ({"base": {"scenario": "no-such-case"}}, "no scenario"),
    ({"randomised": {"count": 3}}, "either base"),
    ({"seeds": 0}, "seeds is a count"),
])
def test_a_bad_campaign_file_is_refused_with_one_line(change, message):
    with pytest.raises(cp.CampaignError, match=message) as caught:
        cp.campaign_from_dict(_doc(**change))
    assert "\n" not in str(caught.value)


@pytest.mark.unit
def test_the_shipped_campaigns_load_and_ask_the_thesis_s_questions():
    shipped = cp.shipped()
    assert {"controller-robustness", "adaptive-500"} <= set(shipped)
    robust = cp.expand(cp.load_campaign("controller-robustness"))
    assert len(robust) == 3 * 2 * 2 * 3 * 3
    assert {r["parameters"]["controller.type"] for r in robust} == {"mfol", "explicit", "gmv"}
    assert {r["parameters"]["vehicle"] for r in robust} == {"baseline", "camera"}
    assert len(cp.expand(cp.load_campaign("adaptive-500"))) == 500


@pytest.mark.unit
def test_a_task_flies_its_runs_and_a_failing_run_is_a_row_with_its_reason():
    rows = cp.expand(cp.campaign_from_dict(_doc(grid={"vehicle": ["baseline", "camera"]}, random={}, seeds=[3])))
    bad = {**rows[1], "index": 99, "spec": {**rows[1]["spec"], "controller": {"type": "hold", "parameters": {"x": 1}}}}
    out = cp.fly_rows([rows[0], bad])
    assert [r["index"] for r in out] == [0, 99] and [r["status"] for r in out] == ["ok", "error"]
    assert out[1]["error"] and "\n" not in out[1]["error"] and not any(k.startswith("metric.") for k in out[1])
    direct = cp.flatten(run(RunSpec.from_dict(rows[0]["spec"])).metrics)
    mine = {k.removeprefix("metric."): v for k, v in out[0].items() if k.startswith("metric.")}
    assert mine.keys() == direct.keys() and len(mine) > 5
    for key, value in direct.items():
        assert mine[key] == value or (isinstance(value, float) and math.isnan(value) and math.isnan(mine[key])), key
    assert out[0]["param.vehicle"] == "baseline" and out[0]["param.seed"] == 3 and out[0]["cpu_s"] > 0


@pytest.mark.unit
def test_a_task_of_mfol_runs_flies_them_as_one_batch_with_each_run_s_own_row():
    """Runs of one MFOL law on one sample grid share a batch (seapup_runs.batch_runner): each row's metrics are
    its run's alone (to rounding), one failing row does not spoil the others, and the rest fly one by one."""
    from seapup_runs.batch_runner import batch_reason
    doc = {"name": "mfol", "base": {"scenario": "square-inspection"}, "grid": {"vehicle": ["baseline", "camera"]},
           "random": {"count": 2, "seed": 8, "draws": {"events+": {"choice": [[], [{**FOUL, "time": 5.0}]]}}},
           "seeds": 1, "runs_per_task": 10}
    rows = cp.expand(cp.campaign_from_dict(doc))
    for row in rows:
        row["spec"]["duration"] = 12.0
    hold = {**cp.expand(cp.campaign_from_dict(_doc(random={}, seeds=[3])))[0], "index": 50}
    assert batch_reason(RunSpec.from_dict(rows[0]["spec"])) is None
    assert batch_reason(RunSpec.from_dict(hold["spec"])) is not None
    out = cp.fly_rows(rows + [hold])
    assert [r["index"] for r in out] == [r["index"] for r in rows] + [50]
    assert all(r["status"] == "ok" for r in out)
    for row, record in zip(rows + [hold], out):
        direct = cp.flatten(run(RunSpec.from_dict(row["spec"])).metrics)
        mine = {k.removeprefix("metric."): v for k, v in record.items() if k.startswith("metric.")}
        assert mine.keys() == direct.keys() and len(mine) > 5
        for key, value in direct.items():
            if isinstance(value, float):
                assert mine[key] == pytest.approx(value, rel=1e-6, abs=1e-9, nan_ok=True), key
            else:
                assert mine[key] == value, key


@pytest.mark.unit
def test_what_a_run_logs_is_kept_in_its_row_not_printed(monkeypatch, caplog):
    """A worker flies hundreds of runs: their cores' log lines (a jacket falling back) go to each run's row."""
    import logging

    import seapup_runs.runner

    def noisy(spec):
        for k in range(25):
            logging.getLogger("seapup_control.explicit").warning("fallback %d (estimated pole |z| = 1.4)", k)
        raise ValueError("diverged")
    rows = cp.expand(cp.campaign_from_dict(_doc(grid={"vehicle": ["baseline"]}, random={}, seeds=[3])))
    monkeypatch.setattr(seapup_runs.runner, "run", noisy)
    before = logging.getLogger("seapup_control").propagate
    (row,) = cp.fly_rows(rows[:1])
    assert row["status"] == "error" and row["error"] == "ValueError: diverged"
    assert row["log_lines"] == 25
    assert row["log"].splitlines() == [f"warning: fallback {k} (estimated pole |z| = 1.4)"
                                       for k in range(cp.LOG_LINES_KEPT)]
    assert not caplog.records, "nothing reached the process's handlers"
    assert logging.getLogger("seapup_control").propagate == before
    logging.getLogger("seapup_control.explicit").warning("after the task")
    assert [r.getMessage() for r in caplog.records] == ["after the task"], "the loggers are given back"


@pytest.mark.unit
def test_flatten_keeps_scalars_and_short_numeric_lists():
    flat = cp.flatten({"a": {"b": 1, "c": True, "d": "x", "e": [1, 2], "f": list(range(9)), "g": None},
                       "h": np.float64(2.5)})
    assert flat == {"a.b": 1.0, "a.c": True, "a.d": "x", "a.e.0": 1.0, "a.e.1": 2.0, "h": 2.5}


# -- bounded and strict (issue 40) ---------------------------------------------------------------------------
TEN = list(range(10))


@pytest.mark.unit
@pytest.mark.parametrize("change, runs", [
    ({"grid": {k: TEN for k in "abcdefg"}, "random": None, "seeds": 1}, r"1e\+07 runs \(10 a x 10 b"),
    ({"grid": None, "random": None, "seeds": 10_000_000}, r"1e\+07 runs \(10000000 seeds\)"),
    ({"grid": None, "random": {"count": 100_000_000, "draws": {"start_depth": {"uniform": [1.0, 2.0]}}}},
     r"2e\+08 runs \(random.count 100000000 x 2 seeds\)"),
    ({"base": None, "grid": None, "random": None, "seeds": None, "randomised": {"count": 100_000_000}},
     r"1e\+08 runs \(randomised.count\)"),
])
def test_a_campaign_too_large_is_refused_from_its_counts_before_anything_is_expanded(monkeypatch, change, runs):
    """Before issue 40 each of these expanded every run first: no answer in 30-120 s and 1.5-2.6 GB."""
    import time
    doc = {k: v for k, v in _doc(**change).items() if v is not None}
    for name in ("_base_spec", "_draw", "RunSpec"):
        monkeypatch.setattr(cp, name, lambda *a, **k: pytest.fail("expanded before the count was checked"))
    monkeypatch.setattr("seapup_runs.randomised.random_adaptive_spec", lambda *a, **k: pytest.fail("expanded"))
    cpu = time.process_time()
    with pytest.raises(cp.CampaignError, match=runs + ".*more than the 100,000 a campaign may have") as caught:
        cp.campaign_from_dict(doc)
    assert time.process_time() - cpu < 1.0 and "SEAPUP_MAX_CAMPAIGN_RUNS" in str(caught.value)


@pytest.mark.unit
def test_the_campaign_cap_is_the_product_of_the_counts_and_can_be_raised(monkeypatch):
    doc = _doc()                                                     # 2 x 3 grid, 2 draws, 2 seeds: 24 runs
    assert cp.run_count(cp.Campaign("trial", "", doc)) == 24 == len(cp.expand(cp.campaign_from_dict(doc)))
    monkeypatch.setenv("SEAPUP_MAX_CAMPAIGN_RUNS", "23")
    with pytest.raises(cp.CampaignError, match=r"24 runs \(2 vehicle x 3 control_period x random.count 2 x 2 seeds"):
        cp.campaign_from_dict(doc)
    monkeypatch.setenv("SEAPUP_MAX_CAMPAIGN_RUNS", "24")
    assert len(cp.expand(cp.campaign_from_dict(doc))) == 24


@pytest.mark.unit
@pytest.mark.parametrize("change, message", [
    ({"seeds": "1e7"}, r"seeds is a count .*got 1e7 \(text, not a number"),
    ({"seeds": [1, True]}, "seeds is a count"),
    ({"random": {"count": "1e8", "draws": {"seed": {"integers": [0, 1]}}}}, "random.count must be an integer"),
    ({"random": {"count": 1, "seed": "abc", "draws": {"seed": {"integers": [0, 1]}}}}, "random.seed must be"),
    ({"random": {"count": 1, "draws": {"start_depth": {"normal": [0, -1]}}}}, r"normal takes \[mean, standard"),
    ({"random": {"count": 1, "draws": {"seed": {"integers": [0, 1e300]}}}}, "integers takes two integers"),
    ({"random": {"count": 1, "draws": {"seed": {"integers": [5, 1]}}}}, "low <= high"),
    ({"random": {"count": 1, "draws": {"start_depth": {"uniform": [-1e308, 1e308]}}}}, "a finite width"),
    ({"random": {"count": 1, "draws": {"start_depth": {"uniform": [0, 10**400]}}}}, "two finite numbers"),
    ({"grid": {"reference.0": [1]}}, "reference is not a mapping"),
    ({"grid": {"reference.0.1": [1]}}, "not a mapping"),
    ({"grid": {"name+": ["x"]}}, r"name is not a list in the run spec"),
    ({"grid": {"events+": [[{"time": "abc", "kind": "configuration", "detail": "camera"}]]}, "random": {}},
     "event time must be a number, got 'abc'$"),
    ({"grid": {"events+": [[]]}}, r'\["events\+"\] both in grid and in random.draws'),
    ({"summary": {"worst": "abc"}}, "summary.worst is an integer"),
    ({"summary": {"metrics": "abc"}}, "summary.metrics is a list"),
    ({"name": {"a": 1}}, "name must be"),
    ({"name": ".."}, "name must be"),
    ({"doc": ["x"]}, "doc must be text"),
    ({"base": {"scenario": "square-surge", "rate_hz": "5"}}, "base.rate_hz must be a number"),
    ({"base": {"scenario": "square-surge", "rate_hz": 0}}, "base.rate_hz must be a number in"),
    ({"base": {"scenario": "square-surge", "schedule": "no"}}, "base.schedule is true or false"),
    ({"base": {"scenario": ["square-surge"]}}, "base.scenario is a name"),
    ({"base": {"spec": {**BASE["spec"], "metrics": ["nope"]}}}, r"run 0 .*unknown metric\(s\) \['nope'\]"),
])
def test_hostile_campaign_values_get_a_reason_not_an_exception_s_words(change, message):
    """Before issue 40: numpy's 'scale < 0' and 'low >= high', OverflowError, AttributeError ('list' object has
    no attribute 'get'), a string seed count converted or a ValueError from int('abc') after the flights."""
    with pytest.raises(cp.CampaignError, match=message) as caught:
        cp.campaign_from_dict(_doc(**change))
    assert "\n" not in str(caught.value)


@pytest.mark.unit
def test_a_campaign_file_is_read_bounded_and_strictly(tmp_path):
    dup = tmp_path / "dup.yaml"
    dup.write_text("name: a\nname: b\nbase: {scenario: square-surge}\n")
    with pytest.raises(cp.CampaignError, match="duplicate key 'name'"):
        cp.load_campaign(dup)
    for path, why in ((tmp_path / "empty.yaml", "is empty"), ("/dev/zero", "larger than 1 MiB"),
                      (tmp_path, "is a directory")):
        if isinstance(path, Path) and path.suffix:
            path.write_text("# nothing but a comment\n")
        with pytest.raises(cp.CampaignError, match=why):
            cp.load_campaign(path)


MISSION = {"graph": {"seed": 0, "start_depth": 40.0},
           "mission": [{"name": "tune", "kind": "self_test", "configure": ["mfol_fixed"], "activate": "mfol_fixed"},
                       {"name": "hold", "kind": "hover", "goal": {"duration": 5.0}},
                       {"name": "foul", "kind": "fouling", "body_velocity": [0.1, 0.0, 0.0], "fouled_seconds": 4.0,
                        "foul": {"after": 1.0, "efficiency": [1.0, 1.0, 1.0, 1.0]},
                        "switch": {"activate": ["gmv"]}, "adaptive_seconds": 4.0}]}


@pytest.mark.unit
def test_a_mission_campaign_expands_into_mission_documents_a_leg_by_its_index():
    doc = {"name": "missions", "base": {"mission": MISSION}, "seeds": [7, 8],
           "grid": {"mission.2.foul.efficiency": [[0.5, 1.0, 1.0, 1.0]], "graph.sensors": ["ideal", "baseline"]}}
    campaign = cp.campaign_from_dict(doc)
    rows = cp.expand(campaign)
    assert cp.is_mission(campaign) and len(rows) == 4 and all(r["kind"] == "mission" for r in rows)
    assert [(r["spec"]["graph"]["sensors"], r["spec"]["graph"]["seed"]) for r in rows] == [
        ("ideal", 7), ("ideal", 8), ("baseline", 7), ("baseline", 8)]
    assert all(r["spec"]["mission"][2]["foul"]["efficiency"] == [0.5, 1.0, 1.0, 1.0] for r in rows)
    assert MISSION["mission"][2]["foul"]["efficiency"] == [1.0, 1.0, 1.0, 1.0]   # the base is not changed
    assert rows[0]["parameters"] == {"mission.2.foul.efficiency": [0.5, 1.0, 1.0, 1.0], "graph.sensors": "ideal",
                                     "graph.seed": 7}


@pytest.mark.unit
@pytest.mark.parametrize("grid, message", [
    ({"mission.9.foul.efficiency": [[0.5, 1, 1, 1]]}, "9 is not an index of a list of 3"),
    ({"mission.2.foul.efficiency": [[2.0, 1, 1, 1]]}, "run 0 (mission.2.foul.efficiency=[2.0, 1, 1, 1], "
                                                      "graph.seed=1): mission leg 3 ('foul', fouling) foul "
                                                      "efficiency must be values in [0, 1], one per thruster"),
    ({"mission.1.goal.duration": ["5"]}, "goal duration must be a number, got '5'"),
])
def test_a_mission_campaign_refuses_a_path_or_a_value_its_missions_cannot_take(grid, message):
    import re
    with pytest.raises(cp.CampaignError, match=re.escape(message)):
        cp.campaign_from_dict({"name": "m", "base": {"mission": MISSION}, "grid": grid, "seeds": [1]})


@pytest.mark.unit
def test_a_mission_row_without_its_hierarchy_is_a_failed_row_with_the_reason():
    rows = cp.expand(cp.campaign_from_dict({"name": "m", "base": {"mission": MISSION}, "seeds": [1]}))
    record, = cp.fly_rows(rows)
    assert record["status"] == "error" and "needs the hierarchy's nodes" in record["error"]


@pytest.mark.unit
def test_a_task_batches_its_self_tuners_only_among_enough_runs_and_keeps_each_run_s_log():
    """_fly_batched: on one sample grid, two MFOL runs batch with or without self-tuners beside them; self-tuners
    join only a batch of at least MIN_TUNER_BATCH runs (fewer fly one by one, as they gain nothing); in such a
    batch each tuner's row carries the log lines its own law said -- those of the run flown alone -- beside
    the batch's shared ones, and its metrics are the run's own."""
    from seapup_runs.batch_runner import batch_key, batch_reason
    tuners = [s for s in (random_adaptive_spec(k) for k in range(80)) if batch_reason(s) is None]
    grid = batch_key(tuners[0])
    tuners = [s for s in tuners if batch_key(s) == grid][:cp.MIN_TUNER_BATCH]
    mfol = [RunSpec.from_dict({**tuners[k].to_dict(), "controller": {"type": "mfol"}, "name": f"mfol-{k}"})
            for k in range(2)]

    def rows(specs):
        return [{"index": k, "parameters": {"seed": k}, "spec": spec.to_dict()} for k, spec in enumerate(specs)]
    few = rows([*mfol, *tuners[:3]])
    assert sorted(cp._fly_batched(few)) == [0, 1]   # the tuners fly one by one
    many = rows([mfol[0], *tuners])
    batched = cp._fly_batched(many)
    assert sorted(batched) == list(range(len(many)))
    said = 0
    for k, spec in enumerate(tuners, start=1):
        with cp.run_log() as lines:
            alone = run(spec)
        # its row: the batch's shared lines (all the MFOL row has) and exactly what its law said alone
        assert batched[k]["log_lines"] == batched[0]["log_lines"] + len(lines)
        said += len(lines)
        assert batched[k]["metric.jacket.samples"] == alone.metrics["jacket"]["samples"]
        assert batched[k]["metric.adaptive.tracking_rms_total"] == alone.metrics["adaptive"]["tracking_rms_total"]
    assert said > 0   # some law said something (a fallback, a mode change): the filing was tested
