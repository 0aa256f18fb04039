"""Vehicle configurations as YAML files with overlays.

A configuration is data: ``seapup_sim/vehicles/<name>.yaml`` (shipped inside
the package, so the pure core finds it without ROS). A file may start with
``extends: <other>``; it is then merged over that configuration: mappings merge
key by key (so an overlay can change one hydrodynamic derivative), any other
value replaces the base's. Every parameter documents its origin in a comment
next to it.
"""
from __future__ import annotations

import copy
from importlib import resources
from pathlib import Path

import yaml

__all__ = ["ConfigError", "available_configs", "load_vehicle_config", "merge_config"]


class ConfigError(ValueError):
    """A vehicle configuration that cannot be found or merged."""


def _vehicles_dir() -> Path:
    return Path(str(resources.files("seapup_sim") / "vehicles"))


def available_configs() -> list[str]:
    """Names of the shipped configurations."""
    return sorted(p.stem for p in _vehicles_dir().glob("*.yaml"))


def merge_config(base: dict, overlay: dict) -> dict:
    """Deep merge: mappings merge recursively, other values replace (copies)."""
    out = copy.deepcopy(base)
    for key, value in overlay.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merge_config(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def load_vehicle_config(name_or_path: str | Path, _seen: tuple = ()) -> dict:
    """Load a configuration by shipped name (``baseline``, ``camera``) or path."""
    path = Path(name_or_path)
    if not path.suffix:
        path = _vehicles_dir() / f"{name_or_path}.yaml"
    if not path.is_file():
        raise ConfigError(f"no vehicle configuration {name_or_path!r} "
                          f"(shipped: {', '.join(available_configs())})")
    if path.resolve() in _seen:
        raise ConfigError(f"configuration {path} extends itself")
    data = yaml.safe_load(path.read_text()) or {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: top level must be a mapping")
    parent = data.pop("extends", None)
    if parent is not None:
        parent_path = parent if Path(str(parent)).suffix else path.parent / f"{parent}.yaml"
        data = merge_config(load_vehicle_config(parent_path, _seen + (path.resolve(),)), data)
    data.setdefault("name", path.stem)
    if parent is not None:
        data["name"] = path.stem
    return data
