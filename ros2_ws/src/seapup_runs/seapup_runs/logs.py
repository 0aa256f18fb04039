"""A run's series from what a graph published: the SIL probe's logs or a recorded bag, one shape.

The graph runner's probe (``seapup_bringup.graph.sil.SilGraph.logs``) and a rosbag2 recording of the same
topics (:func:`logs_from_bag`, read with rosbags from the bag's own message definitions, no ROS)
both give a mapping of stamped arrays; :func:`series_from_logs` turns it into the
:class:`~seapup_runs.result.Series` of a spec, one row per control sample, and
:func:`result_from_bag` into the :class:`~seapup_runs.result.RunResult` the in-process runner would
have returned for that spec.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from seapup_common import frames, topics
from seapup_runs.metrics import compute
from seapup_runs.result import RunResult, Series
from seapup_runs.spec import RunEvent, RunSpec

__all__ = ["series_from_logs", "logs_from_bag", "result_from_bag", "RECORDED_TOPICS", "BAG_TRANSPORT"]

BAG_TRANSPORT = "ros graph (lockstep), from its bag"
#: The topics a run's series is read from (record these to load a run from its bag).
RECORDED_TOPICS = (topics.TRUTH_ODOMETRY, topics.VELOCITY, topics.IMU, topics.DEPTH, topics.POSITION,
                   topics.ALTITUDE, topics.COMMAND, topics.APPLIED, topics.VELOCITY_REFERENCE)


def _by_stamp(times, values, stamps_ns: np.ndarray, width: int) -> np.ndarray:
    """``values`` at each of ``stamps_ns`` (NaN where nothing was heard for that stamp; the last heard
    wins where a stamp was heard twice)."""
    out = np.full((len(stamps_ns), width), np.nan)
    if len(times) == 0:
        return out
    values = np.asarray(values, float).reshape(len(times), width)
    index = {int(round(t * 1e9)): i for i, t in enumerate(np.asarray(times, float))}
    for k, stamp in enumerate(stamps_ns):
        i = index.get(int(stamp))
        if i is not None:
            out[k] = values[i]
    return out


def series_from_logs(spec: RunSpec, logs: dict) -> Series:
    """The run's series from stamped logs (keys as ``SilGraph.logs``: ``truth_t``, ``truth_position``,
    ``truth_attitude``, ``truth_velocity``, ``velocity_t``/``velocity``, ``imu_t``/``attitude``,
    ``depth_t``/``depth``, ``position_t``/``position``, ``altitude_t``/``altitude``,
    ``reference_t``/``reference``, ``command_t``/``command``, ``applied_t``/``applied``), one row per
    sample 0 ... duration.

    Raises
    ------
    ValueError
        If the logs do not hold every sample of the spec.
    """
    stamps = np.array(sorted({int(round(t * 1e9)) for t in logs["truth_t"] if t <= spec.duration + 1e-6}),
                      dtype=np.int64)
    if len(stamps) != spec.samples + 1:
        raise ValueError(f"the record holds {len(stamps)} samples of the {spec.samples + 1} the spec flies")
    truth = np.column_stack([_by_stamp(logs["truth_t"], logs["truth_position"], stamps, 3),
                             _by_stamp(logs["truth_t"], logs["truth_attitude"], stamps, 3),
                             _by_stamp(logs["truth_t"], logs["truth_velocity"], stamps, 6)])
    velocity = _by_stamp(logs["velocity_t"], logs["velocity"], stamps, 6)
    attitude = _by_stamp(logs["imu_t"], logs["attitude"], stamps, 3)
    position = _by_stamp(logs["position_t"], logs["position"], stamps, 3)
    depth = _by_stamp(logs["depth_t"], np.reshape(logs["depth"], (-1, 1)), stamps, 1)[:, 0]
    altitude = _by_stamp(logs["altitude_t"], np.reshape(logs["altitude"], (-1, 1)), stamps, 1)[:, 0]
    measured = {"u": velocity[:, 0], "v": velocity[:, 1], "w": velocity[:, 2], "p": velocity[:, 3],
                "q": velocity[:, 4], "r": velocity[:, 5], "roll": attitude[:, 0], "pitch": attitude[:, 1],
                "yaw": attitude[:, 2], "x": position[:, 0], "y": position[:, 1], "z": position[:, 2],
                "depth": depth, "altitude": altitude}
    reference = _by_stamp(logs["reference_t"], logs["reference"], stamps, 4)
    command = _by_stamp(logs["command_t"], logs["command"], stamps, 4)
    reference[-1] = command[-1] = np.nan  # as in process: no command is asked for at the end
    applied = _by_stamp(logs["applied_t"], logs["applied"], stamps, 4)
    events = [{"time": e.time, "kind": e.kind, "detail": RunEvent.to_dict(e)["detail"]} for e in spec.plant_events()]
    events += [{"time": t, "kind": "controller", "detail": {"type": c.type}}
               for t, c in spec.controller_timeline()[1:]]
    return Series.from_states(stamps * 1e-9, truth, measured, reference, command, applied,
                              sorted(events, key=lambda e: e["time"]))


def _stamp(msg) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def _xyz(v) -> list:
    return [v.x, v.y, v.z]


def _euler(q) -> list:
    return list(frames.quaternion_to_euler([q.x, q.y, q.z, q.w]))


def logs_from_bag(bag_dir: str | Path) -> dict:
    """The stamped logs of a rosbag2 recording (:data:`RECORDED_TOPICS`), as :func:`series_from_logs` reads
    them; message definitions come from the bag itself."""
    from rosbags.highlevel import AnyReader

    heard: dict[str, list] = {topic: [] for topic in RECORDED_TOPICS}
    with AnyReader([Path(bag_dir)]) as reader:
        connections = [c for c in reader.connections if c.topic in heard]
        for connection, _, raw in reader.messages(connections=connections):
            heard[connection.topic].append(reader.deserialize(raw, connection.msgtype))
    truth, reference = heard[topics.TRUTH_ODOMETRY], heard[topics.VELOCITY_REFERENCE]
    velocity, imu = heard[topics.VELOCITY], heard[topics.IMU]
    return {
        "truth_t": [_stamp(m) for m in truth],
        "truth_position": np.reshape([_xyz(m.pose.pose.position) for m in truth], (-1, 3)),
        "truth_attitude": np.reshape([_euler(m.pose.pose.orientation) for m in truth], (-1, 3)),
        "truth_velocity": np.reshape([_xyz(m.twist.twist.linear) + _xyz(m.twist.twist.angular) for m in truth],
                                     (-1, 6)),
        "velocity_t": [_stamp(m) for m in velocity],
        "velocity": np.reshape([_xyz(m.twist.twist.linear) + _xyz(m.twist.twist.angular) for m in velocity], (-1, 6)),
        "imu_t": [_stamp(m) for m in imu],
        "attitude": np.reshape([_euler(m.orientation) for m in imu], (-1, 3)),
        "depth_t": [_stamp(m) for m in heard[topics.DEPTH]],
        "depth": [m.depth for m in heard[topics.DEPTH]],
        "position_t": [_stamp(m) for m in heard[topics.POSITION]],
        "position": np.reshape([_xyz(m.pose.pose.position) for m in heard[topics.POSITION]], (-1, 3)),
        "altitude_t": [_stamp(m) for m in heard[topics.ALTITUDE]],
        "altitude": [m.range if m.min_range <= m.range <= m.max_range else math.nan for m in heard[topics.ALTITUDE]],
        "reference_t": [_stamp(m) for m in reference],
        "reference": np.reshape([_xyz(m.twist.linear) + [m.twist.angular.z] for m in reference], (-1, 4)),
        "command_t": [_stamp(m) for m in heard[topics.COMMAND]],
        "command": np.reshape([list(m.pitch) for m in heard[topics.COMMAND]], (-1, 4)),
        "applied_t": [_stamp(m) for m in heard[topics.APPLIED]],
        "applied": np.reshape([list(m.pitch) for m in heard[topics.APPLIED]], (-1, 4)),
    }


def result_from_bag(bag_dir: str | Path, spec: RunSpec) -> RunResult:
    """The :class:`RunResult` of ``spec`` read back from the bag its graph run recorded (its metrics
    recomputed from the bag)."""
    result = RunResult(spec, series_from_logs(spec, logs_from_bag(bag_dir)), transport=BAG_TRANSPORT)
    result.metrics = compute(result)
    return result
