"""Seabed depth profiles, so that an altimeter reading exists (seabed following).

A profile maps a horizontal NED position (x, y) to the seabed's depth [m,
positive down]:

- ``flat``: constant ``depth``;
- ``slope``: ``depth + gradient * d``, d the distance along ``direction``;
- ``polyline``: linear interpolation of ``points`` [[d, depth], ...] along
  ``direction`` (held constant beyond the ends).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["Seabed"]


class Seabed:
    """A seabed profile built from the ``seabed`` section of an environment YAML."""

    def __init__(self, kind: str = "flat", depth: float = 100.0, gradient: float = 0.0,
                 direction: float = 0.0, points=()):
        if kind not in ("flat", "slope", "polyline"):
            raise ValueError(f"seabed kind must be flat, slope or polyline, got {kind!r}")
        if not all(math.isfinite(v) for v in (depth, gradient, direction)):
            raise ValueError("seabed depth, gradient and direction must be finite")
        self.kind = kind
        self.depth = float(depth)
        self.gradient = float(gradient)
        self.direction = float(direction)
        pts = np.asarray(points, float).reshape(-1, 2) if len(points) else np.zeros((0, 2))
        if kind == "polyline":
            if len(pts) < 2 or np.any(np.diff(pts[:, 0]) <= 0) or not np.all(np.isfinite(pts)):
                raise ValueError("a polyline seabed needs >= 2 finite points with increasing distance")
        self.points = pts

    @classmethod
    def from_config(cls, cfg: dict) -> "Seabed":
        return cls(cfg.get("kind", "flat"), cfg.get("depth", 100.0), cfg.get("gradient", 0.0),
                   cfg.get("direction", 0.0), cfg.get("points", ()))

    def __call__(self, x: float, y: float) -> float:
        """Seabed depth [m] below (x, y)."""
        if self.kind == "flat":
            return self.depth
        d = x * math.cos(self.direction) + y * math.sin(self.direction)
        if self.kind == "slope":
            return self.depth + self.gradient * d
        return float(np.interp(d, self.points[:, 0], self.points[:, 1]))

    def depth_at(self, x, y) -> np.ndarray:
        """Seabed depth [m] below each of the positions (arrays ``x``, ``y``): :meth:`__call__` element by
        element, with the same arithmetic."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        if self.kind == "flat":
            return np.full(np.broadcast(x, y).shape, self.depth)
        d = x * math.cos(self.direction) + y * math.sin(self.direction)
        if self.kind == "slope":
            return self.depth + self.gradient * d
        return np.interp(d, self.points[:, 0], self.points[:, 1])
