"""Recording from the running simulator, crash safety, and replay through the ROS graph."""
import signal
import sys
import time

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message

from seapup_common.bag import read_bag, recover_bag, storage_file
from tests.test_simulator_node import Probe, start_simulator

ODOM = "/seapup/truth/odometry"


def stamp(m):
    return m.header.stamp.sec * 10**9 + m.header.stamp.nanosec


def start_recorder(node_process, bag_dir, *extra):
    rec = node_process(package="seapup_common", executable="recorder", name="recorder",
                       args=["--ros-args", "-p", f"bag_path:={bag_dir}", "-p", f"topics:=['{ODOM}']",
                             *[a for e in extra for a in ("-p", e)]])
    deadline = time.monotonic() + 20
    while f"recording {ODOM} [" not in rec.log_text() and time.monotonic() < deadline:
        time.sleep(0.05)
    return rec


def test_sigint_gives_a_complete_bag_both_readers_decode_to_the_published_values(
        ros_context, node_process, spin, tmp_path):
    sim = start_simulator(node_process, "mode:=realtime", "real_time_factor:=10.0")
    probe = Probe(ros_context, spin)
    probe.record(ODOM, Odometry)
    rec = start_recorder(node_process, tmp_path / "bag")
    # once the recorder hears the topic (discovery may take seconds here, and what a live publisher
    # sends before it has matched the recorder is not for the recorder): two more seconds of samples
    # (50/s at 10x real time) to record
    assert probe.spin(lambda: f"first message on {ODOM}" in rec.log_text(), 30.0), rec.log_text()
    heard, since = len(probe.msgs[ODOM]), time.monotonic()
    # and two seconds of wall time besides: on a loaded machine this probe's queue holds a backlog, and its count
    # once rose by 100 within 0.1 s of the recorder's first message, so the recorder had 5 messages to give
    assert probe.spin(lambda: len(probe.msgs[ODOM]) > heard + 100 and time.monotonic() - since >= 2.0, 30.0), \
        sim.log_text()
    assert rec.stop() == 0, rec.log_text()
    sent = {stamp(m): m for m in probe.msgs[ODOM]}
    bag = [deserialize_message(m.cdr, Odometry) for m in read_bag(tmp_path / "bag")]
    with open(storage_file(tmp_path / "bag"), "rb") as f:
        other = [m for _, _, _, m in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages()]
    assert len(bag) == len(other) >= 10
    common = 0
    for a, b in zip(bag, other):
        assert stamp(a) == stamp(b) and a.pose.pose.position.z == b.pose.pose.position.z
        if stamp(a) in sent:  # field by field against what the probe received
            s = sent[stamp(a)]
            assert (a.pose.pose.position.x, a.pose.pose.position.z, a.twist.twist.linear.x, a.child_frame_id) == \
                (s.pose.pose.position.x, s.pose.pose.position.z, s.twist.twist.linear.x, s.child_frame_id)
            common += 1
    assert common >= 10
    probe.close()


def test_sigkill_loses_at_most_the_flush_interval_and_recover_makes_it_readable(
        ros_context, node_process, spin, tmp_path):
    start_simulator(node_process, "mode:=realtime", "real_time_factor:=10.0")
    probe = Probe(ros_context, spin)
    arrivals = []  # (wall arrival time in this process, stamp)
    probe.node.create_subscription(Odometry, ODOM, lambda m: arrivals.append((time.monotonic(), stamp(m))), 1000)
    rec = start_recorder(node_process, tmp_path / "bag", "flush_interval:=0.5")
    assert probe.spin(lambda: len(arrivals) > 60, 30.0)
    probe.spin(lambda: False, 3.0)  # the recorder has been recording for at least 3 s
    killed_at = time.monotonic()
    rec.popen.send_signal(signal.SIGKILL)
    rec.popen.wait(10)
    report = recover_bag(tmp_path / "bag")
    got = [deserialize_message(m.cdr, Odometry) for m in read_bag(tmp_path / "bag")]
    assert report["messages"] == len(got) > 0
    stamps = [stamp(m) for m in got]
    assert stamps == sorted(stamps) and len(set(np.diff(stamps))) == 1  # a gap-free run of samples
    # What the graph delivered more than the flush interval (0.5 s) before the kill is on disk.
    # 1.5 s more is allowed for the recorder's own lag behind this process on a loaded machine
    # (messages still in its DDS queue die with it; that is not the bag's loss).
    settled = [s for t, s in arrivals if t < killed_at - 0.5 - 1.5 and s >= stamps[0]]
    assert settled and stamps[-1] >= settled[-1], (stamps[-1], settled[-1])
    probe.close()


def test_replay_reproduces_order_count_and_timing(ros_context, node_process, spin, tmp_path, ros_env):
    sim = start_simulator(node_process, "mode:=realtime", "real_time_factor:=1.0")
    probe = Probe(ros_context, spin)
    rec = start_recorder(node_process, tmp_path / "bag")
    # ten-odd samples after the recorder's first (at 1x, 5 Hz: about 3 s; longer on a loaded machine)
    probe.record(ODOM, Odometry)
    assert probe.spin(lambda: "first message on" in rec.log_text(), 30.0), rec.log_text()[-2000:]
    heard = len(probe.msgs[ODOM])
    assert probe.spin(lambda: len(probe.msgs[ODOM]) >= heard + 14, 30.0)
    assert rec.stop() == 0
    sim.stop()
    recorded = list(read_bag(tmp_path / "bag"))
    assert len(recorded) >= 10
    probe.msgs[ODOM] = []
    arrivals = []
    probe.node.create_subscription(Odometry, ODOM, lambda m: (probe.msgs[ODOM].append(m),
                                                              arrivals.append(time.monotonic())), 1000)
    node_process([sys.executable, "-m", "seapup_bringup.cli", "replay", str(tmp_path / "bag"), "--rate", "2.0",
                  "--wait-for-subscribers", "1"],
                 name="replay")
    assert probe.spin(lambda: len(probe.msgs[ODOM]) == len(recorded), 30.0), (len(probe.msgs[ODOM]), len(recorded))
    assert [stamp(m) for m in probe.msgs[ODOM]] == [stamp(deserialize_message(r.cdr, Odometry)) for r in recorded]
    # relative timing at rate 2: arrival spacing is half the recorded log-time spacing
    recorded_span = (recorded[-1].t_ns - recorded[0].t_ns) * 1e-9
    assert abs((arrivals[-1] - arrivals[0]) - recorded_span / 2.0) < 0.3
    probe.close()


def test_lockstep_replay_drives_a_controller_sample_by_sample(ros_context, node_process, spin, tmp_path):
    """The reference demo bag, replayed in lockstep into a fresh open_loop node with the demo's
    schedule: one answer per sample, stamped with it, equal to the commands recorded in the bag."""
    import json

    from seapup_bringup.graph.open_loop import demo_config, manoeuvres, schedule_args
    from seapup_msgs.msg import BladePitch
    from tests.test_reference_bags import DEMO

    probe = Probe(ros_context, spin)
    probe.record("/seapup/thrusters/command", BladePitch)
    node_process(package="seapup_control", executable="open_loop", name="controller",
                 args=["--ros-args", "-p", "wait_for_command_subscribers:=2",
                       *schedule_args(demo_config()["duration"], manoeuvres())])
    replay = node_process([sys.executable, "-m", "seapup_bringup.cli", "replay", str(DEMO),
                           "--lockstep", "/seapup/thrusters/command", "--wait-for-subscribers", "1",
                           "--json", str(tmp_path / "replay.json")], name="replay")
    # keep this process's subscription drained while the replay runs (a loaded machine)
    assert probe.spin(lambda: replay.popen.poll() is not None, 120.0), replay.log_text()
    assert replay.popen.wait(10) == 0, replay.log_text()
    report = json.loads((tmp_path / "replay.json").read_text())
    recorded = [deserialize_message(m.cdr, BladePitch) for m in read_bag(DEMO, ["/seapup/thrusters/command"])]
    samples = len(list(read_bag(DEMO, ["/seapup/truth/odometry"])))
    assert (report["samples"], report["answered"], report["timeouts"]) == (samples, samples, 0)
    assert "/seapup/thrusters/command" not in report["topics"]  # the node under test makes those
    # what this process overheard (its subscription may match after the first answers on a loaded
    # machine; the replay's own count above is the lockstep evidence): every answer once, stamped with
    # its sample, equal to the command the bag holds for that sample
    answers = probe.msgs["/seapup/thrusters/command"]
    probe.spin(lambda: len(answers) >= samples, 30.0)
    assert len(answers) >= 0.9 * samples, (len(answers), samples, answers[-1:] and stamp(answers[-1]))
    assert stamp(answers[-1]) == (samples - 1) * 200_000_000  # the last sample's answer too
    stamps = [stamp(a) for a in answers]
    assert stamps == sorted(set(stamps)) and all(s % 200_000_000 == 0 for s in stamps)
    by_stamp = {stamp(r): r.pitch for r in recorded}
    common = [a for a in answers if stamp(a) in by_stamp]
    assert len(common) >= 0.9 * len(recorded)
    np.testing.assert_array_equal([a.pitch for a in common], [by_stamp[stamp(a)] for a in common])
    probe.close()


def test_seapup_record_stops_on_max_duration_or_sigint_and_reports_the_bag(
        ros_context, node_process, spin, tmp_path):
    """``./seapup record`` itself: the CLI's bag is closed, readable, and its JSON report matches it."""
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    start_simulator(node_process, "mode:=realtime", "real_time_factor:=5.0")
    probe = Probe(ros_context, spin)
    probe.record(ODOM, Odometry)
    assert probe.spin(lambda: len(probe.msgs[ODOM]) > 5, 30.0)
    # 1. --max-duration: the recorder stops by itself after 2 s of (wall-clock) graph time
    timed = node_process([str(root / "seapup"), "record", "-o", str(tmp_path / "timed"), "--topics", ODOM,
                          "--max-duration", "2", "--wall-time", "--json", str(tmp_path / "timed.json")],
                         name="record_timed")
    assert timed.popen.wait(60) == 0, timed.log_text()
    report = json.loads((tmp_path / "timed.json").read_text())
    got = list(read_bag(tmp_path / "timed"))
    assert report["messages"] == len(got) and [t["name"] for t in report["topics"]] == [ODOM]
    assert 1.9 <= report["duration_s"] <= 2.5 and len(got) >= 20  # 25 samples/s at 5x real time
    # 2. SIGINT to ./seapup: the bag is finalised and reported
    held = node_process([str(root / "seapup"), "record", "-o", str(tmp_path / "held"), "--topics", ODOM,
                         "--clock-wait", "30", "--json", str(tmp_path / "held.json")], name="record_sigint")
    deadline = time.monotonic() + 60
    while f"recording {ODOM} [" not in held.log_text() and time.monotonic() < deadline:
        time.sleep(0.1)  # subscribed (the bootstrap and discovery can take a while on a loaded machine)
    probe.spin(lambda: False, 2.0)
    held.popen.send_signal(signal.SIGINT)
    assert held.popen.wait(30) == 0, held.log_text()
    report = json.loads((tmp_path / "held.json").read_text())
    assert report["messages"] == len(list(read_bag(tmp_path / "held"))) >= 10
    # the simulator publishes /clock: without a flag the bag logs graph time, and says so
    assert "logging the graph time of /clock (/clock is published)" in held.log_text()
    for m in read_bag(tmp_path / "held"):  # graph time: never before the stamp, at most a few samples after
        assert 0 <= m.t_ns - stamp(deserialize_message(m.cdr, Odometry)) <= 10**9
    # 3. an existing bag is refused, nothing is touched
    again = node_process([str(root / "seapup"), "record", "-o", str(tmp_path / "held"), "--topics", ODOM],
                         name="record_again")
    assert again.popen.wait(60) == 2 and "exists" in again.log_text()
    assert json.loads((tmp_path / "held.json").read_text()) == report
    # 4. ./seapup record killed outright (SIGKILL: no handler runs): its recorder is not orphaned -- it
    # finishes the bag (readable without recovery) and is gone within 2 s
    from tests.test_process_ownership import descendants, gone_within
    killed = node_process([str(root / "seapup"), "record", "-o", str(tmp_path / "killed"), "--topics", ODOM],
                          name="record_sigkill")
    deadline = time.monotonic() + 60
    while f"recording {ODOM} [" not in killed.log_text() and time.monotonic() < deadline:
        time.sleep(0.1)
    probe.spin(lambda: False, 1.0)
    recorder = descendants(killed.popen.pid)
    assert recorder
    killed.popen.send_signal(signal.SIGKILL)
    assert gone_within(recorder, 2.0)
    assert len(list(read_bag(tmp_path / "killed"))) >= 5 and (tmp_path / "killed" / "metadata.yaml").is_file()
    probe.close()


def test_a_malformed_parameter_rule_is_a_clear_error_not_a_traceback(ros_env):
    import subprocess

    from seapup_common.processes import find_executable
    run = subprocess.run([str(find_executable("seapup_common", "recorder")), "--ros-args", "-p", "exclude:="],
                         env=ros_env, capture_output=True, text=True, timeout=60)
    assert run.returncode == 1
    assert "fatal" in run.stderr and "exclude:=" in run.stderr and "Traceback" not in run.stderr


def _bag_cli(capsys, *argv):
    """``./seapup bag ...`` in this process: (exit code, stdout, stderr)."""
    from seapup_bringup.ros2cli.bag_commands import bag
    code = bag(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def _copy_reference_bag(tmp_path, name):
    import shutil
    from pathlib import Path
    source = Path(__file__).resolve().parents[1] / "bags" / "selftest_5hz"
    target = tmp_path / name
    target.mkdir()
    shutil.copyfile(storage_file(source), storage_file(target))
    meta = (source / "metadata.yaml").read_text().replace(storage_file(source).name, storage_file(target).name)
    (target / "metadata.yaml").write_text(meta)
    return target


def test_bag_recover_outcomes_are_consistent_and_true(tmp_path, capsys):
    """Issue 40: random bytes were "recovered 0 messages" with exit 0 (an empty file exit 1), and an intact
    bag was "damaged file kept as " (no name). Now: not MCAP -> exit 1 saying so, nothing changed;
    intact -> exit 0, "nothing to recover", nothing changed; damaged -> the count and the kept file's name."""
    import os
    for name, content in (("noise", os.urandom(10_000)), ("empty", b"")):
        (tmp_path / name).mkdir()
        storage_file(tmp_path / name).write_bytes(content)
        code, out, err = _bag_cli(capsys, "recover", str(tmp_path / name))
        assert code == 1 and out == "" and err.count("\n") == 1 and "not an MCAP file" in err, (name, err)
        assert [p.name for p in (tmp_path / name).iterdir()] == [storage_file(tmp_path / name).name]
        assert storage_file(tmp_path / name).read_bytes() == content

    intact = _copy_reference_bag(tmp_path, "intact")
    before = {p.name: p.read_bytes() for p in intact.iterdir()}
    code, out, err = _bag_cli(capsys, "recover", str(intact))
    assert code == 0 and out == "nothing to recover: the bag is intact (5714 messages); nothing changed\n", out
    assert {p.name: p.read_bytes() for p in intact.iterdir()} == before

    cut = _copy_reference_bag(tmp_path, "cut")
    data = storage_file(cut).read_bytes()
    storage_file(cut).write_bytes(data[:800_000])
    code, out, err = _bag_cli(capsys, "recover", str(cut))
    first = out.splitlines()[0]
    kept = first.rsplit("damaged file kept as ", 1)[1]
    assert code == 0 and kept == "cut_0.mcap.damaged" and (cut / kept).read_bytes() == data[:800_000], out
    n = int(first.split()[1])
    assert first.startswith(f"recovered {n} messages (reading stopped: cut_0.mcap ends early (truncated at byte "
                            f"800000))") and 0 < n == len(list(read_bag(cut))) < 5714


def test_hostile_bags_are_refused_with_reasons_by_info_and_replay(tmp_path, capsys):
    """Reading errors are reasons ("ends early ... run ./seapup bag recover DIR"), never an exception's name
    ("EndOfFile:", "InvalidMagic:"), and nothing is played."""
    import os
    from seapup_bringup.ros2cli.bag_commands import replay
    cut = _copy_reference_bag(tmp_path, "cut")
    storage_file(cut).write_bytes(storage_file(cut).read_bytes()[:800_000])
    (tmp_path / "noise").mkdir()
    storage_file(tmp_path / "noise").write_bytes(os.urandom(5000))
    (tmp_path / "void").mkdir()
    for path, reason in ((cut, f"cut_0.mcap ends early (truncated at byte 800000): run ./seapup bag recover {cut}"),
                         (tmp_path / "noise", "is not an MCAP file"), (tmp_path / "void", "has no void_0.mcap")):
        assert replay([str(path)]) == 1
        out, err = capsys.readouterr()
        assert reason in err and err.count("\n") == 1 and "Error" not in err and "EndOfFile" not in err, err
    code, out, err = _bag_cli(capsys, "info", str(tmp_path / "void"))
    assert code == 1 and "is not a bag: it has neither metadata.yaml nor void_0.mcap" in err


#: The simulator's topics said once at every sample t_k (the acoustic position fix comes at some samples only).
_EVERY_SAMPLE = ("/seapup/truth/odometry", "/seapup/odometry", "/seapup/thrusters/applied", "/seapup/sensors/velocity",
                 "/seapup/sensors/imu", "/seapup/sensors/depth", "/seapup/sensors/altitude", "/seapup/sensors/sample")


def record_with_the_graph(out, end: float) -> dict:
    """Fly the identification graph to ``end`` with a recorder started as one of its nodes, every per-sample
    topic typed (subscribed at its start); each topic's header stamps in the bag [ns], in the order recorded."""
    from seapup_bringup.graph.sil import SilGraph
    from seapup_common import topics
    from seapup_common.bag import header_stamp_ns
    from seapup_common.launch_format import NodeSpec

    entries = [f"{t}:{topics.TOPIC_TYPES.get(t, 'nav_msgs/msg/Odometry')}" for t in (topics.CLOCK, *_EVERY_SAMPLE)]
    # named "recorder": the harness stops it after the graph, so it has everything (SilGraph.close)
    recorder = NodeSpec("seapup_common", "recorder", name="recorder",
                        parameters=[{"bag_path": str(out / "bag"), "use_sim_time": True, "topics": entries}])
    with SilGraph("seapup_bringup identification.launch.yaml", {"end_time": repr(end)}, out_dir=out,
                  ready_status=None, extra_nodes=[recorder]) as sil:
        assert sil.spin_until(lambda: sil.t >= end - 1e-6, 120.0), f"flew {sil.t} of {end} s"
    stamps = {topic: [] for topic in _EVERY_SAMPLE}
    for message in read_bag(out / "bag", list(_EVERY_SAMPLE)):
        stamps[message.topic].append(header_stamp_ns(message.cdr))
    return stamps


@pytest.mark.graph
def test_a_recorder_started_with_a_lockstep_graph_misses_no_sample(tmp_path):
    """Issue 43: a recorder started with a lockstep graph is a listener of the graph's lockstep roster
    (seapup_common.lockstep.roster: its typed topics), so t_0 waits for its subscriptions: every per-sample
    topic of the bag begins at t_0 and goes on sample by sample without a gap (the demo's bag had missed the
    first 2-9 samples of the velocity, IMU, depth and applied pitch). The graph's own nodes (the identifier)
    hear only some of these topics, the recorder all of them."""
    end, period = 3.0, round(0.2e9)
    for topic, got in record_with_the_graph(tmp_path, end).items():
        stamps = sorted(set(got))   # t_0 may be said again (to a reader that matched late): once per stamp
        assert stamps[:1] == [0] and stamps == list(range(0, stamps[-1] + 1, period)), (topic, stamps[:4])
        assert stamps[-1] >= (end - 1.0) * 1e9, (topic, len(stamps))   # the recorder stops with the graph
