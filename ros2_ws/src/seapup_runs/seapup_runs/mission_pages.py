"""A mission's results shown: the leg table printed, the plots and the index page (``./seapup demo``,
``./seapup fly MISSION``), for a mission flown on the graph or in process alike."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import yaml

from seapup_runs.actuators import THRASH_ALLOWANCE_S
from seapup_runs.mission_metrics import NAVIGATION_SIGMAS

__all__ = ["leg_table", "mission_plots", "index_page", "report_mission", "PASS_CRITERIA", "leg_passed"]


def task_error(leg: dict) -> str:
    """The task's own measure of how well it went (from the navigation estimate)."""
    if leg["kind"] in ("goto", "inspection", "fouling"):
        return f"end {leg['distance']:.2f} m, xt {leg['cross_track_rms']:.2f} m"
    if leg["kind"] == "follow_seabed":
        return f"alt rms {leg['altitude_rms']:.2f} m"
    if leg["kind"] in ("hover", "current", "manual"):   # a manual leg's: the hover after the hand-back
        return f"rms {leg['horizontal_rms']:.2f} m"
    return ""


def swap_step(leg: dict) -> tuple | None:
    """(blade-pitch change into the incoming controller's first command, the largest one-sample change in the
    15 s before it) [deg] of a leg's swap -- a manual leg's: its hand-back to the task's controller -- or None."""
    step, normal = ((leg.get("hand_back_step_deg"), leg.get("hand_back_normal_deg")) if leg["kind"] == "manual"
                    else (leg.get("switch_step_deg"), leg.get("normal_step_deg")))
    return None if step is None or math.isnan(step) else (step, normal)


def truth_error(leg: dict) -> str:
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


def thrash(leg: dict) -> str:
    """The table's thrash column: the longest thrashing [s], '!' when the leg thrashed."""
    return f"{leg.get('thrash_s', 0.0):.1f}{' !' if leg.get('thrashed') else ''}"


def marked(leg: dict) -> str:
    """The page's note on a leg marked for its actuators ("" for none)."""
    from seapup_runs.pages import esc
    verdict = leg.get("actuator_verdict")
    return f"<div class=reason>marked: {esc(verdict)}</div>" if verdict else ""


def leg_table(legs: list, text) -> None:
    head = (f"{'leg':<20}{'status':<11}{'sim s':>7}{'wall s':>7}  {'task (navigation)':<24}{'truth':<26}"
            f"{'nav err (std)':>15}{'sat %':>6}{'thrash s':>9}{'swap step':>16}")
    print(head, file=text)
    print("-" * len(head), file=text)
    for leg in legs:
        swap = swap_step(leg)
        swap = "" if swap is None else f"{swap[0]:.2f} ({swap[1]:.2f}) deg"
        nav = f"{leg['nav_error']:.2f} ({leg['nav_std']:.2f}){' !' if leg.get('truth_verdict') else ''}" \
            if "nav_error" in leg else ""
        print(f"{leg['name']:<20}{leg.get('status', ''):<11}{leg['duration']:>7.1f}{leg['wall_s']:>7.1f}  "
              f"{task_error(leg):<24}{truth_error(leg):<26}{nav:>15}{leg['saturation_pct']:>6.1f}"
              f"{thrash(leg):>9}{swap:>16}",
              file=text)
    print("truth: hold and altitude errors from hold_from s into the leg (config/mission.yaml: after braking from "
          "the previous leg, or reaching the altitude); nav err (std): the estimate's horizontal distance from the "
          f"truth at the leg's end (the navigator's stated std; '!': over {NAVIGATION_SIGMAS:g} std, or a target "
          "missed by more than tolerance + that); thrash s: the longest stretch of blade pitches swinging between "
          f"their limits ('!': longer than the thesis's commissioning, {THRASH_ALLOWANCE_S:g} s, sec. 7.6.1); swap "
          "step: blade-pitch change into the incoming controller's first command (largest one-sample change in the "
          "15 s before it; a manual leg's: the hand-back to the task's controller); "
          "v err: the fouled-thruster leg's velocity-tracking RMS from the truth before the fouling / fouled under "
          "the fixed gains / under the self-tuner once tuned in", file=text)


def mission_plots(result: dict, out: Path) -> list[str]:
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


def leg_passed(leg: dict) -> bool:
    return leg.get("status") == "succeeded" and not leg.get("truth_verdict")


def index_page(summary: dict, config: dict, out: Path) -> Path:
    """``out/index.html``: the legs (units, pass criteria, verdicts), the plots, the seed and configuration."""
    from seapup_runs.pages import CSS, esc, figure, fmt
    rows = []
    for leg in summary["legs"]:
        swap = swap_step(leg)
        passed = leg_passed(leg)
        rows.append(
            f'<tr class="row-{"passed" if passed else "failed"}" data-leg="{esc(leg["name"])}" '
            f'data-status="{"passed" if passed else "failed"}">'
            f'<td>{esc(leg["name"])}</td><td>{esc(leg["kind"])}</td><td>{esc(leg.get("status", ""))}</td>'
            f'<td class=num>{fmt(leg.get("duration"))}</td><td class=num>{fmt(leg.get("wall_s"))}</td>'
            f'<td>{esc(task_error(leg))}</td><td>{esc(truth_error(leg))}</td>'
            f'<td class=num>{fmt(leg.get("nav_error"))} ({fmt(leg.get("nav_std"))})</td>'
            f'<td class=num>{fmt(leg.get("saturation_pct"))}</td>'
            f'<td class=num data-thrashed="{str(bool(leg.get("thrashed"))).lower()}">{esc(thrash(leg))}</td>'
            f'<td class=num>{"" if swap is None else fmt(swap[0]) + " (" + fmt(swap[1]) + ")"}</td>'
            f'<td class=status>{"passed" if passed else "failed"}'
            f'{"<div class=reason>" + esc(leg["truth_verdict"]) + "</div>" if leg.get("truth_verdict") else ""}'
            f'{marked(leg)}'
            '</td></tr>')
    plots = "".join(figure(path, caption, wide=True) for path, caption in zip(
        summary.get("plots", []), ("top view and depth: truth, navigation estimate, setpoint; legs marked",
                                   "body velocities: truth and the velocity controller's reference",
                                   "blade-pitch commands of the four thrusters")))
    graph = "".join(f"<tr><td><code>{esc(k)}</code></td><td>{esc(v)}</td></tr>" for k, v in config["graph"].items())
    flown = ("Flown in one process: the hierarchy's cores, sample for sample as the lockstep graph flies them"
             if summary.get("transport") == "process" else
             "Self-tested through ROS, then flown leg by leg on the lockstep graph")
    bag = f"; bag <code>{esc(summary['bag'])}</code>" if summary.get("bag") else ""
    page = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>seapup: the mission</title><style>{CSS}</style></head>
<body><h1>seapup: the Seapup flies a mission through the supervisory hierarchy</h1>
<p class=muted>{flown} (thesis sec. 4.2, fig. 4.3); seed
{esc(config["graph"].get("seed", 0))}; held at {fmt(summary.get("held"))} s simulated after
{fmt(summary.get("wall_s"))} s wall{bag}.</p>
<section id="legs"><h2>The legs</h2>
<p>A leg passes when {esc(PASS_CRITERIA)}.</p>
<table><thead><tr><th>leg</th><th>kind</th><th>task verdict</th><th>simulated [s]</th><th>wall [s]</th>
<th>task error (navigation) [m]</th><th>truth error [m]</th><th>navigation error (stated std) [m]</th>
<th>saturated [% of samples]</th><th>thrashing [s]</th><th>swap step (largest before) [deg]</th>
<th>passed</th></tr></thead>
<tbody>{"".join(rows)}</tbody></table>
<p class=reason>Truth errors count from each leg's <code>hold_from</code> (after braking from the previous leg or
reaching the altitude); the swap step is the blade-pitch change into the incoming controller's first command, beside
the largest one-sample change in the 15 s before it (a manual leg's: the hand-back from the pilot's controller to the
task's). Thrashing is the longest stretch of blade pitches swinging between
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


def report_mission(result: dict, config: dict, out: Path | None, text, label: str, plots: bool = True) -> tuple:
    """A flown mission (:func:`seapup_runs.mission_flight.run_mission`'s or
    :func:`seapup_bringup.graph.mission_graph.fly_mission`'s result) shown: the leg table printed and, into ``out``
    (None: nothing written), the plots, ``summary.json`` and ``index.html``; what did not go well said in a line
    each. (the summary -- the result without its logs --, the exit code: 1 if a leg failed or the truth
    contradicts its verdict)."""
    legs = result["legs"]
    leg_table(legs, text)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        if plots and legs:
            result["plots"] = mission_plots(result, out)
            print(f"{label}: plots {', '.join(Path(p).name for p in result['plots'])} in {out}", file=text)
    if result.get("bag"):
        print(f"{label}: bag {result['bag']}", file=text)
    held = result.get("held")   # None: interrupted before the graph was first held
    flown = f"{held:.0f} s simulated" if held is not None else "interrupted before the first hold"
    print(f"{label}: {flown} in {result.get('wall_s', math.nan):.1f} s wall", file=text)
    summary = {k: v for k, v in result.items() if k != "logs"}
    if out is not None:
        (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float))
        print(f"{label}: see {index_page(summary, config, out)}", file=text)
    failed = [leg["name"] for leg in legs if leg.get("status") not in ("succeeded", None)]
    if failed:
        print(f"{label}: legs that did not succeed: {', '.join(failed)}", file=text)
    thrashed = [f"{leg['name']}: {leg['actuator_verdict']}" for leg in legs if leg.get("actuator_verdict")]
    if thrashed:  # marked, not failed: the task was done, the thrusters paid for it
        print(f"{label}: legs marked for their actuators: " + "; ".join(thrashed), file=text)
    doubted = [f"{leg['name']}: {leg['truth_verdict']}" for leg in legs if leg.get("truth_verdict")]
    if doubted:  # the task judged by its estimate; the truth says otherwise
        print(f"{label}: legs whose verdict the truth contradicts: " + "; ".join(doubted), file=text)
    return summary, 1 if failed or doubted else 0
