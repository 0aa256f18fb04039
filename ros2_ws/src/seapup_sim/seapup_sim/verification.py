"""The thesis's open-loop verification of the Seapup model (sec. 3.3-3.7).

:func:`verify` runs the tests of Table 3.2 and the linear analyses on one
configuration and returns a JSON-ready dict (units: m/s, deg, deg/s, rad/s for
eigenvalues) together with the time histories for plots. The thesis's values
and tolerances are data of the run layer (``seapup_runs/data/thesis_targets.yaml``,
run ``verify:<config>``), which scores this dict; the same rows are printed by
``./seapup verify`` and plotted, so numbers and pictures never disagree.

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

import numpy as np

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_sim.analysis import (OUTPUTS, TrimError, linearise, output_matrix, system_zeros, trim_sweep,
                                 trim)
from seapup_sim.integrator import VehicleIntegrator
from seapup_sim.vehicle import VehicleModel

__all__ = ["run_open_loop", "rest_trim", "oscillatory_mode", "step_gains", "verify", "verify_current",
           "verify_umbilical"]

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
               sample_period: float = 0.2, samples: int = 51, dt: float = 0.05, state0=None):
    """B0^-1 and B1^-1 of eq. 5.3 (or 5.7) from open-loop steps about an operating point.

    As in sec. 5.3.1: start at the operating point -- at rest with u = u0 (hover), or in the trimmed
    ``state0`` with its blade pitch ``hover`` (eq. 5.7: 0.7 m/s) -- and step thruster j by
    ``step_deg``; B0^-1[i, j] is the change of output i one sample period after the step,
    B1^-1[i, j] its change at the end of the test (``samples`` samples at 5 Hz: 10 s, the
    self-test length), both per degree of blade pitch. Outputs u, v, w [m/s] and r [deg/s].
    ``dt`` divides the sample period.
    """
    per_sample = int(round(sample_period / dt))
    b0, b1 = np.zeros((4, 4)), np.zeros((4, 4))
    y0 = np.zeros(4) if state0 is None else np.asarray(state0, float)[list(OUTPUTS)].copy()
    y0[3] = np.degrees(y0[3])
    for j in range(4):
        cmd = hover.copy()
        cmd[j] += D(step_deg)
        _, x, _ = run_open_loop(model, cmd, (samples - 1) * sample_period, state0=state0, pitch0=hover, dt=dt)
        y = x[:, list(OUTPUTS)].copy()
        y[:, 3] = np.degrees(y[:, 3])
        b0[:, j] = (y[per_sample] - y0) / step_deg
        b1[:, j] = (y[-1] - y0) / step_deg
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
    return {"stable": stable, "eigenvalue": [ev.real, ev.imag], "natural_frequency": abs(ev),
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
    # App. A.3's trial 2, the 'climb': full surge and full negative (upward) heave input (Table A.1 row 1)
    t, x, _ = run_open_loop(model, np.array([lim, lim, -lim, -lim]), duration)
    hist["climb"] = (t, x)
    res["climb"] = {"max_pitch_deg": float(np.degrees(x[:, 4].max())), "max_u": float(x[:, 6].max()),
                    "max_rise_w": float((-x[:, 8]).max())}
    # trial 5, the 'high speed turn': full surge and full yaw input (Table A.1 row 5). The thesis does not say
    # how the two demands share the mains; mixed as port = surge + yaw, starboard = surge - yaw, each clipped to
    # the blade limit, the port main runs full ahead and the starboard one stops: a turn to starboard
    t, x, _ = run_open_loop(model, np.array([lim, 0.0, 0.0, 0.0]), duration)
    hist["fast_turn"] = (t, x)
    res["fast_turn"] = {"max_r_dps": float(np.degrees(x[:, 11].max())), "max_u": float(x[:, 6].max()),
                        "max_roll_deg": float(np.degrees(np.abs(x[:, 3]).max()))}
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
    if "error" not in res["trim_0_7"]:  # eq. 5.7: the same steps about level flight at 0.7 m/s
        b0, b1 = step_gains(model, t07.blade_pitch, state0=t07.state)
        res["step_gains_0_7_5hz"] = {"B0inv": b0.tolist(), "B1inv": b1.tolist()}
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
