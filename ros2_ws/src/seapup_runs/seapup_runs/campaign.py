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

:func:`load_campaign` checks a file (unknown keys, distributions, and every run spec it expands into, before any
run is flown); :func:`expand` lists the runs (the same file, the same runs, in the same order); :func:`fly_rows`
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
import yaml

from seapup_common import CORE_LOGGERS
from seapup_runs.spec import RunSpec, RunSpecError

__all__ = ["CampaignError", "Campaign", "shipped", "load_campaign", "campaign_from_dict", "expand", "tasks", "fly_rows",
           "flatten", "DISTRIBUTIONS"]

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
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise CampaignError(f"{path}: {str(exc).splitlines()[0]}") from None
    return campaign_from_dict(data, str(path))


def campaign_from_dict(data, where: str = "campaign") -> Campaign:
    """A campaign from its parsed YAML (see the module docstring); every run it expands into is checked."""
    if not isinstance(data, dict):
        raise CampaignError(f"{where}: a campaign is a mapping")
    unknown = sorted(set(data) - _KEYS)
    if unknown:
        raise CampaignError(f"{where}: unknown key(s) {unknown}; known: {', '.join(sorted(_KEYS))}")
    name = str(data.get("name") or "")
    if not name or not all(c.isalnum() or c in "-_." for c in name):
        raise CampaignError(f"{where}: name must be a non-empty word of letters, digits, '-', '_' or '.'")
    per_task = data.get("runs_per_task", 20)
    if isinstance(per_task, bool) or not isinstance(per_task, int) or per_task < 1:
        raise CampaignError(f"{where}: runs_per_task must be an integer >= 1, got {per_task!r}")
    summary = data.get("summary") or {}
    if not isinstance(summary, dict) or set(summary) - _SUMMARY_KEYS:
        raise CampaignError(f"{where}: summary takes {', '.join(sorted(_SUMMARY_KEYS))}")
    if ("randomised" in data) == ("base" in data):
        raise CampaignError(f"{where}: give either base (with grid, random, seeds) or randomised")
    if "randomised" in data and set(data) & {"grid", "random", "seeds"}:
        raise CampaignError(f"{where}: randomised runs draw everything themselves: no grid, random or seeds")
    campaign = Campaign(name, str(data.get("doc") or ""), copy.deepcopy(data), per_task, dict(summary))
    rows = expand(campaign)
    if not rows:
        raise CampaignError(f"{where}: the campaign has no runs")
    for row in rows:
        try:
            _check(RunSpec.from_dict(row["spec"]))
        except (RunSpecError, KeyError, TypeError, ValueError) as exc:
            raise CampaignError(f"{where}: run {row['index']} ({_label(row['parameters'])}): "
                                f"{str(exc).strip(chr(39))}") from None
    return campaign


def _check(spec: RunSpec) -> None:
    """What a run spec leaves to flight time, checked before a campaign flies thousands: the vehicles and
    the controllers' names."""
    from seapup_common.controllers import controller_type
    from seapup_sim.vehicle_config import available_configs
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


def _base_spec(base, where: str) -> dict:
    from seapup_runs.scenarios import scenario_spec
    if not isinstance(base, dict) or len(set(base) & {"scenario", "spec"}) != 1:
        raise CampaignError(f"{where}: base is {{scenario: NAME, ...}} or {{spec: {{...}}}}")
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
    try:
        spec = scenario_spec(str(base["scenario"]), vehicle=str(base.get("vehicle", "baseline")),
                             rate=float(base.get("rate_hz", 5.0)), schedule=base.get("schedule"),
                             controller=str(base.get("controller", "mfol")), sensors=base.get("sensors"))
    except (KeyError, RunSpecError, ValueError) as exc:
        raise CampaignError(f"{where}: base: {str(exc).strip(chr(39))}") from None
    return spec.to_dict()


def _get(spec: dict, path: str):
    node = spec
    for key in path.split("."):
        if not isinstance(node, dict):
            return None
        node = node.get(key)
    return node


def _set(spec: dict, path: str, value, where: str) -> None:
    """Set a dotted ``path`` of the run spec dict (``events+``-style paths append)."""
    append = path.endswith("+")
    keys = path.rstrip("+").split(".")
    node = spec
    for key in keys[:-1]:
        if not isinstance(node.get(key), dict):
            if key in node and node[key] is not None:
                raise CampaignError(f"{where}: {path}: {key} is not a mapping in the run spec")
            node[key] = {}
        node = node[key]
    last = keys[-1]
    value = copy.deepcopy(value)
    if append:
        items = value if isinstance(value, list) else [value]
        node[last] = list(node.get(last) or []) + items
        if last == "events":
            node[last].sort(key=lambda e: float(e.get("time", 0.0)) if isinstance(e, dict) else 0.0)
    elif isinstance(value, dict) and isinstance(node.get(last), dict):
        node[last] = {**node[last], **value}      # a mapping merges into the spec's (environment.current ...)
    else:
        node[last] = value


def _draw(rng: np.random.Generator, spec, where: str):
    if not isinstance(spec, dict) or len(spec) != 1 or next(iter(spec)) not in DISTRIBUTIONS:
        raise CampaignError(f"{where}: a draw is one of {{{', '.join(DISTRIBUTIONS)}}}: ARGS, got {spec!r}")
    kind, args = next(iter(spec.items()))
    if kind == "choice":
        if not isinstance(args, list) or not args:
            raise CampaignError(f"{where}: choice takes a non-empty list")
        return copy.deepcopy(args[int(rng.integers(len(args)))])
    if not isinstance(args, list) or len(args) != 2 or not all(isinstance(a, (int, float)) and math.isfinite(a)
                                                                 for a in args):
        raise CampaignError(f"{where}: {kind} takes two finite numbers, got {args!r}")
    lo, hi = float(args[0]), float(args[1])
    if kind == "uniform":
        return float(rng.uniform(lo, hi))
    if kind == "normal":
        return float(rng.normal(lo, hi))
    if kind == "integers":
        return int(rng.integers(int(lo), int(hi) + 1))
    if lo <= 0 or hi <= 0:
        raise CampaignError(f"{where}: loguniform takes two positive numbers, got {args!r}")
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def expand(campaign: Campaign) -> list[dict]:
    """Every run of the campaign, in order: ``{"index", "parameters", "spec"}`` (the spec as a dict; the
    parameters are what varies: the grid's and the draws' paths and the seed, or the randomised run's law and
    number). The first parameter is the axis the summary page groups by."""
    data, where = campaign.source, campaign.name
    if "randomised" in data:
        from seapup_runs.randomised import random_adaptive_spec
        r = data["randomised"]
        if not isinstance(r, dict) or set(r) - {"count", "first", "controllers"}:
            raise CampaignError(f"{where}: randomised takes count, first, controllers")
        count, first = r.get("count"), r.get("first", 0)
        if isinstance(count, bool) or not isinstance(count, int) or count < 1 or not isinstance(first, int) or first < 0:
            raise CampaignError(f"{where}: randomised.count must be >= 1 and first >= 0 (integers)")
        laws = tuple(r.get("controllers") or ("explicit", "gmv"))
        rows = []
        for k in range(count):
            try:
                spec = random_adaptive_spec(first + k, laws).to_dict()
            except ValueError as exc:
                raise CampaignError(f"{where}: randomised: {exc}") from None
            rows.append({"index": k, "parameters": {"controller.type": spec["controller"]["type"],
                                                    "number": first + k}, "spec": spec})
        return rows
    base = _base_spec(data["base"], where)
    base.pop("physics_step", None)   # derived from the control period, which a campaign may vary
    grid = data.get("grid") or {}
    if not isinstance(grid, dict) or not all(isinstance(v, list) and v for v in grid.values()):
        raise CampaignError(f"{where}: grid maps a dotted path to a non-empty list of values")
    random = data.get("random") or {}
    if not isinstance(random, dict) or set(random) - {"count", "seed", "draws"}:
        raise CampaignError(f"{where}: random takes count, seed, draws")
    count = random.get("count", 1 if not random else None)
    draws = random.get("draws") or {}
    if random and (isinstance(count, bool) or not isinstance(count, int) or count < 1 or not isinstance(draws, dict)
                   or not draws):
        raise CampaignError(f"{where}: random needs count >= 1 and draws (a dotted path: a distribution)")
    seeds = data.get("seeds", 1)
    if isinstance(seeds, int) and not isinstance(seeds, bool) and seeds >= 1:
        # the replicates' seeds: from the campaign's name, so two campaigns do not share their noise
        seed_list = [int(s) % 2**31 for s in np.random.SeedSequence(_hash_text(campaign.name)).generate_state(seeds)]
    elif isinstance(seeds, list) and seeds and all(isinstance(s, int) and 0 <= s < 2**31 for s in seeds):
        seed_list = [int(s) for s in seeds]
    else:
        raise CampaignError(f"{where}: seeds is a count >= 1 or a list of seeds in [0, 2^31)")
    rng = np.random.default_rng(int(random.get("seed", 0)))
    rows = []
    for point in itertools.product(*grid.values()):
        for _ in range(count or 1):
            drawn = {path: _draw(rng, d, f"{where}: random.draws.{path}") for path, d in draws.items()}
            for seed in seed_list:
                parameters = {**dict(zip(grid, point)), **drawn, "seed": seed}
                spec = copy.deepcopy(base)
                # a new law starts from its own defaults: the base's parameters belong to the base's law
                for path, value in sorted(parameters.items(), key=lambda item: not item[0].endswith(".type")):
                    if path.endswith(".type") and isinstance(_get(spec, path[:-5]), dict) \
                            and _get(spec, path) != value:
                        _get(spec, path[:-5])["parameters"] = {}
                    _set(spec, path, value, where)
                rows.append({"index": len(rows), "parameters": parameters, "spec": spec})
    return rows


def _hash_text(text: str) -> int:
    return int(hashlib.sha256(text.encode()).hexdigest()[:8], 16)


def tasks(rows: list[dict], per_task: int) -> list[list[dict]]:
    """The runs grouped into tasks of ``per_task`` (the last may be shorter)."""
    return [rows[i:i + per_task] for i in range(0, len(rows), per_task)]


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


#: The loggers of the cores a run executes; a campaign keeps their records with the run's row.
RUN_LOGGERS = CORE_LOGGERS + ("seapup_runs",)
#: At most this many of a run's log lines are kept in its row (all are counted).
LOG_LINES_KEPT = 20


@contextmanager
def run_log():
    """The records the cores log meanwhile (:data:`RUN_LOGGERS`), as lines, instead of on the process's stderr:
    for code that flies many runs (a campaign task, a benchmark) and keeps or counts what they said."""
    lines: list[str] = []

    class Keep(logging.Handler):
        def emit(self, record):
            lines.append(f"{record.levelname.lower()}: {record.getMessage()}")
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
    their records by position in ``rows``. A batch shares its time, and its log lines, among its runs."""
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
        if len(members) < 2:
            continue
        wall, cpu = time.perf_counter(), time.process_time()
        with run_log() as lines:
            try:
                results = fly_batch([spec for _, spec in members])
            except Exception:   # e.g. a design that fails: each run then says why on its own
                continue
        wall, cpu = (time.perf_counter() - wall) / len(members), (time.process_time() - cpu) / len(members)
        for (k, spec), result in zip(members, results):
            record = _record(rows[k])
            record["name"] = spec.name
            if isinstance(result, Exception):
                _failed(record, result)
            else:
                record.update({f"metric.{key}": v for key, v in flatten(result.metrics).items()})
            record["log_lines"], record["log"] = len(lines), "\n".join(lines[:LOG_LINES_KEPT])
            record["wall_s"], record["cpu_s"] = wall, cpu
            out[k] = record
    return out


def fly_rows(rows: list[dict]) -> list[dict]:
    """Fly each run of a task in this process; one flat row per run (see the module docstring). Runs of one
    MFOL law on one sample grid fly together as a batch (:func:`seapup_runs.batch_runner.fly_batch`, the same
    results to rounding), the others one by one."""
    from seapup_runs.runner import run
    batched = _fly_batched(rows)
    out = []
    for k, row in enumerate(rows):
        if k in batched:
            out.append(batched[k])
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
