"""A run's figure: what :func:`seapup_runs.runner.run` or the graph runner returned, drawn as the thesis draws
its closed-loop cases (figs 5.10-5.24; with a self-tuner's parameter traces, figs 7.10-7.25). Pure: the
:class:`~seapup_runs.result.RunResult` in, a PNG out (matplotlib, Agg)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from seapup_runs.result import RunResult

__all__ = ["plot_scenario"]


def plot_scenario(result: RunResult, out_dir: Path) -> Path:
    """A figure like figs 5.10-5.24: velocities, roll and pitch, blade pitches."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    spec, series = result.spec, result.series
    estimate = series.estimate
    fig, axes = plt.subplots(6 if estimate else 4, 1, figsize=(7, 13 if estimate else 9), sharex=True)
    for key, unit in (("u", "m/s"), ("v", "m/s"), ("w", "m/s")):
        axes[0].plot(series.t, series.truth[key], label=f"{key} [{unit}]")
    axes[1].plot(series.t, np.degrees(series.truth["r"]), label="r [deg/s]")
    axes[2].plot(series.t, np.degrees(series.truth["roll"]), label="roll [deg]")
    axes[2].plot(series.t, np.degrees(series.truth["pitch"]), label="pitch [deg]")
    from seapup_sim.vehicle import VehicleModel
    from seapup_sim.vehicle_config import load_vehicle_config
    inputs = VehicleModel(load_vehicle_config(spec.vehicle)).inputs
    if inputs.kind == "virtual":   # the four virtual inputs, in % of full scale
        for j, key in enumerate(inputs.names):
            axes[3].plot(series.t, 100.0 * series.applied[:, j], label=f"{key} [%]")
    else:
        for j, key in enumerate(("main port", "main stbd", "vect stbd", "vect port")):
            axes[3].plot(series.t, np.degrees(series.applied[:, j]), label=f"{key} [deg]")
    if estimate:  # the self-tuner's parameter traces (figs 7.10, 7.17, 7.19, 7.25)
        for j, name in enumerate(estimate["names"]):
            if name == "trace_P":
                continue
            panel = axes[4] if name.startswith(("a_", "f0_")) else axes[5]
            panel.plot(series.t, estimate["values"][:, j], label=name)
    axes[-1].set_xlabel("time [s]")
    for ax in axes:
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    rate = 1.0 / spec.control_period
    last = spec.controller_timeline()[-1][1]
    scheduled = bool(last.parameters.get("schedule", False))
    tuner = "" if last.type in ("mfol", "hold") else last.type
    axes[0].set_title(f"{spec.name} ({spec.vehicle}, {rate:g} Hz{', gain-scheduled' if scheduled else ''}"
                      f"{', ' + tuner if tuner else ''})")
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / (f"scenario_{spec.name}_{spec.vehicle}_{int(round(rate))}hz{'_scheduled' if scheduled else ''}"
                      f"{'_' + tuner if tuner else ''}.png")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
