"""``./seapup demo``: the mission -- the thesis's supervisory hierarchy (sec. 4.2, fig. 4.3) flying the Seapup.

Starts the whole graph (``seapup_bringup/launch/hierarchy.launch.yaml`` in lockstep,
faster than real time, every node its own process, plus the recorder) with
:class:`seapup_bringup.sil.SilGraph`, then flies, through ROS only:

1. the self-test (sec. 4.5.2) through its action; both velocity controllers
   are configured from its result and the fixed-gain one is activated;
2. hover, swapping the velocity controller (fixed gain -> gain scheduled)
   half way through;
3. a goto of ~10 m with a 90 deg heading change;
4. the inspection manoeuvre (sec. 5.4.2: body velocities 0.2, 0.1, 0.1 m/s,
   "a diagonal creeping motion"), as a goto along that diagonal at its speed;
5. seabed following at a set height up the slope;
6. station keeping in the thesis's 0.26 m/s Gauss-Markov current (sec. 3.9);
7. a fouled thruster (sec. 7.4.4): on an inspection creep the main-port thruster's
   efficiency is halved under the self-tested gains, then the controller manager
   switches to a self-tuner of ch. 7 (GMV), which re-tunes while the creep goes on;
   the leg reports the velocity-tracking RMS (truth against the reference) before
   the fouling, fouled under the fixed gains, and under the self-tuner after it
   tuned in.

Everything is recorded to an MCAP bag (``<out>/bag``); the demo prints a table
per leg (duration, tracking errors, position-hold RMS and max from the truth,
thruster saturation, the swap's command step), writes PNG plots next to the
bag, the numbers as JSON (``summary.json``, ``--json``) and ``index.html``: one page with the legs
(units, pass criteria and verdicts), the plots, the seed and the configuration flown.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

import numpy as np
import yaml

from seapup_bringup.output import add_json_argument, emit_json, progress, stopped_by_signal, text_stream
from seapup_common import topics
from seapup_runs.actuators import THRASH_ALLOWANCE_S
from seapup_runs.mission_metrics import NAVIGATION_SIGMAS, leg_numbers, swap_bump

__all__ = ["MISSION", "main", "fly_mission"]

#: The graph's arguments and the mission (seapup_bringup/config/mission.yaml).
MISSION = "mission.yaml"
#: The graph a mission is flown on (its ``graph`` section: this launch document's arguments).
GRAPH = "seapup_bringup hierarchy.launch.yaml"

#: What the demo's bag holds. Every per-sample topic is typed, so the recorder subscribes before the graph
#: starts and is an extra listener of the graph's lockstep roster: the simulator's first sample waits for it
#: as for the graph's own readers, and the bag holds every sample from t_0 on (docs/recording.md).
#: ``/tf_static`` is untyped: the recorder then matches its publisher's latched QoS and gets the fixed frames
#: sent before it subscribed; ``/tf`` (odom -> base_link) makes the bag show an upright vehicle in any ROS viewer.
RECORDED = [topics.TF_STATIC] + topics.typed(
    topics.CLOCK, topics.TF, topics.COMMAND, topics.APPLIED, topics.TRUTH_ODOMETRY, topics.VELOCITY, topics.IMU,
    topics.DEPTH, topics.POSITION, topics.ALTITUDE, topics.NAVIGATION_ODOMETRY, topics.VELOCITY_REFERENCE,
    topics.POSITION_REFERENCE, topics.SELF_TEST_SAMPLES, topics.DIAGNOSTICS)


def mission_path() -> Path:
    """The shipped mission: ``seapup_bringup/config/mission.yaml`` as installed."""
    from ament_index_python.packages import get_package_share_directory
    return Path(get_package_share_directory("seapup_bringup")) / "config" / MISSION


def mission_config(path: Path | None = None) -> dict:
    """A mission document (default the shipped one), checked strictly (:mod:`seapup_runs.mission`), its
    graph arguments among those the hierarchy's launch document declares.

    Raises
    ------
    MissionError
        The first thing wrong, in one line naming the file.
    """
    from seapup_common.ros.launch_graph import find_graph, graph_arguments, load_graph
    from seapup_runs.mission import MissionError, load_mission
    path = path or mission_path()
    config = load_mission(path).to_dict()
    graph = find_graph(*GRAPH.split())
    declared = graph_arguments(graph)
    unknown = sorted(set(config["graph"]) - set(declared))
    if unknown:
        raise MissionError(f"{path}: graph argument {unknown[0]!r} is not one of {GRAPH}'s: "
                           f"{', '.join(sorted(declared))}")
    controllers = sorted(n.name for n in load_graph(graph) if n.executable == "velocity_controller")
    for leg in config["mission"]:
        request = leg.get("switch", {})
        request = request.get("request", request)   # a hover's switch has its request inside
        named = [*leg.get("configure", []), *([leg["activate"]] if "activate" in leg else []),
                 *request.get("activate", []), *request.get("deactivate", [])]
        strangers = [name for name in named if name not in controllers]
        if strangers:
            raise MissionError(f"{path}: leg {leg['name']!r} names {strangers[0]!r}, not a velocity controller of "
                               f"{GRAPH} ({', '.join(controllers)})")
    return config


def _set_parameter(sil, node: str, name: str, value: str) -> None:
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    parameter = Parameter(name=name, value=ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value))
    response = sil.call(f"{topics.NAMESPACE}/{node}/set_parameters", "rcl_interfaces/srv/SetParameters", {"parameters": [parameter]})
    if not response.results[0].successful:
        raise RuntimeError(f"{node}: {name} refused: {response.results[0].reason}")


def fly_mission(out: Path, config: dict, text, extra_nodes=()) -> dict:
    """Fly the mission in a SIL graph (with ``extra_nodes``: the live view); the per-leg numbers (and the logs
    as arrays under ``logs``)."""
    from seapup_bringup.sil import SilGraph
    from seapup_sim.seabed import Seabed

    graph = config["graph"]
    seabed = Seabed(graph.get("seabed_kind", "flat"), float(graph.get("seabed_depth", 100.0)),
                    float(graph.get("seabed_gradient", 0.0)), float(graph.get("seabed_direction", 0.0)))
    legs, swap = [], {}
    plan = config["mission"]
    total = sum(leg.get("expected", 60.0) for leg in plan)
    done = 0.0
    stopped = None  # the signal that ended the mission early (Ctrl-C, SIGTERM, SIGHUP)
    logs, bag, held = {}, out / "bag", None
    try:
        with SilGraph(GRAPH, arguments=graph, out_dir=out, record=RECORDED, ready_status="", start_at=0.0,
                      extra_nodes=extra_nodes) as sil:
            print(f"seapup demo: ROS domain {sil.env['ROS_DOMAIN_ID']} (loopback only), output in {out}", file=text)
            for leg in plan:
                start, wall = sil.t, time.monotonic()
                progress(f"{leg['name']:<18}", done / total)
                try:
                    numbers = _fly_leg(sil, leg, swap)
                except BaseException as exc:  # interrupted: the legs flown so far still get their numbers
                    if not stopped_by_signal(exc):
                        raise
                    stopped = exc
                    print(f"\nseapup demo: interrupted in leg {leg['name']}; reporting the {len(legs)} legs flown",
                          file=text)
                    break
                numbers.setdefault("t0", start)
                numbers.setdefault("t1", sil.t)
                done += leg.get("expected", 60.0)
                legs.append({"name": leg["name"], "kind": leg["kind"], "goal": leg.get("goal", {}),
                             "hold_from": float(leg.get("hold_from", 0.0)),
                             "wall_s": time.monotonic() - wall, **numbers})
                print(f"seapup demo: {leg['name']}: {numbers.get('status', 'done')} in "
                      f"{numbers['t1'] - numbers['t0']:.1f} s simulated ({time.monotonic() - wall:.1f} s wall)",
                      file=text)
            if stopped is None:
                progress("mission", 1.0)
            logs = sil.logs()
            bag, held = sil.bag, sil.held
    except BaseException as exc:  # interrupted while the graph started or stopped: nothing (more) flown
        if stopped is not None or not stopped_by_signal(exc):
            raise
        stopped = exc
        print(f"\nseapup demo: interrupted; reporting the {len(legs)} legs flown", file=text)
    for leg in legs:
        leg.update(leg_numbers(logs, leg, seabed))
    if swap and swap["leg"] < len(legs):
        legs[swap["leg"]].update(swap_bump(logs, swap["t"]))
    for leg in legs:
        if leg["kind"] == "fouling" and "switch_t" in leg:
            leg.update(swap_bump(logs, leg["switch_t"]))
    # held: the sample [s] the paced graph was held at when it stopped
    return {"legs": legs, "bag": str(bag), "held": held, "logs": logs, "stopped": stopped}


def _set_current(sil, detail: dict) -> None:
    """The simulator's current (``seapup_msgs/srv/SetCurrent`` fields), or why not."""
    reply = sil.call(topics.SET_CURRENT_SERVICE, "seapup_msgs/srv/SetCurrent", detail)
    if not reply.success:
        raise RuntimeError(f"set_current: {reply.message}")


def _fly_fouling(sil, leg: dict, swap: dict) -> dict:
    """The fouled-thruster leg: an inspection creep whose thruster fouls ``foul.after`` s in under the active
    (self-tested) controller, then, held at its end, the switch to the self-tuner and a second creep."""
    marks = {}
    if "current" in leg:   # the station keeping's current off: the fouling, not the current, is the test
        _set_current(sil, leg["current"])

    def foul():
        marks["foul_t"] = sil.t
        reply = sil.call(topics.SET_THRUSTER_EFFICIENCY_SERVICE, "seapup_msgs/srv/SetThrusterEfficiency",
                         {"efficiency": [float(v) for v in leg["foul"]["efficiency"]]})
        if not reply.success:
            raise RuntimeError(f"set_thruster_efficiency: {reply.message}")
        return reply
    creep = {"kind": "inspection", "name": leg["name"], "body_velocity": leg["body_velocity"],
             "index": leg["index"]}
    fixed = _fly_leg(sil, {**creep, "seconds": leg["fouled_seconds"]}, swap, during=(leg["foul"]["after"], foul))
    marks["switch_t"] = sil.t
    reply = sil.switch(**leg["switch"])
    if not reply.ok:
        raise RuntimeError(f"{leg['name']}: switch refused: {reply.message}")
    adaptive = _fly_leg(sil, {**creep, "seconds": leg["adaptive_seconds"]}, swap)
    status = "succeeded" if fixed.get("status") == adaptive.get("status") == "succeeded" else \
        adaptive.get("status") if fixed.get("status") == "succeeded" else fixed.get("status")
    return {**adaptive, "status": status, "t0": fixed["t0"], "t1": adaptive["t1"], **marks,
            "controller": leg["switch"]["activate"][0], "tune_in": float(leg.get("tune_in", 0.0))}


def _fly_leg(sil, leg: dict, swap: dict, during: tuple | None = None) -> dict:
    kind = leg["kind"]
    if kind == "fouling":
        return _fly_fouling(sil, leg, swap)
    if kind == "self_test":
        t0 = sil.t
        fields = {k: [float(x) for x in v] if isinstance(v, list) else v for k, v in leg.get("goal", {}).items()}
        result = sil.action(topics.SELF_TEST_ACTION, "seapup_msgs/action/SelfTest", fields)
        t1 = sil.t
        if not result.success:
            raise RuntimeError(f"self-test failed: {result.message}")
        for node in leg["configure"]:
            _set_parameter(sil, node, "controller_file", result.controller_file)
        reply = sil.switch(activate=[leg["activate"]])
        if not reply.ok:
            raise RuntimeError(f"activating {leg['activate']}: {reply.message}")
        return {"status": "succeeded", "t0": t0, "t1": t1, "controller_file": result.controller_file,
                "self_test_duration": result.duration}
    if kind == "current":
        _set_current(sil, leg["current"])
        kind = "hover"
    _, here, attitude = sil.estimate()
    yaw = float(attitude[2])
    goal = dict(leg.get("goal", {}))
    target = None
    if kind == "inspection":
        body = np.asarray(leg["body_velocity"], dtype=float)
        c, s = math.cos(yaw), math.sin(yaw)
        target = here + np.array([c * body[0] - s * body[1], s * body[0] + c * body[1], body[2]]) * leg["seconds"]
        goal = {"x": target[0], "y": target[1], "z": target[2], "yaw": yaw,
                "speed": float(np.linalg.norm(body)), "tolerance": 0.5}
        kind = "goto"
    elif "face" in leg:  # hold where it is, turned to this heading (e.g. into the current)
        goal.update(hold_current=False, x=here[0], y=here[1], z=here[2], yaw=float(leg["face"]))
    elif "offset" in leg:
        target = here + np.asarray(leg["offset"], dtype=float)
        goal.update(x=target[0], y=target[1], z=target[2], yaw=float(yaw + leg.get("turn", 0.0)))
    if "switch" in leg:
        def do_switch():
            swap["t"] = sil.t
            return sil.switch(**leg["switch"]["request"])
        during = (leg["switch"]["after"], do_switch)
    result = sil.goal(kind, timeout=600.0, during=during, **{k: float(v) if not isinstance(v, bool) else v
                                                             for k, v in goal.items()})
    if not result["accepted"]:
        raise RuntimeError(f"{leg['name']}: goal rejected: {result['rejection']}")
    if "switch" in leg:
        swap["leg"] = leg["index"]
        result["switch_ok"] = bool(result["during"].ok)
    out = {k: v for k, v in result.items() if k not in ("during", "accepted_t", "end_t")}
    out.update(t0=result["accepted_t"], t1=result["end_t"])
    if target is not None:
        out["target"] = [float(v) for v in target]
        out["tolerance"] = float(goal.get("tolerance", 0.5))  # the task controller's default arrival radius
    return out


def _task_error(leg: dict) -> str:
    """The task's own measure of how well it went (from the navigation estimate)."""
    if leg["kind"] in ("goto", "inspection", "fouling"):
        return f"end {leg['distance']:.2f} m, xt {leg['cross_track_rms']:.2f} m"
    if leg["kind"] == "follow_seabed":
        return f"alt rms {leg['altitude_rms']:.2f} m"
    if leg["kind"] in ("hover", "current"):
        return f"rms {leg['horizontal_rms']:.2f} m"
    return ""


def _truth_error(leg: dict) -> str:
    """The same from the simulator's truth."""
    if "track_fouled" in leg:
        return (f"v err {leg['track_before']:.3f}/{leg['track_fouled']:.3f}/"
                f"{leg.get('track_adaptive', math.nan):.3f} m/s")
    if "hold_rms" in leg:
        return f"rms {leg['hold_rms']:.2f}, max {leg['hold_max']:.2f} m"
    if "altitude_true_rms" in leg:
        return f"alt rms {leg['altitude_true_rms']:.2f}, max {leg['altitude_true_max']:.2f} m"
    if "end_error_true" in leg:
        return f"end {leg['end_error_true']:.2f} m"
    return ""


def _thrash(leg: dict) -> str:
    """The table's thrash column: the longest thrashing [s], '!' when the leg thrashed."""
    return f"{leg.get('thrash_s', 0.0):.1f}{' !' if leg.get('thrashed') else ''}"


def _marked(leg: dict) -> str:
    """The page's note on a leg marked for its actuators ("" for none)."""
    from seapup_bringup.pages import esc
    verdict = leg.get("actuator_verdict")
    return f"<div class=reason>marked: {esc(verdict)}</div>" if verdict else ""


def _table(legs: list, text) -> None:
    head = (f"{'leg':<20}{'status':<11}{'sim s':>7}{'wall s':>7}  {'task (navigation)':<24}{'truth':<26}"
            f"{'nav err (std)':>15}{'sat %':>6}{'thrash s':>9}{'swap step':>16}")
    print(head, file=text)
    print("-" * len(head), file=text)
    for leg in legs:
        swap = leg.get("switch_step_deg", math.nan)
        swap = "" if math.isnan(swap) else f"{swap:.2f} ({leg['normal_step_deg']:.2f}) deg"
        nav = f"{leg['nav_error']:.2f} ({leg['nav_std']:.2f}){' !' if leg.get('truth_verdict') else ''}" \
            if "nav_error" in leg else ""
        print(f"{leg['name']:<20}{leg.get('status', ''):<11}{leg['duration']:>7.1f}{leg['wall_s']:>7.1f}  "
              f"{_task_error(leg):<24}{_truth_error(leg):<26}{nav:>15}{leg['saturation_pct']:>6.1f}"
              f"{_thrash(leg):>9}{swap:>16}",
              file=text)
    print("truth: hold and altitude errors from hold_from s into the leg (config/mission.yaml: after braking from "
          "the previous leg, or reaching the altitude); nav err (std): the estimate's horizontal distance from the "
          f"truth at the leg's end (the navigator's stated std; '!': over {NAVIGATION_SIGMAS:g} std, or a target "
          "missed by more than tolerance + that); thrash s: the longest stretch of blade pitches swinging between "
          f"their limits ('!': longer than the thesis's commissioning, {THRASH_ALLOWANCE_S:g} s, sec. 7.6.1); swap "
          "step: blade-pitch change into the incoming controller's first command (largest one-sample change in the "
          "15 s before it); "
          "v err: the fouled-thruster leg's velocity-tracking RMS from the truth before the fouling / fouled under "
          "the fixed gains / under the self-tuner once tuned in", file=text)


def _plots(result: dict, out: Path) -> list[str]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    logs = result["logs"]
    paths = []
    fig, (top, side) = plt.subplots(1, 2, figsize=(12, 5))
    top.plot(logs["truth_position"][:, 1], logs["truth_position"][:, 0], label="truth")
    top.plot(logs["estimate_position"][:, 1], logs["estimate_position"][:, 0], lw=0.6, label="navigation")
    top.plot(logs["setpoint"][:, 1], logs["setpoint"][:, 0], "--", lw=0.8, label="setpoint")
    top.set_xlabel("east y [m]"), top.set_ylabel("north x [m]"), top.set_aspect("equal"), top.legend()
    top.set_title("top view (odom_ned)")
    side.plot(logs["truth_t"], logs["truth_position"][:, 2], label="depth (truth)")
    side.plot(logs["setpoint_t"], logs["setpoint"][:, 2], "--", lw=0.8, label="depth setpoint")
    side.invert_yaxis(), side.set_xlabel("t [s]"), side.set_ylabel("depth [m]"), side.legend()
    for leg in result["legs"]:
        side.axvline(leg["t0"], color="grey", lw=0.5)
        side.text(leg["t0"], side.get_ylim()[1], leg["name"], rotation=90, fontsize=7, va="top")
    fig.tight_layout()
    paths.append(out / "mission_path.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)
    fig, axes = plt.subplots(4, 1, figsize=(12, 9), sharex=True)
    names = ["u [m/s]", "v [m/s]", "w [m/s]", "r [rad/s]"]
    columns = [0, 1, 2, 5]
    for ax, name, col, ref in zip(axes, names, columns, range(4)):
        ax.plot(logs["truth_t"], logs["truth_velocity"][:, col], lw=0.8, label="truth")
        ax.plot(logs["reference_t"], logs["reference"][:, ref], lw=0.8, label="reference")
        ax.set_ylabel(name)
    axes[0].legend(), axes[-1].set_xlabel("t [s]")
    fig.tight_layout()
    paths.append(out / "mission_velocities.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(12, 4))
    for i, name in enumerate(["main port", "main starboard", "vectored starboard", "vectored port"]):
        ax.plot(logs["command_t"], np.degrees(logs["command"][:, i]), lw=0.7, label=name)
    ax.set_xlabel("t [s]"), ax.set_ylabel("blade pitch [deg]"), ax.legend(ncol=4)
    fig.tight_layout()
    paths.append(out / "mission_blade_pitch.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)
    return [str(p) for p in paths]


#: What a leg must do to pass (the index page says it beside each leg).
PASS_CRITERIA = (f"the task succeeded by its own (navigation) measure, and in truth: the estimate within "
                 f"{NAVIGATION_SIGMAS:g} x its stated standard deviation of the vehicle at the leg's end, and a leg "
                 f"with a target ended within its tolerance + that")


def _passed(leg: dict) -> bool:
    return leg.get("status") == "succeeded" and not leg.get("truth_verdict")


def index_page(summary: dict, config: dict, out: Path) -> Path:
    """``out/index.html``: the legs (units, pass criteria, verdicts), the plots, the seed and configuration."""
    from seapup_bringup.pages import CSS, esc, figure, fmt
    rows = []
    for leg in summary["legs"]:
        swap = leg.get("switch_step_deg")
        passed = _passed(leg)
        rows.append(
            f'<tr class="row-{"passed" if passed else "failed"}" data-leg="{esc(leg["name"])}" '
            f'data-status="{"passed" if passed else "failed"}">'
            f'<td>{esc(leg["name"])}</td><td>{esc(leg["kind"])}</td><td>{esc(leg.get("status", ""))}</td>'
            f'<td class=num>{fmt(leg.get("duration"))}</td><td class=num>{fmt(leg.get("wall_s"))}</td>'
            f'<td>{esc(_task_error(leg))}</td><td>{esc(_truth_error(leg))}</td>'
            f'<td class=num>{fmt(leg.get("nav_error"))} ({fmt(leg.get("nav_std"))})</td>'
            f'<td class=num>{fmt(leg.get("saturation_pct"))}</td>'
            f'<td class=num data-thrashed="{str(bool(leg.get("thrashed"))).lower()}">{esc(_thrash(leg))}</td>'
            f'<td class=num>{"" if swap is None or swap != swap else fmt(swap) + " (" + fmt(leg.get("normal_step_deg")) + ")"}</td>'
            f'<td class=status>{"passed" if passed else "failed"}'
            f'{"<div class=reason>" + esc(leg["truth_verdict"]) + "</div>" if leg.get("truth_verdict") else ""}'
            f'{_marked(leg)}'
            '</td></tr>')
    plots = "".join(figure(path, caption, wide=True) for path, caption in zip(
        summary.get("plots", []), ("top view and depth: truth, navigation estimate, setpoint; legs marked",
                                   "body velocities: truth and the velocity controller's reference",
                                   "blade-pitch commands of the four thrusters")))
    graph = "".join(f"<tr><td><code>{esc(k)}</code></td><td>{esc(v)}</td></tr>" for k, v in config["graph"].items())
    page = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>seapup demo: the mission</title><style>{CSS}</style></head>
<body><h1>seapup demo: the Seapup flies a mission through the supervisory hierarchy</h1>
<p class=muted>Self-tested through ROS, then flown leg by leg in lockstep (thesis sec. 4.2, fig. 4.3); seed
{esc(config["graph"].get("seed", 0))}; held at {fmt(summary.get("held"))} s simulated after
{fmt(summary.get("wall_s"))} s wall; bag <code>{esc(summary.get("bag", ""))}</code>.</p>
<section id="legs"><h2>The legs</h2>
<p>A leg passes when {esc(PASS_CRITERIA)}.</p>
<table><thead><tr><th>leg</th><th>kind</th><th>task verdict</th><th>simulated [s]</th><th>wall [s]</th>
<th>task error (navigation) [m]</th><th>truth error [m]</th><th>navigation error (stated std) [m]</th>
<th>saturated [% of samples]</th><th>thrashing [s]</th><th>swap step (largest before) [deg]</th>
<th>passed</th></tr></thead>
<tbody>{"".join(rows)}</tbody></table>
<p class=reason>Truth errors count from each leg's <code>hold_from</code> (after braking from the previous leg or
reaching the altitude); the swap step is the blade-pitch change into the incoming controller's first command, beside
the largest one-sample change in the 15 s before it. Thrashing is the longest stretch of blade pitches swinging between
their limits (one-sample changes of at least the limit, each within {THRASH_ALLOWANCE_S:g} s of the last); a leg that
thrashed longer than the thesis's self-tuner did while commissioning ({THRASH_ALLOWANCE_S:g} s, sec. 7.6.1) is marked,
not failed. The fouled-thruster leg's
truth column is its velocity-tracking RMS [m/s] (truth against the reference): before the fouling / fouled under the
self-tested gains / under the self-tuner from <code>tune_in</code> s after the switch.</p></section>
<section id="plots"><h2>Plots</h2>{plots or "<p class=muted>no plots (--no-plots)</p>"}</section>
<section id="configuration"><h2>Configuration</h2>
<p>The graph's arguments (<code>seapup_bringup/launch/hierarchy.launch.yaml</code>, from
<code>{esc(config.get("source", "seapup_bringup/config/mission.yaml"))}</code>):</p><table><tbody>{graph}</tbody></table>
<p>The mission:</p><pre>{esc(yaml.safe_dump(config["mission"], sort_keys=False))}</pre></section>
</body></html>
"""
    path = out / "index.html"
    path.write_text(page)
    return path


def demo_parser() -> argparse.ArgumentParser:
    """The parser of ``./seapup demo`` (its usage line in ``./seapup help`` is generated from it)."""
    from seapup_bringup.view import add_view_arguments
    parser = argparse.ArgumentParser(prog="./seapup demo", description=__doc__.splitlines()[0])
    parser.add_argument("--out", help="output directory: the bag (OUT/bag), plots, summary.json and node logs "
                                      "(default bags/demo_<UTC time> under the checkout)")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    parser.add_argument("--mission", type=Path, help="a mission file to fly instead of the shipped one "
                                                     "(seapup_bringup/config/mission.yaml; keys: docs/missions.md)")
    add_view_arguments(parser, "fly at this many times real time (the lockstep graph paced; default: as fast as "
                               "it answers, or 1 with --view); the summary is the same at any rate")
    add_json_argument(parser)
    return parser


def main(argv=None) -> int:
    from seapup_bringup.view import check_port, view_node, view_url
    parser = demo_parser()
    args = parser.parse_args(argv)
    rate = args.rate if args.rate is not None else (1.0 if args.view else 0.0)
    if not (rate >= 0 and rate < 1e4):
        parser.error(f"--rate must be >= 0 (0: unpaced) and < 10000, got {args.rate}")
    if args.view:
        try:
            check_port(args.view_port)
        except ValueError as exc:
            parser.error(str(exc))
    text = text_stream(args)
    root = Path(os.environ.get("SEAPUP_ROOT", "."))
    out = Path(args.out) if args.out else root / "bags" / time.strftime("demo_%Y%m%d_%H%M%S", time.gmtime())
    from seapup_runs.mission import MissionError
    try:
        config = mission_config(args.mission)
    except MissionError as exc:
        parser.error(str(exc))
    config["source"] = str(args.mission) if args.mission else "seapup_bringup/config/mission.yaml"
    for index, leg in enumerate(config["mission"]):
        leg["index"] = index
    if rate:
        config["graph"]["lockstep_pace"] = rate
    extra = [view_node(args.view_port)] if args.view else []
    if args.view:
        print(f"seapup demo: live view at {view_url(args.view_port)}", file=text)
    wall = time.monotonic()
    try:
        result = fly_mission(out, config, text, extra)
    except Exception as exc:  # a failed leg or graph: say which, point at the logs
        if stopped_by_signal(exc):
            raise
        print(f"seapup demo: failed: {exc}; node logs in {out}", file=text)
        return 1
    _table(result["legs"], text)
    if not args.no_plots and result["legs"]:
        result["plots"] = _plots(result, out)
        print(f"seapup demo: plots {', '.join(Path(p).name for p in result['plots'])} in {out}", file=text)
    result["wall_s"] = time.monotonic() - wall
    print(f"seapup demo: bag {result['bag']}; {result['wall_s']:.0f} s wall", file=text)
    stopped = result.pop("stopped")
    summary = {k: v for k, v in result.items() if k != "logs"}
    summary["interrupted"] = stopped is not None
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float))
    print(f"seapup demo: see {index_page(summary, config, out)}", file=text)
    emit_json(args, summary)
    if stopped is not None:
        raise stopped  # ./seapup: "interrupted", exit 128 + the signal
    failed = [leg["name"] for leg in result["legs"] if leg.get("status") not in ("succeeded", None)]
    if failed:
        print(f"seapup demo: legs that did not succeed: {', '.join(failed)}", file=text)
    thrashed = [f"{leg['name']}: {leg['actuator_verdict']}" for leg in result["legs"] if leg.get("actuator_verdict")]
    if thrashed:  # marked, not failed: the task was done, the thrusters paid for it
        print("seapup demo: legs marked for their actuators: " + "; ".join(thrashed), file=text)
    doubted = [f"{leg['name']}: {leg['truth_verdict']}" for leg in result["legs"] if leg.get("truth_verdict")]
    if doubted:  # the task judged by its estimate; the truth says otherwise
        print("seapup demo: legs whose verdict the truth contradicts: " + "; ".join(doubted), file=text)
    return 1 if failed or doubted else 0


if __name__ == "__main__":
    raise SystemExit(main())
