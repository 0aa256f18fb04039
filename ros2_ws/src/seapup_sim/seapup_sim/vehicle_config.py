"""Vehicle configurations as YAML files with overlays.

A configuration is data: ``seapup_sim/vehicles/<name>.yaml`` (shipped inside
the package, so the pure core finds it without ROS). A file may start with
``extends: <other>``; it is then merged over that configuration
(:func:`seapup_common.config.load_yaml`): mappings merge key by key (so an
overlay can change one hydrodynamic derivative), any other value replaces the
base's. Every parameter documents its origin in a comment next to it. The
model reads the result through a :class:`~seapup_common.config.ConfigView`,
so a missing or bad key is named in the error.

The keys are checked when a configuration is loaded: ``baseline.yaml`` is
the schema (every key a vehicle has), plus the optional keys of
:data:`OPTIONAL_KEYS` (``payloads``: solid spheres added to the rigid body,
sec. 3.6; ``thruster_efficiency``: per-thruster thrust fractions, fouling).
A misspelled key (``rigid_body.bouyancy_mass``) is an error naming the file,
the dotted key and the nearest valid one -- never silently ignored. The keys
of ``hydrodynamics`` are derivative names, an open set (any term of sec. 2.3.1's
notation): the term parser checks those.
"""
from __future__ import annotations

import functools
import os
from importlib import resources
from pathlib import Path

from seapup_common.config import ConfigError, load_yaml, nearest

__all__ = ["ConfigError", "available_configs", "load_vehicle_config", "OPTIONAL_KEYS", "PAYLOAD_KEYS",
           "COEFFICIENT_SCALES", "scaled"]

#: Top-level keys a configuration may have beyond those of ``baseline.yaml``.
OPTIONAL_KEYS = ("payloads", "thruster_efficiency", "inputs", "open_loop_unstable", "self_test")
#: The ``thrusters`` section of fixed-pitch propeller thrusters (``kind: fixed_pitch``,
#: :class:`seapup_sim.thrusters.FixedPitchThrusters`): its schema in place of baseline's controllable-pitch one.
FIXED_PITCH_KEYS = {"kind": None, "thrust_curve": {"polynomial": None, "table": None}, "deadband": None,
                    "actuator_time_constant": None, "positions": None, "directions": None}
#: The keys of ``inputs`` (:func:`seapup_sim.inputs.inputs_of`).
INPUT_KEYS = {"kind": None, "weights": None}
#: Mappings whose keys are not fixed (derivative names, checked by :func:`seapup_sim.hydrodynamics.parse_term`).
OPEN_KEYS = ("hydrodynamics",)
#: The keys of one payload (:func:`seapup_sim.vehicle.compose_mass_properties`).
PAYLOAD_KEYS = ("name", "mass", "buoyancy_mass", "position", "radius")


@functools.cache
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
    schema = data if os.path.abspath(path) == os.path.abspath(_vehicles_dir() / "baseline.yaml") \
        else load_yaml(_vehicles_dir() / "baseline.yaml")
    schema = {**schema, "thrusters": {**schema.get("thrusters", {}), "kind": None}}
    thrusters = data.get("thrusters")
    if isinstance(thrusters, dict) and "kind" in thrusters:
        from seapup_sim.thrusters import THRUSTER_KINDS
        if thrusters["kind"] not in THRUSTER_KINDS:
            raise ConfigError(f"{path.name}: thrusters.kind must be one of {', '.join(THRUSTER_KINDS)}, "
                              f"got {str(thrusters['kind'])[:40]!r}")
        if thrusters["kind"] == "fixed_pitch":
            schema["thrusters"] = FIXED_PITCH_KEYS
    _check_keys(data, schema, path.name)
    if isinstance(data.get("inputs"), dict):
        _check_keys(data["inputs"], INPUT_KEYS, path.name, "inputs.")
    data["name"] = path.stem
    return data


def _check_keys(data: dict, schema: dict, source: str, prefix: str = "") -> None:
    """Refuse a key the schema (baseline) lacks, naming it and the nearest valid one."""
    for key, value in data.items():
        if not prefix and key in (*OPTIONAL_KEYS, "name"):
            if key == "payloads":
                _check_payloads(value, source)
            continue
        if key not in schema:
            options = list(schema) + (list(OPTIONAL_KEYS) if not prefix else [])
            near = nearest(key, options)
            raise ConfigError(f"{source}: unknown key {prefix}{key}"
                              + (f" (did you mean {prefix}{near}?)" if near else f" (valid: {', '.join(options)})"))
        if isinstance(value, dict) and isinstance(schema[key], dict) and f"{prefix}{key}" not in OPEN_KEYS:
            _check_keys(value, schema[key], source, f"{prefix}{key}.")


def _check_payloads(payloads, source: str) -> None:
    if not isinstance(payloads, list):
        raise ConfigError(f"{source}: payloads must be a list of {{{', '.join(PAYLOAD_KEYS)}}} mappings")
    for i, payload in enumerate(payloads):
        if not isinstance(payload, dict):
            raise ConfigError(f"{source}: payloads[{i}] must be a mapping of {', '.join(PAYLOAD_KEYS)}")
        for key in payload:
            if key not in PAYLOAD_KEYS:
                near = nearest(key, PAYLOAD_KEYS)
                raise ConfigError(f"{source}: unknown key payloads[{i}].{key}"
                                  + (f" (did you mean {near}?)" if near else f" (valid: {', '.join(PAYLOAD_KEYS)})"))


#: The uncertain coefficients a run may scale (:func:`scaled`): every hydrodynamic derivative (the damping, lift
#: and Munk-like terms of sec. 2.3.1, Fossen's D_L and D_NL), and the added-mass matrix.
COEFFICIENT_SCALES = ("damping", "added_mass")


def scaled(config: dict, damping: float = 1.0, added_mass: float = 1.0) -> dict:
    """A copy of ``config`` with every ``hydrodynamics`` derivative times ``damping`` and the ``added_mass``
    matrix times ``added_mass``: the same vehicle as its description is uncertain (a campaign's "how robust is
    the autopilot to the coefficients?"). Named ``<name>*damping*added_mass`` unless both are 1.

    Raises
    ------
    ConfigError
        On a factor that is not a finite number in [0.1, 10].
    """
    import copy
    import math
    for what, factor in (("damping", damping), ("added_mass", added_mass)):
        if isinstance(factor, bool) or not isinstance(factor, (int, float)) or not math.isfinite(factor) \
                or not 0.1 <= factor <= 10.0:
            raise ConfigError(f"the {what} scale must be a number in [0.1, 10], got {str(factor)[:40]}")
    out = copy.deepcopy(config)
    if damping != 1.0:
        out["hydrodynamics"] = {name: float(value) * damping for name, value in out["hydrodynamics"].items()}
    if added_mass != 1.0:
        out["added_mass"] = [[float(v) * added_mass for v in row] for row in out["added_mass"]]
    if (damping, added_mass) != (1.0, 1.0):
        out["name"] = f"{config.get('name', 'vehicle')}*{damping:g}*{added_mass:g}"
    return out
