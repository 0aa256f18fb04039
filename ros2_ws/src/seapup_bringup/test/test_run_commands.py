"""./seapup fly and ./seapup controllers: runs and control laws as data on the command line."""
import json
from pathlib import Path

import numpy as np
import yaml

from seapup_bringup.verbs.run_commands import controllers, fly
from seapup_runs.result import RunResult

EXAMPLE = Path(__file__).resolve().parents[2] / "seapup_runs" / "seapup_runs" / "data" / "specs" / "drift_then_hold.yaml"


def test_the_example_spec_flies_in_process_and_its_json_is_a_run_result(tmp_path, capsys):
    out = tmp_path / "drift.json"
    assert fly([str(EXAMPLE), "--json", str(out), "--plots", str(tmp_path)]) == 0
    result = RunResult.from_json(out)
    assert result.spec.name == "drift-then-hold" and result.transport == "in-process"
    t = result.series.t
    assert [e["kind"] for e in result.series.events] == ["controller", "configuration"]
    drift, held = (t > 5.0) & (t <= 10.0), t >= 20.0
    speed = np.hypot(result.series.truth["u"], result.series.truth["v"])
    assert speed[drift].max() > 0.05 and speed[held].max() < speed[drift].max()  # carried, then held
    np.testing.assert_array_equal(result.series.command[(t > 0) & (t < 10.0)][0], result.series.applied[0])
    assert list(tmp_path.glob("*.png"))
    assert "run drift-then-hold" in capsys.readouterr().out


def test_bad_specs_are_one_line_errors_and_nothing_is_flown(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    for text in ("duraton: 3\n", "controller: {type: no_such_law}\n", "events: [{time: 1, kind: teleport}]\n",
                 "control_period: 0.15\n", "- not a mapping\n", "reference: [[0, 1, 2]]\n"):
        bad.write_text(text)
        assert fly([str(bad)]) == 1, text
    assert fly([str(tmp_path / "missing.yaml")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 7 and all(line.startswith("seapup: error: ") for line in err), err


def test_controllers_lists_every_registered_law_with_its_parameters(tmp_path):
    out = tmp_path / "controllers.json"
    assert controllers(["--json", str(out)]) == 0
    listed = json.loads(out.read_text())
    assert {"hold", "mfol"} <= set(listed["controllers"]) and listed["not_loaded"] == {}
    assert listed["controllers"]["mfol"]["parameters"]["schedule"] is True
    assert listed["controllers"]["mfol"]["needs_document"] and not listed["controllers"]["hold"]["needs_document"]
    yaml.safe_dump(listed)  # plain data
