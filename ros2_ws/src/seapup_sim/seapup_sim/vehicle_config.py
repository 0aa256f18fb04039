"""Vehicle configurations as YAML files with overlays.

A configuration is data: ``seapup_sim/vehicles/<name>.yaml`` (shipped inside
the package, so the pure core finds it without ROS). A file may start with
``extends: <other>``; it is then merged over that configuration
(:func:`seapup_common.config.load_yaml`): mappings merge key by key (so an
overlay can change one hydrodynamic derivative), any other value replaces the
base's. Every parameter documents its origin in a comment next to it. The
model reads the result through a :class:`~seapup_common.config.ConfigView`,
so a missing or bad key is named in the error.
"""
from __future__ import annotations

from importlib import resources
from pathlib import Path

from seapup_common.config import ConfigError, load_yaml

__all__ = ["ConfigError", "available_configs", "load_vehicle_config"]


def _vehicles_dir() -> Path:
    return Path(str(resources.files("seapup_sim") / "vehicles"))


def available_configs() -> list[str]:
    """Names of the shipped configurations."""
    return sorted(p.stem for p in _vehicles_dir().glob("*.yaml"))


def load_vehicle_config(name_or_path: str | Path) -> dict:
    """Load a configuration by shipped name (``baseline``, ``camera``) or path.

    Raises
    ------
    ConfigError
        If there is no such configuration or a file in its ``extends`` chain is
        unreadable or not a mapping.
    """
    path = Path(name_or_path)
    if not path.suffix:
        if not str(name_or_path) or "/" in str(name_or_path) or str(name_or_path) not in available_configs():
            raise ConfigError(f"no vehicle configuration {str(name_or_path)[:80]!r} "
                              f"(shipped: {', '.join(available_configs())})")
        path = _vehicles_dir() / f"{name_or_path}.yaml"
    if not path.is_file():
        raise ConfigError(f"no vehicle configuration file {str(path)[:200]}")
    data = load_yaml(path)
    data["name"] = path.stem
    return data
