"""The thesis's open-loop verification of the Seapup model (sec. 3.3-3.7).

:func:`verify` runs the tests of Table 3.2 and the linear analyses on one
configuration and returns a JSON-ready dict (units: m/s, deg, deg/s, rad/s for
eigenvalues) together with the time histories for plots. :data:`TARGETS`
holds the thesis values and tolerances that :func:`check_targets` turns into
PASS/FAIL rows; the same rows are printed by ``./seapup verify`` and plotted,
so numbers and pictures never disagree.

Table 3.2 (thruster order main port, main starboard, vectored starboard,
vectored port):

===========  =====================================  ==============================
test         inputs                                 outputs
===========  =====================================  ==============================
1 roll       thrusters disabled, roll(0) = 24 deg   transient (stable, oscillatory)
2 pitch      thrusters disabled, pitch(0) = 22 deg  transient
3 surge      mains +35, vectored 0                  top speed, impulsive-start pitch
4a / 4b      vectored +35/-35 (4b: -35/+35)         max roll, roll rate, sway speed
5a / 5b      vectored +35/+35 (5b: -35/-35)         max heave speed down / up
===========  =====================================  ==============================
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_sim.analysis import (OUTPUTS, TrimError, linearise, output_matrix, system_zeros, trim_sweep,
                                 trim)
from seapup_sim.integrator import VehicleIntegrator
from seapup_sim.vehicle import VehicleModel

__all__ = ["run_open_loop", "rest_trim", "oscillatory_mode", "step_gains", "verify", "verify_current",
           "verify_umbilical", "Target", "TARGETS", "check_targets", "summary"]

D = math.radians


def run_open_loop(model: VehicleModel, command, duration: float, state0=None, pitch0=None,
                  thrusters_on: bool = True, dt: float = 0.1):
    """Integrate with a constant blade-pitch command; return (t, states, pitches)."""
    n = int(round(duration / dt))
    integrator = VehicleIntegrator(model, dt=dt, state=state0,
                            pitch=command if pitch0 is None else pitch0)
    integrator.thrusters_on = thrusters_on
    t = np.arange(n + 1) * dt
    states = np.empty((n + 1, 12))
    pitches = np.empty((n + 1, 4))
    states[0], pitches[0] = integrator.state, integrator.pitch
    for k in range(1, n + 1):
        states[k] = integrator.step(command)
        pitches[k] = integrator.pitch
    return t, states, pitches


def rest_trim(model: VehicleModel) -> float:
    """Pitch angle [rad] at rest with thrusters disabled: the hydrostatic pitch
    moment about the body origin vanishes (sec. 3.6: 0.0 deg baseline,
    -6.3 deg with the camera)."""
    mp = model.mass_properties
    moment_x = mp.cg[0] * model.weight - mp.cb[0] * model.buoyancy
    moment_z = mp.cg[2] * model.weight - mp.cb[2] * model.buoyancy
    return math.atan2(-moment_x, moment_z)


def step_gains(model: VehicleModel, hover: np.ndarray, step_deg: float = 8.0,
               sample_period: float = 0.2, samples: int = 51, dt: float = 0.05):
    """B0^-1 and B1^-1 of eq. 5.3 from open-loop steps about the hover setting.

    As in sec. 5.3.1: start at rest with u = u0 (hover), step thruster j by
    ``step_deg``; B0^-1[i, j] is output i one sample period after the step,
    B1^-1[i, j] its value at the end of the test (``samples`` samples at 5 Hz:
    10 s, the self-test length), both per degree of blade pitch. Outputs
    u, v, w [m/s] and r [deg/s]. ``dt`` divides the sample period.
    """
    per_sample = int(round(sample_period / dt))
    b0, b1 = np.zeros((4, 4)), np.zeros((4, 4))
    for j in range(4):
        cmd = hover.copy()
        cmd[j] += D(step_deg)
        _, x, _ = run_open_loop(model, cmd, (samples - 1) * sample_period, pitch0=hover, dt=dt)
        y = x[:, list(OUTPUTS)].copy()
        y[:, 3] = np.degrees(y[:, 3])
        b0[:, j] = y[per_sample] / step_deg
        b1[:, j] = y[-1] / step_deg
    return b0, b1


def oscillatory_mode(a: np.ndarray, state_index: int) -> complex:
    """The oscillatory eigenvalue whose eigenvector is dominated by one state."""
    w, v = np.linalg.eig(a)
    best, score = 0j, -1.0
    for k in range(len(w)):
        if w[k].imag <= 1e-9:
            continue
        col = np.abs(v[:, k])
        share = col[state_index] / (col[3:].sum() + 1e-300)
        if share > score:
            best, score = complex(w[k]), share
    return best


def _trims_until_failure(model: VehicleModel, speeds):
    """The trims of :func:`trim_sweep` up to the first speed without one."""
    try:
        yield from trim_sweep(model, speeds)
    except TrimError:
        return


def _release_test(model, index: int, angle_deg: float, duration: float = 40.0):
    x0 = np.zeros(12)
    x0[index] = D(angle_deg)
    t, x, _ = run_open_loop(model, np.zeros(4), duration, state0=x0, thrusters_on=False)
    a, _ = linearise(model, np.zeros(12), np.zeros(4), thrusters_on=False)
    ev = oscillatory_mode(a, index)
    tail = np.abs(x[t >= duration - 10.0, index]).max()
    stable = bool(tail < 0.2 * D(angle_deg) and np.all(np.isfinite(x)))
    return {"stable": stable, "eigenvalue": [ev.real, ev.imag],
            "final_deg": float(np.degrees(x[-1, index]))}, (t, x)


def _rise_time(t, y, fraction=0.95):
    final = y[-1]
    above = np.flatnonzero(y >= fraction * final)
    return float(t[above[0]]) if above.size else float("nan")


def verify(model: VehicleModel, duration: float = 30.0, loci_speeds=None) -> tuple[dict, dict]:
    """Run the verification; return (results JSON dict, time histories)."""
    res: dict = {"config": model.config_name}
    hist: dict = {}
    res["rest_trim_deg"] = math.degrees(rest_trim(model))
    res["roll_release"], hist["roll_release"] = _release_test(model, 3, 24.0)
    res["pitch_release"], hist["pitch_release"] = _release_test(model, 4, 22.0)

    lim = BLADE_PITCH_LIMIT
    t, x, _ = run_open_loop(model, np.array([lim, lim, 0.0, 0.0]), duration)
    hist["surge"] = (t, x)
    u = x[:, 6]
    res["surge"] = {"max_u": float(u.max()), "steady_pitch_deg": float(np.degrees(x[-1, 4])),
                    "max_pitch_deg": float(np.degrees(x[:, 4].max())),
                    "max_pitch_rate_dps": float(np.degrees(x[:, 10].max())),
                    "rise95_s": _rise_time(t, u)}
    for name, cmd in (("sway_4a", [0.0, 0.0, lim, -lim]), ("sway_4b", [0.0, 0.0, -lim, lim])):
        t, x, _ = run_open_loop(model, np.array(cmd), duration)
        hist[name] = (t, x)
        res[name] = {"max_v": float(np.abs(x[:, 7]).max()),
                     "max_roll_deg": float(np.degrees(np.abs(x[:, 3]).max())),
                     "max_roll_rate_dps": float(np.degrees(np.abs(x[:, 9]).max()))}
    # full yaw input from rest, the zero-radius turn of App. A.3 / Table A.1: mains push-pull, vectored 0
    for name, cmd, sign in (("yaw_starboard", [lim, -lim, 0.0, 0.0], 1.0), ("yaw_port", [-lim, lim, 0.0, 0.0], -1.0)):
        t, x, _ = run_open_loop(model, np.array(cmd), duration)
        hist[name] = (t, x)
        res[name] = {"max_r_dps": float(np.degrees((sign * x[:, 11]).max())),
                     "max_roll_deg": float(np.degrees(np.abs(x[:, 3]).max())),
                     "max_pitch_rate_dps": float(np.degrees(np.abs(x[:, 10]).max()))}
    for name, cmd, sign in (("heave_down", [0.0, 0.0, lim, lim], 1.0),
                            ("heave_up", [0.0, 0.0, -lim, -lim], -1.0)):
        t, x, _ = run_open_loop(model, np.array(cmd), duration)
        hist[name] = (t, x)
        res[name] = {"max_w": float((sign * x[:, 8]).max())}
    mirror = np.array([1, -1, 1, -1, 1, -1, 1, -1, 1, -1, 1, -1], float)
    res["sway_mirror_error"] = float(np.abs(hist["sway_4a"][1] - mirror * hist["sway_4b"][1]).max())

    hover = trim(model, 0.0)
    res["hover_blade_pitch_deg"] = np.degrees(hover.blade_pitch).tolist()
    res["hover_pitch_deg"] = math.degrees(hover.pitch_angle)
    try:
        t07 = trim(model, 0.7, hover.unknowns)
        res["trim_0_7"] = {"pitch_deg": math.degrees(t07.pitch_angle),
                           "blade_pitch_deg": np.degrees(t07.blade_pitch).tolist()}
    except TrimError as exc:
        res["trim_0_7"] = {"error": str(exc)}
    a, b = linearise(model, hover.state, hover.blade_pitch)
    ev = np.linalg.eigvals(a)
    res["eigenvalues_quiescent"] = sorted([[float(e.real), float(e.imag)] for e in ev])
    res["zero_eigenvalues_quiescent"] = int(np.sum(np.abs(ev) < 1e-6))

    speeds = np.round(np.arange(0.0, 1.0001, 0.05), 3) if loci_speeds is None else loci_speeds
    loci, onset, max_real, beyond = [], None, -np.inf, None
    c = output_matrix()
    for tr in _trims_until_failure(model, speeds):
        s = tr.surge_speed
        if not tr.within_limits and beyond is None:
            beyond = float(s)
        a_s, b_s = linearise(model, tr.state, tr.blade_pitch)
        ev_s = np.linalg.eigvals(a_s)
        zs = [z.value for z in system_zeros(a_s, b_s, c) if z.kind == "transmission"]
        max_real = max(max_real, float(ev_s.real.max()))
        if onset is None and any(z.real > 0 for z in zs):
            onset = float(s)
        loci.append({"surge_speed": float(s), "pitch_deg": math.degrees(tr.pitch_angle),
                     "blade_pitch_deg": np.degrees(tr.blade_pitch).tolist(),
                     "within_blade_limits": tr.within_limits,
                     "eigenvalues": [[e.real, e.imag] for e in ev_s],
                     "transmission_zeros": [[z.real, z.imag] for z in zs]})
    res["loci_max_speed"] = loci[-1]["surge_speed"] if loci else None
    # from this speed on, level trimmed flight needs blade pitch beyond +/-35 deg
    res["trim_beyond_blade_limits_from"] = beyond
    res["max_real_eigenvalue_0_1"] = max_real
    res["nmp_onset_surge"] = onset
    hist["loci"] = loci

    b0, b1 = step_gains(model, hover.blade_pitch)
    res["step_gains_5hz"] = {"B0inv": b0.tolist(), "B1inv": b1.tolist()}
    res["current"], hist["current"] = verify_current()
    res["umbilical"], hist["umbilical"] = verify_umbilical(model)
    return res, hist


def verify_current(seed: int = 1, realisations: int = 100, seconds: float = 300.0):
    """Sec. 3.9: coefficients for the thesis's parameters and long-run statistics.

    Also returns a 40 s realisation (201 samples, fig. 3.12a) and the mean FFT
    magnitude of 30 realisations of 256 samples (fig. 3.12b).
    """
    from seapup_sim.current import GaussMarkovCurrent, coefficients
    from seapup_sim.environment_config import load_environment
    params, ts = load_environment().current.params, 0.2
    c = coefficients(params, ts)
    rng = np.random.default_rng(seed)
    n = int(round(seconds / ts))
    speeds = np.empty((realisations, n))
    for k in range(realisations):
        speeds[k] = GaussMarkovCurrent(params, ts, rng, start_at_mean=False).sample(n)[:, 0]
    example = GaussMarkovCurrent(params, ts, rng).sample(201)
    spectra = np.array([np.abs(np.fft.rfft(GaussMarkovCurrent(params, ts, rng).sample(256)[:, 0])) / 256
                        for _ in range(30)]).mean(axis=0)
    res = {"a_c": c.a_c, "b": c.b, "d": c.d, "E_wc2": c.var_w_c,
           "w_alpha_per_w_c": math.degrees(c.w_alpha_per_w_c),
           "sample_mean": float(speeds.mean()), "sample_std": float(speeds.std())}
    return res, {"example": example, "spectrum": spectra, "sample_time": ts}


def verify_umbilical(model: VehicleModel, depths=(50.0, 100.0, 200.0), duration: float = 40.0):
    """Sec. 3.8: surge test (Table 3.2 no. 3) with the cable, ship above at the start.

    Returns, per depth, the top speed and the cable force on the vehicle in
    body axes [N] at that moment.
    """
    from seapup_sim.environment_config import load_environment
    from seapup_sim.simulation import Simulation
    cable_config = load_environment(rho=model.rho).umbilical
    lim = BLADE_PITCH_LIMIT
    cmd = np.array([lim, lim, 0.0, 0.0])
    out, shapes = {}, {}
    for depth in depths:
        x0 = np.zeros(12)
        x0[2] = depth
        cable = cable_config.build()
        simulation = Simulation(model, umbilical=cable, state=x0, pitch=cmd)
        shape, best = None, -1.0
        n = int(round(duration / simulation.control_period))
        for _ in range(n):
            simulation.advance(cmd)
            if simulation.plant.state[6] > best:
                best = float(simulation.plant.state[6])
                force = simulation.umbilical.wrench(simulation.plant.state)[:3]
                shape = cable.solution.shape(60) if not cable.solution.bypassed else None
        out[f"{depth:g}"] = {"max_u": best, "Fx": float(force[0]), "Fz": float(force[2])}
        shapes[f"{depth:g}"] = shape
    return out, shapes


@dataclass(frozen=True)
class Target:
    """One thesis number: where it is in the results, the value and a tolerance."""

    key: str
    label: str
    thesis: float
    low: float
    high: float
    primary: bool
    source: str
    #: A documented deviation: why the model does not reach this number (one line, with a pointer to
    #: its entry in the deviation register, docs/decisions.md). Shown as DEV, kept in the JSON, never a
    #: reason to exit 1.
    deviation: str = ""

    def value(self, res: dict):
        node = res
        for part in self.key.split("."):
            if isinstance(node, dict):
                node = node.get(part)
            elif isinstance(node, list):
                node = node[int(part)]
            if node is None:
                return None
        return node

    def check(self, res: dict) -> tuple[float | None, bool]:
        v = self.value(res)
        if isinstance(v, bool):
            return float(v), bool(v)
        if v is None or not math.isfinite(float(v)):
            return None, False
        return float(v), self.low <= float(v) <= self.high


def _rel(key, label, value, tol, primary, source, deviation=""):
    lo, hi = sorted((value * (1 - tol), value * (1 + tol)))
    return Target(key, label, value, lo, hi, primary, source, deviation)


#: Why the camera's crossover comes later than the thesis's (issue 11).
CAMERA_NMP_DEVIATION = ("the bow payload's own heave-pitch added mass and its forward CG stabilise the pitch "
                        "zero dynamics, so the camera crosses after the baseline, not before; "
                        "docs/decisions.md#camera-crossover")

#: Why the umbilical table's F_z is not reached (issue 11 decided to keep the exact cable solution).
UMBILICAL_FZ_DEVIATION = ("exact solution of the thesis's stated cable assumptions leaves the cable ~26 deg above "
                          "horizontal where the table implies ~35 deg; docs/decisions.md#umbilical-fz")


def _abs(key, label, value, tol, primary, source):
    return Target(key, label, value, value - tol, value + tol, primary, source)


TARGETS = {
    "baseline": [
        _rel("surge.max_u", "surge top speed [m/s]", 0.98, 0.05, True, "sec. 3.5"),
        _abs("surge.steady_pitch_deg", "surge steady pitch [deg]", 27.4, 3.0, True, "sec. 3.6"),
        _rel("sway_4a.max_v", "sway 4a top speed [m/s]", 0.34, 0.10, True, "sec. 3.5"),
        _abs("sway_4a.max_roll_deg", "sway 4a max roll [deg]", 24.8, 3.0, True, "sec. 3.5"),
        _abs("sway_mirror_error", "4a/4b mirror error", 0.0, 1e-9, True, "symmetry"),
        _rel("heave_down.max_w", "heave down [m/s]", 0.33, 0.10, True, "sec. 3.5"),
        _abs("heave_up.max_w", "heave up [m/s]", 0.17, 0.05, True, "sec. 3.5"),
        Target("roll_release.stable", "roll release stable", 1, 1, 1, True, "fig. 3.2"),
        Target("pitch_release.stable", "pitch release stable", 1, 1, 1, True, "fig. 3.3"),
        _rel("roll_release.eigenvalue.1", "roll mode frequency [rad/s]", 2.56, 0.15, True, "App. A.3"),
        Target("roll_release.eigenvalue.0", "roll mode real part [1/s]", -0.185, -0.37, -0.0925, True, "App. A.3"),
        _rel("pitch_release.eigenvalue.1", "pitch mode frequency [rad/s]", 1.46, 0.15, True, "App. A.3"),
        Target("pitch_release.eigenvalue.0", "pitch mode real part [1/s]", -0.167, -0.334, -0.0835, True, "App. A.3"),
        _abs("hover_blade_pitch_deg.0", "hover main port [deg]", -3.38, 1.5, True, "eq. 5.2"),
        _abs("hover_blade_pitch_deg.1", "hover main stbd [deg]", -3.38, 1.5, True, "eq. 5.2"),
        _abs("hover_blade_pitch_deg.2", "hover vect stbd [deg]", -13.10, 1.5, True, "eq. 5.2"),
        _abs("hover_blade_pitch_deg.3", "hover vect port [deg]", -13.10, 1.5, True, "eq. 5.2"),
        _abs("zero_eigenvalues_quiescent", "zero eigenvalues at rest", 4, 0, True, "sec. 3.2"),
        Target("max_real_eigenvalue_0_1", "max Re(pole) over 0-1 m/s", 0.0, -np.inf, 1e-9, True, "sec. 3.7"),
        _abs("loci_max_speed", "poles/zeros computed up to [m/s]", 1.0, 0.0, True, "sec. 3.7"),
        _abs("rest_trim_deg", "rest trim [deg]", 0.0, 1.0, True, "sec. 3.6"),
        _abs("surge.max_pitch_deg", "impulsive start max pitch [deg]", 32.5, 3.0, False, "sec. 3.5"),
        _rel("surge.max_pitch_rate_dps", "impulsive start max pitch rate [deg/s]", 23.2, 0.2, False, "sec. 3.5"),
        _rel("sway_4a.max_roll_rate_dps", "sway max roll rate [deg/s]", 32.7, 0.2, False, "sec. 3.5"),
        _rel("surge.rise95_s", "surge 95% rise time [s]", 2.2, 0.25, False, "sec. 3.6"),
        _abs("trim_0_7.pitch_deg", "trim 0.7 m/s pitch [deg]", 10.0, 3.0, False, "sec. 3.7"),
        _abs("trim_0_7.blade_pitch_deg.0", "trim 0.7 m/s mains [deg]", 14.6, 3.0, False, "sec. 3.7"),
        _abs("trim_0_7.blade_pitch_deg.2", "trim 0.7 m/s vectored [deg]", -5.9, 3.0, False, "sec. 3.7"),
        _abs("nmp_onset_surge", "non-minimum phase from [m/s]", 0.7, 0.1, True, "sec. 3.7"),
        # large amplitude (issue 11): the vehicle's measured zero-radius turn
        _rel("yaw_starboard.max_r_dps", "full yaw to stbd: max yaw rate [deg/s]", 53.3, 0.15, True,
             "App. A.3 (gyro; timed 53.0)"),
        _rel("yaw_port.max_r_dps", "full yaw to port: max yaw rate [deg/s]", 50.0, 0.15, True,
             "App. A.3 (gyro; timed 51.7)"),
        _abs("yaw_starboard.max_roll_deg", "zero-radius turn max roll [deg]", 4.9, 1.5, False,
             "Table A.1 (b) 3: 6.2/3.6"),
        _rel("yaw_starboard.max_pitch_rate_dps", "zero-radius turn max pitch rate [deg/s]", 9.6, 0.3, False,
             "Table A.1 (b) 4: 9.8/9.4"),
        _rel("step_gains_5hz.B1inv.0.0", "B1inv[u, main port]", 0.0246, 0.5, False, "eq. 5.3b"),
        _rel("step_gains_5hz.B1inv.3.0", "B1inv[r, main port] [deg/s/deg]", 1.96, 0.5, False, "eq. 5.3b"),
        _rel("step_gains_5hz.B1inv.2.2", "B1inv[w, vect stbd]", 0.004875, 0.5, False, "eq. 5.3b"),
        Target("step_gains_5hz.B1inv.1.2", "B1inv[v, vect stbd]", -0.00766, -0.01149, -0.00511, False, "eq. 5.3b"),
    ] + [
        # stochastic current (sec. 3.9, eq. 3.13-3.14): b, d, a_c to 6 significant figures;
        # E{w_c^2} and w_alpha/w_c from the formulas, within 0.1 % of the printed values
        _abs("current.b", "current b", 0.9801987, 5e-7, True, "eq. 3.13"),
        _abs("current.d", "current d", 0.0198013, 5e-8, True, "eq. 3.13"),
        _abs("current.a_c", "current a_c", 0.0051483, 5e-8, True, "eq. 3.13"),
        _rel("current.E_wc2", "current E{w_c^2}", 0.739269, 1e-3, True, "eq. 3.14"),
        _rel("current.w_alpha_per_w_c", "current w_alpha / w_c [deg per m/s]", 232.546, 1e-3, True, "eq. 3.14"),
        _rel("current.sample_mean", "current long-run mean [m/s]", 0.26, 0.03, True, "sec. 3.9"),
        _rel("current.sample_std", "current long-run std [m/s]", 0.086, 0.05, True, "sec. 3.9"),
    ] + [
        target for depth, (u, fx, fz) in (("50", (0.474, -148.0, -104.0)), ("100", (0.354, -163.0, -112.0)),
                                          ("200", (0.259, -172.0, -119.0)))
        for target in (_rel(f"umbilical.{depth}.max_u", f"umbilical {depth} m: top speed [m/s]", u, 0.10, True, "sec. 3.8"),
                       _rel(f"umbilical.{depth}.Fx", f"umbilical {depth} m: F_x [N]", fx, 0.15, True, "sec. 3.8"),
                       _rel(f"umbilical.{depth}.Fz", f"umbilical {depth} m: F_z [N]", fz, 0.15, False, "sec. 3.8",
                            UMBILICAL_FZ_DEVIATION))
    ],
    "camera": [
        _abs("rest_trim_deg", "rest trim [deg]", -6.3, 1.0, True, "sec. 3.6"),
        _rel("surge.max_u", "surge top speed [m/s]", 1.13, 0.05, False, "sec. 3.6"),
        _abs("surge.steady_pitch_deg", "surge steady pitch [deg]", 20.8, 3.0, False, "sec. 3.6"),
        _rel("surge.rise95_s", "surge 95% rise time [s]", 2.8, 0.25, False, "sec. 3.6"),
        _rel("heave_down.max_w", "heave down [m/s]", 0.35, 0.10, False, "sec. 3.6"),
        _abs("heave_up.max_w", "heave up [m/s]", 0.14, 0.05, False, "sec. 3.6"),
        _rel("sway_4a.max_v", "sway top speed [m/s]", 0.35, 0.10, False, "sec. 3.6"),
        _abs("sway_4a.max_roll_deg", "sway max roll [deg]", 22.6, 3.0, False, "sec. 3.6"),
        _rel("sway_4a.max_roll_rate_dps", "sway max roll rate [deg/s]", 29.4, 0.2, False, "sec. 3.6"),
        Target("nmp_onset_surge", "non-minimum phase from [m/s]", 0.45, 0.35, 0.55, False, "sec. 3.7, 5.5",
               CAMERA_NMP_DEVIATION),
    ],
}


def check_targets(res: dict, config: str) -> list[dict]:
    """Rows for the targets of ``config`` ('baseline' or 'camera'): ``status`` PASS, FAIL, or DEV (a
    documented deviation that is missed; its ``deviation`` says why). ``primary`` is false for a
    documented deviation: only primary rows decide ``./seapup verify``'s exit status."""
    rows = []
    for tg in TARGETS.get(config, []):
        value, ok = tg.check(res)
        status = "PASS" if ok else ("DEV" if tg.deviation else "FAIL")
        rows.append({"label": tg.label, "key": tg.key, "value": value, "thesis": tg.thesis,
                     "low": tg.low, "high": tg.high, "primary": tg.primary and not tg.deviation, "pass": ok,
                     "status": status, "deviation": tg.deviation, "source": tg.source})
    return rows


def summary(rows: list[dict]) -> dict:
    """Counts of what passed: primaries, secondaries, documented deviations; ``ok`` iff every primary passed."""
    primary = [r for r in rows if r["primary"]]
    secondary = [r for r in rows if not r["primary"] and not r["deviation"]]
    deviations = [r for r in rows if r["deviation"]]
    return {"primary_passed": sum(r["pass"] for r in primary), "primary": len(primary),
            "secondary_passed": sum(r["pass"] for r in secondary), "secondary": len(secondary),
            "deviations": sum(not r["pass"] for r in deviations),
            "ok": all(r["pass"] for r in primary)}
