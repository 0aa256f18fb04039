"""A run spec as a ROS graph: the one function that turns a :class:`~seapup_runs.spec.RunSpec` into nodes
and their parameters (pure data in the graph-file format of ``./seapup launch``; nothing is started here).

The graph flies in lockstep and equals the in-process run sample for sample:

- ``simulator``: the vehicle, dynamics, seed, start depth, control period
  and physics step of the spec, its environment overrides, its plant
  events as the ``events`` parameter (each lands on its physics step,
  whatever the transport), and ``end_time``: it flies no further than the
  spec's duration;
- one ``velocity_controller`` per entry of the spec's controller timeline
  (``controller_0``, ``controller_1``, ...), each flying its registered type
  over the window of simulated time it is in charge of (``start_at``,
  ``stop_at``): the switch falls on its sample and the incoming law starts
  bumpless from the applied pitch stamped with it, as :func:`~seapup_runs.runner.run` does;
- ``reference_schedule``: the spec's reference profile, one reference per
  sample stamped with it, each controller waiting for the one of its sample
  (``first_reference_wait``, ``reference_every_sample``).

Who must hear the first sample, command and reference is not written here: the launcher derives it from
these nodes' lockstep roles and the harness's listeners (:mod:`seapup_common.lockstep.roster`), e.g. with
two controllers and one probe the simulator waits for three subscribers of the velocity, each controller's
first command for the simulator and the probe, the first reference for both controllers and the probe.

``seapup_bringup.graph.graph_runner.run_on_graph`` writes this document to a file
and starts it through the SIL harness.
"""
from __future__ import annotations

import yaml

from seapup_common import topics
from seapup_runs.spec import RunSpec, RunSpecError

__all__ = ["graph_document", "controller_nodes", "LISTENED_TOPICS", "REFERENCE_WAIT"]

#: What a run's series are read from: a listener of the run (a probe, a recorder) subscribes to these, the
#: commands and the references, and the graph's first messages wait for it (its lockstep roster).
LISTENED_TOPICS = [topics.TRUTH_ODOMETRY, topics.VELOCITY, topics.IMU, topics.DEPTH, topics.POSITION,
                   topics.ALTITUDE, topics.APPLIED, topics.COMMAND, topics.VELOCITY_REFERENCE]
#: [s wall] how long a sample waits for its reference or applied pitch before going on (counted
#: late): generous, since a lockstep run must not depend on how busy the machine is.
REFERENCE_WAIT = 10.0


def controller_nodes(spec: RunSpec, files: list[str]) -> list[dict]:
    """A ``velocity_controller`` node per controller of the spec's timeline (``files[i]``: its design
    document's path, "" for none)."""
    from seapup_common.controllers import controller_type

    timeline = spec.controller_timeline()
    if len(files) != len(timeline):
        raise RunSpecError(f"{len(timeline)} controllers need {len(timeline)} files (or ''), got {len(files)}")
    from seapup_runs.runner import at_vehicle_limit
    from seapup_sim.vehicle import VehicleModel
    limit = VehicleModel(spec.vehicle_config()).pitch_limit   # the laws saturate where the vehicle does
    nodes = []
    for i, (start, controller) in enumerate(timeline):
        stop = timeline[i + 1][0] if i + 1 < len(timeline) else 0.0
        controller = at_vehicle_limit(controller, limit)
        kind = controller_type(controller.type)
        parameters = {"controller_type": controller.type, "controller_file": files[i],
                      "sample_period": spec.control_period, "lockstep": True, "autostart": True,
                      "start_at": float(start), "stop_at": float(stop), "first_reference_wait": REFERENCE_WAIT,
                      "reference_every_sample": True, "reference_wait": REFERENCE_WAIT,
                      "applied_wait": REFERENCE_WAIT}
        parameters.update(kind.complete(controller.parameters))
        nodes.append({"package": "seapup_control", "executable": "velocity_controller", "name": f"controller_{i}",
                      "required": True, "parameters": [parameters]})
    return nodes


def graph_document(spec: RunSpec, files: list[str], lockstep_timeout: float = 60.0) -> dict:
    """The graph of a run (see the module docstring), as a ROS 2 YAML launch document
    (:func:`seapup_common.launch_format.launch_document`).

    ``files``: each controller's design-document path (:func:`controller_nodes`). The launcher fills the
    handshake's counts from the graph's lockstep roster and the harness's listeners (the module docstring).

    Raises
    ------
    RunSpecError
        For what the simulator node cannot start from (a start state other than at rest at
        ``start_depth``, a start pitch other than the hover setting).
    """
    if spec.start_state is not None:
        raise RunSpecError("the simulator node starts at rest at start_depth: a start_state is in-process only")
    if spec.start_pitch is not None:
        raise RunSpecError("the simulator node starts at the hover setting: a start_pitch is in-process only")
    if spec.coefficients:
        raise RunSpecError("the simulator node flies a vehicle as its file describes it: scaled coefficients are "
                           "in-process only")
    simulator = {"mode": "lockstep", "lockstep_timeout": float(lockstep_timeout), "vehicle": spec.vehicle,
                 "dynamics": spec.dynamics, "seed": spec.seed, "start_depth": spec.start_depth,
                 "control_period": spec.control_period, "physics_step": spec.physics_step,
                 "end_time": spec.duration,
                 "events": yaml.safe_dump([e.to_dict() for e in spec.plant_events()], default_flow_style=True).strip()}
    if spec.environment:
        simulator["environment"] = spec.environment
    steps = spec.reference.to_list()
    if steps[0][0] > 0:  # the node's schedule starts at 0 with the first value, as the profile does
        steps.insert(0, [0.0, *steps[0][1:]])
    references = {"lockstep": True, "sample_period": spec.control_period, "times": [row[0] for row in steps],
                  "references": [float(v) for row in steps for v in row[1:]], "period": 0.0}
    from seapup_common.launch_format import launch_document
    return launch_document([{"package": "seapup_sim", "executable": "simulator", "required": True,
                             "parameters": [simulator]},
                            *controller_nodes(spec, files),
                            {"package": "seapup_control", "executable": "reference_schedule", "required": True,
                             "parameters": [references]}])
