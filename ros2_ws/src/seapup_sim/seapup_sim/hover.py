"""The hover setting (eq. 5.2) of a vehicle configuration, solved once per configuration when the package is built.

:func:`hover_of` gives :func:`seapup_sim.analysis.hover_blade_pitch` -- the zero-speed trim of sec. 3.7 (unknowns
pitch angle, main and vectored blade pitch; zero surge, heave and pitch accelerations), solved with scipy's
``least_squares`` -- for a configuration (the mapping :func:`~seapup_sim.vehicle_config.load_vehicle_config`
returns). Every simulator start needs it, and scipy's import with the solve was most of a simulator's start
(about 0.75 s of 1.6 s CPU; ``./seapup test`` starts over a hundred simulators). So building ``seapup_sim``
(``python -m seapup_sim.hover``, run by ``./seapup``'s build beside numba's cache) solves it for every shipped
configuration and keeps the solutions in ``hover_trims.json`` beside this module, keyed by the SHA-256 of the
configuration's content, and a start looks its configuration up there.

A solution from the file is used only if the model hovers with it: at zero speed the accelerations left are no
larger than the trim's own acceptance (:data:`TOLERANCE`, as :func:`~seapup_sim.analysis.trim`) and the blade
pitches are within their limits. A file that is missing, oversized (:data:`MAX_BYTES`), unreadable or
malformed, an entry of the wrong shape, a number that is not a finite float, or a solution that does not hover
the model is ignored, and the trim is solved as before. What the file holds is the solver's own answer to the
same configuration (the same inputs and code: bit for bit what solving again gives), so a simulator flies the
same with the file or without it.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import sys
import tempfile
from importlib import resources
from pathlib import Path

import numpy as np

__all__ = ["hover_of", "cached_hover", "config_key", "write_cache", "CACHE_NAME", "MAX_BYTES", "TOLERANCE"]

#: The solutions' file, beside this module in the installed package.
CACHE_NAME = "hover_trims.json"
#: A larger file is not read (a few hundred bytes per configuration).
MAX_BYTES = 1 << 20
#: [m/s^2, rad/s^2] the largest acceleration a solution may leave (the trim's acceptance).
TOLERANCE = 1e-7


def config_key(config: dict) -> str:
    """The SHA-256 of a configuration's content (its keys sorted): equal configurations, equal keys."""
    return hashlib.sha256(json.dumps(config, sort_keys=True, default=str).encode()).hexdigest()


def _cache_path() -> Path:
    return Path(str(resources.files("seapup_sim") / CACHE_NAME))


def _read(path: Path) -> dict:
    try:
        if path.stat().st_size > MAX_BYTES:
            return {}
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):   # missing, unreadable, not UTF-8, not JSON
        return {}
    return data if isinstance(data, dict) else {}


def cached_hover(config: dict, path: str | Path | None = None) -> np.ndarray | None:
    """The blade pitch [rad] (4,) the file holds for ``config`` if the model hovers with it, else None."""
    entry = _read(Path(path) if path is not None else _cache_path()).get(config_key(config))
    if not isinstance(entry, dict):
        return None
    theta, pitch = entry.get("pitch_angle"), entry.get("blade_pitch")
    if not (isinstance(theta, float) and isinstance(pitch, list) and len(pitch) == 4
            and all(isinstance(v, float) for v in pitch) and all(math.isfinite(v) for v in (theta, *pitch))):
        return None
    from seapup_sim.vehicle import VehicleModel
    model = VehicleModel(config)
    pitch = np.array(pitch, float)
    state = np.zeros(12)
    state[4] = theta
    if not (np.all(np.abs(pitch) <= model.pitch_limit + 1e-9)
            and np.abs(model.input_derivatives(state, pitch)[6:]).max() <= TOLERANCE):
        return None
    return pitch


def _solve(config: dict):
    from seapup_sim.analysis import trim
    from seapup_sim.vehicle import VehicleModel
    return trim(VehicleModel(config), 0.0)


def hover_of(config: dict) -> np.ndarray:
    """The hover blade pitch [rad] (4,) of ``config``: from the file when it holds a checked solution, else
    solved (:func:`seapup_sim.analysis.hover_blade_pitch`).

    Raises
    ------
    seapup_sim.analysis.TrimError
        If the configuration cannot hover within the blade limits.
    """
    cached = cached_hover(config)
    return cached if cached is not None else _solve(config).blade_pitch.copy()


def write_cache(configs: dict[str, dict] | None = None, path: str | Path | None = None) -> dict:
    """Solve the hover of each configuration (default: every shipped one) and write the file atomically;
    the entries written (key -> ``{"vehicle", "pitch_angle", "blade_pitch"}``). A configuration that cannot
    hover is left out (a start solves it, and says why)."""
    from seapup_sim.analysis import TrimError
    from seapup_sim.vehicle_config import available_configs, load_vehicle_config
    if configs is None:
        configs = {name: load_vehicle_config(name) for name in available_configs()}
    entries = {}
    for name, config in configs.items():
        try:
            solution = _solve(config)
        except TrimError:
            continue
        entries[config_key(config)] = {"vehicle": name, "pitch_angle": float(solution.pitch_angle),
                                       "blade_pitch": [float(v) for v in solution.blade_pitch]}
    target = Path(path) if path is not None else _cache_path()
    handle, temporary = tempfile.mkstemp(dir=target.parent, prefix=".hover_trims.", suffix=".json")
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as out:
            json.dump(entries, out, indent=1)
        os.chmod(temporary, 0o644)   # read by every user's simulator
        os.replace(temporary, target)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return entries


if __name__ == "__main__":
    written = write_cache()
    print(f"hover trims of {len(written)} configurations in {_cache_path()}", file=sys.stderr)
