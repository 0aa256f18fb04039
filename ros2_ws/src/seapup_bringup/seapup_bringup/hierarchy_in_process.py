"""The supervisory hierarchy (thesis sec. 4.2, fig. 4.3) flown in one process, in lockstep, without ROS.

The same pure cores the nodes wrap -- :class:`~seapup_control.navigation.Navigator`,
a task of :mod:`seapup_control.tasks`, the
:class:`~seapup_control.position_control.PositionController` and a velocity
controller made by name (:func:`seapup_common.controllers.create_controller`)
-- with the same parameters (the nodes' YAML files) and the graph's delays: the
task's setpoint from the estimate at t_k is used by the position controller from
t_{k+1} on (stamped t_k + T), and the velocity reference it makes at t_k is
stamped t_k + reference_delay x T into the velocity controller's
:class:`~seapup_common.contract.StampedReferences`, the queue the
``velocity_controller`` node keeps. So a task can be studied (and unit tested)
in seconds from any state. It is not the graph sample for sample (the task steps
at the estimate it is built from, after a warm-up hover); a whole mission flown
as the graph flies it, command for command, is
:func:`seapup_runs.mission_flight.run_mission`.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from seapup_common.contract import Command, Reference, StampedReferences
from seapup_common.controllers import ControllerSpec, create_controller
from seapup_common.parameters import load_node_parameters

__all__ = ["HierarchyRun", "node_parameters", "fly_hierarchy"]


def node_parameters(package: str, file: str, node: str) -> dict:
    """The ``ros__parameters`` of ``node`` in the installed ``<package>/config/<file>``."""
    from ament_index_python.packages import get_package_share_directory
    return load_node_parameters(Path(get_package_share_directory(package)) / "config" / file, node)


@dataclass
class HierarchyRun:
    """What happened, one row per control sample (SI, odom_ned / base_link_frd)."""

    t: np.ndarray             # (n,) [s]
    state: np.ndarray         # (n, 12) truth
    estimate: np.ndarray      # (n, 3) navigation position
    setpoint: np.ndarray      # (n, 4) x, y, z, yaw of the setpoint in force
    reference: np.ndarray     # (n, 4) velocity reference used (u, v, w, r)
    command: np.ndarray       # (n, 4) blade pitch [rad]
    altitude: np.ndarray      # (n,) altimeter reading (NaN when invalid)
    steps: list               # the task's TaskStep per sample
    task: object


def fly_hierarchy(make_task, controller: ControllerSpec, *, vehicle="baseline", environment=None, seed: int = 0,
                  state=None, duration: float = 600.0, warmup: float = 5.0) -> HierarchyRun:
    """Fly one task through navigator -> task -> position controller -> velocity controller -> simulator.

    Parameters
    ----------
    make_task : callable
        ``make_task(limits, estimate, altitude)`` -> a :class:`~seapup_control.tasks.Task`, called
        after ``warmup`` s of hovering (the navigation has converged by then).
    controller : ControllerSpec
        The velocity controller, by registered type (e.g. ``mfol`` with a self-test's document).
    environment : mapping, optional
        Environment overrides of the simulator (sensors, current, seabed).
    state : array_like (12,), optional
        Start state (default: at rest, 30 m deep).
    duration : float
        Simulated seconds after the task started at most; the run ends when the task is done.
    """
    from seapup_control.navigation import SHELL_PARAMETERS, Navigator, NavigatorParams
    from seapup_control.position_control import PoseReference, PositionController, PositionControllerParams
    from seapup_control.tasks import Hover, TaskLimits
    from seapup_sim.simulation import Simulation

    task_p = node_parameters("seapup_control", "task_controller.yaml", "task_controller")
    limits = TaskLimits.from_mapping(task_p["limits"])
    position_p = node_parameters("seapup_control", "position_controller.yaml", "position_controller")
    period = float(position_p["sample_period"])
    delay = int(position_p["reference_delay"])
    navigator_p = node_parameters("seapup_control", "navigator.yaml", "navigator")
    navigator = Navigator(NavigatorParams.from_mapping({k: v for k, v in navigator_p.items()
                                                        if k not in SHELL_PARAMETERS}))
    position = PositionController(PositionControllerParams.from_mapping(
        {k: position_p[k] for k in ("gains", "yaw_gain", "speed_limits", "max_yaw_rate", "acceleration_limits",
                                    "feedforward")}), period)
    start = np.r_[0.0, 0.0, 30.0, np.zeros(9)] if state is None else np.asarray(state, float)
    law = create_controller(controller, period)
    fallback = getattr(law, "fallback_command", None)
    pitch = np.asarray(fallback(), float) if fallback is not None else np.zeros(4)
    simulation = Simulation.from_config(vehicle, environment or {}, seed=seed, control_period=period, state=start,
                                 pitch=pitch)
    law.reset(Command(pitch))
    references = StampedReferences()            # velocity references stamped t + delay T, as the node keeps them
    pending: PoseReference | None = None        # the setpoint stamped t_k + T, used from t_{k+1}
    task, started, hover = None, None, None
    rows = {name: [] for name in ("t", "state", "estimate", "setpoint", "reference", "command", "altitude")}
    steps = []
    while True:
        sample = simulation.sample()
        t, measurement = sample.t, sample.measurement
        estimate = navigator.update(measurement)
        altitude = measurement.altitude if measurement.altitude.valid else None
        if pending is not None:
            position.set_reference(pending)
        if estimate is not None:
            if task is None and t >= warmup:
                task, started = make_task(limits, estimate, altitude), t
            if task is None and hover is None:
                hover = Hover(limits, estimate, hold_current=True)  # warm-up: hold where the filter starts
            step = (task or hover).step(t, estimate, altitude)
            pending = PoseReference(step.setpoint.position, step.setpoint.yaw, t + period)
            if task is not None:
                steps.append(step)
            references.add(position.update(estimate.position, estimate.attitude)
                           if position.reference is not None else Reference(), at=t + delay * period)
        else:
            references.add(Reference(), at=t + delay * period)
        reference = references.at(t)
        law.applied(t, Command(simulation.plant.pitch.copy(), t))
        command = law.update(t, measurement, reference)
        for name, value in (("t", t), ("state", sample.state), ("estimate", estimate.position if estimate else
                                                                  np.full(3, np.nan)),
                            ("setpoint", [*position.reference.position, position.reference.yaw]
                             if position.reference is not None else np.full(4, np.nan)),
                            ("reference", reference.velocity), ("command", command.blade_pitch),
                            ("altitude", float(altitude.value) if altitude is not None else np.nan)):
            rows[name].append(value)
        if task is not None and (steps[-1].done or t - started >= duration):
            break
        simulation.advance(command.blade_pitch)
    return HierarchyRun(**{k: np.asarray(v, float) for k, v in rows.items()}, steps=steps, task=task)
