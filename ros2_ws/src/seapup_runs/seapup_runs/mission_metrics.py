"""A mission leg's numbers from the flight's logs: pure (numpy), the same for a mission flown on the graph or in
process (``./seapup demo``'s table, page and ``summary.json``).

The logs are arrays by name (a harness's probe gives them, :meth:`seapup_bringup.graph.sil.SilGraph.logs`), times in
simulated seconds, one row per sample heard:

- ``command_t``, ``command`` (n, 4): the blade pitches commanded [rad];
- ``truth_t``, ``truth_position`` (n, 3) [m, odom_ned], ``truth_attitude`` (n, 3) [rad, roll, pitch, yaw in
  (-pi, pi]], ``truth_velocity`` (n, 6) [m/s, rad/s, base_link_frd]: the simulator's truth;
- ``setpoint_t``, ``setpoint`` (n, 4+): the position setpoint (x, y, z [m], yaw [rad]) in force;
- ``reference_t``, ``reference`` (n, 4): the velocity reference (u, v, w [m/s], r [rad/s]);
- ``estimate_t``, ``estimate_position`` (n, 3), ``estimate_horizontal_std`` (n,): the navigator's estimate
  and its stated horizontal standard deviation [m].

A leg is a mapping with its ``kind``, ``t0`` and ``t1`` (its goal's window, simulated [s]) and what its kind
adds (``hold_from``, ``goal``, ``target`` and ``tolerance``, ``foul_t``, ``switch_t``, ``tune_in``, ``take_t``,
``hand_back_t``;
:mod:`seapup_runs.mission`).
"""
from __future__ import annotations

import math

import numpy as np

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_runs.actuators import THRASH_ALLOWANCE_S, actuator_activity

__all__ = ["mission_numbers", "leg_numbers", "actuator_verdict", "velocity_tracking", "navigation_check", "swap_bump",
           "manual_handover", "NAVIGATION_SIGMAS"]


def mission_numbers(legs: list, logs: dict, seabed: dict, swap: dict, limit: float = BLADE_PITCH_LIMIT) -> list:
    """Every leg's numbers (:func:`leg_numbers`), the swap's bump on the leg that swapped (``swap``: its index
    ``leg`` and sample ``t``) and on a fouling leg's switch; ``seabed``: the simulator's seabed
    (:meth:`seapup_sim.seabed.Seabed.from_config`); ``limit``: the vehicle's input limit (the Seapup's blade
    pitch, a virtual-input vehicle's full scale). The legs, updated."""
    from seapup_sim.seabed import Seabed
    floor = Seabed.from_config(seabed)
    for leg in legs:
        leg.update(leg_numbers(logs, leg, floor, limit))
    if swap and swap["leg"] < len(legs):
        legs[swap["leg"]].update(swap_bump(logs, swap["t"]))
    for leg in legs:
        if leg["kind"] == "fouling" and "switch_t" in leg:
            leg.update(swap_bump(logs, leg["switch_t"]))
        if leg["kind"] == "manual" and "hand_back_t" in leg:
            leg.update(manual_handover(logs, leg))
    return legs


def leg_numbers(logs: dict, leg: dict, seabed, limit: float = BLADE_PITCH_LIMIT) -> dict:
    """Truth-based numbers of one leg over its goal's window: its actuator activity against the inputs'
    ``limit`` (:func:`seapup_runs.actuators.actuator_activity`), hold or altitude error."""
    t0, t1 = leg["t0"], leg["t1"]
    ct = logs["command_t"]
    flown = (ct >= t0) & (ct <= t1)
    out = {**actuator_activity(ct[flown], logs["command"][flown], limit), "duration": t1 - t0}
    out["actuator_verdict"] = actuator_verdict(out)
    t, truth = logs["truth_t"], logs["truth_position"]
    window = (t >= t0) & (t <= t1)
    if not window.any():
        return out
    if leg["kind"] in ("hover", "current", "manual"):
        start = leg.get("hand_back_t", t0) if leg["kind"] == "manual" else t0   # a manual leg holds after its hand-back
        st = logs["setpoint_t"]
        held = (st >= start) & (st <= t1)
        steady = window & (t >= start + leg.get("hold_from", 0.0))  # after braking from the previous leg's speed
        if held.any() and steady.any():  # the point held is the leg's last setpoint (the pose at acceptance)
            errors = truth[steady] - logs["setpoint"][held][-1, :3]
            horizontal = np.hypot(errors[:, 0], errors[:, 1])
            out.update(hold_rms=float(np.sqrt(np.mean(horizontal ** 2))), hold_max=float(horizontal.max()),
                       depth_rms=float(np.sqrt(np.mean(errors[:, 2] ** 2))))
    elif leg["kind"] == "follow_seabed":
        steady = window & (t >= t0 + leg.get("hold_from", 0.0))  # after climbing or descending to the altitude
        if steady.any():
            x, y, z = truth[steady].T
            error = np.array([seabed(a, b) for a, b in zip(x, y)]) - z - leg["goal"]["altitude"]
            out.update(altitude_true_rms=float(np.sqrt(np.mean(error ** 2))),
                       altitude_true_max=float(np.abs(error).max()))
    elif "target" in leg:
        out["end_error_true"] = float(np.linalg.norm(truth[window][-1] - leg["target"]))
    if leg["kind"] == "fouling":
        out.update(velocity_tracking(logs, leg))
    out.update(navigation_check(logs, leg, t[window][-1], truth[window][-1]))
    return out


def actuator_verdict(activity: dict) -> str:
    """"" for a leg whose blade pitches did not thrash (:mod:`seapup_runs.actuators`), else what they did."""
    if not activity["thrashed"]:
        return ""
    return (f"blade pitches thrashed between their limits for {activity['thrash_s']:.1f} s from t = "
            f"{activity['thrash_t']:.1f} s ({activity['swings_per_min']:.0f} swings/min; the thesis's commissioning "
            f"thrashed {THRASH_ALLOWANCE_S:g} s, sec. 7.6.1)")


def velocity_tracking(logs: dict, leg: dict) -> dict:
    """A fouling leg's velocity tracking: the RMS over samples of |(u, v, w) reference - truth| [m/s] and of the
    yaw-rate error [deg/s] before the fouling, fouled under the fixed gains, and under the self-tuner from
    ``tune_in`` s after the switch (its commissioning and first estimates) to the leg's end."""
    rt, ref = logs["reference_t"], logs["reference"]
    t, velocity = logs["truth_t"], logs["truth_velocity"]
    index = np.searchsorted(t, rt)
    ok = (index < len(t))
    ok[ok] = np.abs(t[index[ok]] - rt[ok]) < 1e-6       # the truth of the sample the reference is for
    out = {}
    windows = {"before": (leg["t0"] + leg.get("hold_from", 0.0), leg["foul_t"]),
               "fouled": (leg["foul_t"], leg["switch_t"]),
               "adaptive": (leg["switch_t"] + leg.get("tune_in", 0.0), leg["t1"])}
    for name, (a, b) in windows.items():
        keep = ok & (rt >= a) & (rt < b)
        if keep.any():
            error = ref[keep] - velocity[index[keep]][:, [0, 1, 2, 5]]
            out[f"track_{name}"] = float(np.sqrt(np.mean(np.sum(error[:, :3] ** 2, axis=1))))
            out[f"track_{name}_r_deg"] = math.degrees(float(np.sqrt(np.mean(error[:, 3] ** 2))))
    return out


#: How far [in the navigator's stated horizontal standard deviations] the estimate may be from the truth
#: before a leg's verdict, which the task controller can only take from the estimate, is not believed:
#: a 2-D Gaussian error exceeds 4 sigma with probability exp(-8) = 3e-4.
NAVIGATION_SIGMAS = 4.0


def navigation_check(logs: dict, leg: dict, t_end: float, truth_end) -> dict:
    """The leg's end in truth against the task's verdict: the navigation error then (``nav_error``) against
    the navigator's stated uncertainty (``nav_std``), and for a leg with a target its true end error
    against the tolerance plus that uncertainty. ``truth_verdict``: "" when they agree, else why not."""
    et, est = logs["estimate_t"], logs["estimate_position"]
    if not len(et):
        return {"truth_verdict": "no navigation estimate"}
    k = int(np.argmin(np.abs(et - t_end)))
    std = float(logs["estimate_horizontal_std"][k]) if len(logs.get("estimate_horizontal_std", ())) else math.nan
    error = float(np.hypot(*(est[k, :2] - truth_end[:2])))
    out = {"nav_error": error, "nav_std": std, "truth_verdict": ""}
    if error > NAVIGATION_SIGMAS * std:
        out["truth_verdict"] = (f"navigation {error:.2f} m from the truth, more than {NAVIGATION_SIGMAS:g} x its "
                                f"stated {std:.2f} m")
    if "target" in leg:
        limit = float(leg["tolerance"]) + NAVIGATION_SIGMAS * std
        end = float(np.linalg.norm(truth_end - np.asarray(leg["target"])))
        if end > limit:
            out["truth_verdict"] = f"ended {end:.2f} m from the target in truth (tolerance + navigation: {limit:.2f} m)"
    return out


def manual_handover(logs: dict, leg: dict) -> dict:
    """A manual leg's hand-overs (:func:`swap_bump` at each): the command change into the pilot's controller
    (``take_step_deg``) and back into the task's (``hand_back_step_deg``), the largest one-sample change in the
    15 s before each (``take_normal_deg``, ``hand_back_normal_deg``), and the truth's (u, v, w) and r when the
    pilot handed back (``hand_back_velocity``: what the task took over from)."""
    take, back = swap_bump(logs, leg["take_t"]), swap_bump(logs, leg["hand_back_t"])
    t = logs["truth_t"]
    at = np.flatnonzero(t <= leg["hand_back_t"] + 1e-6)
    velocity = logs["truth_velocity"][at[-1]] if len(at) else np.full(6, math.nan)
    return {"take_step_deg": take["switch_step_deg"], "take_normal_deg": take["normal_step_deg"],
            "hand_back_step_deg": back["switch_step_deg"], "hand_back_normal_deg": back["normal_step_deg"],
            "hand_back_velocity": [float(v) for v in (*velocity[:3], velocity[5])]}


def swap_bump(logs: dict, t_switch: float) -> dict:
    """The command change into the incoming controller's first command (the switch is made while the graph
    is held at sample ``t_switch``, answered by the outgoing one: the incoming one answers the next), and the
    largest one-sample change in the 15 s of flight before it [deg, largest over the thrusters]."""
    t, c = logs["command_t"], logs["command"]
    steps = np.abs(np.diff(c, axis=0)).max(axis=1)
    ts = t[1:]
    at = steps[ts > t_switch + 1e-6][:1]
    before = steps[(ts > t_switch - 15.0) & (ts <= t_switch + 1e-6)]
    return {"switch_step_deg": math.degrees(float(at.max())) if len(at) else math.nan,
            "normal_step_deg": math.degrees(float(before.max())) if len(before) else math.nan}
