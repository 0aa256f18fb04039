"""ros2cli's introspection verbs for the embedded install: ``./seapup topic|node|param|service|interface``.

Same spelling and output formats as ``ros2 topic echo`` & co. (users with a
system ROS 2 keep using ros2cli on our packages), messages converted
generically by :mod:`seapup_common.ros.introspection`. Every verb runs one
short-lived node on the current ``ROS_DOMAIN_ID`` (loopback discovery), waits
at most ``--timeout`` seconds for what it needs, and ends with a one-line
error and exit 1 on an unknown topic, type or node, or data that does not fit
the type; nothing waits forever. Works with sim time: the verbs never use the
node clock.
"""
from __future__ import annotations

import argparse
import math
import sys
import time

import yaml

from seapup_bringup.output import add_json_argument, emit_json, text_stream

__all__ = ["topic", "node", "param", "service", "action", "interface"]


class CommandError(RuntimeError):
    """A one-line reason for exit 1."""


def _did_you_mean(name: str, known) -> str:
    """``"; did you mean /seapup/x?"`` for the nearest of ``known`` names other than ``name`` itself, or "".

    The graph lists a service as soon as a client asks for it (our own probe's client for the mistyped
    name included), so the name itself is never a suggestion."""
    from seapup_common.config import nearest
    near = nearest(name, [k for k in known if k != name])
    return f"; did you mean {near}?" if near else ""


class Probe:
    """One node on the graph, spun by hand."""

    def __init__(self, name: str = "seapup_cli"):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(f"{name}_{int(time.time() * 1000) % 100000}", context=self.context,
                                      start_parameter_services=False)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def spin_until(self, predicate, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not predicate() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)
        return bool(predicate())

    def call(self, srv_type, name: str, request, timeout: float):
        client = self.node.create_client(srv_type, name)
        if not self.spin_until(client.service_is_ready, timeout):
            services = [n for n, _ in self.node.get_service_names_and_types()]
            raise CommandError(f"service {name} is not available (waited {timeout:g} s)"
                               + _did_you_mean(name, services))
        future = client.call_async(request)
        if not self.spin_until(future.done, timeout):
            raise CommandError(f"service {name} did not answer within {timeout:g} s")
        return future.result()

    def topic_type(self, topic: str, timeout: float) -> str:
        found: dict = {}

        def seen():
            found.update(dict(self.node.get_topic_names_and_types()))
            return topic in found
        if not self.spin_until(seen, timeout):
            known = [name for name, _ in self.settle(self.node.get_topic_names_and_types, 0.0)]
            raise CommandError(f"unknown topic {topic} (not on the graph after {timeout:g} s)"
                               + _did_you_mean(topic, known))
        return found[topic][0]

    def settle(self, getter, timeout: float, extra: float = 5.0):
        """Spin ``timeout`` s of discovery, then up to ``extra`` s more until another node is on the graph and
        ``getter()`` stops changing for 0.3 s; returns its last value (without this probe's own entries).

        Another *node*, not merely another entry: every participant has ``/rosout`` and
        ``/parameter_events``, so a list holding only those says nothing was discovered yet (seen: a
        simulator publishing for seconds, listed after 2 s of discovery as an empty graph)."""
        own = f"/{self.node.get_name()}/"

        def seen():
            return sorted(x for x in getter() if not str(x[0] if isinstance(x, tuple) else x).startswith(own))

        def others() -> bool:
            return any(name != self.node.get_name() for name in self.node.get_node_names())
        self.spin_until(lambda: False, timeout)
        deadline, last, since = time.monotonic() + extra, seen(), time.monotonic()
        while time.monotonic() < deadline and (not last or not others() or time.monotonic() - since < 0.3):
            self.executor.spin_once(timeout_sec=0.05)
            now = seen()
            if now != last:
                last, since = now, time.monotonic()
        return last

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()


def _fail(exc) -> int:
    print(f"seapup: error: {exc}", file=sys.stderr)
    return 1


def _verb_parser(name: str, description: str):
    """The parser of ``./seapup NAME`` and its verbs' subparsers."""
    parser = argparse.ArgumentParser(prog=f"./seapup {name}", description=description)
    return parser, parser.add_subparsers(dest="verb", required=True)


def _list_and_request(sub, verb: str, target: str, type_help: str):
    """The ``list [-t]`` verb and a request verb (``TARGET TYPE ['YAML'] [--timeout]``); the latter's parser."""
    p = sub.add_parser("list")
    p.add_argument("-t", "--show-types", action="store_true")
    p.add_argument("--timeout", type=float, default=1.0, help="seconds of discovery first")
    p = sub.add_parser(verb)
    p.add_argument(target)
    p.add_argument("type", help=type_help)
    p.add_argument("values", nargs="?", default="", help="YAML mapping of the fields")
    p.add_argument("--timeout", type=float, default=10.0, help="wait this long for the server and its answer")
    return p


def _typed_request(args, part: str, kind: str):
    """(interface class, its ``part`` filled from ``args.values``); ``part`` "" means the class itself."""
    from seapup_common.ros.introspection import fill, interface_class
    cls = interface_class(args.type)
    if not hasattr(getattr(cls, part, None) if part else cls, "get_fields_and_field_types"):
        raise CommandError(f"{args.type} is not {kind}")
    return cls, fill((getattr(cls, part) if part else cls)(), yaml.safe_load(args.values) if args.values else {})


def _listed(entries, show_types: bool, key: str) -> dict:
    """Print ``name [types]`` lines as ros2cli does; the JSON result."""
    for name, types in entries:
        print(f"{name} [{', '.join(types)}]" if show_types else name)
    return {key: [{"name": n, "types": list(t)} for n, t in entries]}


def _json_options(parser: argparse.ArgumentParser) -> None:
    """``--json [FILE]`` on every verb (the ./seapup convention)."""
    for sub in parser._subparsers._group_actions[0].choices.values():
        add_json_argument(sub)
    parser.epilog = ("Every verb takes --json [FILE] (its result as JSON; to stdout without FILE, the text then "
                     "goes to stderr) and --help.")


def _run(fn, args) -> int:
    """Run a verb on a probe node; its ``args.result`` goes out as JSON with ``--json``."""
    import contextlib
    from seapup_common.ros.introspection import InterfaceError
    probe = None
    args.result = {}
    human = text_stream(args)
    try:
        with contextlib.redirect_stdout(human):
            probe = Probe()
            code = fn(probe, args)
            emit_json(args, args.result)
        return code
    except (CommandError, InterfaceError, yaml.YAMLError) as exc:
        return _fail(str(exc).splitlines()[0])
    finally:  # Ctrl-C goes on to ./seapup's one line and exit 130, after the probe is closed
        if probe is not None:
            probe.close()


def _qos_for(probe: Probe, topic: str):
    """Reliable unless a publisher is best effort; transient local only if every publisher is."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    infos = probe.node.get_publishers_info_by_topic(topic)
    best_effort = any(i.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for i in infos)
    latched = bool(infos) and all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
    return QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


# -- topic ------------------------------------------------------------------------------
def _topic_list(probe, args):
    args.result = _listed(probe.settle(probe.node.get_topic_names_and_types, args.timeout), args.show_types,
                          "topics")
    return 0


def _topic_info(probe, args):
    type_ = probe.topic_type(args.topic, args.timeout)

    def named():  # endpoints are discovered before the names of their nodes
        infos = (probe.node.get_publishers_info_by_topic(args.topic)
                 + probe.node.get_subscriptions_info_by_topic(args.topic))
        return all(i.node_name != "_NODE_NAME_UNKNOWN_" for i in infos)
    probe.spin_until(named, args.timeout)
    pubs = probe.node.get_publishers_info_by_topic(args.topic)
    subs = [s for s in probe.node.get_subscriptions_info_by_topic(args.topic)
            if s.node_name != probe.node.get_name()]
    print(f"Type: {type_}\nPublisher count: {len(pubs)}")
    if args.verbose:
        for info in pubs:
            _print_endpoint(info)
    print(f"Subscription count: {len(subs)}")
    if args.verbose:
        for info in subs:
            _print_endpoint(info)
    args.result = {"type": type_, **{key: [{"node": _full_name(i.node_name, i.node_namespace),
                                            "reliability": i.qos_profile.reliability.name.lower(),
                                            "durability": i.qos_profile.durability.name.lower(),
                                            "depth": i.qos_profile.depth} for i in infos]
                                     for key, infos in (("publishers", pubs), ("subscriptions", subs))}}
    return 0


def _print_endpoint(info):
    q = info.qos_profile
    print(f"\nNode name: {info.node_name}\nNode namespace: {info.node_namespace}\nTopic type: {info.topic_type}\n"
          f"Endpoint type: {info.endpoint_type.name}\nQoS profile:\n  Reliability: {q.reliability.name}\n"
          f"  History (Depth): {q.history.name} ({q.depth})\n  Durability: {q.durability.name}")


def _topic_echo(probe, args):
    from seapup_common.ros.introspection import field_value, interface_class, to_data, to_yaml
    type_ = args.type or probe.topic_type(args.topic, args.timeout)
    cls = interface_class(type_)
    got = []
    args.result = {"topic": args.topic, "type": type_, "messages": got}

    def on_message(msg):
        value = field_value(msg, args.field) if args.field else to_data(msg)
        got.append(value)
        if args.csv:
            print(",".join(str(v) for v in _flatten(value)))
        else:
            print(to_yaml(value) if isinstance(value, dict) else _plain(value))
            print("---")
        sys.stdout.flush()
    probe.node.create_subscription(cls, args.topic, on_message, _qos_for(probe, args.topic))
    wanted = 1 if args.once else args.count
    deadline = None if (args.duration is None) else time.monotonic() + args.duration
    first = time.monotonic() + args.timeout
    while not (wanted and len(got) >= wanted):
        if deadline is not None and time.monotonic() > deadline:
            break
        if not got and time.monotonic() > first and (args.once or args.count):
            raise CommandError(f"no message on {args.topic} within {args.timeout:g} s")
        probe.executor.spin_once(timeout_sec=0.05)
    return 0


def _plain(value) -> str:
    from seapup_common.ros.introspection import to_yaml
    if isinstance(value, list):
        return "\n".join(f"- {v}" for v in value) if value else "[]"
    return to_yaml(value)


def _flatten(value):
    if isinstance(value, dict):
        for v in value.values():
            yield from _flatten(v)
    elif isinstance(value, list):
        for v in value:
            yield from _flatten(v)
    else:
        yield value


def _topic_pub(probe, args):
    from seapup_common.ros.introspection import to_yaml
    cls, msg = _typed_request(args, "", "a message type")
    publisher = probe.node.create_publisher(cls, args.topic, 10)
    print(f"publisher: beginning loop\npublishing #1: {type(msg).__name__}(...)")
    if args.once or args.times:
        probe.spin_until(lambda: publisher.get_subscription_count() > 0, args.timeout)
        if publisher.get_subscription_count() == 0:
            raise CommandError(f"no subscriber on {args.topic} within {args.timeout:g} s")
    times = 1 if args.once else args.times
    period = 1.0 / args.rate
    sent = 0
    next_t = time.monotonic()
    while times == 0 or sent < times:
        publisher.publish(msg)
        sent += 1
        if args.verbose:
            print(to_yaml(msg) + "\n---")
        next_t += period
        probe.spin_until(lambda: time.monotonic() >= next_t, max(0.0, next_t - time.monotonic()) + 0.01)
    probe.spin_until(lambda: False, 0.3)  # let a reliable message be acknowledged
    args.result = {"topic": args.topic, "type": args.type, "published": sent}
    return 0


def _topic_hz(probe, args):
    from seapup_common.ros.introspection import interface_class
    cls = interface_class(probe.topic_type(args.topic, args.timeout))
    stamps: list[float] = []
    probe.node.create_subscription(cls, args.topic, lambda _m: stamps.append(time.monotonic()),
                                   _qos_for(probe, args.topic))
    end = time.monotonic() + args.duration
    while time.monotonic() < end:
        probe.executor.spin_once(timeout_sec=0.05)
    window = stamps[-(args.window + 1):]
    if len(window) < 2:
        raise CommandError(f"fewer than two messages on {args.topic} in {args.duration:g} s")
    import numpy as np
    gaps = np.diff(window)
    rate = 1.0 / gaps.mean()
    print(f"average rate: {rate:.3f}\n\tmin: {gaps.min():.3f}s max: {gaps.max():.3f}s std dev: {gaps.std():.5f}s "
          f"window: {len(window)}")
    args.result = {"topic": args.topic, "rate_hz": float(rate), "min_s": float(gaps.min()), "max_s": float(gaps.max()),
                   "std_s": float(gaps.std()), "window": len(window)}
    return 0


def topic_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup topic`` (its usage line in ``./seapup help`` is generated from it)."""
    parser, sub = _verb_parser("topic", "topics, as 'ros2 topic'")
    p = sub.add_parser("list", help="topics on the graph")
    p.add_argument("-t", "--show-types", action="store_true")
    p.add_argument("--timeout", type=float, default=1.0, help="seconds of discovery first")
    p.set_defaults(fn=_topic_list)
    p = sub.add_parser("info", help="type, publishers and subscriptions")
    p.add_argument("topic")
    p.add_argument("-v", "--verbose", action="store_true")
    p.add_argument("--timeout", type=float, default=5.0)
    p.set_defaults(fn=_topic_info)
    p = sub.add_parser("echo", help="print messages as YAML")
    p.add_argument("topic")
    p.add_argument("type", nargs="?", help="pkg/msg/Type (default: from the graph)")
    p.add_argument("--once", action="store_true")
    p.add_argument("--count", type=int, default=0, help="stop after N messages")
    p.add_argument("--duration", type=float, help="stop after S seconds")
    p.add_argument("--field", help="print only this field (a.b.c)")
    p.add_argument("--csv", action="store_true", help="one comma-separated line per message")
    p.add_argument("--timeout", type=float, default=10.0)
    p.set_defaults(fn=_topic_echo)
    p = sub.add_parser("pub", help="publish a message given as YAML")
    p.add_argument("topic")
    p.add_argument("type")
    p.add_argument("values", nargs="?", default="", help="YAML mapping of the fields")
    p.add_argument("-1", "--once", action="store_true", help="publish once (after a subscriber matched)")
    p.add_argument("-t", "--times", type=int, default=0, help="publish N times (0: until Ctrl-C)")
    p.add_argument("-r", "--rate", type=float, default=1.0, help="Hz")
    p.add_argument("-v", "--verbose", action="store_true")
    p.add_argument("--timeout", type=float, default=10.0, help="wait this long for a subscriber (--once/--times)")
    p.set_defaults(fn=_topic_pub)
    p = sub.add_parser("hz", help="rate of a topic over a window")
    p.add_argument("topic")
    p.add_argument("--window", "-w", type=int, default=10000)
    p.add_argument("--duration", type=float, default=5.0, help="seconds to listen")
    p.add_argument("--timeout", type=float, default=10.0)
    p.set_defaults(fn=_topic_hz)
    _json_options(parser)
    return parser


def topic(argv: list[str]) -> int:
    """``./seapup topic list|info|echo|pub|hz``, as ros2cli spells them."""
    parser = topic_parser()
    args = parser.parse_args(argv)
    if args.verb == "pub" and not (args.rate > 0 and math.isfinite(args.rate)):
        return _fail(f"--rate must be > 0, got {args.rate}")
    return _run(args.fn, args)


# -- node -----------------------------------------------------------------------------------
def _full_name(name, namespace):
    return (namespace.rstrip("/") + "/" + name) if namespace != "/" else "/" + name


def _nodes(probe, timeout):
    me = probe.node.get_name()
    found = probe.settle(lambda: [(_full_name(n, ns),) for n, ns in probe.node.get_node_names_and_namespaces()
                                  if n != me], timeout)
    return [f[0] for f in found]


def _split(full: str):
    full = full if full.startswith("/") else "/" + full
    namespace, _, name = full.rpartition("/")
    return name, namespace or "/"


def node_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup node`` (its usage line in ``./seapup help`` is generated from it)."""
    parser, sub = _verb_parser("node", "nodes, as 'ros2 node'")
    p = sub.add_parser("list")
    p.add_argument("--timeout", type=float, default=1.0)
    p = sub.add_parser("info")
    p.add_argument("node")
    p.add_argument("--timeout", type=float, default=2.0)
    _json_options(parser)
    return parser


def node(argv: list[str]) -> int:
    """``./seapup node list|info``."""
    parser = node_parser()
    args = parser.parse_args(argv)

    def run(probe, args):
        nodes = _nodes(probe, args.timeout)
        if args.verb == "list":
            print("\n".join(nodes))
            args.result = {"nodes": nodes}
            return 0
        full = args.node if args.node.startswith("/") else "/" + args.node
        if full not in nodes:
            raise CommandError(f"unknown node {full} (on the graph: {', '.join(nodes) or 'none'})")
        name, ns = _split(full)
        n = probe.node
        sections = (("Subscribers", n.get_subscriber_names_and_types_by_node(name, ns)),
                    ("Publishers", n.get_publisher_names_and_types_by_node(name, ns)),
                    ("Service Servers", n.get_service_names_and_types_by_node(name, ns)))
        print(full)
        args.result = {"node": full}
        for title, items in sections:
            print(f"  {title}:")
            args.result[title.lower().replace(" ", "_")] = {n: list(t) for n, t in sorted(items)}
            for topic_name, types in sorted(items):
                print(f"    {topic_name}: {', '.join(types)}")
        return 0
    return _run(run, args)


# -- param ------------------------------------------------------------------------------------
_PARAM_FIELDS = {1: "bool_value", 2: "integer_value", 3: "double_value", 4: "string_value",
                 5: "byte_array_value", 6: "bool_array_value", 7: "integer_array_value",
                 8: "double_array_value", 9: "string_array_value"}
_PARAM_NAMES = {1: "Boolean", 2: "Integer", 3: "Double", 4: "String", 5: "Byte array", 6: "Boolean array",
                7: "Integer array", 8: "Double array", 9: "String array"}


def _param_value(text: str):
    """A parameter value from its YAML text (as ``ros2 param set`` reads it)."""
    from rcl_interfaces.msg import ParameterType, ParameterValue
    value = yaml.safe_load(text)
    v = ParameterValue()
    if isinstance(value, bool):
        v.type, v.bool_value = ParameterType.PARAMETER_BOOL, value
    elif isinstance(value, int):
        v.type, v.integer_value = ParameterType.PARAMETER_INTEGER, value
    elif isinstance(value, float):
        v.type, v.double_value = ParameterType.PARAMETER_DOUBLE, value
    elif isinstance(value, str):
        v.type, v.string_value = ParameterType.PARAMETER_STRING, value
    elif isinstance(value, list) and value and all(isinstance(x, bool) for x in value):
        v.type, v.bool_array_value = ParameterType.PARAMETER_BOOL_ARRAY, value
    elif isinstance(value, list) and value and all(isinstance(x, int) and not isinstance(x, bool) for x in value):
        v.type, v.integer_array_value = ParameterType.PARAMETER_INTEGER_ARRAY, value
    elif isinstance(value, list) and value and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                   for x in value):
        v.type, v.double_array_value = ParameterType.PARAMETER_DOUBLE_ARRAY, [float(x) for x in value]
    elif isinstance(value, list) and all(isinstance(x, str) for x in value):
        v.type, v.string_array_value = ParameterType.PARAMETER_STRING_ARRAY, value
    else:
        raise CommandError(f"cannot make a parameter value of {text!r}")
    return v


def _plain_value(v):
    if v is None:
        return None
    field = _PARAM_FIELDS.get(v.type)
    if field is None:
        return None
    value = getattr(v, field)
    return list(value) if not isinstance(value, (bool, int, float, str)) else value


def param_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup param`` (its usage line in ``./seapup help`` is generated from it)."""
    parser, sub = _verb_parser("param", "parameters, as 'ros2 param'")
    for verb in ("list", "dump"):
        p = sub.add_parser(verb)
        p.add_argument("node")
    p = sub.add_parser("get")
    p.add_argument("node")
    p.add_argument("name")
    p = sub.add_parser("set")
    p.add_argument("node")
    p.add_argument("name")
    p.add_argument("value")
    for p in sub.choices.values():
        p.add_argument("--timeout", type=float, default=5.0)
    _json_options(parser)
    return parser


def param(argv: list[str]) -> int:
    """``./seapup param list|get|set|dump NODE ...``."""
    parser = param_parser()
    args = parser.parse_args(argv)

    def run(probe, args):
        from rcl_interfaces.msg import Parameter
        from rcl_interfaces.srv import GetParameters, ListParameters, SetParameters
        full = args.node if args.node.startswith("/") else "/" + args.node

        def names():
            return sorted(probe.call(ListParameters, f"{full}/list_parameters", ListParameters.Request(),
                                     args.timeout).result.names)

        def values(keys):
            def get(names):
                return list(probe.call(GetParameters, f"{full}/get_parameters", GetParameters.Request(names=names),
                                       args.timeout).values)
            got = get(keys)
            if len(got) == len(keys):
                return got
            # rclpy answers nothing at all when one value cannot be read (e.g. an empty array
            # parameter): ask one by one, None for those
            return [(get([k]) or [None])[0] for k in keys]
        if args.verb == "list":
            listed = names()
            print(f"{full}:\n" + "\n".join(f"  {n}" for n in listed))
            args.result = {"node": full, "names": listed}
        elif args.verb == "get":
            (v,) = values([args.name])
            if v is None or v.type == 0:
                raise CommandError(f"parameter {args.name} is not set on {full}")
            print(f"{_PARAM_NAMES[v.type]} value is: {_plain_value(v)}")
            args.result = {"node": full, "name": args.name, "type": _PARAM_NAMES[v.type].lower(),
                           "value": _plain_value(v)}
        elif args.verb == "set":
            request = SetParameters.Request(parameters=[Parameter(name=args.name, value=_param_value(args.value))])
            (result,) = probe.call(SetParameters, f"{full}/set_parameters", request, args.timeout).results
            if not result.successful:
                raise CommandError(f"setting parameter failed: {result.reason or 'refused'}")
            print("Set parameter successful")
            args.result = {"node": full, "name": args.name, "value": _plain_value(request.parameters[0].value),
                           "successful": True}
        else:
            keys = names()
            tree: dict = {}
            for key, v in zip(keys, values(keys)):
                node = tree
                *head, last = key.split(".")
                for part in head:
                    node = node.setdefault(part, {})
                node[last] = _plain_value(v)
            args.result = {full: {"ros__parameters": tree}}
            print(yaml.safe_dump(args.result, sort_keys=True), end="")
        return 0
    return _run(run, args)


# -- service ----------------------------------------------------------------------------------
def service_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup service`` (its usage line in ``./seapup help`` is generated from it)."""
    parser, sub = _verb_parser("service", "services, as 'ros2 service'")
    _list_and_request(sub, "call", "service", "pkg/srv/Type")
    _json_options(parser)
    return parser


def service(argv: list[str]) -> int:
    """``./seapup service list|call``."""
    parser = service_parser()
    args = parser.parse_args(argv)

    def run(probe, args):
        from seapup_common.ros.introspection import to_data, to_yaml, type_name
        if args.verb == "list":
            args.result = _listed(probe.settle(probe.node.get_service_names_and_types, args.timeout),
                                  args.show_types, "services")
            return 0
        srv, request = _typed_request(args, "Request", "a service type")
        print(f"requester: making request: {type_name(srv.Request)}(...)")
        response = probe.call(srv, args.service, request, args.timeout)
        print("\nresponse:\n" + to_yaml(response) + "\n")
        args.result = {"service": args.service, "type": args.type, "response": to_data(response)}
        return 0
    return _run(run, args)


# -- action ------------------------------------------------------------------------------------
_STATUS = {1: "ACCEPTED", 2: "EXECUTING", 3: "CANCELING", 4: "SUCCEEDED", 5: "CANCELED", 6: "ABORTED"}


def action_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup action`` (its usage line in ``./seapup help`` is generated from it)."""
    parser, sub = _verb_parser("action", "actions, as 'ros2 action'")
    p = _list_and_request(sub, "send_goal", "action_name", "pkg/action/Type")
    p.add_argument("-f", "--feedback", action="store_true", help="print the feedback")
    p.add_argument("--result-timeout", type=float, default=3600.0, help="wall seconds to wait for the result")
    _json_options(parser)
    return parser


def action(argv: list[str]) -> int:
    """``./seapup action list|send_goal``."""
    parser = action_parser()
    args = parser.parse_args(argv)

    def run(probe, args):
        from rclpy.action import ActionClient, get_action_names_and_types

        from seapup_common.ros.graph import GoalNotAnswered, send_goal
        from seapup_common.ros.introspection import to_data, to_yaml
        if args.verb == "list":
            args.result = _listed(probe.settle(lambda: get_action_names_and_types(probe.node), args.timeout),
                                  args.show_types, "actions")
            return 0
        kind, goal = _typed_request(args, "Goal", "an action type")
        feedback = []

        def on_feedback(message):
            feedback.append(to_data(message.feedback))
            if args.feedback:
                print("Feedback:\n" + to_yaml(message.feedback) + "\n")
                sys.stdout.flush()
        client = ActionClient(probe.node, kind, args.action_name)
        print("Waiting for an action server to become available...")
        print("Sending goal:\n" + to_yaml(goal) + "\n")
        try:
            handle = send_goal(probe.executor, client, goal, on_feedback, ready_timeout=args.timeout,
                               response_timeout=min(5.0, args.timeout))
        except GoalNotAnswered as exc:
            raise CommandError(str(exc)) from None
        if not handle.accepted:
            print("Goal was rejected.")
            args.result = {"action": args.action_name, "accepted": False}
            return 1
        print(f"Goal accepted with ID: {bytes(handle.goal_id.uuid).hex()}\n")
        future = handle.get_result_async()
        try:
            if not probe.spin_until(future.done, args.result_timeout):
                raise CommandError(f"no result within {args.result_timeout:g} s")
        except KeyboardInterrupt:  # Ctrl-C cancels the goal, as ros2cli does
            cancel = handle.cancel_goal_async()
            probe.spin_until(cancel.done, 5.0)
            print("Goal canceled.")
            raise
        answer = future.result()
        # feedback sent before the result travels on its own topic and may arrive just after it (on a loaded
        # machine the last ones did); rclpy forgets a goal's feedback callback once its result is in (a done
        # callback of the result, which may run a spin later), so it is handed back at every turn of this wait
        callbacks, goal_key = client._feedback_callbacks, bytes(handle.goal_id.uuid)
        probe.spin_until(lambda: callbacks.setdefault(goal_key, on_feedback) is None, 0.3)
        status = _STATUS.get(answer.status, str(answer.status))
        print("Result:\n" + to_yaml(answer.result) + f"\n\nGoal finished with status: {status}")
        args.result = {"action": args.action_name, "accepted": True, "status": status.lower(),
                       "result": to_data(answer.result), "feedback": feedback}
        return 0 if status == "SUCCEEDED" else 1
    return _run(run, args)


# -- interface ----------------------------------------------------------------------------------
def interface_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup interface`` (its usage line in ``./seapup help`` is generated from it)."""
    parser, sub = _verb_parser("interface", "interfaces, as 'ros2 interface'")
    p = sub.add_parser("show")
    p.add_argument("type")
    _json_options(parser)
    return parser


def interface(argv: list[str]) -> int:
    """``./seapup interface show TYPE``."""
    parser = interface_parser()
    args = parser.parse_args(argv)
    from seapup_common.ros.introspection import InterfaceError, definition, interface_class
    try:
        text = definition(interface_class(args.type))
    except InterfaceError as exc:
        return _fail(exc)
    print(text, file=text_stream(args))
    emit_json(args, {"type": args.type, "definition": text.split("\n")})
    return 0
