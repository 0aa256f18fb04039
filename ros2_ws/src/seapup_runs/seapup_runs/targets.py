"""The thesis's numbers as data (``data/thesis_targets.yaml``) and how ours are scored against them.

One file holds every reproducible result of Goheen's thesis that a seapup run can be asked for: its place
in the thesis, the value and unit, a tolerance with a one-line reason, the run that produces ours and the
metric (a dotted path into that run's result) that extracts it, and, where it applies, a documented
deviation or a thesis typo we read around. :func:`load_targets` reads and checks it (unknown keys,
units, runs, tolerances, duplicate ids: :class:`TargetsError`, one line); a matrix or vector ``value``
expands into one target per entry (``id[i,j]``, metric ``path.i.j``). A target with ``versus`` compares
two runs (the thesis's "at 20 Hz the rise time has decreased"): ours is the ratio of the metric in its run
to the metric in the ``versus`` run, judged by the tolerance (a number) or by ``holds`` (a statement:
``below`` / ``above`` a factor, or ``near`` 1 within a factor).

:func:`score` decides one target: ``reproduced`` (ours within the tolerance), ``deviation`` (missed, with
a documented deviation; also when the run produced no value for it), ``failed`` (missed, or the run produced no
finite value) or ``not_run`` (its run was not run). A deviation never counts as reproduced. :func:`summarise` counts per chapter and pooled.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from seapup_common.input_files import InputFileError, load_yaml_file

__all__ = ["Target", "Tolerance", "Score", "TargetsError", "STATUSES", "CHAPTERS", "TARGETS_FILE",
           "load_targets", "load_document", "runs_of", "score", "score_all", "summarise", "lookup",
           "targets_for_run", "verify_rows", "CAUSE_CLASSES", "verify_summary", "thesis_value", "thesis_by_metric"]

TARGETS_FILE = Path(__file__).resolve().parent / "data" / "thesis_targets.yaml"
STATUSES = ("reproduced", "deviation", "failed", "not_run")
CHAPTERS = ("3", "4", "5", "6", "7", "A")
_TARGET_KEYS = {"id", "chapter", "where", "quantity", "value", "unit", "tolerance", "run", "metric", "primary",
                "deviation", "typo", "versus"}
_REQUIRED = _TARGET_KEYS - {"primary", "deviation", "typo", "versus"}
_VERSUS_KEYS = {"run", "metric", "holds", "factor"}
_HOLDS = ("below", "above", "near")
_TOLERANCE_KEYS = {"abs", "rel", "abs_row", "range", "range_factor", "at_most", "at_least", "reason"}
_DEVIATION_KEYS = {"decision", "reason", "doc"}
_CAUSE_KEYS = {"class", "passage"}
CAUSE_CLASSES = {
    "a": "the thesis contradicts itself or omits what is needed",
    "b": "beyond the thesis's model",
    "c": "the thesis's implementation",
    "d": "unverifiable",
}
_TYPO_KEYS = {"read", "why"}
_RUN_KEYS = {"kind", "doc", "config", "rate_hz", "speeds", "name", "mode", "realisations", "seed", "dynamics", "current", "closed_loop", "scheduled", "seeds",
             "controller", "params", "sensors", "fit", "vehicles", "commissioning"}


class TargetsError(ValueError):
    """The targets file is malformed: the message names the target and the key."""


@dataclass(frozen=True)
class Tolerance:
    """How close counts: ``abs`` and/or ``rel`` (the larger band), ``range`` [lo, hi], ``range_factor`` k
    (within a factor k of the value, same sign), ``at_most`` / ``at_least`` a bound; with none of them
    (``abs: 0``) ours must equal the thesis's. ``same_sign``: ours must also have the sign of a non-zero
    thesis value (a small gain entry judged on its row's scale, :func:`_expand`). ``reason`` is the one line
    shown beside it."""

    reason: str
    abs: float | None = None
    rel: float | None = None
    range: tuple[float, float] | None = None
    range_factor: float | None = None
    at_most: float | None = None
    at_least: float | None = None
    name: str = ""
    same_sign: bool = False

    def bounds(self, value) -> tuple[float, float]:
        """The accepted interval [low, high] for a thesis value."""
        if isinstance(value, bool):
            return float(value), float(value)
        value = float(value)
        if self.range is not None:
            return float(self.range[0]), float(self.range[1])
        if self.at_most is not None or self.at_least is not None:
            return (-math.inf if self.at_least is None else self.at_least,
                    math.inf if self.at_most is None else self.at_most)
        if self.range_factor is not None:
            low, high = sorted((value / self.range_factor, value * self.range_factor))
            return low, high
        band = max(self.abs or 0.0, (self.rel or 0.0) * abs(value))
        low, high = value - band, value + band
        if self.same_sign and value > 0.0:
            low = max(low, math.ulp(0.0))      # the smallest positive number: zero has no sign
        elif self.same_sign and value < 0.0:
            high = min(high, -math.ulp(0.0))
        return low, high

    def text(self) -> str:
        """The tolerance in a few characters, for a table cell."""
        if self.range is not None:
            return f"[{self.range[0]:g}, {self.range[1]:g}]"
        if self.at_most is not None:
            return f"<= {self.at_most:g}"
        if self.at_least is not None:
            return f">= {self.at_least:g}"
        if self.range_factor is not None:
            return f"x/÷ {self.range_factor:g}"
        parts = ([f"±{self.rel * 100:g} %"] if self.rel else []) + ([f"±{self.abs:.3g}"] if self.abs else [])
        return (" or ".join(parts) if parts else "exact") + (", same sign" if self.same_sign else "")


@dataclass(frozen=True)
class Target:
    """One thesis number (or statement) and how ours is found and judged."""

    id: str
    chapter: str
    where: str
    quantity: str
    value: float | bool
    unit: str
    tolerance: Tolerance
    run: str
    metric: str
    primary: bool = True
    deviation: dict = field(default_factory=dict)
    typo: dict = field(default_factory=dict)
    versus: dict = field(default_factory=dict)

    @property
    def runs(self) -> tuple[str, ...]:
        """The runs whose results decide it: its own, and the one it is compared with."""
        return (self.run, self.versus["run"]) if self.versus else (self.run,)

    def holds(self, ratio: float) -> bool:
        """Whether a comparison statement holds for ``ratio`` (ours in :attr:`run` / ours in the versus run)."""
        factor = float(self.versus.get("factor", 1.0))
        kind = self.versus["holds"]
        if kind == "below":
            return ratio < factor
        if kind == "above":
            return ratio > factor
        return 1.0 / factor <= ratio <= factor

    @property
    def label(self) -> str:
        unit = "" if self.unit in ("1", "bool", "count") else f" [{self.unit}]"
        return f"{self.quantity}{unit}"


@dataclass(frozen=True)
class Score:
    """A target judged: ours, the accepted interval and the status (one of :data:`STATUSES`)."""

    target: Target
    ours: float | bool | None
    low: float
    high: float
    status: str
    ratio: float | None = None

    def row(self) -> dict:
        """The JSON row of ``report.json``'s ``targets``."""
        t = self.target
        ours = self.ours
        difference = (None if ours is None or isinstance(t.value, bool) or isinstance(ours, bool)
                      else float(ours) - float(t.value))
        return {"id": t.id, "chapter": t.chapter, "where": t.where, "quantity": t.quantity, "thesis": t.value,
                "ours": ours, "difference": difference, "unit": t.unit, "tolerance": t.tolerance.text(),
                "low": _finite_or_none(self.low), "high": _finite_or_none(self.high),
                "reason": t.tolerance.reason, "status": self.status, "run": t.run, "metric": t.metric,
                "primary": t.primary, "deviation": t.deviation or None, "typo": t.typo or None,
                "versus": dict(t.versus) or None, "ratio": self.ratio}


def _finite_or_none(v: float):
    return float(v) if math.isfinite(v) else None


def _fail(where: str, message: str):
    raise TargetsError(f"{TARGETS_FILE.name}: {where}: {message}")


def _tolerance(spec, named: dict, where: str) -> Tolerance:
    if isinstance(spec, str):
        if spec not in named:
            _fail(where, f"unknown tolerance {spec!r} (known: {', '.join(sorted(named))})")
        return named[spec]
    if not isinstance(spec, dict):
        _fail(where, f"tolerance must be a name or a mapping, got {spec!r}")
    unknown = set(spec) - _TOLERANCE_KEYS
    if unknown:
        _fail(where, f"unknown tolerance key(s) {sorted(unknown)}")
    reason = spec.get("reason")
    if not isinstance(reason, str) or not reason.strip():
        _fail(where, "a tolerance needs its one-line reason")
    numbers = {k: spec[k] for k in ("abs", "rel", "abs_row", "range_factor", "at_most", "at_least") if k in spec}
    for key, v in numbers.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or (
                key in ("abs", "rel", "abs_row", "range_factor") and v < 0):
            _fail(where, f"tolerance {key} must be a finite number >= 0, got {v!r}")
    if "range_factor" in spec and spec["range_factor"] < 1:
        _fail(where, "range_factor must be >= 1")
    rng = spec.get("range")
    if rng is not None and (not isinstance(rng, list) or len(rng) != 2 or not rng[0] <= rng[1]):
        _fail(where, f"range must be [low, high] with low <= high, got {rng!r}")
    kinds = [k for k in ("range", "range_factor", "at_most", "at_least") if k in spec]
    if len(kinds) > 1 + ("at_most" in kinds and "at_least" in kinds) or (kinds and ({"abs", "rel"} & set(spec))):
        _fail(where, f"a tolerance is abs/rel, range, range_factor or at_most/at_least, not {sorted(spec)}")
    return Tolerance(reason=reason.strip(), abs=numbers.get("abs"), rel=numbers.get("rel"),
                     range=tuple(rng) if rng is not None else None, range_factor=numbers.get("range_factor"),
                     at_most=numbers.get("at_most"), at_least=numbers.get("at_least"))


def load_document(path: str | Path | None = None) -> dict:
    """The targets file as parsed YAML (``units``, ``runs``, ``tolerances``, ``causes``, ``targets``)."""
    path = Path(path) if path is not None else TARGETS_FILE
    try:   # bounded and strict: at most 1 MiB, no duplicated key (a target given twice), safe tags only
        doc = load_yaml_file(path, "config")
    except InputFileError as exc:
        raise TargetsError(str(exc)) from None
    if not isinstance(doc, dict) or doc.get("schema") != 1:
        raise TargetsError(f"{path}: not a thesis targets file (schema: 1)")
    unknown = set(doc) - {"schema", "units", "runs", "tolerances", "causes", "targets"}
    if unknown:
        raise TargetsError(f"{path}: unknown top-level key(s) {sorted(unknown)}")
    return doc


def _text_fields(value, allowed: set) -> bool:
    return (isinstance(value, dict) and set(value) == allowed
            and all(isinstance(v, str) and v.strip() for v in value.values()))


def _check_deviation(entry: dict, where: str) -> None:
    """A deviation is {decision, reason, doc} for the whole target; a matrix or vector target may instead
    list several, each naming the ``entries`` ("i,j") it explains, no entry twice."""
    deviation = entry["deviation"]
    needs = f"deviation needs exactly {', '.join(sorted(_DEVIATION_KEYS))} (each a line of text)"
    if isinstance(deviation, dict) and "entries" not in deviation:
        if not _text_fields(deviation, _DEVIATION_KEYS):
            _fail(where, needs)
        return
    if not isinstance(entry["value"], list):
        _fail(where, "a deviation's entries are for a matrix or vector value")
    shape = np.shape(entry["value"])
    valid = {",".join(str(i) for i in index) for index in np.ndindex(shape)}
    seen = set()
    for part in deviation if isinstance(deviation, list) else [deviation]:
        if not isinstance(part, dict) or not _text_fields({k: v for k, v in part.items() if k != "entries"},
                                                          _DEVIATION_KEYS):
            _fail(where, needs + ", and entries")
        entries = part.get("entries")
        if not isinstance(entries, list) or not entries:
            _fail(where, "a deviation of part of a matrix lists its entries, e.g. entries: [\"2,3\"]")
        for key in entries:
            key = str(key).replace(" ", "")
            if key not in valid:
                _fail(where, f"deviation entry {key!r} is not an index of the {'x'.join(map(str, shape))} value")
            if key in seen:
                _fail(where, f"deviation entry {key!r} is explained twice")
            seen.add(key)


def _deviation_of(entry: dict, suffix: str) -> dict:
    """The deviation that explains one entry of a matrix/vector target (``suffix`` "i,j"), or none."""
    deviation = entry.get("deviation") or {}
    if isinstance(deviation, dict) and "entries" not in deviation:
        return dict(deviation)
    for part in deviation if isinstance(deviation, list) else [deviation]:
        if suffix in {str(k).replace(" ", "") for k in part["entries"]}:
            return {k: v for k, v in part.items() if k != "entries"}
    return {}


def _expand(entry: dict, tolerance: Tolerance, spec: dict) -> list[Target]:
    """A scalar target, or one per entry of a vector or matrix value (abs_row: a band per matrix row)."""
    value = entry["value"]
    base = dict(chapter=str(entry["chapter"]), where=str(entry["where"]), unit=str(entry["unit"]),
                run=str(entry["run"]), primary=bool(entry.get("primary", True)),
                deviation=_deviation_of(entry, ""), typo=dict(entry.get("typo") or {}),
                versus=dict(entry.get("versus") or {}))
    if not isinstance(value, list):
        if spec.get("abs_row") is not None:
            _fail(entry["id"], "abs_row is for a matrix value")
        return [Target(id=entry["id"], quantity=str(entry["quantity"]), value=value, tolerance=tolerance,
                       metric=str(entry["metric"]), **base)]
    array = np.asarray(value, dtype=float)
    if array.ndim not in (1, 2) or not np.all(np.isfinite(array)):
        _fail(entry["id"], "a list value must be a finite vector or matrix")
    out = []
    for index in np.ndindex(array.shape):
        tol = tolerance
        if spec.get("abs_row") is not None:
            if array.ndim != 2:
                _fail(entry["id"], "abs_row is for a matrix value")
            tol = _entry_band(tolerance, float(spec["abs_row"]), float(array[index]),
                              float(np.abs(array[index[0]]).max()))
        suffix = ",".join(str(i) for i in index)
        out.append(Target(id=f"{entry['id']}[{suffix}]", quantity=f"{entry['quantity']} [{suffix}]",
                          value=float(array[index]), tolerance=tol,
                          metric=".".join([str(entry["metric"]), *(str(i) for i in index)]),
                          **{**base, "deviation": _deviation_of(entry, suffix)}))
    return out


def _entry_band(tolerance: Tolerance, abs_row: float, value: float, row_max: float) -> Tolerance:
    """The band of one matrix entry under an ``abs_row`` tolerance. An entry of at least ``abs_row`` of its
    thesis row's largest magnitude is judged by the relative band alone (within +-``rel`` of it, which keeps
    its sign); a smaller one -- a cross-coupling whose own size makes a relative band a few thousandths wide,
    narrower than the noise of the step it was read from -- within ``abs_row`` of the row's largest entry,
    and with the thesis's sign where the thesis's entry is not zero."""
    scale = abs_row * row_max
    if abs(value) >= scale and tolerance.rel:
        return replace(tolerance, abs=None)
    return replace(tolerance, abs=scale, rel=None, same_sign=value != 0.0)


def _check_versus(entry: dict, runs: dict, where: str) -> None:
    versus = entry["versus"]
    if not isinstance(versus, dict) or set(versus) - _VERSUS_KEYS or "run" not in versus:
        _fail(where, f"versus is a mapping with run and optionally {', '.join(sorted(_VERSUS_KEYS - {'run'}))}")
    if versus["run"] not in runs:
        _fail(where, f"unknown versus run {versus['run']!r}")
    if versus["run"] == entry["run"] and versus.get("metric", entry["metric"]) == entry["metric"]:
        _fail(where, "versus compares a metric with itself")
    if "metric" in versus and (not isinstance(versus["metric"], str) or not versus["metric"]):
        _fail(where, "versus metric must be a dotted path")
    if isinstance(entry["value"], list):
        _fail(where, "a comparison (versus) is for a number or a statement, not a matrix")
    statement = isinstance(entry["value"], bool)
    if statement != ("holds" in versus):
        _fail(where, "a compared statement says how it holds (versus holds: below, above or near), "
                     "and a compared number has no holds (its tolerance judges the ratio)")
    if statement and versus["holds"] not in _HOLDS:
        _fail(where, f"versus holds must be one of {', '.join(_HOLDS)}, got {versus['holds']!r}")
    factor = versus.get("factor", 1.0)
    if "factor" in versus and (not statement or isinstance(factor, bool) or not isinstance(factor, (int, float))
                               or not math.isfinite(factor) or factor <= 0
                               or (versus["holds"] == "near" and factor < 1)):
        _fail(where, f"versus factor must be a finite number > 0 (>= 1 for near) with holds, got {factor!r}")
    if statement and versus["holds"] == "near" and "factor" not in versus:
        _fail(where, "versus holds near needs its factor")


@lru_cache(maxsize=4)
def _load(path: str) -> tuple[tuple[Target, ...], dict]:
    doc = load_document(path)
    units = doc.get("units") or {}
    runs = doc.get("runs") or {}
    for name, run in runs.items():
        if not isinstance(run, dict) or "kind" not in run or set(run) - _RUN_KEYS:
            raise TargetsError(f"{TARGETS_FILE.name}: run {name!r}: a mapping with kind and only "
                               f"{', '.join(sorted(_RUN_KEYS))}")
        if "fit" in run and (run["kind"] != "scenario" or run["fit"] not in _fits()):
            raise TargetsError(f"{Path(path).name}: run {name!r}: fit is a scenario run's (how its designing "
                               f"self-test fits its steps): {' or '.join(_fits())}, got {str(run['fit'])[:40]!r}")
    raw_tolerances = doc.get("tolerances") or {}
    named = {}
    for name, spec in raw_tolerances.items():
        named[name] = replace(_tolerance(spec, {}, f"tolerance {name!r}"), name=name)
    causes = _causes(doc.get("causes"), Path(path).name)
    targets, seen = [], set()
    for k, entry in enumerate(doc.get("targets") or []):
        where = f"target {k} ({entry.get('id', '?') if isinstance(entry, dict) else '?'})"
        if not isinstance(entry, dict):
            _fail(where, "a target is a mapping")
        missing, unknown = _REQUIRED - set(entry), set(entry) - _TARGET_KEYS
        if missing or unknown:
            _fail(where, f"missing {sorted(missing)}" if missing else f"unknown key(s) {sorted(unknown)}")
        if str(entry["chapter"]) not in CHAPTERS:
            _fail(where, f"chapter must be one of {', '.join(CHAPTERS)}, got {entry['chapter']!r}")
        if str(entry["unit"]) not in units:
            _fail(where, f"unknown unit {entry['unit']!r} (known: {', '.join(map(str, units))})")
        if entry["run"] not in runs:
            _fail(where, f"unknown run {entry['run']!r}")
        if isinstance(entry["value"], bool) != (entry["unit"] == "bool"):
            _fail(where, "a yes/no statement has unit bool and a true/false value, and only it")
        if not isinstance(entry["value"], (bool, int, float, list)):
            _fail(where, f"value must be a number, true/false or a list, got {entry['value']!r}")
        if not isinstance(entry["metric"], str) or not entry["metric"]:
            _fail(where, "metric must be a dotted path")
        if "typo" in entry and not _text_fields(entry["typo"], _TYPO_KEYS):
            _fail(where, f"typo needs exactly {', '.join(sorted(_TYPO_KEYS))} (each a line of text)")
        if "deviation" in entry:
            _check_deviation(entry, where)
        if "versus" in entry:
            _check_versus(entry, runs, where)
        spec = entry["tolerance"] if isinstance(entry["tolerance"], dict) else raw_tolerances.get(entry["tolerance"], {})
        tolerance = _tolerance(entry["tolerance"], named, where)
        for target in _expand(entry, tolerance, spec):
            if target.id in seen:
                _fail(where, f"duplicate id {target.id!r}")
            seen.add(target.id)
            if target.deviation:
                target = replace(target, deviation={**target.deviation, **_cause_of(target.deviation, causes, where)})
            targets.append(target)
    unused = set(causes) - {t.deviation.get("cause") for t in targets if t.deviation}
    if unused:
        raise TargetsError(f"{Path(path).name}: cause(s) {sorted(unused)} explain no target's deviation")
    return tuple(targets), {"units": units, "runs": runs, "tolerances": named, "causes": causes}


def _fits() -> tuple:
    from seapup_control.self_test import FITS   # the self-test's own list (a scenario run's design.fit)
    return FITS


def _causes(raw, file: str) -> dict:
    """The register's causes: anchor of ``docs/decisions.md`` -> {class, passage} (:data:`CAUSE_CLASSES`)."""
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        raise TargetsError(f"{file}: causes: a mapping of docs/decisions.md anchors to {{class, passage}}")
    for name, cause in raw.items():
        if not _text_fields(cause, _CAUSE_KEYS):
            raise TargetsError(f"{file}: cause {name!r}: needs exactly class and passage (each a line of text)")
        if cause["class"] not in CAUSE_CLASSES:
            raise TargetsError(f"{file}: cause {name!r}: class must be one of {', '.join(CAUSE_CLASSES)}, "
                               f"got {str(cause['class'])[:40]!r}")
    return {str(k): dict(v) for k, v in raw.items()}


def _cause_of(deviation: dict, causes: dict, where: str) -> dict:
    """A deviation's cause (its ``doc`` anchor in ``docs/decisions.md``), class and deciding passage; with no
    ``causes`` section (a targets file of a test) none is asked for."""
    if not causes:
        return {}
    doc = deviation["doc"]
    anchor = doc.partition("#")[2] if doc.startswith("docs/decisions.md#") else ""
    if anchor not in causes:
        _fail(where, f"deviation's entry {doc!r} is not a cause of the register (causes: docs/decisions.md#<anchor>)")
    return {"cause": anchor, "class": causes[anchor]["class"], "passage": causes[anchor]["passage"]}


def load_targets(path: str | Path | None = None) -> list[Target]:
    """Every target of the file (matrices expanded), checked; :class:`TargetsError` names what is wrong."""
    return list(_load(str(Path(path) if path is not None else TARGETS_FILE))[0])


def runs_of(path: str | Path | None = None) -> dict:
    """The file's ``runs``: name -> its description (``kind`` and the kind's settings)."""
    return dict(_load(str(Path(path) if path is not None else TARGETS_FILE))[1]["runs"])


def targets_for_run(run: str, path: str | Path | None = None) -> list[Target]:
    """The targets a run answers alone (comparisons with another run are left to :func:`score_all`)."""
    return [t for t in load_targets(path) if t.run == run and not t.versus]


def lookup(result, path: str):
    """The value at a dotted ``path`` in a run's result (mappings by key, lists by index); None if absent."""
    node = result
    for part in path.split("."):
        if isinstance(node, dict):
            node = node.get(part)
        elif isinstance(node, (list, tuple, np.ndarray)):
            try:
                node = node[int(part)]
            except (ValueError, IndexError):
                return None
        else:
            return None
        if node is None:
            return None
    if isinstance(node, np.generic):
        node = node.item()
    return node


def _number(value) -> float | None:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
        return None
    return float(value)


def score(target: Target, result, versus_result=None) -> Score:
    """Judge ``target`` against its run's ``result`` (None: the run was not run); a comparison also against
    its versus run's ``versus_result``."""
    low, high = target.tolerance.bounds(target.value)
    if result is None or (target.versus and versus_result is None):
        return Score(target, None, low, high, "not_run")
    if target.versus:
        mine = _number(lookup(result, target.metric))
        theirs = _number(lookup(versus_result, target.versus.get("metric", target.metric)))
        if mine is None or theirs is None or theirs == 0.0:
            return Score(target, None, low, high, _missed(target))
        ratio = mine / theirs
        if isinstance(target.value, bool):
            ours = target.holds(ratio)
            return Score(target, ours, low, high, "reproduced" if ours == target.value else _missed(target), ratio)
        return Score(target, ratio, low, high, "reproduced" if low <= ratio <= high else _missed(target), ratio)
    ours = lookup(result, target.metric)
    if isinstance(target.value, bool):
        if isinstance(ours, (bool, int, float, np.bool_)) and not (isinstance(ours, float) and math.isnan(ours)):
            ours = bool(ours)
            return Score(target, ours, low, high, "reproduced" if ours == target.value else _missed(target))
        return Score(target, None, low, high, _missed(target))
    ours = _number(ours)
    if ours is None:
        return Score(target, None, low, high, _missed(target))  # no value: missed (a limit cycle that never came)
    return Score(target, ours, low, high, "reproduced" if low <= ours <= high else _missed(target))


def _missed(target: Target) -> str:
    return "deviation" if target.deviation else "failed"


def score_all(targets: list[Target], results: dict) -> list[Score]:
    """Every target judged against ``results`` (run name -> result; a missing run: not run)."""
    return [score(t, results.get(t.run), results.get(t.versus["run"]) if t.versus else None) for t in targets]


def summarise(scores: list[Score]) -> dict:
    """``{"chapters": {ch: counts}, "pooled": counts}``; counts: asked, reproduced, deviations, failed,
    not_run, by_class (the missed deviations per class of their cause, :data:`CAUSE_CLASSES`), misses (the ids
    not reproduced). Pooled over every chapter scored."""
    def counts(rows):
        return {"asked": len(rows), "reproduced": sum(s.status == "reproduced" for s in rows),
                "deviations": sum(s.status == "deviation" for s in rows),
                "failed": sum(s.status == "failed" for s in rows),
                "not_run": sum(s.status == "not_run" for s in rows),
                "by_class": {c: sum(s.status == "deviation" and s.target.deviation.get("class") == c for s in rows)
                             for c in CAUSE_CLASSES},
                "misses": [s.target.id for s in rows if s.status in ("failed", "deviation")]}
    chapters = {ch: counts([s for s in scores if s.target.chapter == ch]) for ch in CHAPTERS
                if any(s.target.chapter == ch for s in scores)}
    return {"chapters": chapters, "pooled": counts(scores)}


# -- ./seapup verify's view: the targets of run verify:<config> as PASS / FAIL / DEV rows ----------------
_VERIFY_STATUS = {"reproduced": "PASS", "failed": "FAIL", "deviation": "DEV", "not_run": "FAIL"}


def verify_rows(result: dict, config: str) -> list[dict]:
    """Rows for ``./seapup verify`` of ``config``: ``status`` PASS, FAIL or DEV (a documented deviation that
    is missed; ``deviation`` says why and where). ``primary`` is false for a target with a deviation: only
    primary rows decide the command's exit status."""
    rows = []
    for s in score_all(targets_for_run(f"verify:{config}"), {f"verify:{config}": result}):
        t = s.target
        deviation = f"{t.deviation['reason']}; {t.deviation['doc']}" if t.deviation else ""
        rows.append({"id": t.id, "label": t.label, "key": t.metric, "value": s.ours, "thesis": t.value,
                     "low": s.low, "high": s.high, "primary": t.primary and not t.deviation,
                     "pass": s.status == "reproduced", "status": _VERIFY_STATUS[s.status], "deviation": deviation,
                     "source": t.where, "tolerance": t.tolerance.text(), "reason": t.tolerance.reason})
    return rows


def verify_summary(rows: list[dict]) -> dict:
    """Counts of what passed: primaries, secondaries, documented deviations; ``ok`` iff every primary passed."""
    primary = [r for r in rows if r["primary"]]
    secondary = [r for r in rows if not r["primary"] and not r["deviation"]]
    deviations = [r for r in rows if r["deviation"]]
    return {"primary_passed": sum(r["pass"] for r in primary), "primary": len(primary),
            "secondary_passed": sum(r["pass"] for r in secondary), "secondary": len(secondary),
            "deviations": sum(not r["pass"] for r in deviations), "scored": len(rows),
            "ok": all(r["pass"] for r in primary)}


def thesis_value(target_id: str, path: str | Path | None = None):
    """The thesis's value of a target by its id in the file: a number or true/false, or an array for a
    vector or matrix target (its expanded entries put back together); KeyError if there is none."""
    found = [t for t in load_targets(path) if t.id == target_id or t.id.startswith(f"{target_id}[")]
    if not found:
        raise KeyError(target_id)
    if len(found) == 1 and found[0].id == target_id:
        return found[0].value
    index = [tuple(int(i) for i in t.id[len(target_id) + 1:-1].split(",")) for t in found]
    out = np.zeros(tuple(max(i[d] for i in index) + 1 for d in range(len(index[0]))))
    for i, t in zip(index, found):
        out[i] = t.value
    return out


def thesis_by_metric(run: str, path: str | Path | None = None) -> dict:
    """The thesis's values of a run's scalar targets, by metric path (for a command's "thesis in brackets")."""
    return {t.metric: t.value for t in targets_for_run(run, path)}
