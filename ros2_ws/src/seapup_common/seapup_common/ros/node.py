"""Shared node entry, parameter declaration, QoS and logging for seapup nodes (rclpy).

Gives every node the same life cycle: ``rclpy.init`` with the process's
arguments, an executor chosen by the read-only parameter ``executor``
(:data:`EXECUTORS`; its default from ``$SEAPUP_EXECUTOR`` so a whole graph
switches at once, see :func:`declare_executor`), a clean exit on SIGINT/SIGTERM, a non-zero exit code if the node
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
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import rclpy
from ament_index_python.packages import get_package_share_directory
from rcl_interfaces.msg import ParameterType
from rclpy.duration import Duration
from rclpy.exceptions import ParameterNotDeclaredException, ParameterUninitializedException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, QoSCompatibility, QoSProfile, ReliabilityPolicy, qos_check_compatible
from rclpy.signals import SignalHandlerOptions

from seapup_common import CORE_LOGGERS  # noqa: F401 - the cores' loggers, routed to the node's (re-exported)
from seapup_common.parameters import load_node_parameters

__all__ = ["run_node", "declare_from_package_file", "declare_guarded", "declare_mapping", "flatten", "RosLogHandler",
           "ParameterGuard", "Allowed", "one_of", "each_one_of", "text", "topic_names", "regular_expression",
           "path_or_empty",
           "refuse_invalid_transitions", "stop_requested", "QUIET_PUBLISHER", "QUIET_SUBSCRIPTION",
           "QosWatch", "EXECUTORS", "EXECUTOR_ENV", "DEFAULT_EXECUTOR", "declare_executor", "make_executor",
           "UnknownExecutorError", "takes_message_info",
           "RELIABLE_QOS", "COMMAND_QOS", "TF_QOS", "TF_STATIC_QOS", "SERVICE_QOS", "CORE_LOGGERS"]

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


def _is_text(value) -> bool:
    """A string or a list of strings (a string array parameter)."""
    if isinstance(value, (list, tuple)):
        return bool(value) and all(isinstance(v, str) for v in value)
    return isinstance(value, str)


@dataclass(frozen=True)
class Allowed:
    """The values a string (or string-array) parameter may take: said in words (the descriptor's
    ``additional_constraints``, so ``./seapup param describe`` shows it) and checked by ``test``
    (``test(value) -> ""`` when allowed, else the reason, which names what is allowed).

    Build one with :func:`one_of`, :func:`each_one_of` or :func:`text`.
    """

    constraint: str
    test: Callable[[Any], str]

    def problem(self, name: str, value) -> str:
        values = value.tolist() if hasattr(value, "tolist") else value
        if isinstance(values, (list, tuple)) and len(values) > MAX_TEXT_ITEMS:
            return f"{name}: {len(values)} entries refused: at most {MAX_TEXT_ITEMS}"
        for v in values if isinstance(values, (list, tuple)) else [values]:
            if isinstance(v, str) and (len(v) > MAX_TEXT_LENGTH or "\0" in v):
                return f"{name} = {v[:40]!r}... refused: at most {MAX_TEXT_LENGTH} characters, no NUL"
        reason = self.test(value)
        return f"{name} = {_short(value)} refused: {reason}" if reason else ""


#: Bounds on every string parameter (a path, a topic name, a YAML text): longer is refused before use.
MAX_TEXT_LENGTH = 65536
MAX_TEXT_ITEMS = 1000


def _short(value) -> str:
    text = repr(list(value) if isinstance(value, tuple) or hasattr(value, "tolist") else value)
    return text if len(text) <= 80 else text[:77] + "..."


def one_of(*choices: str) -> Allowed:
    """A string that is one of ``choices``."""
    allowed = tuple(str(c) for c in choices)
    return Allowed(f"one of: {', '.join(allowed)}",
                   lambda v: "" if v in allowed else f"it must be one of {', '.join(allowed)}")


def each_one_of(*choices: str, empty: bool = True, unique: bool = False) -> Allowed:
    """A list of strings, each one of ``choices`` (``empty``: the list may be empty; ``unique``: no repeats)."""
    allowed = tuple(str(c) for c in choices)

    def test(values) -> str:
        values = list(values)
        bad = [v for v in values if v not in allowed]
        if bad:
            return f"{bad[0]!r} is not one of {', '.join(allowed)}"
        if not values and not empty:
            return f"it needs at least one of {', '.join(allowed)}"
        if unique and len(set(values)) != len(values):
            return "each may be listed once"
        return ""
    return Allowed(f"each one of: {', '.join(allowed)}" + ("" if empty else " (at least one)"), test)


def text(constraint: str, test: Callable[[Any], str] | None = None) -> Allowed:
    """Free text (a path, a topic name, a regular expression, YAML) with its constraint in words and an
    optional check; length and NUL are bounded for every string parameter (:class:`Allowed`)."""
    return Allowed(constraint, test or (lambda v: ""))


def _topic_problem(name: str) -> str:
    from rclpy.exceptions import InvalidTopicNameException
    from rclpy.validate_topic_name import validate_topic_name
    try:
        validate_topic_name(name.split(":", 1)[0])
    except InvalidTopicNameException as exc:
        return f"{name!r} is not a topic name: {str(exc).splitlines()[0][:120]}"
    return ""


def topic_names(typed: bool = False) -> Allowed:
    """A topic name or a list of them (relative or absolute; ``typed``: ``/topic:pkg/msg/Type`` allowed)."""
    def test(value) -> str:
        for name in [value] if isinstance(value, str) else list(value):
            if typed and not name:
                continue
            problem = _topic_problem(name)
            if problem:
                return problem
        return ""
    return Allowed("ROS topic names" + (" (each may end in :pkg/msg/Type)" if typed else ""), test)


def regular_expression() -> Allowed:
    """A Python regular expression, or empty."""
    import re

    def test(value: str) -> str:
        try:
            re.compile(value)
        except re.error as exc:
            return f"not a regular expression: {exc}"
        return ""
    return Allowed("a Python regular expression, or empty", test)


def path_or_empty(what: str) -> Allowed:
    """A file-system path (created or read by the node as ``what`` says), or empty for its default."""
    return Allowed(f"{what}, or empty", lambda v: "")


class ParameterGuard:
    """The allowed values of every parameter of a node, checked on every change.

    rclpy checks a scalar's declared range on ``param set`` but lets NaN through
    (every comparison with NaN is false) and never checks arrays; a value out of range
    or not finite must be refused before the node uses it (``reference_wait:
    .nan`` once killed a controller at its next sample). Strings are checked against
    their :class:`Allowed` values. Registered by :func:`declare_from_package_file` and
    :func:`declare_guarded` as an on-set-parameters callback; the declared values are
    checked too (a bad ``-p`` stops the start, naming it).

    Parameters
    ----------
    ranges : dict
        Name: (lo, hi) of a number or of each element of a number array.
    allowed : dict, optional
        Name: :class:`Allowed` of a string or string array.
    """

    def __init__(self, ranges: dict, allowed: dict | None = None):
        self.ranges = dict(ranges)
        self.allowed = dict(allowed or {})

    def problem(self, name: str, value) -> str:
        """Why ``value`` cannot be parameter ``name``, or ""."""
        if name in self.allowed and (_is_text(value) or isinstance(value, (list, tuple))):
            return self.allowed[name].problem(name, value)
        bounds = self.ranges.get(name)
        if bounds is None:
            return ""
        lo, hi = bounds
        values = value.tolist() if hasattr(value, "tolist") else value
        for v in values if isinstance(values, (list, tuple)) else [values]:
            if _is_number(v) and not (math.isfinite(v) and lo <= v <= hi):
                return f"{name} = {_short(value)} refused: it must be finite and within [{lo:g}, {hi:g}]"
        return ""

    def __call__(self, parameters):
        from rcl_interfaces.msg import SetParametersResult
        for parameter in parameters:
            reason = self.problem(parameter.name, parameter.value)
            if reason:
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)


def _describe(descriptor, value, bounds=None, allowed: Allowed | None = None):
    """``descriptor`` (or a new one) with the range ``bounds`` of a number (array) and the constraint of
    ``allowed`` in words; rclpy enforces a scalar's range itself, the guard every element and NaN."""
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
    descriptor = descriptor if descriptor is not None else ParameterDescriptor()
    if bounds is not None and _range_of(descriptor) is None:
        lo, hi = bounds
        first = value[0] if isinstance(value, (list, tuple)) and value else value
        if isinstance(first, int) and not isinstance(first, bool) and float(lo).is_integer() \
                and float(hi).is_integer():
            descriptor.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi), step=1)]
        else:
            descriptor.floating_point_range = [FloatingPointRange(from_value=float(lo), to_value=float(hi))]
    if allowed is not None and not descriptor.additional_constraints:
        descriptor.additional_constraints = allowed.constraint
    return descriptor


def declare_guarded(node, values: Mapping, descriptors: dict | None = None, ranges: dict | None = None,
                    allowed: dict | None = None, where: str = "") -> dict:
    """Declare the flat parameters ``values`` (name: default) of ``node``, each number with its range and each
    string with its :class:`Allowed` values in its descriptor, and guard them (:class:`ParameterGuard`) at
    declaration (an override out of range raises ``ValueError`` naming it) and on every change.

    Raises
    ------
    ValueError
        A number (array) without a range, a string (array) without its allowed values, a range or allowed
        values for a parameter ``values`` does not have, or a declared value that is not allowed.
    """
    descriptors = dict(descriptors or {})
    ranges, allowed = dict(ranges or {}), dict(allowed or {})
    extra = sorted((set(ranges) | set(allowed)) - set(values))
    if extra:
        raise ValueError(f"{where or node.get_name()}: a range or allowed values for {', '.join(extra)}, which "
                         "it does not declare")
    for name, descriptor in descriptors.items():
        if _range_of(descriptor) is not None:
            ranges.setdefault(name, _range_of(descriptor))
    def strings(name, value) -> bool:   # an empty list is what its descriptor says (default: numbers)
        descriptor = descriptors.get(name)
        if isinstance(value, (list, tuple)) and not value:
            return descriptor is not None and descriptor.type == ParameterType.PARAMETER_STRING_ARRAY
        return _is_text(value)

    unranged = sorted(name for name, value in values.items() if name not in ranges and (
        _numeric(value) or (isinstance(value, (list, tuple)) and not value and not strings(name, value))))
    if unranged:
        raise ValueError(f"{where or node.get_name()}: numeric parameters without an allowed range: "
                         f"{', '.join(unranged)}")
    unstated = sorted(name for name, value in values.items() if strings(name, value) and name not in allowed)
    if unstated:
        raise ValueError(f"{where or node.get_name()}: string parameters without their allowed values: "
                         f"{', '.join(unstated)}")
    for name, value in values.items():
        if name in ranges or name in allowed:
            descriptors[name] = _describe(descriptors.get(name), value, ranges.get(name), allowed.get(name))
    guard = ParameterGuard(ranges, allowed)
    declared = {name: _declare(node, name, value, descriptors.get(name)) for name, value in values.items()}
    for name, value in declared.items():
        reason = guard.problem(name, value)
        if reason:
            raise ValueError(reason)
    node.add_on_set_parameters_callback(guard)
    return declared


def declare_from_package_file(node, package: str, file_name: str, descriptors: dict | None = None,
                              defaults: dict | None = None, section: str | None = None,
                              ranges: dict | None = None, allowed: dict | None = None) -> dict:
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
    an array); every string (array) its :class:`Allowed` values in ``allowed``;
    one without is a programming error (``ValueError`` at start). A
    :class:`ParameterGuard` refuses any value outside them or not finite, at
    declaration (``ValueError`` naming it) and on every change
    (:func:`declare_guarded`).
    """
    path = Path(get_package_share_directory(package)) / "config" / file_name
    values = {**(defaults or {}), **flatten(load_node_parameters(path, section or node.get_name()))}
    return declare_guarded(node, values, descriptors, ranges, allowed, where=file_name)


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


#: Seconds a stopping node waits for its reliable subscribers' acknowledgements (:func:`_await_acknowledgements`):
#: longer than Fast DDS's default 3 s periodic heartbeat, after which a lost message is sent again (seapup's
#: processes send one every 100 ms: ``seapup_common/config/fastdds_profiles.xml``; the budget covers a process
#: started without it).
ACK_BUDGET = 4.0


#: [s wall] How long a draining node must take no new message before it stops (:func:`_drain`).
DRAIN_IDLE = 0.25


def _drain(executor, node, budget: float = 1.5, idle: float = DRAIN_IDLE) -> None:
    """Run the callbacks already queued (e.g. a recorder's received messages) before stopping: until no
    message received *before the stop* has been taken for ``idle`` seconds, or ``budget`` seconds pass (a
    stopped process must end promptly: its parent may be gone). A message is the node's ``received`` count
    growing; when it was received, the node's ``last_received_ns`` (the middleware's reception time of the
    newest message taken, ``time.time_ns``'s clock): a live graph keeps publishing, and what arrives after
    the stop is not waited for.

    Not until the first step that takes nothing: a step runs one callback, and a timer's (a recorder's
    flush) or a service's takes none -- a recorder stopped that way under load closed its bag with the last
    12 s of a self-test's samples, acknowledged to their writer, still queued."""
    import threading
    deadline = time.monotonic() + budget
    stop_ns = time.time_ns()
    spent = _Stop()   # the events executor's steps may overrun their timeout: the budget ends them (_spin_step)
    timer = threading.Timer(budget, spent.request)
    timer.daemon = True
    timer.start()
    try:
        quiet_since = None
        while time.monotonic() < deadline:
            before = getattr(node, "received", None)
            _spin_step(executor, spent, 0.01)
            backlog = (getattr(node, "received", None) != before
                       and getattr(node, "last_received_ns", 0) < stop_ns)
            if backlog:
                quiet_since = None
            elif quiet_since is None:
                quiet_since = time.monotonic()
            elif time.monotonic() - quiet_since >= idle:
                break
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        timer.cancel()


def _await_acknowledgements(node) -> None:
    """Give reliable subscribers up to :data:`ACK_BUDGET` seconds to acknowledge what was published.

    A process that exits right after publishing (a controller stopped just after
    its last command) would otherwise take an unacknowledged message with it: a
    subscriber that lost the first transmission never gets the resend, while
    another (a recorder) did receive it. A lost transmission is repaired only after the writer's next
    heartbeat, and a writer that stopped writing sends one every 3 s by default (Fast DDS's
    ``WriterTimes.heartbeat_period``; 100 ms in seapup's processes, ``config/fastdds_profiles.xml``, since
    a reader also acknowledges only in answer to one: with 3 s the wait below took 1-2 s per graph stop even
    when nothing was lost): on a loaded machine a recorder was seen 0.7 s of wall time (190
    samples) behind a self-test's commands when the graph stopped (most likely waiting for such a repair);
    the bag lost them all with a 0.5 s budget, none in 24 runs with 4 s (an identification bag lost its
    last 14 samples the same way). The wait
    ends as soon as every subscriber has acknowledged, so a budget longer than the heartbeat period costs a
    stop nothing when nothing is missing. A node may set its own ``ack_budget``.
    """
    budget = float(getattr(node, "ack_budget", ACK_BUDGET))
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


#: [s wall] How long a node waits for its readers to acknowledge the first message of a stream it starts
#: (:func:`acknowledge_stream_start`); the wait is only at a stream's start, never per sample.
STREAM_START_ACK_WAIT = 2.0


def acknowledge_stream_start(publisher, seconds: float = STREAM_START_ACK_WAIT) -> bool:
    """Wait (at most ``seconds`` wall) until every reader of ``publisher`` has acknowledged the first message
    of a stream just published; whether they all did.

    A lockstep harness acts while the graph is held; a node that starts a stream then (the position
    controller's first reference) is heard by the harness's
    probe and by the next node of the chain at about the same time, but not necessarily: a datagram repaired
    by a heartbeat reaches one reader later. The next node only waits for a stream's messages once it knows the
    stream flows, so if the graph went on first, that node would step one sample without it (under load, once
    in about five paced runs). The node then says the stream's start on ``/diagnostics`` (``stream_start``,
    its stamp), a wait that ran out counted in ``unacknowledged_stream_starts``. An acknowledgement is not
    proof that the reader's callback has run (beside two burners a first setpoint acknowledged by every reader
    was still taken after the next estimate once), so the harness waits for the consumers' own word too: the
    position controller's ``setpoint_stream_start`` and the active velocity controller's
    ``reference_stream_start`` (:func:`seapup_bringup.graph.readiness.stream_started`)."""
    return bool(publisher.wait_for_all_acked(Duration(seconds=float(seconds))))


#: Parameters a node may be given without declaring them itself (rclpy's own).
_IMPLICIT_PARAMETERS = ("use_sim_time", "start_type_description_service")


def _unknown_with_hint(name: str, declared) -> str:
    from seapup_common.config import nearest
    near = nearest(name, declared)
    return f"{name!r}" + (f" (did you mean {near!r}?)" if near else "")


class UndeclaredParameterError(ParameterNotDeclaredException):
    """A parameter set at run time (``./seapup param set``) that the node does not have: the one-line
    message names it and the nearest declared one (rclpy's said ``undeclared parameter(s): []``)."""

    def __init__(self, names: list[str], declared):
        hints = ", ".join(_unknown_with_hint(n, declared) for n in names)
        Exception.__init__(self, f"no parameter {hints} on this node; './seapup param list NODE' lists them")


def _name_undeclared(node) -> None:
    """Make a set of an undeclared parameter fail with :class:`UndeclaredParameterError`.

    rclpy's ``Node._check_undeclared_parameters`` (Jazzy) tests ``any()`` of a generator and then lists what
    is left of it, which is nothing: ``Invalid access to undeclared parameter(s): []``."""
    def check(parameter_list):
        if not all(isinstance(parameter, Parameter) for parameter in parameter_list):
            raise TypeError("parameter must be instance of type '{}'".format(repr(Parameter)))
        unknown = [p.name for p in parameter_list if p.name not in node._parameters]
        if unknown and not node._allow_undeclared_parameters:
            raise UndeclaredParameterError(unknown, node._parameters)
    node._check_undeclared_parameters = check   # rclpy has no public hook for this message


def refuse_unknown_overrides(node) -> None:
    """Raise ``ValueError`` for a parameter given to ``node`` (``-p``, ``--params-file``, a graph file)
    that it never declared: rclpy ignores such a value silently, so a misspelled
    ``real_time_facter:=2.0`` or ``environment.current.enabeld:=true`` would change nothing while
    the user believes it did. The message names each one and the nearest declared name. From then on,
    setting an undeclared parameter at run time is refused with the same kind of message
    (:class:`UndeclaredParameterError`)."""
    declared = set(node._parameters)
    _name_undeclared(node)
    unknown = sorted(name for name in node._parameter_overrides
                     if name not in declared and name not in _IMPLICIT_PARAMETERS
                     and not name.startswith("qos_overrides."))
    if unknown:
        hints = [_unknown_with_hint(name, declared) for name in unknown]
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
    answers what it found last (a node may ask at every sample). An endpoint
    whose node is not named yet waits up to :attr:`NAMING_PATIENCE` for its
    name, so the one report names it.
    """

    #: [s wall] an endpoint whose node the graph has not named yet (its node's discovery lags the endpoint's on
    #: a busy machine) is left unreported this long, so the report names the node
    NAMING_PATIENCE = 5.0

    def __init__(self, node, interval: float = 1.0):
        self.node = node
        self.interval = interval
        self._unnamed: dict = {}   # endpoint gid -> when it was first seen without its node's name
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
            if "_NODE_NAME_UNKNOWN_" in info.node_name:
                first = self._unnamed.setdefault(bytes(info.endpoint_gid), time.monotonic())
                if time.monotonic() - first < self.NAMING_PATIENCE:
                    continue   # reported once its node is named (or, never named, after the patience)
                other = "of an unnamed node"
            text = (f"{topic}: {'subscription' if publishing else 'publisher'} {other} has an incompatible "
                    f"QoS ({reason.strip().rstrip(';') or 'see ./seapup topic info -v'}): no messages pass")
            found.append(text)
            if text not in self._said:
                self._said.add(text)
                self.node.get_logger().warn(text)
        return found


#: The signals :func:`run_node` has been asked to stop by (empty while it runs on).
_STOP: list[int] = []
#: When the first stop signal came (monotonic wall time), for :func:`_slow_stop_line`.
_STOP_AT: list[float] = []
#: [s wall] a stop that takes longer from its signal to the context's shutdown says where the time went.
SLOW_STOP = 2.0


def _slow_stop_line(name: str, marks: list[tuple[str, float]]) -> str | None:
    """The line a slow stop prints: each phase's wall seconds since the previous mark, from the first stop
    signal (:data:`_STOP_AT`) to the last mark; None without a signal or when the stop took at most
    :data:`SLOW_STOP` s (what is left after the last mark is the interpreter's own exit).

    >>> _STOP_AT[:] = [10.0]
    >>> _slow_stop_line("simulator", [("spin", 10.2), ("executor shutdown", 11.2), ("node destroyed", 13.7)])
    '[simulator] slow stop: 3.7 s from the signal (spin 0.2 s, executor shutdown 1.0 s, node destroyed 2.5 s)'
    >>> _slow_stop_line("simulator", [("spin", 10.1), ("node destroyed", 10.5)]) is None
    True
    """
    if not _STOP_AT or not marks:
        return None
    total = marks[-1][1] - _STOP_AT[0]
    if total <= SLOW_STOP:
        return None
    times = [_STOP_AT[0]] + [t for _, t in marks]
    phases = ", ".join(f"{label} {max(t - before, 0.0):.1f} s" for (label, t), before in zip(marks, times))
    return f"[{name}] slow stop: {total:.1f} s from the signal ({phases})"
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


class _Stop:
    """A request to end a spin, shaped like the part of ``rclpy.task.Future`` that
    ``spin_until_future_complete`` uses (``done``, ``add_done_callback``, ``remove_done_callback``).

    :meth:`request` calls the waiting callbacks at once, in the caller's thread, taking no lock: it is called
    from a signal handler, which runs in the main thread between two bytecodes of whatever it interrupted (a
    ``Future``'s own non-reentrant lock included), and from a timer thread. The events executor's callback only
    stops its queue.
    """

    def __init__(self):
        self._requested = False
        self._callbacks: list = []

    def done(self) -> bool:
        return self._requested

    def add_done_callback(self, callback) -> None:
        if self._requested:
            callback(self)
        else:
            self._callbacks.append(callback)

    def remove_done_callback(self, callback) -> bool:
        try:
            self._callbacks.remove(callback)
        except ValueError:
            return False
        return True

    def request(self) -> None:
        self._requested = True
        for callback in list(self._callbacks):
            callback(self)


#: The stop request of the running :func:`run_node` (ends the events executor's spin at once; see :func:`_spin_step`).
_STOPPING: list[_Stop] = []


def _request_stop(signum: int, parent: int) -> None:
    """The stop signals' handler: ask the loop to stop and arm the watchdog (again, shorter, when orphaned).

    The request also ends a spin of the events executor in progress (:class:`_Stop`)."""
    first = not _STOP
    _STOP.append(signum)
    if first:
        _STOP_AT[:] = [time.monotonic()]
    if _STOPPING:
        _STOPPING[0].request()
    if first or _orphaned(parent):
        _arm_stop_watchdog(ORPHAN_STOP_BUDGET if _orphaned(parent) else STOP_BUDGET)


def _spin_step(executor, until, timeout: float) -> None:
    """One step of the executor's loop: at most ``timeout`` s, or until the future ``until`` completes.

    The SingleThreadedExecutor runs one callback per ``spin_once`` and honours its timeout. The events
    executor of rclpy 7.1 does not: its ``spin_once(timeout_sec)`` goes on dispatching while events keep
    coming (measured: 1.9-2.6 s, once 5 s, for a 0.1 s step of a free-running simulator with 200 queued
    commands), and its ``spin()`` never returns to Python at all, so a flag checked between steps is seen late
    or never (the hang seen before): its queue checks the deadline only when it is empty. A request of
    ``until`` (:class:`_Stop`) stops its queue after the callback in progress, from any thread
    (``spin_until_future_complete`` registers a done callback that does so, and removes it on return).
    """
    if isinstance(executor, SingleThreadedExecutor):
        executor.spin_once(timeout_sec=timeout)
    else:
        executor.spin_until_future_complete(until, timeout_sec=timeout)


def stop_requested() -> bool:
    """True once :func:`run_node` was asked to stop (SIGINT, SIGTERM, SIGHUP): a callback that waits
    (a blocking service call) gives up, so the node exits promptly."""
    return bool(_STOP)


#: The executors a node can run under (parameter ``executor``): ``single``, rclpy's SingleThreadedExecutor
#: (a wait set rebuilt at every iteration, in Python); ``events``, rclpy's ``experimental.EventsExecutor``
#: (middleware callbacks queued and dispatched in C++). :func:`run_node` spins both in steps of at most 0.1 s,
#: the stop flag checked between them (:func:`_spin_step`).
EXECUTORS = ("single", "events")
#: The environment variable that gives every node of a graph its default executor (a ``-p executor:=...``
#: of one node still wins).
EXECUTOR_ENV = "SEAPUP_EXECUTOR"
#: The executor of a node given neither the parameter nor the environment variable, unless its class names
#: another in its ``EXECUTOR`` attribute: ``single``. ``events`` was measured faster with less CPU on every graph
#: of ``./seapup bench``'s ``graph_executor_ab`` (simulator + MFOL at 5 Hz: about twice the samples per second,
#: each process about half the CPU per sample; see docs/nodes.md), but rclpy 7.1's EventsExecutor is not safe
#: for every node: a subscription whose callback takes the message info (the recorder's, for the DDS receive
#: and source times) kills it at the first message ("SystemError: null argument to internal routine"; such a
#: node says ``MESSAGE_INFO = True`` and always runs on ``single``: :func:`declare_executor`), and it runs no
#: coroutine (async) service callback by itself (the simulator's go through
#: ``seapup_sim.ros.simulation_control.deferred_service``). So the per-sample nodes that were soaked and
#: hostile-tested under it (the demo's hierarchy -- simulator, navigator, velocity controllers, controller
#: manager, position and task controllers, self-test -- and open_loop) say ``EXECUTOR = "events"``; the rest
#: (recorder, identifier, reference_schedule, live view) stay on ``single``.
DEFAULT_EXECUTOR = "single"


class UnknownExecutorError(ValueError):
    """``$SEAPUP_EXECUTOR`` (or ``executor``) names no executor of :data:`EXECUTORS`."""


def takes_message_info(node) -> bool:
    """Whether ``node`` has (or, by its class's ``MESSAGE_INFO`` attribute, will have) a subscription whose
    callback takes the message info -- which rclpy 7.1's EventsExecutor cannot deliver (:data:`DEFAULT_EXECUTOR`)."""
    from rclpy.subscription import Subscription
    return bool(getattr(type(node), "MESSAGE_INFO", False)) or any(
        getattr(sub, "_callback_type", None) == Subscription.CallbackType.WithMessageInfo for sub in node.subscriptions)


def _executor_default(preferred: str = DEFAULT_EXECUTOR) -> str:
    import os
    value = os.environ.get(EXECUTOR_ENV, "").strip() or preferred
    if value not in EXECUTORS:
        raise UnknownExecutorError(f"{EXECUTOR_ENV}={value[:40]!r} refused: it must be one of {', '.join(EXECUTORS)}")
    return value


def declare_executor(node) -> str:
    """Declare ``node``'s read-only string parameter ``executor`` (one of :data:`EXECUTORS`; default
    ``$SEAPUP_EXECUTOR``, else the node class's ``EXECUTOR`` attribute, else :data:`DEFAULT_EXECUTOR`) and
    return its value.

    Read-only: the executor is chosen once, when :func:`run_node` builds it; a change at run time
    could not take effect, so it is refused rather than accepted and ignored.

    A node whose subscriptions take the message info (:func:`takes_message_info`) runs on ``single``
    whatever ``$SEAPUP_EXECUTOR`` prefers for the graph (a whole-graph A/B keeps its recorder), and a
    ``-p executor:=events`` given to it is refused: the events executor would die at its first message.

    Raises
    ------
    UnknownExecutorError
        ``$SEAPUP_EXECUTOR`` is set to something else than one of :data:`EXECUTORS`.
    ValueError
        ``-p executor:=...`` is not one of :data:`EXECUTORS`, or is ``events`` for a node that takes message info.
    """
    from rcl_interfaces.msg import ParameterDescriptor
    descriptor = ParameterDescriptor(read_only=True, description="the executor that spins this node: single "
                                     f"(SingleThreadedExecutor) or events (EventsExecutor); default ${EXECUTOR_ENV}")
    preferred = getattr(type(node), "EXECUTOR", DEFAULT_EXECUTOR)
    default = _executor_default(preferred)
    info = takes_message_info(node)
    if info:
        default = "single"
    choice = declare_guarded(node, {"executor": default}, {"executor": descriptor},
                             allowed={"executor": one_of(*EXECUTORS)})["executor"]
    if info and choice == "events":
        raise ValueError("executor events refused: this node's subscriptions take the message info, which rclpy "
                         "7.1's EventsExecutor cannot deliver (it dies at the first message); use executor:=single")
    return choice


def make_executor(choice: str, context=None):
    """The rclpy executor named ``choice`` (one of :data:`EXECUTORS`) on ``context`` (default: rclpy's)."""
    if choice == "single":
        return SingleThreadedExecutor(context=context)
    if choice == "events":
        from rclpy.experimental import EventsExecutor
        return EventsExecutor(context=context)
    raise UnknownExecutorError(f"executor {choice!r} refused: it must be one of {', '.join(EXECUTORS)}")


def run_node(make_node, args=None) -> int:
    """Construct a node with ``make_node()`` and spin it until SIGINT or SIGTERM.

    The executor is the node's ``executor`` parameter (:func:`declare_executor`, :func:`make_executor`).
    Both signals only *ask* the node to stop (a flag checked between two
    executor steps, at least every 0.1 s, also when the node has nothing
    to do; the events executor's step is ended by the request itself, see :func:`_spin_step`): an exception thrown from a signal handler into whatever runs at
    that moment could be swallowed by it -- a ``KeyboardInterrupt`` raised
    inside a message deserialisation comes back from pybind11 as an ordinary
    error, which the simulator counts as a malformed command and keeps
    running (seen: 1 SIGTERM in 30 with queued commands at full rate). Then
    the executor stops, the node (its timers, callbacks and publishers) is
    destroyed, and only then is the context shut down: no callback ever runs
    on a dead context, and the exit code is 0. Before the node goes, reliable
    publishers wait (briefly) until their subscribers have acknowledged every
    message, so the last command of a stopped controller is not lost for one
    subscriber while another has it -- unless the first stop signal was SIGTERM, which asks for a prompt stop
    (launch escalates to it after SIGINT; a command interrupted by its user stops its graph with it): then
    nothing is drained or waited for. A callback may still end the node on
    purpose by raising ``KeyboardInterrupt`` (the recorder's ``max_duration``).
    """
    import os
    parent = os.getppid()
    stop = _STOP
    stop.clear()
    _STOP_AT.clear()
    marks: list[tuple[str, float]] = []   # the stop's phases, for a slow stop's line (_slow_stop_line)
    stopping = _Stop()
    _STOPPING[:] = [stopping]
    # before rclpy.init: a signal while starting is a request like any other, never a KeyboardInterrupt
    # thrown into the middle of rcl's or DDS's set-up
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):  # SIGHUP: the terminal it ran in closed
        signal.signal(sig, lambda signum, frame: _request_stop(signum, parent))
    try:
        rclpy.init(args=sys.argv if args is None else args, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # rcl refuses the command line (e.g. a malformed -p rule)
        print(f"[{getattr(make_node, '__name__', 'node')}] fatal: {exc}", file=sys.stderr)
        return 1
    node = executor = None
    routed = []
    try:
        if stop:   # told to stop while rclpy started: the node is not built
            return 0
        node = make_node()
        if getattr(node, "drain_on_shutdown", False) and not hasattr(node, "received"):
            raise TypeError(f"{type(node).__name__} drains at its stop but counts no received message "
                            "(its 'received' and 'last_received_ns': _drain would stop after its idle time)")
        choice = declare_executor(node)
        refuse_unknown_overrides(node)
        routed = _route_core_logs(node)
        executor = make_executor(choice, context=node.context)
        executor.add_node(node)
        try:
            while not stop:  # back here at least every 0.1 s (or when asked to stop), so a signal is acted on promptly
                _spin_step(executor, stopping, 0.1)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        marks.append(("spin", time.monotonic()))
        # orphaned: nobody is left to acknowledge, and the budget is short; SIGTERM first: a stop in a hurry (a
        # user's Ctrl-C on the command that owns the graph, or launch's escalation after SIGINT)
        if not _orphaned(parent) and _STOP[:1] != [signal.SIGTERM]:
            if getattr(node, "drain_on_shutdown", False):
                _drain(executor, node, float(getattr(node, "drain_budget", 1.5)))
            _await_acknowledgements(node)
            marks.append(("drain and acknowledgements", time.monotonic()))
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
        try:
            name = node.get_name() if node is not None else getattr(make_node, "__name__", "node")
        except Exception:  # noqa: BLE001 - a node whose context was shut down from outside: its name is moot
            name = "node"
        if executor is not None:   # the events executor holds the node's entities until it lets go of them
            executor.shutdown(timeout_sec=1.0)
            marks.append(("executor shutdown", time.monotonic()))
        if node is not None:
            node.destroy_node()
            marks.append(("node destroyed", time.monotonic()))
        rclpy.try_shutdown()
        marks.append(("context shut down", time.monotonic()))
        line = _slow_stop_line(name, marks)
        if line is not None:
            print(line, file=sys.stderr, flush=True)
    return 0
