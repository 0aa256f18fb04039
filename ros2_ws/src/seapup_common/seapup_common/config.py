"""Typed configuration loading: YAML files with ``extends``, read through views
whose errors name the file and the key.

Every seapup configuration -- vehicles, environments, sensor profiles, node
parameter files -- is data in YAML, read once at a boundary into typed
objects. This module is the shared machinery for that:

- :func:`merge` deep-merges an overlay over a base (mappings merge key by key,
  anything else replaces);
- :func:`load_yaml` reads one mapping and follows ``extends: <name>`` chains
  (an overlay changes only what it names);
- :class:`ConfigView` is a read-only mapping over the result that remembers
  where it came from: ``view["rigid_body"]["mass"]`` on a file without it
  raises :class:`ConfigError` ``"baseline.yaml: missing key rigid_body.mass"``
  instead of a bare ``KeyError``, and :meth:`ConfigView.number`,
  :meth:`~ConfigView.vector`, :meth:`~ConfigView.flag`,
  :meth:`~ConfigView.choice` check type and range with the same kind of
  message.
"""
from __future__ import annotations

import copy
import os
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from seapup_common.values import finite_real, is_real

__all__ = ["ConfigError", "merge", "load_yaml", "parsed_yaml", "ConfigView", "nearest"]

_MISSING = object()


class ConfigError(ValueError):
    """A configuration that is missing, malformed, or has a bad or missing key."""


def merge(base: Mapping, overlay: Mapping, strict: str | None = None, _path: str = "") -> dict:
    """Deep merge (copies): mappings merge recursively, other values replace.

    With ``strict`` (the overlay's source, for the message) every key of the overlay must be one the
    base has: a misspelled key would otherwise be carried along unread, and what it meant to change
    would silently stay as it was.

    Raises
    ------
    ConfigError
        ``strict`` and a key the base does not have, naming it (dotted) and the nearest valid key.

    Examples
    --------
    >>> merge({"a": {"x": 1, "y": 2}, "b": 1}, {"a": {"y": 3}})
    {'a': {'x': 1, 'y': 3}, 'b': 1}
    >>> merge({"current": {"enabled": False}}, {"current": {"enabeld": True}}, strict="my.yaml")
    Traceback (most recent call last):
    ...
    seapup_common.config.ConfigError: my.yaml: unknown key current.enabeld (did you mean current.enabled?)
    """
    out = {k: copy.deepcopy(v) for k, v in base.items()}
    for key, value in overlay.items():
        if strict is not None and key not in out:
            raise ConfigError(f"{strict}: unknown key {_path}{key}" + _nearest(key, out, _path))
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = merge(out[key], value, strict, f"{_path}{key}.")
        else:
            out[key] = copy.deepcopy(value)
    return out


def nearest(name, options) -> str | None:
    """The one of ``options`` closest to a misspelled ``name`` (``difflib``), or None: the hint of every
    "unknown key/parameter/topic" message."""
    import difflib
    near = difflib.get_close_matches(str(name), sorted(str(o) for o in options), n=1, cutoff=0.6)
    return near[0] if near else None


def _nearest(key, options, path: str = "") -> str:
    near = nearest(key, options)
    return f" (did you mean {path}{near}?)" if near else f" (valid: {', '.join(map(str, options))})"


#: Parsed files by (resolved path, modification time, size): a batch of runs reads the same few
#: configurations thousands of times; an edited file is parsed again.
_PARSED: dict = {}


def parsed_yaml(path: str | Path, *, shared: bool = False):
    """The YAML document in ``path``, a fresh copy: parsed once per version of the file, bounded and
    strictly (:mod:`seapup_common.input_files`: at most 1 MiB, no duplicated key, safe tags only).
    ``shared``: the cached document itself, not a copy, for a caller that only reads it.

    Raises
    ------
    ConfigError
        If the file is missing, unreadable, too large, or not strict YAML (one line naming the file).
    """
    from seapup_common.input_files import InputFileError, parse_yaml, read_text
    path = Path(path)
    try:
        stat = path.stat()
    except OSError as exc:
        raise ConfigError(f"cannot read configuration {path}: {exc.strerror or exc}") from None
    key = (os.path.abspath(path), stat.st_mtime_ns, stat.st_size)   # abspath: no system call per read
    if key not in _PARSED:
        try:
            document = parse_yaml(read_text(path, "config"), str(path))
        except InputFileError as exc:
            raise ConfigError(f"cannot read configuration {exc}") from None
        if len(_PARSED) > 256:
            _PARSED.clear()
        _PARSED[key] = document
    return _PARSED[key] if shared else copy.deepcopy(_PARSED[key])


def load_yaml(path: str | Path, _seen: tuple = ()) -> dict:
    """A YAML mapping, with ``extends: <name or file>`` resolved recursively.

    ``extends: baseline`` names ``baseline.yaml`` in the same directory (or a
    path with a suffix). The result has no ``extends`` key.

    Raises
    ------
    ConfigError
        If a file is unreadable, not a mapping, or the chain loops.
    """
    path = Path(path)
    if _seen and path.resolve() in _seen:
        raise ConfigError(f"{path.name}: 'extends' loops back to itself")
    data = parsed_yaml(path)
    data = {} if data is None else data
    if not isinstance(data, dict):
        raise ConfigError(f"{path.name}: the top level must be a mapping, got {type(data).__name__}")
    parent = data.pop("extends", None)
    if parent is None:
        return data
    parent_path = Path(str(parent))
    if not parent_path.suffix:
        parent_path = path.parent / f"{parent}.yaml"
    elif not parent_path.is_absolute():
        parent_path = path.parent / parent_path
    if not parent_path.is_file():
        raise ConfigError(f"{path.name}: extends {parent!r}, but {parent_path} does not exist")
    return merge(load_yaml(parent_path, _seen + (path.resolve(),)), data)


class ConfigView(Mapping):
    """Read-only view of a configuration mapping that names keys in its errors.

    Parameters
    ----------
    data : Mapping
        The configuration (nested mappings become nested views on access).
    source : str
        Where it came from, used in messages (e.g. ``"camera.yaml"``).
    path : str, optional
        Dotted key path of this view inside the source.
    """

    def __init__(self, data: Mapping, source: str = "configuration", path: str = ""):
        if not isinstance(data, Mapping):
            raise ConfigError(f"{source}: {path or 'the top level'} must be a mapping, "
                              f"got {type(data).__name__}")
        self._data = data
        self.source = source
        self.path = path

    def _where(self, key) -> str:
        return f"{self.path}.{key}" if self.path else str(key)

    def error(self, key, message: str) -> ConfigError:
        """A :class:`ConfigError` naming this source and ``key``."""
        return ConfigError(f"{self.source}: {self._where(key)}: {message}")

    def __getitem__(self, key):
        if key not in self._data:
            raise ConfigError(f"{self.source}: missing key {self._where(key)}")
        value = self._data[key]
        if isinstance(value, Mapping):
            return ConfigView(value, self.source, self._where(key))
        return value

    def get(self, key, default=None):
        """The value (nested mappings as views), or ``default`` when the key is absent."""
        return self[key] if key in self._data else default

    def __iter__(self):
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __repr__(self) -> str:
        return f"ConfigView({self.source}:{self.path or '/'}, {dict(self._data)!r})"

    def raw(self) -> dict:
        """A deep copy of the underlying data as plain dicts and lists."""
        return copy.deepcopy(dict(self._data))

    def section(self, key, default=_MISSING) -> "ConfigView":
        """A nested mapping as a view (an empty view if absent and ``default`` given)."""
        if key not in self._data and default is not _MISSING:
            return ConfigView(default if default is not None else {}, self.source, self._where(key))
        value = self[key]
        if not isinstance(value, ConfigView):
            raise self.error(key, f"must be a mapping, got {value!r}")
        return value

    def number(self, key, default=_MISSING, *, lo: float = -math.inf, hi: float = math.inf,
               lo_open: bool = False) -> float:
        """A finite real in [lo, hi] (``(lo, hi]`` with ``lo_open``)."""
        value = self._get(key, default)
        if not is_real(value):
            raise self.error(key, f"must be a number, got {value!r}")
        value = finite_real(value)
        value = math.inf if value is None else value
        low_ok = value > lo if lo_open else value >= lo
        if not (math.isfinite(value) and low_ok and value <= hi):
            bracket = "(" if lo_open else "["
            raise self.error(key, f"{value!r} is outside the allowed range {bracket}{lo:g}, {hi:g}]")
        return value

    def integer(self, key, default=_MISSING, *, lo: int | None = None, hi: int | None = None) -> int:
        """An integer in [lo, hi]."""
        value = self._get(key, default)
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise self.error(key, f"must be an integer, got {value!r}")
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise self.error(key, f"{value} is outside the allowed range [{lo}, {hi}]")
        return int(value)

    def vector(self, key, n: int | None = None, default=_MISSING, *, lo: float = -math.inf,
               hi: float = math.inf) -> np.ndarray:
        """A 1-D array of finite reals (exactly ``n`` of them if given), each in [lo, hi]."""
        value = self._get(key, default)
        if isinstance(value, np.ndarray):
            value = value.tolist()
        if not isinstance(value, (list, tuple)) or not all(is_real(v) for v in value):   # numbers only: no '0.2' strings, no booleans, no nested lists
            raise self.error(key, f"must be a list of numbers, got {value!r}"[:300])
        try:
            arr = np.asarray(value, dtype=float)
        except OverflowError:   # an integer beyond a float's range
            arr = np.full(len(value), np.inf)
        if arr.ndim != 1 or (n is not None and arr.size != n):
            raise self.error(key, f"needs {n if n is not None else 'a list of'} numbers, got {value!r}")
        if not np.all(np.isfinite(arr)) or np.any(arr < lo) or np.any(arr > hi):
            raise self.error(key, f"{arr.tolist()} has values outside the allowed range [{lo:g}, {hi:g}]")
        return arr

    def flag(self, key, default=_MISSING) -> bool:
        """A true/false value (YAML booleans only: ``1`` or ``"yes"`` are refused)."""
        value = self._get(key, default)
        if not isinstance(value, bool):
            raise self.error(key, f"must be true or false, got {value!r}")
        return value

    def choice(self, key, choices, default=_MISSING) -> str:
        """A string out of ``choices``."""
        value = self._get(key, default)
        if value not in tuple(choices):
            raise self.error(key, f"{value!r} is not one of {', '.join(map(str, choices))}")
        return str(value)

    def _get(self, key, default):
        if key in self._data:
            return self._data[key]
        if default is _MISSING:
            raise ConfigError(f"{self.source}: missing key {self._where(key)}")
        return default
