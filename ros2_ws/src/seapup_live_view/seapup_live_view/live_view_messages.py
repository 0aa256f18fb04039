"""The live view's geometry (:mod:`seapup_live_view.view_scene`) as Foxglove messages: copies only, no maths.

Stamps are the sample's sim time; every Quaternion and Color is given in full (the SDK's defaults are w = 0 and
alpha = 0: an invisible, degenerate object).
"""
from __future__ import annotations

import numpy as np
from foxglove.messages import (ArrowPrimitive, Color, CubePrimitive, Duration, FrameTransform, FrameTransforms,
                               LinePrimitive, LinePrimitiveLineType, Log, LogLevel, Point3, Pose, Quaternion,
                               SceneEntity,
                               SceneUpdate, SpherePrimitive, Timestamp, TriangleListPrimitive, Vector3)

from seapup_common import frames

__all__ = ["frame_transforms", "vehicle", "world", "seabed", "timestamp", "event"]

_IDENTITY = (0.0, 0.0, 0.0, 1.0)
_FRAME_COLOUR = Color(r=0.95, g=0.75, b=0.1, a=0.55)
_THRUSTER_COLOUR = Color(r=0.3, g=0.3, b=0.35, a=1.0)
_ARROW_COLOUR = Color(r=0.1, g=0.6, b=1.0, a=1.0)


def event(text: str, t_ns: int, error: bool = False) -> Log:
    """A line on the view's ``/events`` (a controller switch; a refused request)."""
    return Log(timestamp=timestamp(t_ns), level=LogLevel.Error if error else LogLevel.Info, message=text,
               name="seapup", file="", line=0)


def timestamp(t_ns: int) -> Timestamp:
    return Timestamp(int(t_ns) // 1_000_000_000, int(t_ns) % 1_000_000_000)


def _pose(position=(0.0, 0.0, 0.0), rotation=_IDENTITY) -> Pose:
    x, y, z, w = (float(v) for v in rotation)
    return Pose(position=Vector3(x=float(position[0]), y=float(position[1]), z=float(position[2])),
                orientation=Quaternion(x=x, y=y, z=z, w=w))


def _points(array) -> list:
    return [Point3(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in np.asarray(array, float).reshape(-1, 3)]


def _rotation_x_to(direction) -> tuple:
    """The quaternion (x, y, z, w) turning +x onto ``direction`` (an arrow primitive points along its +x)."""
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    axis = np.cross([1.0, 0.0, 0.0], d)
    s, c = float(np.linalg.norm(axis)), float(d[0])
    if s < 1e-12:
        return _IDENTITY if c > 0 else (0.0, 0.0, 1.0, 0.0)
    half = 0.5 * np.arctan2(s, c)
    axis = axis / s
    return (*(np.sin(half) * axis).tolist(), float(np.cos(half)))


def frame_transforms(transforms, t_ns: int) -> FrameTransforms:
    """:func:`~seapup_live_view.view_scene.frame_transforms` as foxglove.FrameTransforms."""
    stamp = timestamp(t_ns)
    return FrameTransforms(transforms=[FrameTransform(
        timestamp=stamp, parent_frame_id=t.parent, child_frame_id=t.child,
        translation=Vector3(x=t.translation[0], y=t.translation[1], z=t.translation[2]),
        rotation=Quaternion(x=t.rotation[0], y=t.rotation[1], z=t.rotation[2], w=t.rotation[3])) for t in transforms])


def vehicle(shape, arrows, t_ns: int) -> SceneUpdate:
    """The vehicle entity in ``base_link_frd``: frame box, thruster discs, thrust arrows, payload spheres."""
    cubes = [CubePrimitive(pose=_pose(shape.frame_center), size=Vector3(x=float(shape.frame_size[0]),
                           y=float(shape.frame_size[1]), z=float(shape.frame_size[2])), color=_FRAME_COLOUR)]
    spheres = [SpherePrimitive(pose=_pose(t.position), size=Vector3(x=t.diameter, y=t.diameter, z=t.diameter),
                               color=_THRUSTER_COLOUR) for t in shape.thrusters]
    spheres += [SpherePrimitive(pose=_pose(position), size=Vector3(x=2 * radius, y=2 * radius, z=2 * radius),
                                color=Color(r=0.9, g=0.2, b=0.2, a=1.0)) for _, position, radius in shape.payloads]
    arrow_list = [ArrowPrimitive(pose=_pose(origin, _rotation_x_to(direction)), shaft_length=max(length, 1e-3),
                                 shaft_diameter=0.03, head_length=0.08, head_diameter=0.07, color=_ARROW_COLOUR)
                  for origin, direction, length in arrows]
    entity = SceneEntity(timestamp=timestamp(t_ns), frame_id=frames.FRAME_FRD, id="vehicle", frame_locked=True,
                         lifetime=Duration(0, 0), cubes=cubes, spheres=spheres, arrows=arrow_list)
    return SceneUpdate(entities=[entity])


def world(parts: dict) -> SceneUpdate:
    """Track, current, goal, estimate and fixes in ``odom_ned`` (whichever ``parts`` has)."""
    stamp = timestamp(parts["t_ns"])
    lines, arrows, spheres = [], [], []
    if len(parts["trail"]) >= 2:
        lines.append(LinePrimitive(type=LinePrimitiveLineType.LineStrip, pose=_pose(), thickness=0.03,
                                   scale_invariant=False, points=_points(parts["trail"]),
                                   color=Color(r=0.2, g=0.9, b=0.3, a=1.0)))
    if "cable" in parts:
        lines.append(LinePrimitive(type=LinePrimitiveLineType.LineStrip, pose=_pose(), thickness=0.025,
                                   scale_invariant=False, points=_points(parts["cable"]),
                                   color=Color(r=1.0, g=0.85, b=0.1, a=1.0)))
    current = parts.get("current")
    if current is not None and len(parts["trail"]):
        direction, length = current
        arrows.append(ArrowPrimitive(pose=_pose(parts["trail"][-1] + [0.0, 0.0, -1.0], _rotation_x_to(direction)),
                                     shaft_length=length, shaft_diameter=0.05, head_length=0.2, head_diameter=0.15,
                                     color=Color(r=0.2, g=0.8, b=0.9, a=1.0)))
    if "goal" in parts:
        spheres.append(SpherePrimitive(pose=_pose(parts["goal"]), size=Vector3(x=0.3, y=0.3, z=0.3),
                                       color=Color(r=1.0, g=0.5, b=0.0, a=0.9)))
    if "estimate" in parts:
        position, two_sigma = parts["estimate"]
        size = max(2.0 * two_sigma, 0.05)
        spheres.append(SpherePrimitive(pose=_pose(position), size=Vector3(x=size, y=size, z=0.05),
                                       color=Color(r=0.6, g=0.3, b=1.0, a=0.35)))
    spheres += [SpherePrimitive(pose=_pose(fix), size=Vector3(x=0.12, y=0.12, z=0.12),
                                color=Color(r=1.0, g=1.0, b=1.0, a=0.8)) for fix in parts["fixes"]]
    entity = SceneEntity(timestamp=stamp, frame_id=frames.FRAME_NED, id="world", lifetime=Duration(0, 0),
                         lines=lines, arrows=arrows, spheres=spheres)
    return SceneUpdate(entities=[entity])


def seabed(vertices, triangles, t_ns: int) -> SceneUpdate:
    """The seabed grid as one triangle list in ``odom_ned``."""
    points = _points(np.asarray(vertices)[np.asarray(triangles).ravel()])
    mesh = TriangleListPrimitive(pose=_pose(), points=points, color=Color(r=0.55, g=0.45, b=0.3, a=0.8))
    entity = SceneEntity(timestamp=timestamp(t_ns), frame_id=frames.FRAME_NED, id="seabed",
                         lifetime=Duration(0, 0), triangles=[mesh])
    return SceneUpdate(entities=[entity])
