"""The recorder node records another process's topics into a readable bag."""
from rclpy.serialization import deserialize_message
from seapup_msgs.msg import BladePitch

from seapup_common.bag import read_bag


def start_recorder(node_process, bag_dir, topics: list[str], awaited: str, *params: str):
    """The recorder on ``topics`` into ``bag_dir`` (``params``: more ``name:=value``), once its log says it
    subscribed to ``awaited`` (a typed topic is subscribed at start)."""
    import time
    rec = node_process(package="seapup_common", executable="recorder",
                       args=["--ros-args", "-p", f"bag_path:={bag_dir}", "-p", f"topics:={topics}",
                             *[a for p in params for a in ("-p", p)]])
    deadline = time.monotonic() + 20.0
    while time.monotonic() < deadline and f"recording {awaited} [" not in rec.log_text():
        time.sleep(0.05)
    return rec


def test_recorder_bags_the_open_loop_commands(node_process, tmp_path):
    bag_dir = tmp_path / "bag"
    rec = node_process(package="seapup_common", executable="recorder",
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


def _typed_recording(ros_context, node_process, spin, tmp_path, qos):
    """Start a recorder on a typed topic before its publisher, then publish 20 strings with ``qos``."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import String

    bag_dir = tmp_path / "bag"
    rec = start_recorder(node_process, bag_dir, ["/typed:std_msgs/msg/String"], "/typed", "discovery_period:=0.1")
    node = rclpy.create_node("typed_source", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    pub = node.create_publisher(String, "/typed", qos)
    assert spin(executor, lambda: pub.get_subscription_count() >= 1, 20.0), rec.log_text()
    spin(executor, lambda: False, 0.5)  # the match is seen here first; give the recorder's side time too
    for k in range(20):
        pub.publish(String(data=f"m{k}"))
        spin(executor, lambda: False, 0.02)
    spin(executor, lambda: False, 0.5)
    assert rec.stop() == 0, rec.log_text()
    node.destroy_node()
    return bag_dir


def test_typed_topic_records_the_publishers_offered_qos(ros_context, node_process, spin, tmp_path):
    """A topic named with its type is subscribed at once, but the bag keeps the publisher's QoS."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    from seapup_common.bag import bag_info

    qos = QoSProfile(depth=7, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    bag_dir = _typed_recording(ros_context, node_process, spin, tmp_path, qos)
    assert [deserialize_message(m.cdr, String).data for m in read_bag(bag_dir)] == [f"m{k}" for k in range(20)]
    (topic,) = bag_info(bag_dir)["topics"]
    (offered,) = topic["qos"]  # the publisher's, not the eager subscription's default (volatile)
    assert (offered["reliability"], offered["durability"]) == ("reliable", "transient_local")


def test_typed_topic_matches_a_best_effort_publisher(ros_context, node_process, spin, tmp_path):
    """A reliable eager subscription cannot match a best-effort publisher: it is replaced by one that can."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    from seapup_common.bag import bag_info

    bag_dir = _typed_recording(ros_context, node_process, spin, tmp_path,
                               QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT))
    got = [deserialize_message(m.cdr, String).data for m in read_bag(bag_dir)]
    assert len(got) >= 18 and got == sorted(got, key=lambda s: int(s[1:]))  # loopback best effort: (nearly) all
    (topic,) = bag_info(bag_dir)["topics"]
    assert [q["reliability"] for q in topic["qos"]] == ["best_effort"]


def test_typed_topic_gets_what_a_latched_publisher_said_before_they_matched(ros_context, node_process, spin,
                                                                            tmp_path):
    """Issue 43: the simulator latches /tf_static once, at its start; the recorder's eager subscription
    (volatile) never got it unless it happened to match first. A transient-local publisher's eager
    subscription is replaced by a transient-local one, which takes the latched message: exactly once."""

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    bag_dir = tmp_path / "bag"
    node = rclpy.create_node("latched_source", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    pub = node.create_publisher(String, "/latched", QoSProfile(
        depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    # said before the recorder exists, so before any match whatever discovery's speed: only the latch has it
    pub.publish(String(data="said once, before any match"))
    rec = start_recorder(node_process, bag_dir, ["/latched:std_msgs/msg/String"], "/latched",
                         "discovery_period:=0.1")
    assert spin(executor, lambda: "first message on /latched" in rec.log_text(), 20.0), rec.log_text()
    spin(executor, lambda: pub.get_subscription_count() >= 1, 5.0)
    assert rec.stop() == 0, rec.log_text()
    node.destroy_node()
    assert [deserialize_message(m.cdr, String).data for m in read_bag(bag_dir)] == ["said once, before any match"]


def _said_twice(ros_context, node_process, spin, tmp_path, *params):
    """Record a stamped and a plain topic while each message is published twice in a row (the second
    stamped pair differing in a field); the bag's (topic, decoded) messages."""

    import rclpy
    from geometry_msgs.msg import PointStamped
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import String

    bag_dir = tmp_path / "bag"
    rec = start_recorder(node_process, bag_dir, ["/stamped:geometry_msgs/msg/PointStamped",
                                                 "/plain:std_msgs/msg/String"], "/plain", *params)
    node = rclpy.create_node("repeating_source", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    stamped, plain = node.create_publisher(PointStamped, "/stamped", 10), node.create_publisher(String, "/plain", 10)
    assert spin(executor, lambda: stamped.get_subscription_count() and plain.get_subscription_count(), 20.0)
    spin(executor, lambda: False, 0.5)  # the match is seen here first; give the recorder's side time too
    for sec, x in ((1, 0.0), (1, 0.0), (2, 0.0), (2, 5.0)):
        msg = PointStamped()
        msg.header.stamp.sec, msg.point.x = sec, x
        stamped.publish(msg)
        plain.publish(String(data="again"))
    assert spin(executor, lambda: rec.log_text().count("first message") == 2, 10.0), rec.log_text()
    spin(executor, lambda: False, 0.5)
    assert rec.stop() == 0, rec.log_text()
    node.destroy_node()
    kinds = {"/stamped": PointStamped, "/plain": String}
    return [(m.topic, deserialize_message(m.cdr, kinds[m.topic])) for m in read_bag(bag_dir)], rec.log_text()


def test_a_sample_said_again_is_recorded_once(ros_context, node_process, spin, tmp_path):
    """Issue 43: a lockstep simulator says a sample again (t_0 on /clock until the first command; the held
    sample when it resumes before it was answered), so the copies in a bag depended on wall time. A message
    that carries its sample's time and repeats the previous one's bytes is recorded once; a plain message
    (no time of its own: each is an event) and a stamped one that differs in any field are all recorded."""
    got, log = _said_twice(ros_context, node_process, spin, tmp_path)
    assert [(m.header.stamp.sec, m.point.x) for t, m in got if t == "/stamped"] == [(1, 0.0), (2, 0.0), (2, 5.0)]
    assert [m.data for t, m in got if t == "/plain"] == ["again"] * 4
    assert "(1 repeats of a sample not recorded again)" in log


def test_record_repeats_keeps_every_copy(ros_context, node_process, spin, tmp_path):
    got, log = _said_twice(ros_context, node_process, spin, tmp_path, "record_repeats:=true")
    assert [(m.header.stamp.sec, m.point.x) for t, m in got if t == "/stamped"] == [(1, 0.0), (1, 0.0), (2, 0.0),
                                                                                  (2, 5.0)]
    assert "repeats of a sample" not in log
