"""Chapter 7's cases (sec. 7.4, 7.6) as run specs flown by the self-tuners: the controller by registered name and
its settings by --param, the case's sensors and plant events, the estimate logged as the series' ``estimate`` and
the jacketing in the events and ``metrics.jacket``."""
import json
import math

import numpy as np
import pytest

from seapup_bringup.verbs.scenario_commands import scenario_command
from seapup_runs.result import RunResult
from seapup_runs.runner import run
from seapup_runs.scenarios import scenario_spec, scenarios
from seapup_runs.spec import RunSpecError

CH7 = ("square-surge", "square-sway", "square-heave", "square-yaw", "square-inspection", "square-turn", "yaw-hold",
       "inspection-haslar", "inspection-current", "camera-change", "fouling-change")


def test_every_case_of_chapter_7_is_defined_as_the_thesis_flew_it():
    cases = scenarios()
    assert set(CH7) <= set(cases)
    for name in CH7[:6]:   # square waves of half-period 10 s, zero in the second half, 60 s
        steps = cases[name]["reference"]
        assert cases[name]["duration"] == 60.0 and [s[0] for s in steps] == [0, 10, 20, 30, 40, 50]
        assert all(any(s[1:]) == (k % 2 == 0) for k, s in enumerate(steps))
        assert cases[name]["sensors"] == "baseline"
    assert math.degrees(cases["square-yaw"]["reference"][0][4]) == pytest.approx(31.5)
    assert cases["square-inspection"]["reference"][0][1:] == [0.2, 0.1, 0.1, 0.0]
    assert cases["inspection-haslar"]["sensors"] == "haslar" and cases["yaw-hold"].get("sensors", "ideal") == "ideal"
    spec = scenario_spec("fouling-change", controller="gmv", parameters={"lambda": 0.1, "order": 1})
    assert spec.controller.type == "gmv" and spec.controller.parameters == {"lambda": 0.1, "order": 1}
    assert [(e.time, e.kind, list(e.detail)) for e in spec.events] == [(65.0, "thruster_efficiency", [0.5, 1, 1, 1])]
    camera = scenario_spec("camera-change", controller="explicit", sensors="haslar")
    assert camera.events[0].detail == "camera" and camera.environment["sensors"] == "haslar"
    with pytest.raises(RunSpecError, match="schedule"):
        scenario_spec("square-surge", controller="explicit", schedule=True)


@pytest.mark.parametrize("controller", ["explicit", "gmv"])
def test_a_self_tuner_flies_the_square_surge_and_logs_its_estimate_and_jacketing(controller):
    result = run(scenario_spec("square-surge", controller=controller))
    u = result.series.truth["u"]
    t = result.series.t
    # the third "on" half (40-50 s) is tracked: within 5 % of 0.85 m/s over its last 2 s
    late = (t >= 48.0) & (t < 50.0)
    assert np.all(np.abs(u[late] - 0.85) < 0.05 * 0.85), u[late]
    estimate = result.series.estimate
    assert estimate is not None and estimate["values"].shape == (len(t), len(estimate["names"]))
    assert "trace_P" in estimate["names"] and np.all(np.isfinite(estimate["values"][:-1]))
    jacket = result.metrics["jacket"]
    assert jacket["commissioning"] == 5 and jacket["samples"] == len(t) - 1
    assert jacket["adaptive"] + jacket["fallback"] + jacket["commissioning"] == jacket["samples"]
    modes = [e for e in result.series.events if e["kind"] == "controller_mode"]
    assert modes[0]["detail"]["mode"] == "commissioning" and modes[0]["time"] == 0.0
    assert any(e["detail"]["mode"] == "adaptive" for e in modes)


def test_the_command_takes_controller_settings_and_refuses_bad_ones_in_one_line(tmp_path, capsys):
    out = tmp_path / "gmv.json"
    assert scenario_command(["square-heave", "--controller", "gmv", "--param", "lambda=0.01", "--param", "order=1",
                             "--json", str(out), "--plots", str(tmp_path)]) == 0
    result = RunResult.from_json(out)
    assert result.spec.controller.parameters == {"lambda": 0.01, "order": 1}
    assert result.series.estimate is not None and "f0_w" in result.series.estimate["names"]
    assert list(tmp_path.glob("scenario_square-heave_baseline_5hz_gmv.png"))
    document = json.loads(out.read_text())
    assert document["metrics"]["jacket"]["commissioning"] == 5
    capsys.readouterr()
    for argv in (["square-heave", "--controller", "gmv", "--param", "weighting=0.1"],
                 ["square-heave", "--controller", "gmv", "--param", "lambda"],
                 ["square-heave", "--controller", "no-such-law"],
                 ["square-heave", "--controller", "gmv", "--param", "lambda=-1"]):
        assert scenario_command(argv) == 1, argv
    err = capsys.readouterr().err
    assert err.count("seapup: error:") == 4 and "Traceback" not in err
    assert "weighting" in err and "KEY=VALUE" in err and "no-such-law" in err


@pytest.mark.graph
@pytest.mark.parametrize("name, controller", [("square-heave", "gmv"), ("fouling-change", "explicit")])
def test_a_self_tuner_through_the_ros_graph_flies_the_same_run(name, controller, tmp_path):
    """The registered law in the generic velocity_controller node, told the applied blade pitch by the lockstep
    protocol before each sample (needs_applied): the same commands and motion as in process, sample for sample
    (with the fouled thruster's event carried out by the simulator node)."""
    from seapup_bringup.graph.graph_runner import run_on_graph

    spec = scenario_spec(name, controller=controller)
    graph, local = run_on_graph(spec, out_dir=tmp_path), run(spec)
    np.testing.assert_allclose(graph.series.command, local.series.command, rtol=0, atol=1e-9)
    for key in ("u", "v", "w", "r", "roll", "pitch"):
        np.testing.assert_allclose(graph.series.truth[key], local.series.truth[key], rtol=0, atol=1e-9, err_msg=key)
    assert graph.metrics["outputs"] == local.metrics["outputs"]


def test_the_computing_cost_benchmark_times_every_law_on_the_same_flight():
    """Sec. 7.7's comparison as ./seapup bench makes it (no time asserted: a benchmark, not a timed test): each
    law flies the 60 s inspection square wave and only its own calls are counted, one per control step."""
    from seapup_bringup.graph.graph_bench import THESIS_EXTRA_S, law_step_costs
    costs = law_step_costs(repeats=1)
    assert set(costs) == {"fixed", "scheduled", "explicit", "gmv"}
    assert all(c["steps"] == 300 and c["cpu_us"] > 0 and c["wall_us"] > 0 for c in costs.values())
    assert costs["fixed"]["cpu_ratio_to_fixed"] == 1.0
    assert costs["explicit"]["thesis_ratio_to_fixed"] == pytest.approx(88.0 / 35.0)
    assert costs["gmv"]["thesis_ratio_to_fixed"] == pytest.approx(THESIS_EXTRA_S["gmv"] / 35.0)
