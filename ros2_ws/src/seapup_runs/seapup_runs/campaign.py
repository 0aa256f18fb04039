"""Monte Carlo campaigns as data: a campaign spec expands into run specs, and a task flies a list of them.

The thesis asks "how robust is it?" of every controller -- under the camera, fouling, current, sensor noise and
the sampling rate (ch. 5, 7) -- and answers with one run each. A campaign answers with many. It is a YAML file:

.. code-block:: yaml

    name: controller-robustness          # names the output directory
    base: {scenario: square-inspection}  # a case of seapup_runs/data/scenarios.yaml (rate_hz, sensors optional)
    # or   base: {spec: {...}}            # a run spec as ./seapup fly reads it
    grid:                                # every combination; a key is a dotted path into the run spec
      controller.type: [mfol, explicit, gmv]
      vehicle: [baseline, camera]
      events+: [[], [{time: 20, kind: thruster_efficiency, detail: [0.5, 1, 1, 1]}]]   # "+": appended
    random:                              # draws for each grid point, from their own seed
      count: 10
      seed: 1
      draws:
        environment.current: {choice: [{enabled: false}, {enabled: true, mean_speed: 0.2}]}
        environment.current.mean_direction: {uniform: [-3.14, 3.14]}
    seeds: 3                             # replicates: each run's seed (current, sensors) drawn per replicate
    runs_per_task: 20                    # runs one worker flies per task (a task costs milliseconds to ship)
    summary: {metrics: [...], worst_by: outputs.u.rise95_s, worst: 5}

or, for the randomised self-tuner runs of :mod:`seapup_runs.randomised`, ``randomised: {count: 500, first: 0}``
in place of ``base``/``grid``/``random``/``seeds``.

A campaign over whole missions (:mod:`seapup_runs.mission`: the supervisory hierarchy flown leg by leg, in
process by :func:`seapup_runs.mission_flight.run_mission`) has ``base: {mission: FILE}`` (a mission file,
relative to the campaign's; ``demo``: the shipped one) or ``base: {mission: {graph: ..., mission: [...]}}``;
its dotted paths go into the mission document, a leg by its index (``mission.6.foul.efficiency``,
``graph.sensors``), and a replicate's seed is ``graph.seed``. Each run's metrics are its legs' numbers
(``legs.<leg name>.<number>``) and the mission's counts (``legs_failed``, ``legs_marked``, ``legs_doubted``).
A mission run needs the hierarchy's nodes as data (``row["hierarchy"]``, a
:class:`~seapup_runs.mission_flight.HierarchyConfig` as a mapping), which the bringup attaches from the launch
document before the rows are shipped.

:func:`load_campaign` checks a file (read bounded and strict: at most 1 MiB, no duplicated key; unknown keys,
distributions, the number of runs -- :func:`run_count`, at most :data:`MAX_CAMPAIGN_RUNS`, computed from the file's
counts before anything is expanded -- and every run spec it expands into, before any run is flown); :func:`expand` lists the runs (the same file, the same runs, in the same order); :func:`fly_rows`
flies a task's runs in the calling process -- a Dask worker's -- and returns one flat row each: the run's index,
its parameters, status (``ok`` or ``error`` with the reason: a failed run is a result, not a crash), wall and
CPU time, every scalar metric, and what the run's cores logged (``log_lines``, and the first lines in ``log``: a
self-tuner's jacket says when and why it fell back) -- kept with the row instead of printed by the worker, where
hundreds of runs' lines would bury the progress bar. Orchestration (the cluster, progress, the Parquet table, resuming, the page)
is the bringup's ``./seapup campaign``.
"""
from __future__ import annotations

import copy
import hashlib
import itertools
import json
import logging
import math
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from seapup_common import CORE_LOGGERS
from seapup_common.input_files import InputFileError, env_limit, load_yaml_file
from seapup_common.values import finite_real
from seapup_runs.spec import RunSpec, RunSpecError, number_hint

__all__ = ["CampaignError", "Campaign", "shipped", "load_campaign", "campaign_from_dict", "expand", "tasks", "fly_rows",
           "is_mission", "mission_metrics", "SHIPPED_MISSIONS",
           "flatten", "DISTRIBUTIONS", "MAX_CAMPAIGN_RUNS", "run_count", "max_campaign_runs"]

#: The most runs a campaign may expand into (grid product x random count x seeds, before ``--limit``).
#: Every run is expanded and its spec checked before the first flies, at about 0.4 ms of CPU and 3 KB of
#: memory a run, so 10^5 runs are about 40 s and 0.3 GB before flying -- and flying them at ~0.1-1 s of CPU
#: each is hours to a day on a workstation. ``$SEAPUP_MAX_CAMPAIGN_RUNS`` raises it (docs/limits.md).
MAX_CAMPAIGN_RUNS = 10**5
ENV_MAX_CAMPAIGN_RUNS = "SEAPUP_MAX_CAMPAIGN_RUNS"
#: The longest campaign name (it names the output directory).
MAX_NAME_LENGTH = 100

_KEYS = {"name", "doc", "base", "grid", "random", "seeds", "runs_per_task", "randomised", "summary", "metrics"}
_SUMMARY_KEYS = {"metrics", "worst_by", "worst", "worst_highest"}
#: how a random draw is described: {kind: arguments}
DISTRIBUTIONS = {"uniform": 2, "loguniform": 2, "integers": 2, "choice": None, "normal": 2}


class CampaignError(ValueError):
    """A campaign file that cannot be flown; the message is one line naming what is wrong."""


@dataclass(frozen=True)
class Campaign:
    """A checked campaign file."""

    name: str
    doc: str
    source: dict = field(repr=False)
    runs_per_task: int = 20
    summary: dict = field(default_factory=dict)

    @property
    def digest(self) -> str:
        """A hash of the file's content: the runs it expands into and how they are grouped."""
        return hashlib.sha256(json.dumps(self.source, sort_keys=True, default=str).encode()).hexdigest()[:16]


def shipped() -> dict[str, Path]:
    """The campaigns shipped with seapup (``seapup_runs/data/campaigns``), by name."""
    from importlib import resources
    folder = Path(str(resources.files("seapup_runs").joinpath("data/campaigns")))
    return {p.stem: p for p in sorted(folder.glob("*.yaml"))}


def load_campaign(path: str | Path) -> Campaign:
    """The campaign in ``path`` (YAML) or shipped under that name, checked; :class:`CampaignError` on anything
    wrong."""
    path = Path(path)
    if not path.exists() and str(path) in shipped():
        path = shipped()[str(path)]
    try:   # bounded and strict: at most 1 MiB, no duplicated key, no !!python tag, not empty
        data = load_yaml_file(path, "spec")
    except InputFileError as exc:
        raise CampaignError(str(exc)) from None
    return campaign_from_dict(data, str(path))


def max_campaign_runs() -> int:
    """:data:`MAX_CAMPAIGN_RUNS`, or ``$SEAPUP_MAX_CAMPAIGN_RUNS`` when set."""
    try:
        return env_limit(ENV_MAX_CAMPAIGN_RUNS, MAX_CAMPAIGN_RUNS)
    except InputFileError as exc:
        raise CampaignError(str(exc)) from None


def campaign_from_dict(data, where: str = "campaign") -> Campaign:
    """A campaign from its parsed YAML (see the module docstring); every run it expands into is checked."""
    if not isinstance(data, dict):
        raise CampaignError(f"{where}: a campaign is a mapping")
    unknown = sorted(map(str, set(data) - _KEYS))
    if unknown:
        raise CampaignError(f"{where}: unknown key(s) {_short(unknown)}; known: {', '.join(sorted(_KEYS))}")
    name = data.get("name")
    if not isinstance(name, str) or not name or len(name) > MAX_NAME_LENGTH \
            or not all(c.isalnum() or c in "-_." for c in name) or name.strip(".") == "":
        raise CampaignError(f"{where}: name must be a non-empty word of letters, digits, '-', '_' or '.' "
                            f"(at most {MAX_NAME_LENGTH} characters)")
    doc = data.get("doc") or ""
    if not isinstance(doc, str):
        raise CampaignError(f"{where}: doc must be text, got {_short(doc)}")
    per_task = data.get("runs_per_task", 20)
    if isinstance(per_task, bool) or not isinstance(per_task, int) or per_task < 1:
        raise CampaignError(f"{where}: runs_per_task must be an integer >= 1, got {_short(per_task)}")
    summary = _summary(data.get("summary") or {}, where)
    if ("randomised" in data) == ("base" in data):
        raise CampaignError(f"{where}: give either base (with grid, random, seeds) or randomised")
    if "randomised" in data and set(data) & {"grid", "random", "seeds"}:
        raise CampaignError(f"{where}: randomised runs draw everything themselves: no grid, random or seeds")
    campaign = Campaign(name, doc, copy.deepcopy(data), per_task, summary)
    run_count(campaign)   # refused above the cap here, from the counts alone: nothing expanded yet
    rows = expand(campaign)
    if not rows:
        raise CampaignError(f"{where}: the campaign has no runs")
    for row in rows:
        try:
            if row.get("kind") == "mission":
                from seapup_runs.mission import MissionSpec
                MissionSpec.load(row["spec"])
            else:
                _check(RunSpec.from_dict(row["spec"]))
        except (RunSpecError, KeyError, TypeError, ValueError) as exc:
            reason = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
            raise CampaignError(f"{where}: run {row['index']} ({_label(row['parameters'])}): {reason}") from None
    return campaign


def _summary(summary, where: str) -> dict:
    """The summary section, typed: what the page shows is checked before anything flies."""
    if not isinstance(summary, dict) or set(summary) - _SUMMARY_KEYS:
        raise CampaignError(f"{where}: summary takes {', '.join(sorted(_SUMMARY_KEYS))}")
    metrics = summary.get("metrics", [])
    if not isinstance(metrics, list) or not all(isinstance(m, str) for m in metrics):
        raise CampaignError(f"{where}: summary.metrics is a list of metric names, got {_short(metrics)}")
    if not isinstance(summary.get("worst_by", ""), str):
        raise CampaignError(f"{where}: summary.worst_by is a metric name, got {_short(summary['worst_by'])}")
    worst = summary.get("worst", 5)
    if isinstance(worst, bool) or not isinstance(worst, int) or not 0 <= worst <= 1000:
        raise CampaignError(f"{where}: summary.worst is an integer in [0, 1000], got {_short(worst)}")
    if not isinstance(summary.get("worst_highest", True), bool):
        raise CampaignError(f"{where}: summary.worst_highest is true or false, got {_short(summary['worst_highest'])}")
    return dict(summary)


def _count(value, what: str, where: str, low: int = 1) -> int:
    """An integer count >= ``low`` (a YAML integer: not a string, a float or a bool)."""
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise CampaignError(f"{where}: {what} must be an integer >= {low}, got {_short(value)}{number_hint(value)}")
    return value


def _layout(data: dict, where: str) -> tuple[dict, int, dict, object]:
    """The grid, the random count, the draws and the seeds of a base campaign, checked (not expanded)."""
    grid = data.get("grid") or {}
    if not isinstance(grid, dict) or not all(isinstance(k, str) and k.strip(".+") and isinstance(v, list) and v
                                             for k, v in grid.items()):
        raise CampaignError(f"{where}: grid maps a dotted path to a non-empty list of values")
    random = data.get("random") or {}
    if not isinstance(random, dict) or set(random) - {"count", "seed", "draws"}:
        raise CampaignError(f"{where}: random takes count, seed, draws")
    count, draws = 1, {}
    if random:
        count = _count(random.get("count"), "random.count", where)
        draws = random.get("draws")
        if not isinstance(draws, dict) or not draws or not all(isinstance(k, str) and k.strip(".+") for k in draws):
            raise CampaignError(f"{where}: random needs count >= 1 and draws (a dotted path: a distribution)")
        both = sorted(set(grid) & set(draws))
        if both:
            raise CampaignError(f"{where}: {_short(both)} both in grid and in random.draws: one would silently "
                                "replace the other; give each path once")
        seed = random.get("seed", 0)
        if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**63:
            raise CampaignError(f"{where}: random.seed must be an integer in [0, 2^63), got {_short(seed)}")
    seeds = data.get("seeds", 1)
    if isinstance(seeds, list):
        if not seeds or not all(isinstance(s, int) and not isinstance(s, bool) and 0 <= s < 2**31 for s in seeds):
            raise CampaignError(f"{where}: seeds is a count >= 1 or a list of seeds in [0, 2^31)")
    elif isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise CampaignError(f"{where}: seeds is a count >= 1 or a list of seeds in [0, 2^31), got "
                            f"{_short(seeds)}{number_hint(seeds)}")
    return grid, count, draws, seeds


def run_count(campaign: Campaign) -> int:
    """How many runs the campaign expands into (before ``--limit``), from its counts alone -- the grid's list
    lengths, the random count and the seeds -- with nothing expanded or drawn.

    Raises
    ------
    CampaignError
        On a malformed count, or more than :func:`max_campaign_runs` runs (:data:`MAX_CAMPAIGN_RUNS`).
    """
    data, where = campaign.source, campaign.name
    if "randomised" in data:
        r = data["randomised"]
        if not isinstance(r, dict) or set(r) - {"count", "first", "controllers"}:
            raise CampaignError(f"{where}: randomised takes count, first, controllers")
        total = _count(r.get("count"), "randomised.count", where)
        first = r.get("first", 0)
        if isinstance(first, bool) or not isinstance(first, int) or not 0 <= first < 2**63:
            raise CampaignError(f"{where}: randomised.first must be an integer in [0, 2^63), got {_short(first)}")
        what = "randomised.count"
    else:
        grid, count, _, seeds = _layout(data, where)
        total = math.prod(len(v) for v in grid.values()) * count * (len(seeds) if isinstance(seeds, list) else seeds)
        what = " x ".join([f"{len(v)} {k}" for k, v in grid.items()] + ([f"random.count {count}"] if count > 1 else [])
                          + [f"{len(seeds) if isinstance(seeds, list) else seeds} seeds"])
    cap = max_campaign_runs()
    if total > cap:
        raise CampaignError(f"{where}: {total:.3g} runs ({what}), more than the {cap:,} a campaign may have "
                            f"(docs/limits.md; set {ENV_MAX_CAMPAIGN_RUNS} to allow more; --limit flies a part of a "
                            "campaign, it does not shrink it)")
    return total


def _check(spec: RunSpec) -> None:
    """What a run spec leaves to flight time, checked before a campaign flies thousands: the vehicles and
    the controllers' names."""
    from seapup_common.controllers import controller_type
    from seapup_runs.metrics import check_names
    from seapup_sim.vehicle_config import available_configs
    check_names(spec.metrics)
    vehicles = [spec.vehicle] + [e.detail for e in spec.events if e.kind == "configuration"]
    for vehicle in vehicles:
        if vehicle not in available_configs():
            raise RunSpecError(f"no vehicle configuration {vehicle!r}; known: {', '.join(available_configs())}")
    for _, controller in spec.controller_timeline():
        controller_type(controller.type).complete(controller.parameters)


def _label(parameters: dict) -> str:
    return ", ".join(f"{k}={_short(v)}" for k, v in parameters.items()) or "the base"


def _short(value) -> str:
    text = json.dumps(value, default=str) if not isinstance(value, str) else value
    return text if len(text) <= 40 else text[:37] + "..."


def is_mission(campaign: Campaign) -> bool:
    """Does the campaign fly missions (``base: {mission: ...}``) rather than run specs?"""
    base = campaign.source.get("base")
    return isinstance(base, dict) and "mission" in base


#: Shipped missions a campaign may name (``base: {mission: demo}``): name -> file, filled by the bringup (the
#: shipped mission lives in its share directory).
SHIPPED_MISSIONS: dict[str, Path] = {}


def _mission_document(base: dict, where: str) -> dict:
    """The base mission's document, checked (:class:`~seapup_runs.mission.MissionSpec`)."""
    from seapup_runs.mission import MissionError, MissionSpec, load_mission
    if set(base) != {"mission"}:
        raise CampaignError(f"{where}: base.mission is a mission file or mapping, and alone")
    mission = base["mission"]
    try:
        if isinstance(mission, dict):
            return MissionSpec.load(mission).to_dict()
        if isinstance(mission, str) and mission:
            shipped_path = SHIPPED_MISSIONS.get(mission)
            folder = Path(where).parent if Path(where).suffix else Path(".")
            path = shipped_path if shipped_path is not None and not (folder / mission).exists() else folder / mission
            return load_mission(path).to_dict()
    except MissionError as exc:
        raise CampaignError(f"{where}: base.mission: {exc}") from None
    raise CampaignError(f"{where}: base.mission is a mission file (or a shipped name: "
                        f"{', '.join(sorted(SHIPPED_MISSIONS)) or 'none'}) or a mapping, got {_short(mission)}")


def _base_spec(base, where: str) -> dict:
    from seapup_runs.scenarios import scenario_spec
    if isinstance(base, dict) and "mission" in base:
        return _mission_document(base, where)
    if not isinstance(base, dict) or len(set(base) & {"scenario", "spec"}) != 1:
        raise CampaignError(f"{where}: base is {{scenario: NAME, ...}}, {{spec: {{...}}}} or {{mission: ...}}")
    if "spec" in base:
        if set(base) != {"spec"} or not isinstance(base["spec"], dict):
            raise CampaignError(f"{where}: base.spec is a run spec mapping (as ./seapup fly reads) and alone")
        try:
            return RunSpec.from_dict(base["spec"]).to_dict()
        except (RunSpecError, KeyError, TypeError, ValueError) as exc:
            raise CampaignError(f"{where}: base.spec: {exc}") from None
    extra = set(base) - {"scenario", "rate_hz", "sensors", "vehicle", "controller", "schedule"}
    if extra:
        raise CampaignError(f"{where}: base takes scenario, rate_hz, sensors, vehicle, controller, schedule; "
                            f"not {sorted(extra)}")
    for key in ("scenario", "vehicle", "controller"):
        if key in base and not isinstance(base[key], str):
            raise CampaignError(f"{where}: base.{key} is a name, got {_short(base[key])}")
    if not isinstance(base.get("schedule", False), bool):
        raise CampaignError(f"{where}: base.schedule is true or false, got {_short(base['schedule'])}")
    rate = base.get("rate_hz", 5.0)
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not 0 < rate <= 1000:
        raise CampaignError(f"{where}: base.rate_hz must be a number in (0, 1000] Hz, got {_short(rate)}"
                            f"{number_hint(rate)}")
    try:
        spec = scenario_spec(base["scenario"], vehicle=base.get("vehicle", "baseline"),
                             rate=float(rate), schedule=base.get("schedule"),
                             controller=str(base.get("controller", "mfol")), sensors=base.get("sensors"))
    except (KeyError, RunSpecError, ValueError) as exc:
        raise CampaignError(f"{where}: base: {str(exc).strip(chr(39))}") from None
    return spec.to_dict()


def _get(spec: dict, path: str):
    node = spec
    for key in path.split("."):
        if isinstance(node, list) and key.isdigit() and int(key) < len(node):
            node = node[int(key)]
            continue
        if not isinstance(node, dict):
            return None
        node = node.get(key)
    return node


def _set(spec: dict, path: str, value, where: str, lists: bool = False) -> None:
    """Set a dotted ``path`` of the run spec dict (``events+``-style paths append); with ``lists`` (a mission
    document) a key may be a list's index (``mission.6.foul``)."""
    append = path.endswith("+")
    keys = path.rstrip("+").split(".")
    node = spec
    if not all(keys):
        raise CampaignError(f"{where}: {path}: an empty key in the dotted path")
    for key in keys[:-1]:
        if lists and isinstance(node, list):   # a mission's legs, by index
            node = node[_index(node, key, path, where)]
            continue
        if not isinstance(node, dict):
            raise CampaignError(f"{where}: {path}: {key} is inside a value that is not a mapping in the run spec")
        if not isinstance(node.get(key), (dict, list) if lists else dict):
            if key in node and node[key] is not None:
                raise CampaignError(f"{where}: {path}: {key} is not a mapping in the run spec")
            node[key] = {}
        node = node[key]
    last = keys[-1]
    value = copy.deepcopy(value)
    if lists and isinstance(node, list):
        node[_index(node, last, path, where)] = value
        return
    if append:
        items = value if isinstance(value, list) else [value]
        existing = node.get(last) or []
        if not isinstance(existing, list):
            raise CampaignError(f"{where}: {path}: {last} is not a list in the run spec (\"+\" appends to a list)")
        node[last] = list(existing) + items
        if last == "events":
            node[last].sort(key=_event_time)
    elif isinstance(value, dict) and isinstance(node.get(last), dict):
        node[last] = {**node[last], **value}      # a mapping merges into the spec's (environment.current ...)
    else:
        node[last] = value


def _index(items: list, key: str, path: str, where: str) -> int:
    if not key.isdigit() or int(key) >= len(items):
        raise CampaignError(f"{where}: {path}: {key} is not an index of a list of {len(items)}")
    return int(key)


def _event_time(event) -> float:
    """An event's time for ordering (the spec check refuses a bad one with its own message)."""
    t = event.get("time", 0.0) if isinstance(event, dict) else 0.0
    return float(t) if isinstance(t, (int, float)) and not isinstance(t, bool) and math.isfinite(t) else 0.0


def _draw(rng: np.random.Generator, spec, where: str):
    if not isinstance(spec, dict) or len(spec) != 1 or next(iter(spec)) not in DISTRIBUTIONS:
        raise CampaignError(f"{where}: a draw is one of {{{', '.join(DISTRIBUTIONS)}}}: ARGS, got {spec!r}")
    kind, args = next(iter(spec.items()))
    if kind == "choice":
        if not isinstance(args, list) or not args:
            raise CampaignError(f"{where}: choice takes a non-empty list")
        return copy.deepcopy(args[int(rng.integers(len(args)))])
    _draw_arguments(kind, args, where)
    lo, hi = float(args[0]), float(args[1])
    if kind == "uniform":
        return float(rng.uniform(lo, hi))
    if kind == "normal":
        return float(rng.normal(lo, hi))
    if kind == "integers":
        return int(rng.integers(int(args[0]), int(args[1]) + 1))
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _draw_arguments(kind: str, args, where: str) -> None:
    """Refuse what numpy would refuse with its own words (``scale < 0``, ``low >= high``, an overflow)."""
    if not isinstance(args, list) or len(args) != 2 or not all(finite_real(a) is not None for a in args):
        raise CampaignError(f"{where}: {kind} takes two finite numbers, got {_short(args)}")
    lo, hi = float(args[0]), float(args[1])
    if kind == "uniform" and not (lo <= hi and math.isfinite(hi - lo)):
        raise CampaignError(f"{where}: uniform takes [low, high] with low <= high and a finite width, got {_short(args)}")
    if kind == "normal" and not hi >= 0:
        raise CampaignError(f"{where}: normal takes [mean, standard deviation >= 0], got {_short(args)}")
    if kind == "integers" and not (all(isinstance(a, int) for a in args) and -2**62 <= args[0] <= args[1] < 2**62):
        raise CampaignError(f"{where}: integers takes two integers [low, high], low <= high, within +-2^62 "
                            f"(both included), got {_short(args)}")
    if kind == "loguniform" and not (0 < lo <= hi):
        raise CampaignError(f"{where}: loguniform takes two positive numbers [low, high], low <= high, got "
                            f"{_short(args)}")


def expand(campaign: Campaign) -> list[dict]:
    """Every run of the campaign, in order: ``{"index", "parameters", "spec"}`` (the spec as a dict; the
    parameters are what varies: the grid's and the draws' paths and the seed, or the randomised run's law and
    number). The first parameter is the axis the summary page groups by."""
    data, where = campaign.source, campaign.name
    if "randomised" in data:
        from seapup_runs.randomised import random_adaptive_spec
        count = run_count(campaign)
        r = data["randomised"]
        first = r.get("first", 0)
        laws = r.get("controllers") or ("explicit", "gmv")
        if not isinstance(laws, (list, tuple)) or not all(isinstance(law, str) for law in laws):
            raise CampaignError(f"{where}: randomised.controllers is a list of laws (explicit, gmv), got {_short(laws)}")
        laws = tuple(laws)
        rows = []
        for k in range(count):
            try:
                spec = random_adaptive_spec(first + k, laws).to_dict()
            except ValueError as exc:
                raise CampaignError(f"{where}: randomised: {exc}") from None
            rows.append({"index": k, "parameters": {"controller.type": spec["controller"]["type"],
                                                    "number": first + k}, "spec": spec})
        return rows
    run_count(campaign)   # the counts checked and the total capped before anything is built
    grid, count, draws, seeds = _layout(data, where)
    base = _base_spec(data["base"], where)
    mission = is_mission(campaign)
    base.pop("physics_step", None)   # derived from the control period, which a campaign may vary
    if isinstance(seeds, int):
        # the replicates' seeds: from the campaign's name, so two campaigns do not share their noise
        seed_list = [int(s) % 2**31 for s in np.random.SeedSequence(_hash_text(campaign.name)).generate_state(seeds)]
    else:
        seed_list = [int(s) for s in seeds]
    rng = np.random.default_rng(int((data.get("random") or {}).get("seed", 0)))
    rows = []
    for point in itertools.product(*grid.values()):
        for _ in range(count):
            drawn = {path: _draw(rng, d, f"{where}: random.draws.{path}") for path, d in draws.items()}
            for seed in seed_list:
                parameters = {**dict(zip(grid, point)), **drawn, "seed": seed}
                spec = copy.deepcopy(base)
                if mission:
                    spec["graph"]["seed"] = seed
                    parameters.pop("seed")
                    parameters["graph.seed"] = seed
                # a new law starts from its own defaults: the base's parameters belong to the base's law
                for path, value in sorted(parameters.items(), key=lambda item: not item[0].endswith(".type")):
                    if path.endswith(".type") and isinstance(_get(spec, path[:-5]), dict) \
                            and _get(spec, path) != value:
                        _get(spec, path[:-5])["parameters"] = {}
                    _set(spec, path, value, where, lists=mission)
                rows.append({"index": len(rows), "parameters": parameters, "spec": spec,
                             **({"kind": "mission"} if mission else {})})
    return rows


def _hash_text(text: str) -> int:
    return int(hashlib.sha256(text.encode()).hexdigest()[:8], 16)


def tasks(rows: list[dict], per_task: int) -> list[list[dict]]:
    """The runs grouped into tasks of ``per_task`` (the last may be shorter), the runs that can fly as one batch side
    by side (:func:`batch_group`: a task of a randomised campaign would otherwise hold a few runs of each sample
    grid and law, each group too small to batch), each task's runs in index order."""
    order = sorted(range(len(rows)), key=lambda k: (batch_group(rows[k]), k))
    return [[rows[k] for k in sorted(order[i:i + per_task])] for i in range(0, len(order), per_task)]


def batch_group(row: dict) -> tuple:
    """What runs must share to fly in one batch (:func:`seapup_runs.batch_runner.batch_key` and the law), as a
    sortable tuple; missions and specs that do not read are grouped apart (their errors are said when they fly)."""
    if row.get("kind") == "mission":
        return (1,)
    try:
        spec = RunSpec.from_dict(row["spec"])
    except (RunSpecError, KeyError, TypeError, ValueError):
        return (2,)
    return (0, float(spec.control_period), float(spec.physics_step), int(spec.samples), str(spec.controller.type))


def flatten(value, prefix: str = "", out: dict | None = None) -> dict:
    """Scalar leaves of nested mappings as ``{"a.b.c": value}`` (numbers as float, bools, strings); short
    numeric lists (<= 6) as ``a.b.0 ...``; longer lists and None are left out."""
    out = {} if out is None else out
    if isinstance(value, dict):
        for key, item in value.items():
            flatten(item, f"{prefix}.{key}" if prefix else str(key), out)
    elif isinstance(value, (bool, np.bool_)):
        out[prefix] = bool(value)
    elif isinstance(value, (int, float, np.integer, np.floating)):
        out[prefix] = float(value)
    elif isinstance(value, str):
        out[prefix] = value
    elif isinstance(value, (list, tuple)) and len(value) <= 6 and all(
            isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) for v in value):
        for i, item in enumerate(value):
            out[f"{prefix}.{i}"] = float(item)
    return out


#: The fewest runs a batch with self-tuners among them is flown as (fewer fly one by one): their laws run run by
#: run either way, and a batch's shared plant and sensors pay for its set-up from about eight runs (measured on
#: ch. 7's randomised runs of one sample grid: per run 60 ms batched against 51 alone for 2, 35 against 38 for 8,
#: 34 against 39 for 16). Runs of MFOL alone batch from two: their laws are stacked as well.
MIN_TUNER_BATCH = 8
#: The loggers of the cores a run executes; a campaign keeps their records with the run's row.
RUN_LOGGERS = CORE_LOGGERS + ("seapup_runs",)
#: At most this many of a run's log lines are kept in its row (all are counted).
LOG_LINES_KEPT = 20


class _Lines(list):
    """:func:`run_log`'s lines, with those of each run of a batch apart (``by_run``) and the rest (``shared``)."""

    def __init__(self):
        super().__init__()
        self.by_run: dict[int, list[str]] = {}
        self.shared: list[str] = []


@contextmanager
def run_log():
    """The records the cores log meanwhile (:data:`RUN_LOGGERS`), as lines, instead of on the process's stderr:
    for code that flies many runs (a campaign task, a benchmark) and keeps or counts what they said. The list
    also files each line under the run of a batch that said it (``lines.by_run``, by
    :data:`seapup_runs.batch_runner.RUN_INDEX`; ``lines.shared``: the others)."""
    from seapup_runs.batch_runner import RUN_INDEX
    lines = _Lines()

    class Keep(logging.Handler):
        def emit(self, record):
            line = f"{record.levelname.lower()}: {record.getMessage()}"
            lines.append(line)
            run = RUN_INDEX.get()
            (lines.shared if run is None else lines.by_run.setdefault(run, [])).append(line)
    handler = Keep(logging.INFO)
    loggers = [logging.getLogger(name) for name in RUN_LOGGERS]
    saved = [(logger, logger.propagate, logger.level) for logger in loggers]
    for logger in loggers:
        logger.addHandler(handler)
        logger.propagate = False
        logger.setLevel(logging.INFO)
    try:
        yield lines
    finally:
        for logger, propagate, level in saved:
            logger.removeHandler(handler)
            logger.propagate, logger.level = propagate, level


def _record(row: dict) -> dict:
    record = {"index": int(row["index"]), "name": "", "status": "ok", "error": ""}
    record.update({f"param.{k}": (v if isinstance(v, (int, float, str, bool)) else json.dumps(v, sort_keys=True))
                   for k, v in row["parameters"].items()})
    return record


def _failed(record: dict, exc: BaseException) -> None:
    record["status"], record["error"] = "error", f"{type(exc).__name__}: {str(exc).splitlines()[0][:300]}"


def _fly_batched(rows: list[dict]) -> dict[int, dict]:
    """The rows whose runs can share a batch (:mod:`seapup_runs.batch_runner`), flown a batch per sample grid;
    their records by position in ``rows``. A batch shares its time among its runs; each keeps its own log lines
    (a self-tuner's) and the batch's (its runs' designs, said once for all of them)."""
    from seapup_runs.batch_runner import batch_key, batch_reason, environments_of, fly_batch
    groups: dict[tuple, list[tuple[int, RunSpec]]] = {}
    read: dict = {}
    for k, row in enumerate(rows):
        try:
            spec = RunSpec.from_dict(row["spec"])
            if batch_reason(spec, environments_of([spec], read)[0]) is None:
                groups.setdefault(batch_key(spec), []).append((k, spec))
        except Exception:   # the single path reports it
            continue
    out = {}
    for members in groups.values():
        if len(members) < MIN_TUNER_BATCH:   # too few for the self-tuners to gain: the MFOL runs batch alone
            members = [(k, spec) for k, spec in members if spec.controller.type == "mfol"]
        if len(members) < 2:
            continue
        wall, cpu = time.perf_counter(), time.process_time()
        with run_log() as lines:
            try:
                results = fly_batch([spec for _, spec in members])
            except Exception:   # e.g. a design that fails: each run then says why on its own
                continue
        wall, cpu = (time.perf_counter() - wall) / len(members), (time.process_time() - cpu) / len(members)
        for position, ((k, spec), result) in enumerate(zip(members, results)):
            record = _record(rows[k])
            record["name"] = spec.name
            if isinstance(result, Exception):
                _failed(record, result)
            else:
                record.update({f"metric.{key}": v for key, v in flatten(result.metrics).items()})
            said = lines.shared + lines.by_run.get(position, [])   # its own lines and the batch's
            record["log_lines"], record["log"] = len(said), "\n".join(said[:LOG_LINES_KEPT])
            record["wall_s"], record["cpu_s"] = wall, cpu
            out[k] = record
    return out


def mission_metrics(result: dict) -> dict:
    """A flown mission's numbers for its campaign row: each leg's scalars (``legs.<name>.<key>``) and the counts
    of legs that failed, were marked for their actuators, or whose verdict the truth contradicts."""
    legs = result["legs"]
    out = {"legs_failed": sum(leg.get("status") != "succeeded" for leg in legs),
           "legs_marked": sum(bool(leg.get("actuator_verdict")) for leg in legs),
           "legs_doubted": sum(bool(leg.get("truth_verdict")) for leg in legs),
           "held_s": float(result["held"])}
    for leg in legs:
        out.update({f"legs.{leg['name']}.{k}": v for k, v in flatten({
            k: v for k, v in leg.items() if k not in ("name", "kind", "goal", "message", "target", "wall_s",
                                                       "controller_file", "rejection")}).items()})
    return out


def _fly_mission_row(row: dict) -> dict:
    """One mission of a campaign, flown in this process (:func:`seapup_runs.mission_flight.run_mission`)."""
    from seapup_runs.mission import MissionSpec
    from seapup_runs.mission_flight import HierarchyConfig, run_mission
    wall, cpu = time.perf_counter(), time.process_time()
    record = _record(row)
    with run_log() as lines:
        try:
            if not isinstance(row.get("hierarchy"), dict):
                raise CampaignError("a mission run needs the hierarchy's nodes (row['hierarchy']): the campaign "
                                    "command attaches them")
            spec = MissionSpec.load(row["spec"])
            record["name"] = f"mission-{row['index']}"
            result = run_mission(spec, HierarchyConfig(**row["hierarchy"]))
            record.update({f"metric.{key}": v for key, v in mission_metrics(result).items()})
        except Exception as exc:   # a mission that fails is a result of the campaign, with its reason
            _failed(record, exc)
    record["log_lines"], record["log"] = len(lines), "\n".join(lines[:LOG_LINES_KEPT])
    record["wall_s"], record["cpu_s"] = time.perf_counter() - wall, time.process_time() - cpu
    return record


def fly_rows(rows: list[dict]) -> list[dict]:
    """Fly each run of a task in this process; one flat row per run (see the module docstring). Runs on one
    sample grid fly together as a batch (:func:`seapup_runs.batch_runner.fly_batch`, the same results: MFOL's to
    rounding, the self-tuners' bit for bit): MFOL runs from two, self-tuners with them from
    :data:`MIN_TUNER_BATCH`; the others one by one."""
    from seapup_runs.runner import run
    plain = [k for k, row in enumerate(rows) if row.get("kind") != "mission"]   # run specs: maybe batched
    batched = {plain[i]: record for i, record in _fly_batched([rows[k] for k in plain]).items()}
    out = []
    for k, row in enumerate(rows):
        if k in batched:
            out.append(batched[k])
            continue
        if row.get("kind") == "mission":
            out.append(_fly_mission_row(row))
            continue
        wall, cpu = time.perf_counter(), time.process_time()
        record = _record(row)
        with run_log() as lines:
            try:
                spec = RunSpec.from_dict(row["spec"])
                record["name"] = spec.name
                result = run(spec)
                record.update({f"metric.{key}": v for key, v in flatten(result.metrics).items()})
            except Exception as exc:   # a run that fails is a result of the campaign, with its reason
                _failed(record, exc)
        record["log_lines"], record["log"] = len(lines), "\n".join(lines[:LOG_LINES_KEPT])
        record["wall_s"], record["cpu_s"] = time.perf_counter() - wall, time.process_time() - cpu
        out.append(record)
    return out
