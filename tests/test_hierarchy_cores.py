"""The supervisory hierarchy's pure cores flown together in one process (seapup_bringup.hierarchy_in_process):
navigator -> task -> position controller -> self-tested MFOL controller -> simulated Seapup.

Independent truth: the simulator's true state and its seabed geometry (never seen by the
controllers, which fly on the baseline instruments: log, gyros, 0.5 m acoustic fix, altimeter).
The ROS graph flies the same cores (tests/test_hierarchy.py).
"""
import math

import numpy as np
import pytest

from seapup_bringup.hierarchy_in_process import fly_hierarchy
from seapup_common.controllers import ControllerSpec
from seapup_control.self_test import result_document
from seapup_runs.self_test_flight import fly_self_test
from seapup_control.tasks import FollowSeabed, Goto
from seapup_sim.seabed import Seabed

START = np.r_[0.0, 0.0, 32.0, np.zeros(9)]


@pytest.fixture(scope="module")
def schedule():
    """The controller the self-test leaves behind, scheduled over 0 and 0.7 m/s (sec. 4.6)."""
    run = fly_self_test("baseline", {"operating_points": [0.0, 0.7]})
    return ControllerSpec("mfol", {"schedule": True}, document=result_document(run.test))


SEABEDS = {
    "slope 1 in 5": {"kind": "slope", "depth": 40.0, "gradient": -0.2, "direction": 0.0},
    "ridge": {"kind": "polyline", "points": [[0, 40], [8, 40], [20, 37], [30, 37], [40, 39]], "direction": 0.0},
}


@pytest.mark.parametrize("speed", [0.1, 0.3])
@pytest.mark.parametrize("seabed", sorted(SEABEDS))
def test_seabed_following_holds_the_true_altitude_within_0_3_m(schedule, seabed, speed):
    """Up to the task's largest speed over a 1 in 5 slope and over a ridge with breaks of slope."""
    environment = {"sensors": "baseline", "seabed": SEABEDS[seabed]}
    run = fly_hierarchy(lambda limits, estimate, altitude: FollowSeabed(
        limits, estimate, altitude, height=8.0, yaw=0.0, speed=speed, duration=110.0),
        schedule, environment=environment, state=START, duration=200.0)
    assert run.steps[-1].success, run.steps[-1].message
    floor = Seabed.from_config(SEABEDS[seabed])
    x, y, z = run.state[:, :3].T
    error = np.array([floor(a, b) for a, b in zip(x, y)]) - z - 8.0
    flying = slice(len(run.t) - len(run.steps) + 50, None)  # after the first 10 s of the task
    assert np.abs(error[flying]).max() <= 0.3
    assert x[-1] == pytest.approx(speed * 110.0, rel=0.15)  # it kept the speed it was given


def test_a_goto_of_10_m_with_a_quarter_turn_arrives_within_tolerance(schedule):
    target = np.array([8.0, 6.0, 33.0])
    run = fly_hierarchy(lambda limits, estimate, altitude: Goto(limits, estimate, target, math.pi / 2),
                        schedule, environment={"sensors": "baseline"}, state=START, duration=200.0)
    last = run.steps[-1]
    assert last.success, last.message
    assert np.linalg.norm(run.state[-1, :3] - target) <= 0.5 + 0.3   # tolerance + the navigation's error
    assert abs(run.state[-1, 5] - math.pi / 2) <= math.radians(5)
    # the line: the truth stays near the straight line from start to target
    direction = (target - START[:3]) / np.linalg.norm(target - START[:3])
    offsets = run.state[:, :3] - START[:3]
    cross = np.linalg.norm(offsets - np.outer(offsets @ direction, direction), axis=1)
    assert cross.max() < 1.0
