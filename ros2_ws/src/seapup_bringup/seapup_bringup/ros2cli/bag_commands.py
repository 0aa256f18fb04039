"""``./seapup record``, ``./seapup bag info|recover`` and ``./seapup replay``: the
embedded ``ros2 bag`` (rosbag2 Jazzy layout, see :mod:`seapup_common.bag`).

- record: runs the ``recorder`` node (seapup_common), passes it Ctrl-C/SIGTERM, then
  prints (or ``--json``) what the closed bag holds;
- bag info / recover: read a bag's metadata, rebuild a killed recorder's bag;
- replay: publishes the recorded bytes with the recorded QoS (reliability,
  durability) at the recorded log-time spacing scaled by ``--rate``,
  optionally ``/clock`` from the bag so sim-time nodes follow it; or, with
  ``--lockstep TOPIC``, sample by sample as the lockstep simulator does,
  waiting for the node under test to answer each sample on TOPIC.
"""
from __future__ import annotations

import argparse
import signal
import struct
import sys
import time
from itertools import groupby
from pathlib import Path

import yaml

from seapup_bringup.output import add_json_argument, emit_json, progress, text_stream
from seapup_common.bag import BagError, bag_info, check_storage_files, recover_bag, storage_files
from seapup_common.topics import CLOCK, TRUTH_ODOMETRY

__all__ = ["record", "bag", "replay"]


def _clock_published(wait: float) -> bool:
    """True if ``/clock`` has a publisher on the graph within ``wait`` seconds."""
    import rclpy
    from rclpy.context import Context

    from seapup_common.topics import CLOCK
    context = Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node("seapup_record_clock_probe", context=context)
        deadline = time.monotonic() + max(wait, 0.0)
        while True:
            if node.count_publishers(CLOCK) > 0:
                return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.05)
    finally:
        context.try_shutdown()


def record_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup record`` (its usage line in ``./seapup help`` is generated from it)."""
    parser = argparse.ArgumentParser(prog="./seapup record", description="record topics into a rosbag2/MCAP bag")
    parser.add_argument("-o", "--output", help="bag directory to create (default bags/rosbag2_<UTC time>)")
    parser.add_argument("--topics", nargs="+", default=[], help="topics (/t or /t:pkg/msg/Type)")
    parser.add_argument("--all", action="store_true", help="record every topic that appears")
    parser.add_argument("--exclude", default="", help="regular expression of topics not to record")
    parser.add_argument("--max-duration", type=float, default=0.0, help="stop after this many graph seconds")
    parser.add_argument("--flush-interval", type=float, default=1.0, help="flush + fsync period [s]")
    parser.add_argument("--max-bag-size", type=int, default=0, help="split files at this many bytes (0: never)")
    parser.add_argument("--max-bag-duration", type=float, default=0.0,
                        help="split files at this many seconds (0: never)")
    clock = parser.add_mutually_exclusive_group()
    clock.add_argument("--use-sim-time", dest="use_sim_time", action="store_const", const=True, default=None,
                       help="log the graph's /clock time (the default when /clock has a publisher)")
    clock.add_argument("--wall-time", dest="use_sim_time", action="store_const", const=False,
                       help="log wall-clock time even when /clock is published")
    parser.add_argument("--clock-wait", type=float, default=5.0,
                        help="seconds to look for a /clock publisher when neither is given (default 5)")
    add_json_argument(parser)
    return parser


def record(argv: list[str]) -> int:
    """``./seapup record``: start a recorder node with the given topics (Ctrl-C finalises the bag)."""
    parser = record_parser()
    args = parser.parse_args(argv)
    if not args.topics and not args.all:
        parser.error("give --topics or --all")
    if args.use_sim_time is None:
        args.use_sim_time = _clock_published(args.clock_wait)
        reason = "/clock is published" if args.use_sim_time else f"no /clock publisher within {args.clock_wait:g} s"
    else:
        reason = "--use-sim-time" if args.use_sim_time else "--wall-time"
    print(f"seapup record: logging {'the graph time of /clock' if args.use_sim_time else 'wall-clock time'} "
          f"({reason})", file=sys.stderr)
    if not all(v >= 0 for v in (args.flush_interval, args.max_duration, args.max_bag_size, args.max_bag_duration)):
        parser.error("--flush-interval, --max-duration, --max-bag-size and --max-bag-duration must be >= 0")
    from seapup_common.processes import find_executable, spawn
    from seapup_common.recorder_node import default_bag_path
    output = Path(args.output).resolve() if args.output else default_bag_path().resolve()
    if output.exists():
        parser.error(f"{output} exists: a bag is never overwritten")
    exe = find_executable("seapup_common", "recorder")
    ros = ["--ros-args", "-p", f"topics:={list(args.topics) or ['']}", "-p", f"all:={str(args.all).lower()}",
           *(["-p", f"exclude:={args.exclude}"] if args.exclude else []),
           "-p", f"max_duration:={float(args.max_duration)}",
           "-p", f"flush_interval:={float(args.flush_interval)}", "-p", f"max_bag_size:={int(args.max_bag_size)}",
           "-p", f"max_bag_duration:={float(args.max_bag_duration)}",
           "-p", f"use_sim_time:={str(args.use_sim_time).lower()}", "-p", f"bag_path:={output}"]
    # the recorder runs as a child so that, when it has closed the bag (Ctrl-C, SIGTERM or
    # --max-duration), this process can say what is in it
    child = spawn([str(exe), *ros])  # signals come once, from us; dies with us

    def forward(signum, frame):  # a closed terminal (SIGHUP) finalises the bag as Ctrl-C does
        child.send_signal(signal.SIGINT if signum == signal.SIGHUP else signum)
    previous = {s: signal.signal(s, forward) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    try:
        code = child.wait()
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    out = text_stream(args)
    if code not in (0, -signal.SIGINT):
        print(f"seapup record: the recorder exited with {code}", file=sys.stderr)
        return 1
    try:
        info = bag_info(output)
    except (BagError, OSError) as exc:
        print(f"seapup record: {exc}", file=sys.stderr)
        return 1
    print(f"recorded {info['messages']} messages in {info['duration_s']:.1f} s into {output}: "
          + ", ".join(f"{t['name']} {t['count']}" for t in info["topics"]), file=out)
    emit_json(args, info)
    return 0


def bag_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup bag`` (its usage line in ``./seapup help`` is generated from it)."""
    parser = argparse.ArgumentParser(prog="./seapup bag", description="inspect or recover a bag")
    parser.add_argument("verb", choices=("info", "recover"))
    parser.add_argument("path", type=Path)
    add_json_argument(parser)
    return parser


def bag(argv: list[str]) -> int:
    """``./seapup bag info DIR`` / ``./seapup bag recover DIR``."""
    hints = {"play": "replay DIR", "record": "record [--topics T... | --all]"}
    if argv and argv[0] in hints:  # the ros2 bag spelling
        print(f"seapup bag: '{argv[0]}' is its own command here: ./seapup {hints[argv[0]]} "
              f"(./seapup {hints[argv[0]].split()[0]} --help)", file=sys.stderr)
        return 2
    parser = bag_parser()
    args = parser.parse_args(argv)
    out = text_stream(args)
    try:
        result = bag_info(args.path) if args.verb == "info" else recover_bag(args.path)
    except (BagError, OSError) as exc:
        print(f"seapup: error: {exc}", file=sys.stderr)
        return 1
    if args.verb == "recover":
        print(_recover_line(result), file=out)
        if result["intact"]:   # nothing changed on disk
            emit_json(args, result)
            return 0
        result = {**result, "info": bag_info(args.path)}
        info = result["info"]
    else:
        info = result
    print(f"Files:             {', '.join(info['files'])}\nBag size:          {info['bag_size_bytes']} B\n"
          f"Storage id:        {info['storage_id']}\nROS Distro:        {info['ros_distro']}\n"
          f"Duration:          {info['duration_s']:.9f}s\nStart:             {info['start_s']:.9f}\n"
          f"End:               {info['end_s']:.9f}\nMessages:          {info['messages']}", file=out)
    for t in info["topics"]:
        qos = t["qos"][0] if t["qos"] else {}
        print(f"  Topic: {t['name']} | Type: {t['type']} | Count: {t['count']} | Serialization Format: "
              f"{t['serialization_format']} | QoS: {qos.get('reliability', '?')}, {qos.get('durability', '?')}",
              file=out)
    emit_json(args, result)
    return 0


def _recover_line(result: dict) -> str:
    """What ``bag recover`` did, in one line: nothing (intact), or what it kept and under which names."""
    if result["intact"]:
        return f"nothing to recover: the bag is intact ({result['messages']} messages); nothing changed"
    if result["damaged_file"]:
        return (f"recovered {result['messages']} messages (reading stopped: {result['stopped_at']}); "
                f"damaged file kept as {result['damaged_file']}")
    return (f"recovered {result['messages']} messages: the files were whole, metadata.yaml rebuilt; originals kept "
            f"as {', '.join(result['kept'])}")


def _qos(channel_metadata: dict):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from seapup_common.input_files import InputFileError, parse_yaml
    try:   # the bag's text: strict and bounded YAML; unreadable profiles are the defaults
        profiles = parse_yaml(str(channel_metadata.get("offered_qos_profiles") or "[]"), "offered_qos_profiles")
    except InputFileError:
        profiles = []
    first = profiles[0] if isinstance(profiles, list) and profiles and isinstance(profiles[0], dict) else {}
    return QoSProfile(depth=1000,
                      reliability=(ReliabilityPolicy.BEST_EFFORT if first.get("reliability") == "best_effort"
                                   else ReliabilityPolicy.RELIABLE),
                      durability=(DurabilityPolicy.TRANSIENT_LOCAL if first.get("durability") == "transient_local"
                                  else DurabilityPolicy.VOLATILE))


def replay_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup replay`` (its usage line in ``./seapup help`` is generated from it)."""
    parser = argparse.ArgumentParser(prog="./seapup replay", description="play a bag back onto the graph")
    parser.add_argument("path", type=Path)
    parser.add_argument("--rate", type=float, default=1.0, help="speed factor (> 0)")
    parser.add_argument("--topics", nargs="+", help="only these topics")
    parser.add_argument("--clock", action="store_true",
                        help="publish /clock from the bag's log times (instead of a recorded /clock)")
    parser.add_argument("--loop", action="store_true", help="play again from the start at the end")
    parser.add_argument("--start-offset", type=float, default=0.0, help="skip this many seconds [bag time]")
    parser.add_argument("--wait-for-subscribers", type=int, default=0, metavar="N",
                        help="start only once every replayed topic has N matched subscribers (30 s at most)")
    parser.add_argument("--lockstep", metavar="TOPIC",
                        help="drive a node under test sample by sample: publish /clock t_k and the messages "
                             "logged at t_k, then wait for its answer on TOPIC (stamped >= t_k) before t_k+1; "
                             "the recorded TOPIC is not replayed")
    parser.add_argument("--view", action="store_true",
                        help="play into the live view (docs/live-view.md): the bag's truth, commands and estimates")
    parser.add_argument("--view-port", type=int, default=8765, help="its port (default 8765)")
    parser.add_argument("--lockstep-timeout", type=float, default=10.0,
                        help="seconds to wait for an answer before going on (counted as a timeout)")
    add_json_argument(parser)
    return parser


def replay(argv: list[str]) -> int:
    """``./seapup replay DIR``: publish a bag's messages with their recorded timing, or in lockstep."""
    parser = replay_parser()
    args = parser.parse_args(argv)
    if not (0 < args.rate < 1e6 and args.start_offset >= 0 and args.lockstep_timeout > 0):
        parser.error("--rate and --lockstep-timeout must be > 0 and --start-offset >= 0")
    if args.lockstep and args.loop:
        parser.error("--lockstep plays the bag once (--loop would send time backwards)")
    if args.view:
        from seapup_live_view.attach import check_port
        try:
            check_port(args.view_port)
        except ValueError as exc:
            parser.error(str(exc))
    clock = args.clock or bool(args.lockstep)
    try:
        check_storage_files(args.path)   # not MCAP, or truncated: a reason, before any reader seeks
        answer_type, channels, records = _load_replay(args.path, args.topics, args.lockstep, clock)
    except BagError as exc:
        print(f"seapup: error: {exc}", file=sys.stderr)
        return 1
    if not records:
        print("seapup: nothing to replay", file=sys.stderr)
        return 1
    t0 = records[0][0] + int(args.start_offset * 1e9)
    records = [r for r in records if r[0] >= t0]
    if args.lockstep and answer_type is None:
        print(f"seapup: error: the bag does not say the type of {args.lockstep}; record it with the bag",
              file=sys.stderr)
        return 1
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rosgraph_msgs.msg import Clock

    from seapup_common.recorder_node import message_class

    rclpy.init()
    node = rclpy.create_node("replay")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    pubs = {cid: node.create_publisher(message_class(type_name), topic, qos)
            for cid, (topic, type_name, qos) in channels.items()}
    clock_pub = node.create_publisher(Clock, CLOCK, _qos({})) if clock else None
    report = {"sent": 0, "topics": sorted(topic for topic, _, _ in channels.values())}
    answers = _answer_subscription(node, args.lockstep, message_class(answer_type)) if args.lockstep else None
    view = _start_view(args.view_port, args.path) if args.view else None
    try:
        if view is not None:
            _await_view(executor, pubs, channels)
        # lockstep: the node under test must hear /clock and be heard on the answer topic;
        # timed: every replayed topic needs its subscribers
        needed = [clock_pub] if args.lockstep else list(pubs.values())

        def ready():
            return all(p.get_subscription_count() >= args.wait_for_subscribers for p in needed) and (
                not args.lockstep or node.count_publishers(args.lockstep) >= 1)
        deadline = time.monotonic() + (30.0 if args.wait_for_subscribers > 0 else 0.5)
        while time.monotonic() < deadline and not (args.wait_for_subscribers > 0 and ready()):
            executor.spin_once(timeout_sec=0.05)  # let subscribers match
        if args.lockstep:
            report.update(_play_lockstep(executor, pubs, clock_pub, records, args, answers))
        else:
            _play_timed(executor, pubs, clock_pub, records, args, report)
    except KeyboardInterrupt:
        pass
    finally:
        from rclpy.duration import Duration
        for pub in [*pubs.values(), *([clock_pub] if clock_pub else [])]:  # reliable subscribers get the last
            pub.wait_for_all_acked(Duration(seconds=2.0))
        node.destroy_node()
        rclpy.try_shutdown()
        if view is not None:
            view.stop()
    line = f"replayed {report['sent']} messages"
    if args.lockstep:
        line += (f" in {report['samples']} samples: {report['answered']} answered on {args.lockstep}, "
                 f"{report['timeouts']} timed out")
    print(line, file=text_stream(args))
    emit_json(args, report)
    return 0 if not args.lockstep or report["timeouts"] == 0 else 1


def _start_view(port: int, bag: Path):
    """The live view on this domain, for a replay (its log in the temporary directory)."""
    import os
    import tempfile
    from seapup_live_view.attach import view_node, view_url
    from seapup_common.processes import NodeProcess
    from seapup_common.ros.launch_graph import command_line
    log = Path(tempfile.gettempdir()) / f"seapup_live_view_{os.getpid()}.log"
    process = NodeProcess(command_line(view_node(port)), dict(os.environ), log, "live_view").start()
    print(f"seapup replay: live view at {view_url(port)}", file=sys.stderr)
    return process


def _await_view(executor, pubs, channels, timeout: float = 15.0) -> None:
    """Wait (briefly) until the view listens to the bag's truth, so it draws from the first sample."""
    truth = [pub for cid, pub in pubs.items() if channels[cid][0] == TRUTH_ODOMETRY]
    deadline = time.monotonic() + timeout
    while truth and time.monotonic() < deadline and truth[0].get_subscription_count() < 1:
        executor.spin_once(timeout_sec=0.05)


def _load_replay(path: Path, topics, lockstep_topic, clock: bool):
    """The channels to publish ({topic: (topic, type, QoS)}) and their messages in log-time order.

    A recorded ``/clock`` is left out when replay makes its own, and the
    lockstep answer topic is left out (the node under test publishes it); the
    answer topic's type is returned from the bag's channels.
    """
    from mcap.exceptions import McapError
    try:
        return _read_replay(path, topics, lockstep_topic, clock)
    except (McapError, EOFError, ValueError, KeyError, struct.error) as exc:
        raise BagError(f"the bag's MCAP files cannot be read ({str(exc).splitlines()[0][:120] if str(exc) else 'damaged'})"
                       f": run ./seapup bag recover {path}") from None


def _read_replay(path: Path, topics, lockstep_topic, clock: bool):
    from mcap.reader import make_reader
    all_types, channels, records = {}, {}, []
    for storage in storage_files(path):  # a split bag: file after file, channels by topic
        with open(storage, "rb") as f:
            reader = make_reader(f)
            summary = reader.get_summary()
            if summary is None:
                raise BagError(f"the bag's MCAP file {storage.name} has no summary: run ./seapup bag recover {path}")
            for c in summary.channels.values():
                all_types[c.topic] = summary.schemas[c.schema_id].name
                if ((topics is None or c.topic in topics) and c.topic != lockstep_topic
                        and not (clock and c.topic == CLOCK)):
                    channels.setdefault(c.topic, (c.topic, all_types[c.topic], _qos(c.metadata)))
            records += [(m.log_time, c.topic, bytes(m.data)) for _, c, m in
                        reader.iter_messages(topics=list(channels), log_time_order=True)]
    return all_types.get(lockstep_topic), channels, records


def _play_timed(executor, pubs, clock_pub, records, args, report) -> None:
    """Publish at the recorded log-time spacing divided by ``--rate`` (and again with ``--loop``)."""
    from rosgraph_msgs.msg import Clock

    from seapup_common.ros.messages import ns_to_stamp
    t0 = records[0][0]
    while True:
        wall0 = time.monotonic()
        for k, (t_ns, cid, data) in enumerate(records):
            due = wall0 + (t_ns - t0) * 1e-9 / args.rate
            while (left := due - time.monotonic()) > 0:
                executor.spin_once(timeout_sec=min(left, 0.05))
            if clock_pub is not None:
                clock_pub.publish(Clock(clock=ns_to_stamp(t_ns)))
            pubs[cid].publish(data)
            report["sent"] += 1
            if k % 50 == 0:
                progress("replaying", (k + 1) / len(records))
        progress("replaying", 1.0)
        if not args.loop:
            return


def _answer_subscription(node, topic: str, answer_class) -> list:
    """Collect the header stamps (None if unstamped) of the node under test's answers."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from seapup_common.bag import header_stamp_ns
    answers: list[int | None] = []
    stamped = hasattr(answer_class, "header")
    node.create_subscription(answer_class, topic, lambda raw: answers.append(header_stamp_ns(raw) if stamped else None),
                             QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE), raw=True)
    return answers


def _play_lockstep(executor, pubs, clock_pub, records, args, answers: list) -> dict:
    """Act as a lockstep simulator from the bag: one sample (log time t_k) at a time.

    Publishes ``/clock`` t_k and every message logged at t_k, then waits until
    the node under test answers on ``--lockstep`` with a message stamped t_k or
    later (any message, if the type has no header) -- the protocol of the
    simulator's lockstep mode, so a controller cannot tell the two apart. As
    the simulator does, the first sample's ``/clock`` is said again every
    0.2 s until the first answer (a node may start listening late).
    """
    from rosgraph_msgs.msg import Clock

    from seapup_common.ros.messages import ns_to_stamp
    samples = [(t, [(cid, data) for _, cid, data in group]) for t, group in groupby(records, key=lambda r: r[0])]
    result = {"sent": 0, "samples": len(samples), "answered": 0, "timeouts": 0}
    for k, (t_ns, messages) in enumerate(samples):
        seen = len(answers)
        clock_pub.publish(Clock(clock=ns_to_stamp(t_ns)))
        for cid, data in messages:
            pubs[cid].publish(data)
            result["sent"] += 1

        def answered():
            return any(a is None or a >= t_ns for a in answers[seen:])
        deadline = time.monotonic() + args.lockstep_timeout
        resend = time.monotonic() + 0.2
        while not answered() and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.01)
            if k == 0 and time.monotonic() > resend:
                clock_pub.publish(Clock(clock=ns_to_stamp(t_ns)))
                resend = time.monotonic() + 0.2
        if answered():
            result["answered"] += 1
        else:
            result["timeouts"] += 1
            print(f"seapup replay: no answer on {args.lockstep} for t = {t_ns * 1e-9:.3f} s within "
                  f"{args.lockstep_timeout:g} s", file=sys.stderr)
        if k % 20 == 0:
            progress("replaying", (k + 1) / len(samples))
    progress("replaying", 1.0)
    return result
