"""Randomised self-tuner runs: one of chapter 7's cases with the vehicle, a thruster's fouling (time and size),
the bow camera fitted mid-run, the current, the sensor profile, the law's settings and the seeds drawn at random.

Chapter 7 flies each case once; a self-tuner in service meets the cases' combinations. :func:`random_adaptive_spec`
turns one integer into one such :class:`~seapup_runs.spec.RunSpec` (the same integer, the same run), so a batch
of them -- a test's hundred, a campaign's thousands -- is a list of integers, and a bad one can be flown again by
its number. The draws:

- the case: any of chapter 7's eleven (:data:`CASES`), its reference and its own events kept;
- the law: ``explicit`` (forgetting 0.95-0.999) or ``gmv`` (lambda 0 or log-uniform 1e-4-0.1, order 1 or 2,
  forgetting 0.98-0.999), both commissioned by the baseline vehicle's self-test as the thesis's are (sec. 7.4.1);
- the vehicle flown: baseline, or with the camera from the start (3 in 10: gains designed for the other vehicle);
- a fouled thruster (1 in 2): which of the four, its efficiency 0.3-1.0, at 5 s to 5 s before the end;
- the camera fitted mid-run (1 in 5, on a baseline start);
- the Gauss-Markov current (1 in 2): mean 0-0.3 m/s from any direction, 0-0.1 m/s and 0-30 deg of spread
  (eq. 2.30-2.33; sec. 5.4.3 flew 0.26 m/s);
- the sensors: ideal, baseline or haslar (sec. 3.7);
- the run's seed (current and sensor noise).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from seapup_runs.scenarios import scenario_spec
from seapup_runs.spec import RunEvent, RunSpec

__all__ = ["CASES", "random_adaptive_spec"]

#: Chapter 7's cases (sec. 7.4, 7.6).
CASES = ("square-surge", "square-sway", "square-heave", "square-yaw", "square-inspection", "square-turn",
         "yaw-hold", "inspection-haslar", "inspection-current", "camera-change", "fouling-change")


def random_adaptive_spec(number: int, controllers: tuple = ("explicit", "gmv")) -> RunSpec:
    """Run ``number`` of the randomised self-tuner runs (see the module docstring).

    Parameters
    ----------
    number : int
        Which run (>= 0): the draws come from ``numpy.random.default_rng(number)``.
    controllers : tuple of str
        The laws drawn from (``explicit``, ``gmv``).

    Raises
    ------
    ValueError
        On a negative or non-integer ``number``, or an unknown law.
    """
    if isinstance(number, bool) or not isinstance(number, (int, np.integer)) or number < 0:
        raise ValueError(f"number must be an integer >= 0, got {number!r}")
    unknown = sorted(set(controllers) - {"explicit", "gmv"})
    if unknown or not controllers:
        raise ValueError(f"controllers must be among explicit, gmv; got {list(controllers)!r}")
    rng = np.random.default_rng(int(number))
    case = str(rng.choice(CASES))
    law = str(rng.choice(list(controllers)))
    if law == "explicit":
        parameters = {"forgetting": round(float(rng.uniform(0.95, 0.999)), 4)}
    else:
        weighting = 0.0 if rng.random() < 0.2 else float(10 ** rng.uniform(-4, -1))
        parameters = {"lambda": weighting, "order": int(rng.choice([1, 2])),
                      "forgetting": round(float(rng.uniform(0.98, 0.999)), 4)}
    vehicle = "camera" if rng.random() < 0.3 else "baseline"
    sensors = str(rng.choice(["ideal", "baseline", "haslar"]))
    base = scenario_spec(case, vehicle=vehicle, controller=law, parameters=parameters, sensors=sensors)
    events = list(base.events)
    end = base.duration
    if rng.random() < 0.5:
        efficiency = [1.0] * 4
        efficiency[int(rng.integers(4))] = round(float(rng.uniform(0.3, 1.0)), 3)
        events.append(RunEvent(_on_sample(rng.uniform(5.0, end - 5.0), base.control_period),
                               "thruster_efficiency", efficiency))
    if vehicle == "baseline" and rng.random() < 0.2:
        events.append(RunEvent(_on_sample(rng.uniform(5.0, end - 5.0), base.control_period), "configuration", "camera"))
    environment = dict(base.environment)
    if rng.random() < 0.5:
        environment["current"] = {"enabled": True, "mean_speed": float(rng.uniform(0.0, 0.3)),
                                  "speed_std": float(rng.uniform(0.0, 0.1)),
                                  "mean_direction": float(rng.uniform(-math.pi, math.pi)),
                                  "direction_std": float(rng.uniform(0.0, math.radians(30.0)))}
    events.sort(key=lambda e: e.time)
    return dataclasses.replace(base, name=f"random-{number}:{case}:{law}", environment=environment,
                               events=tuple(events), seed=int(rng.integers(2**31)))


def _on_sample(t: float, period: float) -> float:
    """``t`` rounded to a control sample (a change falls on one whatever the draw)."""
    return round(round(t / period) * period, 9)
