"""The vehicle's four inputs: what a velocity autopilot commands, and how they reach the thrusters.

The thesis's laws (ch. 4-7) are square: four inputs for the four outputs u, v, w, r of sec. 4.2. The Seapup
has exactly four independent actuators, its blade pitches, and they are its inputs (:class:`DirectInputs`).
A vehicle with more thrusters than outputs -- a BlueROV2 Heavy's eight -- is flown through four *virtual
inputs* (:class:`VirtualInputs`), as sec. 8.3 suggests ("a simple thruster allocation matrix"): surge, sway,
heave and yaw demands, each a fraction in [-1, 1] of the generalised force the thrusters can give along
that axis alone, spread over the thrusters by :class:`seapup_sim.allocation.ThrustAllocator` (the weighted
pseudo-inverse; a demand beyond the thrusters scaled down along its own direction) and turned into each
thruster's command by the inverse of its thrust curve. A fully actuated vehicle (the allocation matrix of
rank 6) is asked for no roll and pitch moment at the same time, so surging does not pitch it through the
thrusters' offsets from the centre of gravity.

The mixer is the vehicle's own (like an ArduSub autopilot's motor mixer): it knows the thrusters' nominal
geometry and curve, never their fouling, and it runs once per held command. Everything upstream -- the
command messages, the gate, the laws, the self-test, identification -- sees four inputs either way; for a
virtual-input vehicle the "applied" inputs are the command held (its thrusters' lag is downstream).
"""
from __future__ import annotations

import math

import numpy as np

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT, VIRTUAL_INPUT_LIMIT
from seapup_sim.allocation import ThrustAllocator

__all__ = ["DirectInputs", "VirtualInputs", "INPUT_KINDS", "VIRTUAL_AXES", "inputs_of"]

#: How a vehicle's four inputs reach its thrusters (``inputs.kind`` of a vehicle description).
INPUT_KINDS = ("direct", "virtual")
#: The virtual inputs: names and their rows of the generalised force (X Y Z K M N).
VIRTUAL_AXES = (("surge", 0), ("sway", 1), ("heave", 2), ("yaw", 5))


class DirectInputs:
    """Four actuators that are the inputs themselves (the Seapup's blade pitches [rad]).

    The trim's two unknown settings are the pairs' (mains, vectored: ``[a, a, b, b]``, sec. 3.7); the vehicle's
    port/starboard mirror swaps the thrusters of each pair (``mirror``: a signed permutation of the inputs).
    """

    kind = "direct"
    names = ("main_port", "main_starboard", "vectored_starboard", "vectored_port")

    def __init__(self, limit: float = BLADE_PITCH_LIMIT, count: int = 4):
        if count != 4:
            raise ValueError(f"direct inputs need exactly four thrusters, got {count}: give the vehicle "
                             "inputs: {kind: virtual}")
        self.limit = float(limit)
        self.trim_guess = (0.0, 0.0, math.radians(-13.0))
        self.mirror = np.eye(4)[[1, 0, 3, 2]]

    def to_actuators(self, inputs: np.ndarray) -> np.ndarray:
        """The thrusters' commands for ``inputs``: the inputs themselves (not copied)."""
        return inputs

    @staticmethod
    def trim_inputs(a: float, b: float) -> np.ndarray:
        """The inputs of a symmetric trim: each pair at its setting."""
        return np.array([a, a, b, b])


class VirtualInputs:
    """Surge, sway, heave and yaw demands in [-1, 1] mixed onto N thrusters (module docstring).

    Parameters
    ----------
    thrusters : FixedPitchThrusters
        Their allocation matrix (``matrix`` (6, N)) and thrust curve (limits, and the command of a thrust).
    weights : array_like (N,), optional
        The allocation's cost of each thruster's thrust (default 1 each).
    """

    kind = "virtual"
    names = tuple(name for name, _ in VIRTUAL_AXES)

    def __init__(self, thrusters, weights=None):
        curve = thrusters.curve
        self.curve = curve
        self.limit = VIRTUAL_INPUT_LIMIT
        rank = int(np.linalg.matrix_rank(thrusters.matrix))
        #: rows of the generalised force allocated: all six (no roll or pitch moment asked) when the thrusters
        #: reach every one, else the four the inputs command
        self.rows = np.arange(6) if rank == 6 else np.array([row for _, row in VIRTUAL_AXES])
        low = np.full(thrusters.count, curve.max_reverse)
        high = np.full(thrusters.count, curve.max_forward)
        self.allocator = ThrustAllocator(thrusters.matrix[self.rows], low, high, weights)
        self._axis_index = [int(np.flatnonzero(self.rows == row)[0]) for _, row in VIRTUAL_AXES]
        m = len(self.rows)
        #: the generalised force [N, N m] at input +1 and -1 along each axis alone (its capacity either way)
        self.full_scale = np.empty((4, 2))
        for i, index in enumerate(self._axis_index):
            axis = np.zeros(m)
            axis[index] = 1.0
            self.full_scale[i] = (self.allocator.capacity(axis), self.allocator.capacity(-axis))
        if not np.all(self.full_scale > 0.0):
            raise ValueError("the thrusters cannot push the vehicle both ways along each of surge, sway, heave and "
                             "yaw")
        self.trim_guess = (0.0, 0.0, 0.0)
        self.mirror = np.diag([1.0, -1.0, 1.0, -1.0])   # sway and yaw change sign in the mirror
        self._last: tuple[bytes, np.ndarray] | None = None

    def demand(self, inputs: np.ndarray) -> np.ndarray:
        """The generalised force the inputs ask for (over ``rows``)."""
        tau = np.zeros(len(self.rows))
        for value, index, (up, down) in zip(np.asarray(inputs, float).tolist(), self._axis_index, self.full_scale):
            tau[index] = value * (up if value >= 0.0 else down)
        return tau

    def to_actuators(self, inputs: np.ndarray) -> np.ndarray:
        """Each thruster's command in [-1, 1] for the four inputs (within the limit: the gate's job)."""
        key = np.asarray(inputs, float).tobytes()
        if self._last is not None and self._last[0] == key:
            return self._last[1]
        thrust = self.allocator.allocate(self.demand(inputs)).efforts
        commands = self.curve.command_for(thrust)
        commands.setflags(write=False)
        self._last = (key, commands)
        return commands

    @staticmethod
    def trim_inputs(a: float, b: float) -> np.ndarray:
        """The inputs of a straight-flight trim: surge ``a``, heave ``b``."""
        return np.array([a, 0.0, b, 0.0])


def inputs_of(thrusters, section: dict | None):
    """The inputs of a vehicle with ``thrusters`` from its description's ``inputs`` section (None: direct for
    four controllable-pitch thrusters, virtual otherwise)."""
    section = dict(section or {})
    kind = section.pop("kind", "direct" if thrusters.kind == "controllable_pitch" else "virtual")
    weights = section.pop("weights", None)
    if section:
        raise ValueError(f"inputs: unknown key(s) {sorted(section)} (known: kind, weights)")
    if kind not in INPUT_KINDS:
        raise ValueError(f"inputs.kind must be one of {', '.join(INPUT_KINDS)}, got {kind!r}")
    if kind == "direct":
        if thrusters.kind != "controllable_pitch":
            raise ValueError("direct inputs are the Seapup's four blade pitches; fixed-pitch thrusters are flown "
                             "through inputs: {kind: virtual}")
        if weights is not None:
            raise ValueError("inputs.weights are the allocation's: direct inputs have none")
        return DirectInputs(count=thrusters.count)
    if thrusters.kind != "fixed_pitch":
        raise ValueError("virtual inputs are mixed onto fixed-pitch thrusters (thrusters.kind: fixed_pitch)")
    return VirtualInputs(thrusters, weights)
