"""The SIL harness's probe: a node of its own that listens to a graph and gives its logs as arrays.

:class:`SilProbe` subscribes to the topics of :data:`TOPICS` on a private rclpy
``Context`` (so it never shares a participant with anything else in the
process), keeps every message heard, and turns them into numpy arrays
(:func:`log_arrays`: times in s, SI units, NED/FRD). The probe is not waited
for by a graph unless the graph's lockstep roster lists it
(:class:`seapup_common.lockstep.roster.Listener`): on a loaded machine it hears
its messages seconds of simulated time behind the nodes, one topic further
behind than another, so :meth:`SilProbe.catch_up` waits until every per-sample
topic has reached the same time before the logs are read.
"""
from __future__ import annotations

import math
import time

import numpy as np

from seapup_common import topics
from seapup_common.topics import TOPIC_TYPES

__all__ = ["SilProbe", "TOPICS", "INSTRUMENTS", "SAMPLED", "SAMPLED_INSTRUMENTS", "log_arrays",
           "once_per_stamp", "stamp_s", "import_path"]

#: What the probe logs: name -> (topic, message type as a Python path).
TOPICS = {name: (topic, TOPIC_TYPES[topic].replace("/", ".")) for name, topic in {
    "truth": topics.TRUTH_ODOMETRY,
    "estimate": topics.NAVIGATION_ODOMETRY,
    "reference": topics.VELOCITY_REFERENCE,
    "setpoint": topics.POSITION_REFERENCE,
    "command": topics.COMMAND,
    "applied": topics.APPLIED,
    "altitude": topics.ALTITUDE,
    "velocity": topics.VELOCITY,
    "imu": topics.IMU,
    "depth": topics.DEPTH,
    "position": topics.POSITION,
    "rejections": topics.TASK_REJECTIONS,
    "diagnostics": topics.DIAGNOSTICS,
}.items()}
#: The instruments' topics, logged only when asked (``instruments=True``): a graph whose simulator waits
#: for a subscriber of one of them (the identification graphs wait for the recorder's) must not be
#: started by the probe's subscription.
INSTRUMENTS = ("velocity", "imu", "depth", "position")
#: The logged topics a graph publishes once per control sample: :meth:`SilProbe.catch_up` waits until
#: each has reached the same time.
SAMPLED = ("truth", "estimate", "reference", "setpoint", "command", "applied")
#: The instruments published at every sample (the acoustic fixes come at some samples only): caught up
#: with :data:`SAMPLED` when instruments are logged (a command heard before its sample's velocity was seen).
SAMPLED_INSTRUMENTS = ("velocity", "imu", "depth")
#: The simulator's per-sample topics: published at a sample before any node answers it, so a log that has
#: heard an answer to sample k (:data:`_ANSWERS`, stamped with the sample's stamp) must have them at k too
#: (caught up exactly, not within the slack).
_SIMULATOR_SAMPLED = ("truth", "applied") + SAMPLED_INSTRUMENTS
_ANSWERS = ("command", "estimate")
#: Topics whose publisher may say a sample again, to a reader that matched late: the simulator (resumed at an
#: unanswered sample) and the navigator (its newest estimate). Logged once per stamp.
_SAID_AGAIN = ("truth", "applied", "altitude", "velocity", "imu", "depth", "position", "estimate")


def import_path(path: str):
    """The object at a dotted Python path (``"nav_msgs.msg.Odometry"``)."""
    module, name = path.rsplit(".", 1)
    return getattr(__import__(module, fromlist=[name]), name)


def stamp_s(msg) -> float:
    """A stamped message's time [s]."""
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def once_per_stamp(msgs: list) -> list:
    """The messages without repeats of the next one's stamp (the last kept: after a simulator reset, t_0
    is a new sample)."""
    out = []
    for msg in msgs:
        if out and (out[-1].header.stamp.sec, out[-1].header.stamp.nanosec) == (msg.header.stamp.sec,
                                                                                msg.header.stamp.nanosec):
            out[-1] = msg
        else:
            out.append(msg)
    return out


def _xyz(v) -> list:
    return [v.x, v.y, v.z]


def _euler(q):
    from seapup_common import frames
    return frames.quaternion_to_euler([q.x, q.y, q.z, q.w])


def _times(msgs) -> np.ndarray:
    return np.array([stamp_s(m) for m in msgs])


def log_arrays(log: dict[str, list]) -> dict[str, np.ndarray]:
    """The messages of a probe's log (name -> messages, names of :data:`TOPICS`) as arrays.

    ``truth_t``, ``truth_position`` (N, 3), ``truth_attitude`` (N, 3), ``truth_velocity`` (N, 6);
    ``estimate_t``, ``estimate_position``, ``estimate_horizontal_std`` [m]; ``reference_t``, ``reference``
    (N, 4: u, v, w, r); ``command_t``, ``command`` (N, 4 blade pitches); ``applied_t``, ``applied``;
    ``setpoint_t``, ``setpoint`` (N, 4: x, y, z, yaw); ``altitude_t``, ``altitude`` (NaN out of range);
    the instruments: ``velocity_t``, ``velocity`` (N, 6: u, v, w, p, q, r), ``imu_t``, ``attitude``
    (N, 3), ``depth_t``, ``depth``, ``position_t``, ``position`` (N, 3: acoustic fixes).
    """
    log = {name: once_per_stamp(msgs) if name in _SAID_AGAIN else msgs for name, msgs in log.items()}
    out = {}
    for name in ("truth", "estimate"):
        msgs = log[name]
        out[f"{name}_t"] = _times(msgs)
        out[f"{name}_position"] = np.array([_xyz(m.pose.pose.position) for m in msgs]).reshape(-1, 3)
        out[f"{name}_attitude"] = np.array([_euler(m.pose.pose.orientation) for m in msgs]).reshape(-1, 3)
        out[f"{name}_velocity"] = np.array([_xyz(m.twist.twist.linear) + _xyz(m.twist.twist.angular)
                                            for m in msgs]).reshape(-1, 6)
    # the navigator's stated horizontal uncertainty [m]: the larger of its x, y standard deviations
    out["estimate_horizontal_std"] = np.array([math.sqrt(max(m.pose.covariance[0], m.pose.covariance[7], 0.0))
                                               for m in log["estimate"]])
    out["reference_t"] = _times(log["reference"])
    out["reference"] = np.array([_xyz(m.twist.linear) + [m.twist.angular.z] for m in log["reference"]]
                                ).reshape(-1, 4)
    for name in ("command", "applied"):
        out[f"{name}_t"] = _times(log[name])
        out[name] = np.array([list(m.pitch) for m in log[name]]).reshape(-1, 4)
    out["setpoint_t"] = _times(log["setpoint"])
    out["setpoint"] = np.array([_xyz(m.pose.position) + [_euler(m.pose.orientation)[2]]
                                for m in log["setpoint"]]).reshape(-1, 4)
    out["velocity_t"] = _times(log["velocity"])
    out["velocity"] = np.array([_xyz(m.twist.twist.linear) + _xyz(m.twist.twist.angular)
                                for m in log["velocity"]]).reshape(-1, 6)
    out["imu_t"] = _times(log["imu"])
    out["attitude"] = np.array([_euler(m.orientation) for m in log["imu"]]).reshape(-1, 3)
    out["depth_t"] = _times(log["depth"])
    out["depth"] = np.array([m.depth for m in log["depth"]])
    out["position_t"] = _times(log["position"])
    out["position"] = np.array([_xyz(m.pose.pose.position) for m in log["position"]]).reshape(-1, 3)
    out["altitude_t"] = _times(log["altitude"])
    out["altitude"] = np.array([m.range if m.min_range <= m.range <= m.max_range else math.nan
                                for m in log["altitude"]])
    return out


class SilProbe:
    """A listening node on a private rclpy context (``open`` it, ``close`` it).

    Parameters
    ----------
    instruments : bool
        Also log :data:`INSTRUMENTS` (a graph may use their subscriptions as its start signal).

    Attributes
    ----------
    log : dict of str to list
        Every message heard, by name (:data:`TOPICS`).
    node, executor
        The probe's rclpy node and its executor (None until :meth:`open`).
    """

    def __init__(self, instruments: bool = False):
        self.instruments = bool(instruments)
        self.log: dict[str, list] = {name: [] for name in TOPICS}
        #: per name: samples DDS reported lost to the probe's subscription (a reliable writer that dropped
        #: them before repairing them), and the (wall time, publishers matched) of every change of its match
        self.lost: dict[str, int] = {}
        self.matches: dict[str, list[tuple[float, int]]] = {name: [] for name in TOPICS}
        self.node = self.executor = self._context = None

    @property
    def topics(self) -> tuple[str, ...]:
        """The topics this probe subscribes to (a lockstep graph's roster counts it as their listener)."""
        return tuple(topic for name, (topic, _) in TOPICS.items() if self.instruments or name not in INSTRUMENTS)

    def open(self, domain: int) -> "SilProbe":
        """Create the node on ``domain`` and subscribe."""
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        self._context = Context()
        rclpy.init(context=self._context, domain_id=domain)
        self.node = rclpy.create_node("sil_probe", context=self._context)
        self.executor = SingleThreadedExecutor(context=self._context)
        self.executor.add_node(self.node)
        from rclpy.event_handler import SubscriptionEventCallbacks
        for name, (topic, kind) in TOPICS.items():
            if self.instruments or name not in INSTRUMENTS:
                events = SubscriptionEventCallbacks(
                    message_lost=lambda status, n=name: self._on_lost(n, status),
                    matched=lambda status, n=name: self.matches[n].append((time.monotonic(),
                                                                            int(status.current_count))),
                    use_default_callbacks=False)
                self.node.create_subscription(import_path(kind), topic, self.log[name].append, 10000,
                                              event_callbacks=events)
        return self

    def _on_lost(self, name: str, status) -> None:
        self.lost[name] = self.lost.get(name, 0) + int(status.total_count_change)

    def account(self, name: str) -> str:
        """What the probe knows of one topic's transport: samples DDS reported lost, and its publishers'
        matches over time (a writer that unmatched mid-run shows as a drop of the count)."""
        counts = [count for _, count in self.matches.get(name, [])]
        return (f"{self.lost.get(name, 0)} reported lost by DDS; publishers matched over time "
                f"{counts or 'never'}")

    def close(self) -> None:
        """Destroy the node and its context: alive, its DDS participant keeps announcing itself on a domain
        the next lease holder reuses (seen: '/sil_probe' in a later test's node list)."""
        if self.executor is not None:
            self.executor.shutdown(timeout_sec=1.0)
            self.executor = None
        if self.node is not None:
            self.node.destroy_node()
            self.node = None
        if self._context is not None:
            self._context.try_shutdown()
            self._context.destroy()
            self._context = None

    def spin_until(self, predicate, timeout: float) -> bool:
        """Spin the probe until ``predicate()`` holds or ``timeout`` wall seconds pass."""
        deadline = time.monotonic() + timeout
        while not predicate() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.02)
        return bool(predicate())

    @property
    def t(self) -> float:
        """Latest simulated time heard [s] (from the truth)."""
        return stamp_s(self.log["truth"][-1]) if self.log["truth"] else 0.0

    def catch_up(self, target: float | None = None, stall: float = 2.0, slack: float = 0.25) -> None:
        """Spin until every per-sample topic heard so far (:data:`SAMPLED`, and :data:`SAMPLED_INSTRUMENTS`
        when the instruments are logged) has reached ``target`` [s simulated] within ``slack`` (default
        target: the newest stamp heard on any of them), and the simulator's own topics, exactly, every
        sample a node has been heard answering (a command or an estimate).

        Gives up when no log has grown for ``stall`` wall seconds (the graph stopped)."""
        def last(name):
            return stamp_s(self.log[name][-1])
        sampled = SAMPLED + (SAMPLED_INSTRUMENTS if self.instruments else ())
        live = [name for name in sampled if self.log[name]]
        if not live:
            return
        if target is None:
            target = max(last(name) for name in live)
        sizes, moved = None, time.monotonic()
        answered = [last(name) for name in _ANSWERS if name in live]
        answered_to = min(target, max(answered)) if answered else -math.inf

        def behind(name):
            return last(name) < target - slack or (name in _SIMULATOR_SAMPLED and last(name) < answered_to - 1e-6)
        while any(behind(name) for name in live):
            now = [len(self.log[name]) for name in live]
            if now != sizes:
                sizes, moved = now, time.monotonic()
            elif time.monotonic() - moved > stall:
                return
            self.executor.spin_once(timeout_sec=0.02)

    def estimate(self) -> tuple[float, np.ndarray, np.ndarray] | None:
        """The latest navigation estimate: time [s], position (x, y, z odom_ned) [m], attitude (phi, theta,
        psi); None before the first."""
        if not self.log["estimate"]:
            return None
        msg = self.log["estimate"][-1]
        p = msg.pose.pose.position
        return stamp_s(msg), np.array([p.x, p.y, p.z]), np.asarray(_euler(msg.pose.pose.orientation), dtype=float)

    def hear(self, t: float, since: float | None = None, answered: bool = True, stall: float = 2.0) -> None:
        """Spin until the probe has heard sample ``t`` [s] of a graph held there: the truth, and (``answered``)
        every per-sample topic that had reached ``since`` (flowing then); one that stops short of ``t`` is
        waited for ``stall`` wall seconds after the logs last grew."""
        def last(name):
            return stamp_s(self.log[name][-1])
        flowing = [name for name in SAMPLED if self.log[name] and (since is None or last(name) >= since - 1e-6)]
        wanted = ["truth"] + (flowing if answered else [])
        sizes, moved = None, time.monotonic()
        while any(not self.log[name] or last(name) < t - 1e-6 for name in wanted):
            now = [len(self.log[name]) for name in wanted]
            if now != sizes:
                sizes, moved = now, time.monotonic()
            elif time.monotonic() - moved > stall:
                return
            self.executor.spin_once(timeout_sec=0.01)
