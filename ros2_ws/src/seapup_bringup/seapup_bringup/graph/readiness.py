"""When a SIL graph is ready to be driven, decided from the ``/diagnostics`` statuses its nodes publish.

Pure functions over ``diagnostic_msgs`` messages (duck-typed: anything with
``status``/``name``/``level``/``values``/``key``/``value`` and a header) and a
``count_subscribers(topic)`` function (the probe's view of the graph), used by
:class:`seapup_bringup.graph.sil.SilGraph`.

A node's status may report each of its publishers' matched readers
(``subscribers:<topic>``: n, the writer's side, which decides delivery). A
status *names* the graph ready once it says OK and each publisher it reports
has matched every reader of its topic the probe sees; a status that must only
be *matched* (the navigator's: its newest estimate has reached every reader,
whatever its level -- t_0 may lack an acoustic fix) need not say OK.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable

__all__ = ["OK", "DEFAULT_READY", "MATCHED_ONLY", "required", "latest_statuses", "publishers_matched",
           "graph_ready", "not_ready_report", "handled_since", "ended_waits", "ended_wait_events"]

#: ``diagnostic_msgs/msg/DiagnosticStatus`` OK level (a byte in rclpy).
OK = (0, b"\x00")
#: The statuses that say a hierarchy is ready: the task controller (it hears the navigator and a position
#: controller listens to its setpoints) and the position controller (active, hearing the navigator and
#: matched to the setpoint publisher), so a goal is accepted and flown at once.
DEFAULT_READY = ("seapup/task_controller", "seapup/position_controller")
#: Statuses whose publishers must have matched every reader, at any level (a graph with a navigator: no
#: reader that matched late lacks the estimate of the sample the graph is held at).
MATCHED_ONLY = ("seapup/navigator",)
#: How many of the newest ``DiagnosticArray`` messages are searched for a node's latest status.
WINDOW = 40


def required(ready_status: str | tuple[str, ...] | None) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The statuses that must say OK and matched, and those that must say matched only.

    Examples
    --------
    >>> required("seapup/task_controller")
    (('seapup/task_controller',), ('seapup/navigator',))
    >>> required(None)
    ((), ())
    >>> required("")
    ((), ('seapup/navigator',))
    """
    names = (ready_status,) if isinstance(ready_status, str) else tuple(ready_status or ())
    return tuple(name for name in names if name), (() if ready_status is None else MATCHED_ONLY)


def latest_statuses(diagnostics: list, window: int = WINDOW) -> dict:
    """Each node's newest status (name -> status) among the last ``window`` diagnostic arrays."""
    found = {}
    for array in diagnostics[-window:]:
        for status in array.status:
            found[status.name] = status
    return found


def _matched(status, count_subscribers: Callable[[str], int]) -> list[tuple[str, int, int]]:
    """(topic, matched readers the status reports, readers the probe sees) per reported publisher."""
    return [(kv.key.split(":", 1)[1], int(kv.value), count_subscribers(kv.key.split(":", 1)[1]))
            for kv in status.values if kv.key.startswith("subscribers:")]


def publishers_matched(status, count_subscribers: Callable[[str], int]) -> bool:
    """Whether every publisher the status reports has matched every reader of its topic the probe sees."""
    return all(reported >= seen for _, reported, seen in _matched(status, count_subscribers))


def graph_ready(found: dict, names: Iterable[str], matched_only: Iterable[str],
                count_subscribers: Callable[[str], int]) -> bool:
    """Whether the statuses ``found`` (:func:`latest_statuses`) say OK and matched for ``names`` and
    matched for ``matched_only`` (a status not heard is not ready)."""
    return (all(name in found and found[name].level in OK and publishers_matched(found[name], count_subscribers)
                for name in names)
            and all(name in found and publishers_matched(found[name], count_subscribers) for name in matched_only))


def not_ready_report(found: dict, names: Iterable[str], count_subscribers: Callable[[str], int]) -> str:
    """What each status of ``names`` said, for an error message (``name: 'message' (matched readers: [..] of
    [..])`` or ``name: no status``)."""
    parts = []
    for name in names:
        if name not in found:
            parts.append(f"{name}: no status")
            continue
        matched = _matched(found[name], count_subscribers)
        parts.append(f"{name}: {found[name].message!r} (matched readers: {[m[1] for m in matched]} of "
                     f"{[m[2] for m in matched]})")
    return "; ".join(parts)


def handled_since(diagnostics: list, name: str, t: float, window: int = WINDOW) -> bool:
    """Whether node ``name`` published a status stamped at or after ``t`` [s] (a node that stamps its status
    with the newest sample it handled has handled sample ``t``)."""
    return any(status.name == name and array.header.stamp.sec + 1e-9 * array.header.stamp.nanosec >= t - 1e-6
               for array in diagnostics[-window:] for status in array.status)


def status_value(diagnostics: list, name: str, key: str, start: int = 0) -> str | None:
    """The value of ``key`` in the newest status of node ``name`` among ``diagnostics[start:]``, or None."""
    for array in reversed(diagnostics[start:]):
        for status in array.status:
            if status.name == name:
                for kv in status.values:
                    if kv.key == key:
                        return kv.value
    return None


def said_otherwise(diagnostics: list, start: int, name: str, key: str, before: str | None) -> bool:
    """Whether node ``name`` published, among ``diagnostics[start:]``, a status whose ``key`` is not ``before``
    (a count that moved on, or began again after the node was configured anew)."""
    return any(status.name == name and kv.key == key and kv.value != before
               for array in diagnostics[start:] for status in array.status for kv in status.values)


def stream_started(diagnostics: list, name: str, t: float, window: int = WINDOW, key: str = "stream_start") -> bool:
    """Whether node ``name`` said (its status value ``key``) that a stream started with the message stamped ``t``
    [s] or later: ``stream_start``, a stream of its that its readers acknowledged or that it waited for in vain
    (then ``unacknowledged_stream_starts`` counts it: :func:`seapup_common.ros.node.acknowledge_stream_start`);
    ``setpoint_stream_start``, the position controller has the first setpoint of a stream it hears."""
    for array in diagnostics[-window:]:
        for status in array.status:
            if status.name != name:
                continue
            for kv in status.values:
                if kv.key == key:
                    try:
                        if float(kv.value) >= t - 1e-6:
                            return True
                    except ValueError:   # "None": no stream yet
                        pass
    return False


def _ended_wait_growths(diagnostics: Iterable):
    """``(array, status name, counter, value)`` each time a counter of :data:`seapup_common.lockstep.ENDED_WAITS`
    grows past what that node reported before (values that are not integers are skipped), in the order heard."""
    from seapup_common.lockstep import ENDED_WAITS
    seen: dict[tuple[str, str], int] = {}
    for array in diagnostics:
        for status in array.status:
            for kv in status.values:
                if kv.key not in ENDED_WAITS:
                    continue
                try:
                    value = int(kv.value)
                except ValueError:
                    continue
                if value > seen.get((status.name, kv.key), 0):
                    seen[(status.name, kv.key)] = value
                    yield array, status.name, kv.key, value


def ended_waits(diagnostics: Iterable) -> dict[str, dict[str, int]]:
    """Each node's wall-clock limits that ended a lockstep wait, from every status heard: name -> {counter:
    its largest value} for the counters of :data:`seapup_common.lockstep.ENDED_WAITS` above zero (empty: every
    node waited for what it waited for, and the run is as a quiet machine would fly it).

    Examples
    --------
    >>> from types import SimpleNamespace as N
    >>> status = lambda name, **v: N(name=name, values=[N(key=k, value=str(x)) for k, x in v.items()])
    >>> arrays = [N(status=[status("seapup/gmv", late_references=0, samples=9)]),
    ...           N(status=[status("seapup/gmv", late_references=2), status("seapup/simulator", steps="x")]),
    ...           N(status=[status("seapup/gmv", late_references=1)])]
    >>> ended_waits(arrays)
    {'seapup/gmv': {'late_references': 2}}
    """
    found: dict[str, dict[str, int]] = {}
    for _, name, counter, value in _ended_wait_growths(diagnostics):
        found.setdefault(name, {})[counter] = value   # each growth is the largest so far
    return found


def ended_wait_events(diagnostics: Iterable) -> list[dict]:
    """Each growth of a counter of :data:`seapup_common.lockstep.ENDED_WAITS` as a run result's event
    (``{"time": the status's stamp [s], "kind": "ended_wait", "detail": "<node>: <counter> <n>"}``), in the
    order heard.

    Examples
    --------
    >>> from types import SimpleNamespace as N
    >>> def array(sec, **v):
    ...     values = [N(key=k, value=str(x)) for k, x in v.items()]
    ...     return N(status=[N(name="seapup/simulator", values=values)], header=N(stamp=N(sec=sec, nanosec=0)))
    >>> [e["time"] for e in ended_wait_events([array(3, lockstep_timeouts=1), array(4, lockstep_timeouts=1),
    ...                                         array(5, lockstep_timeouts=3)])]
    [3.0, 5.0]
    """
    return [{"time": array.header.stamp.sec + 1e-9 * array.header.stamp.nanosec, "kind": "ended_wait",
             "detail": f"{name}: {counter} {value}"} for array, name, counter, value in _ended_wait_growths(diagnostics)]
