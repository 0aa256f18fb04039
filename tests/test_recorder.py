"""The recorder node records another process's topics into a readable bag."""
from rclpy.serialization import deserialize_message
from seapup_msgs.msg import BladePitch

from seapup_common.bag import read_bag


def test_recorder_bags_the_open_loop_commands(node_process, tmp_path):
    bag_dir = tmp_path / "bag"
    rec = node_process(package="seapup_ident", executable="recorder",
                       args=["--ros-args", "-p", f"bag_path:={bag_dir}",
                             "-p", "topics:=['/seapup/thrusters/command']"])
    src = node_process(package="seapup_control", executable="open_loop",
                       args=["--ros-args", "-p", "sample_period:=0.05",
                             "-p", "times:=[0.0, 0.5]",
                             "-p", "pitches:=[0.1, 0.1, 0.0, 0.0, 0.0, 0.0, -0.2, -0.2]"])
    import time
    deadline = time.monotonic() + 20.0
    while time.monotonic() < deadline and "recording /seapup/thrusters/command [" not in rec.log_text():
        time.sleep(0.05)
    assert "recording /seapup/thrusters/command [seapup_msgs/msg/BladePitch]" in rec.log_text()
    time.sleep(1.5)  # let ~30 commands flow, both schedule segments included
    src.stop()
    assert rec.stop() == 0, rec.log_text()
    msgs = [deserialize_message(m.cdr, BladePitch) for m in read_bag(bag_dir)]
    assert len(msgs) >= 15, rec.log_text()
    pitches = {tuple(m.pitch) for m in msgs}
    assert pitches <= {(0.1, 0.1, 0.0, 0.0), (0.0, 0.0, -0.2, -0.2)}
    assert (0.0, 0.0, -0.2, -0.2) in pitches
