"""What the live view draws, as plain geometry (the pure core of :mod:`seapup_live_view.live_view_node`).

No viewer types here: numpy arrays, frame names and small dataclasses, so every shape is tested without a
server, and the node only copies them into Foxglove's messages.

Frames (:mod:`seapup_common.frames`): the vehicle is drawn in ``base_link_frd`` with the configuration's own
body coordinates (sec. 2.2: x forward, y starboard, z down), world things (trail, current, seabed, goals) in
``odom_ned``; :func:`frame_transforms` relates both to the REP-103/105 ``odom``/``base_link`` a viewer displays
in (ENU: up is up), the same tree as the simulator's ``/tf`` (:func:`seapup_common.ros.messages.transforms_enu`).

The Seapup's hull dimensions are not in the thesis: the frame is drawn as the box spanning the four thrusters
(Table 3.2's positions) padded by one propeller diameter, the bow camera (sec. 3.6) as its payload sphere. Any
other vehicle the same way from its description (a fixed-pitch thruster drawn 0.1 m across).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from seapup_common import frames

__all__ = ["Transform", "Thruster", "VehicleShape", "vehicle_shape", "thrust_arrows", "frame_transforms",
           "Trail", "seabed_grid", "current_arrow", "ARROW_FULL_LENGTH"]

#: Length [m] of a thruster's arrow at the blade-pitch limit (the arrows scale with |beta - beta_0| / limit).
ARROW_FULL_LENGTH = 0.5


@dataclass(frozen=True)
class Transform:
    """``child`` in ``parent``: p_parent = R(rotation) p_child + translation; rotation (x, y, z, w)."""

    parent: str
    child: str
    translation: tuple
    rotation: tuple


@dataclass(frozen=True)
class Thruster:
    position: np.ndarray     # [m] body axes (FRD), Table 3.2
    direction: np.ndarray    # unit thrust axis (FRD)
    diameter: float          # [m]


@dataclass(frozen=True)
class VehicleShape:
    """The drawn vehicle in ``base_link_frd``: the frame box, the thrusters and payload spheres, and how the
    four inputs the vehicle reports applied become each thruster's share of its full thrust (``thrust_share``:
    the Seapup's blade pitches, or a virtual-input vehicle's inputs through its mixer and thrust curve)."""

    frame_center: np.ndarray
    frame_size: np.ndarray
    thrusters: tuple
    payloads: tuple          # (name, position (3,), radius)
    zero_thrust_pitch: float
    pitch_limit: float
    thrust_share: Callable = None   # applied inputs (4,) -> (N,) signed shares of full thrust
    #: the four inputs' names, and how the plot shows them: the Seapup's blade pitches in degrees, a virtual-input
    #: vehicle's surge, sway, heave and yaw in percent of their full scale (:func:`plot_inputs`)
    input_names: tuple = ("input 1", "input 2", "input 3", "input 4")
    input_unit: str = "deg"


#: [m] the drawn diameter of a fixed-pitch thruster, whose description has none (a T200's nozzle is about 0.1 m)
FIXED_PITCH_DIAMETER = 0.1


def vehicle_shape(model) -> VehicleShape:
    """The shape of a :class:`~seapup_sim.vehicle.VehicleModel`'s active configuration (a configuration switch
    changes it: the camera appears)."""
    th = model.thrusters
    positions = np.asarray(th.positions, float)
    diameter = float(getattr(th, "diameter", FIXED_PITCH_DIAMETER))
    low, high = positions.min(axis=0) - diameter, positions.max(axis=0) + diameter
    thrusters = tuple(Thruster(positions[j].copy(), np.asarray(th.directions[j], float).copy(), diameter)
                      for j in range(len(positions)))
    payloads = tuple((str(p.get("name", f"payload {i}")), np.asarray(p["position"], float), float(p.get("radius", 0.1)))
                     for i, p in enumerate(model.config.get("payloads") or []))
    if th.kind == "controllable_pitch":
        beta0, limit = float(th.zero_thrust_pitch), float(model.pitch_limit)

        def share(applied):   # eq. 2.18's bollard term: (beta - beta_0) over the limit
            pitch = np.asarray(applied, float).reshape(len(thrusters))
            return (pitch - beta0) / limit
        return VehicleShape(0.5 * (low + high), high - low, thrusters, payloads, beta0, limit, share,
                            tuple(model.inputs.names), "deg")
    inputs, curve = model.inputs, th.curve

    def share(applied):       # the mixer's commands through the thrust curve, over the curve's full thrust
        applied = np.asarray(applied, float)
        if applied.shape != (4,):
            raise ValueError(f"a virtual-input vehicle reports 4 applied inputs, got shape {applied.shape}")
        thrust = curve.thrust(inputs.to_actuators(applied))
        return np.where(thrust >= 0.0, thrust / curve.max_forward, thrust / -curve.max_reverse)
    return VehicleShape(0.5 * (low + high), high - low, thrusters, payloads, 0.0, float(model.pitch_limit), share,
                        tuple(inputs.names), "%")


#: The factor from an input's own unit to the plot's (radians to degrees; a fraction of full scale to percent).
_PLOT_SCALE = {"deg": 180.0 / np.pi, "%": 100.0}


def plot_inputs(shape: VehicleShape, applied) -> dict:
    """The ``/plot`` fields of the four inputs applied: ``inputs`` and their limit ``input_limit`` in the unit
    ``input_unit`` (the Seapup's blade pitches in degrees against the +-35 deg limit; a virtual-input vehicle's
    surge, sway, heave and yaw in percent of full scale against 100 %), and their ``input_names``. A
    blade-pitch vehicle also keeps ``blade_pitch_deg`` and ``pitch_limit_deg`` (the layout's fields before
    there were other vehicles); a virtual-input vehicle has no blade pitches to show."""
    scale = _PLOT_SCALE[shape.input_unit]
    values = np.asarray(applied, float).reshape(4) * scale
    out = {"inputs": values.tolist(), "input_limit": float(shape.pitch_limit * scale), "input_unit": shape.input_unit,
           "input_names": list(shape.input_names)}
    if shape.input_unit == "deg":
        out["blade_pitch_deg"], out["pitch_limit_deg"] = out["inputs"], out["input_limit"]
    return out


def thrust_arrows(shape: VehicleShape, applied) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """One arrow per thruster (origin, unit direction, length) in ``base_link_frd``: along the thrust axis, pointing
    the way the thrust acts, its length :data:`ARROW_FULL_LENGTH` times the thruster's share of its full thrust
    (:attr:`VehicleShape.thrust_share`: the Seapup's |beta - beta_0| / limit, eq. 2.18's bollard term, so an
    arrow at full length is a blade at the +-35 deg limit; a fixed-pitch thruster's thrust over its curve's
    largest)."""
    shares = shape.thrust_share(applied)
    arrows = []
    for thruster, share in zip(shape.thrusters, np.asarray(shares, float).tolist()):
        sign = 1.0 if share >= 0.0 else -1.0
        arrows.append((thruster.position.copy(), sign * thruster.direction,
                       ARROW_FULL_LENGTH * min(abs(share), 2.0)))
    return arrows


def frame_transforms(state) -> list[Transform]:
    """The frame tree for a 12-state (eq. 2.1's z-y-x angles): ``odom`` -> ``base_link`` (REP-105, ENU/FLU),
    ``odom`` -> ``odom_ned`` and ``base_link`` -> ``base_link_frd`` (fixed)."""
    x = np.asarray(state, float)
    q = frames.orientation_ned_frd_to_enu_flu(frames.euler_to_quaternion(*x[3:6]))
    zero = (0.0, 0.0, 0.0)
    return [Transform(frames.FRAME_ENU, frames.FRAME_FLU, tuple(frames.ned_to_enu(x[:3]).tolist()), tuple(q.tolist())),
            Transform(frames.FRAME_ENU, frames.FRAME_NED, zero, tuple(frames.QUATERNION_NED_IN_ENU.tolist())),
            Transform(frames.FRAME_FLU, frames.FRAME_FRD, zero, tuple(frames.QUATERNION_FRD_IN_FLU.tolist()))]


class Trail:
    """The track flown (``odom_ned``): a point each time the vehicle has moved ``spacing`` m, the last
    ``capacity`` kept (a ring: constant memory however long the graph runs)."""

    def __init__(self, capacity: int = 2000, spacing: float = 0.05):
        if capacity < 2 or not spacing > 0.0:
            raise ValueError(f"a trail needs capacity >= 2 and spacing > 0, got {capacity}, {spacing}")
        self._points = np.zeros((capacity, 3))
        self._count = 0
        self._next = 0
        self.spacing = float(spacing)

    def add(self, position_ned) -> bool:
        """Take a position; True if it was kept (far enough from the last)."""
        p = np.asarray(position_ned, float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            return False
        if self._count and np.linalg.norm(p - self._points[(self._next - 1) % len(self._points)]) < self.spacing:
            return False
        self._points[self._next] = p
        self._next = (self._next + 1) % len(self._points)
        self._count = min(self._count + 1, len(self._points))
        return True

    def points(self) -> np.ndarray:
        """The kept positions, oldest first."""
        if self._count < len(self._points):
            return self._points[:self._count].copy()
        return np.roll(self._points, -self._next, axis=0)


def seabed_grid(seabed, center_ned, half_width: float = 20.0, cells: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """The seabed under a square around ``center_ned`` as triangles: vertices (``odom_ned``, depth from
    :meth:`seapup_sim.seabed.Seabed.depth_at`) and a (k, 3) array of vertex indices, two per cell."""
    if cells < 1 or not half_width > 0.0:
        raise ValueError(f"a seabed grid needs cells >= 1 and half_width > 0, got {cells}, {half_width}")
    c = np.asarray(center_ned, float)
    xs = np.linspace(c[0] - half_width, c[0] + half_width, cells + 1)
    ys = np.linspace(c[1] - half_width, c[1] + half_width, cells + 1)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    vertices = np.column_stack([gx.ravel(), gy.ravel(), seabed.depth_at(gx.ravel(), gy.ravel())])
    i, j = np.meshgrid(np.arange(cells), np.arange(cells), indexing="ij")
    a = (i * (cells + 1) + j).ravel()
    b, d = a + 1, a + cells + 1
    triangles = np.concatenate([np.column_stack([a, d, b]), np.column_stack([b, d, d + 1])])
    return vertices, triangles


def current_arrow(current_ned, metres_per_knot: float = 2.0) -> tuple[np.ndarray, float] | None:
    """The current's arrow in ``odom_ned``: unit direction and length (``metres_per_knot`` per knot of speed);
    None in still water."""
    v = np.asarray(current_ned, float)
    speed = float(np.linalg.norm(v))
    if not math.isfinite(speed) or speed < 1e-9:
        return None
    return v / speed, metres_per_knot * speed / 0.514444
