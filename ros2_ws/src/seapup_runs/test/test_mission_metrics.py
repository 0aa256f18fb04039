"""A mission leg's numbers from synthetic logs whose answers are known in closed form (seapup_runs.mission_metrics)."""
import math

import numpy as np
import pytest

from seapup_runs.mission_metrics import (NAVIGATION_SIGMAS, actuator_verdict, leg_numbers, swap_bump,
                                         velocity_tracking)

T = 0.2


def logs(n=301, truth=None, setpoint=(0.0, 0.0, 30.0, 0.0), command=None, velocity=None, reference=None,
         estimate_error=(0.0, 0.0), std=0.5):
    """``n`` samples from t = 0 every T: a vehicle at ``truth`` (callable t -> xyz), estimate off by
    ``estimate_error``."""
    t = np.arange(n) * T
    position = np.array([truth(x) for x in t]) if truth else np.tile([0.0, 0.0, 30.0], (n, 1))
    return {"command_t": t, "command": np.zeros((n, 4)) if command is None else command,
            "truth_t": t, "truth_position": position,
            "truth_velocity": np.zeros((n, 6)) if velocity is None else velocity,
            "setpoint_t": t, "setpoint": np.tile(setpoint, (n, 1)),
            "reference_t": t, "reference": np.zeros((n, 4)) if reference is None else reference,
            "estimate_t": t, "estimate_position": position + [*estimate_error, 0.0],
            "estimate_horizontal_std": np.full(n, std)}


def test_a_hover_held_off_its_point_by_a_known_circle():
    """Truth on a circle of 0.3 m about the setpoint, 0.1 m deep of it: hold RMS and max 0.3 m, depth RMS 0.1
    m -- from hold_from on (before it, 5 m off: braking, not counted)."""
    def truth(t):
        r = 0.3 if t >= 10.0 else 5.0
        return [r * math.cos(t), r * math.sin(t), 30.1]
    out = leg_numbers(logs(truth=truth), {"kind": "hover", "t0": 0.0, "t1": 60.0, "hold_from": 10.0}, None)
    assert out["hold_rms"] == pytest.approx(0.3) and out["hold_max"] == pytest.approx(0.3)
    assert out["depth_rms"] == pytest.approx(0.1) and out["duration"] == 60.0
    assert out["truth_verdict"] == "" and out["nav_error"] == 0.0 and not out["thrashed"]


def test_following_a_sloping_seabed_at_a_known_altitude_error():
    """Seabed 40 m deep falling 1 in 10 eastwards; the vehicle 10.2 m above it: altitude error 0.2 m throughout."""
    seabed = lambda x, y: 40.0 + 0.1 * y  # noqa: E731 - a depth field
    truth = lambda t: [0.0, t, 40.0 + 0.1 * t - 10.2]  # noqa: E731
    leg = {"kind": "follow_seabed", "t0": 0.0, "t1": 60.0, "goal": {"altitude": 10.0}}
    out = leg_numbers(logs(truth=truth), leg, seabed)
    assert out["altitude_true_rms"] == pytest.approx(0.2) and out["altitude_true_max"] == pytest.approx(0.2)


def test_a_goto_ends_a_known_distance_from_its_target():
    leg = {"kind": "goto", "t0": 0.0, "t1": 20.0, "target": [3.0, 4.0, 30.0], "tolerance": 0.5}
    out = leg_numbers(logs(), leg, None)
    assert out["end_error_true"] == pytest.approx(5.0)
    assert "ended 5.00 m from the target in truth" in out["truth_verdict"]   # 5 > 0.5 + 4 x 0.5


def test_an_estimate_beyond_its_stated_uncertainty_contradicts_the_task():
    out = leg_numbers(logs(estimate_error=(3.0, 4.0), std=1.0), {"kind": "hover", "t0": 0.0, "t1": 60.0}, None)
    assert out["nav_error"] == pytest.approx(5.0) and "more than 4 x its stated 1.00 m" in out["truth_verdict"]
    near = leg_numbers(logs(estimate_error=(3.0, 4.0), std=5.0 / NAVIGATION_SIGMAS), {"kind": "hover", "t0": 0.0,
                                                                                     "t1": 60.0}, None)
    assert near["truth_verdict"] == ""   # exactly at the bound: believed


def test_fouling_tracking_windows_see_known_errors():
    """Reference 0.2 m/s surge throughout; the truth 0.2 before the fouling (t < 20), 0.1 fouled (to the switch
    at 40), 0.15 under the self-tuner until it tuned in (40 + 10) and 0.19 after: RMS 0, 0.1, 0.01."""
    n = 301
    t = np.arange(n) * T
    surge = np.where(t < 20, 0.2, np.where(t < 40, 0.1, np.where(t < 50, 0.15, 0.19)))
    velocity = np.zeros((n, 6))
    velocity[:, 0] = surge
    velocity[:, 5] = np.where(t < 20, 0.0, math.radians(2.0))   # a 2 deg/s yaw-rate error from the fouling on
    reference = np.tile([0.2, 0.0, 0.0, 0.0], (n, 1))
    leg = {"kind": "fouling", "t0": 0.0, "t1": 60.0, "foul_t": 20.0, "switch_t": 40.0, "tune_in": 10.0}
    out = velocity_tracking(logs(velocity=velocity, reference=reference), leg)
    assert out["track_before"] == pytest.approx(0.0, abs=1e-12)
    assert out["track_fouled"] == pytest.approx(0.1) and out["track_adaptive"] == pytest.approx(0.01)
    assert out["track_fouled_r_deg"] == pytest.approx(2.0) and out["track_before_r_deg"] == 0.0


def test_a_switch_bump_against_the_largest_step_before_it():
    n = 301
    t = np.arange(n) * T
    command = np.zeros((n, 4))
    command[:, 1] = np.radians(0.5) * np.sin(t)            # small steps before the switch at t = 40
    command[t > 40.0 + 1e-6, 1] += np.radians(10.0)         # the incoming law's first command: +10 deg
    out = swap_bump(logs(command=command), 40.0)
    assert out["switch_step_deg"] == pytest.approx(10.0, abs=0.2)
    assert out["normal_step_deg"] == pytest.approx(math.degrees(np.abs(np.diff(command[:, 1]))[
        (t[1:] > 25.0) & (t[1:] <= 40.0 + 1e-6)].max()))


def test_thrashing_is_named_with_the_thesis_allowance():
    n = 301
    command = np.zeros((n, 4))
    command[100:130, 0] = np.radians(35.0) * (-1.0) ** np.arange(30)   # swings from t = 20 (0 -> +35) to 26 (-35 -> 0)
    out = leg_numbers(logs(command=command), {"kind": "hover", "t0": 0.0, "t1": 60.0}, None)
    assert out["thrashed"] and out["thrash_s"] == pytest.approx(6.0)
    assert out["actuator_verdict"].startswith("blade pitches thrashed between their limits for 6.0 s from t = 20.0")
    assert "1.6 s, sec. 7.6.1" in out["actuator_verdict"]
    assert actuator_verdict({"thrashed": False}) == ""
