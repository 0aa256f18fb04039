"""Task controllers: the top level of the thesis's supervisory hierarchy (sec. 4.2, fig. 4.3).

"A series of task controllers will be next to the operator. He will be able
to choose to execute such functions as hovering, following the seabed at a
set height and heading or moving to a point. The task controller will
generate a series of reference signals for a global position controller"
(sec. 4.2). Each task here is a pure object: built from a goal (checked
against :class:`TaskLimits`; a goal that cannot be met raises
:class:`TaskRejected` with the reason), then called once per control sample
with the navigation estimate (and the altimeter) to return the setpoint --
a :class:`~seapup_control.position_control.PoseReference` -- its feedback,
and, when it ends, its outcome and result numbers.

- :class:`Hover` holds a pose for a duration (or until cancelled).
- :class:`Goto` moves the setpoint along the straight line from the start to
  the target at a set speed (the vehicle creeps along it, as a pilot does in
  the thesis's inspection manoeuvre, sec. 5.4.2) and succeeds once the pose
  estimate stays within the tolerances for ``settle_time``.
- :class:`FollowSeabed` holds a height over the seabed, heading and speed:
  the seabed depth below the vehicle is depth + altitude cos(phi) cos(theta)
  (the altimeter looks along body z), low-pass filtered; the depth setpoint
  is that minus the height asked for.
"""
from __future__ import annotations

import abc
import math
from dataclasses import dataclass, field

import numpy as np

from seapup_common.contract import NavigationEstimate, Reading
from seapup_common.frames import wrap_angle
from seapup_control.position_control import PoseReference

__all__ = ["TaskRejected", "TaskLimits", "TaskStep", "Task", "Hover", "Goto", "FollowSeabed", "TrackingStats",
           "advance_along", "norm3"]


class TaskRejected(ValueError):
    """A goal that cannot be met (the message says why and what is allowed)."""


@dataclass(frozen=True)
class TaskLimits:
    """What goals the task controller accepts, and its defaults (YAML: ``config/task_controller.yaml``).

    Depths [m] positive down, distances [m], speeds [m/s], angles [rad], times [s].
    """

    min_depth: float = 1.0
    max_depth: float = 300.0
    max_distance: float = 200.0
    min_speed: float = 0.02
    max_speed: float = 0.3
    min_altitude: float = 1.0
    max_altitude: float = 50.0
    max_duration: float = 3600.0
    default_speed: float = 0.2
    default_tolerance: float = 0.5
    default_yaw_tolerance: float = 0.0873
    settle_time: float = 3.0
    timeout_margin: float = 60.0
    altitude_timeout: float = 2.0
    seabed_filter_time: float = 2.0
    max_estimate_std: float = 3.0
    max_lead: float = 0.5

    @classmethod
    def from_mapping(cls, mapping: dict) -> "TaskLimits":
        unknown = set(mapping) - set(cls.__dataclass_fields__)
        if unknown:
            raise ValueError(f"task limits: unknown key(s) {sorted(unknown)}")
        values = {k: float(v) for k, v in mapping.items()}
        bad = {k: v for k, v in values.items() if not math.isfinite(v) or v < 0}
        if bad:
            raise ValueError(f"task limits must be finite and >= 0: {bad}")
        return cls(**values)


def _finite(name: str, value: float) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise TaskRejected(f"{name} must be finite, got {value!r}")
    return value


def _in_range(name: str, value: float, low: float, high: float, unit: str) -> float:
    value = _finite(name, value)
    if not low <= value <= high:
        raise TaskRejected(f"{name} {value:g} {unit} is outside [{low:g}, {high:g}] {unit}")
    return value


def _check_estimate(estimate: NavigationEstimate | None, limits: TaskLimits) -> NavigationEstimate:
    if estimate is None:
        raise TaskRejected("no navigation estimate (is the navigator running and has it had a position fix?)")
    if estimate.horizontal_std > limits.max_estimate_std:
        raise TaskRejected(f"navigation too uncertain: horizontal std {estimate.horizontal_std:.2f} m > "
                           f"{limits.max_estimate_std:g} m")
    return estimate


class TrackingStats:
    """Running RMS and maximum of a few error signals (for results)."""

    def __init__(self, *names: str):
        self.sums = dict.fromkeys(names, 0.0)
        self.maxima = dict.fromkeys(names, 0.0)
        self.count = 0

    def add(self, **errors: float) -> None:
        self.count += 1
        for name, value in errors.items():
            self.sums[name] += value * value
            self.maxima[name] = max(self.maxima[name], abs(value))

    def rms(self, name: str) -> float:
        return math.sqrt(self.sums[name] / self.count) if self.count else 0.0


def norm3(x: float, y: float, z: float) -> float:
    """|(x, y, z)| in plain floats: ``sqrt(x x + y y + z z)``, summed in order as numpy's ``np.linalg.norm`` of three
    values sums them (tested), at a tenth of its cost."""
    return math.sqrt(x * x + y * y + z * z)


def advance_along(previous: float, dt: float, speed: float, vehicle_along: float, lead: float, end: float) -> float:
    """The moving setpoint's distance along its line after ``dt`` s at ``speed``, never more than ``lead`` m
    ahead of the vehicle's own distance along the line (nor past ``end``), and never moving back.

    A setpoint that runs ahead while the vehicle is held back (surge at its speed limit, a current)
    piles up an along-track error the velocity loop can never recover, and the vehicle's pitch
    turns part of it into a false depth error through the body-frame conversion of sec. 4.2: the
    trajectory waits for the vehicle instead (anti-windup for the trajectory).
    """
    return max(previous, min(previous + speed * max(dt, 0.0), vehicle_along + lead, end))


@dataclass
class TaskStep:
    """What a task says at one sample.

    ``setpoint`` for the position controller; ``feedback`` (action feedback
    fields); when ``done``: ``success``, ``message`` and ``result`` (action
    result fields).
    """

    setpoint: PoseReference
    feedback: dict
    done: bool = False
    success: bool = False
    message: str = ""
    result: dict = field(default_factory=dict)


class Task(abc.ABC):
    """A task: ``step(t, estimate, altitude)`` once per sample until it says done."""

    kind = "task"

    def __init__(self, limits: TaskLimits):
        self.limits = limits
        self.t0: float | None = None

    def elapsed(self, t: float) -> float:
        if self.t0 is None:
            self.t0 = t
        return t - self.t0

    @abc.abstractmethod
    def step(self, t: float, estimate: NavigationEstimate, altitude: Reading | None = None) -> TaskStep:
        """The setpoint, feedback and (when done) outcome at sample ``t``."""

    def hold(self, estimate: NavigationEstimate, t: float) -> PoseReference:
        """Where to hover when this task is cancelled or ends badly: the estimated pose now."""
        return PoseReference(estimate.position, estimate.yaw, t)


class Hover(Task):
    """Hold ``pose`` (x, y, z, yaw) -- or the estimated pose at the start -- for ``duration`` s (0 = until cancelled).

    With ``follow`` the setpoint is instead the estimated pose at every sample: while a pilot flies the vehicle
    (:mod:`seapup_control.manual`) the position controller then tracks it -- its slew-limited reference follows
    the setpoint's rate, the vehicle's own velocity, as its feed-forward (sec. 8.3's references the thrusters can
    follow) -- so the task that takes the vehicle back starts from the velocity the vehicle has, without a bump
    (the tracking mode of a bumpless transfer). Its errors are then the vehicle's excursion from where it was at
    the start.
    """

    kind = "hover"

    def __init__(self, limits: TaskLimits, estimate: NavigationEstimate | None, *, hold_current: bool = True,
                 pose=(0.0, 0.0, 0.0, 0.0), duration: float = 0.0, follow: bool = False):
        super().__init__(limits)
        estimate = _check_estimate(estimate, limits)
        self.duration = _in_range("duration", duration, 0.0, limits.max_duration, "s")
        self.follow = bool(follow)
        if hold_current or self.follow:
            self.target = np.array(estimate.position, dtype=float)
            self.yaw = estimate.yaw
        else:
            x, y, z, yaw = (_finite(name, v) for name, v in zip("x y z yaw".split(), pose))
            self.target = np.array([x, y, _in_range("z", z, limits.min_depth, limits.max_depth, "m")])
            distance = float(np.linalg.norm(self.target - estimate.position))
            if distance > limits.max_distance:
                raise TaskRejected(f"hover point {distance:.1f} m away: more than max_distance "
                                   f"{limits.max_distance:g} m (use goto)")
            self.yaw = float(wrap_angle(yaw))
        self.stats = TrackingStats("horizontal", "depth", "yaw")

    def step(self, t, estimate, altitude=None) -> TaskStep:
        elapsed = self.elapsed(t)
        (px, py, pz), (tx, ty, tz) = estimate.position.tolist(), self.target.tolist()
        ex, ey, depth_error = px - tx, py - ty, pz - tz
        horizontal = math.hypot(ex, ey)
        yaw_error = float(wrap_angle(estimate.yaw - self.yaw))
        self.stats.add(horizontal=horizontal, depth=depth_error, yaw=yaw_error)
        setpoint = (PoseReference(estimate.position, estimate.yaw, t) if self.follow
                    else PoseReference(self.target, self.yaw, t))
        step = TaskStep(setpoint,
                        {"elapsed": elapsed, "horizontal_error": horizontal, "depth_error": depth_error,
                         "yaw_error": yaw_error})
        if self.duration > 0 and elapsed >= self.duration - 1e-9:
            step.done, step.success, step.message = True, True, f"held {elapsed:.1f} s"
            step.result = self.result(elapsed)
        return step

    def result(self, elapsed: float) -> dict:
        return {"duration": elapsed, "horizontal_rms": self.stats.rms("horizontal"),
                "horizontal_max": self.stats.maxima["horizontal"], "depth_rms": self.stats.rms("depth"),
                "yaw_rms": self.stats.rms("yaw")}


class Goto(Task):
    """Move to ``(x, y, z)`` and ``yaw`` along the straight line from the start (class docstring)."""

    kind = "goto"

    def __init__(self, limits: TaskLimits, estimate: NavigationEstimate | None, target, yaw: float, *,
                 speed: float = 0.0, tolerance: float = 0.0, yaw_tolerance: float = 0.0, timeout: float = 0.0):
        super().__init__(limits)
        estimate = _check_estimate(estimate, limits)
        x, y, z = (_finite(name, v) for name, v in zip("xyz", target))
        self.target = np.array([x, y, _in_range("z", z, limits.min_depth, limits.max_depth, "m")])
        self.yaw = float(wrap_angle(_finite("yaw", yaw)))
        self.speed = _in_range("speed", speed, limits.min_speed, limits.max_speed, "m/s") if speed else \
            limits.default_speed
        self.tolerance = _in_range("tolerance", tolerance, 0.05, 10.0, "m") if tolerance else \
            limits.default_tolerance
        self.yaw_tolerance = _in_range("yaw_tolerance", yaw_tolerance, 0.01, math.pi, "rad") if yaw_tolerance \
            else limits.default_yaw_tolerance
        self.start = np.array(estimate.position, dtype=float)
        self.length = float(np.linalg.norm(self.target - self.start))
        if self.length > limits.max_distance:
            raise TaskRejected(f"target {self.length:.1f} m away: more than max_distance {limits.max_distance:g} m")
        self.direction = (self.target - self.start) / self.length if self.length > 1e-9 else np.zeros(3)
        travel = self.length / self.speed
        self.timeout = _in_range("timeout", timeout, 1.0, limits.max_duration, "s") if timeout else \
            travel + limits.timeout_margin
        if self.timeout < travel:
            raise TaskRejected(f"timeout {self.timeout:g} s is shorter than the {travel:.1f} s the line takes at "
                               f"{self.speed:g} m/s")
        self.start_yaw = estimate.yaw
        self.stats = TrackingStats("cross_track")
        self._inside_since: float | None = None
        self._travelled, self._t_last = 0.0, None

    def step(self, t, estimate, altitude=None) -> TaskStep:
        elapsed = self.elapsed(t)
        # the 3-vectors in plain floats: the sums of products numpy's dot and norm make of them (tested)
        px, py, pz = estimate.position.tolist()
        (sx, sy, sz), (dx, dy, dz) = self.start.tolist(), self.direction.tolist()
        ox, oy, oz = px - sx, py - sy, pz - sz
        along = ox * dx + oy * dy + oz * dz
        dt = 0.0 if self._t_last is None else t - self._t_last
        self._t_last = t
        self._travelled = travelled = advance_along(self._travelled, dt, self.speed, along, self.limits.max_lead,
                                                    self.length)
        setpoint = PoseReference([sx + travelled * dx, sy + travelled * dy, sz + travelled * dz], self.yaw, t)
        cross = norm3(ox - along * dx, oy - along * dy, oz - along * dz)
        tx, ty, tz = self.target.tolist()
        distance = norm3(tx - px, ty - py, tz - pz)
        yaw_error = float(wrap_angle(estimate.yaw - self.yaw))
        if travelled < self.length:
            self.stats.add(cross_track=cross)
        step = TaskStep(setpoint, {"elapsed": elapsed, "distance": distance, "along_track": along,
                                   "cross_track": cross, "yaw_error": yaw_error})
        inside = travelled >= self.length and distance <= self.tolerance and abs(yaw_error) <= self.yaw_tolerance
        self._inside_since = (self._inside_since if self._inside_since is not None else t) if inside else None
        if inside and t - self._inside_since >= self.limits.settle_time - 1e-9:
            step.done, step.success = True, True
            step.message = f"arrived: {distance:.2f} m, yaw {math.degrees(yaw_error):.1f} deg off after {elapsed:.1f} s"
        elif elapsed >= self.timeout:
            step.done, step.setpoint = True, self.hold(estimate, t)
            step.message = (f"timeout after {elapsed:.1f} s: {distance:.2f} m and {math.degrees(yaw_error):.1f} deg "
                            f"from the target (tolerance {self.tolerance:g} m, "
                            f"{math.degrees(self.yaw_tolerance):.1f} deg)")
        if step.done:
            step.result = {"distance": distance, "yaw_error": yaw_error, "duration": elapsed,
                           "cross_track_rms": self.stats.rms("cross_track")}
        return step


class FollowSeabed(Task):
    """Hold ``altitude`` over the seabed, heading ``yaw`` and ``speed`` for ``duration`` s (class docstring)."""

    kind = "follow_seabed"

    def __init__(self, limits: TaskLimits, estimate: NavigationEstimate | None, altitude: Reading | None, *,
                 height: float, yaw: float, speed: float, duration: float):
        super().__init__(limits)
        estimate = _check_estimate(estimate, limits)
        self.height = _in_range("altitude", height, limits.min_altitude, limits.max_altitude, "m")
        self.yaw = float(wrap_angle(_finite("yaw", yaw)))
        self.speed = _in_range("speed", speed, 0.0, limits.max_speed, "m/s")
        self.duration = _in_range("duration", duration, 1.0, limits.max_duration, "s")
        if altitude is None or not altitude.valid:
            raise TaskRejected("the altimeter sees no seabed (out of range or no altitude reading)")
        self.seabed = self._seabed_depth(estimate, altitude)
        self.start = np.array(estimate.position, dtype=float)
        self.heading = np.array([math.cos(self.yaw), math.sin(self.yaw), 0.0])
        self.last_altitude_t: float | None = None
        self.stats = TrackingStats("altitude")
        self._t_last: float | None = None
        self._along = 0.0  # the setpoint's distance along the heading from the start [m]

    @staticmethod
    def _seabed_depth(estimate: NavigationEstimate, altitude: Reading) -> float:
        phi, theta = estimate.attitude[0], estimate.attitude[1]
        return float(estimate.position[2] + float(altitude.value) * math.cos(phi) * math.cos(theta))

    def step(self, t, estimate, altitude=None) -> TaskStep:
        elapsed = self.elapsed(t)
        dt = 0.0 if self._t_last is None else t - self._t_last
        self._t_last = t
        measured = None
        if altitude is not None and altitude.valid:
            phi, theta = estimate.attitude[0], estimate.attitude[1]
            measured = float(altitude.value) * math.cos(phi) * math.cos(theta)
            a = 1.0 - math.exp(-dt / self.limits.seabed_filter_time) if dt > 0 else 0.0
            self.seabed += a * (self._seabed_depth(estimate, altitude) - self.seabed)
            self.last_altitude_t = t
        depth = min(max(self.seabed - self.height, self.limits.min_depth), self.limits.max_depth)
        vehicle_along = float((estimate.position - self.start) @ self.heading)
        self._along = advance_along(self._along, dt, self.speed, vehicle_along, self.limits.max_lead, math.inf)
        along = self.start + self._along * self.heading
        setpoint = PoseReference([along[0], along[1], depth], self.yaw, t)
        travelled = float(math.hypot(*(estimate.position[:2] - self.start[:2])))
        error = (measured - self.height) if measured is not None else math.nan
        if measured is not None:
            self.stats.add(altitude=error)
        feedback = {"elapsed": elapsed, "altitude": measured if measured is not None else math.nan,
                    "altitude_error": error, "yaw_error": float(wrap_angle(estimate.yaw - self.yaw)),
                    "distance": travelled}
        step = TaskStep(setpoint, feedback)
        lost = t - (self.last_altitude_t if self.last_altitude_t is not None else (self.t0 or t))
        if lost > self.limits.altitude_timeout:
            step.done, step.setpoint = True, self.hold(estimate, t)
            step.message = f"altimeter lost the seabed for {lost:.1f} s (more than {self.limits.altitude_timeout:g} s)"
        elif elapsed >= self.duration - 1e-9:
            step.done, step.success = True, True
            step.message = (f"followed {travelled:.1f} m: altitude error rms {self.stats.rms('altitude'):.3f} m, "
                            f"max {self.stats.maxima['altitude']:.3f} m")
        if step.done:
            step.result = {"duration": elapsed, "distance": travelled, "altitude_rms": self.stats.rms("altitude"),
                           "altitude_max": self.stats.maxima["altitude"]}
        return step
