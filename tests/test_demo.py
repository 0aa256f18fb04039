"""The README's main command: ``./seapup demo`` flies the mission through the supervisory hierarchy
(seapup_bringup.demo), records it, tabulates and plots it. The open-loop flight
(``./seapup open-loop``) is tested in test_open_loop.py."""
import json
import subprocess
import sys
from pathlib import Path

import pytest


@pytest.mark.graph
def test_the_demo_mission_flies_every_leg_and_its_bag_opens_with_rosbags_and_mcap(tmp_path, ros_env):
    """Acceptance of issue 13 through ROS, every node its own process, truth from the simulator."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.highlevel import AnyReader

    out = tmp_path / "demo"
    run = subprocess.run([sys.executable, "-m", "seapup_bringup.demo", "--out", str(out), "--json",
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
    # every sample's command is in the bag (the first waits for the recorder; the graph may stop with the
    # last sample unanswered)
    assert counts["/seapup/thrusters/command"] >= samples - 2
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
    # one time base: every stamped message of every topic is logged no earlier than its own header stamp,
    # and no node stamps with the wall clock on this sim-time graph (/diagnostics once mixed the two)
    from seapup_common.bag import header_stamp_ns
    early, stamped = {}, {}
    with AnyReader([out / "bag"]) as reader:
        for connection, log_ns, raw in reader.messages():
            topic = connection.topic
            if topic not in stamped:
                stamped[topic] = hasattr(reader.deserialize(raw, connection.msgtype), "header")
            stamp = header_stamp_ns(raw) if stamped[topic] else None
            if stamp is not None:
                assert stamp < 10**6 * 10**9, f"{topic} stamped {stamp * 1e-9:.0f} s: the wall clock?"
                if log_ns < stamp:
                    early[topic] = early.get(topic, 0) + 1
    assert sum(stamped.values()) >= 10 and early == {}, early
