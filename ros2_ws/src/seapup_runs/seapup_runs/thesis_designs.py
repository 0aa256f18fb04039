"""The thesis's own MFOL models as controller designs: fly our plant with the gains the thesis's self-test gave.

Chapter 5 flew its closed-loop cases with gains designed from its realistic self-test (Table 5.1, sec. 5.4.2:
"the data from the realistic self-test ... was used to generate the controller gains"); eq. 5.3 is its
benchmark read off the velocity log. Designing the same two-term law (eq. 4.10-4.11, sec. 5.2's poles) from
those matrices and flying it on *our* plant separates the two halves of a closed-loop difference (issue 25):
if the responses become the thesis's, the plant is right and our self-test's fit differs; if not, the plant
does. The matrices are read from the targets file (``thesis_targets.yaml``: ``ch5.eq5_3a.B0inv``,
``ch5.eq5_3b.B1inv``, ``ch5.table5_1.realistic.*``, ``ch5.table5_2.realistic.*``, ``ch5.eq5_2.hover``), so
they are typed once, with their typo readings (Table 5.1's realistic column as printed: its asymmetries,
e.g. B1^-1[r, vectored stbd] 1.537 against port -0.394, are the realistic self-test's own errors, sec. 5.3.3). The thesis's units (m/s and deg/s per degree of blade pitch,
eq. 5.3) are converted to ours (SI per radian).

Designs (:data:`DESIGNS`):

- ``eq-5.3``: the velocity log's matrices at 0 m/s (eq. 5.3a-b, u0 of eq. 5.2);
- ``table-5.1``: the realistic self-test at 0 m/s (Table 5.1), and for a gain schedule the realistic
  self-test at 0.7 m/s (Table 5.2) about sec. 5.3.1's y0 = (0.7, 0, 0, 0) and u0 = (14.589, 14.589, -5.929,
  -5.929) deg -- the point whose wrong-sign surge gains gave the thesis's scheduled steady-state error
  (sec. 5.4.4).
"""
from __future__ import annotations

import math

import numpy as np

from seapup_control.mfol import THESIS_POLES_5HZ, MFOLModel, design
from seapup_runs.targets import thesis_value

__all__ = ["DESIGNS", "thesis_design"]

#: The thesis's designs by name: (0 m/s B0inv id, B1inv id, 0.7 m/s B0inv id, B1inv id or None).
DESIGNS = {
    "eq-5.3": ("ch5.eq5_3a.B0inv", "ch5.eq5_3b.B1inv", None, None),
    "table-5.1": ("ch5.table5_1.realistic.B0inv", "ch5.table5_1.realistic.B1inv",
                  "ch5.table5_2.realistic.B0inv", "ch5.table5_2.realistic.B1inv"),
}
#: Sec. 5.3.1: the 0.7 m/s operating point of the scheduled benchmark [m/s; deg].
Y0_07 = (0.7, 0.0, 0.0, 0.0)
U0_07_DEG = (14.589, 14.589, -5.929, -5.929)
#: The thesis's matrices are for T = 0.2 s (5 Hz, sec. 5.3).
SAMPLE_PERIOD = 0.2


def _si(matrix) -> np.ndarray:
    """Thesis units (rows u, v, w in m/s and r in deg/s, per degree of pitch) to SI per radian."""
    m = np.array(matrix, dtype=float) * (180.0 / math.pi)
    m[3] *= math.pi / 180.0          # deg/s per deg is rad/s per rad
    return m


def thesis_design(name: str, schedule: bool = False, drop_b1: bool = False) -> dict:
    """A controller document (``kind: seapup/mfol_controller``) designed from the thesis's matrices ``name``.

    Parameters
    ----------
    name : str
        One of :data:`DESIGNS`.
    schedule : bool
        Add the 0.7 m/s point (a gain schedule; ``table-5.1`` only).
    drop_b1 : bool
        Eq. 5.6's proportional gain ``B0 diag(2 - k - c)`` without eq. 4.11's ``- B1``.

    Raises
    ------
    KeyError
        On an unknown design, or a schedule of a design without a 0.7 m/s point.
    """
    if name not in DESIGNS:
        raise KeyError(f"no thesis design {name!r}; known: {', '.join(DESIGNS)}")
    b0_id, b1_id, b0_07, b1_07 = DESIGNS[name]
    if schedule and b0_07 is None:
        raise KeyError(f"the thesis design {name!r} has no 0.7 m/s point to schedule on (table-5.1 has)")
    hover = np.radians(np.asarray(thesis_value("ch5.eq5_2.hover"), dtype=float))
    points = [(0.0, MFOLModel(_si(thesis_value(b0_id)), _si(thesis_value(b1_id)), SAMPLE_PERIOD, u0=hover))]
    if schedule:
        points.append((0.7, MFOLModel(_si(thesis_value(b0_07)), _si(thesis_value(b1_07)), SAMPLE_PERIOD, y0=Y0_07,
                                      u0=np.radians(U0_07_DEG))))
    out = []
    for surge, model in points:
        gains = design(model, THESIS_POLES_5HZ)
        k_err = gains.K_err + model.B1 if drop_b1 else gains.K_err
        out.append({"surge": surge, "cycle": 0, "B0inv": model.B0inv.tolist(), "B1inv": model.B1inv.tolist(),
                    "y0": model.y0.tolist(), "u0": model.u0.tolist(), "K_int": gains.K_int.tolist(),
                    "K_err": k_err.tolist()})
    return {"kind": "seapup/mfol_controller", "version": 1, "sample_period": SAMPLE_PERIOD, "phase": "thesis",
            "reason": f"the thesis's {name} matrices" + (" (eq. 5.6: no -B1)" if drop_b1 else ""),
            "duration": 0.0, "quiescence_speed": 0.0,
            "poles": {"k": THESIS_POLES_5HZ.k.tolist(), "c": THESIS_POLES_5HZ.c.tolist()},
            "operating_points": out}
