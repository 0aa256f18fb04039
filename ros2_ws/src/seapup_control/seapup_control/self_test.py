"""The self-test: a supervisory procedure that designs the autopilot from step tests (sec. 4.5.2, 5.3).

Two cycles over the four thrusters (sec. 4.5.2). In each test the vehicle is
first made quiescent, then one thruster is stepped by ``step`` about the
quiescent setting and held for ``samples`` samples while (u, v, w, r) are
logged; each channel is fitted with a first-order lag
(:func:`~seapup_control.step_identification.fit_first_order`), giving column j
of B0^-1 and B1^-1 (eq. 4.23-4.24).

- Cycle 1 is open loop: quiescence is waited for with every thruster at its
  zero level, until the total speed falls under a threshold (``auto``: the
  settled drift speed at the zero level x 1.2 + 0.01 m/s; the Seapup drifts
  at zero pitch, sec. 5.3). Its model gives a first controller.
- Cycle 2 waits for quiescence under that controller (reference zero, a
  threshold ``closed_loop_divisor`` times smaller), stepping about the
  setting the controller holds, which is no longer the zero level; its model
  gives the final controller at zero speed (offset u0: that setting).
- Further operating points (e.g. 0.7 m/s, sec. 5.3.1) are reached under the
  controller designed so far and tested about the setting that holds them
  (eq. 5.4-5.5); the controllers make a :class:`~seapup_control.mfol_controller.GainSchedule`.
- ``artificial`` mode (sec. 5.3.2) asks the driver to reset the plant to the
  operating point before every step (:attr:`SelfTest.reset_request`,
  :meth:`SelfTest.plant_reset`) instead of waiting for quiescence.

:class:`SelfTest` is a :class:`~seapup_common.contract.VelocityController`:
the caller feeds it measurements every sample and holds the commands it
returns; it never sees the plant's truth. When it has finished, failed or
been cancelled it flies the best controller it has at zero reference (hover),
or holds the zero level if it has none.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path

import numpy as np
import yaml

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT, THRUSTER_NAMES
from seapup_common.config import ConfigError, ConfigView, load_yaml, merge
from seapup_common.contract import Command, Measurement, Reference
from seapup_control.mfol import DesignError, LoopPoles, MFOLModel, TwoTermGains, design, equilibrated_condition
from seapup_control.mfol_controller import GainSchedule, MFOLController
from seapup_control.step_identification import IdentificationError, fit_first_order

__all__ = ["vehicle_self_test", "write_result_file", "FITS", "Phase", "SelfTestConfig", "goal_overrides", "StepTest", "OperatingPoint", "SelfTest", "fit_operating_point",
           "result_document", "refit", "tests_from_samples", "DEFAULTS_FILE"]

#: The defaults (every key documented there).
DEFAULTS_FILE = Path(__file__).with_name("data") / "self_test.yaml"


FITS = ("deviation", "raw")   # StepTest.column: eq. 5.5's y - y0, or the raw outputs (the thesis's Table 5.2)


class Phase(str, Enum):
    DRIFT = "drift"            # cycle 1, auto threshold: letting the vehicle settle at the zero level
    QUIESCE = "quiesce"        # waiting for quiescence (or for an operating point)
    RESET = "reset"            # artificial mode: waiting for the driver to reset the plant
    STEP = "step"              # a thruster stepped, outputs logged
    DONE = "done"
    FAILED = "failed"
    CANCELLED = "cancelled"


#: The ``seapup_msgs/action/SelfTest`` goal fields that are settings (zero: the default of ``data/self_test.yaml``).
GOAL_SETTINGS = ("sample_period", "step", "quiescence_speed", "closed_loop_divisor", "max_wait")


def goal_overrides(goal) -> dict:
    """A self-test goal's non-default fields as self-test settings (zero / empty: the default).

    ``goal``: a ``seapup_msgs/action/SelfTest`` goal, or a mapping of its fields (a mission's self-test leg).

    Examples
    --------
    >>> goal_overrides({"operating_points": [0.0, 0.7], "step": 0.0})
    {'operating_points': [0.0, 0.7]}
    """
    get = goal.get if isinstance(goal, Mapping) else (lambda name, default: getattr(goal, name, default))
    overrides = {}
    for name in GOAL_SETTINGS:
        value = float(get(name, 0.0) or 0.0)
        if value != 0.0:
            overrides[name] = value
    if get("samples", 0):
        overrides["samples"] = int(get("samples", 0))
    points = get("operating_points", ())
    if len(points):
        overrides["operating_points"] = [float(v) for v in points]
    for name in ("poles_k", "poles_c"):   # the operator's closed-loop poles (sec. 5.2), at 5 Hz
        poles = get(name, ())
        if len(poles):
            overrides[name] = [float(v) for v in poles]
    return overrides

@dataclass(frozen=True)
class SelfTestConfig:
    """The self-test's settings (defaults in ``data/self_test.yaml``; see :meth:`load`)."""

    sample_period: float
    step: float
    samples: int
    quiescence_speed: float | None      # None: auto (from the drift)
    closed_loop_divisor: float
    drift_tolerance: float
    drift_window: float
    drift_noise_sigmas: float
    max_wait: float
    operating_points: tuple[float, ...]
    reach_tolerance: float
    zero_level: np.ndarray
    mode: str
    poles: LoopPoles
    settle: bool
    max_condition: float
    limit: float = BLADE_PITCH_LIMIT
    fit: str = "deviation"     # "deviation" (eq. 5.5) or "raw" (the thesis's Table 5.2 at 0.7 m/s)

    @classmethod
    def load(cls, overrides: Mapping | None = None, limit: float = BLADE_PITCH_LIMIT) -> "SelfTestConfig":
        """The defaults with ``overrides`` merged over them, checked.

        Raises
        ------
        ConfigError
            Naming the key and the allowed range.
        """
        view = ConfigView(merge(load_yaml(DEFAULTS_FILE), dict(overrides or {}), strict="self-test settings"),
                          "self-test settings")
        period = view.number("sample_period", lo=1e-3, hi=10.0)
        quiescence = view.get("quiescence_speed")
        if quiescence != "auto":
            quiescence = view.number("quiescence_speed", lo=1e-4, hi=2.0)
        else:
            quiescence = None
        speeds = tuple(float(s) for s in view.vector("operating_points", lo=-2.0, hi=2.0))
        if not speeds or speeds[0] != 0.0 or len(set(speeds)) != len(speeds):
            raise ConfigError("self-test settings: operating_points must start with 0.0 and be distinct, "
                              f"got {list(speeds)}")
        poles = LoopPoles(view.vector("poles_k", 4), view.vector("poles_c", 4),
                          view.number("poles_sample_period", lo=1e-3, hi=10.0))
        if not math.isclose(poles.sample_period, period):
            poles = poles.at_rate(period)  # eq. 5.1: the same continuous poles at this rate
        step = view.number("step", lo=math.radians(0.5), hi=limit)
        return cls(period, step, view.integer("samples", lo=5, hi=100_000), quiescence,
                   view.number("closed_loop_divisor", lo=1.0, hi=1000.0),
                   view.number("drift_tolerance", lo=1e-6, hi=1.0), view.number("drift_window", lo=period, hi=600.0),
                   view.number("drift_noise_sigmas", lo=0.0, hi=10.0),
                   view.number("max_wait", lo=period, hi=36_000.0), speeds,
                   view.number("reach_tolerance", lo=1e-4, hi=1.0),
                   view.vector("zero_level", 4, lo=-limit, hi=limit),
                   view.choice("mode", ("realistic", "artificial")), poles, view.flag("settle"),
                   view.number("max_condition", lo=1.0, hi=1e12), float(limit), view.choice("fit", FITS))


def write_result_file(directory: Path, document: Mapping, now: float | None = None) -> Path:
    """Write a self-test result ``document`` as a new YAML file in ``directory`` and return its path:
    ``self_test_<UTC time>_<process id>.yaml``, created exclusively (``_2``, ``_3`` ... appended while the name is
    taken). Two self-tests finishing in the same second -- two graphs of a test run side by side -- once wrote
    one file, and a graph's controllers were configured from the other's result."""
    import os
    import time as _time
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    stem = _time.strftime("self_test_%Y%m%d_%H%M%S", _time.gmtime(now)) + f"_{os.getpid()}"
    text = yaml.safe_dump(dict(document), sort_keys=False)
    for n in range(1, 1000):
        path = directory / (f"{stem}.yaml" if n == 1 else f"{stem}_{n}.yaml")
        try:
            with open(path, "x", encoding="utf-8") as f:
                f.write(text)
            return path
        except FileExistsError:
            continue
    raise OSError(f"no free result file name {stem}_N.yaml in {directory}")


def vehicle_self_test(vehicle_config: Mapping, overrides: Mapping | None = None) -> dict:
    """The self-test settings of a vehicle: its description's ``self_test`` section (the operator's choices for
    that vehicle: step size, poles, ...) with ``overrides`` (a goal's, a command line's) over them; the defaults
    of ``data/self_test.yaml`` under both (:meth:`SelfTestConfig.load`)."""
    section = vehicle_config.get("self_test") or {}
    if not isinstance(section, Mapping):
        raise ConfigError(f"vehicle configuration {vehicle_config.get('name', '')!r}: self_test must be a mapping "
                          "of self-test settings")
    return {**section, **dict(overrides or {})}


@dataclass
class StepTest:
    """One thruster's step test: the raw data the fit is made from (kept for refits from bags)."""

    cycle: int
    surge: float               # operating point [m/s]
    thruster: int              # 0..3, BladePitch order
    start_time: float          # [s] when the step was applied
    quiescent_input: np.ndarray
    step: float                # [rad]
    equilibrium: np.ndarray    # outputs the quiescent input holds: y0 of eq. 5.5
    outputs: list = field(default_factory=list)  # (u, v, w, r) at the step and each sample after

    def column(self, sample_period: float, fit: str = "deviation") -> tuple[np.ndarray, np.ndarray]:
        """Column ``thruster`` of (B0^-1, B1^-1): each output's fitted g and g / (1 - f) per rad (eq. 4.24).

        ``fit="deviation"``: deviations are taken from the equilibrium of the quiescent input (eq. 5.5), not
        from the output at the step: a test that starts before the vehicle is fully at rest then still fits
        its own free decay. ``fit="raw"``: the raw outputs against the input's step (y0 = 0), the thesis's
        procedure as its Table 5.2 reads at 0.7 m/s (:data:`FITS`).
        """
        if fit not in FITS:
            raise IdentificationError(f"fit must be one of {', '.join(FITS)}, got {fit!r}")
        y = np.asarray(self.outputs, float)
        u = np.full(len(y), self.quiescent_input[self.thruster] + self.step)
        initial, final = np.empty(4), np.empty(4)
        for i in range(4):
            lag = fit_first_order(y[:, i], u, sample_period, y0=self.equilibrium[i] if fit == "deviation" else 0.0,
                                  u0=self.quiescent_input[self.thruster])
            initial[i], final[i] = lag.initial_response, lag.steady_state_gain
        return initial, final


@dataclass(frozen=True)
class OperatingPoint:
    """What the self-test found about one surge speed."""

    surge: float
    model: MFOLModel
    gains: TwoTermGains
    cycle: int


def fit_operating_point(tests: list[StepTest], sample_period: float, poles: LoopPoles,
                        max_condition: float = math.inf, fit: str = "deviation") -> OperatingPoint:
    """The MFOL model and controller from one set of four step tests (eq. 4.20-4.24, 5.5, 4.11), each
    step fitted as ``fit`` says (:meth:`StepTest.column`).

    The offset u0 is the mean quiescent setting of the tests (the setting that
    holds the operating point, eq. 5.6); y0 = (surge, 0, 0, 0).

    ``max_condition`` bounds the row-equilibrated condition number of B0^-1
    and B1^-1 (:func:`~seapup_control.mfol.equilibrated_condition`): the
    thesis needs |B0| != 0 (eq. 4.9), but fitted data are never exactly
    singular. A thruster that does not work still "responds" with whatever
    the vehicle was doing anyway (the rest of its drift), so its column is
    small but not zero, and the design would put a huge gain on it. Beyond
    the bound the model counts as singular.

    Raises
    ------
    IdentificationError, DesignError
        If a channel cannot be fitted or the model admits no controller.
    """
    by_thruster = {t.thruster: t for t in tests}
    if sorted(by_thruster) != [0, 1, 2, 3]:
        raise IdentificationError(f"an operating point needs a test of each thruster, got {sorted(by_thruster)}")
    b0inv, b1inv = np.empty((4, 4)), np.empty((4, 4))
    for j, test in by_thruster.items():
        b0inv[:, j], b1inv[:, j] = test.column(sample_period, fit)
    surge = tests[0].surge
    for name, matrix in (("B0^-1", b0inv), ("B1^-1", b1inv)):
        condition, weakest = equilibrated_condition(matrix)
        if not condition <= max_condition:
            raise DesignError(
                f"{name} is singular to the test's resolution at {surge:g} m/s (condition number {condition:.3g} "
                f"with each output scaled, limit {max_condition:g}): thruster {weakest} "
                f"({THRUSTER_NAMES[weakest]}) moved "
                + ("no output; " if math.isinf(condition) else "no output much beyond the vehicle's own drift; ")
                + "is it dead, disconnected or fouled?")
    u0 = np.mean([t.quiescent_input for t in tests], axis=0)
    model = MFOLModel(b0inv, b1inv, sample_period, y0=[surge, 0.0, 0.0, 0.0], u0=u0)
    return OperatingPoint(surge, model, design(model, poles), tests[0].cycle)


class SelfTest:
    """The self-test as a sampled supervisor (see the module docstring).

    Parameters
    ----------
    config : SelfTestConfig

    Attributes
    ----------
    phase : Phase
    cycle, thruster, surge : the test in progress (1-based cycle, 0-based thruster)
    points : list of OperatingPoint
        The final point per speed once done (cycle 2 replaces cycle 1's at 0 m/s).
    tests : list of StepTest
        Every test's raw data.
    last_logged : list of int
        Indices in ``tests`` of the tests the last sample's outputs went into
        (two when one test ends and the next starts at the same sample).
    reason : str
        Why it failed ("" otherwise).
    """

    def __init__(self, config: SelfTestConfig):
        self.config = config
        self.sample_period = config.sample_period
        self.plan = ([(1, 0.0, j) for j in range(4)] + [(2, 0.0, j) for j in range(4)]
                     + [(2, s, j) for s in config.operating_points[1:] for j in range(4)])
        self.tests: list[StepTest] = []
        self.points: list[OperatingPoint] = []
        self.controller: MFOLController | None = None
        self.threshold = config.quiescence_speed
        self.reason = ""
        self.start_time: float | None = None
        self.end_time: float | None = None
        self.reset_request: float | None = None
        self.last_logged: list[int] = []  # indices in ``tests`` of the tests the last sample was logged into
        self._applied = config.zero_level.copy()
        self._next = 0
        self._phase_start = 0.0
        self._last_t = 0.0
        self._drift: np.ndarray | None = None  # settled outputs at the zero level
        self._log_sigma = 0.0   # the velocity log's noise standard deviation, from its readings
        self._window: list[tuple[float, np.ndarray]] = []   # (t, outputs) over drift_window, for the settling test
        self._current: StepTest | None = None
        self.phase = Phase.DRIFT if self.threshold is None else Phase.QUIESCE

    # -- what the action reports ------------------------------------------------------
    @property
    def test_in_progress(self) -> tuple[int, float, int]:
        cycle, surge, thruster = self.plan[min(self._next, len(self.plan) - 1)]
        return cycle, surge, thruster

    @property
    def progress(self) -> float:
        """Fraction of the step tests done (the one under way counted by its samples)."""
        if self.phase == Phase.DONE:
            return 1.0
        partial = len(self._current.outputs) / (self.config.samples + 1) if self._current else 0.0
        return min((self._next + partial) / len(self.plan), 1.0)

    @property
    def finished(self) -> bool:
        return self.phase in (Phase.DONE, Phase.FAILED, Phase.CANCELLED)

    @property
    def duration(self) -> float:
        """Time from the first sample to the end (or to now) [s]."""
        if self.start_time is None:
            return 0.0
        return (self.end_time if self.end_time is not None else self._last_t) - self.start_time

    def schedule(self) -> GainSchedule | None:
        return GainSchedule([(p.surge, p.gains) for p in self.points]) if self.points else None

    # -- the controller contract ------------------------------------------------------
    def reset(self, applied: Command) -> None:
        """Start from the applied command (held until the first decision)."""
        self._applied = np.asarray(applied.blade_pitch, float).copy()

    def cancel(self, reason: str = "cancelled") -> None:
        """Stop testing; from now on hover under the best controller (or hold the zero level)."""
        if not self.finished:
            self._finish(Phase.CANCELLED, reason)

    def abort(self, reason: str) -> None:
        """Fail the run from outside (e.g. its node gets no velocity data); then hover as after any failure."""
        if not self.finished:
            self._finish(Phase.FAILED, reason)

    def plant_reset(self, applied: Command) -> None:
        """Artificial mode: the driver has reset the plant to the operating point, holding ``applied``."""
        if self.phase != Phase.RESET:
            raise RuntimeError(f"no reset was requested (phase {self.phase.value})")
        self.reset_request = None
        self._applied = np.asarray(applied.blade_pitch, float).copy()
        self._start_step(self._last_t, None)

    def update(self, t: float, measurement: Measurement, reference: Reference | None = None) -> Command:
        """One sample: decide, log, and return the command to hold (the reference is not used)."""
        y = measurement.body_velocity()  # ContractError on an invalid reading: nothing changes
        self._log_sigma = math.sqrt(float(np.max(measurement.velocity.variance)))
        t = float(t)
        if self.start_time is None:
            self.start_time = self._phase_start = t
        self._last_t = t
        self.last_logged = []
        try:
            command = self._decide(t, y)
        except (IdentificationError, DesignError) as exc:
            self._finish(Phase.FAILED, f"{type(exc).__name__}: {exc}")
            command = self._hover(t, y)
        self._applied = np.clip(command, -self.config.limit, self.config.limit)
        return Command(self._applied, stamp=t)

    # -- the procedure -----------------------------------------------------------------
    def _decide(self, t: float, y: np.ndarray) -> np.ndarray:
        if self.finished:
            return self._hover(t, y)
        if self.phase == Phase.DRIFT:
            if self._settled(t, y):
                self._drift = np.mean([v for _, v in self._window], axis=0)  # the window's mean: noise averaged
                self.threshold = 1.2 * float(np.linalg.norm(self._drift[:3])) + 0.01
                self._enter(Phase.QUIESCE, t)
            else:
                self._check_wait(t, y, "the drift at the zero level did not settle")
            return self.config.zero_level.copy()
        if self.phase == Phase.RESET:
            return self._applied.copy()
        if self.phase == Phase.STEP:
            return self._log_step(t, y)
        return self._quiesce(t, y)

    def _quiesce(self, t: float, y: np.ndarray) -> np.ndarray:
        cycle, surge, _ = self.test_in_progress
        if self.config.mode == "artificial":
            self.reset_request = surge
            self._enter(Phase.RESET, t)
            return self._applied.copy()
        open_loop = cycle == 1
        command = (self.config.zero_level.copy() if open_loop
                   else self.controller.update(t, self._measurement(t, y), Reference([surge, 0, 0, 0])).blade_pitch)
        settled = self._settled(t, y)  # also required: the vehicle, and so the setting held, has stopped changing
        if open_loop:
            quiet = np.linalg.norm(y[:3]) < self.threshold
        elif surge == 0.0:
            quiet = np.linalg.norm(y[:3]) < self.threshold / self.config.closed_loop_divisor
        else:
            quiet = bool(np.all(np.abs(y - [surge, 0, 0, 0]) < self.config.reach_tolerance))
        quiet = quiet and (settled or not self.config.settle)
        if quiet:
            # step about what is held now: the zero level, or the controller's setting at quiescence
            self._start_step(t, y, quiescent=command)
            return self._log_step(t, y)
        self._check_wait(t, y, f"no quiescence at {surge:g} m/s")
        return command

    def _start_step(self, t: float, y, quiescent=None) -> None:
        cycle, surge, thruster = self.test_in_progress
        base = np.asarray(self._applied if quiescent is None else quiescent, float).copy()
        stepped = base[thruster] + self.config.step
        if abs(stepped) > self.config.limit:
            raise DesignError(f"thruster {thruster} would saturate: {math.degrees(base[thruster]):.1f} deg + "
                              f"{math.degrees(self.config.step):.1f} deg step exceeds the "
                              f"{math.degrees(self.config.limit):.0f} deg limit")
        if cycle == 1 and self.config.mode == "realistic":
            # open loop: the zero level holds the settled drift (or, without it, where we are)
            equilibrium = self._drift if self._drift is not None else np.asarray(y if y is not None else 0.0)
        else:  # the controller, or the artificial reset's trim, holds the operating point
            equilibrium = np.array([surge, 0.0, 0.0, 0.0])
        self._current = StepTest(cycle, surge, thruster, t, base, self.config.step,
                                 np.broadcast_to(np.asarray(equilibrium, float), (4,)).copy())
        self.tests.append(self._current)
        self._enter(Phase.STEP, t)

    def _log_step(self, t: float, y: np.ndarray) -> np.ndarray:
        test = self._current
        test.outputs.append(y.copy())
        self.last_logged.append(len(self.tests) - 1)
        if len(test.outputs) <= self.config.samples:
            command = test.quiescent_input.copy()
            command[test.thruster] += test.step
            return command
        self._current = None
        self._next += 1
        done_point = self._next == len(self.plan) or self.plan[self._next][:2] != (test.cycle, test.surge)
        if done_point:
            point_tests = [s for s in self.tests if (s.cycle, s.surge) == (test.cycle, test.surge)][-4:]
            point = fit_operating_point(point_tests, self.sample_period, self.config.poles,
                                        self.config.max_condition, self.config.fit)
            self.points = [p for p in self.points if p.surge != point.surge] + [point]
            self.points.sort(key=lambda p: p.surge)
            self.controller = MFOLController(self.schedule(), limit=self.config.limit)
            self.controller.reset(Command(test.quiescent_input))  # bumpless: from the setting held before
        if self._next == len(self.plan):
            self._finish(Phase.DONE, "")
            return self._hover(t, y)
        self._enter(Phase.QUIESCE, t)
        return self._quiesce(t, y)

    # -- helpers ----------------------------------------------------------------------
    def _hover(self, t: float, y: np.ndarray) -> np.ndarray:
        if self.controller is None:
            return self.config.zero_level.copy()
        return self.controller.update(t, self._measurement(t, y), Reference()).blade_pitch

    @staticmethod
    def _measurement(t: float, y: np.ndarray) -> Measurement:
        return Measurement.build(t, velocity=y[:3], rates=(0.0, 0.0, y[3]))

    def _settled(self, t: float, y: np.ndarray) -> bool:
        """Has the speed stopped changing? Its range over ``drift_window`` is under the tolerance.

        The tolerance is ``drift_tolerance`` plus ``drift_noise_sigmas`` standard
        deviations of the log's white noise (the reading's own variance, sec.
        6.5.1): the range of eleven noise samples exceeds 5 sigma in 2 % of
        windows, so noisy logs cannot hold the test open forever, while a drift
        or an oscillation larger than the noise still fails it. Noise-free logs
        (variance 0) get the tolerance alone.
        """
        self._window.append((t, np.asarray(y, float).copy()))
        window = self.config.drift_window
        while self._window and self._window[0][0] < t - window - 1e-9:
            self._window.pop(0)
        if t - self._phase_start < window:
            return False
        speeds = np.linalg.norm([v[:3] for _, v in self._window], axis=1)
        allowance = self.config.drift_tolerance + self.config.drift_noise_sigmas * self._log_sigma
        return float(speeds.max() - speeds.min()) < allowance

    def _check_wait(self, t: float, y: np.ndarray, what: str) -> None:
        if t - self._phase_start > self.config.max_wait:
            raise IdentificationError(f"{what} within {self.config.max_wait:g} s "
                                      f"(speed {np.linalg.norm(y[:3]):.3f} m/s)")

    def _enter(self, phase: Phase, t: float) -> None:
        self.phase = phase
        self._phase_start = t
        self._window.clear()

    def _finish(self, phase: Phase, reason: str) -> None:
        self.phase = phase
        self.reason = reason
        self.end_time = getattr(self, "_last_t", self.start_time)
        self.reset_request = None


def tests_from_samples(samples, sample_period: float | None = None) -> list[StepTest]:
    """The step tests of a run rebuilt from its per-sample records (``seapup_msgs/SelfTestSample`` as dicts).

    Each record with ``test_index >= 0`` is one output of that test; the
    tests come back in index order with their outputs in time order. With
    ``sample_period`` [s] a test's records must be one period apart.

    Raises
    ------
    IdentificationError
        If the indices have gaps or a test's records do (samples lost from
        the record), or a test's records disagree about what it was.
    """
    grouped: dict[int, list[dict]] = {}
    for record in samples:
        if int(record["test_index"]) >= 0:
            grouped.setdefault(int(record["test_index"]), []).append(record)
    if sorted(grouped) != list(range(len(grouped))):
        raise IdentificationError(f"the record misses step tests: indices {sorted(grouped)}")
    tests = []
    for index in range(len(grouped)):
        records = sorted(grouped[index], key=lambda r: r["t"])
        first = records[0]
        if sample_period is not None:
            steps = np.diff([r["t"] for r in records]) / sample_period
            if np.any(np.abs(steps - 1.0) > 1e-6):
                k = int(np.argmax(np.abs(steps - 1.0)))
                raise IdentificationError(f"step test {index}: its records jump from t = {records[k]['t']:.3f} s "
                                          f"to {records[k + 1]['t']:.3f} s (samples lost from the record)")
        keys = {(r["cycle"], r["surge"], r["thruster"], r["step"]) for r in records}
        if len(keys) != 1:
            raise IdentificationError(f"step test {index}: its records disagree about it")
        tests.append(StepTest(int(first["cycle"]), float(first["surge"]), int(first["thruster"]), float(first["t"]),
                              np.asarray(first["quiescent_input"], float), float(first["step"]),
                              np.asarray(first["equilibrium"], float),
                              [np.asarray(r["velocity"], float) for r in records]))
    return tests


def refit(tests: list[StepTest], sample_period: float, poles: LoopPoles,
          max_condition: float = math.inf, fit: str = "deviation") -> list[OperatingPoint]:
    """The operating points a run's logged step tests give: for each surge speed its last four tests
    (cycle 2 replaces cycle 1 at 0 m/s), fitted as live (:func:`fit_operating_point`, ``fit`` as there)."""
    points = {}
    for surge in dict.fromkeys(t.surge for t in tests):
        last = [t for t in tests if t.surge == surge][-4:]
        if len(last) == 4 and len({t.cycle for t in last}) == 1:
            points[surge] = fit_operating_point(last, sample_period, poles, max_condition, fit)
    return [points[s] for s in sorted(points)]


def result_document(test: SelfTest) -> dict:
    """The self-test's result as plain data (the controller file; ``GainSchedule.from_document`` reads it).

    SI units and radians; matrices as lists of rows; outputs (u, v, w, r),
    inputs in ``BladePitch`` order.
    """
    return {"kind": "seapup/mfol_controller", "version": 1, "sample_period": test.sample_period,
            "phase": test.phase.value, "reason": test.reason, "duration": test.duration,
            "quiescence_speed": test.threshold,
            "poles": {"k": test.config.poles.k.tolist(), "c": test.config.poles.c.tolist()},
            "operating_points": [{"surge": p.surge, "cycle": p.cycle, "B0inv": p.model.B0inv.tolist(),
                                  "B1inv": p.model.B1inv.tolist(), "y0": p.model.y0.tolist(),
                                  "u0": p.model.u0.tolist(), "K_int": p.gains.K_int.tolist(),
                                  "K_err": p.gains.K_err.tolist()} for p in test.points]}
