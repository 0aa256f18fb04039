"""``./seapup ident``: the open-loop PRBS experiment recorded through ROS, and fits from its bag and from CSV.

Truths: the experiment's own schedule (every sample recorded once, the PRBS levels applied), a
known generating system for the CSV fit, and the model's one-step predictions explaining the
recorded motion far better than its mean.
"""
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from seapup_ident.armax import ArmaxModel, ArmaxOrders
from seapup_ident.prbs import prbs


def ident(env, *args, timeout=300):
    return subprocess.run([sys.executable, "-m", "seapup_bringup.cli", "ident", *map(str, args)], env=env,
                          capture_output=True, text=True, timeout=timeout)


def assert_in_process_is_the_graph_s(env, tmp_path, bag, *args):
    """``ident experiment --in-process`` with the same ARGS gives the graph's record sample for sample (the
    in-process transport's equality, once per case: open loop, linearised in current, closed loop)."""
    from seapup_bringup.graph.identification import bag_data, load_source
    out = tmp_path / "in_process"
    local = ident(env, "experiment", "--in-process", *args, "--out", out, "--json", tmp_path / "in_process.json")
    assert local.returncode == 0, (local.stdout + local.stderr)[-2000:]
    doc = json.loads((tmp_path / "in_process.json").read_text())
    assert doc["record"] == str(out / "run.json") and doc["transport"] == "in-process" and "bag" not in doc
    graph, here = bag_data(bag), load_source(doc["record"], None, None, "ch6")
    graph_doc = json.loads((Path(bag).parent / "experiment.json").read_text())
    assert not graph_doc["ended_waits"], f"the graph's flight was not deterministic: {graph_doc['ended_waits']}"
    assert graph.outputs == here.outputs and graph.inputs == here.inputs
    np.testing.assert_allclose(here.t, graph.t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(here.y, graph.y, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(here.u, graph.u, rtol=1e-12, atol=1e-15)
    return doc


@pytest.mark.graph
def test_experiment_records_every_sample_and_its_bag_fits(tmp_path, ros_env):
    from seapup_bringup.graph.identification import bag_data
    from seapup_sim.analysis import hover_blade_pitch
    from seapup_sim.vehicle import VehicleModel
    from seapup_sim.vehicle_config import load_vehicle_config

    run = ident(ros_env, "experiment", "--duration", 30, "--out", tmp_path / "exp", "--json", tmp_path / "exp.json")
    assert run.returncode == 0, (run.stdout + run.stderr)[-2000:]
    bag = json.loads((tmp_path / "exp.json").read_text())["bag"]
    data = bag_data(bag)
    # 30 s at 5 Hz: t = 0 .. 29.8 s, each with its interval's pitch (read at the next sample, t <= 30 s)
    assert len(data.t) == 150 and np.all(np.isfinite(data.y)) and np.all(np.isfinite(data.u))
    np.testing.assert_allclose(np.diff(data.t), 0.2, atol=1e-9)                # no sample missing
    hover = hover_blade_pitch(VehicleModel(load_vehicle_config("baseline")))
    # the input of each interval, read at its end: +-10 deg about hover, the 0.05 s actuator lag
    # settled to within 2 % of a switch (e^-4) by then
    offset = np.abs(data.u - hover)
    assert offset.max() <= np.radians(10) + 1e-9
    assert np.all(np.isclose(offset, np.radians(10), atol=np.radians(0.4)))
    # (e) ch. 6's findings on this record: second order needed (F-test, 5 % risk) on most outputs, and
    # ELS slightly better than LS (lower AIC, within 10 %) on most outputs (Tables 6.2, 6.3)
    from seapup_ident.identify import compare_methods, order_table
    from seapup_ident.recursive import Forgetting
    schedule = lambda: Forgetting.schedule(0.6, 0.9)  # noqa: E731
    assert sum(order_table(data, 2, forgetting_factory=schedule)["rows"][1]["significant"]) >= 4
    methods = compare_methods(data, 2, ("ls", "els"), forgetting_factory=schedule)["methods"]
    ls, els = np.array(methods["ls"]["aic"]), np.array(methods["els"]["aic"])
    assert np.sum(els < ls) >= 4 and np.all(np.abs(els - ls) < 0.1 * np.abs(ls))
    fit = ident(ros_env, "fit", bag, "--orders", "2,2,0", "--passes", 3, "--json", tmp_path / "fit.json")
    assert fit.returncode == 0, fit.stdout + fit.stderr
    doc = json.loads((tmp_path / "fit.json").read_text())
    assert doc["orders"] == [2, 2, 0] and np.shape(doc["A"]) == (2, 6, 6) and np.shape(doc["B"]) == (2, 6, 4)
    assert doc["outputs"] == ["u", "v", "w", "r", "roll", "pitch"] and doc["data"]["non_finite"] == 0
    assert np.all(np.asarray(doc["loss"]) < 0.2 * np.var(data.y, axis=0))    # explains the motion
    # (f) the identifier estimated online during the run; fitting the readings it recorded, with the
    # same settings, gives the model it published last
    from rclpy.serialization import deserialize_message
    from seapup_common.bag import read_bag
    from seapup_msgs.msg import IdentifiedModel
    identifier_bag = json.loads((tmp_path / "exp.json").read_text())["identifier_bag"]
    models = [deserialize_message(m.cdr, IdentifiedModel) for m in read_bag(identifier_bag, ["/seapup/identifier/model"])]
    assert 140 <= len(models) <= 151 and models[-1].samples == len(models)
    offline = ident(ros_env, "fit", identifier_bag, "--orders", "2,2,0", "--json", tmp_path / "offline.json")
    assert offline.returncode == 0, offline.stdout + offline.stderr
    again = json.loads((tmp_path / "offline.json").read_text())
    last = models[-1]
    np.testing.assert_allclose(np.ravel(again["A"]), last.a, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(np.ravel(again["B"]), last.b, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(again["d"], last.d, rtol=1e-9, atol=1e-12)
    assert_in_process_is_the_graph_s(ros_env, tmp_path, bag, "--duration", 30)


def test_fit_from_csv_through_the_command_recovers_a_known_system(tmp_path, ros_env):
    model = ArmaxModel(ArmaxOrders(1, 2, 1, 1, 0), np.array([[[-0.8]]]), np.array([[[0.4, -0.2]]]),
                       np.zeros((0, 1, 1)), np.array([0.1]))
    rng = np.random.default_rng(2)
    u = prbs(1000, clock=4, n_inputs=2, nbits=9)
    y = model.simulate(u, 0.01 * rng.normal(size=(1000, 1)))
    path = tmp_path / "run.csv"
    np.savetxt(path, np.column_stack([y, u]), delimiter=",", header="y0,ua,ub", comments="")
    run = ident(ros_env, "fit", path, "--orders", "1,1,0", "--json", tmp_path / "m.json")
    assert run.returncode == 0, run.stdout + run.stderr
    doc = json.loads((tmp_path / "m.json").read_text())
    np.testing.assert_allclose(doc["A"], [[[-0.8]]], atol=0.01)
    np.testing.assert_allclose(doc["B"], [[[0.4, -0.2]]], atol=0.01)
    np.testing.assert_allclose(doc["d"], [0.1], atol=0.01)
    # a missing column, a least-squares noise model and a non-source: one clear line, exit 1
    for args, reason in ((["--outputs", "nope"], "not found"), (["--orders", "1,1,1"], "no noise model")):
        bad = ident(ros_env, "fit", path, *args)
        assert bad.returncode == 1 and reason in bad.stdout + bad.stderr
    bad = ident(ros_env, "fit", tmp_path / "missing.txt")
    assert bad.returncode == 1 and "neither a bag directory, a run result (.json) nor a .csv file" in bad.stdout + bad.stderr
    # the comparison's and the residual test's plots and JSON; the right model's residuals are white
    # and a too-low order's are not (its missing B_2 term leaves the input in them)
    run = ident(ros_env, "compare", path, "--order", 1, "--points", 2000, "--rpem-k0", 0.1, "--plots",
                tmp_path / "plots", "--json", tmp_path / "cmp.json")
    assert run.returncode == 0, run.stdout + run.stderr
    table = json.loads((tmp_path / "cmp.json").read_text())
    assert set(table["methods"]) == {"ls", "els", "rpem"} and table["rpem_filter"] == [0.1, 0.98]
    assert all(m["scored"] == 2000 - 2 for m in table["methods"].values())   # 2 passes of 1000, each fills 1 lag
    assert table["scope"]["samples"] == 1000 and not table["scope"]["trimmed"]  # no t column: t = sample number
    assert "data: 1000 samples, t = 0 .. 999 s" in run.stdout
    assert [p.endswith(".png") for p in table["plots"]] == [True] * 3
    assert all((tmp_path / "plots" / name).stat().st_size > 10_000 for name in
               ("ident_ls_1_1_0.png", "ident_els_1_1_1.png", "ident_rpem_1_1_1.png"))
    run = ident(ros_env, "residuals", path, "--orders", "1,1,0", "--passes", 2, "--plots", tmp_path / "plots",
                "--json", tmp_path / "res.json")
    assert run.returncode == 0, run.stdout + run.stderr
    res = json.loads((tmp_path / "res.json").read_text())
    assert res["white"] == [True] and np.shape(res["autocorrelation"]) == (1, 21)
    assert (tmp_path / "plots" / "ident_residuals_ls.png").is_file()
    low = ident(ros_env, "residuals", path, "--orders", "1,1,0", "--inputs", "ua", "--json", tmp_path / "low.json")
    assert low.returncode == 0 and json.loads((tmp_path / "low.json").read_text())["white"] == [False]
    for args, reason in ((["compare", path, "--passes", 2, "--points", 100], "--passes or --points"),
                         (["fit", path, "--duration", 0.5], "duration must be >= one sample period"),
                         (["experiment", "--duration", 10.1], "a whole number of 0.2 s sample periods"),
                         (["orders", path, "--risk", 0], "risk alpha must be in (0, 1)"),
                         (["residuals", path, "--orders", "1,1,0", "--lags", 0], "max_lag >= 1"),
                         (["fit", path, "--orders", "2,x"], "three integers"),
                         (["experiment", "--duration", -5], "--duration must be > 0"),
                         (["experiment", "--closed-loop", "--references", "a,b"], "two rows of four")):
        bad = ident(ros_env, *args)
        assert bad.returncode == 1 and reason in bad.stdout + bad.stderr, (args, bad.stdout + bad.stderr)
    bad = ident(ros_env, "fit", path, "--duration", "x")                  # argparse's usage error
    assert bad.returncode == 2 and "--duration must be seconds > 0 or 'all'" in bad.stderr


@pytest.mark.graph
def test_closed_loop_experiment_follows_the_square_wave_and_identifies(tmp_path, ros_env):
    """Sec. 6.5.5: the fixed-gain self-tested controller on the square wave; the loop tracks it (the
    recorded truth), and the record identifies: yaw rate, roll and pitch need second order
    (Table 6.6) and the model's one-step predictions explain the motion."""
    from rclpy.serialization import deserialize_message
    from nav_msgs.msg import Odometry
    from seapup_common.bag import read_bag

    run = ident(ros_env, "experiment", "--closed-loop", "--duration", 40, "--out", tmp_path / "cl",
                "--json", tmp_path / "cl.json")
    assert run.returncode == 0, (run.stdout + run.stderr)[-2000:]
    doc = json.loads((tmp_path / "cl.json").read_text())
    assert doc["excitation"] == "closed_loop" and (tmp_path / "cl" / "controller.yaml").is_file()
    truth = [deserialize_message(m.cdr, Odometry) for m in read_bag(doc["bag"], ["/seapup/truth/odometry"])]
    t = np.array([m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in truth])
    twist = np.array([[m.twist.twist.linear.x, m.twist.twist.linear.y, m.twist.twist.linear.z,
                       m.twist.twist.angular.z] for m in truth])
    assert t[0] == 0.0 and len(t) >= 200
    # settled halves of each half-period: (0.2 m/s, 0, 0, 15 deg/s) then (0, 0.1, -0.1 m/s, 0) (body FRD)
    first = ((t % 20) > 5) & ((t % 20) < 10)
    second = ((t % 20) > 15) & ((t % 20) < 20)
    np.testing.assert_allclose(twist[first].mean(axis=0), [0.2, 0, 0, np.radians(15)], atol=0.015)
    np.testing.assert_allclose(twist[second].mean(axis=0), [0, 0.1, -0.1, 0], atol=0.015)
    orders = ident(ros_env, "orders", doc["bag"], "--max-order", 2, "--json", tmp_path / "orders.json")
    assert orders.returncode == 0, orders.stdout + orders.stderr
    table = json.loads((tmp_path / "orders.json").read_text())
    significant = dict(zip(table["outputs"], table["rows"][1]["significant"]))
    assert significant["r"] and significant["roll"] and significant["pitch"]
    fit = ident(ros_env, "fit", doc["bag"], "--method", "els", "--orders", "2,2,2", "--json", tmp_path / "fit.json")
    assert fit.returncode == 0, fit.stdout + fit.stderr
    from seapup_bringup.graph.identification import bag_data
    data = bag_data(doc["bag"])
    assert np.all(np.asarray(json.loads((tmp_path / "fit.json").read_text())["loss"]) < 0.1 * np.var(data.y, axis=0))
    local = assert_in_process_is_the_graph_s(ros_env, tmp_path, doc["bag"], "--closed-loop", "--duration", 40,
                                             "--controller", tmp_path / "cl" / "controller.yaml")
    assert local["references"] == doc["references"] and local["half_period"] == doc["half_period"]


@pytest.mark.graph
def test_experiment_on_the_linearised_model(tmp_path, ros_env):
    """--dynamics linearised and --current reach the simulator node: it flies eq. 3.2 about hover (sec. 6.5.1) in
    the Gauss-Markov current (sec. 6.5.4), and the in-process experiment flies the same."""
    run = ident(ros_env, "experiment", "--dynamics", "linearised", "--current", "--duration", 10,
                "--out", tmp_path / "lin", "--json", tmp_path / "lin.json")
    assert run.returncode == 0, (run.stdout + run.stderr)[-2000:]
    doc = json.loads((tmp_path / "lin.json").read_text())
    assert doc["dynamics"] == "linearised" and doc["current"] is True
    assert "vehicle baseline (linearised)" in (tmp_path / "lin" / "simulator.log").read_text()
    assert_in_process_is_the_graph_s(ros_env, tmp_path, doc["bag"], "--dynamics", "linearised", "--current",
                                      "--duration", 10)


def short_record(n, period=0.2):
    from seapup_ident.identify import IdentificationData
    u = prbs(n, clock=4, n_inputs=1, nbits=7)
    return IdentificationData(np.zeros((n, 1)), u, period * np.arange(n), ("y",), ("u",))


def test_scope_scores_what_the_experiment_asked_for_and_says_so():
    from seapup_bringup.graph.identification import scope
    record = short_record(425)                                 # run on to 84.8 s (issue 22's record)
    scored, doc, lines = scope(record, asked=60.0)
    assert doc["samples"] == 300 and doc["t"] == [0.0, pytest.approx(59.8)] and doc["seconds"] == pytest.approx(60)
    assert doc["record"]["samples"] == 425 and doc["trimmed"] and doc["asked_s"] == 60.0 and doc["duration_s"] == 60
    np.testing.assert_array_equal(scored.u, record.u[:300])
    assert lines == ["note: the record holds 425 samples (85 s), longer than the 60 s its experiment asked for; "
                     "scoring the first 60 s (--duration all scores all of it)",
                     "data: 300 samples, t = 0 .. 59.8 s (T = 0.2 s, 60 s of inputs), the first 60 s of a "
                     "425-sample record"]
    # --duration all: the whole record, still said to be longer than asked
    scored, doc, lines = scope(record, math.inf, asked=60.0)
    assert doc["samples"] == 425 and not doc["trimmed"] and doc["duration_s"] is None
    assert lines[0].endswith("longer than the 60 s its experiment asked for; scoring all of it")
    assert lines[1] == "data: 425 samples, t = 0 .. 84.8 s (T = 0.2 s, 85 s of inputs)"
    # --duration shorter than asked; a record of exactly what was asked (300 = 60 s / 0.2 s): no note
    assert scope(record, 10.0, asked=60.0)[1]["samples"] == 50
    scored, doc, lines = scope(short_record(300), asked=60.0)
    assert doc["samples"] == 300 and not doc["trimmed"] and len(lines) == 1 and lines[0].startswith("data: 300")
    # no experiment record: all of it unless --duration says otherwise
    assert scope(record)[1]["samples"] == 425 and len(scope(record)[2]) == 1
    assert scope(record, 20.0)[1]["samples"] == 100


def test_experiment_record_is_found_next_to_the_bag_it_names(tmp_path):
    from seapup_bringup.graph.identification import experiment_record
    bag, identifier = tmp_path / "bag", tmp_path / "identifier"
    bag.mkdir(), identifier.mkdir()
    assert experiment_record(bag) is None
    (tmp_path / "experiment.json").write_text(json.dumps({"bag": str(bag), "identifier_bag": str(identifier),
                                                          "duration": 60.0}))
    assert experiment_record(bag)["duration"] == 60.0 and experiment_record(identifier)["duration"] == 60.0
    other = tmp_path / "other"
    other.mkdir()
    assert experiment_record(other) is None                  # a bag the record does not name
    assert experiment_record(tmp_path / "run.csv") is None
    (tmp_path / "experiment.json").write_text("{not json")
    assert experiment_record(bag) is None


def test_an_experiment_flies_a_whole_number_of_samples():
    from seapup_bringup.graph.identification import experiment_samples
    assert experiment_samples(60.0, 0.2) == 300 and experiment_samples(10, 0.2) == 50
    assert experiment_samples(0.2, 0.2) == 1 and experiment_samples(3600.0, 0.2) == 18000
    for bad in (10.1, 0.1, 0.0, -5.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="whole number of 0.2 s sample periods"):
            experiment_samples(bad, 0.2)


@pytest.mark.graph
def test_an_experiment_ends_at_its_duration_in_graph_time(tmp_path, ros_env):
    """Issue 22: a 60 s experiment once recorded 84.8 s. The simulator now stops stepping at the
    experiment's end (its end_time), so a 10 s experiment records exactly t = 0, 0.2, ..., 10 s --
    51 samples on every sample topic, and its record says what it asked for. (The end_time hold itself is
    unit-tested in seapup_common's lockstep server; one experiment here, twice took 37 s of a loaded suite.)"""
    from seapup_bringup.graph.identification import bag_data
    from seapup_common.bag import read_bag
    sample_topics = ("/seapup/truth/odometry", "/seapup/sensors/velocity", "/seapup/sensors/imu",
                     "/seapup/sensors/depth", "/seapup/thrusters/applied", "/seapup/thrusters/command")
    out = tmp_path / "run"
    run = ident(ros_env, "experiment", "--duration", 10, "--out", out, "--json", tmp_path / "experiment.json")
    assert run.returncode == 0, (run.stdout + run.stderr)[-2000:]
    doc = json.loads((tmp_path / "experiment.json").read_text())
    assert doc["samples"] == 51 and doc["duration"] == 10 and doc["sample_period"] == 0.2
    assert json.loads((out / "experiment.json").read_text()) == doc
    counts = dict.fromkeys(sample_topics, 0)
    for message in read_bag(doc["bag"], list(sample_topics)):
        counts[message.topic] += 1
    assert counts == dict.fromkeys(sample_topics, 51), counts
    data = bag_data(doc["bag"])
    assert len(data.t) == 50 and data.t[0] == 0.0 and data.t[-1] == pytest.approx(9.8)
    # the fit scores those 50 and says so; the record is not longer than asked: no note
    fit = ident(ros_env, "fit", doc["bag"], "--set", "ch7", "--json", tmp_path / "fit.json")
    assert fit.returncode == 0, fit.stdout + fit.stderr
    assert json.loads((tmp_path / "fit.json").read_text())["scope"]["samples"] == 50
    assert "data: 50 samples, t = 0 .. 9.8 s" in fit.stdout and "note:" not in fit.stdout


@pytest.mark.unit
def test_a_csv_source_is_read_bounded_and_refused_in_one_line(tmp_path, monkeypatch):
    """Issue 40: a row longer than the header ended in numpy's 'inhomogeneous shape'; /dev/zero was read whole."""
    from seapup_bringup.graph import identification as ident_commands
    from seapup_bringup.graph.identification import load_source
    ragged = tmp_path / "ragged.csv"
    ragged.write_text("t,y1,u1\n0,1,2\n0.2,1,2,3,4\n")
    with pytest.raises(ValueError, match=r"ragged.csv: row 3 has 5 cells, more than the header's 3$"):
        load_source(str(ragged), None, None, "velocities")
    zero = tmp_path / "zero.csv"
    zero.symlink_to("/dev/zero")
    with pytest.raises(ValueError, match="zero.csv: larger than 64 MiB"):
        load_source(str(zero), None, None, "velocities")
    good = tmp_path / "good.csv"
    good.write_text("t,y1,u1\n" + "".join(f"{k * 0.2:.1f},{k % 3},{k % 2}\n" for k in range(10)))
    assert load_source(str(good), None, None, "velocities").y.shape == (10, 1)
    monkeypatch.setattr(ident_commands, "MAX_CSV_CELLS", 20)     # 11 lines x 3 columns: 33 cells
    with pytest.raises(ValueError, match="about 33 cells, more than the 20 a CSV record may have"):
        load_source(str(good), None, None, "velocities")


@pytest.mark.process
def test_an_in_process_experiment_is_a_source_for_every_fit_and_says_its_scope(tmp_path):
    """``--in-process`` writes the run result and the request beside it; ``orders`` reads it as it reads a bag
    (the experiment's duration is the default scope, a longer request is refused nothing), and a JSON that is no
    run result, or an option only a CSV has, is refused in one line naming why."""
    import os
    env = {**os.environ, "ROS_DOMAIN_ID": "0"}
    run = ident(env, "experiment", "--in-process", "--duration", 20, "--out", tmp_path / "exp",
                "--json", tmp_path / "exp.json")
    assert run.returncode == 0, (run.stdout + run.stderr)[-2000:]
    doc = json.loads((tmp_path / "exp.json").read_text())
    assert json.loads((tmp_path / "exp" / "experiment.json").read_text()) == doc
    assert doc["samples"] == 101 and doc["excitation"] == "prbs" and doc["switches"] >= 2
    assert "method" not in doc and "identifier_bag" not in doc   # no identifier runs online in process
    orders = ident(env, "orders", doc["record"], "--max-order", 2, "--duration", 10, "--json", tmp_path / "o.json")
    assert orders.returncode == 0, orders.stdout + orders.stderr
    table = json.loads((tmp_path / "o.json").read_text())
    assert table["outputs"] == ["u", "v", "w", "r", "roll", "pitch"]
    assert table["scope"]["samples"] == 50 and table["scope"]["asked_s"] == 20 and table["scope"]["trimmed"]
    assert len(table["rows"]) == 2 and all(np.all(np.isfinite(row["loss"])) for row in table["rows"])
    (tmp_path / "other.json").write_text(json.dumps({"format": "something else"}))
    for source, extra, reason in ((tmp_path / "other.json", (), "not a seapup run result"),
                                  (doc["record"], ("--inputs", "u0"), "--inputs names CSV columns"),
                                  (tmp_path / "missing.json", (), "missing.json")):
        refused = ident(env, "fit", source, *extra)
        said = (refused.stdout + refused.stderr).strip()
        assert refused.returncode == 1 and reason in said and "Traceback" not in said, said
        assert len(said.splitlines()) == 1, said
