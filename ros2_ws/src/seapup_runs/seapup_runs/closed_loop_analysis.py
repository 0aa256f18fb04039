"""The closed loop's eigenvalues over surge speed (thesis sec. 5.4.1, eq. 5.8-5.15, figs 5.4-5.9; sec. 5.5.1,
figs 5.25-5.30): the vehicle linearised about its trim at each speed (:mod:`seapup_sim.analysis`) under the
self-tested two-term law (:func:`seapup_control.closed_loop.closed_loop`), each eigenvalue labelled by the
mode it belongs to, and the loci drawn per mode. Pure (numpy, scipy; matplotlib for the figures):
``./seapup closed-loop`` and the reproduction report both call it."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from seapup_control.closed_loop import closed_loop
from seapup_sim.analysis import TrimError, linearise, output_matrix, trim
from seapup_sim.vehicle import VehicleModel

__all__ = ["MODES", "analyse", "plot_loci"]


#: State groups that name a closed-loop mode (figs 5.4-5.9): states 0-11 of the vehicle, 12-15 the
#: controller's integrators of the u, v, w, r loops.
MODES = {"surge": [6, 12], "sway": [7, 13], "heave": [8, 14], "yaw": [11, 15], "roll": [3, 9],
         "pitch": [4, 10], "position": [0, 1, 2, 5]}


def _mode_of(vector: np.ndarray, s: complex) -> str:
    """The mode a closed-loop eigenvector belongs to: its largest velocity, attitude or integrator component.

    The four pure integrations to X, Y, Z and psi (s = 0) are the position
    modes; position components are left out of the others' weights (a slow
    mode's displacement, v / s, would outweigh its own velocity).
    """
    if abs(s) < 1e-6:
        return "position"
    weight = {name: float(np.abs(vector[idx]).max()) for name, idx in MODES.items() if name != "position"}
    return max(weight, key=weight.get)


#: The vehicle's own states of each non-position mode (no integrator: its size grows as the sample period
#: shrinks, so it would make the labels depend on the rate)
_MODE_STATES = {"surge": [6], "sway": [7], "heave": [8], "yaw": [11], "roll": [3, 9], "pitch": [4, 10]}


def _label_modes(vectors: np.ndarray, s_values: np.ndarray) -> list[str]:
    """Each closed-loop eigenvalue's mode, two per mode (eq. 5.15: per velocity loop its own pole and its
    integrator's, per attitude its angle and rate; plus the four pure integrations to position).

    The two-per-mode assignment maximises the summed share of each eigenvector on its mode's vehicle states
    (an optimal assignment, :func:`scipy.optimize.linear_sum_assignment`), so every mode keeps its two
    eigenvalues at every speed and rate, as in figs 5.4-5.9. With other than 12 non-position eigenvalues it
    falls back to each eigenvector's largest component (:func:`_mode_of`)."""
    from scipy.optimize import linear_sum_assignment
    labels = ["position" if abs(s) < 1e-6 else "" for s in s_values]
    rest = [k for k, label in enumerate(labels) if not label]
    names = list(_MODE_STATES)
    if len(rest) != 2 * len(names):
        return [label or _mode_of(vectors[:, k], s_values[k]) for k, label in enumerate(labels)]
    share = np.array([[float(np.abs(vectors[idx, k]).max()) for idx in _MODE_STATES.values()] for k in rest])
    share /= np.maximum(share.max(axis=1, keepdims=True), 1e-300)
    rows, cols = linear_sum_assignment(-np.repeat(share, 2, axis=1))
    for r, c in zip(rows, cols):
        labels[rest[r]] = names[c // 2]
    return labels


def analyse(model: VehicleModel, schedule, speeds, scheduled: bool) -> list[dict]:
    """Closed-loop poles about the trim at each surge speed (eq. 5.8-5.15), labelled by mode.

    ``schedule``: the two-term law's gains over surge speed (``gains_at(speed)``, ``sample_period``:
    the ``mfol`` controller's schedule, as the self-test leaves it)."""
    c = output_matrix()
    rows = []
    for speed in speeds:
        try:
            held = trim(model, speed)
        except TrimError as exc:
            rows.append({"surge": speed, "error": str(exc)})
            continue
        a, b = linearise(model, held.state, held.blade_pitch)
        k_int, k_err = schedule.gains_at(speed if scheduled else 0.0)
        loop = closed_loop(a, b, c, k_int, k_err, schedule.sample_period)
        values, vectors = np.linalg.eig(loop.phi)
        with np.errstate(divide="ignore"):
            s_values = np.log(values.astype(complex)) / schedule.sample_period  # eq. 5.1
        modes = {}
        for s, label in zip(s_values, _label_modes(vectors, s_values)):
            modes.setdefault(label, []).append([float(s.real), float(s.imag)])
        dynamic = [p[0] for name, poles in modes.items() if name != "position" for p in poles]
        # stable: every mode but the four pure integrations to position decays
        rows.append({"surge": speed, "stable": max(dynamic) < 0.0, "max_re_s": max(dynamic),
                     "spectral_radius": loop.spectral_radius,
                     "z_poles": [[float(z.real), float(z.imag)] for z in loop.z_poles],
                     "s_poles": [[float(s.real), float(s.imag)] for s in loop.s_poles], "modes": modes})
    return rows


def plot_loci(result: dict, out_dir: Path) -> list[Path]:
    """One s-plane figure per mode, coloured by surge speed (from the JSON result)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    speeds = [r for r in result["speeds"] if "modes" in r]
    for number, mode in enumerate(m for m in MODES if m != "position"):
        fig, ax = plt.subplots(figsize=(6, 4.5))
        for row in speeds:
            poles = np.array(row["modes"].get(mode, [])).reshape(-1, 2)
            ax.scatter(poles[:, 0], poles[:, 1], color=plt.cm.viridis(row["surge"] / 1.0), s=14,
                       label=f"{row['surge']:.1f} m/s")
        ax.axvline(0.0, color="k", lw=0.8)
        ax.set_xlabel("Re s [1/s]")
        ax.set_ylabel("Im s [rad/s]")
        kind = "scheduled" if result["scheduled"] else "fixed"
        ax.set_title(f"{mode} modes, {result['rate_hz']:g} Hz, {kind} gains (cf. fig. 5.{4 + number})")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6, ncol=2)
        path = out_dir / f"fig5_{4 + number}_{mode}_{int(result['rate_hz'])}hz_{kind}.png"
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths
