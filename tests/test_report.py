"""``./seapup report``: the thesis's targets scored against runs (flown now or cached), ``report.json`` and one HTML page
rendered in a real browser (headless Chromium, Debian's package).

Truth: the targets file (every target has its row, with the status the scoring gives for the run's own
result), what a reader of the page sees in Chromium (every chapter's section, every target's row with
its status, every figure decoded to a non-zero size, no console error), a cache that reruns nothing
while the code is unchanged, and a deliberately broken metric that turns its rows red.
"""
import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml


ROOT = Path(__file__).resolve().parents[1]

def _seapup(*args, timeout=1200):
    run = subprocess.run([sys.executable, "-m", "seapup_bringup.cli", *args], capture_output=True, text=True,
                         timeout=timeout, cwd=ROOT)
    assert run.returncode == 0, run.stderr[-3000:]
    return run


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    base = tmp_path_factory.mktemp("report")
    first = _seapup("report", "--out", str(base / "out"), "--cache", str(base / "cache"), "--jobs", "2",
                    "--json", str(base / "first.json"))
    return base, json.loads((base / "first.json").read_text()), first


@pytest.mark.process
def test_every_target_is_scored_from_its_run(report):
    from seapup_runs import targets as tg
    base, document, _ = report
    expected = tg.load_targets()
    rows = {r["id"]: r for r in document["targets"]}
    assert sorted(rows) == sorted(t.id for t in expected)
    assert set(document) >= {"commit", "chapters", "pooled", "targets"}
    assert all(r["status"] != "not_run" for r in rows.values())
    results = {r["name"]: json.loads(Path(r["directory"], "run.json").read_text())["result"] for r in document["runs"]}
    for t in expected:  # each run's own result decides its rows (re-scored here; a comparison from both runs)
        again = tg.score(t, results[t.run], results[t.versus["run"]] if t.versus else None)
        assert rows[t.id]["status"] == again.status and rows[t.id]["ratio"] == again.ratio, t.id
    assert any(t.versus for t in expected)
    pooled = document["pooled"]
    assert pooled["asked"] == len(expected) == sum(c["asked"] for c in document["chapters"].values())
    assert pooled["reproduced"] + pooled["deviations"] + pooled["failed"] + pooled["not_run"] == pooled["asked"]
    assert set(document["chapters"]) == {t.chapter for t in expected}
    assert 0 < len(document["largest_misses"]) <= 10
    # every missed deviation counted once under the class of its cause (the register's causes)
    assert sum(pooled["by_class"].values()) == pooled["deviations"]
    for c in tg.CAUSE_CLASSES:
        assert pooled["by_class"][c] == sum(r["status"] == "deviation" and r["deviation"]["class"] == c
                                            for r in rows.values())


@pytest.mark.process
def test_the_page_renders_in_chromium_with_every_section_row_and_figure(report, browser, tmp_path):
    base, document, _ = report
    seen = browser(base / "out" / "report.html", tmp_path)
    assert seen["errors"] == []
    assert {f"chapter-{ch}" for ch in document["chapters"]} | {"summary", "vehicles", "deviations", "made"} \
        <= set(seen["sections"])
    rows = {r[0]: r for r in seen["rows"]}
    assert sorted(rows) == sorted(r["id"] for r in document["targets"])
    colours = {}
    for r in document["targets"]:
        _, status, text, colour, visible = rows[r["id"]]
        assert status == r["status"] and text.replace(" ", "_") == r["status"] and visible, r["id"]
        colours.setdefault(status, set()).add(colour)
    assert all(len(c) == 1 for c in colours.values()) and len({c.pop() for c in colours.values()}) == len(colours)
    runs_with_figures = [r for r in document["runs"] if r["figures"]]
    assert len(seen["imgs"]) >= len(runs_with_figures) >= 3
    assert all(complete and width > 0 and height > 0 for _, complete, width, height in seen["imgs"]), seen["imgs"]
    assert seen["screenshot"].stat().st_size > 10_000   # kept: the test's tmp folder holds report.png


@pytest.mark.process
def test_a_second_report_takes_every_run_from_the_cache(report):
    base, document, _ = report
    _seapup("report", "--out", str(base / "again"), "--cache", str(base / "cache"), "--json", str(base / "second.json"))
    second = json.loads((base / "second.json").read_text())
    assert all(r["cached"] for r in second["runs"]) and not any(r["cached"] for r in document["runs"])
    assert [(r["id"], r["ours"], r["status"]) for r in second["targets"]] == \
        [(r["id"], r["ours"], r["status"]) for r in document["targets"]]


@pytest.mark.process
def test_a_broken_metric_turns_its_rows_red(report, browser, tmp_path):
    """Acceptance: the surge trials' metric pointed at the wrong test (sway's top speed read as surge's)
    fails those rows, and the page shows them red; nothing else changes."""
    from seapup_runs.targets import TARGETS_FILE
    base, document, _ = report
    doc = yaml.safe_load(TARGETS_FILE.read_text())
    broken = [t["id"] for t in doc["targets"] if t.get("metric") == "surge.max_u"]
    for t in doc["targets"]:
        if t["id"] in broken:
            t["metric"] = "sway_4a.max_v"
    changed = tmp_path / "broken.yaml"
    changed.write_text(yaml.safe_dump(doc, sort_keys=False))
    _seapup("report", "--targets", str(changed), "--chapters", "3", "--out", str(tmp_path / "out"),
            "--cache", str(base / "cache"), "--json", str(tmp_path / "broken.json"))
    rows = {r["id"]: r for r in json.loads((tmp_path / "broken.json").read_text())["targets"]}
    before = {r["id"]: r for r in document["targets"]}
    assert sorted(broken) == ["ch3.camera.surge.max_u", "ch3.surge.max_u"]
    assert before["ch3.surge.max_u"]["status"] == "reproduced" and rows["ch3.surge.max_u"]["status"] == "failed"
    assert rows["ch3.camera.surge.max_u"]["status"] in ("failed", "deviation")
    assert all(rows[i]["status"] == before[i]["status"] for i in rows if i not in broken)
    seen = browser(tmp_path / "out" / "report.html", tmp_path)
    red = {r[0]: r[3] for r in seen["rows"]}
    assert red["ch3.surge.max_u"] == next(r[3] for r in seen["rows"] if r[1] == "failed")
    assert red["ch3.surge.max_u"] != next(r[3] for r in seen["rows"] if r[1] == "reproduced")


@pytest.mark.process
def test_bad_arguments_are_one_line_and_change_nothing(tmp_path):
    for args, message in ((["--chapters", "9"], "unknown 9"), (["--jobs", "0"], "at least 1")):
        run = subprocess.run([sys.executable, "-m", "seapup_bringup.cli", "report", "--out", str(tmp_path / "o"), *args],
                             capture_output=True, text=True, timeout=120, cwd=ROOT)
        assert run.returncode == 2 and message in run.stderr and "Traceback" not in run.stderr
    bad = tmp_path / "bad.yaml"
    bad.write_text("schema: 1\ntargets: [{id: x}]\n")
    run = subprocess.run([sys.executable, "-m", "seapup_bringup.cli", "report", "--targets", str(bad), "--out",
                          str(tmp_path / "o")], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert run.returncode == 1 and "missing" in run.stderr and len(run.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


@pytest.mark.process
def test_the_readme_shows_this_commits_scores(report):
    """The README's score table is generated (``./seapup report --readme README.md``), never typed: it must be
    the table of a fresh report of this code."""
    from seapup_bringup.report.page import readme_block
    _, document, _ = report
    assert readme_block(document) in (ROOT / "README.md").read_text(), \
        "README's score table is stale: run ./seapup report --readme README.md"


def test_the_wrong_sign_surge_gains_of_fig_5_19_are_decided_from_the_gain_matrices():
    """Sec. 5.4.2: the thesis's 0.7 m/s gains from the surge error and its integral to both mains were
    negative. Truth: gain matrices made by eq. 4.11's design from a model whose main-thruster surge
    responses have the sign flipped, and from the same model unflipped."""
    import numpy as np

    from seapup_bringup.report.reproduction import _surge_gains
    from seapup_control.mfol import THESIS_POLES_5HZ, MFOLModel, design
    b0 = np.array([[.0026, .0026, .000125, .000125], [-.0001, .0001, -.0004265, .0004265],  # eq. 5.3a
                   [.0000625, .0000625, .000525, .000525], [.2629, -.2629, .001588, -.001588]])
    b1 = 10.0 * b0  # a lag: the steady response ten times the first sample's
    right = _surge_gains(design(MFOLModel(b0, b1, 0.2), THESIS_POLES_5HZ))
    assert not right["main_surge_gains_negative"]
    assert min(right["main_surge_gains"]["K_int"] + right["main_surge_gains"]["K_err"]) > 0
    wrong_b0, wrong_b1 = b0.copy(), b1.copy()
    wrong_b0[0, :2] *= -1.0  # identified: more main thrust, less surge speed
    wrong_b1[0, :2] *= -1.0
    wrong = _surge_gains(design(MFOLModel(wrong_b0, wrong_b1, 0.2), THESIS_POLES_5HZ))
    assert wrong["main_surge_gains_negative"]
    assert max(wrong["main_surge_gains"]["K_int"] + wrong["main_surge_gains"]["K_err"]) < 0


def test_whiteness_is_decided_in_the_thesis_form():
    """Sec. 6.3: residuals are white when 95 % of their autocorrelations at lags > 0 fall within 2 sigma; with
    20 lags one outside still passes, two do not."""
    from seapup_bringup.report.reproduction import _whiteness
    table = {"outputs": ["u", "v", "w"], "inside": [0.95, 0.90, 1.0], "white": [False, False, True]}
    verdict = _whiteness(table)
    assert verdict["white"] == {"u": True, "v": False, "w": True} and verdict["white_on_most"]
    assert verdict["ljung_box_white"] == {"u": False, "v": False, "w": True}
    assert not _whiteness({**table, "inside": [0.95, 0.9, 0.85]})["white_on_most"]


def test_a_run_over_seeds_averages_every_number_found_in_all_of_them():
    """``seeds: N`` (a statement about a random current decided over realisations): the mean of each finite
    number at the same place in every result; statements, lists and values some results lack are left out."""
    from seapup_bringup.report.reproduction import _mean_leaves
    results = [{"station_keep": {"x": 1.0, "y": 2.0}, "limit_cycle": {"detected": True, "period_s": 4.0}, "t": [1, 2]},
               {"station_keep": {"x": 3.0, "y": float("nan")}, "limit_cycle": {"detected": False, "period_s": 6.0}},
               {"station_keep": {"x": 5.0, "y": 1.0}, "limit_cycle": {"detected": True, "period_s": 5.0}, "t": [3]}]
    assert _mean_leaves(results) == {"station_keep": {"x": 3.0}, "limit_cycle": {"period_s": 5.0}}


@pytest.mark.process
def test_the_page_says_which_runs_were_flown_and_which_came_from_the_cache(report):
    """Before: "scored against fresh runs" even when every run came from the cache."""
    from seapup_bringup.report.page import provenance
    base, document, first = report
    page = (base / "out" / "report.html").read_text()
    assert "fresh runs" not in page
    assert f"all {len(document['runs'])} runs flown for this report" in page   # a cold cache: every run flown
    assert provenance([{"cached": True}] * 3) == ("all 3 runs taken from the run cache (flown earlier by this code "
                                                  "version; --no-cache flies them again)")
    assert provenance([{"cached": False}, {"cached": True}, {"cached": True}]).startswith(
        "1 runs flown for this report, 2 taken from the run cache")


@pytest.mark.process
def test_the_page_puts_the_two_vehicles_side_by_side(report):
    """Issue 45's section: the thesis's claim tried on a second ROV. The self-test finished on both; the
    BlueROV2's virtual inputs are decoupled (its mixer) where the Seapup's blade pitches are not (eq. 5.3: the
    mains drive surge and yaw together); every law held every step on both vehicles."""
    _, document, _ = report
    rows = {r["vehicle"]: r for r in document["vehicles"]}
    assert set(rows) == {"baseline", "bluerov2_heavy"}
    assert rows["bluerov2_heavy"]["inputs"] == "virtual" and rows["baseline"]["inputs"] == "direct"
    assert rows["bluerov2_heavy"]["off_diagonal_share"] < 0.05 < rows["baseline"]["off_diagonal_share"]
    assert all(0 < r["self_test_s"] < 300 for r in rows.values())
    for r in rows.values():
        assert set(r["laws"]) == {"mfol", "explicit", "gmv"}
        for law, entry in r["laws"].items():
            assert all(h["share"] < 0.15 for h in entry["held"].values()), (r["vehicle"], law, entry["held"])
            assert 0 < entry["input_peak_share"] <= 1.0
