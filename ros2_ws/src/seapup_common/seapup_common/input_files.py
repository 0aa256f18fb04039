"""Bounded, strict reading of the files a user hands seapup.

Every file seapup reads -- run and mission specifications, campaign files, launch files, vehicle,
environment, controller and node parameter files, bag metadata -- passes through this module before it
is parsed, so a hostile or mistaken file is refused in one line and nothing is allocated for it:

- :func:`read_text` reads at most a stated number of bytes (:data:`LIMITS`, by kind of file) and
  refuses anything larger *while reading* (``/dev/zero`` is refused after ``limit + 1`` bytes, not
  after it filled the memory), a directory, a file that is not UTF-8 text, and a NUL byte;
- :func:`parse_yaml` is YAML 1.1 with the safe tags only (``!!python/...`` is refused), and it
  refuses a duplicated key in a mapping (YAML says keys are unique; PyYAML silently keeps the last
  one), a document nested deeper than :data:`MAX_DEPTH`, and one whose aliases expand to more than
  :data:`MAX_NODES` nodes (the "billion laughs"), before any Python object is built;
- :func:`load_yaml_file` is both, with an empty (or comment-only) file refused unless the caller
  says an empty document is meant.

The limits can be raised where a user may need more: ``SEAPUP_MAX_FILE_BYTES`` (bytes) applies to
every kind of file at once.

Errors are :class:`InputFileError` (a :class:`ValueError`), whose message names the file and the reason.
"""
from __future__ import annotations

import os
import stat
from pathlib import Path

import yaml

__all__ = ["InputFileError", "LIMITS", "MAX_DEPTH", "MAX_NODES", "limit_for", "env_limit", "read_text",
           "parse_yaml", "load_yaml_file"]

#: The largest file of each kind, in bytes: far above anything seapup ships (its largest YAML file,
#: the thesis targets, is about 0.1 MB) and far below what would strain a machine.
LIMITS: dict[str, int] = {
    "spec": 1 << 20,          # run, mission and campaign specifications
    "config": 1 << 20,        # vehicle, environment, sensor, controller and node parameter files
    "launch": 1 << 20,        # ROS 2 YAML launch files
    "bag_metadata": 16 << 20,  # a bag's metadata.yaml (one entry per topic)
    "data": 64 << 20,         # CSV records and JSON results read back
}
#: The deepest nesting of a YAML document (seapup's deepest file has 6 levels).
MAX_DEPTH = 64
#: The most nodes a YAML document may expand to, aliases counted at every use.
MAX_NODES = 1_000_000
#: The environment variable that raises every limit of :data:`LIMITS` (a size in bytes).
ENV_LIMIT = "SEAPUP_MAX_FILE_BYTES"


class InputFileError(ValueError):
    """A file that is too large, unreadable, not text, not the format expected, or empty."""


def limit_for(kind: str) -> int:
    """The byte limit of a kind of file: :data:`LIMITS`, or ``$SEAPUP_MAX_FILE_BYTES`` when set.

    Raises
    ------
    InputFileError
        For an unknown kind, or a ``SEAPUP_MAX_FILE_BYTES`` that is not a positive integer.
    """
    if kind not in LIMITS:
        raise InputFileError(f"unknown kind of file {kind!r} (known: {', '.join(LIMITS)})")
    text = os.environ.get(ENV_LIMIT, "").strip()
    if not text:
        return LIMITS[kind]
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value <= 0:
        raise InputFileError(f"{ENV_LIMIT} must be a positive number of bytes, got {text!r}")
    return value


def env_limit(name: str, default: int) -> int:
    """A count limit: ``default``, or the positive integer in the environment variable ``name`` when set
    (how a user raises one of seapup's stated caps: ``docs/limits.md``).

    Raises
    ------
    InputFileError
        If the variable is set to anything but a positive integer.
    """
    text = os.environ.get(name, "").strip()
    if not text:
        return default
    if not text.isdigit() or int(text) <= 0:
        raise InputFileError(f"{name} must be a positive integer, got {text!r}")
    return int(text)


def _size_text(n: int) -> str:
    return f"{n / (1 << 20):g} MiB" if n >= 1 << 20 else f"{n} bytes"


def read_text(path: str | Path, kind: str = "config", *, limit: int | None = None) -> str:
    """The text of ``path``, read with a bound.

    Parameters
    ----------
    path : str or Path
        The file.
    kind : str
        Its kind (a key of :data:`LIMITS`), which sets the bound.
    limit : int, optional
        The bound in bytes, instead of the kind's.

    Returns
    -------
    str
        The file's text (UTF-8).

    Raises
    ------
    InputFileError
        If the file is missing, a directory, unreadable, larger than the bound (refused after reading
        ``limit + 1`` bytes at most), not UTF-8 text, or holds a NUL byte.
    """
    path = Path(path)
    limit = limit_for(kind) if limit is None else int(limit)
    if path.is_dir():
        raise InputFileError(f"{path}: is a directory, not a file")
    try:
        mode = path.stat().st_mode
    except OSError:
        mode = 0
    if stat.S_ISFIFO(mode) or stat.S_ISSOCK(mode):
        # opening a pipe with no writer blocks for ever: refused by its kind, before it is opened
        raise InputFileError(f"{path}: is a {'pipe' if stat.S_ISFIFO(mode) else 'socket'}, not a file")
    try:
        with open(path, "rb") as handle:
            data = handle.read(limit + 1)
    except FileNotFoundError:
        raise InputFileError(f"{path}: no such file") from None
    except PermissionError:
        raise InputFileError(f"{path}: permission denied") from None
    except OSError as exc:
        raise InputFileError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if len(data) > limit:
        raise InputFileError(f"{path}: larger than {_size_text(limit)}, the limit for a {kind.replace('_', ' ')} "
                             f"file (set {ENV_LIMIT} to allow more)")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputFileError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    if "\x00" in text:
        raise InputFileError(f"{path}: holds a NUL byte at offset {text.index(chr(0))} (not a text file)")
    return text


_BASE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class _StrictLoader(_BASE_LOADER):
    """The safe loader, refusing duplicated mapping keys."""


def _mapping_without_duplicates(loader, node, deep=False):
    seen = {}
    for key_node, _ in node.value:
        if key_node.tag == "tag:yaml.org,2002:merge":
            continue
        key = loader.construct_object(key_node, deep=True)
        try:
            hash(key)
        except TypeError:
            raise yaml.constructor.ConstructorError(
                None, None, f"a mapping key must be a scalar, got {type(key).__name__}", key_node.start_mark)
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key {key!r} (first at line {seen[key] + 1})", key_node.start_mark)
        seen[key] = key_node.start_mark.line
    return loader.construct_mapping(node, deep=deep)


_StrictLoader.add_constructor("tag:yaml.org,2002:map", _mapping_without_duplicates)


def _check_shape(node, source: str) -> None:
    """Refuse a node graph nested deeper than MAX_DEPTH or expanding (aliases at every use) past MAX_NODES.

    Iterative and memoised by node: linear in the distinct nodes, whatever the aliases multiply."""
    expanded: dict[int, int] = {}
    stack = [(node, 1, False)]
    while stack:
        current, depth, done = stack.pop()
        if depth > MAX_DEPTH:
            raise InputFileError(f"{source}: nested deeper than {MAX_DEPTH} levels")
        key = id(current)
        if key in expanded and not done:
            continue
        children = []
        if isinstance(current, yaml.SequenceNode):
            children = list(current.value)
        elif isinstance(current, yaml.MappingNode):
            children = [n for pair in current.value for n in pair]
        if not done:
            stack.append((current, depth, True))
            stack.extend((child, depth + 1, False) for child in children if id(child) not in expanded)
            expanded.setdefault(key, -1)
            continue
        total = 1 + sum(max(expanded.get(id(child), 1), 1) for child in children)
        if total > MAX_NODES:
            raise InputFileError(f"{source}: expands to more than {MAX_NODES:,} values (aliases counted at "
                                 "every use)")
        expanded[key] = total


def parse_yaml(text: str, source: str = "document"):
    """The YAML document in ``text``, parsed strictly (module docstring): safe tags only, no duplicated
    keys, bounded depth and expansion.

    Returns
    -------
    object
        The document (None for an empty one).

    Raises
    ------
    InputFileError
        Naming ``source``, the line and the reason.
    """
    loader = _StrictLoader(text)
    try:
        try:
            node = loader.get_single_node()
        except yaml.composer.ComposerError as exc:
            raise InputFileError(f"{source}: {_yaml_reason(exc)}") from None
        if node is None:
            return None
        _check_shape(node, source)
        return loader.construct_document(node)
    except yaml.YAMLError as exc:
        raise InputFileError(f"{source}: not valid YAML: {_yaml_reason(exc)}") from None
    except RecursionError:
        raise InputFileError(f"{source}: nested too deeply") from None
    finally:
        loader.dispose()


def _yaml_reason(exc: yaml.YAMLError) -> str:
    """One line out of a PyYAML error: its problem and where."""
    problem = getattr(exc, "problem", None) or getattr(exc, "context", None) or str(exc).splitlines()[0]
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    problem = str(problem).replace("could not determine a constructor for the tag",
                                   "a tag that is not plain data:")
    return f"{problem}{where}"


def load_yaml_file(path: str | Path, kind: str = "config", *, empty_ok: bool = False, limit: int | None = None):
    """:func:`read_text` then :func:`parse_yaml`: the bounded, strict YAML (or JSON) document in ``path``.

    Parameters
    ----------
    empty_ok : bool
        Whether an empty or comment-only file is a document (returned as None); refused otherwise.

    Raises
    ------
    InputFileError
        As :func:`read_text` and :func:`parse_yaml`, and for an empty file unless ``empty_ok``.
    """
    text = read_text(path, kind, limit=limit)
    data = parse_yaml(text, str(path))
    if data is None and not empty_ok:
        raise InputFileError(f"{path}: is empty (no YAML document in it)")
    return data
