"""``./seapup teleop`` in a terminal: keys pressed in a pseudo-terminal become the pilot's Twist on
/seapup/pilot/cmd_vel, heard by a subscriber on the test's domain; ``x`` quits with the terminal restored.
The keys' logic is tested purely (seapup_control/test/test_manual.py's TeleopKeys cases below too)."""
import os
import pty
import subprocess
import sys
import termios

import pytest

from seapup_control.manual import TeleopKeys


@pytest.mark.unit
def test_each_key_steps_one_component_within_its_limit_and_space_stops():
    keys = TeleopKeys(linear_step=0.05, angular_step=0.1, max_linear=0.12, max_angular=0.25)
    for key in "wwwa":
        keys.press(key)
    assert keys.linear() == (0.12, 0.05, 0.0)   # bounded at 0.12
    assert keys.press("e") and keys.angular() == (0.0, 0.0, -0.1)
    assert not keys.press("?") and keys.linear() == (0.12, 0.05, 0.0)
    assert keys.press(" ") and keys.linear() == (0.0, 0.0, 0.0) and keys.angular() == (0.0, 0.0, 0.0)
    assert keys.press("x") and keys.quit
    with pytest.raises(ValueError):
        TeleopKeys(linear_step=float("nan"))


@pytest.mark.process
def test_teleop_in_a_terminal_publishes_the_pilot_s_twist(ros_context, ros_env, spin):
    from geometry_msgs.msg import Twist
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from seapup_common.ros.node import COMMAND_QOS
    heard = []
    node = Node("teleop_probe", context=ros_context)
    node.create_subscription(Twist, "/seapup/pilot/cmd_vel", heard.append, COMMAND_QOS)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    master, slave = pty.openpty()
    before = termios.tcgetattr(slave)
    proc = subprocess.Popen([sys.executable, "-m", "seapup_bringup.cli", "teleop"], stdin=slave, stdout=slave,
                            stderr=slave, env=ros_env, start_new_session=True)
    try:
        assert spin(executor, lambda: len(heard) >= 3, 60.0), "no Twist heard"
        assert heard[-1].linear.x == 0.0
        os.write(master, b"wwa")        # two steps forward, one left
        assert spin(executor, lambda: heard[-1].linear.x == pytest.approx(0.1), 20.0), heard[-1]
        assert heard[-1].linear.y == pytest.approx(0.05) and heard[-1].angular.z == 0.0
        os.write(master, b"q ")         # a turn, then stop
        assert spin(executor, lambda: heard[-1].linear.x == 0.0 and heard[-1].angular.z == 0.0, 20.0)
        os.write(master, b"x")
        assert proc.wait(timeout=30) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        after = termios.tcgetattr(slave)
        os.close(master)
        os.close(slave)
    assert after[3] == before[3]   # the terminal's local modes (echo, canonical input) restored


MANUAL_SPEC = {
    "name": "manual", "vehicle": "baseline", "environment": {"sensors": "ideal"}, "duration": 40.0,
    "controller": {"type": "manual", "parameters": {"silence_timeout": 60.0}},
    "design": {"vehicle": "baseline", "operating_points": [0.0]},
    "reference": [[0.0, 0.0, 0.0, 0.0, 0.0]],          # the task's: the manual law does not fly it
    "pilot": [[0.0, 0.2, -0.1, 0.0, 0.0]]}             # ahead 0.2, to starboard 0.1 (Twist y left) [m/s]


@pytest.mark.unit
def test_a_scripted_pilot_flies_the_seapup_in_process_under_the_manual_law():
    """A run spec's scripted pilot (a stick held ahead and to starboard): the self-tested fixed gains fly the
    Seapup to 0.2 m/s ahead and 0.1 m/s to starboard, not the run's zero reference."""
    import numpy as np
    from seapup_runs.runner import run
    from seapup_runs.spec import RunSpec
    result = run(RunSpec.from_dict(MANUAL_SPEC))
    truth, t = result.series.truth, result.series.t
    held = t > 30.0
    np.testing.assert_allclose([truth["u"][held].mean(), truth["v"][held].mean()], [0.2, 0.1], atol=0.01)
    assert RunSpec.from_dict(MANUAL_SPEC).to_dict()["pilot"] == [[0.0, 0.2, -0.1, 0.0, 0.0]]


@pytest.mark.graph
def test_a_scripted_pilot_flies_the_vehicle_through_the_graph_under_the_manual_law(tmp_path):
    """The same scripted client on the lockstep graph: the harness publishes the pilot's Twist on
    /seapup/pilot/cmd_vel as a teleop tool does, the ``manual`` velocity controller node flies it; the vehicle
    holds what the in-process run holds."""
    import numpy as np
    from seapup_bringup.graph.graph_runner import run_on_graph
    from seapup_runs.spec import RunSpec
    result = run_on_graph(RunSpec.from_dict(MANUAL_SPEC), out_dir=tmp_path)
    truth, t = result.series.truth, result.series.t
    held = t > 30.0
    np.testing.assert_allclose([truth["u"][held].mean(), truth["v"][held].mean()], [0.2, 0.1], atol=0.01)
