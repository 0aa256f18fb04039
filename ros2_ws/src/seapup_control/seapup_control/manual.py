"""Manual flight: a pilot's stick as the velocity reference, a mode of the controller manager like the laws.

A pilot flies an ROV first by hand. Here the pilot's demand -- a ``geometry_msgs/Twist`` as every ROS
teleop tool sends it (REP-103: ``base_link`` forward-left-up, x forward, y left, z up, yaw counter-clockwise
seen from above), from ``./seapup teleop``'s keyboard or Foxglove's Teleop panel -- becomes the body-velocity
reference (u, v, w, r) in ``base_link_frd`` of the self-tested fixed-gain law (eq. 4.11, 5.6), which flies
it; the vehicle holds what the pilot asks as it holds a task's reference. The pilot's demand is

- **bounded**: each velocity within its limit (``max_speed`` u, v, w [m/s]; ``max_yaw_rate`` [rad/s]);
- **slewed**: each reference moves by at most its acceleration limit times the elapsed time a sample, so a
  key press is a ramp the thrusters can follow (as the position controller's references, sec. 8.3);
- **zeroed when the pilot goes silent**: a demand older than ``silence_timeout`` [s] (a dropped link, a
  crashed tool) no longer counts: the reference ramps to zero and the vehicle comes to rest;
- **taken and handed back without a bump**: switched in, the reference starts from the vehicle's measured
  velocity and the law from the applied inputs (bumpless, as every law); switched out, the task's position
  controller starts its own slew from the manual reference in force
  (:meth:`seapup_control.position_control.PositionController.reset`).

:class:`ManualPilot` is the pure reference logic; :class:`ManualLaw` wraps a self-tested MFOL law with it
(registered as ``manual``; its node subscribes ``pilot/cmd_vel`` and calls :meth:`ManualLaw.pilot`).
"""
from __future__ import annotations

import math
import types

import numpy as np

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT, INPUT_LIMIT_RANGE, VIRTUAL_INPUT_LIMIT
from seapup_common.contract import Command, ContractError, Measurement, Reference
from seapup_common.controllers import ControllerType, Ranged

__all__ = ["ManualPilot", "ManualLaw", "MANUAL_TYPE", "twist_to_body_velocity", "TeleopKeys", "TELEOP_HELP"]


def twist_to_body_velocity(linear, angular) -> np.ndarray:
    """(u, v, w, r) in ``base_link_frd`` of a ``Twist``'s linear (x, y, z) and angular (x, y, z) in ``base_link``
    (FLU: y left, z up, yaw counter-clockwise): u = x, v = -y, w = -z, r = -angular z.

    Raises
    ------
    ContractError
        If a component is not a finite number.
    """
    try:
        x, y, z = (float(v) for v in linear)
        _, _, yaw = (float(v) for v in angular)
    except (TypeError, ValueError):
        raise ContractError(f"a twist needs three linear and three angular numbers, got {linear!r}, {angular!r}") \
            from None
    if not all(math.isfinite(v) for v in (x, y, z, yaw)):
        raise ContractError(f"a twist must be finite, got linear {[x, y, z]}, angular z {yaw}")
    return np.array([x, -y, -z, -yaw])


class ManualPilot:
    """The pilot's demand as a bounded, slewed body-velocity reference that fades to rest when the pilot is
    silent (module docstring).

    Parameters
    ----------
    max_speed : sequence of 3 float
        Largest |u|, |v|, |w| [m/s].
    max_yaw_rate : float
        Largest |r| [rad/s].
    acceleration : sequence of 4 float
        Largest change per second of u, v, w [m/s^2] and r [rad/s^2].
    silence_timeout : float
        [s] after the pilot's last demand, the demand counts as zero.
    """

    def __init__(self, max_speed=(0.3, 0.15, 0.15), max_yaw_rate: float = 0.26,
                 acceleration=(0.05, 0.05, 0.05, 0.1), silence_timeout: float = 1.0):
        limits = np.array([*max_speed, max_yaw_rate], dtype=float)
        accel = np.array(acceleration, dtype=float)
        if limits.shape != (4,) or accel.shape != (4,) or not (np.all(np.isfinite(limits)) and np.all(limits > 0)
                                                              and np.all(np.isfinite(accel)) and np.all(accel > 0)):
            raise ValueError("manual flight needs 3 speeds, a yaw rate and 4 accelerations, finite and > 0")
        if not (math.isfinite(silence_timeout) and silence_timeout > 0):
            raise ValueError(f"silence_timeout must be finite and > 0 s, got {silence_timeout!r}")
        self.limits, self.acceleration, self.silence_timeout = limits, accel, float(silence_timeout)
        self.demand = np.zeros(4)
        self.demand_t: float | None = None   # when the pilot's last demand came [s]
        self.output = np.zeros(4)
        self.t: float | None = None
        self.refused = 0
        self.received = 0   # demands taken (a harness holding the graph waits for its own: diagnostics' pilot_received)

    def pilot(self, t: float, body_velocity) -> None:
        """The pilot's demand (u, v, w, r) at time ``t`` [s], bounded to the limits; a non-finite one is refused
        and counted (nothing changes)."""
        demand = np.asarray(body_velocity, dtype=float)
        if demand.shape != (4,) or not np.all(np.isfinite(demand)) or not math.isfinite(float(t)):
            self.refused += 1
            raise ContractError(f"a pilot demand needs 4 finite values and a finite time, got {body_velocity!r}")
        self.demand = np.clip(demand, -self.limits, self.limits)
        self.demand_t = float(t)
        self.received += 1

    def reset(self, t: float, velocity) -> None:
        """Take over at ``t`` from the vehicle moving at ``velocity`` (u, v, w, r): the reference starts there
        (bounded) and moves toward the pilot's demand from the next sample -- a stick already held when the
        controller comes in counts, an older one than ``silence_timeout`` is silence (:meth:`silent`)."""
        self.output = np.clip(np.asarray(velocity, dtype=float), -self.limits, self.limits)
        self.t = float(t)

    def silent(self, t: float) -> bool:
        """No demand yet, or the last one older than ``silence_timeout``."""
        return self.demand_t is None or t - self.demand_t > self.silence_timeout + 1e-9

    def reference(self, t: float) -> Reference:
        """The reference at ``t`` [s]: from the last one toward the pilot's demand (zero when silent) by at
        most the acceleration limits times the time since."""
        t = float(t)
        target = np.zeros(4) if self.silent(t) else self.demand
        dt = 0.0 if self.t is None else max(t - self.t, 0.0)
        step = self.acceleration * dt
        self.output = self.output + np.clip(target - self.output, -step, step)
        self.t = t
        return Reference(self.output)


class ManualLaw:
    """A self-tested MFOL law (eq. 4.11, 5.6) flying the pilot's reference instead of the task's: the
    ``manual`` mode of the controller manager (module docstring)."""

    def __init__(self, inner, pilot: ManualPilot):
        self.inner = inner
        self.manual = pilot
        self.sample_period = inner.sample_period
        self._take_over = True

    def reset(self, applied: Command) -> None:
        """Bumpless: the law from the applied inputs; the reference from the first sample's measured velocity."""
        self.inner.reset(applied)
        self._take_over = True

    def applied(self, t: float, command: Command) -> None:
        self.inner.applied(t, command)

    def pilot(self, t: float, linear, angular) -> None:
        """A ``Twist`` from the pilot at time ``t`` [s] (``base_link``, FLU); refused (counted) if malformed."""
        try:
            velocity = twist_to_body_velocity(linear, angular)
        except ContractError:
            self.manual.refused += 1
            raise
        self.manual.pilot(t, velocity)

    def update(self, t: float, measurement: Measurement, reference: Reference) -> Command:
        """The inner law on the pilot's reference (the task's ``reference`` is not used)."""
        if self._take_over:
            self.manual.reset(t, measurement.body_velocity())   # ContractError without a velocity: nothing changes
            self._take_over = False
        return self.inner.update(t, measurement, self.manual.reference(t))

    def diagnostics(self) -> dict:
        return {**self.inner.diagnostics(), "pilot_demand": self.manual.demand.tolist(),
                "pilot_silent": self.manual.silent(self.manual.t if self.manual.t is not None else 0.0),
                "pilot_refused": self.manual.refused, "pilot_received": self.manual.received}


def create_manual(parameters: dict, document, sample_period: float | None) -> ManualLaw:
    """The ``manual`` controller type's factory: the document's fixed gains (its zero-speed point) flying the
    pilot's reference."""
    from seapup_control.mfol_controller import create_mfol
    inner = create_mfol({"schedule": False, "anti_windup": True, "blade_pitch_limit": parameters["blade_pitch_limit"]},
                        document, sample_period)
    return ManualLaw(inner, ManualPilot(parameters["max_speed"], parameters["max_yaw_rate"],
                                        parameters["acceleration_limits"], parameters["silence_timeout"]))


#: Manual flight: the pilot's Twist as the reference of the self-tested fixed gains (registered as ``manual``).
MANUAL_TYPE = ControllerType(
    "manual", create_manual, types.MappingProxyType({
        "max_speed": Ranged([0.3, 0.15, 0.15], 0.01, 2.0, "the position controller's default speed limits; 2 m/s: "
                                                           "beyond any small ROV"),
        "max_yaw_rate": Ranged(0.26, 0.01, 3.0, "the position controller's default; 3 rad/s: beyond any small ROV"),
        "acceleration_limits": Ranged([0.05, 0.05, 0.05, 0.1], 0.001, 10.0,
                                      "per second, the position controller's defaults (sec. 8.3: references the "
                                      "thrusters can follow)"),
        "silence_timeout": Ranged(1.0, 0.1, 60.0, "[s] a teleop tool sends at 10 Hz or more: 1 s is ten lost "
                                                  "messages"),
        "blade_pitch_limit": Ranged(BLADE_PITCH_LIMIT, 0.01, VIRTUAL_INPUT_LIMIT, INPUT_LIMIT_RANGE)}),
    "manual flight: a pilot's Twist (pilot/cmd_vel, REP-103) bounded, slewed and zeroed when silent, as the "
    "reference of a self-test's fixed gains (eq. 4.11)", needs_document=True)


#: ``./seapup teleop``'s keys: (Twist field, sign) in ``base_link`` (REP-103: x forward, y left, z up, yaw
#: counter-clockwise); each press moves that demand by one step, space zeroes every demand.
_KEY_FIELDS = {"w": ("linear.x", 1), "s": ("linear.x", -1), "a": ("linear.y", 1), "d": ("linear.y", -1),
               "r": ("linear.z", 1), "f": ("linear.z", -1), "q": ("angular.z", 1), "e": ("angular.z", -1)}
TELEOP_HELP = ("w/s forward/astern, a/d left/right, r/f up/down, q/e turn left/right (each press one step), "
               "space: stop, x: quit")


class TeleopKeys:
    """A keyboard's demand for ``./seapup teleop``: each key press steps one Twist component (``linear_step``
    [m/s], ``angular_step`` [rad/s]) within +-``max_linear`` / ``max_angular``; space zeroes all; ``x`` (or
    Ctrl-C, Ctrl-D) quits. Pure: the node publishes :attr:`twist` at its rate."""

    def __init__(self, linear_step: float = 0.05, angular_step: float = 0.05, max_linear: float = 0.5,
                 max_angular: float = 0.5):
        values = (linear_step, angular_step, max_linear, max_angular)
        if not all(math.isfinite(v) and v > 0 for v in values):
            raise ValueError(f"teleop steps and limits must be finite and > 0, got {values}")
        self.linear_step, self.angular_step = float(linear_step), float(angular_step)
        self.max_linear, self.max_angular = float(max_linear), float(max_angular)
        self.twist = {"linear.x": 0.0, "linear.y": 0.0, "linear.z": 0.0, "angular.z": 0.0}
        self.quit = False

    def press(self, key: str) -> bool:
        """Apply one key; True if it changed anything (an unknown key changes nothing)."""
        if key in ("x", "X", "\x03", "\x04"):
            self.quit = True
            return True
        if key == " ":
            changed = any(self.twist.values())
            self.twist = dict.fromkeys(self.twist, 0.0)
            return changed
        if key.lower() not in _KEY_FIELDS:
            return False
        name, sign = _KEY_FIELDS[key.lower()]
        angular = name.startswith("angular")
        step, top = (self.angular_step, self.max_angular) if angular else (self.linear_step, self.max_linear)
        value = round(min(max(self.twist[name] + sign * step, -top), top), 9)
        changed, self.twist[name] = value != self.twist[name], value
        return changed

    def linear(self) -> tuple:
        return self.twist["linear.x"], self.twist["linear.y"], self.twist["linear.z"]

    def angular(self) -> tuple:
        return 0.0, 0.0, self.twist["angular.z"]
