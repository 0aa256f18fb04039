"""The thesis's closed-loop cases (sec. 5.4.2-5.4.3, figs 5.10-5.24; sec. 7.4, 7.6, figs 7.3-7.25) as run
specifications.

The cases are package data (``seapup_runs/data/scenarios.yaml``): a duration,
reference steps, optionally a current (from the start or switched on later),
the time a controller is connected after drifting, gain scheduling, the
self-test's operating points, the sensors and the simulator's scheduled changes
(a configuration or a thruster's efficiency). :func:`scenario_spec` turns one
into a :class:`~seapup_runs.spec.RunSpec`: a velocity controller by registered
name (default the self-tested Owens-Chotai ``mfol``; ``explicit`` and ``gmv``
the self-tuners of ch. 7, commissioned by the same self-test) designed on the
baseline vehicle -- the thesis designs once and then changes the vehicle (sec.
5.5) -- flying the chosen vehicle from rest at the hover setting 50 m deep with
the case's sensors (noise-free unless it says), measured by the
``step_response`` metrics.
"""
from __future__ import annotations

import math

from importlib import resources
from pathlib import Path

from seapup_common.config import parsed_yaml
from seapup_common.controllers import ControllerSpec
from seapup_runs.spec import ReferenceSteps, RunEvent, RunSpec, RunSpecError, SelfTestDesign

__all__ = ["scenarios", "scenario_spec", "CASE_KEYS"]

#: Keys a case may have (anything else is refused: a misspelled key must not be silently ignored).
CASE_KEYS = ("duration", "reference", "current", "controller_on", "schedule", "speeds", "sensors", "events",
             "metrics")


def scenarios() -> dict:
    """The case definitions, by name."""
    cases = parsed_yaml(Path(str(resources.files("seapup_runs").joinpath("data/scenarios.yaml"))))
    for name, case in cases.items():
        unknown = sorted(set(case) - set(CASE_KEYS))
        if unknown:
            raise RunSpecError(f"scenario {name!r}: unknown key(s) {unknown}; known: {', '.join(CASE_KEYS)}")
    return cases


def scenario_spec(name: str, vehicle: str = "baseline", rate: float = 5.0, schedule: bool | None = None,
                  seed: int = 0, controller: str = "mfol", parameters: dict | None = None,
                  sensors: str | None = None, design: str = "self-test", fit: str = "deviation") -> RunSpec:
    """The run of case ``name`` at ``rate`` [Hz] on ``vehicle`` (see the module docstring).

    ``controller`` names a registered velocity controller and ``parameters`` its settings (checked when
    the run is made); ``schedule`` is the ``mfol`` controller's. ``sensors`` overrides the case's profile.
    ``design``: ``self-test`` (our self-test on the baseline vehicle designs the controller), or one of
    :data:`seapup_runs.thesis_designs.DESIGNS` -- the thesis's own matrices (eq. 5.3, Table 5.1) at 5 Hz.
    ``fit``: how the self-test fits its steps (``deviation``, eq. 5.5; ``raw``, the thesis's Table 5.2 procedure).

    Raises
    ------
    KeyError
        On an unknown case or design (the message lists the known ones).
    RunSpecError
        A thesis design at another rate than 5 Hz.
    """
    cases = scenarios()
    if not isinstance(name, str) or name not in cases:
        raise KeyError(f"no scenario {str(name)[:60]!r}; known: {', '.join(cases)}")
    case = cases[name]
    if schedule is not None and not isinstance(schedule, bool):
        raise RunSpecError(f"schedule is true or false, got {str(schedule)[:60]!r}")
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not 0 < rate < math.inf:
        raise RunSpecError(f"the rate must be a positive number of Hz, got {str(rate)[:60]!r}")
    scheduled = bool(case.get("schedule", False)) if schedule is None else schedule
    period = 1.0 / float(rate)
    environment: dict = {"sensors": sensors or case.get("sensors", "ideal")}
    events = [RunEvent(float(e["time"]), e["kind"], e.get("detail")) for e in case.get("events") or ()]
    current = case.get("current")
    if current is not None:
        current = dict(current)
        at = float(current.pop("at", 0.0))
        if at > 0:
            events.append(RunEvent(at, "current", current))
        else:
            environment["current"] = {"enabled": True, **current}
    if controller == "mfol":
        mfol = ControllerSpec("mfol", {"schedule": scheduled, **(parameters or {})})
    else:
        if schedule:
            raise RunSpecError(f"gain scheduling is the mfol controller's; {controller!r} has no schedule")
        mfol = ControllerSpec(controller, dict(parameters or {}))
    self_test = SelfTestDesign("baseline", tuple(case.get("speeds", (0.0, 0.7))), fit=fit)   # checks the fit
    if design != "self-test" and fit != "deviation":
        raise RunSpecError(f"fit {fit!r} is how our self-test fits its steps; the thesis's {design!r} "
                           "matrices are not fitted here (no self-test designs this run)")
    if design != "self-test":
        from seapup_runs.thesis_designs import SAMPLE_PERIOD, thesis_design
        if abs(period - SAMPLE_PERIOD) > 1e-9:
            raise RunSpecError(f"the thesis's {design!r} matrices are for 5 Hz (T = {SAMPLE_PERIOD} s), "
                               f"not {float(rate):g} Hz")
        mfol = ControllerSpec(mfol.type, mfol.parameters, document=thesis_design(design, schedule=scheduled))
    t_on = float(case.get("controller_on", 0.0))
    if t_on > 0:  # drifting at the hover setting (the start's) until the controller is connected (fig. 5.23)
        controller = ControllerSpec("hold")
        events.append(RunEvent(t_on, "controller", mfol))
    else:
        controller = mfol
    return RunSpec(name=name, vehicle=vehicle, environment=environment, control_period=period,
                   duration=float(case["duration"]), start_depth=50.0, controller=controller,
                   design=self_test,
                   reference=ReferenceSteps.from_list(case["reference"]), events=tuple(events), seed=seed,
                   metrics=tuple(case.get("metrics", ("step_response",))))
