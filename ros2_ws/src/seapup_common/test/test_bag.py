"""Tests of seapup_common.bag: rosbag2 Jazzy (v9, MCAP) bags from raw CDR bytes.

Independent checks: rclpy's serializer makes the bytes and decodes what comes
back; rosbags' reader and the ``mcap`` library's reader with the
``mcap-ros2-support`` decoder (two other implementations) must both read the
file; the layout is checked against rosbag2 Jazzy's documented format.
"""
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import yaml
from ament_index_python.packages import get_package_share_directory
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rclpy.serialization import deserialize_message, serialize_message
from seapup_msgs.msg import BladePitch
from std_msgs.msg import String

from seapup_common.bag import (BagError, BagWriter, bag_info, make_typestore, read_bag,
                               read_bag_with_publish_times, recover_bag, storage_file)

PITCH_TYPE = "seapup_msgs/msg/BladePitch"
T0 = 1_000_000_000


def typestore():
    share = Path(get_package_share_directory("seapup_msgs"))
    return make_typestore({PITCH_TYPE: share / "msg" / "BladePitch.msg"})


def pitch(i):
    m = BladePitch()
    m.header.stamp.sec = i
    m.header.frame_id = "base_link_frd"
    m.pitch = [0.01 * i, -0.01 * i, 0.1, -0.1]
    return m


def write_sample(path, n=50, flush_interval=1.0):
    with BagWriter(path, typestore(), flush_interval=flush_interval) as bag:
        bag.add_topic("/seapup/thrusters/command", PITCH_TYPE)
        bag.add_topic("/notes", "std_msgs/msg/String")
        for i in range(n):
            bag.write("/seapup/thrusters/command", serialize_message(pitch(i)), T0 + i * 200_000_000,
                      T0 + i * 200_000_000 - 1000)
            if i % 10 == 0:
                bag.write("/notes", serialize_message(String(data=f"note {i}")), T0 + i * 200_000_000 + 1)
    return bag


def test_round_trip_through_rclpy_serialization(tmp_path):
    bag = write_sample(tmp_path / "b")
    assert bag.count == 55
    msgs = list(read_bag(tmp_path / "b", topics=["/seapup/thrusters/command"]))
    assert len(msgs) == 50 and [m.t_ns for m in msgs] == [T0 + i * 200_000_000 for i in range(50)]
    for i, m in enumerate(msgs):
        back = deserialize_message(m.cdr, BladePitch)
        assert back.header.stamp.sec == i and back.header.frame_id == "base_link_frd"
        assert list(back.pitch) == list(pitch(i).pitch)
    published = [m.publish_ns for m in read_bag_with_publish_times(tmp_path / "b", ["/seapup/thrusters/command"])]
    assert published == [T0 + i * 200_000_000 - 1000 for i in range(50)]


def test_layout_and_metadata_are_rosbag2_jazzy(tmp_path):
    write_sample(tmp_path / "run")
    assert sorted(os.listdir(tmp_path / "run")) == ["metadata.yaml", "run_0.mcap"]
    doc = yaml.safe_load((tmp_path / "run" / "metadata.yaml").read_text())
    assert list(doc) == ["rosbag2_bagfile_information"]
    meta = doc["rosbag2_bagfile_information"]
    assert set(meta) == {"version", "storage_identifier", "duration", "starting_time", "message_count",
                         "topics_with_message_count", "compression_format", "compression_mode",
                         "relative_file_paths", "files", "custom_data", "ros_distro"}
    assert meta["version"] == 9 and meta["storage_identifier"] == "mcap" and meta["ros_distro"] == "jazzy"
    assert meta["relative_file_paths"] == ["run_0.mcap"] and meta["message_count"] == 55
    assert meta["starting_time"] == {"nanoseconds_since_epoch": T0}
    assert meta["duration"] == {"nanoseconds": 49 * 200_000_000}
    assert meta["files"] == [{"path": "run_0.mcap", "starting_time": {"nanoseconds_since_epoch": T0},
                              "duration": {"nanoseconds": 49 * 200_000_000}, "message_count": 55}]
    topics = {t["topic_metadata"]["name"]: t for t in meta["topics_with_message_count"]}
    cmd = topics["/seapup/thrusters/command"]
    assert cmd["message_count"] == 50
    tm = cmd["topic_metadata"]
    assert set(tm) == {"name", "type", "serialization_format", "offered_qos_profiles", "type_description_hash"}
    assert tm["type"] == PITCH_TYPE and tm["serialization_format"] == "cdr"
    assert tm["type_description_hash"].startswith("RIHS01_") and len(tm["type_description_hash"]) == 71
    (qos,) = tm["offered_qos_profiles"]
    assert set(qos) == {"history", "depth", "reliability", "durability", "deadline", "lifespan", "liveliness",
                        "liveliness_lease_duration", "avoid_ros_namespace_conventions"}
    assert qos["deadline"] == {"sec": 9223372036, "nsec": 854775807}
    # std_msgs/String's RIHS01 hash as ROS 2 Jazzy's rosidl computes it
    assert topics["/notes"]["topic_metadata"]["type_description_hash"] == \
        "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"


def test_the_mcap_library_decodes_every_message_and_sees_the_channel_metadata(tmp_path):
    write_sample(tmp_path / "b")
    with open(storage_file(tmp_path / "b"), "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        assert header.profile == "ros2"
        summary = reader.get_summary()
        for channel in summary.channels.values():
            assert channel.message_encoding == "cdr"
            assert set(channel.metadata) == {"offered_qos_profiles", "topic_type_hash"}
            assert yaml.safe_load(channel.metadata["offered_qos_profiles"])[0]["reliability"] == "reliable"
        assert all(s.encoding == "ros2msg" for s in summary.schemas.values())
        decoded = [(c.topic, m) for _, c, _, m in reader.iter_decoded_messages()]
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    pitches = [m for t, m in decoded if t == "/seapup/thrusters/command"]
    assert len(pitches) == 50
    for i, m in enumerate(pitches):  # field by field, decoded by another implementation
        assert m.header.stamp.sec == i and m.header.frame_id == "base_link_frd"
        assert list(m.pitch) == list(pitch(i).pitch)
    assert [m.data for t, m in decoded if t == "/notes"] == [f"note {i}" for i in range(0, 50, 10)]
    assert metadata["rosbag2"]["ROS_DISTRO"] == "jazzy"
    assert yaml.safe_load(metadata["rosbag2"]["serialized_metadata"])["message_count"] == 55


def test_info_reports_what_ros2_bag_info_shows(tmp_path):
    write_sample(tmp_path / "b")
    info = bag_info(tmp_path / "b")
    assert info["messages"] == 55 and info["duration_s"] == pytest.approx(9.8)
    assert info["start_s"] == pytest.approx(1.0) and info["end_s"] == pytest.approx(10.8)
    assert info["bag_size_bytes"] == storage_file(tmp_path / "b").stat().st_size
    assert {t["name"]: t["count"] for t in info["topics"]} == {"/seapup/thrusters/command": 50, "/notes": 5}


KILLED_WRITER = textwrap.dedent("""
    import os, sys
    from rclpy.serialization import serialize_message
    from std_msgs.msg import String
    from seapup_common.bag import BagWriter, make_typestore
    bag = BagWriter(sys.argv[1], make_typestore(), flush_interval=1.0).open()
    bag.add_topic("/s", "std_msgs/msg/String")
    for i in range(200):                     # 20 s of graph time at 10 Hz
        bag.write("/s", serialize_message(String(data=f"m{i}")), 10**9 + i * 10**8)
    os.kill(os.getpid(), 9)                  # no close, no metadata.yaml
""")


@pytest.mark.process
def test_sigkill_loses_at_most_the_flush_interval_and_recover_restores_it(tmp_path):
    path = tmp_path / "killed"
    proc = subprocess.run([sys.executable, "-c", KILLED_WRITER, str(path)], capture_output=True, text=True)
    assert proc.returncode == -9
    assert not (path / "metadata.yaml").exists()
    with pytest.raises(BagError, match="recover"):
        list(read_bag(path))
    report = recover_bag(path)
    msgs = list(read_bag(path))
    # flushed every 1 s of graph time (10 messages): at most the last interval is lost
    assert 200 - 10 <= len(msgs) == report["messages"] <= 200
    assert [deserialize_message(m.cdr, String).data for m in msgs] == [f"m{i}" for i in range(len(msgs))]
    with open(storage_file(path), "rb") as f:
        assert sum(1 for _ in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages()) == len(msgs)
    assert (path / report["damaged_file"]).is_file()


def test_a_bag_truncated_mid_chunk_is_recovered_up_to_the_last_complete_chunk(tmp_path):
    path = tmp_path / "cut"
    write_sample(path, n=100, flush_interval=2.0)  # a chunk every 2 s of graph time
    data = storage_file(path).read_bytes()
    with open(storage_file(path), "rb") as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    cut = len(data) // 2
    complete = [c for c in chunks if c.chunk_start_offset + c.chunk_length <= cut]
    (path / "metadata.yaml").unlink()
    storage_file(path).write_bytes(data[:cut])
    report = recover_bag(path)
    everything = list(read_bag(path))
    msgs = [deserialize_message(m.cdr, BladePitch) for m in everything if m.topic == "/seapup/thrusters/command"]
    n = len(msgs)
    assert len(complete) >= 2 and 20 <= n < 100
    assert [m.header.stamp.sec for m in msgs] == list(range(n))  # a gap-free prefix
    assert everything[-1].t_ns == complete[-1].message_end_time  # up to the last complete chunk, exactly
    assert report["topics"]["/seapup/thrusters/command"] == n


def test_refuses_existing_directory_unknown_type_undeclared_topic_and_type_change(tmp_path):
    (tmp_path / "exists").mkdir()
    with pytest.raises(BagError, match="exists already"):
        BagWriter(tmp_path / "exists", typestore())
    with BagWriter(tmp_path / "b", make_typestore()) as bag:
        with pytest.raises(BagError, match="unknown to the typestore"):
            bag.add_topic("/p", PITCH_TYPE)
        with pytest.raises(BagError, match="was not added"):
            bag.write("/s", serialize_message(String(data="x")), 0)
        bag.add_topic("/s", "std_msgs/msg/String")
        with pytest.raises(BagError, match="recorded as std_msgs/msg/String"):
            bag.add_topic("/s", "std_msgs/msg/Header")
    with pytest.raises(BagError, match="nothing to recover"):
        recover_bag(tmp_path / "exists")


def test_header_stamp_is_read_from_cdr_without_decoding():
    """Against rclpy's serializer, both byte orders' encapsulation ids, and short or invalid input."""
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Header
    from builtin_interfaces.msg import Time

    from seapup_common.bag import header_stamp_ns

    raw = serialize_message(Header(stamp=Time(sec=1234, nanosec=567_890_123), frame_id="odom_ned"))
    assert header_stamp_ns(raw) == 1234 * 10**9 + 567_890_123
    big = bytes([0, 0, 0, 0]) + (1234).to_bytes(4, "big") + (5).to_bytes(4, "big")
    assert header_stamp_ns(big) == 1234 * 10**9 + 5
    assert header_stamp_ns(raw[:11]) is None
    bad = raw[:8] + (2 * 10**9).to_bytes(4, "little") + raw[12:]
    assert header_stamp_ns(bad) is None


def _split_sample(path, **limits):
    """200 strings 0.1 s apart, flushed every 1 s of graph time (a chunk per 10 messages)."""
    with BagWriter(path, make_typestore(), flush_interval=1.0, **limits) as bag:
        bag.add_topic("/s", "std_msgs/msg/String")
        bag.add_topic("/n", "std_msgs/msg/String")
        for i in range(200):
            bag.write("/s", serialize_message(String(data=f"m{i}")), T0 + i * 10**8)
            if i % 50 == 0:
                bag.write("/n", serialize_message(String(data=f"n{i}")), T0 + i * 10**8)
    return bag


@pytest.mark.parametrize("limits, files", [({"max_file_chunks": 5}, 4), ({"max_bag_duration": 5.0}, 4),
                                           ({"max_bag_size": 3000}, None)])
def test_split_bags_are_rosbag2_split_bags_both_readers_read_in_full(tmp_path, limits, files):
    """As rosbag2 splits: <dir>_0.mcap, <dir>_1.mcap, ...; every file finished with its own summary."""
    from seapup_common.bag import storage_files

    bag = _split_sample(tmp_path / "run", **limits)
    names = [f.name for f in storage_files(tmp_path / "run")]
    assert names == [f"run_{k}.mcap" for k in range(len(names))] and len(names) >= 2
    if files:
        assert len(names) == files
    meta = yaml.safe_load((tmp_path / "run" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["relative_file_paths"] == names and [f["path"] for f in meta["files"]] == names
    assert sum(f["message_count"] for f in meta["files"]) == meta["message_count"] == bag.count == 204
    assert meta["starting_time"]["nanoseconds_since_epoch"] == T0 and meta["duration"]["nanoseconds"] == 199 * 10**8
    # rosbags reads the split bag as one (it follows relative_file_paths)
    got = [deserialize_message(m.cdr, String).data for m in read_bag(tmp_path / "run", ["/s"])]
    assert got == [f"m{i}" for i in range(200)]
    # the mcap library reads every file on its own (each has its channels, schemas and summary)
    decoded = []
    for name in names:
        with open(tmp_path / "run" / name, "rb") as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            assert reader.get_summary() is not None
            decoded += [(c.topic, d.data) for _, c, _, d in reader.iter_decoded_messages(log_time_order=True)]
    assert [d for t, d in decoded if t == "/s"] == got
    assert [d for t, d in decoded if t == "/n"] == ["n0", "n50", "n100", "n150"]
    assert [m.publish_ns for m in read_bag_with_publish_times(tmp_path / "run", ["/s"])] == \
        [T0 + i * 10**8 for i in range(200)]


def test_file_splitting_bounds_the_writers_index_memory():
    """A graph far faster than real time closes a chunk every flush interval of graph time; every
    chunk keeps an index entry until its file is finished: max_file_chunks bounds them."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        bag = BagWriter(Path(tmp) / "fast", make_typestore(), flush_interval=1.0, max_file_chunks=50).open()
        bag.add_topic("/s", "std_msgs/msg/String")
        data = serialize_message(String(data="x" * 100))
        for i in range(2000):  # a chunk per 10 messages: 200 chunks
            bag.write("/s", data, T0 + i * 10**8)
            assert len(bag._writer._Writer__chunk_indices) <= 50
        bag.close()
        assert len(bag.files) == 4 and len(list(read_bag(Path(tmp) / "fast"))) == 2000


def test_a_killed_split_bag_is_recovered_from_all_its_files(tmp_path):
    from seapup_common.bag import storage_files

    path = tmp_path / "split"
    _split_sample(path, max_file_chunks=5)
    last = storage_files(path)[-1]
    last.write_bytes(last.read_bytes()[:len(last.read_bytes()) // 2])  # the writer died in the last file
    (path / "metadata.yaml").unlink()
    report = recover_bag(path)
    got = [deserialize_message(m.cdr, String).data for m in read_bag(path, ["/s"])]
    assert 150 <= len(got) < 200 and got == [f"m{i}" for i in range(len(got))]  # all files, a gap-free prefix
    assert report["damaged_file"] == last.name + ".damaged"
    assert sorted(p.name for p in path.iterdir() if p.suffix == ".orig") == [f"split_{k}.mcap.orig" for k in range(3)]


def _snapshot(path: Path) -> dict:
    """Every file of a bag directory with its bytes: what 'nothing changed on disk' compares."""
    return {p.name: p.read_bytes() for p in sorted(path.iterdir())}


def test_recover_leaves_an_intact_bag_untouched_and_says_so(tmp_path):
    """Issue 40: on an intact bag recover said "damaged file kept as " (an empty name) and rewrote it."""
    write_sample(tmp_path / "b")
    before = _snapshot(tmp_path / "b")
    report = recover_bag(tmp_path / "b")
    assert report["intact"] and report["messages"] == 55 and report["damaged_file"] == "" and report["kept"] == []
    assert _snapshot(tmp_path / "b") == before


@pytest.mark.parametrize("content, reason", [(os.urandom(4096), "is not an MCAP file"),
                                             (b"", "is empty: not an MCAP file")])
def test_recover_refuses_a_file_that_is_not_mcap_and_changes_nothing(tmp_path, content, reason):
    """Issue 40: random bytes were "recovered 0 messages" with exit 0 (and the file renamed)."""
    path = tmp_path / "junk"
    path.mkdir()
    storage_file(path).write_bytes(content)
    before = _snapshot(path)
    with pytest.raises(BagError, match=reason):
        recover_bag(path)
    assert _snapshot(path) == before


def test_recover_of_a_truncated_bag_names_the_kept_file_and_the_byte_in_words(tmp_path):
    path = tmp_path / "cut"
    write_sample(path, n=100, flush_interval=2.0)
    data = storage_file(path).read_bytes()
    storage_file(path).write_bytes(data[:len(data) // 2])
    with pytest.raises(BagError, match=rf"cut_0.mcap ends early \(truncated at byte {len(data) // 2}\): "
                                       rf"run ./seapup bag recover {path}"):
        list(read_bag(path))   # the metadata is there, the file is not whole: a reason, not "EndOfFile:"
    report = recover_bag(path)
    assert not report["intact"] and report["damaged_file"] == "cut_0.mcap.damaged"
    assert (path / report["damaged_file"]).read_bytes() == data[:len(data) // 2]
    assert report["stopped_at"] == f"cut_0.mcap ends early (truncated at byte {len(data) // 2})"
    assert 0 < report["messages"] == len(list(read_bag(path))) < 110


@pytest.mark.parametrize("edit, reason", [
    (lambda i: i.update(message_count=10**30), r"message_count must be an integer in \[0, 2\^63\), got 10{30}"),
    (lambda i: i.update(message_count="55"), r"message_count must be an integer in \[0, 2\^63\), got '55'"),
    (lambda i: i.update(relative_file_paths=5), "relative_file_paths must be a list of 1 to 10000 file names, got 5"),
    (lambda i: i.update(relative_file_paths=["../../etc/passwd"]), "each entry must be a file name in the bag"),
    (lambda i: i.update(relative_file_paths=["gone_0.mcap"]), "lists gone_0.mcap, which is not in the bag"),
    (lambda i: i["duration"].update(nanoseconds=-1), r"duration.nanoseconds must be an integer in \[0, 2\^63\)"),
    (lambda i: i.update(topics_with_message_count=[{"message_count": 3}]), "each of topics_with_message_count"),
])
def test_bag_metadata_with_wrong_types_or_counts_is_refused_in_one_line(tmp_path, edit, reason):
    write_sample(tmp_path / "b")
    meta = yaml.safe_load((tmp_path / "b" / "metadata.yaml").read_text())
    edit(meta["rosbag2_bagfile_information"])
    (tmp_path / "b" / "metadata.yaml").write_text(yaml.safe_dump(meta))
    for call in (bag_info, lambda p: list(read_bag(p))):
        with pytest.raises(BagError, match=reason) as refused:
            call(tmp_path / "b")
        assert "\n" not in str(refused.value)


def test_bag_metadata_is_read_bounded_and_strictly(tmp_path):
    write_sample(tmp_path / "b")
    text = (tmp_path / "b" / "metadata.yaml").read_text()
    (tmp_path / "b" / "metadata.yaml").write_text(text + "rosbag2_bagfile_information: {}\n")
    with pytest.raises(BagError, match="duplicate key 'rosbag2_bagfile_information'"):
        bag_info(tmp_path / "b")
    (tmp_path / "b" / "metadata.yaml").write_text("")
    with pytest.raises(BagError, match="is empty"):
        bag_info(tmp_path / "b")


def test_a_directory_that_is_no_bag_is_named_so(tmp_path):
    (tmp_path / "nothing").mkdir()
    with pytest.raises(BagError, match="is not a bag: it has neither metadata.yaml nor nothing_0.mcap"):
        bag_info(tmp_path / "nothing")
    with pytest.raises(BagError, match="has no nothing_0.mcap: not a bag"):
        recover_bag(tmp_path / "nothing")
    with pytest.raises(BagError, match="no such bag directory"):
        recover_bag(tmp_path / "absent")
