"""``./seapup ident``: the open-loop PRBS experiment recorded through ROS, and fits from its bag and from CSV.

Truths: the experiment's own schedule (every sample recorded once, the PRBS levels applied), a
known generating system for the CSV fit, and the model's one-step predictions explaining the
recorded motion far better than its mean.
"""
import json
import subprocess
import sys

import numpy as np
import pytest

from seapup_ident.armax import ArmaxModel, ArmaxOrders
from seapup_ident.prbs import prbs


def ident(env, *args, timeout=300):
    return subprocess.run([sys.executable, "-m", "seapup_bringup.cli", "ident", *map(str, args)], env=env,
                          capture_output=True, text=True, timeout=timeout)


@pytest.mark.graph
def test_experiment_records_every_sample_and_its_bag_fits(tmp_path, ros_env):
    from seapup_bringup.ident_commands import bag_data
    from seapup_sim.analysis import hover_blade_pitch
    from seapup_sim.vehicle import VehicleModel
    from seapup_sim.vehicle_config import load_vehicle_config

    run = ident(ros_env, "experiment", "--duration", 30, "--out", tmp_path / "exp", "--json", tmp_path / "exp.json")
    assert run.returncode == 0, (run.stdout + run.stderr)[-2000:]
    bag = json.loads((tmp_path / "exp.json").read_text())["bag"]
    data = bag_data(bag)
    assert len(data.t) >= 151 and np.all(np.isfinite(data.y)) and np.all(np.isfinite(data.u))  # 30 s at 5 Hz
    np.testing.assert_allclose(np.diff(data.t), 0.2, atol=1e-9)                # no sample missing
    hover = hover_blade_pitch(VehicleModel(load_vehicle_config("baseline")))
    # the applied pitch: +-10 deg about hover, reached a few samples after each switch (the pitch actuator slews)
    offset = np.abs(data.u - hover)
    assert offset.max() <= np.radians(10) + 1e-9
    assert np.mean(np.isclose(offset, np.radians(10), atol=1e-9)) > 0.75   # ~15 switches x 2 samples of slew
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
    assert len(models) >= 140 and models[-1].samples == len(models)
    offline = ident(ros_env, "fit", identifier_bag, "--orders", "2,2,0", "--json", tmp_path / "offline.json")
    assert offline.returncode == 0, offline.stdout + offline.stderr
    again = json.loads((tmp_path / "offline.json").read_text())
    last = models[-1]
    np.testing.assert_allclose(np.ravel(again["A"]), last.a, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(np.ravel(again["B"]), last.b, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(again["d"], last.d, rtol=1e-9, atol=1e-12)


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
    assert bad.returncode == 1 and "neither a bag directory nor a .csv file" in bad.stdout + bad.stderr
