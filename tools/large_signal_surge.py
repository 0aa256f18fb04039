#!/usr/bin/env python3
"""Why the closed-loop surge step rises slower than the thesis's with the thesis's own gains (developer tool).

Issue 41's "large-signal look". Sec. 5.4.2 / fig. 5.10: the fixed-gain MFOL at 5 Hz takes the Seapup from rest
to 0.85 m/s with a 95 % rise of 1.4 s; flown with the thesis's own matrices (eq. 5.3, ``--design eq-5.3``) on
our plant it takes about 4 s. This tool separates the candidate causes, each by removing it from the plant
(a vehicle file written beside the others, flown by the same run spec):

1. the amplitude: the same design stepped to 0.1 ... 0.85 m/s (a linear plant rises alike at every amplitude);
2. the pitch-up: no bow-up moment (M_u|u| = 0), and the pitch frozen (I_yy and M_qdot x 1000);
3. the thrust's loss with speed (k_j = 0), and the plant's quick open-loop start (surge added mass + 120 kg:
   the full-thrust start as slow as sec. 3.6's);
4. saturation: the share of the first 3 s with a main at its limit;
5. the plant against its command: the open-loop response to the trim's blade pitch at 0.85 m/s applied at once,
   and the closed loop's main pitch against that trim's.

Usage (inside ``eval "$(./seapup env)"``): ``python tools/large_signal_surge.py [--design eq-5.3|table-5.1|self-test]``.
Its output is what docs/fidelity.md ("Large-signal surge") quotes.
"""
from __future__ import annotations

import argparse
import copy
import dataclasses
import math
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

from seapup_runs.runner import run
from seapup_runs.scenarios import scenario_spec
from seapup_sim.analysis import trim
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config
from seapup_sim.verification import run_open_loop

TARGET = 0.85   # [m/s] fig. 5.10's step


def crossing(t: np.ndarray, u: np.ndarray, level: float) -> float | None:
    """The first time [s] ``u`` reaches ``level`` (None if never)."""
    above = np.flatnonzero(u >= level)
    return round(float(t[above[0]]), 2) if above.size else None


def fly(vehicle: str, design: str, amplitude: float = TARGET) -> dict:
    """The surge case stepped to ``amplitude``: rise times, saturation, the main's command against time."""
    spec = scenario_spec("surge", vehicle=vehicle, design=design)
    spec = dataclasses.replace(spec, reference=dataclasses.replace(
        spec.reference, steps=((0.0, (amplitude, 0.0, 0.0, 0.0)),)))
    series = run(spec).series
    t, u = np.asarray(series.t), np.asarray(series.truth["u"])
    mains = np.degrees(np.asarray(series.command)[:, :2])
    early = t[:len(mains)] <= 3.0
    return {"t63": crossing(t, u, 0.63 * amplitude), "t95": crossing(t, u, 0.95 * amplitude),
            "saturated": float(np.mean(np.abs(mains[early]) >= 34.99)),
            "main": {round(float(k), 1): round(float(mains[i, 0]), 1) for i, k in enumerate(t[:len(mains)])
                     if round(float(k), 1) in (0.0, 0.4, 0.8, 1.6, 2.4, 3.2)},
            "peak_pitch": round(float(np.degrees(np.max(series.truth["pitch"]))), 1)}


def variants(folder: Path) -> dict[str, str]:
    """Vehicle files with one cause removed each (name -> path)."""
    base = load_vehicle_config("baseline")
    changes = {
        "as is": lambda c: None,
        "no bow-up moment (M_u|u| = 0)": lambda c: c["hydrodynamics"].__setitem__("M_u|u|", 0.0),
        "pitch frozen (I_yy, M_qdot x 1000)": lambda c: (
            c["rigid_body"]["inertia_cg"][1].__setitem__(1, 1000.0 * c["rigid_body"]["inertia_cg"][1][1]),
            c["added_mass"][4].__setitem__(4, 1000.0 * c["added_mass"][4][4])),
        "no thrust loss with speed (k_j = 0)": lambda c: c["thrusters"].__setitem__("k_j", 0.0),
        # the open-loop full-thrust start as slow as sec. 3.6's (95 % in 2.4 s against 2.2; ours 1.3 s)
        "surge added mass + 120 kg": lambda c: c["added_mass"][0].__setitem__(0, c["added_mass"][0][0] + 120.0),
    }
    out = {}
    for i, (name, change) in enumerate(changes.items()):
        config = copy.deepcopy(base)
        config.pop("name", None)
        change(config)
        path = folder / f"variant{i}.yaml"
        path.write_text(yaml.safe_dump(config, sort_keys=False))
        out[name] = str(path)
    return out


def open_loop_at_trim() -> dict:
    """The plant alone: the trim at 0.85 m/s (sec. 3.7's procedure) applied at once from hover."""
    model = VehicleModel(load_vehicle_config("baseline"))
    hover, at = trim(model, 0.0), trim(model, TARGET, [0.3, 0.4, -0.1])
    t, x, _ = run_open_loop(model, np.asarray(at.blade_pitch, float), 20.0, pitch0=hover.blade_pitch)
    u = x[:, 6]
    return {"trim_blade_pitch_deg": np.degrees(at.blade_pitch).round(1).tolist(),
            "trim_pitch_deg": round(math.degrees(at.pitch_angle), 1),
            "t63": crossing(t, u, 0.63 * TARGET), "t95": crossing(t, u, 0.95 * TARGET)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--design", default="eq-5.3", choices=("eq-5.3", "table-5.1", "self-test"))
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="seapup_large_signal_") as folder:
        files = variants(Path(folder))
        print(f"design {args.design}: step amplitude against rise (baseline plant)")
        for amplitude in (0.1, 0.3, 0.5, 0.7, TARGET):
            r = fly("baseline", args.design, amplitude)
            print(f"  step {amplitude:.2f} m/s: t63 {r['t63']} s, t95 {r['t95']} s")
        print(f"\ndesign {args.design}: the 0.85 m/s step with one cause removed")
        for name, path in files.items():
            r = fly(path, args.design)
            print(f"  {name:38} t95 {r['t95']} s; mains saturated {100 * r['saturated']:.0f} % of the first 3 s; "
                  f"pitch peak {r['peak_pitch']} deg")
            if name == "as is":
                print(f"  {'':38} main blade pitch [deg] at t [s]: {r['main']}")
    trimmed = open_loop_at_trim()
    print(f"\nopen loop, the trim at 0.85 m/s applied at once: blade pitch {trimmed['trim_blade_pitch_deg']} deg "
          f"(pitch {trimmed['trim_pitch_deg']} deg): t63 {trimmed['t63']} s, t95 {trimmed['t95']} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
