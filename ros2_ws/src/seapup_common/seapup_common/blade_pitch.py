"""Blade-pitch commands of the Seapup's four controllable-pitch thrusters.

The Seapup is driven by four fixed-speed, controllable-pitch ducted thrusters
(thesis sec. 2.3.3): two main thrusters aft (port, starboard) and two vectored
thrusters on the centreline at 45 deg to the vertical. A command is the vector
of their four blade pitches in radians, in the index order of
``seapup_msgs/BladePitch`` (thesis Table 3.2 numbering).

This module is the gate every command passes before it can reach the vehicle
model: wrong-length or non-finite commands are rejected, pitches beyond the
blade limit are saturated, and every outcome is counted.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import resources

import numpy as np
import yaml

__all__ = [
    "BLADE_PITCH_LIMIT",
    "VIRTUAL_INPUT_LIMIT",
    "INPUT_LIMIT_RANGE",
    "MAIN_PORT",
    "MAIN_STARBOARD",
    "VECTORED_STARBOARD",
    "VECTORED_PORT",
    "THRUSTER_NAMES",
    "InvalidBladePitchError",
    "check_blade_pitch",
    "within_limits",
    "CommandGate",
]

MAIN_PORT, MAIN_STARBOARD, VECTORED_STARBOARD, VECTORED_PORT = range(4)


def _interface() -> dict:
    text = (resources.files("seapup_common") / "data" / "interface.yaml").read_text()
    return yaml.safe_load(text)


_INTERFACE = _interface()
#: Thruster names in ``seapup_msgs/BladePitch`` index order (``data/interface.yaml``).
THRUSTER_NAMES = tuple(_INTERFACE["thrusters"])
#: Symmetric blade-pitch limit [rad]: +/-35 deg (thesis sec. 3.1); the one place
#: of this value is ``seapup_common/data/interface.yaml``.
BLADE_PITCH_LIMIT = math.radians(float(_INTERFACE["blade_pitch_limit_deg"]))
#: Full scale of a virtual input (surge, sway, heave or yaw demand of a vehicle with more thrusters than
#: outputs, :mod:`seapup_sim.inputs`): the four inputs of such a vehicle lie in [-1, 1].
VIRTUAL_INPUT_LIMIT = 1.0
#: Why a law's input limit (``blade_pitch_limit``) lies in [0.01, 1]: its parameter description.
INPUT_LIMIT_RANGE = ("the vehicle's input limit: +/-35 deg blade pitch (sec. 3.1) for the Seapup, 1 (full scale) "
                     "for a virtual-input vehicle, set from the vehicle where runs are flown; 0.01 as the simulator's")
if len(THRUSTER_NAMES) != 4 or not 0.0 < BLADE_PITCH_LIMIT < math.pi / 2:
    raise ValueError("seapup_common/data/interface.yaml: need 4 thrusters and a blade-pitch "
                     f"limit in (0, 90) deg, got {THRUSTER_NAMES} and {_INTERFACE['blade_pitch_limit_deg']}")


class InvalidBladePitchError(ValueError):
    """A blade-pitch command that must not reach the vehicle model."""


def within_limits(pitch, limit: float) -> bool:
    """True for the usual command, a float64 array of four finite pitches within ``[-limit, limit]``, checked
    in a fraction of :func:`check_blade_pitch`'s time (a NaN fails every comparison): such a command passes it
    unchanged. False says nothing; :func:`check_blade_pitch` then decides."""
    if type(pitch) is not np.ndarray or pitch.dtype != np.float64 or pitch.shape != (4,):
        return False
    a, b, c, d = pitch.tolist()
    return -limit <= a <= limit and -limit <= b <= limit and -limit <= c <= limit and -limit <= d <= limit


def check_blade_pitch(pitch, limit: float = BLADE_PITCH_LIMIT) -> tuple[np.ndarray, int]:
    """Validate a blade-pitch command and saturate it to the blade limits.

    Parameters
    ----------
    pitch : array_like
        Four blade pitches [rad] in ``seapup_msgs/BladePitch`` index order.
    limit : float, optional
        Symmetric blade-pitch limit [rad], > 0; default :data:`BLADE_PITCH_LIMIT`
        (the Seapup's blades stop at +/-35 deg, thesis sec. 3.1).

    Returns
    -------
    saturated : ndarray, shape (4,)
        The command clipped to ``[-limit, limit]`` (a new array).
    n_saturated : int
        How many of the four pitches were clipped.

    Raises
    ------
    InvalidBladePitchError
        If the command does not have exactly four elements or any is NaN or
        infinite. Nothing is clipped or returned in that case.
    """
    if not (math.isfinite(limit) and limit > 0.0):
        raise ValueError(f"blade-pitch limit must be finite and > 0 rad, got {limit!r}")
    if within_limits(pitch, limit):   # the usual case: the same answer as below, a third of its cost
        return pitch.copy(), 0
    try:
        values = np.asarray(pitch, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidBladePitchError(f"blade pitch is not numeric: {pitch!r}") from exc
    if values.shape != (4,):
        raise InvalidBladePitchError(
            f"blade pitch needs exactly 4 values (one per thruster), got shape {values.shape}")
    bad = ~np.isfinite(values)
    if bad.any():
        names = ", ".join(THRUSTER_NAMES[i] for i in np.flatnonzero(bad))
        raise InvalidBladePitchError(f"blade pitch of {names} is not finite: {values.tolist()}")
    saturated = np.clip(values, -limit, limit)
    return saturated, int(np.count_nonzero(saturated != values))


@dataclass
class CommandGate:
    """Counts and filters a stream of blade-pitch commands.

    Parameters
    ----------
    limit : float
        Blade-pitch limit [rad] passed to :func:`check_blade_pitch`.

    Attributes
    ----------
    accepted, rejected, saturated : int
        Commands passed on, commands refused, and individual pitches clipped.
    last_error : str
        Message of the most recent rejection ('' if none).
    """

    limit: float = BLADE_PITCH_LIMIT
    accepted: int = 0
    rejected: int = 0
    saturated: int = 0
    last_error: str = ""
    _last: np.ndarray | None = field(default=None, repr=False)

    def submit(self, pitch) -> np.ndarray | None:
        """Return the saturated command, or None (and count it) if it is invalid."""
        try:
            value, n_clipped = check_blade_pitch(pitch, self.limit)
        except InvalidBladePitchError as exc:
            self.rejected += 1
            self.last_error = str(exc)
            return None
        self.accepted += 1
        self.saturated += n_clipped
        self._last = value
        return value.copy()

    @property
    def last(self) -> np.ndarray | None:
        """The most recent accepted command (a copy), or None before the first."""
        return None if self._last is None else self._last.copy()

    def counters(self) -> dict[str, int]:
        """The counters as a dict, e.g. for diagnostics."""
        return {"accepted": self.accepted, "rejected": self.rejected, "saturated": self.saturated}
