"""Tests of the ./seapup command registry and the commands' --json convention."""
import pytest
import json
import subprocess
import sys

import numpy as np

from seapup_bringup.cli import COMMANDS, main

pytestmark = pytest.mark.graph  # runs ./seapup, a build or subprocesses: not a seconds-fast unit test


def test_every_registered_command_has_help_text_and_answers_help():
    for name, entry in COMMANDS.items():
        assert entry.summary, name
        if entry.run is None or name in ("test", "run"):
            continue
        r = subprocess.run([sys.executable, "-m", "seapup_bringup.cli", name, "--help"],
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 0 and "--json" in r.stdout, (name, r.stdout + r.stderr)


def test_unknown_command_exits_2_with_one_line(capsys):
    assert main(["frobnicate"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("seapup: unknown command 'frobnicate'") and err.count("\n") == 1


def test_the_commands_parsed_before_the_bootstrap_answer_help(capsys):
    for name in ("setup", "env", "lock", "help", "run"):
        assert main([name, "--help"]) == 0
        assert capsys.readouterr().out.startswith(f"usage: ./seapup {name}")


def test_check_model_json_goes_to_stdout_and_text_to_stderr():
    r = subprocess.run([sys.executable, "-m", "seapup_bringup.cli", "check-model", "--json"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    data = json.loads(r.stdout)
    assert data["ok"] is True and data["findings"] == [] and len(data["sweep"]) == 11
    assert "no findings" in r.stderr


def test_cli_writes_the_documented_json(tmp_path, capsys):
    out = tmp_path / "v.json"
    code = main(["verify", "--config", "baseline", "--json", str(out), "--plots", str(tmp_path / "p")])
    text = capsys.readouterr().out
    assert "PASS" in text
    data = json.loads(out.read_text())
    primary_failed = [r for r in data["checks"] if r["primary"] and not r["pass"]]
    assert code == (1 if primary_failed else 0) and data["summary"]["ok"] == (not primary_failed)
    assert text.rstrip().splitlines()[-1].startswith("summary: primary ")  # the summary comes last
    assert {r["status"] for r in data["checks"]} <= {"PASS", "FAIL", "DEV"}
    for key in ("config", "rest_trim_deg", "surge", "sway_4a", "sway_4b", "heave_down", "heave_up",
                "roll_release", "pitch_release", "hover_blade_pitch_deg", "trim_0_7",
                "eigenvalues_quiescent", "nmp_onset_surge", "step_gains_5hz", "current", "umbilical"):
        assert key in data, key
    assert set(data["surge"]) >= {"max_u", "steady_pitch_deg", "max_pitch_deg", "max_pitch_rate_dps", "rise95_s"}
    assert set(data["sway_4a"]) == {"max_v", "max_roll_deg", "max_roll_rate_dps"}
    assert set(data["climb"]) == {"max_pitch_deg", "max_u", "max_rise_w"}
    assert set(data["fast_turn"]) == {"max_r_dps", "max_u", "max_roll_deg"}
    assert set(data["roll_release"]) >= {"stable", "eigenvalue"}
    assert np.array(data["step_gains_5hz"]["B0inv"]).shape == (4, 4)
    assert len(data["hover_blade_pitch_deg"]) == 4 and len(data["eigenvalues_quiescent"]) == 12
    assert {p.name for p in (tmp_path / "p").glob("*.png")} == {
        "fig3_2_roll_release.png", "fig3_3_pitch_release.png", "fig3_4_surge.png",
        "fig3_11_umbilical.png", "fig3_12_current.png", "fig3_5_heave.png", "fig3_6_sway.png",
        "fig3_8_3_10_loci.png", "appA_climb.png", "appA_fast_turn.png"}
    assert set(data["current"]) == {"a_c", "b", "d", "E_wc2", "w_alpha_per_w_c", "sample_mean", "sample_std"}
    assert set(data["umbilical"]) == {"50", "100", "200"}
    assert set(data["umbilical"]["50"]) == {"max_u", "Fx", "Fz"}


def test_verify_checks_a_virtual_input_vehicle_against_its_paper_or_says_why_it_cannot(tmp_path, capsys):
    """Issue 45: ``./seapup verify --config bluerov2_heavy`` flies the description against [vB]'s own equations
    (it had ended in an exception's name); a virtual-input vehicle with no published reference is refused in one
    line naming why, not with Table 3.2's blade-pitch tests."""
    out = tmp_path / "v.json"
    assert main(["verify", "--config", "bluerov2_heavy", "--json", str(out), "--plots", str(tmp_path / "p")]) == 0
    data = json.loads(out.read_text())
    assert data["reference"] == "von_benzon_2022" and data["summary"] == {"ok": True, "passed": 5, "checks": 5}
    assert {r["test"] for r in data["checks"]} >= {"surge ahead", "heave down", "yaw to starboard"}
    assert [p.name for p in (tmp_path / "p").glob("*.png")] == ["reference_responses.png"]
    capsys.readouterr()
    assert main(["verify", "--config", "bluerov2_heavy_t200"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no published reference model" in err and "Error" not in err


def test_did_you_mean_never_suggests_the_mistyped_name_itself():
    """The graph lists a service once a client asks for it, so the probe's own client for the typo was the
    "nearest" name: "service /seapup/simulatr/get_parameters is not available; did you mean
    /seapup/simulatr/get_parameters?"."""
    from seapup_bringup.ros2cli.ros2_commands import _did_you_mean
    typo, right = "/seapup/simulatr/get_parameters", "/seapup/simulator/get_parameters"
    assert _did_you_mean(typo, [typo, right, "/seapup/navigator/get_parameters"]) == f"; did you mean {right}?"
    assert _did_you_mean(typo, [typo]) == ""


def test_a_campaign_worker_logs_an_error_in_one_line():
    """The workers' log filter (dask_worker_setup.OneLine): an exception logged with a record becomes its type
    and reason after the message, no traceback (a worker's failed heartbeat once printed a screen of them)."""
    import io
    import logging
    from seapup_bringup.dask_worker_setup import OneLine
    stream = io.StringIO()
    handler = logging.StreamHandler(stream)
    handler.addFilter(OneLine())
    logger = logging.getLogger("test.one_line")
    logger.addHandler(handler)
    logger.propagate = False
    try:
        try:
            raise OSError("Stream is closed")
        except OSError:
            logger.exception("Failed to communicate with scheduler during %s.", "heartbeat")
    finally:
        logger.removeHandler(handler)
    assert stream.getvalue() == ("Failed to communicate with scheduler during heartbeat. "
                                 "(OSError: Stream is closed)\n")


def test_a_file_that_cannot_be_written_is_said_with_its_reason_not_an_exception_s_name(tmp_path, capsys):
    from seapup_bringup.cli import error_reason
    assert main(["view", "--write-layout", str(tmp_path / "no" / "such" / "dir.json")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "No such file or directory" in err and "Error" not in err
    assert not (tmp_path / "no").exists()
    assert error_reason(IsADirectoryError(21, "Is a directory", "/tmp")) == "Is a directory: /tmp"
    assert error_reason(RuntimeError("first\nsecond")) == "RuntimeError: first"   # a bug, named for its report


def test_the_bench_draws_its_cost_curves_with_their_workloads(tmp_path):
    """Issue 42 item 5: ./seapup bench --plots DIR draws cost against N and threads, and runs/s against workers,
    each titled with what was flown (here from a bench's own dictionary, as the verb hands it over)."""
    from seapup_bringup.campaign_runner import workload
    from seapup_bringup.verbs.model_commands import bench_plots
    from seapup_runs.spec import RunSpec
    spec = RunSpec.from_dict({"vehicle": "camera", "environment": {"sensors": "haslar", "current": {
        "enabled": True, "mean_speed": 0.26}}, "control_period": 0.2, "duration": 30.0,
        "controller": {"type": "mfol", "parameters": {"schedule": False}}})
    text = workload(spec)
    assert text == "camera, mfol (schedule False), haslar sensors, a 0.26 m/s Gauss-Markov current, T = 0.2 s over 30 s"
    point = {"cpu_us_per_vehicle_step": 4.0, "vehicle_steps_per_s": 250000.0}
    out = {"batch_threads": {str(n): {"1": point, "2": point} for n in (1, 10, 100)},
           "batch_plant": {"workload": "N x baseline"},
           "campaign": {"runs": 8, "workload": text, "runs_per_s_1_worker": 100.0, "runs_per_s_2_workers": 180.0}}
    paths = bench_plots(out, tmp_path / "plots")
    assert [p.name for p in paths] == ["bench_batch.png", "bench_workers.png"]
    assert all(p.read_bytes().startswith(b"\x89PNG") and p.stat().st_size > 5000 for p in paths)
    del out["campaign"]
    assert [p.name for p in bench_plots(out, tmp_path / "again")] == ["bench_batch.png"]


def test_a_task_s_table_keeps_every_metric_of_every_run():
    """A task's rows as the campaign writes them (campaign_runner._columns_safe, then pyarrow): a metric only a
    later run has (a change event's figures, a step on an axis the first run held) is kept for it, None for the
    others -- pyarrow's from_pylist takes its columns from the first row and dropped such a metric for every run
    of the task (adaptive-500 lost figures of about a hundred runs in tasks of 10) -- and an integer metric is a
    float whatever run comes first."""
    import pyarrow as pa
    from seapup_bringup.campaign_runner import _columns_safe
    records = [{"index": 0, "status": "ok", "metric.a": 1, "param.seed": 3},
               {"index": 1, "status": "ok", "metric.a": 2.5, "metric.change.time_s": 8.6, "param.seed": 4},
               {"index": 2, "status": "failed", "error": "diverged", "param.seed": 5}]
    table = pa.Table.from_pylist(_columns_safe(records)).to_pydict()
    assert table["metric.change.time_s"] == [None, 8.6, None]
    assert table["metric.a"] == [1.0, 2.5, None] and table["error"] == [None, None, "diverged"]
    assert table["param.seed"] == [3, 4, 5] and pa.Table.from_pylist(_columns_safe(records)).schema.field(
        "metric.a").type == pa.float64()
