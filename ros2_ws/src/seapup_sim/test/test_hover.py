"""The hover setting kept by the build (seapup_sim.hover): the solver's own answer, used only if the model hovers
with it, and a simulator that starts from it imports no scipy.

Truth: the zero-speed trim solved again (analysis.trim, scipy's least_squares) and eq. 5.2's hover setting.
"""
import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from seapup_sim import hover
from seapup_sim.analysis import hover_blade_pitch
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import available_configs, load_vehicle_config


def _solved(config):
    return hover_blade_pitch(VehicleModel(config))


def test_the_kept_hover_is_the_solvers_bit_for_bit_and_eq_5_2(tmp_path):
    path = tmp_path / hover.CACHE_NAME
    written = hover.write_cache(path=path)
    assert sorted(entry["vehicle"] for entry in written.values()) == available_configs()
    for name in available_configs():
        config = load_vehicle_config(name)
        kept = hover.cached_hover(config, path)
        assert kept is not None and np.array_equal(kept, _solved(config)), name
    baseline = hover.cached_hover(load_vehicle_config("baseline"), path)
    np.testing.assert_allclose(np.degrees(baseline), [-3.383, -3.383, -13.098, -13.098], atol=0.01)  # eq. 5.2


def test_the_build_kept_every_shipped_vehicle():
    """``./seapup``'s build wrote the file beside the installed module (a start then needs no solve)."""
    for name in available_configs():
        config = load_vehicle_config(name)
        kept = hover.cached_hover(config)
        assert kept is not None and np.array_equal(kept, _solved(config)), name


def test_another_configuration_is_solved_not_looked_up(tmp_path):
    """One derivative changed: another key, so the file has nothing for it and the trim is solved for it."""
    path = tmp_path / hover.CACHE_NAME
    hover.write_cache(path=path)
    config = load_vehicle_config("baseline")
    changed = json.loads(json.dumps(config))
    changed["rigid_body"]["buoyancy_mass"] = changed["rigid_body"]["buoyancy_mass"] * 0.98
    assert hover.config_key(changed) != hover.config_key(config)
    assert hover.cached_hover(changed, path) is None
    assert not np.allclose(_solved(changed), _solved(config), atol=1e-4)


def _entry(path):
    data = json.loads(path.read_text())
    key = hover.config_key(load_vehicle_config("baseline"))
    return data, key


@pytest.mark.parametrize("spoil", [
    "moved", "nan", "inf", "integers", "three", "strings", "bool", "not_json", "list", "binary", "huge", "empty",
    "beyond_limits"])
def test_a_spoilt_file_is_ignored_and_the_trim_solved(tmp_path, monkeypatch, spoil):
    """A wrong, malformed, oversized or hostile file changes nothing: the start solves the trim."""
    path = tmp_path / hover.CACHE_NAME
    hover.write_cache(path=path)
    data, key = _entry(path)
    entry = data[key]
    if spoil == "moved":           # a solution that does not hover the model (0.5 deg off)
        entry["blade_pitch"][0] += math.radians(0.5)
    elif spoil in ("nan", "inf"):
        entry["blade_pitch"][1] = float(spoil)
    elif spoil == "integers":
        entry["blade_pitch"] = [0, 0, 0, 0]
    elif spoil == "three":
        entry["blade_pitch"] = entry["blade_pitch"][:3]
    elif spoil == "strings":
        entry["pitch_angle"] = str(entry["pitch_angle"])
    elif spoil == "bool":
        entry["pitch_angle"] = True
    elif spoil == "beyond_limits":  # a "hover" beyond the blades' reach is no hover
        entry["blade_pitch"] = [1.0, 1.0, 1.0, 1.0]
    if spoil == "not_json":
        path.write_text("{" + json.dumps(data)[:40])
    elif spoil == "list":
        path.write_text(json.dumps([data]))
    elif spoil == "binary":
        path.write_bytes(b"\xff\xfe" + json.dumps(data).encode())
    elif spoil == "huge":
        path.write_text(json.dumps(data) + " " * hover.MAX_BYTES)
    elif spoil == "empty":
        path.write_text("")
    else:
        path.write_text(json.dumps(data))
    config = load_vehicle_config("baseline")
    assert hover.cached_hover(config, path) is None
    monkeypatch.setattr(hover, "_cache_path", lambda: path)
    assert np.array_equal(hover.hover_of(config), _solved(config))


def test_no_file_at_all_solves(tmp_path, monkeypatch):
    monkeypatch.setattr(hover, "_cache_path", lambda: tmp_path / "absent.json")
    config = load_vehicle_config("camera")
    assert np.array_equal(hover.hover_of(config), _solved(config))


@pytest.mark.process
def test_a_simulator_starts_without_importing_scipy():
    """The point of the file: scipy.optimize and scipy.linalg were 0.75 s CPU of every simulator's start."""
    code = ("import sys\n"
            "from seapup_sim.simulator_core import SimulatorConfig, SimulatorCore\n"
            "core = SimulatorCore(SimulatorConfig(vehicle='camera'))\n"
            "print(repr(core.hover.tolist()))\n"
            "print(sorted(m for m in sys.modules if m == 'scipy' or m.startswith('scipy.')))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         env=dict(os.environ))
    assert out.returncode == 0, out.stderr
    pitch, modules = out.stdout.strip().splitlines()[-2:]
    assert modules == "[]", modules
    assert np.array_equal(np.array(eval(pitch)), _solved(load_vehicle_config("camera")))
