"""Tests of seapup_ident.bag: rosbag2/MCAP bags written from raw CDR bytes.

Independent checks: rclpy's own serializer makes the bytes and decodes what
comes back; the ``mcap`` library (a second reader, not rosbags) must parse the
file and agree on topics, schemas and message counts.
"""
from pathlib import Path

import pytest
import yaml
from ament_index_python.packages import get_package_share_directory
from mcap.reader import make_reader
from rclpy.serialization import deserialize_message, serialize_message
from seapup_msgs.msg import BladePitch
from std_msgs.msg import String

from seapup_ident.bag import BagError, BagRecorder, make_typestore, read_bag

PITCH_TYPE = "seapup_msgs/msg/BladePitch"


def typestore():
    share = Path(get_package_share_directory("seapup_msgs"))
    return make_typestore({PITCH_TYPE: share / "msg" / "BladePitch.msg"})


def pitch(i):
    m = BladePitch()
    m.header.stamp.sec = i
    m.header.frame_id = "base_link_frd"
    m.pitch = [0.01 * i, -0.01 * i, 0.1, -0.1]
    return m


def write_sample(path, n=50):
    with BagRecorder(path, typestore()) as bag:
        for i in range(n):
            bag.write("/seapup/thrusters/command", PITCH_TYPE, 1_000_000_000 + i * 200_000_000,
                      serialize_message(pitch(i)))
            if i % 10 == 0:
                s = String(data=f"note {i}")
                bag.write("/notes", "std_msgs/msg/String", 1_000_000_000 + i * 200_000_000 + 1,
                          serialize_message(s))
    return bag


def test_round_trip_through_rclpy_serialization(tmp_path):
    bag = write_sample(tmp_path / "b")
    assert bag.count == 55
    msgs = list(read_bag(tmp_path / "b", topics=["/seapup/thrusters/command"]))
    assert len(msgs) == 50
    assert [m.t_ns for m in msgs] == sorted(m.t_ns for m in msgs)
    for i, m in enumerate(msgs):
        back = deserialize_message(m.cdr, BladePitch)
        assert back.header.stamp.sec == i and back.header.frame_id == "base_link_frd"
        assert list(back.pitch) == list(pitch(i).pitch)


def test_bag_is_rosbag2_v9_mcap_readable_by_the_mcap_library(tmp_path):
    write_sample(tmp_path / "b")
    meta = yaml.safe_load((tmp_path / "b" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["version"] == 9 and meta["storage_identifier"] == "mcap"
    assert meta["message_count"] == 55
    (storage_file,) = meta["relative_file_paths"]
    counts = {}
    with open(tmp_path / "b" / storage_file, "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        for schema, channel, message in reader.iter_messages():
            assert channel.message_encoding == "cdr" and schema.encoding == "ros2msg"
            counts[(channel.topic, schema.name)] = counts.get((channel.topic, schema.name), 0) + 1
    assert counts == {("/seapup/thrusters/command", PITCH_TYPE): 50, ("/notes", "std_msgs/msg/String"): 5}


def test_refuses_existing_directory_unknown_type_and_type_change(tmp_path):
    (tmp_path / "exists").mkdir()
    with pytest.raises(BagError, match="exists already"):
        BagRecorder(tmp_path / "exists", typestore())
    with BagRecorder(tmp_path / "b", make_typestore()) as bag:
        with pytest.raises(BagError, match="unknown to the typestore"):
            bag.write("/p", PITCH_TYPE, 0, b"")
        bag.write("/s", "std_msgs/msg/String", 0, serialize_message(String(data="x")))
        with pytest.raises(BagError, match="recorded as std_msgs/msg/String"):
            bag.write("/s", "std_msgs/msg/Header", 1, b"")


def test_unclosed_bag_is_reported(tmp_path):
    (tmp_path / "open").mkdir()
    with pytest.raises(BagError, match="no metadata.yaml"):
        list(read_bag(tmp_path / "open"))
