"""./seapup topic|node|param|service|interface against a running simulator (real processes).

Independent truth: the simulator's own parameters, rates and services (what
its node declares and publishes), and the effect of a command on the
simulated vehicle.
"""
import json
import statistics
import subprocess
import sys
import time

import pytest

from tests.test_simulator_node import start_simulator


def cli(env, *args, timeout=60):
    return subprocess.run([sys.executable, "-m", "seapup_bringup.cli", *args], env=env, capture_output=True,
                          text=True, timeout=timeout)


@pytest.fixture
def realtime_simulator(node_process, ros_env):
    # 5 Hz samples at 5x real time: 25 messages per wall second on every sample topic
    simulator = start_simulator(node_process, "mode:=realtime", "real_time_factor:=5.0", "start_depth:=50.0")
    # on the graph and publishing before a verb looks: a node takes ~1.5-2 s to start and be discovered, and
    # `topic list --timeout T` shows what was discovered within T (seen: an empty list on a loaded machine)
    up = cli(ros_env, "topic", "echo", "/seapup/truth/odometry", "--once")
    assert up.returncode == 0, up.stderr
    return simulator


def test_topic_list_info_echo_and_hz(realtime_simulator, ros_env):
    listed = cli(ros_env, "topic", "list", "-t", "--timeout", "2.0")
    assert listed.returncode == 0, listed.stderr
    assert "/seapup/sensors/velocity [geometry_msgs/msg/TwistWithCovarianceStamped]" in listed.stdout.splitlines()
    info = cli(ros_env, "topic", "info", "/seapup/thrusters/command", "-v")
    assert info.returncode == 0 and "Type: seapup_msgs/msg/BladePitch" in info.stdout
    assert "Publisher count: 0" in info.stdout and "Subscription count: 1" in info.stdout
    assert "Node name: simulator" in info.stdout and "Endpoint type: SUBSCRIPTION" in info.stdout
    echo = cli(ros_env, "topic", "echo", "/seapup/truth/odometry", "--once")
    assert echo.returncode == 0, echo.stderr
    text = echo.stdout
    assert text.startswith("header:\n  stamp:\n    sec: ") and "frame_id: odom_ned" in text
    assert "child_frame_id: base_link_frd" in text and text.rstrip().endswith("---")
    as_json = cli(ros_env, "topic", "echo", "/seapup/truth/odometry", "--once", "--json")
    (message,) = json.loads(as_json.stdout)["messages"]
    assert message["child_frame_id"] == "base_link_frd" and len(message["pose"]["covariance"]) == 36
    depth = cli(ros_env, "topic", "echo", "/seapup/truth/odometry", "--once", "--field", "pose.pose.position.z")
    assert 45.0 < float(depth.stdout.split()[0]) < 55.0  # started at 50 m, NED z down
    hz = cli(ros_env, "topic", "hz", "/seapup/truth/odometry", "--duration", "3")
    assert hz.returncode == 0, hz.stderr
    rate = float(hz.stdout.split("average rate:")[1].split()[0])
    assert 15.0 < rate < 35.0, hz.stdout  # 25 Hz: 5 Hz samples at 5x real time


def test_topic_pub_moves_the_vehicle(realtime_simulator, ros_env):
    # both mains +35 deg, the vectored at the hover setting (radians on every topic)
    pub = subprocess.Popen([sys.executable, "-m", "seapup_bringup.cli", "topic", "pub", "/seapup/thrusters/command",
                            "seapup_msgs/msg/BladePitch", "{pitch: [0.61, 0.61, -0.2286, -0.2286]}", "-r", "20",
                            "-t", "200"], env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline, u = time.monotonic() + 30.0, 0.0
        while time.monotonic() < deadline and u < 0.3:
            out = cli(ros_env, "topic", "echo", "/seapup/truth/odometry", "--once", "--field",
                      "twist.twist.linear.x")
            u = float(out.stdout.split()[0]) if out.returncode == 0 else 0.0
        assert u >= 0.3  # surging ahead under the published command
    finally:
        pub.terminate()
        pub.wait(10)


def test_params_and_services_of_the_simulator(realtime_simulator, ros_env):
    got = cli(ros_env, "param", "get", "/seapup/simulator", "real_time_factor")
    assert got.returncode == 0 and got.stdout.strip() == "Double value is: 5.0", got.stdout + got.stderr
    assert cli(ros_env, "param", "set", "/seapup/simulator", "real_time_factor", "4.0").returncode == 0
    assert cli(ros_env, "param", "get", "/seapup/simulator", "real_time_factor").stdout.strip() == \
        "Double value is: 4.0"
    refused = cli(ros_env, "param", "set", "/seapup/simulator", "mode", "lockstep")
    assert refused.returncode == 1 and "read-only" in refused.stderr  # the node's own reason
    listed = cli(ros_env, "param", "list", "/seapup/simulator")
    assert "  watchdog_timeout" in listed.stdout.splitlines()
    dumped = cli(ros_env, "param", "dump", "/seapup/simulator")
    assert dumped.stdout.startswith("/seapup/simulator:\n  ros__parameters:\n") and "real_time_factor: 4.0" in dumped.stdout

    def velocity_spread():
        out = cli(ros_env, "topic", "echo", "/seapup/sensors/velocity", "--count", "25", "--csv", "--field",
                  "twist.twist.linear.x")
        values = [float(line) for line in out.stdout.split()]
        return statistics.pstdev(values)
    noisy = velocity_spread()
    call = cli(ros_env, "service", "call", "/seapup/simulator/set_sensor_profile", "seapup_msgs/srv/SetSensorProfile",
               "{name: ideal}")
    assert call.returncode == 0 and "success: true" in call.stdout, call.stdout + call.stderr
    assert noisy > 10 * velocity_spread()  # the velocity noise is gone (truth drifts smoothly)
    services = cli(ros_env, "service", "list", "-t")
    assert "/seapup/simulator/reset [seapup_msgs/srv/Reset]" in services.stdout.splitlines()
    nodes = cli(ros_env, "node", "list")
    assert "/seapup/simulator" in nodes.stdout.splitlines()
    info = cli(ros_env, "node", "info", "/seapup/simulator")
    assert "    /seapup/thrusters/command: seapup_msgs/msg/BladePitch" in info.stdout


def test_bad_input_is_one_line_and_exit_1(realtime_simulator, ros_env):
    for args, words in ((["topic", "echo", "/nope", "--once", "--timeout", "1"], "unknown topic /nope"),
                        (["topic", "echo", "/seapup/truth/odometri", "--once", "--timeout", "1"],
                         "did you mean /seapup/truth/odometry?"),
                        (["topic", "pub", "/x", "seapup_msgs/msg/Nope", "{}"], "has no 'Nope'"),
                        (["topic", "pub", "/x", "seapup_msgs/msg/BladePitch", "{pitch: [1, 2]}", "-1"],
                         "exactly 4 values"),
                        (["service", "call", "/seapup/simulator/reset", "seapup_msgs/srv/Reset", "{sed: 3}"],
                         "no field 'sed'"),
                        (["param", "get", "/nobody", "x", "--timeout", "1"], "not available"),
                        (["interface", "show", "seapup_msgs/msg/Nope"], "has no 'Nope'"),
                        (["topic", "pub", "/x", "seapup_msgs/srv/Reset", "{}", "-1"], "is not a message type"),
                        (["service", "call", "/x", "seapup_msgs/msg/BladePitch", "{}"], "is not a service type"),
                        (["topic", "pub", "/x", "seapup_msgs/msg/BladePitch", "{pitch: [1, 2, 3", "-1"], "")):
        out = cli(ros_env, *args)
        assert out.returncode == 1 and words in out.stderr and len(out.stderr.strip().splitlines()) == 1, \
            (args, out.stderr)


@pytest.mark.process
def test_interface_show_lists_the_fields_nested():
    out = subprocess.run([sys.executable, "-m", "seapup_bringup.cli", "interface", "show",
                          "seapup_msgs/srv/SetCurrent"], capture_output=True, text=True, timeout=60)
    lines = out.stdout.splitlines()
    assert out.returncode == 0 and lines[:2] == ["bool enabled", "float64 mean_speed"]  # .msg spelling
    assert "float64 at" in lines and "---" in lines and lines[-1] == "string message"
    nested = subprocess.run([sys.executable, "-m", "seapup_bringup.cli", "interface", "show",
                             "seapup_msgs/msg/BladePitch"], capture_output=True, text=True, timeout=60).stdout
    # the constants that define the thruster order come first, typed as in the .msg (they were dropped)
    assert nested.splitlines() == ["uint8 MAIN_PORT=0", "uint8 MAIN_STARBOARD=1", "uint8 VECTORED_STARBOARD=2",
                                   "uint8 VECTORED_PORT=3", "uint8 COUNT=4", "",
                                   "std_msgs/Header header", "\tbuiltin_interfaces/Time stamp", "\t\tint32 sec",
                                   "\t\tuint32 nanosec", "\tstring frame_id", "float64[4] pitch"]


def test_action_list_and_send_goal_run_the_self_test(node_process, ros_env, tmp_path):
    from tests.test_self_test_action import start_graph
    start_graph(node_process, self_test_params=[f"result_dir:={tmp_path}", "wait_for_command_subscribers:=1"])
    # a list is what discovery has found by then (as ros2cli's): on a loaded machine the self-test's server can
    # come a moment after the simulator's, so ask again, a bounded number of times, until it is there
    for _ in range(5):
        listed = cli(ros_env, "action", "list", "-t")
        if "/seapup/self_test [seapup_msgs/action/SelfTest]" in listed.stdout.splitlines():
            break
    assert "/seapup/self_test [seapup_msgs/action/SelfTest]" in listed.stdout.splitlines(), listed.stdout
    run = cli(ros_env, "action", "send_goal", "/seapup/self_test", "seapup_msgs/action/SelfTest",
              "{operating_points: [0.0]}", "--feedback", "--json", timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    result = json.loads(run.stdout)
    assert result["status"] == "succeeded" and result["result"]["success"] is True
    assert len(result["result"]["b0_inverse"]) == 16 and result["result"]["surge_speeds"] == [0.0]
    phases = {f["phase"] for f in result["feedback"]}
    # the feedback reports progress to the end, also what arrives just after the result (beside two CPU burners the
    # last one shown was once at 0.978: rclpy had dropped the goal's feedback callback with its result)
    assert {"quiesce", "step"} <= phases and max(f["progress"] for f in result["feedback"]) > 0.99
    assert "Goal finished with status: SUCCEEDED" in run.stderr and "Feedback:\nphase: " in run.stderr
    # a goal the server refuses: exit 1, said so
    refused = cli(ros_env, "action", "send_goal", "/seapup/self_test", "seapup_msgs/action/SelfTest",
                  "{operating_points: [0.7]}")
    assert refused.returncode == 1 and "Goal was rejected." in refused.stdout
