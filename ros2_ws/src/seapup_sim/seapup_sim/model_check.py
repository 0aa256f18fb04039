"""Model checker: what thesis sec. 3.4-3.5 found by hand, found by code.

Goheen's verification of the NMI model traced its instabilities and
asymmetries to four kinds of defect. :func:`check_model` looks for each:

1. **Mass-matrix asymmetry** (sec. 3.4): for a rigid body in an ideal fluid
   the mass matrix is symmetric (Newman); NMI's was not. Checked on the
   rigid-body, added-mass and total matrices; the total must also be positive
   definite.
2. **Port/starboard symmetry** (sec. 3.5): a left-right symmetric vehicle
   mirrored in its x-z plane flips v, p, r (and Y, K, N). So X, Z, M may
   contain only products with an *even* number of plain v, p, r factors, and
   Y, K, N only an *odd* number (|v|, |p|, |r| do not flip). The thesis removed X_r, X_vrr, X_vpp, X_pq, X_qr,
   Y_vp, Z_ur, Z_vrr, Z_pq, L_vvw, L_vp, M_ur, M_vvr, M_vrr, M_p, M_qr, N_vp.
   Also checked: mass matrices, CG/CB and the thruster matrix under the mirror
   (port and starboard thrusters swapped), and the linearised model at hover.
3. **Negative damping** (sec. 3.5, M_|w|q > 0): a term on axis i whose value
   always has the sign of velocity i (velocity i an odd number of times as a
   plain factor, every other plain factor an even number of times) damps
   when its coefficient is negative and feeds energy in when it is positive.
4. **Instability in the speed range** (sec. 3.3, 3.7): poles of the model
   linearised about trimmed flight at surge speeds 0-1 m/s.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from seapup_sim.analysis import TrimError, linearise, trim, trim_sweep
from seapup_sim.hydrodynamics import AXES, VELOCITIES, HydroTerm
from seapup_sim.vehicle import VehicleModel

__all__ = ["Finding", "ModelReport", "check_model", "MIRROR", "ASYMMETRIC"]

#: Mirror in the body x-z plane: sign of u v w p q r (and X Y Z K M N).
MIRROR = np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0])
#: Velocity indices that flip under the mirror.
ASYMMETRIC = (1, 3, 5)


def thruster_mirror(thrusters, tol: float = 1e-6) -> list[int] | None:
    """Each thruster's mirror image in the body x-z plane, found from the geometry: the thruster at
    (x, -y, z) pushing along (dx, -dy, dz) (the Seapup: the mains swap, the vectored pair swap), or None
    when some thruster has none (an asymmetric layout)."""
    flip = np.array([1.0, -1.0, 1.0])
    mirror = []
    for position, direction in zip(thrusters.positions, thrusters.directions):
        match = [k for k, (p, d) in enumerate(zip(thrusters.positions, thrusters.directions))
                 if np.abs(p - flip * position).max() <= tol * max(1.0, np.abs(position).max())
                 and np.abs(d - flip * direction).max() <= tol]
        if len(match) != 1:
            return None
        mirror.append(match[0])
    return mirror


@dataclass(frozen=True)
class Finding:
    """One problem: its kind, where, and what is wrong."""

    kind: str        # mass-asymmetry | symmetry | negative-damping | instability | mass-not-positive
    where: str
    message: str


#: Open-loop modes a vehicle description may declare unstable (``open_loop_unstable``), and the velocities
#: (indices of u v w p q r) whose motion makes each: sway-yaw, the Munk moment's directional instability of a
#: vehicle with more sway than surge added mass and little linear sway and yaw damping; heave-pitch, the same
#: moment in the vertical plane (more heave than surge added mass) against a weak pitch restoring moment (a
#: BlueROV2 in von Benzon et al. 2022 has both).
MODES = {"sway_yaw": (1, 5), "heave_pitch": (2, 4)}


def mode_of(vector: np.ndarray) -> str | None:
    """The declared mode (:data:`MODES`) an eigenvector (12,) of A is, by its velocities: at least 90 % of
    their squared size in the mode's (None: another motion)."""
    velocities = np.abs(np.asarray(vector)[6:]) ** 2
    total = float(velocities.sum())
    for name, indices in MODES.items():
        if total > 0.0 and float(velocities[list(indices)].sum()) >= 0.9 * total:
            return name
    return None


@dataclass
class ModelReport:
    """All findings for one configuration, plus the speed sweep and what was noted without failing."""

    config: str
    findings: list[Finding] = field(default_factory=list)
    sweep: list[tuple[float, float]] = field(default_factory=list)  # (speed, max Re(pole))
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.findings

    def by_kind(self, kind: str) -> list[Finding]:
        return [f for f in self.findings if f.kind == kind]


def _relative_asymmetry(m: np.ndarray) -> float:
    return float(np.abs(m - m.T).max() / max(np.abs(m).max(), 1e-300))


def _term_symmetry_ok(term: HydroTerm) -> bool:
    # |v| is unchanged by the mirror: only plain factors of v, p, r flip sign
    asym = sum(1 for i in term.signed if i in ASYMMETRIC)
    axis_asymmetric = term.axis in ASYMMETRIC
    return (asym % 2 == 1) == axis_asymmetric


def _term_is_damper_shaped(term: HydroTerm) -> bool:
    """True if the term always has the sign of its own axis's velocity."""
    counts = Counter(term.signed)
    own = counts.pop(term.axis, 0)
    return own % 2 == 1 and all(c % 2 == 0 for c in counts.values())


def check_hydrodynamics(terms, findings: list[Finding]) -> None:
    for t in terms:
        if not _term_symmetry_ok(t):
            n = sum(1 for i in t.signed if i in ASYMMETRIC)
            findings.append(Finding(
                "symmetry", t.name,
                f"{AXES[t.axis]} is {'asymmetric' if t.axis in ASYMMETRIC else 'symmetric'} but "
                f"{t.name} has {n} plain asymmetric factor(s) (v, p, r): a port/starboard-symmetric "
                "vehicle cannot have it"))
        if _term_is_damper_shaped(t) and t.coefficient > 0.0:
            findings.append(Finding(
                "negative-damping", t.name,
                f"{t.name} = {t.coefficient:g} > 0 always has the sign of "
                f"{VELOCITIES[t.axis]}: it feeds energy into that motion (negative damping)"))


def check_mass(model: VehicleModel, findings: list[Finding], tol: float = 1e-9) -> None:
    for name, m in (("rigid-body mass matrix", model.m_rigid), ("added-mass matrix", model.m_added),
                    ("total mass matrix", model.m_total)):
        asym = _relative_asymmetry(m)
        if asym > tol:
            i, j = np.unravel_index(np.argmax(np.abs(m - m.T)), m.shape)
            findings.append(Finding("mass-asymmetry", name,
                                    f"m[{i},{j}] = {m[i, j]:g} but m[{j},{i}] = {m[j, i]:g} "
                                    f"(relative asymmetry {asym:.2e}); Newman: must be symmetric"))
        mirrored = MIRROR[:, None] * m * MIRROR[None, :]
        if np.abs(mirrored - m).max() > tol * max(np.abs(m).max(), 1.0):
            i, j = np.unravel_index(np.argmax(np.abs(mirrored - m)), m.shape)
            findings.append(Finding("symmetry", name,
                                    f"entry [{i},{j}] = {m[i, j]:g} couples a symmetric and an "
                                    "asymmetric degree of freedom"))
    eig = np.linalg.eigvalsh(0.5 * (model.m_total + model.m_total.T))
    if eig.min() <= 0:
        findings.append(Finding("mass-not-positive", "total mass matrix",
                                f"smallest eigenvalue {eig.min():g} <= 0"))
    for name, c in (("CG", model.mass_properties.cg), ("CB", model.mass_properties.cb)):
        if abs(c[1]) > tol:
            findings.append(Finding("symmetry", name, f"{name} is off the centreline: y = {c[1]:g} m"))


def check_thrusters(model: VehicleModel, findings: list[Finding], tol: float = 1e-9) -> None:
    b = model.thrusters.matrix * model.thrusters.efficiency
    mirror = thruster_mirror(model.thrusters)
    if mirror is None:
        findings.append(Finding("symmetry", "thrusters", "some thruster has no mirror image in the body x-z plane "
                                "(a thruster at (x, -y, z) pushing along (dx, -dy, dz))"))
        return
    mirrored = MIRROR[:, None] * b[:, mirror]
    if np.abs(mirrored - b).max() > tol * max(np.abs(b).max(), 1.0):
        i, j = np.unravel_index(np.argmax(np.abs(mirrored - b)), b.shape)
        findings.append(Finding("symmetry", "thrusters",
                                f"{AXES[i]} per newton of thruster {j}: {b[i, j]:g}, but its mirror "
                                f"thruster gives {AXES[i]} {mirrored[i, j]:g} mirrored"))


def check_linear_symmetry(model: VehicleModel, findings: list[Finding], tol: float = 1e-6) -> None:
    try:
        hover = trim(model, 0.0)
    except TrimError as exc:
        findings.append(Finding("instability", "hover", f"no hover trim: {exc}"))
        return
    a, b = linearise(model, hover.state, hover.blade_pitch)
    s = np.concatenate([np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0]), MIRROR])
    a_m = s[:, None] * a * s[None, :]
    b_m = s[:, None] * (b @ model.inputs.mirror)   # the inputs' mirror: the pairs swap, or sway and yaw flip
    scale = max(np.abs(a).max(), np.abs(b).max(), 1.0)
    err = max(np.abs(a_m - a).max(), np.abs(b_m - b).max()) / scale
    if err > tol:
        findings.append(Finding("symmetry", "linearised model at hover",
                                f"A, B are not mirror-symmetric (relative error {err:.2e}): "
                                "port and starboard inputs do not act alike"))


def check_speed_range(model: VehicleModel, findings: list[Finding], speeds,
                      notes: list[str] | None = None) -> list[tuple[float, float]]:
    """Max Re(pole) of the trimmed, linearised vehicle at each speed (sec. 3.7).

    Equilibria beyond the blade limits still say whether the equations are stable. A virtual-input vehicle
    (:mod:`seapup_sim.inputs`) has no equilibrium beyond what its thrusters give: its sweep ends at its top
    speed, noted. A right-half-plane pole of a mode the description declares (``open_loop_unstable``,
    :data:`MODES`) is noted, not a finding; any other is a finding.
    """
    notes = [] if notes is None else notes
    declared = set(model.config.get("open_loop_unstable") or ())
    sweep, noted = [], {}
    try:
        for tr in trim_sweep(model, speeds):
            a, _ = linearise(model, tr.state, tr.blade_pitch)
            ev, vectors = np.linalg.eig(a)
            worst = float(ev.real.max())
            sweep.append((tr.surge_speed, worst))
            for k in np.flatnonzero(ev.real > 1e-6):
                e, mode = ev[k], mode_of(vectors[:, k])
                if mode in declared:
                    noted[mode] = max(noted.get(mode, -np.inf), float(e.real))
                    continue
                findings.append(Finding("instability", f"u = {tr.surge_speed:.2f} m/s",
                                        f"pole {e.real:+.4f}{e.imag:+.4f}j 1/s in the right half plane"
                                        + (f" (the {mode.replace('_', '-')} mode, not declared open_loop_unstable)"
                                           if mode else "")))
                break
    except TrimError as exc:
        if model.inputs.kind == "virtual" and sweep and sweep[-1][0] > 0.0:
            notes.append(f"top speed about {sweep[-1][0]:.2f} m/s: {exc} (the thrusters' full scale)")
        else:
            findings.append(Finding("instability", "speed sweep", f"no trimmed flight: {exc}"))
    for mode in sorted(noted):
        notes.append(f"open-loop unstable {mode.replace('_', '-')} mode, as the description declares "
                     f"(its largest pole real part {noted[mode]:+.4f} 1/s over the sweep)")
    for mode in sorted(declared - set(noted) - set(MODES)):
        findings.append(Finding("symmetry", "open_loop_unstable", f"unknown mode {mode!r} (known: {', '.join(MODES)})"))
    return sweep


def check_model(model: VehicleModel, speeds=None) -> ModelReport:
    """Run every check on ``model``; see the module docstring."""
    report = ModelReport(model.config_name)
    check_mass(model, report.findings)
    check_hydrodynamics(model.hydro.terms, report.findings)
    check_thrusters(model, report.findings)
    check_linear_symmetry(model, report.findings)
    speeds = np.round(np.arange(0.0, 1.0001, 0.1), 3) if speeds is None else speeds
    report.sweep = check_speed_range(model, report.findings, speeds, report.notes)
    return report
