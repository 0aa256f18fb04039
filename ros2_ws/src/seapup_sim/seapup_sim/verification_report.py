"""Tables and plots of a verification run, from the same results dict.

The table rows are the scored thesis targets of the verification run (the run
layer's ``seapup_runs.targets.verify_rows``) and the plots come from the time
histories returned with those results, so the printed numbers and the pictures
cannot disagree.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["format_rows", "write_plots"]


def _fmt(v) -> str:
    if v is None:
        return "n/a"
    if abs(v) >= 100 or v == int(v):
        return f"{v:.1f}" if abs(v) < 1e4 else f"{v:.3g}"
    return f"{v:.4g}"


def format_rows(rows: list[dict], title: str, totals: dict) -> str:
    """A fixed-width table: target, simulated, thesis, accepted range, PASS/FAIL/DEV, then the summary line
    of ``totals`` (primary/secondary counts, deviations, ok).

    Tags: P primary, s secondary, D documented deviation (its reason on the next line).
    """
    lines = [title, f"{'':2}{'quantity':<42}{'simulated':>11}{'thesis':>10}  {'accepted':<21}{'':6}source"]
    for r in rows:
        rng = f"[{_fmt(r['low'])}, {_fmt(r['high'])}]"
        status = r.get("status") or ("PASS" if r["pass"] else "FAIL")
        tag = "D" if r.get("deviation") else ("P" if r["primary"] else "s")
        lines.append(f"{tag:<2}{r['label']:<42}{_fmt(r['value']):>11}{_fmt(r['thesis']):>10}  "
                     f"{rng:<21}{status:<6}{r['source']}")
        if r.get("deviation") and not r["pass"]:
            lines.append(f"{'':4}deviation: {r['deviation']}")
    s = totals
    if not rows:   # a vehicle of the user's own: measured, but the thesis has no numbers for it
        lines.append("summary: nothing scored -- the thesis has no targets for this configuration (the values above "
                     "are measured; ./seapup check-model checks any vehicle's model)")
        return "\n".join(lines)
    lines.append(f"summary: primary {s['primary_passed']}/{s['primary']} PASS, secondary "
                 f"{s['secondary_passed']}/{s['secondary']} PASS, {s['deviations']} documented deviation(s) "
                 f"(P = primary, s = secondary, D = documented deviation) -> "
                 + ("all primaries pass" if s["ok"] else "a primary target FAILS"))
    return "\n".join(lines)


def write_plots(results: dict, histories: dict, out_dir: str | Path) -> list[Path]:
    """PNG plots like thesis figs 3.2-3.6 and 3.8/3.10 and of App. A.3's climb and high-speed turn; returns the
    paths."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cfg = results.get("config", "")
    paths = []

    def panel(name, title, series):
        fig, axes = plt.subplots(len(series), 1, figsize=(7, 2.2 * len(series)), sharex=True)
        axes = np.atleast_1d(axes)
        for ax, (label, t, y) in zip(axes, series):
            ax.plot(t, y, lw=1.4)
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
        axes[-1].set_xlabel("time [s]")
        axes[0].set_title(f"{title} ({cfg})")
        fig.tight_layout()
        path = out / f"{name}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)

    t, x = histories["roll_release"]
    panel("fig3_2_roll_release", "Autonomous roll test (Table 3.2 no. 1)",
          [("roll [deg]", t, np.degrees(x[:, 3])), ("pitch [deg]", t, np.degrees(x[:, 4])),
           ("yaw rate [deg/s]", t, np.degrees(x[:, 11]))])
    t, x = histories["pitch_release"]
    panel("fig3_3_pitch_release", "Autonomous pitch test (no. 2)",
          [("pitch [deg]", t, np.degrees(x[:, 4])), ("pitch rate [deg/s]", t, np.degrees(x[:, 10])),
           ("surge [m/s]", t, x[:, 6])])
    t, x = histories["surge"]
    panel("fig3_4_surge", "Surge test (no. 3)",
          [("surge u [m/s]", t, x[:, 6]), ("pitch [deg]", t, np.degrees(x[:, 4])),
           ("pitch rate [deg/s]", t, np.degrees(x[:, 10]))])
    td, xd = histories["heave_down"]
    tu, xu = histories["heave_up"]
    panel("fig3_5_heave", "Heave tests (nos. 5a, 5b)",
          [("heave w down [m/s]", td, xd[:, 8]), ("heave w up [m/s]", tu, -xu[:, 8])])
    t, x = histories["sway_4a"]
    panel("fig3_6_sway", "Sway test (no. 4a)",
          [("sway v [m/s]", t, x[:, 7]), ("roll [deg]", t, np.degrees(x[:, 3])),
           ("roll rate [deg/s]", t, np.degrees(x[:, 9]))])

    if "climb" in histories:  # App. A.3's trials 2 and 5 (Table A.1 rows 1 and 5)
        t, x = histories["climb"]
        panel("appA_climb", "Climb: full surge and full upward heave (App. A.3 trial 2, Table A.1 row 1)",
              [("pitch [deg]", t, np.degrees(x[:, 4])), ("surge u [m/s]", t, x[:, 6]),
               ("rise -w [m/s]", t, -x[:, 8])])
        t, x = histories["fast_turn"]
        panel("appA_fast_turn", "High-speed turn: full surge and full yaw (App. A.3 trial 5, Table A.1 row 5)",
              [("yaw rate [deg/s]", t, np.degrees(x[:, 11])), ("surge u [m/s]", t, x[:, 6]),
               ("roll [deg]", t, np.degrees(x[:, 3]))])

    shapes = histories.get("umbilical") or {}
    if any(v is not None for v in shapes.values()):
        fig, ax = plt.subplots(figsize=(7, 5))
        for depth, pts in shapes.items():
            if pts is None:
                continue
            u = results["umbilical"][depth]
            ax.plot(pts[:, 0], -pts[:, 2], label=f"{depth} m: u = {u['max_u']:.3f} m/s, "
                    f"F = ({u['Fx']:.0f}, {u['Fz']:.0f}) N")
        ax.set_xlabel("x [m] (NED)")
        ax.set_ylabel("height [m] (-z)")
        ax.set_title(f"Umbilical at the surge test's top speed (fig. 3.11) ({cfg})")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
        ax.set_aspect("equal", adjustable="datalim")
        fig.tight_layout()
        path = out / "fig3_11_umbilical.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    cur = histories.get("current")
    if cur is not None:
        fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7, 6))
        ex, ts = cur["example"], cur["sample_time"]
        ax1.plot(np.arange(len(ex)) * ts, ex[:, 0])
        ax1.axhline(0.26, color="k", lw=0.8, ls="--")
        ax1.set_xlabel("time [s]")
        ax1.set_ylabel("current speed [m/s]")
        ax1.set_title(f"Current realisation (fig. 3.12a): mean {ex[:, 0].mean():.4f}, "
                      f"std {ex[:, 0].std():.4f} m/s")
        spec = cur["spectrum"]
        omega = 2 * np.pi * np.fft.rfftfreq(2 * (len(spec) - 1), ts)
        ax2.semilogx(omega[1:], spec[1:])
        ax2.axvline(0.1, color="k", lw=0.8, ls="--")
        ax2.set_xlabel("frequency [rad/s]")
        ax2.set_ylabel("mean |FFT| [m/s]")
        ax2.set_title(f"30 realisations of 256 samples (fig. 3.12b); zero-frequency level {spec[0]:.3f} m/s")
        ax2.grid(alpha=0.3)
        fig.tight_layout()
        path = out / "fig3_12_current.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)

    loci = histories.get("loci") or []
    if loci:
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.5))
        speeds = [p["surge_speed"] for p in loci]
        cmap = plt.get_cmap("viridis")
        for k, p in enumerate(loci):
            colour = cmap(k / max(len(loci) - 1, 1))
            ev = np.array(p["eigenvalues"])
            ax1.scatter(ev[:, 0], ev[:, 1], s=10, color=colour)
            z = np.array(p["transmission_zeros"]).reshape(-1, 2)
            if z.size:
                ax2.scatter(z[:, 0], z[:, 1], s=14, color=colour)
        for ax, what in ((ax1, "Open-loop eigenvalues (fig. 3.8)"), (ax2, "Transmission zeros (fig. 3.10)")):
            ax.axvline(0.0, color="k", lw=0.8)
            ax.set_xlabel("real [1/s]")
            ax.set_ylabel("imaginary [rad/s]")
            ax.set_title(f"{what}, u = {speeds[0]:.1f}-{speeds[-1]:.1f} m/s")
            ax.grid(alpha=0.3)
        sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(speeds[0], speeds[-1]))
        fig.colorbar(sm, ax=[ax1, ax2], label="surge speed [m/s]")
        path = out / "fig3_8_3_10_loci.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def write_reference_plot(histories: dict, rows: list[dict], out_dir: str | Path) -> Path:
    """One panel per open-loop response of :func:`seapup_sim.fossen.verify_fossen`: the description flown by the
    simulator against the paper's model (``reference_responses.png`` in ``out_dir``)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from seapup_sim.fossen import RESPONSES
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(1, len(RESPONSES), figsize=(4 * len(RESPONSES), 3.2), squeeze=False)
    for ax, (name, _, index, unit), row in zip(axes[0], RESPONSES, rows):
        t, ours, theirs = histories[name]
        ax.plot(t, ours[:, index], label="description (simulator)")
        ax.plot(t, theirs[:, index], "--", label="paper's equations")
        ax.axhline(row["balance"], color="0.6", lw=0.8, ls=":", label="damping = force")
        ax.set_title(name)
        ax.set_xlabel("t [s]")
        ax.set_ylabel(unit)
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    path = out / "reference_responses.png"
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
