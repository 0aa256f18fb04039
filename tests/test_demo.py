"""The README's main command: ``./seapup demo`` flies the mission through the supervisory hierarchy
(seapup_bringup.mission), records it, tabulates and plots it. And the open-loop demo
(``./seapup open-loop``, seapup_bringup.demo): it flies, records everything it publishes, summarises."""
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message

from seapup_common.bag import read_bag


@pytest.mark.graph
def test_the_demo_mission_flies_every_leg_and_its_bag_opens_with_rosbags_and_mcap(tmp_path, ros_env):
    """Acceptance of issue 13 through ROS, every node its own process, truth from the simulator."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.highlevel import AnyReader

    out = tmp_path / "demo"
    run = subprocess.run([sys.executable, "-m", "seapup_bringup.mission", "--out", str(out), "--json",
                          str(tmp_path / "summary.json")], env=ros_env, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, (run.stdout + run.stderr)[-3000:]
    summary = json.loads((tmp_path / "summary.json").read_text())
    legs = {leg["kind"]: leg for leg in summary["legs"]}
    assert [leg["status"] for leg in summary["legs"]] == ["succeeded"] * 6
    assert {"self_test", "hover", "goto", "inspection", "follow_seabed", "current"} == set(legs)
    assert legs["goto"]["end_error_true"] <= 0.5 + 0.3            # arrival tolerance + navigation error
    assert legs["follow_seabed"]["altitude_true_max"] <= 0.3       # on the 1 in 10 slope, from the truth
    assert legs["current"]["hold_rms"] <= 0.5                      # station keeping in the 0.26 m/s current
    hover = legs["hover"]
    assert hover["switch_ok"] and hover["switch_step_deg"] <= hover["normal_step_deg"]  # bumpless swap
    for line in ("leg ", "self-test", "station keeping", "swap step"):
        assert line in run.stdout + run.stderr
    for name in summary["plots"]:
        assert Path(name).stat().st_size > 10_000
    # the bag: rosbags and the mcap library both read every message, and agree
    with AnyReader([out / "bag"]) as reader:
        counts = {}
        for connection, _, raw in reader.messages():
            counts[connection.topic] = counts.get(connection.topic, 0) + 1
            if connection.topic == "/seapup/truth/odometry" and counts[connection.topic] == 1:
                first = reader.deserialize(raw, connection.msgtype)
    assert first.header.frame_id == "odom_ned" and first.child_frame_id == "base_link_frd"
    storage = next((out / "bag").glob("*.mcap"))
    with open(storage, "rb") as f:
        theirs = {}
        for _, channel, _, _ in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            theirs[channel.topic] = theirs.get(channel.topic, 0) + 1
    assert counts == theirs
    samples = counts["/seapup/truth/odometry"]
    assert samples > 5 * 500 and counts["/seapup/navigation/odometry"] > 0.95 * samples
    assert counts["/seapup/thrusters/command"] >= samples - 10
    # in lockstep the velocity controllers waited for the position level's reference of every sample
    from diagnostic_msgs.msg import DiagnosticArray
    from seapup_common.bag import read_bag
    from rclpy.serialization import deserialize_message
    last = {}
    for message in read_bag(out / "bag", ["/diagnostics"]):
        for status in deserialize_message(message.cdr, DiagnosticArray).status:
            values = {kv.key: kv.value for kv in status.values}
            if "late_references" in values:
                last[status.name] = (int(values["samples"]), int(values["late_references"]))
    assert set(last) == {"seapup/mfol_fixed", "seapup/mfol_scheduled"}
    assert sum(late for _, late in last.values()) <= 0.01 * sum(n for n, _ in last.values())


def run_demo(out, env, duration=16):
    return subprocess.run([sys.executable, "-m", "seapup_bringup.demo", "--duration", str(duration),
                           "--out", str(out), "--json", str(out / "summary.json")],
                          env=env, capture_output=True, text=True, timeout=180)


def test_demo_flies_records_and_summarises(tmp_path, ros_env):
    out = tmp_path / "demo"
    out.mkdir()
    run = run_demo(out, ros_env)
    assert run.returncode == 0, [l for l in (run.stdout + run.stderr).splitlines() if "flying" not in l][-15:]
    assert re.search(r"flew 1[67]\.\d s of simulated time", run.stdout), run.stdout
    assert "every published sample and command is in the bag" in run.stdout
    for name in ("hover", "surge", "sway"):
        assert f"\n{name} " in run.stdout
    truth = [(m.t_ns, deserialize_message(m.cdr, Odometry))
             for m in read_bag(out / "bag", ["/seapup/truth/odometry"])]
    assert len(truth) >= 81  # 16 s at 5 Hz, t_0 included
    # log times are the graph's (sim) receive times: within one sample (0.2 s) of each stamp,
    # most of them exactly on it (not wall time, which would be seconds off)
    lag = [t - (o.header.stamp.sec * 10**9 + o.header.stamp.nanosec) for t, o in truth]
    assert all(0 <= d <= 200_000_000 for d in lag), [d for d in lag if d]
    assert sum(d == 0 for d in lag) > 0.5 * len(lag)
    # the surge segment (4-8 s, mains +35 deg) really drives the vehicle ahead
    assert max(o.twist.twist.linear.x for _, o in truth if 4.0 <= o.header.stamp.sec < 8.0) > 0.5


@pytest.mark.graph
def test_twenty_lockstep_demos_lose_nothing(tmp_path, ros_env):
    """Nothing missed at start or end, run after run (the graph-ready handshake)."""
    for k in range(20):
        out = tmp_path / f"d{k}"
        out.mkdir()
        run = run_demo(out, ros_env, duration=4)
        assert run.returncode == 0, (k, [l for l in (run.stdout + run.stderr).splitlines() if "flying" not in l][-12:])
        summary = json.loads((out / "summary.json").read_text())
        assert summary["missed"] == {}, (k, summary["missed"])
        for topic, n in summary["published"].items():
            assert n > 0 and summary["counts"][topic] == n, (k, topic)
