"""The thesis's closed-loop cases (sec. 5.4.2-5.4.3, figs 5.10-5.24) as run specifications.

The cases are package data (``seapup_runs/data/scenarios.yaml``): a duration,
reference steps, optionally a current (from the start or switched on later),
the time a controller is connected after drifting, gain scheduling and the
self-test's operating points. :func:`scenario_spec` turns one into a
:class:`~seapup_runs.spec.RunSpec`: the self-tested Owens-Chotai controller
(``mfol``) designed on the baseline vehicle -- the thesis designs once and then
changes the vehicle (sec. 5.5) -- flying the chosen vehicle from rest at the
hover setting 50 m deep with noise-free sensors, measured by the
``step_response`` metrics.
"""
from __future__ import annotations

from importlib import resources

import yaml

from seapup_common.controllers import ControllerSpec
from seapup_runs.spec import ReferenceSteps, RunEvent, RunSpec, RunSpecError, SelfTestDesign

__all__ = ["scenarios", "scenario_spec", "CASE_KEYS"]

#: Keys a case may have (anything else is refused: a misspelled key must not be silently ignored).
CASE_KEYS = ("duration", "reference", "current", "controller_on", "schedule", "speeds")


def scenarios() -> dict:
    """The case definitions, by name."""
    cases = yaml.safe_load(resources.files("seapup_runs").joinpath("data/scenarios.yaml").read_text())
    for name, case in cases.items():
        unknown = sorted(set(case) - set(CASE_KEYS))
        if unknown:
            raise RunSpecError(f"scenario {name!r}: unknown key(s) {unknown}; known: {', '.join(CASE_KEYS)}")
    return cases


def scenario_spec(name: str, vehicle: str = "baseline", rate: float = 5.0, schedule: bool | None = None,
                  seed: int = 0) -> RunSpec:
    """The run of case ``name`` at ``rate`` [Hz] on ``vehicle`` (see the module docstring).

    Raises
    ------
    KeyError
        On an unknown case (the message lists the known ones).
    """
    cases = scenarios()
    if name not in cases:
        raise KeyError(f"no scenario {name!r}; known: {', '.join(cases)}")
    case = cases[name]
    scheduled = bool(case.get("schedule", False)) if schedule is None else bool(schedule)
    period = 1.0 / float(rate)
    environment: dict = {"sensors": "ideal"}
    events = []
    current = case.get("current")
    if current is not None:
        current = dict(current)
        at = float(current.pop("at", 0.0))
        if at > 0:
            events.append(RunEvent(at, "current", current))
        else:
            environment["current"] = {"enabled": True, **current}
    mfol = ControllerSpec("mfol", {"schedule": scheduled})
    t_on = float(case.get("controller_on", 0.0))
    if t_on > 0:  # drifting at the hover setting (the start's) until the controller is connected (fig. 5.23)
        controller = ControllerSpec("hold")
        events.append(RunEvent(t_on, "controller", mfol))
    else:
        controller = mfol
    return RunSpec(name=name, vehicle=vehicle, environment=environment, control_period=period,
                   duration=float(case["duration"]), start_depth=50.0, controller=controller,
                   design=SelfTestDesign("baseline", tuple(case.get("speeds", (0.0, 0.7)))),
                   reference=ReferenceSteps.from_list(case["reference"]), events=tuple(events), seed=seed,
                   metrics=("step_response",))
