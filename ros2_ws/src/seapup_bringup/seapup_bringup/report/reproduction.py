"""The runs the thesis's targets need, each cached by its description and the code version.

The targets file (:mod:`seapup_runs.targets`) names the runs that produce ours (``runs:``): a
``verify`` of a vehicle configuration (:func:`seapup_sim.verification.verify`: Table 3.2's trials, the
linear analyses, the open-loop step gains of eq. 5.3 and 5.7, the current and the umbilical), a
``selftest`` flown in process (:func:`seapup_runs.self_test_flight.fly_self_test`, sec. 5.3) and a
``scenario`` of sec. 5.4 (:func:`seapup_runs.scenarios.scenario_spec` flown by the in-process runner).
:func:`execute` runs one and returns its result (JSON-ready: the document the targets' metric paths
read) with the figures it drew; :func:`run_all` runs several in parallel processes and keeps each
in a cache directory named by the hash of the run's description and of the code that computes it
(every source file of the product's packages), so a second report reruns nothing that could have
changed.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

from seapup_common.input_files import read_text
from seapup_common.jsondata import jsonable

__all__ = ["code_version", "run_key", "execute", "run_all", "default_cache", "ReproductionError"]

#: The product's packages: a change to any of their files is a new code version.
PACKAGES = ("seapup_common", "seapup_sim", "seapup_control", "seapup_ident", "seapup_runs", "seapup_bringup")


class ReproductionError(RuntimeError):
    """A run of the targets file that cannot be run (an unknown kind, a bad description)."""


def code_version() -> str:
    """A hash of every source and data file of the product's packages as imported (sorted by path)."""
    digest = hashlib.sha256()
    for name in PACKAGES:
        root = Path(__import__(name).__file__).resolve().parent
        for path in sorted(p for p in root.rglob("*") if p.is_file() and p.suffix in (".py", ".yaml", ".yml", ".json")
                           and "__pycache__" not in p.parts):
            digest.update(f"{name}/{path.relative_to(root).as_posix()}\0".encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def run_key(name: str, description: dict, version: str) -> str:
    """The cache key of a run: its name and description and the code version."""
    text = json.dumps({"name": name, "description": description, "code": version}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def default_cache() -> Path:
    """``$SEAPUP_CACHE`` or ``$XDG_CACHE_HOME/seapup/runs`` (``~/.cache/seapup/runs``)."""
    if os.environ.get("SEAPUP_CACHE"):
        return Path(os.environ["SEAPUP_CACHE"])
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "seapup" / "runs"


# -- one run --------------------------------------------------------------------------------------------------
def _verify(description: dict, out: Path) -> tuple[dict, list]:
    from seapup_sim.verification_report import write_plots
    from seapup_sim.vehicle import VehicleModel
    from seapup_sim.vehicle_config import load_vehicle_config
    from seapup_sim.verification import verify
    result, histories = verify(VehicleModel(load_vehicle_config(description["config"])))
    figures = [(path.name, _caption(path.stem, description["config"])) for path in write_plots(result, histories, out)]
    return result, figures


def _caption(stem: str, config: str) -> str:
    """``fig3_8_3_10_loci`` -> ``figs 3.8, 3.10 analogue (baseline): loci``."""
    import re
    if stem.startswith("appA_"):
        return f"App. A.3 trial analogue ({config}): {stem[5:].replace('_', ' ')}"
    match = re.fullmatch(r"fig((?:\d+_\d+_?)+?)_?([a-z][\w]*)", stem)
    if not match:
        return f"{stem} ({config})"
    numbers = match.group(1).strip("_").split("_")
    figures = [f"{a}.{b}" for a, b in zip(numbers[::2], numbers[1::2])]
    return f"fig{'s' if len(figures) > 1 else ''}. {', '.join(figures)} analogue ({config}): {match.group(2).replace('_', ' ')}"


def _self_test(description: dict, out: Path) -> tuple[dict, list]:
    """The self-test's points in the thesis's units (eq. 5.3, Tables 5.1-5.2) with the time and box of water
    each operating point took (sec. 5.3.3), and a figure of the test."""
    from seapup_runs.self_test_flight import fly_self_test
    rate = float(description.get("rate_hz", 5.0))
    run = fly_self_test(description["config"], {"sample_period": 1.0 / rate,
                                                "operating_points": list(description.get("speeds", [0.0])),
                                                "mode": description.get("mode", "realistic")})
    test = run.test
    if test.phase.value != "done":
        raise ReproductionError(f"the self-test did not finish: {test.phase.value}")
    period = 1.0 / rate
    start = test.start_time or 0.0
    points, previous_end = [], start
    for point in test.points:
        b0, b1 = point.model.in_thesis_units()
        steps = [s for s in test.tests if abs(s.surge - point.surge) < 1e-9]
        end = max(s.start_time + (len(s.outputs) - 1) * period for s in steps) if steps else previous_end
        within = run.truth[run.truth[:, 0] <= end + 1e-9, 1:4]
        points.append({"surge": point.surge, "B0inv": b0, "B1inv": b1, "u0_deg": np.degrees(point.model.u0),
                       "cycle": point.cycle, "duration_s": end - previous_end,
                       "space_m": within.max(axis=0) - within.min(axis=0), **_surge_gains(point.gains)})
        previous_end = end
    # the same steps fitted as the thesis's Table 5.2 reads (eq. 4.30 on the raw outputs, y0 not subtracted)
    from seapup_control.mfol import DesignError
    from seapup_control.self_test import refit
    from seapup_control.step_identification import IdentificationError
    try:   # a refit that admits no design leaves Table 5.2 without a value (missed), not the whole run failed
        thesis_fit = [{"surge": p.surge, **dict(zip(("B0inv", "B1inv"), p.model.in_thesis_units()))}
                      for p in refit(test.tests, period, test.config.poles, math.inf, "raw")]
        thesis_fit_error = None
    except (DesignError, IdentificationError) as exc:
        thesis_fit, thesis_fit_error = [], str(exc)
    result = {"points": points, "thesis_fit": thesis_fit, "thesis_fit_error": thesis_fit_error,
              "duration_s": test.duration, "space_m": run.space,
              "depth_range_m": list(run.depth_range), "steps": len(test.tests)}
    return result, [(_plot_self_test(run, description, out), "the self-test's speeds and blade pitches (sec. 5.3)")]


def _surge_gains(gains) -> dict:
    """The terms of eq. 5.6's gain matrices from the surge error and its integral to the two main thrusters'
    blade pitch (rows main port, main stbd; column u), and whether all four are negative: the thesis's
    0.7 m/s self-test gave such wrong-sign gains, the cause of fig. 5.19's steady-state error (sec. 5.4.2,
    5.6) -- more forward speed then asks for less main thrust."""
    terms = [float(gains.K_int[0, 0]), float(gains.K_int[1, 0]), float(gains.K_err[0, 0]), float(gains.K_err[1, 0])]
    return {"main_surge_gains": {"K_int": terms[:2], "K_err": terms[2:]},
            "main_surge_gains_negative": bool(all(g < 0 for g in terms))}


def _plot_self_test(run, description: dict, out: Path) -> str:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t, state = run.truth[:, 0], run.truth[:, 1:]
    fig, axes = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    for index, label in ((6, "u [m/s]"), (7, "v [m/s]"), (8, "w [m/s]")):
        axes[0].plot(t, state[:, index], label=label)
    axes[1].plot(t, np.degrees(state[:, 11]), label="r [deg/s]")
    for step in run.test.tests:
        axes[1].axvline(step.start_time, color="0.8", lw=0.6)
    axes[1].set_xlabel("time [s]")
    for ax in axes:
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    axes[0].set_title(f"self-test, {description['config']}, {description.get('mode', 'realistic')} quiescence, "
                      f"{description.get('rate_hz', 5):g} Hz (grey: steps)")
    name = f"selftest_{description['config']}_{description.get('mode', 'realistic')}.png"
    fig.tight_layout()
    fig.savefig(out / name, dpi=90)
    plt.close(fig)
    return name


def _scenario(description: dict, out: Path) -> tuple[dict, list]:
    from seapup_runs.run_plots import plot_scenario
    from seapup_runs.runner import run
    from seapup_runs.scenarios import scenario_spec
    def spec(seed):
        return scenario_spec(description["name"], description.get("config", "baseline"),
                             float(description.get("rate_hz", 5.0)), description.get("scheduled"), seed,
                             description.get("controller", "mfol"), description.get("params"),
                             description.get("sensors"), fit=description.get("fit", "deviation"))
    result = run(spec(0))
    figure = plot_scenario(result, out)
    metrics = dict(result.metrics)
    seeds = int(description.get("seeds", 1))
    if seeds > 1:  # a statement about a random disturbance, decided over realisations, not one
        metrics["over_seeds"] = {"seeds": seeds, "mean": _mean_leaves(
            [metrics] + [dict(run(spec(seed)).metrics) for seed in range(1, seeds)])}
    controller = description.get("controller", "mfol")
    said = "sec. 5.4's figures" if controller == "mfol" else "ch. 7's figures"
    settings = ", ".join(f"{k} {v}" for k, v in (description.get("params") or {}).items())
    return metrics, [(figure.name, f"{description['name']} at {description.get('rate_hz', 5):g} Hz"
                                   f"{'' if controller == 'mfol' else ', ' + controller}"
                                   f"{' (' + settings + ')' if settings else ''} (the analogue of {said})")]


def _mean_leaves(results: list):
    """The mean over ``results`` of every finite number found at the same place in all of them (nested
    mappings; booleans, lists and missing or non-finite values left out)."""
    first = results[0]
    if isinstance(first, dict):
        out = {}
        for key in first:
            if all(isinstance(r, dict) and key in r for r in results):
                value = _mean_leaves([r[key] for r in results])
                if value is not None and value != {}:
                    out[key] = value
        return out
    if all(isinstance(r, (int, float)) and not isinstance(r, bool) and math.isfinite(r) for r in results):
        return float(np.mean(results))
    return None


#: Table 4.1's noise powers as keys of the result (a metric path splits at dots)
_POWER_KEYS = {0.0: "0", 0.001: "1e-3", 0.005: "5e-3", 0.01: "1e-2"}


def _batch_identification(description: dict, out: Path) -> tuple[dict, list]:
    """Table 4.1: Prony's method and batch least squares (eq. 4.25-4.30) on a unit step of dy/dt = -y + u
    sampled at 5 Hz, white noise of each power on the measured output; per method, sample count and noise
    power the mean and standard deviation of y_0 and tau_c over the realisations that did not fail, and
    the fraction that failed."""
    from seapup_control.step_identification import step_fits
    period, count = 0.2, int(description.get("realisations", 400))
    rng = np.random.default_rng(int(description.get("seed", 41)))
    result = {}
    for method in ("prony", "bls"):
        for n in (50, 100):
            for power in (0.0, 0.001, 0.005, 0.01):
                runs = count if power else 1  # without noise every realisation is the same
                fits, failed = step_fits(method, n, power, runs, rng, period)
                ok = len(fits) > 0
                result.setdefault(method, {}).setdefault(str(n), {})[_POWER_KEYS[power]] = {
                    "y0_mean": fits[:, 0].mean() if ok else None, "y0_std": fits[:, 0].std(ddof=1) if len(fits) > 1 else 0.0,
                    "tau_mean": fits[:, 1].mean() if ok else None, "tau_std": fits[:, 1].std(ddof=1) if len(fits) > 1 else 0.0,
                    "failed_fraction": failed, "realisations": runs}
    return result, []


def _ident_command(argv: list) -> dict:
    """``./seapup ident ARGV`` carried out in this process (:func:`seapup_bringup.graph.identification.identify`):
    its result; what stops it as a ReproductionError naming the request."""
    from seapup_bringup.graph.identification import identify
    from seapup_bringup.graph.sil import SilError
    try:
        return identify(argv)
    except (ValueError, OSError, SilError) as exc:
        raise ReproductionError(f"./seapup ident {' '.join(map(str, argv))} failed: {exc}") from None


def _identification(description: dict, out: Path) -> tuple[dict, list]:
    """Sec. 6.5: an identification experiment (``./seapup ident experiment --in-process``: 60 s of PRBS on the
    linearised or nonlinear model, with or without current, or the closed loop; flown in this process, its record
    the graph's sample for sample, tested once per case in ``tests/test_ident_commands.py``) and on its record the
    order table (Tables 6.1, 6.2, 6.6: V_N, AIC and F per output for n = 1..3) and LS, ELS and RPEM at order 2 over
    300 and 2000 points (Tables 6.3-6.5, 6.7), with the statements the thesis draws from them."""
    experiment = ["experiment", "--in-process", "--out", out / "experiment",
                  "--dynamics", description.get("dynamics", "nonlinear")]
    experiment += ["--current"] if description.get("current") else []
    experiment += ["--closed-loop"] if description.get("closed_loop") else []
    record = _ident_command(experiment)["record"]
    orders = _ident_command(["orders", record])
    names = orders["outputs"]
    result = {"orders": {name: {str(row["order"]): {"loss": row["loss"][i], "aic": row["aic"][i]} for row in orders["rows"]}
                         for i, name in enumerate(names)},
              # F from order n to n + 1 (the thesis's F_{N -> N+1} on row N) and whether that increase is significant
              "f": {name: {f"{row['order'] - 1}_{row['order']}": row["f"][i] for row in orders["rows"] if "f" in row}
                    for i, name in enumerate(names)},
              "f_significant": {name: {f"{row['order'] - 1}_{row['order']}": row["significant"][i]
                                       for row in orders["rows"] if "f" in row} for i, name in enumerate(names)},
              "aic_order": dict(zip(names, orders["aic_order"])), "f_order": dict(zip(names, orders["f_order"])),
              "system_order": orders["system_order"]}
    figures = []
    for points in (300, 2000):
        plots = ["--plots", out] if points == 2000 else []  # the data against the adapting and the final model
        compared = _ident_command(["compare", record, "--rpem-k0", "0.1", *(["--points", points] if points > 300 else []),
                                   *plots])
        for path, method in zip(compared.get("plots", []), compared["methods"]):
            figures.append((Path(path).name, f"{method.upper()}(2, 2{', 2' if method != 'ls' else ''}) on the "
                                             f"{description.get('dynamics', 'nonlinear')} record"
                                             f"{' in current' if description.get('current') else ''}"
                                             f"{' (closed loop)' if description.get('closed_loop') else ''}: adapting "
                                             f"and after 2000 points (figs 6.3, 6.5-6.11, 6.13-6.14 analogue)"))
        aic = {method: dict(zip(names, values["aic"])) for method, values in compared["methods"].items()}
        entry = {**aic}
        if "els" in aic and "ls" in aic:
            entry["els_better_than_ls_on_most"] = sum(aic["els"][n] < aic["ls"][n] for n in names) > len(names) / 2
        if "rpem" in aic and "els" in aic:
            entry["rpem_worse_than_els_on_most"] = sum(aic["rpem"][n] > aic["els"][n] for n in names) > len(names) / 2
        result[f"compare_{points}"] = entry
    if not description.get("closed_loop") and not description.get("current"):  # figs 6.2 and 6.4
        residuals = _ident_command(["residuals", record, "--points", 2000, "--plots", out])
        result["residuals"] = _whiteness(residuals)
        figures += [(Path(path).name, f"correlation functions of the LS(2, 2) residuals, "
                                      f"{description.get('dynamics', 'nonlinear')} record "
                                      f"(fig. {'6.2' if description.get('dynamics') == 'linearised' else '6.4'} analogue)")
                    for path in residuals.get("plots", [])]
    return result, figures


def _whiteness(table: dict) -> dict:
    """Sec. 6.3's residual test in the thesis's own form: an output's residuals are white when at least 95 %
    of their autocorrelations at lags > 0 lie inside +-1.96/sqrt(N); with the fraction per output and the
    Ljung-Box verdict beside it. ``white_on_most``: more than half the outputs (fig. 6.2: "close to white
    noise"; fig. 6.4: "probably not white ... but weakly correlated")."""
    names = table["outputs"]
    white = [inside >= 0.95 - 1e-12 for inside in table["inside"]]
    return {"inside": dict(zip(names, table["inside"])), "white": dict(zip(names, white)),
            "ljung_box_white": dict(zip(names, table["white"])),
            "white_on_most": sum(white) > len(names) / 2}


def _closed_loop(description: dict, out: Path) -> tuple[dict, list]:
    """Sec. 5.4.1 and 5.5.1: the closed-loop poles (eq. 5.8-5.15) about the trim at 0, 0.1, ..., 1 m/s of the
    plant ``config`` under the controller the self-test designs on the baseline (5 Hz, realistic, operating
    points 0 and 0.7 m/s; fixed gains or ``scheduled``), labelled by mode, with the figures of the loci
    (figs 5.4-5.9, 5.25-5.30) and the statements the thesis makes of them."""
    from seapup_runs.closed_loop_analysis import MODES, analyse, plot_loci
    from seapup_runs.self_test_flight import fly_self_test
    from seapup_sim.vehicle import VehicleModel
    from seapup_sim.vehicle_config import load_vehicle_config
    rate = float(description.get("rate_hz", 5.0))
    run = fly_self_test("baseline", {"sample_period": 1.0 / rate, "operating_points": [0.0, 0.7], "mode": "realistic"})
    if run.test.phase.value != "done":
        raise ReproductionError(f"the self-test did not finish: {run.test.phase.value}")
    scheduled = bool(description.get("scheduled", False))
    rows = analyse(VehicleModel(load_vehicle_config(description["config"])), run.test.schedule(),
                   [round(0.1 * k, 1) for k in range(11)], scheduled)
    flown = [r for r in rows if "error" not in r]

    def least_damped(rows_, mode):
        """The mode's largest real part at each speed; None (undecided) if the mode is missing at one."""
        out = [max((p[0] for p in r["modes"].get(mode, [])), default=None) for r in rows_]
        return None if not out or None in out else out

    modes = [m for m in MODES if m != "position"]
    fast = [r for r in flown if r["surge"] > 0.8 + 1e-9]
    unstable_fast = {mode: least_damped(fast, mode) for mode in modes}
    # by mode: at every speed the vehicle can hold (a speed with no trim -- the camera vehicle's 1.0 m/s -- is
    # judged by stable_at_every_speed, which needs them all)
    every_speed = {mode: least_damped(flown, mode) for mode in modes}
    result = {"speeds": rows, "eigenvalues_at_rest": len(flown[0]["z_poles"]) if flown else None,
              "integrations_at_rest": sum(1 for z in flown[0]["z_poles"] if abs(complex(*z) - 1) < 1e-6) if flown else None,
              "stable_at_every_speed": all(r["stable"] for r in flown) and len(flown) == len(rows),
              "unstable_above_0_8": {mode: None if v is None else max(v) > 0.0 for mode, v in unstable_fast.items()},
              "stable_at_every_speed_by_mode": {mode: None if v is None else max(v) < 0.0
                                                for mode, v in every_speed.items()}}
    document = {"config": description["config"], "rate_hz": rate, "scheduled": scheduled,
                "designed_s": [[float(v.real), float(v.imag)] for v in run.test.config.poles.continuous()[0]],
                "speeds": rows}
    figures = [(path.name, f"closed-loop loci of the {path.stem.split('_')[2]} mode, {description['config']}, "
                           f"{rate:g} Hz, {'scheduled' if scheduled else 'fixed'} gains (figs 5.4-5.9, 5.25-5.30 analogue)")
               for path in plot_loci(document, out)]
    return result, figures


#: The steps each vehicle flies under each law in the "two vehicles" run: (time [s], u, v, w, r), 10 s each.
VEHICLE_STEPS = [[0.0, 0.3, 0.0, 0.0, 0.0], [10.0, 0.0, 0.15, 0.0, 0.0], [20.0, 0.0, 0.0, 0.1, 0.0],
                 [30.0, 0.0, 0.0, 0.0, 0.2], [40.0, 0.0, 0.0, 0.0, 0.0]]


def _vehicles(description: dict, out: Path) -> tuple[dict, list]:
    """The thesis's claim (abstract, ch. 8: an ROV autopilot designed on the vehicle itself, no model needed)
    tried on each of ``vehicles``: what the self-test at rest found (its time, its box of water, how diagonal
    B0^-1 is), then each law (the self-tested fixed gains, the explicit and the GMV self-tuners, commissioned as
    ``commissioning`` says for a vehicle or by the law's default) flying the same steps in surge, sway, heave and yaw with the baseline instruments: each output's
    error over the last 5 s of its step, the others' largest excursion there, and the inputs' peak as a share
    of the vehicle's limit."""
    from seapup_runs.runner import run
    from seapup_runs.self_test_flight import fly_self_test
    from seapup_runs.spec import RunSpec
    from seapup_sim.vehicle import VehicleModel
    from seapup_sim.vehicle_config import load_vehicle_config
    rows, traces = [], {}
    for vehicle in description["vehicles"]:
        limit = VehicleModel(load_vehicle_config(vehicle)).pitch_limit
        flown = fly_self_test(vehicle, {"operating_points": [0.0]})
        test = flown.test
        if test.phase.value != "done":
            raise ReproductionError(f"the self-test on {vehicle} did not finish: {test.reason}")
        b0 = test.points[0].model.B0inv
        diagonal = np.abs(np.diag(b0))
        row = {"vehicle": vehicle, "inputs": VehicleModel(load_vehicle_config(vehicle)).inputs.kind,
               "self_test_s": test.duration, "space_m": flown.space,
               "b0inv_diagonal": np.diag(b0), "off_diagonal_share": float(np.max(np.abs(b0 - np.diag(np.diag(b0)))
                                                                                 / diagonal[:, None])),
               "laws": {}}
        for law in ("mfol", "explicit", "gmv"):
            commissioning = description.get("commissioning", {}).get(vehicle)
            parameters = ({"schedule": False} if law == "mfol"
                          else {"commissioning_samples": int(commissioning)} if commissioning else {})
            spec = RunSpec.from_dict({
                "name": f"{vehicle}-{law}", "vehicle": vehicle, "environment": {"sensors": "baseline"},
                "control_period": 0.2, "duration": 50.0, "start_depth": 30.0,
                "controller": {"type": law, "parameters": parameters},
                "design": {"vehicle": vehicle, "operating_points": [0.0]}, "reference": VEHICLE_STEPS})
            result = run(spec)
            t, truth = result.series.t, result.series.truth
            held = {}
            for (start, *value), key in zip(VEHICLE_STEPS[:4], ("u", "v", "w", "r")):
                window = (t > start + 5.0) & (t <= start + 10.0)
                target = value[("u", "v", "w", "r").index(key)]
                others = [k for k in ("u", "v", "w") if k != key]
                held[key] = {"error_rms": float(np.sqrt(np.mean((truth[key][window] - target) ** 2))),
                             "share": float(np.sqrt(np.mean((truth[key][window] - target) ** 2)) / abs(target)),
                             "interaction": float(max(np.abs(truth[k][window]).max() for k in others))}
            row["laws"][law] = {"held": held,
                                "input_peak_share": float(np.nanmax(np.abs(result.series.command)) / limit)}
            traces[(vehicle, law)] = (t, truth)
        rows.append(row)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(4, 1, figsize=(7, 9), sharex=True)
    for (vehicle, law), (t, truth) in traces.items():
        if law != "mfol":
            continue
        for ax, key in zip(axes, ("u", "v", "w", "r")):
            ax.plot(t, truth[key], label=vehicle)
    times = [row[0] for row in VEHICLE_STEPS] + [50.0]
    for ax, key, unit in zip(axes, ("u", "v", "w", "r"), ("m/s", "m/s", "m/s", "rad/s")):
        level = [row[1 + ("u", "v", "w", "r").index(key)] for row in VEHICLE_STEPS]
        ax.step(times, level + [level[-1]], where="post", color="k", lw=0.8, ls="--", label="reference")
        ax.set_ylabel(f"{key} [{unit}]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    axes[0].set_title("the self-tested fixed-gain law on each vehicle (no model of either)")
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    path = out / "vehicles_steps.png"
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return {"vehicles": rows}, [(path.name, "the same steps flown by each vehicle under its self-tested fixed "
                                            "gains (docs/vehicles.md)")]


_KINDS = {"vehicles": _vehicles, "verify": _verify, "selftest": _self_test, "scenario": _scenario, "batch_identification": _batch_identification,
          "identification": _identification, "closed_loop": _closed_loop}


def execute(name: str, description: dict, out: Path) -> dict:
    """Run ``name`` (a ``runs:`` entry of the targets file) into directory ``out``: ``{"result", "figures":
    [{"file", "caption"}], "wall_s", "cpu_s"}``, figures as PNG files in ``out``."""
    kind = description.get("kind")
    if kind not in _KINDS:
        raise ReproductionError(f"run {name!r}: unknown kind {kind!r} (known: {', '.join(_KINDS)})")
    out.mkdir(parents=True, exist_ok=True)
    wall, cpu = time.perf_counter(), time.process_time()
    result, figures = _KINDS[kind](description, out)
    return {"name": name, "result": jsonable(result), "figures": [{"file": f, "caption": c} for f, c in figures],
            "wall_s": time.perf_counter() - wall, "cpu_s": time.process_time() - cpu}


def _cached_execute(name: str, description: dict, directory: str) -> dict:
    """In a worker: run into a fresh directory, then move it into place (a reader never sees half a run)."""
    final = Path(directory)
    partial = Path(tempfile.mkdtemp(prefix=f".{final.name}.", dir=final.parent))
    try:
        payload = execute(name, description, partial)
        (partial / "run.json").write_text(json.dumps(payload))
        if final.exists():
            shutil.rmtree(final)
        partial.rename(final)
    finally:
        if partial.exists():
            shutil.rmtree(partial, ignore_errors=True)
    return payload


def run_all(runs: dict, cache: Path, jobs: int = 1, use_cache: bool = True, progress=None) -> dict:
    """Run every ``name: description`` of ``runs`` (or take it from ``cache``): name -> payload (see
    :func:`execute`, plus ``directory``, ``cached`` and, on failure, ``error`` with ``result`` None)."""
    cache = Path(cache)
    cache.mkdir(parents=True, exist_ok=True)
    version = code_version()
    out, todo = {}, {}
    for name, description in runs.items():
        directory = cache / run_key(name, description, version)
        if use_cache and (directory / "run.json").is_file():
            out[name] = {**json.loads(read_text(directory / "run.json", "data")), "directory": str(directory),
                         "cached": True}
        else:
            todo[name] = (description, directory)
    done = len(out)
    if progress is not None:
        progress(done / max(len(runs), 1))
    if todo:
        with ProcessPoolExecutor(max_workers=max(1, min(jobs, len(todo))), initializer=_ignore_interrupts) as pool:
            try:   # the submits too: a Ctrl-C among them must not leave the submitted runs to be waited for
                futures = {pool.submit(_cached_execute, name, description, str(directory)): (name, directory)
                           for name, (description, directory) in todo.items()}
                _collect(futures, out, runs, done, progress)
            except BaseException:   # Ctrl-C, SIGTERM: the runs in flight are dropped, not waited for
                _stop_pool(pool)
                raise
    return {name: out[name] for name in runs}


def _collect(futures: dict, out: dict, runs: dict, done: int, progress) -> None:
    """Each finished run's payload into ``out`` as it comes."""
    for future in as_completed(futures):
        name, directory = futures[future]
        try:
            out[name] = {**future.result(), "directory": str(directory), "cached": False}
        except Exception as exc:  # one failed run is a row of failed targets, not a lost report
            out[name] = {"name": name, "result": None, "figures": [], "error": f"{type(exc).__name__}: {exc}",
                         "directory": str(directory), "cached": False, "wall_s": None, "cpu_s": None}
        done += 1
        if progress is not None:
            progress(done / len(runs))


def _ignore_interrupts() -> None:
    """A run worker ignores SIGINT: Ctrl-C reaches the terminal's whole process group, and only the parent
    answers it (:func:`_stop_pool`); the workers printed tracebacks and finished their runs first."""
    import signal
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _stop_pool(pool: ProcessPoolExecutor) -> None:
    """End the pool's workers now (SIGKILL) and drop the queued runs: an interrupted report stops within a
    second instead of waiting for the runs in flight (25-45 s)."""
    for process in list(getattr(pool, "_processes", {}).values()):
        try:
            process.kill()
        except (OSError, ValueError):
            pass
    pool.shutdown(wait=False, cancel_futures=True)
