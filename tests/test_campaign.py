"""./seapup campaign: a campaign flown on a Dask LocalCluster, its table, its page, resuming (issue 26).

Truth: the same runs flown directly in this process by seapup_runs.runner (the table must hold exactly their
metrics), the campaign file's own expansion, and the files a resumed campaign leaves untouched.
"""
import io
import json
import math
import os
import subprocess
import sys

import pytest
import yaml

from seapup_runs import campaign as cp
from seapup_runs.runner import run
from seapup_runs.spec import RunSpec

SHORT = {"name": "short", "duration": 3.0, "controller": {"type": "hold"},
         "reference": [[0.0, 0.0, 0.0, 0.0, 0.0]], "metrics": ["step_response"]}


def _file(tmp_path, **changes):
    doc = {"name": "dask-trial", "doc": "four short runs", "base": {"spec": SHORT},
           "grid": {"vehicle": ["baseline", "camera"], "environment.sensors": ["ideal", "baseline"]},
           "seeds": [5], "runs_per_task": 1,
           "summary": {"metrics": ["pitch_deg.peak", "roll_deg.peak"], "worst_by": "pitch_deg.peak", "worst": 2}}
    doc.update(changes)
    path = tmp_path / "campaign.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def _same(a, b) -> bool:
    return a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b))


@pytest.mark.process
def test_a_campaign_on_a_local_cluster_writes_every_run_s_metrics_and_resumes(tmp_path):
    import pyarrow.parquet as pq

    from seapup_bringup.campaign_runner import run_campaign
    campaign = cp.load_campaign(_file(tmp_path))
    out = tmp_path / "out"
    summary = run_campaign(campaign, out, workers=2)
    assert summary["runs"] == summary["ok"] == 4 and summary["errors"] == 0 and summary["tasks"] == 4
    table = pq.read_table(out / "results.parquet").to_pylist()
    assert [r["index"] for r in table] == [0, 1, 2, 3]
    for row, expected in zip(table, cp.expand(campaign)):
        assert row["param.vehicle"] == expected["parameters"]["vehicle"] and row["param.seed"] == 5
        direct = cp.flatten(run(RunSpec.from_dict(expected["spec"])).metrics)
        assert direct and all(_same(row[f"metric.{k}"], v) for k, v in direct.items()), row["index"]
    page = (out / "index.html").read_text()
    assert page.count("<img") == 2 and "dask-trial" in page and "./seapup fly" in page
    worst = summary["worst"]
    assert len(worst) == 2 and worst[0]["pitch_deg.peak"] >= worst[1]["pitch_deg.peak"]
    assert RunSpec.from_dict(json.loads(open(worst[0]["spec"]).read())).vehicle in ("baseline", "camera")
    # interrupted: one task's part is lost and another's cut short (a corrupt Parquet file); --resume says so in
    # one line and flies only those two, and the table is the same
    (out / "parts" / "task-00002.parquet").unlink()
    corrupt = out / "parts" / "task-00001.parquet"
    corrupt.write_bytes(corrupt.read_bytes()[:40])
    before = {p.name: p.stat().st_mtime_ns for p in (out / "parts").iterdir() if p != corrupt}
    said = io.StringIO()
    again = run_campaign(campaign, out, workers=1, resume=True, text=said)
    assert again["tasks_reused"] == 2 and again["runs"] == 4
    assert [line for line in said.getvalue().splitlines() if "task-00001" in line] == [
        line for line in said.getvalue().splitlines() if line.startswith("task-00001.parquet: unreadable (")]
    assert "task-00001.parquet: unreadable" in said.getvalue()
    assert all((out / "parts" / name).stat().st_mtime_ns == t for name, t in before.items())
    # resuming converges: nothing left to fly the second time
    assert run_campaign(campaign, out, workers=1, resume=True, text=io.StringIO())["tasks_reused"] == 4
    timed = ("wall_s", "cpu_s")   # the re-flown task's own timings differ, nothing else
    resumed = pq.read_table(out / "results.parquet").to_pylist()
    assert [sorted(r) for r in resumed] == [sorted(r) for r in table]
    assert all(_same(a[k], b[k]) for a, b in zip(resumed, table) for k in a if k not in timed)
    # a changed file cannot resume into the same directory
    changed = cp.load_campaign(_file(tmp_path, seeds=[6]))
    with pytest.raises(cp.CampaignError, match="another campaign"):
        run_campaign(changed, out, workers=1, resume=True)


@pytest.mark.process
def test_the_command_refuses_a_bad_file_and_an_unreachable_scheduler_with_one_line(tmp_path):
    env = dict(os.environ)
    bad = _file(tmp_path, grid={"vehicle": ["submarine"]})
    proc = subprocess.run([sys.executable, "-m", "seapup_bringup.cli", "campaign", str(bad)], capture_output=True,
                          text=True, env=env, timeout=120)
    assert proc.returncode == 1 and proc.stderr.strip().count("\n") == 0 and "submarine" in proc.stderr
    good = _file(tmp_path)
    proc = subprocess.run([sys.executable, "-m", "seapup_bringup.cli", "campaign", str(good), "--out",
                           str(tmp_path / "x"), "--scheduler", "tcp://127.0.0.1:9", "--connect-timeout", "3"],
                          capture_output=True, text=True, env=env, timeout=180)
    assert proc.returncode == 1 and "no Dask scheduler at tcp://127.0.0.1:9" in proc.stderr
    assert "Traceback" not in proc.stderr and not (tmp_path / "x").exists()   # nothing written
    proc = subprocess.run([sys.executable, "-m", "seapup_bringup.cli", "campaign", str(good), "--out",
                           str(tmp_path / "y"), "--connect-timeout", "nan"], capture_output=True, text=True,
                          env=env, timeout=120)
    assert proc.returncode == 2 and "--connect-timeout" in proc.stderr and proc.stderr.strip().count("\n") == 0
    assert not (tmp_path / "y").exists()   # refused: nothing written


MISSION_BASE = {
    "graph": {"mode": "lockstep", "initial_controller": "", "seed": 3, "start_depth": 50.0, "sensors": "baseline",
              "current": False, "seabed_kind": "flat", "seabed_depth": 100.0},
    "mission": [
        {"name": "tune", "kind": "self_test", "goal": {"operating_points": [0.0]},
         "configure": ["mfol_fixed", "mfol_scheduled", "explicit", "gmv"], "activate": "mfol_fixed"},
        {"name": "hold", "kind": "hover", "goal": {"hold_current": True, "duration": 6.0}},
        {"name": "fouled", "kind": "fouling", "body_velocity": [0.15, 0.0, 0.0], "fouled_seconds": 6.0,
         "foul": {"after": 2.0, "efficiency": [1.0, 1.0, 1.0, 1.0]},
         "switch": {"activate": ["gmv"], "deactivate": ["mfol_fixed"]}, "adaptive_seconds": 6.0, "tune_in": 2.0}]}


@pytest.mark.process
def test_a_mission_campaign_gives_the_same_table_on_a_local_cluster_and_on_a_separate_scheduler(tmp_path):
    """Issue 44: a campaign over whole missions -- the hierarchy flown in process on Dask workers -- each row the
    mission's own numbers (run_mission flown here), the same table however the work is distributed, and the worst
    mission written as a file ./seapup fly reads (on the graph: --graph)."""
    import pyarrow.parquet as pq
    from distributed import LocalCluster

    from seapup_bringup.campaign_runner import attach_hierarchies, run_campaign
    from seapup_bringup.graph.hierarchy_config import hierarchy_config
    from seapup_runs.mission import MissionSpec
    from seapup_runs.mission_flight import run_mission
    path = tmp_path / "missions.yaml"
    path.write_text(yaml.safe_dump({
        "name": "fouled-missions", "doc": "a short mission, each main thruster fouled in turn, two seeds",
        "base": {"mission": MISSION_BASE}, "runs_per_task": 1,
        "grid": {"mission.2.foul.efficiency": [[0.4, 1.0, 1.0, 1.0], [1.0, 0.4, 1.0, 1.0]]}, "seeds": [1, 2],
        "summary": {"metrics": ["legs.fouled.track_adaptive", "legs.hold.hold_rms"],
                    "worst_by": "legs.fouled.track_adaptive", "worst": 1}}))
    campaign = cp.load_campaign(path)
    rows = cp.expand(campaign)
    assert [r["parameters"] for r in rows] == [
        {"mission.2.foul.efficiency": e, "graph.seed": s} for e in ([0.4, 1.0, 1.0, 1.0], [1.0, 0.4, 1.0, 1.0])
        for s in (1, 2)]
    assert rows[1]["spec"]["graph"]["seed"] == 2 and rows[2]["spec"]["mission"][2]["foul"]["efficiency"][1] == 0.4
    local = run_campaign(campaign, tmp_path / "local", workers=2, text=io.StringIO())
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        remote = run_campaign(campaign, tmp_path / "remote", scheduler=cluster.scheduler_address, text=io.StringIO())
    assert local["runs"] == local["ok"] == remote["ok"] == 4, (local, remote)
    a = pq.read_table(tmp_path / "local" / "results.parquet").to_pylist()
    b = pq.read_table(tmp_path / "remote" / "results.parquet").to_pylist()
    metrics = sorted(k for k in a[0] if k.startswith(("metric.", "param.")))
    assert "metric.legs.fouled.track_adaptive" in metrics and "metric.legs_failed" in metrics
    for x, y in zip(a, b):
        assert all(_same(x[k], y[k]) for k in metrics), x["index"]
    # each row is the mission flown by itself, here
    attach_hierarchies(rows)
    direct = run_mission(MissionSpec.load(rows[3]["spec"]), hierarchy_config(rows[3]["spec"]["graph"]))
    expected = cp.mission_metrics(direct)
    assert all(_same(a[3][f"metric.{k}"], v) for k, v in expected.items() if isinstance(v, float))
    assert a[3]["metric.legs.fouled.foul_t"] < a[3]["metric.legs.fouled.switch_t"]
    worst = local["worst"][0]
    again = MissionSpec.load(json.loads(open(worst["spec"]).read()))
    assert again.graph["seed"] in (1, 2) and "--graph" in (tmp_path / "local" / "index.html").read_text()


def test_the_shipped_mission_campaign_varies_the_demo_s_current_and_fouling_legs():
    """demo-mission-robustness names the demo's legs by index: its draws and grid must land on the station-keeping
    current and the fouled thruster, in every one of its 32 missions."""
    from seapup_bringup.campaign_runner import ship_missions
    from seapup_runs.mission import MissionSpec
    ship_missions()
    rows = cp.expand(cp.load_campaign("demo-mission-robustness"))
    assert len(rows) == 8 * 4 and all(r["kind"] == "mission" for r in rows)
    for row in rows:
        legs = MissionSpec.load(row["spec"]).legs
        assert legs[5]["kind"] == "current" and legs[6]["kind"] == "fouling"
        assert 0.0 <= legs[5]["current"]["mean_speed"] <= 0.35 and min(legs[6]["foul"]["efficiency"]) in (0.3, 0.65)
    assert len({json.dumps(r["spec"], sort_keys=True) for r in rows}) == 32
