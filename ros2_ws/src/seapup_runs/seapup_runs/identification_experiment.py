"""The identification experiments of thesis sec. 6.5 as run specifications, and their records as identification data.

An experiment is a :class:`~seapup_runs.spec.RunSpec` like any run, so it is flown in this process by
:func:`seapup_runs.runner.run` or on the ROS graph (``./seapup ident experiment``, whose simulator, open-loop or
controller and reference nodes take the same numbers), and the two records are the same sample for sample
(tested on the graph for the open loop, the linearised model in current and the closed loop):

- **open loop** (sec. 6.5.1-6.5.4): every thruster holds a PRBS of +-``amplitude`` about the hover setting
  (eq. 5.2) switching at most every ``clock`` samples (:func:`seapup_ident.prbs.prbs`, sec. 6.2.1), flown
  by the ``open_loop`` controller type on the nonlinear model (ch. 2) or eq. 3.2 linearised about hover,
  optionally in the Gauss-Markov current of sec. 6.5.4 (eq. 2.30-2.33);
- **closed loop** (sec. 6.5.5): the fixed-gain self-tested controller (eq. 5.6, gains from a self-test
  result) following a square wave between two body-velocity references.

:func:`identification_data` turns a flown record into ch. 6's data with the convention of the graph's bags
(:func:`seapup_ident.online.held_inputs`): y(t_k) is what the instruments measured at sample k (velocity log
u, v, w, yaw rate r; roll and pitch from the attitude sensor), u(t_k) the blade pitch the vehicle applied
over [t_k, t_k+1], read at t_k+1; the last sample, whose interval the record does not cover, is left out.
"""
from __future__ import annotations

import math

import numpy as np

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT, THRUSTER_NAMES
from seapup_common.controllers import ControllerSpec
from seapup_runs.spec import ReferenceSteps, RunSpec, RunSpecError

__all__ = ["EXPERIMENT_PERIOD", "OUTPUT_SETS", "MAX_EXPERIMENT_SECONDS", "experiment_samples", "prbs_schedule",
           "square_wave", "experiment_spec", "identification_data"]

#: The experiment's sample period [s]: the 5 Hz control rate of sec. 5.1 at which ch. 6 identifies.
EXPERIMENT_PERIOD = 0.2
#: Output sets: ch. 6 (surge, sway, heave, yaw velocities, roll, pitch) and ch. 7 (u, v, w, r).
OUTPUT_SETS = {"ch6": ("u", "v", "w", "r", "roll", "pitch"), "ch7": ("u", "v", "w", "r")}
#: The longest experiment [s]: 10^5 samples at 5 Hz (the thesis's records are 60 s), checked before the PRBS or a
#: reference step is allocated; a run's own bound (``seapup_runs.spec.MAX_RUN_SAMPLES``) applies too.
MAX_EXPERIMENT_SECONDS = 2.0e4


def experiment_samples(duration: float, period: float = EXPERIMENT_PERIOD) -> int:
    """D / T: the sample intervals an experiment of ``duration`` seconds flies (its record holds one more
    sample, t = D). Raises ValueError unless D is a positive whole number of periods, at most
    :data:`MAX_EXPERIMENT_SECONDS`."""
    if not (isinstance(duration, (int, float)) and not isinstance(duration, bool)):
        raise ValueError(f"--duration must be a number of seconds, got {duration!r}")
    if math.isfinite(duration) and duration > MAX_EXPERIMENT_SECONDS:
        raise ValueError(f"--duration {duration:g} s is longer than the {MAX_EXPERIMENT_SECONDS:g} s an "
                         "identification experiment may fly (docs/limits.md)")
    count = round(duration / period) if math.isfinite(duration) else 0
    if not (count >= 1 and abs(count * period - duration) <= 1e-9 * max(1.0, duration)):
        raise ValueError(f"--duration must be > 0 s and a whole number of {period:g} s sample periods, "
                         f"got {duration}")
    return int(count)


def prbs_schedule(vehicle: str, duration: float, clock: int = 10, amplitude_deg: float = 10.0) -> dict:
    """The open-loop excitation of sec. 6.5.1-6.5.4: a PRBS of +-``amplitude_deg`` about ``vehicle``'s hover
    setting on each thruster, as the switching times [s] and the four pitches [rad] per time that the
    ``open_loop`` controller (and node) holds.

    Returns
    -------
    dict
        ``times`` (list of s), ``pitches`` (4 per time, flat, rad), ``switches``.
    """
    from seapup_ident.prbs import prbs
    from seapup_sim.hover import hover_of
    from seapup_sim.vehicle_config import load_vehicle_config
    if not (isinstance(clock, int) and not isinstance(clock, bool) and clock >= 1):
        raise ValueError(f"--clock must be a whole number of samples >= 1, got {clock!r}")
    limit = math.degrees(BLADE_PITCH_LIMIT)
    if not (isinstance(amplitude_deg, (int, float)) and math.isfinite(amplitude_deg)
            and 0 < amplitude_deg <= limit + 1e-9):
        raise ValueError(f"--amplitude must be in (0, {limit:g}] deg (the blade-pitch limit, sec. 3.1), "
                         f"got {amplitude_deg}")
    samples = experiment_samples(duration)
    hover = hover_of(load_vehicle_config(vehicle))
    signal = prbs(samples, clock=clock, amplitude=math.radians(amplitude_deg), n_inputs=4, offset=hover)
    if np.any(np.abs(signal) > BLADE_PITCH_LIMIT + 1e-12):
        raise ValueError(f"a PRBS of +-{amplitude_deg:g} deg about {vehicle}'s hover setting "
                         f"({', '.join(f'{math.degrees(v):.1f}' for v in hover)} deg) leaves the +-{limit:g} deg "
                         "blade-pitch limit (sec. 3.1): lower --amplitude")
    switches = np.flatnonzero(np.r_[True, np.any(np.diff(signal, axis=0) != 0, axis=1)])
    return {"times": [round(float(k) * EXPERIMENT_PERIOD, 6) for k in switches],
            "pitches": [float(v) for k in switches for v in signal[k]], "switches": int(len(switches))}


def square_wave(levels, half_period: float, duration: float) -> ReferenceSteps:
    """Sec. 6.5.5's reference: ``levels[0]`` from t = 0, ``levels[1]`` from ``half_period``, and so on over
    ``duration`` (each level u, v, w [m/s], r [rad/s])."""
    if len(levels) != 2 or any(len(level) != 4 for level in levels):
        raise ValueError(f"a square wave needs two levels of four values (u, v, w, r), got {levels!r}")
    if not (isinstance(half_period, (int, float)) and math.isfinite(half_period) and half_period > 0):
        raise ValueError(f"--half-period must be > 0 s, got {half_period}")
    experiment_samples(duration)   # bounded before the steps are listed
    if duration / half_period > 10**5:
        raise ValueError(f"--half-period {half_period:g} s switches more than 10^5 times in {duration:g} s")
    steps = [(k * float(half_period), tuple(float(v) for v in levels[k % 2]))
             for k in range(int(math.floor(duration / half_period + 1e-9)) + 1)]
    return ReferenceSteps(tuple(steps))


def experiment_spec(*, vehicle: str = "baseline", dynamics: str = "nonlinear", seed: int = 0, current: bool = False,
                    sensors: str = "baseline", duration: float = 60.0, start_depth: float = 50.0,
                    schedule: dict | None = None, controller_file: str | None = None,
                    reference: ReferenceSteps | None = None, name: str = "identification experiment") -> RunSpec:
    """The experiment as a run: open loop when ``schedule`` (:func:`prbs_schedule`) is given, else the
    fixed-gain MFOL of ``controller_file`` (a self-test result) following ``reference`` (:func:`square_wave`).

    Raises
    ------
    ValueError
        Neither or both excitations, or what :class:`RunSpec` refuses (named).
    """
    if (schedule is None) == (controller_file is None):
        raise ValueError("an identification experiment is open loop (a PRBS schedule) or closed loop (a controller "
                         "file and a reference), one of the two")
    experiment_samples(duration)
    if schedule is not None:
        controller = ControllerSpec("open_loop", {"times": list(schedule["times"]),
                                                  "pitches": list(schedule["pitches"])})
        reference = ReferenceSteps()
    else:
        controller = ControllerSpec("mfol", {}, str(controller_file))
        if reference is None:
            raise ValueError("a closed-loop experiment needs its reference (square_wave)")
    environment = {"sensors": sensors, "current": {"enabled": bool(current)}}
    try:
        return RunSpec(name=name, vehicle=vehicle, dynamics=dynamics, environment=environment,
                       control_period=EXPERIMENT_PERIOD, duration=float(duration), start_depth=start_depth,
                       controller=controller, reference=reference, seed=int(seed), metrics=())
    except RunSpecError as exc:
        raise ValueError(str(exc)) from None


def identification_data(result, outputs=OUTPUT_SETS["ch6"]):
    """Ch. 6's data from a flown record (a :class:`~seapup_runs.result.RunResult`, in process or read from a
    graph run): the samples t_0 .. t_N-1 with their measured outputs and the applied blade pitch held over
    each interval (see the module docstring). An invalid measurement is NaN (reported, never used).

    Raises
    ------
    ValueError
        An output the record does not measure, or a record of fewer than two samples.
    """
    from seapup_ident.identify import IdentificationData
    unknown = [name for name in outputs if name not in OUTPUT_SETS["ch6"]]
    if unknown:
        raise ValueError(f"unknown output(s) {unknown}; choose from {', '.join(OUTPUT_SETS['ch6'])}")
    series = result.series
    if len(series.t) < 2:
        raise ValueError(f"a record of {len(series.t)} sample(s) has no input interval to identify from")
    y = np.column_stack([np.asarray(series.measured[name], float)[:-1] for name in outputs])
    u = np.asarray(series.applied, float)[1:]
    return IdentificationData(y, u, np.asarray(series.t, float)[:-1], tuple(outputs), THRUSTER_NAMES)
