"""What a run gives back: the spec, the logged signals by name, the metrics -- one shape for every verb.

Like python-control's ``TimeResponseData``: one object per run, signals named
rather than indexed, plots and reports built from it (never from a verb's
private dict). :meth:`RunResult.to_json` writes the shape every ``--json`` of
a run uses (documented in ``docs/run-result.md``)::

    {"format": "seapup/run_result", "version": 1,
     "spec": {...RunSpec.to_dict()...},
     "metrics": {...},
     "series": {"t": [...],                                   # s, one row per control sample
                "truth":    {"u": [...], "v": ..., "w", "r", "p", "q", "roll", "pitch", "yaw", "x", "y", "z"},
                "measured": {same names where measured, plus "depth", "altitude"; null where invalid},
                "reference": {"u", "v", "w", "r"},            # used at each sample (null at the last)
                "command": [[4 blade pitches], ...],          # rad, held over [t_k, t_k+1] (null at the last)
                "applied": [[4 blade pitches], ...],          # rad, the vehicle's at t_k
                "events":  [{"time", "kind", "detail"}, ...],
                "estimate": {"names": [...], "values": [[...], ...]}}}   # estimating controllers only

SI units and radians; ``truth`` and ``measured`` in ``odom_ned`` / ``base_link_frd``.
:func:`~seapup_runs.bag.result_from_bag` reads the same object back from a
graph run's recording.
"""
from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from seapup_common.input_files import InputFileError, read_text
from seapup_common.jsondata import jsonable
from seapup_runs.spec import RunSpec, RunSpecError

__all__ = ["RunResultError", "Series", "RunResult", "TRUTH_NAMES", "STATE_INDEX", "MEASURED_NAMES",
           "REFERENCE_NAMES", "FORMAT", "jsonable"]

FORMAT = "seapup/run_result"
#: Named truth signals and their index in the thesis-order 12-state (x y z phi theta psi u v w p q r).
STATE_INDEX = {"u": 6, "v": 7, "w": 8, "r": 11, "p": 9, "q": 10, "roll": 3, "pitch": 4, "yaw": 5,
               "x": 0, "y": 1, "z": 2}
TRUTH_NAMES = tuple(STATE_INDEX)
#: Measured signals: the truth names an instrument gives, plus the depth gauge and the altimeter.
MEASURED_NAMES = TRUTH_NAMES + ("depth", "altitude")
REFERENCE_NAMES = ("u", "v", "w", "r")


class RunResultError(ValueError):
    """A result document that is not a seapup run result, or signals of inconsistent lengths."""


def _array(values, width: int | None = None) -> np.ndarray:
    """A float array from JSON lists (None -> NaN)."""
    if width is None:
        return np.array([np.nan if v is None else v for v in values], dtype=float)
    return np.array([[np.nan if x is None else x for x in row] if row is not None else [np.nan] * width
                     for row in values], dtype=float).reshape(-1, width)


@dataclass
class Series:
    """The logged signals of a run, one row per control sample (see the module docstring).

    ``truth``, ``measured`` and ``reference`` map names to (n,) arrays; ``command`` and ``applied``
    are (n, 4); ``events`` a list of ``{"time", "kind", "detail"}``; ``estimate`` ``{"names": [...],
    "values": (n, k)}`` or None.
    """

    t: np.ndarray
    truth: dict
    measured: dict
    reference: dict
    command: np.ndarray
    applied: np.ndarray
    events: list = field(default_factory=list)
    estimate: dict | None = None

    def __post_init__(self):
        n = len(self.t)
        for group in ("truth", "measured", "reference"):
            for name, values in getattr(self, group).items():
                if len(values) != n:
                    raise RunResultError(f"{group} {name}: {len(values)} values for {n} samples")
        for name in ("command", "applied"):
            if getattr(self, name).shape != (n, 4):
                raise RunResultError(f"{name} must be ({n}, 4), got {getattr(self, name).shape}")

    @classmethod
    def from_states(cls, t, states, measured: Mapping, reference, command, applied, events=(),
                    estimate=None) -> "Series":
        """From a (n, 12) thesis-order truth array and a (n, 4) reference array."""
        states = np.asarray(states, float)
        reference = np.asarray(reference, float)
        return cls(np.asarray(t, float), {k: states[:, i].copy() for k, i in STATE_INDEX.items()},
                   {k: np.asarray(v, float) for k, v in measured.items()},
                   {k: reference[:, j].copy() for j, k in enumerate(REFERENCE_NAMES)},
                   np.asarray(command, float), np.asarray(applied, float), list(events), estimate)

    def states(self) -> np.ndarray:
        """The truth as the thesis-order (n, 12) state."""
        out = np.full((len(self.t), 12), np.nan)
        for name, i in STATE_INDEX.items():
            out[:, i] = self.truth[name]
        return out

    def velocity(self) -> np.ndarray:
        """True (u, v, w, r) as (n, 4)."""
        return np.column_stack([self.truth[k] for k in REFERENCE_NAMES])

    def reference_array(self) -> np.ndarray:
        return np.column_stack([self.reference[k] for k in REFERENCE_NAMES])

    def to_dict(self) -> dict:
        out = {"t": self.t, "truth": self.truth, "measured": self.measured, "reference": self.reference,
               "command": self.command, "applied": self.applied, "events": self.events}
        if self.estimate is not None:
            out["estimate"] = self.estimate
        return jsonable(out)

    @classmethod
    def from_dict(cls, data: Mapping) -> "Series":
        try:
            estimate = data.get("estimate")
            if estimate is not None:
                estimate = {"names": list(estimate["names"]), "values": _array(estimate["values"],
                                                                                len(estimate["names"]))}
            return cls(_array(data["t"]), {k: _array(v) for k, v in data["truth"].items()},
                       {k: _array(v) for k, v in data["measured"].items()},
                       {k: _array(v) for k, v in data["reference"].items()},
                       _array(data["command"], 4), _array(data["applied"], 4), list(data.get("events") or []),
                       estimate)
        except (KeyError, TypeError) as exc:
            raise RunResultError(f"malformed series: missing or bad {exc}") from None


@dataclass
class RunResult:
    """A run: its spec, its signals and its metrics (see the module docstring)."""

    spec: RunSpec
    series: Series
    metrics: dict = field(default_factory=dict)
    transport: str = "in-process"

    def reference_steps_flown(self) -> list:
        """The reference profile's ``(time, (u, v, w, r))`` steps the run reached with at least two samples
        (a profile may go on beyond the duration); the first step always."""
        t, steps = self.series.t, self.spec.reference.steps
        return [steps[0]] + [step for step in steps[1:] if len(t) > 1 and step[0] <= t[-2] + 1e-9]

    def to_dict(self) -> dict:
        return {"format": FORMAT, "version": 1, "transport": self.transport, "spec": jsonable(self.spec.to_dict()),
                "metrics": jsonable(self.metrics), "series": self.series.to_dict()}

    def to_json(self, path: str | Path | None = None, indent: int | None = None) -> str:
        """The JSON text (and written to ``path`` when given)."""
        text = json.dumps(self.to_dict(), indent=indent)
        if path is not None:
            Path(path).write_text(text + "\n")
        return text

    @classmethod
    def from_dict(cls, data: Mapping) -> "RunResult":
        if not isinstance(data, Mapping) or data.get("format") != FORMAT:
            raise RunResultError(f"not a seapup run result (format: {FORMAT})")
        if data.get("version") != 1:
            raise RunResultError(f"run result version {data.get('version')!r} is not supported (1 is)")
        return cls(RunSpec.from_dict(data["spec"]), Series.from_dict(data["series"]), dict(data.get("metrics") or {}),
                   str(data.get("transport", "in-process")))

    @classmethod
    def from_json(cls, source: str | Path) -> "RunResult":
        """From JSON text or a file path."""
        text = source
        if isinstance(source, Path) or (isinstance(source, str) and not source.lstrip().startswith("{")):
            try:   # bounded: at most the data limit (docs/limits.md), UTF-8 text
                text = read_text(source, "data")
            except InputFileError as exc:
                raise RunResultError(str(exc)) from None
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise RunResultError(f"not JSON: {exc}") from None
        except RecursionError:
            raise RunResultError("not a seapup run result: nested too deeply") from None
        try:
            return cls.from_dict(data)
        except RunSpecError as exc:
            raise RunResultError(f"its spec: {exc}") from None
