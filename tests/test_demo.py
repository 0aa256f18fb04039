"""The README's main command, in short: the demo flies, records and summarises."""
import subprocess
import sys

from rclpy.serialization import deserialize_message
from nav_msgs.msg import Odometry

from seapup_ident.bag import read_bag


def test_demo_flies_records_and_summarises(tmp_path, ros_env):
    out = tmp_path / "demo"
    run = subprocess.run([sys.executable, "-m", "seapup_control.demo", "--duration", "16", "--out", str(out)],
                         env=ros_env, capture_output=True, text=True, timeout=180)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "flew 16.0 s of simulated time" in run.stdout
    for name in ("hover", "surge", "sway"):
        assert f"\n{name} " in run.stdout
    truth = [deserialize_message(m.cdr, Odometry) for m in read_bag(out / "bag", ["/seapup/truth/odometry"])]
    assert len(truth) >= 80  # 16 s at 5 Hz
    # the surge segment (4-8 s, mains +35 deg) really drives the vehicle ahead
    speeds = [m.twist.twist.linear.x for m in truth if 4.0 <= m.header.stamp.sec < 8.0]
    assert max(speeds) > 0.5
