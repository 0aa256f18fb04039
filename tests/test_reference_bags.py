"""The reference bags in ``bags/`` read back, and still say what the plant does.

``bags/demo_120s`` is ``./seapup open-loop --bag bags/demo_120s`` (see bags/README.md).
Checked against independent readers (rosbags, the mcap library's ROS 2
decoder), the rosbag2 layout, and the pure core flown again with the demo's
configuration (``seapup_bringup/config/demo.yaml``) and schedule: the bag's
truth and sensor samples must be what the model gives today. If the model
changes on purpose, record the bag again with the command above.
"""
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rclpy.serialization import deserialize_message

from seapup_common.bag import bag_info, header_stamp_ns, read_bag, storage_file

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "bags" / "demo_120s"
PER_SAMPLE = ["/seapup/thrusters/applied", "/seapup/truth/odometry", "/seapup/sensors/velocity",
              "/seapup/sensors/imu", "/seapup/sensors/depth"]


def reference_bags() -> list[Path]:
    """The committed bags: those .gitignore lets through (``!bags/NAME/``); ./seapup demo and record
    write other directories under bags/, which are ignored."""
    lines = (ROOT / ".gitignore").read_text().splitlines()
    return [ROOT / line[1:].strip("/") for line in lines if line.startswith("!bags/") and line.endswith("/")]


def test_every_reference_bag_is_small_and_in_the_rosbag2_layout():
    bags = reference_bags()
    assert all(bag.is_dir() for bag in bags), bags
    assert DEMO in bags
    for bag in bags:
        size = sum(f.stat().st_size for f in bag.iterdir())
        assert size < 5 * 2**20, (bag, size)
        info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        assert info["version"] == 9 and info["ros_distro"] == "jazzy"
        assert info["relative_file_paths"] == [f"{bag.name}_0.mcap"] and storage_file(bag).is_file()
        assert (ROOT / "bags" / "README.md").read_text().count(f"bags/{bag.name}") >= 1, f"{bag.name} undocumented"


def test_demo_bag_reads_back_with_both_readers_and_one_message_per_sample():
    info = bag_info(DEMO)
    counts = {t["name"]: t["count"] for t in info["topics"]}
    ours = list(read_bag(DEMO))
    with open(storage_file(DEMO), "rb") as f:
        theirs = [(c.topic, d) for _, c, _, d in make_reader(f, decoder_factories=[DecoderFactory()])
                  .iter_decoded_messages(log_time_order=True)]
    assert len(ours) == len(theirs) == info["messages"] == sum(counts.values())
    samples = round(info["duration_s"] / 0.2) + 1
    for topic in PER_SAMPLE:
        assert counts[topic] == samples, topic
        stamps = [header_stamp_ns(m.cdr) for m in ours if m.topic == topic]
        assert stamps == [k * 200_000_000 for k in range(samples)], topic  # sim time, every sample once
        # the log time is the graph's (sim) time of the sample
        assert [m.t_ns for m in ours if m.topic == topic] == stamps, topic
    assert counts["/seapup/thrusters/command"] >= samples - 1  # every sample answered (the last may not be)
    for (topic, decoded), raw in zip(theirs[:200], ours[:200]):
        if topic == "/seapup/truth/odometry":  # the two decoders agree field by field
            from nav_msgs.msg import Odometry
            mine = deserialize_message(raw.cdr, Odometry)
            assert (decoded.pose.pose.position.x, decoded.twist.twist.linear.x, decoded.child_frame_id) == \
                (mine.pose.pose.position.x, mine.twist.twist.linear.x, mine.child_frame_id)


def _refly():
    """The demo flown by the pure core (no ROS) with the demo's configuration and schedule."""
    from seapup_bringup.graph.open_loop import demo_config, manoeuvres, schedule_times
    from seapup_control.profiles import OpenLoop, PitchProfile
    from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
    from seapup_sim.simulation import Simulation

    config = demo_config()
    sim = config["simulator"]
    environment = {}
    for key, value in sim.items():
        if key.startswith("environment."):
            *path, leaf = key.split(".")[1:]
            node = environment
            for part in path:
                node = node.setdefault(part, {})
            node[leaf] = value
    plan = manoeuvres()
    state = np.zeros(12)
    state[2] = sim["start_depth"]
    core = Simulation.from_config(sim["vehicle"], environment, seed=sim["seed"], state=state, pitch=plan[0][1])
    schedule = PitchProfile(schedule_times(config["duration"], plan), [x for _, r in plan for x in r],
                             BLADE_PITCH_LIMIT)
    return core.run(OpenLoop(schedule, 0.2), config["duration"])


@pytest.fixture(scope="module")
def reflown():
    return _refly()


def test_demo_bag_is_what_the_model_flies_today(reflown):
    from geometry_msgs.msg import TwistWithCovarianceStamped
    from nav_msgs.msg import Odometry
    from seapup_msgs.msg import BladePitch

    odom = [deserialize_message(m.cdr, Odometry) for m in read_bag(DEMO, ["/seapup/truth/odometry"])]
    vel = [deserialize_message(m.cdr, TwistWithCovarianceStamped)
           for m in read_bag(DEMO, ["/seapup/sensors/velocity"])]
    cmd = [deserialize_message(m.cdr, BladePitch) for m in read_bag(DEMO, ["/seapup/thrusters/command"])]
    n = min(len(odom), len(reflown.t))
    bag_state = np.array([(o.pose.pose.position.x, o.pose.pose.position.y, o.pose.pose.position.z,
                           o.twist.twist.linear.x, o.twist.twist.linear.y, o.twist.twist.angular.z)
                          for o in odom[:n]])
    core_state = reflown.state[:n][:, [0, 1, 2, 6, 7, 11]]
    assert np.abs(core_state[:, 3]).max() > 0.9  # the run did fly (surge ~1 m/s)
    np.testing.assert_allclose(bag_state, core_state, rtol=0, atol=1e-6,
                               err_msg="the plant no longer flies the reference demo: if intended, record "
                                       "bags/demo_120s again (bags/README.md)")
    np.testing.assert_allclose([(v.twist.twist.linear.x, v.twist.twist.linear.y) for v in vel[:n]],
                               reflown.measured["velocity"][:n, :2], rtol=0, atol=1e-6)
    # the recorded commands are the schedule's, stamped with their samples
    # (the pure run logs no command at its final sample; the graph may have answered that one too)
    held = int(np.isfinite(reflown.command[:, 0]).sum())
    assert len(cmd) in (held, held + 1)
    np.testing.assert_allclose([c.pitch for c in cmd[:held]], reflown.command[:held], rtol=0, atol=1e-12)


SELFTEST = ROOT / "bags" / "selftest_5hz"


def test_selftest_bag_refits_to_what_the_self_test_finds_today():
    """Refit from the recorded samples (--from-bag) == the self-test flown again in process, started as the
    simulator node starts (at the hover setting)."""
    from seapup_bringup.graph.self_test_graph import self_test_from_bag as _from_bag
    from seapup_runs.self_test_flight import fly_self_test
    from seapup_sim.analysis import hover_blade_pitch
    from seapup_sim.vehicle import VehicleModel
    from seapup_sim.vehicle_config import load_vehicle_config

    refitted = _from_bag(SELFTEST)
    hover = hover_blade_pitch(VehicleModel(load_vehicle_config("baseline")))
    again = fly_self_test("baseline", {"operating_points": [0.0]}, start_pitch=hover)
    (bag_point,), (live_point,) = refitted["points"], again.test.points
    np.testing.assert_allclose(bag_point.model.B0inv, live_point.model.B0inv, rtol=1e-6, atol=1e-12,
                               err_msg="record bags/selftest_5hz again if the plant or self-test changed")
    np.testing.assert_allclose(bag_point.model.B1inv, live_point.model.B1inv, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(bag_point.model.u0, live_point.model.u0, atol=1e-9)
    assert abs(refitted["duration"] - again.test.duration) < 1e-6
    np.testing.assert_allclose(refitted["space"], again.space, atol=1e-6)
