"""The self-test (thesis sec. 4.5.2, 5.3) through the ROS graph: ``seapup_bringup/launch/self_test.launch.yaml``
(the simulator in lockstep and the ``self_test`` action server) in the SIL harness, recorded to a bag, this
process the action client (:func:`fly_self_test_graph`); and a recorded run refitted from its bag
(:func:`self_test_from_bag`). ``./seapup selftest`` (:mod:`seapup_bringup.verbs.autopilot_commands`) calls both.
"""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from seapup_bringup.output import progress
from seapup_common.topics import (APPLIED, CLOCK, COMMAND, DEPTH, IMU, SELF_TEST_ACTION, SELF_TEST_SAMPLES,
                                  TRUTH_ODOMETRY, VELOCITY, typed)
from seapup_control.self_test import SelfTestConfig
from seapup_sim.vehicle_config import ConfigError

__all__ = ["SelfTestFailed", "SELF_TEST_TOPICS", "fly_self_test_graph", "self_test_from_bag"]


class SelfTestFailed(RuntimeError):
    """A self-test or closed-loop analysis that cannot go on: the reason says why (and where the logs are)."""


#: What a self-test run records (typed: subscribed before the publishers exist).
SELF_TEST_TOPICS = (CLOCK, COMMAND, APPLIED, VELOCITY, IMU, DEPTH, TRUTH_ODOMETRY, SELF_TEST_SAMPLES)


def fly_self_test_graph(config: str, rate: float, speeds: list, out: Path, bag: Path, text) -> dict:
    """The self-test through the ROS graph in lockstep (``seapup_bringup/launch/self_test.launch.yaml``: simulator
    and self_test action server) in the SIL harness, recorded to ``bag``; this process is the action client.

    Raises
    ------
    SelfTestFailed
        If the goal is refused or the self-test does not succeed; the harness's SilError if the graph
        does not come up.
    """
    from seapup_bringup.graph.graph_runner import GraphSpec, fly_graph, send_goal
    from seapup_runs.spec import PHYSICS_STEP

    period = 1.0 / rate
    # the first sample, command and self-test sample wait for every reader of them -- the recorder and the
    # probe included (the lockstep roster the harness fills): nothing of the run is lost
    arguments = {"vehicle": config, "control_period": period, "physics_step": min(PHYSICS_STEP, period),
                 "start_depth": 50.0, "result_dir": str(out.resolve())}
    spec = GraphSpec("self-test", "seapup_bringup self_test.launch.yaml", arguments,
                     record=tuple(typed(*SELF_TEST_TOPICS)),
                     banner=f"self-test: {config}, {rate:g} Hz, operating points {speeds} m/s, through the ROS "
                            "graph (domain {domain}); output in {out}")
    flown = fly_graph(spec, out, send_goal(
        SELF_TEST_ACTION, "seapup_msgs/action/SelfTest", {"sample_period": period, "operating_points": speeds},
        feedback=lambda f: progress(f"{f.phase} c{f.cycle} t{f.thruster}", f.progress)), logs=False, text=text)
    result, bag_dir = flown.outcome, flown.bag
    if not result.success:
        raise SelfTestFailed(f"the self-test did not succeed: {result.message}; see {out}")
    if bag_dir != bag:
        shutil.move(str(bag_dir), str(bag))
    return {"result": result, "bag": bag}


def self_test_from_bag(bag_dir: Path, fit: str | None = None) -> dict:
    """Refit a recorded run from its /seapup/self_test/samples (each step fitted as ``fit`` says,
    :meth:`seapup_control.self_test.StepTest.column`; None: as the self-test settings say, as the node did)
    and measure its space from the truth."""
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message
    from seapup_msgs.msg import SelfTestSample

    from seapup_common.bag import read_bag
    from seapup_control.mfol import DesignError
    from seapup_control.self_test import refit, tests_from_samples
    from seapup_control.step_identification import IdentificationError
    records, positions, stamps = [], [], []
    for m in read_bag(bag_dir, [SELF_TEST_SAMPLES, TRUTH_ODOMETRY]):
        if m.topic == TRUTH_ODOMETRY:
            odometry = deserialize_message(m.cdr, Odometry)
            p, stamp = odometry.pose.pose.position, odometry.header.stamp
            positions.append((stamp.sec + stamp.nanosec * 1e-9, p.x, p.y, p.z))
            continue
        s = deserialize_message(m.cdr, SelfTestSample)
        t = s.header.stamp.sec + s.header.stamp.nanosec * 1e-9
        stamps.append(t)
        records.append({"t": t, "test_index": s.test_index, "cycle": s.cycle, "surge": s.surge,
                        "thruster": s.thruster, "step": s.step, "quiescent_input": list(s.quiescent_input),
                        "equilibrium": list(s.equilibrium), "velocity": list(s.velocity),
                        "sample_period": s.sample_period, "phase": s.phase})
    if not records:
        raise SelfTestFailed(f"{bag_dir} has no {SELF_TEST_SAMPLES}: not a self-test bag")
    last = max(records, key=lambda r: r["t"])
    if last["phase"] not in ("done", "failed", "cancelled"):
        raise SelfTestFailed(f"{bag_dir}: its self-test record ends at t = {last['t']:.3f} s in phase "
                             f"{last['phase']!r}: the recording stopped before the self-test ended")
    try:
        config = SelfTestConfig.load({"sample_period": records[0]["sample_period"]})
        points = refit(tests_from_samples(records, config.sample_period), config.sample_period, config.poles,
                       config.max_condition, fit or config.fit)
    except (ConfigError, IdentificationError, DesignError) as exc:
        raise SelfTestFailed(f"{bag_dir}: {exc}") from None
    # the box of water of the run itself: truth from its first to its last sample
    position = np.array([p[1:] for p in positions if min(stamps) - 1e-9 <= p[0] <= max(stamps) + 1e-9]
                        or [(0.0, 0.0, 0.0)])
    return {"points": points, "duration": max(stamps) - min(stamps),
            "space": position.max(axis=0) - position.min(axis=0)}
