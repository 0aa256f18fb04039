"""Shared node entry, parameter declaration, QoS and logging for seapup nodes (rclpy).

Gives every node the same life cycle: ``rclpy.init`` with the process's
arguments, a SingleThreadedExecutor (the events executor deadlocks with these
wheels), a clean exit on SIGINT/SIGTERM, a non-zero exit code if the node
could not be constructed (e.g. a rejected parameter), and the log lines of
the pure cores (Python ``logging`` under ``seapup_*``) on the node's ROS
logger, so ``rosout`` and the console show them.
"""
from __future__ import annotations

import logging
import math
import signal
import sys
import time
from collections.abc import Mapping
from pathlib import Path

import rclpy
from ament_index_python.packages import get_package_share_directory
from rcl_interfaces.msg import ParameterType
from rclpy.duration import Duration
from rclpy.exceptions import ParameterUninitializedException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, QoSCompatibility, QoSProfile, ReliabilityPolicy, qos_check_compatible
from rclpy.signals import SignalHandlerOptions

from seapup_common import CORE_LOGGERS  # noqa: F401 - the cores' loggers, routed to the node's (re-exported)
from seapup_common.parameters import load_node_parameters

__all__ = ["run_node", "declare_from_package_file", "declare_mapping", "flatten", "RosLogHandler",
           "refuse_invalid_transitions", "stop_requested", "QUIET_PUBLISHER", "QUIET_SUBSCRIPTION",
           "QosWatch", "RELIABLE_QOS", "COMMAND_QOS", "TF_QOS", "TF_STATIC_QOS", "SERVICE_QOS", "CORE_LOGGERS"]

#: Reliable, keep-last 10: the default for seapup topics.
RELIABLE_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
#: Per-sample streams are published with a deep history: a reliable writer keeps what a reader has not yet
#: acknowledged only up to its depth, so a reader that falls behind for a moment (a recorder on a loaded
#: machine, while lockstep races on) caught up with the samples at depth 10 overwritten -- a bag with holes.
STREAM_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
#: ``/tf`` and ``/tf_static`` as tf2's broadcasters offer them (reliable, depth 100; the static one latched, depth 1,
#: every fixed transform in its one message), so rviz, Foxglove and tf2 listeners match them.
TF_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
TF_STATIC_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Commands queue deeper: every one, good or bad, must be seen and counted.
COMMAND_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
#: Services queue deep enough for bursts: 1000 concurrent requests are each
#: answered (rclpy's default keeps 10 and drops the rest silently).
SERVICE_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
#: A publisher or subscription without rclpy's default event handlers. Those (one per endpoint: "incompatible
#: QoS") are waited on at every executor iteration: with the simulator's thirteen publishers they doubled the cost
#: of each ``spin_once`` (about 500 against 220 us measured here), several times per lockstep sample. A node that
#: uses these checks the same thing at its diagnostics period instead (:class:`QosWatch`).
QUIET_PUBLISHER = PublisherEventCallbacks(use_default_callbacks=False)
QUIET_SUBSCRIPTION = SubscriptionEventCallbacks(use_default_callbacks=False)


class RosLogHandler(logging.Handler):
    """Forwards Python ``logging`` records to an rclpy logger (same severity)."""

    def __init__(self, ros_logger):
        super().__init__()
        self.ros_logger = ros_logger

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = f"[{record.name}] {record.getMessage()}"
            if record.levelno >= logging.ERROR:
                self.ros_logger.error(text)
            elif record.levelno >= logging.WARNING:
                self.ros_logger.warn(text)
            elif record.levelno >= logging.INFO:
                self.ros_logger.info(text)
            else:
                self.ros_logger.debug(text)
        except Exception:  # noqa: BLE001 - logging must never raise into the caller
            self.handleError(record)


def _route_core_logs(node) -> list[tuple[logging.Logger, logging.Handler]]:
    handler = RosLogHandler(node.get_logger())
    installed = []
    for name in CORE_LOGGERS:
        logger = logging.getLogger(name)
        logger.addHandler(handler)
        logger.setLevel(logging.DEBUG)
        logger.propagate = False
        installed.append((logger, handler))
    return installed


def flatten(mapping: Mapping, prefix: str = "") -> dict:
    """Nested mappings to ROS dotted parameter names: ``{"a": {"b": 1}}`` -> ``{"a.b": 1}``."""
    out = {}
    for key, value in mapping.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, Mapping):
            out.update(flatten(value, name))
        else:
            out[name] = value
    return out


def _declare(node, name, value, descriptor):
    if isinstance(value, (list, tuple)) and not value:  # an empty list has no type of its own
        strings = descriptor is not None and descriptor.type == ParameterType.PARAMETER_STRING_ARRAY
        value = Parameter.Type.STRING_ARRAY if strings else Parameter.Type.DOUBLE_ARRAY
    if isinstance(value, (list, tuple)) and value and all(isinstance(v, (list, tuple)) for v in value):
        value = [float(x) for row in value for x in row]  # ROS has no nested arrays: flatten rows
    if descriptor is not None:
        node.declare_parameter(name, value, descriptor)
    else:
        node.declare_parameter(name, value)
    try:
        got = node.get_parameter(name).value
    except ParameterUninitializedException:
        return []
    return list(got) if isinstance(got, (list, tuple)) or hasattr(got, "tolist") else got


def declare_mapping(node, prefix: str, mapping: Mapping, descriptors: dict | None = None) -> dict:
    """Declare every leaf of a nested mapping as ``<prefix>.<path>`` and return the
    values (after overrides) as a nested dict of the same shape.

    ``descriptors`` maps dotted names (without the prefix) to
    ``ParameterDescriptor`` objects. Lists of rows are declared flattened.
    """
    descriptors = descriptors or {}
    out: dict = {}
    for key, value in mapping.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, Mapping):
            sub = {k[len(key) + 1:]: d for k, d in descriptors.items() if k.startswith(f"{key}.")}
            out[key] = declare_mapping(node, name, value, sub)
        else:
            out[key] = _declare(node, name, value, descriptors.get(key))
    return out


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _numeric(value) -> bool:
    """A number or a (non-empty) list of numbers."""
    if isinstance(value, (list, tuple)):
        return bool(value) and all(_numeric(v) for v in value)
    return _is_number(value)


def _range_of(descriptor) -> tuple | None:
    if descriptor is None:
        return None
    for r in list(descriptor.floating_point_range) + list(descriptor.integer_range):
        return (r.from_value, r.to_value)
    return None


class ParameterGuard:
    """The allowed range of every numeric parameter of a node, checked on every change.

    rclpy checks a scalar's declared range on ``param set`` but lets NaN through
    (every comparison with NaN is false) and never checks arrays; a value out of range
    or not finite must be refused before the node uses it (``reference_wait:
    .nan`` once killed a controller at its next sample). Registered by
    :func:`declare_from_package_file` as an on-set-parameters callback; the
    declared values are checked too (a bad ``-p`` stops the start, naming it).
    """

    def __init__(self, ranges: dict):
        self.ranges = dict(ranges)

    def problem(self, name: str, value) -> str:
        """Why ``value`` cannot be parameter ``name``, or ""."""
        bounds = self.ranges.get(name)
        if bounds is None:
            return ""
        lo, hi = bounds
        values = value.tolist() if hasattr(value, "tolist") else value
        for v in values if isinstance(values, (list, tuple)) else [values]:
            if _is_number(v) and not (math.isfinite(v) and lo <= v <= hi):
                return f"{name} = {value!r} refused: it must be finite and within [{lo:g}, {hi:g}]"
        return ""

    def __call__(self, parameters):
        from rcl_interfaces.msg import SetParametersResult
        for parameter in parameters:
            reason = self.problem(parameter.name, parameter.value)
            if reason:
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)


def declare_from_package_file(node, package: str, file_name: str, descriptors: dict | None = None,
                              defaults: dict | None = None, section: str | None = None,
                              ranges: dict | None = None) -> dict:
    """Declare every parameter of ``share/<package>/config/<file_name>`` for ``node``;
    return their values (after overrides) by name.

    Defaults come from the package's YAML (nested mappings become dotted
    names); ``defaults`` adds parameters whose default lives in one shared place
    in code-side data (e.g. the blade-pitch limit of ``seapup_common``).
    Overrides given on the command line (``-p``, ``--params-file``) win as
    usual. ``descriptors`` maps names to ``ParameterDescriptor`` objects.
    ``section`` is the node's name in the file (default: its name now; pass the
    executable's own name so a remapped ``__node:=other`` still finds its defaults).

    Every numeric parameter (and numeric array) has an allowed range: from its
    descriptor's range or from ``ranges`` (name: (lo, hi), for each element of
    an array); a number without one is a programming error (``ValueError`` at
    start). A :class:`ParameterGuard` refuses any value outside its range or
    not finite, at declaration (``ValueError`` naming it) and on every change.
    """
    path = Path(get_package_share_directory(package)) / "config" / file_name
    values = {**(defaults or {}), **flatten(load_node_parameters(path, section or node.get_name()))}
    descriptors = dict(descriptors or {})
    ranges = dict(ranges or {})
    for name, bounds in ranges.items():
        if name not in values:
            raise ValueError(f"{file_name}: a range for {name!r}, which the file does not have")
        if name not in descriptors and _is_number(values[name]):
            descriptors[name] = _ranged_descriptor(values[name], bounds)
    for name, descriptor in descriptors.items():
        if _range_of(descriptor) is not None:
            ranges.setdefault(name, _range_of(descriptor))
    unranged = sorted(name for name, value in values.items() if _numeric(value) and name not in ranges)
    if unranged:
        raise ValueError(f"{file_name}: numeric parameters without an allowed range: {', '.join(unranged)}")
    guard = ParameterGuard(ranges)
    declared = {name: _declare(node, name, value, descriptors.get(name)) for name, value in values.items()}
    for name, value in declared.items():
        reason = guard.problem(name, value)
        if reason:
            raise ValueError(reason)
    node.add_on_set_parameters_callback(guard)
    return declared


def _ranged_descriptor(default, bounds):
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
    lo, hi = bounds
    if isinstance(default, int):
        return ParameterDescriptor(integer_range=[IntegerRange(from_value=int(lo), to_value=int(hi), step=1)])
    return ParameterDescriptor(floating_point_range=[FloatingPointRange(from_value=float(lo), to_value=float(hi))])


def refuse_invalid_transitions(node) -> None:
    """Make ``~/change_state`` answer ``success: false`` to a transition the present state does not have.

    rclpy's LifecycleNode (Jazzy) lets the state machine's RCLError escape
    its service callback, so e.g. a second ``activate`` kills the node from
    inside the executor; rclcpp answers false. This wraps the service's
    callback to do the same (logged as a warning).
    """
    from lifecycle_msgs.srv import ChangeState
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

    service = node._service_change_state  # rclpy has no public hook for this service
    handle = service.callback

    def guarded(request, response):
        try:
            return handle(request, response)
        except _rclpy.RCLError as exc:
            state = node._state_machine.current_state[1]
            node.get_logger().warn(f"transition {request.transition.id} {request.transition.label!r} refused in "
                                   f"state {state!r}: {str(exc).splitlines()[0][:200]}")
            response = ChangeState.Response()
            response.success = False
            return response
    service.callback = guarded


def _drain(executor, node, budget: float = 1.5) -> None:
    """Run the callbacks already queued (e.g. a recorder's received messages) before stopping: until a
    short wait brings nothing new (a live graph keeps publishing; what arrives after the stop is not
    waited for) or ``budget`` seconds pass (a stopped process must end promptly: its parent may be gone)."""
    deadline = time.monotonic() + budget
    try:
        while time.monotonic() < deadline:
            before = getattr(node, "received", None)
            executor.spin_once(timeout_sec=0.01)
            if getattr(node, "received", None) == before:
                break
    except (KeyboardInterrupt, ExternalShutdownException):
        pass


def _await_acknowledgements(node) -> None:
    """Give reliable subscribers a few seconds (the budget below) to acknowledge what was published.

    A process that exits right after publishing (a controller stopped just after
    its last command) would otherwise take an unacknowledged message with it: a
    subscriber that lost the first transmission never gets the resend, while
    another (a recorder) did receive it. On a loaded machine a lockstep graph stopped at its end can be
    seconds of samples ahead of a recorder's acknowledgements (an identification bag lost its last 14
    samples with 0.5 s here); the wait ends as soon as every subscriber has acknowledged. The budget: the
    node's ``ack_budget`` if it sets one (the simulator, whose samples are what a bag records), else 0.5 s.
    """
    budget = float(getattr(node, "ack_budget", 0.5))
    deadline = time.monotonic() + budget
    step = Duration(nanoseconds=100_000_000)
    try:
        for publisher in list(node.publishers):
            if publisher.qos_profile.reliability != ReliabilityPolicy.RELIABLE or \
                    publisher.topic_name in ("/parameter_events", "/rosout"):   # rclpy's own: every node hears them
                continue
            # in short waits, and only while a subscriber is still there: one that is shutting down too (a
            # graph stopped all at once) never acknowledges, and waiting for it cost every stop the budget
            while time.monotonic() < deadline and publisher.get_subscription_count() > 0:
                if publisher.wait_for_all_acked(step):
                    break
    except (KeyboardInterrupt, ExternalShutdownException):
        pass


def destroy_actions(node) -> None:
    """Destroy the node's action servers and clients; call it before ``Node.destroy_node``.

    ``Node.destroy_node`` (rclpy Jazzy) destroys publishers, subscriptions, services, timers and guard
    conditions but not waitables. An action server left to the garbage collector is finalised there after
    its node's clock, and ``rcl_action_server_fini`` removes its goal-expiry timer's jump callback from that
    freed clock: a segmentation fault in whatever runs next (seen: 1 in 4 runs of the task controller's
    tests, gdb: ``rcl_clock_remove_jump_callback`` <- ``rcl_timer_fini`` <- ``rcl_action_server_fini``).
    """
    from rclpy.action import ActionClient, ActionServer

    for waitable in list(node.waitables):
        if isinstance(waitable, (ActionServer, ActionClient)):
            waitable.destroy()


def graph_time_ns(node, latest_stamp_ns: int | None) -> int:
    """The stamp for a message a node publishes on its own (a periodic status, not an answer to a sample):
    the graph's time as the node knows it -- its clock under ``use_sim_time``, else the newest stamp it
    received (a lockstep graph's time lives in its stamps), else 0 (unknown). Never the wall clock on a
    sim-time graph: ``/diagnostics`` once mixed the two."""
    if node.get_parameter("use_sim_time").value:
        return node.get_clock().now().nanoseconds
    return int(latest_stamp_ns) if latest_stamp_ns is not None else 0


#: Parameters a node may be given without declaring them itself (rclpy's own).
_IMPLICIT_PARAMETERS = ("use_sim_time", "start_type_description_service")


def refuse_unknown_overrides(node) -> None:
    """Raise ``ValueError`` for a parameter given to ``node`` (``-p``, ``--params-file``, a graph file)
    that it never declared: rclpy ignores such a value silently, so a misspelled
    ``real_time_facter:=2.0`` or ``environment.current.enabeld:=true`` would change nothing while
    the user believes it did. The message names each one and the nearest declared name."""
    from seapup_common.config import nearest

    declared = set(node._parameters)
    unknown = sorted(name for name in node._parameter_overrides
                     if name not in declared and name not in _IMPLICIT_PARAMETERS
                     and not name.startswith("qos_overrides."))
    if unknown:
        hints = []
        for name in unknown:
            near = nearest(name, declared)
            hints.append(f"{name!r}" + (f" (did you mean {near!r}?)" if near else ""))
        raise ValueError(f"unknown parameter{'s' if len(unknown) > 1 else ''} {', '.join(hints)}; "
                         f"'./seapup param list {node.get_fully_qualified_name()}' on a running node lists them")


class QosWatch:
    """The incompatible-QoS warnings of rclpy's default event handlers, checked when asked rather than waited on.

    :meth:`problems` compares each of the node's publishers with every matched
    subscription on its topic, and each subscription with every publisher
    (``qos_check_compatible``), and returns one line per pair that cannot
    communicate; a pair is logged as a warning the first time it is seen, like
    the default handler's "requesting incompatible QoS. No messages will be
    sent to it". Asked more often than every ``interval`` wall seconds, it
    answers what it found last (a node may ask at every sample).
    """

    def __init__(self, node, interval: float = 1.0):
        self.node = node
        self.interval = interval
        self._said: set = set()
        self._found: list[str] = []
        self._checked = -math.inf

    def problems(self) -> list[str]:
        if time.monotonic() - self._checked < self.interval:
            return list(self._found)
        self._checked = time.monotonic()
        node, found = self.node, []
        me = (node.get_namespace(), node.get_name())
        # both sides as the graph reports them: a requested profile leaves deadline and liveliness at
        # "default", which the check would read as a mismatch with what the middleware actually offers
        endpoints = [(topic, node.get_publishers_info_by_topic, node.get_subscriptions_info_by_topic, True)
                     for topic in {pub.topic_name for pub in node.publishers}]
        endpoints += [(topic, node.get_subscriptions_info_by_topic, node.get_publishers_info_by_topic, False)
                      for topic in {sub.topic_name for sub in node.subscriptions}]
        for topic, mine, others, publishing in endpoints:
            own = [info.qos_profile for info in mine(topic) if (info.node_namespace, info.node_name) == me]
            for qos in own[:1]:
                found += self._check(topic, qos, others(topic), publishing)
        self._found = found
        return list(found)

    def _check(self, topic: str, qos, others, publishing: bool) -> list[str]:
        found = []
        for info in others:
            pair = (qos, info.qos_profile) if publishing else (info.qos_profile, qos)
            compatibility, reason = qos_check_compatible(*pair)
            if compatibility != QoSCompatibility.ERROR:
                continue
            other = f"{info.node_namespace.rstrip('/')}/{info.node_name}"
            text = (f"{topic}: {'subscription' if publishing else 'publisher'} {other} has an incompatible "
                    f"QoS ({reason.strip().rstrip(';') or 'see ./seapup topic info -v'}): no messages pass")
            found.append(text)
            if text not in self._said:
                self._said.add(text)
                self.node.get_logger().warn(text)
        return found


#: The signals :func:`run_node` has been asked to stop by (empty while it runs on).
_STOP: list[int] = []
#: Seconds a node has to end once asked to stop, its parent alive (drain, acknowledgements, destruction) or
#: gone (nobody is left to hear it: no drain, no acknowledgements). Past them the process ends at once: a
#: C-level watchdog (:func:`faulthandler.dump_traceback_later`, no GIL needed) calls ``_exit``, so a node
#: hung where no Python handler runs (a futex in DDS) still ends, and never ignores a signal meanwhile.
STOP_BUDGET = 10.0
ORPHAN_STOP_BUDGET = 1.0
_WATCHDOG_SINK = []   # the file the watchdog's traceback goes to (/dev/null: never shown to a user)


def _arm_stop_watchdog(budget: float) -> None:
    import faulthandler
    import os
    if not _WATCHDOG_SINK:
        _WATCHDOG_SINK.append(open(os.devnull, "w"))  # noqa: SIM115 - held for the process's life
    faulthandler.dump_traceback_later(budget, exit=True, file=_WATCHDOG_SINK[0])


def _orphaned(parent: int) -> bool:
    """True once the process that started this one is gone (the kernel gave us another parent)."""
    import os
    return os.getppid() != parent


def _request_stop(signum: int, parent: int) -> None:
    """The stop signals' handler: ask the loop to stop and arm the watchdog (again, shorter, when orphaned)."""
    first = not _STOP
    _STOP.append(signum)
    if first or _orphaned(parent):
        _arm_stop_watchdog(ORPHAN_STOP_BUDGET if _orphaned(parent) else STOP_BUDGET)


def stop_requested() -> bool:
    """True once :func:`run_node` was asked to stop (SIGINT, SIGTERM, SIGHUP): a callback that waits
    (a blocking service call) gives up, so the node exits promptly."""
    return bool(_STOP)


def run_node(make_node, args=None) -> int:
    """Construct a node with ``make_node()`` and spin it until SIGINT or SIGTERM.

    Both signals only *ask* the node to stop (a flag checked between two
    executor iterations, at least every 0.1 s, also when the node has nothing
    to do): an exception thrown from a signal handler into whatever runs at
    that moment could be swallowed by it -- a ``KeyboardInterrupt`` raised
    inside a message deserialisation comes back from pybind11 as an ordinary
    error, which the simulator counts as a malformed command and keeps
    running (seen: 1 SIGTERM in 30 with queued commands at full rate). Then
    the executor stops, the node (its timers, callbacks and publishers) is
    destroyed, and only then is the context shut down: no callback ever runs
    on a dead context, and the exit code is 0. Before the node goes, reliable
    publishers wait (briefly) until their subscribers have acknowledged every
    message, so the last command of a stopped controller is not lost for one
    subscriber while another has it. A callback may still end the node on
    purpose by raising ``KeyboardInterrupt`` (the recorder's ``max_duration``).
    """
    import os
    parent = os.getppid()
    stop = _STOP
    stop.clear()
    # before rclpy.init: a signal while starting is a request like any other, never a KeyboardInterrupt
    # thrown into the middle of rcl's or DDS's set-up
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):  # SIGHUP: the terminal it ran in closed
        signal.signal(sig, lambda signum, frame: _request_stop(signum, parent))
    try:
        rclpy.init(args=sys.argv if args is None else args, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # rcl refuses the command line (e.g. a malformed -p rule)
        print(f"[{getattr(make_node, '__name__', 'node')}] fatal: {exc}", file=sys.stderr)
        return 1
    node = None
    routed = []
    try:
        executor = None
        if stop:   # told to stop while rclpy started: the node is not built
            return 0
        node = make_node()
        refuse_unknown_overrides(node)
        routed = _route_core_logs(node)
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        try:
            while not stop:  # back here at least every 0.1 s, so a signal is acted on promptly
                executor.spin_once(timeout_sec=0.1)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        if not _orphaned(parent):   # orphaned: nobody is left to acknowledge, and the budget is short
            if getattr(node, "drain_on_shutdown", False):
                _drain(executor, node)
            _await_acknowledgements(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception as exc:  # construction or callback failure: report and exit non-zero
        name = node.get_name() if node is not None else getattr(make_node, "__name__", "node")
        print(f"[{name}] fatal: {exc}", file=sys.stderr)
        return 1
    finally:
        # a second signal only asks again (never ignored: the watchdog armed by the first bounds the clean-up)
        if not stop:
            _arm_stop_watchdog(ORPHAN_STOP_BUDGET if _orphaned(parent) else STOP_BUDGET)
        for logger, handler in routed:
            logger.removeHandler(handler)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
