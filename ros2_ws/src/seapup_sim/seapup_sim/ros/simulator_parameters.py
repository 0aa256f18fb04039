"""The simulator node's parameters: their descriptors and ranges, and the environment as read-only parameters.

:func:`declare_simulator_parameters` declares every parameter of ``config/simulator.yaml`` with its
descriptor and allowed values; :func:`environment_overrides` declares ``environment_file`` and every
``environment.<section>.<key>`` leaf (defaults from ``environment/default.yaml``, overridden by the YAML
file named in ``environment_file``, then by ``-p``/``--params-file``) and returns the environment mapping
they give; :func:`events_parameter` reads the ``events`` parameter.
"""
from __future__ import annotations

import math
from pathlib import Path

import yaml
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType

from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_common.config import load_yaml, merge
from seapup_common.ros.node import declare_from_package_file, declare_guarded, flatten, one_of, text, topic_names
from seapup_sim.environment_config import default_environment_mapping
from seapup_sim.linearised import DYNAMICS
from seapup_sim.sensors import sensor_profiles
from seapup_sim.vehicle_config import available_configs

__all__ = ["ENVIRONMENT_RANGES", "declare_simulator_parameters", "environment_overrides", "events_parameter", "refusal"]


def _float_range(lo, hi, description, read_only=False):
    return ParameterDescriptor(description=description, read_only=read_only,
                               floating_point_range=[FloatingPointRange(from_value=lo, to_value=hi)])


#: The allowed range of each numeric ``environment.*`` parameter (read-only: given at start). The environment's
#: own validation (:func:`~seapup_sim.environment_config.load_environment`, ``environment/limits.yaml``) is the
#: finer check; these bound what it is given and show in ``./seapup param describe``.
ENVIRONMENT_RANGES = {
    "current.mean_speed": (0.0, 3.0), "current.speed_std": (0.0, 3.0),        # limits.yaml current.speed_max
    "current.mean_direction": (-2 * math.pi, 2 * math.pi), "current.direction_std": (0.0, math.pi),
    "current.break_time": (0.1, 1e5),                                          # limits.yaml current.break_time
    "umbilical.ship_ned": (-1e4, 1e4),            # [m] limits.yaml start_state.horizontal_max
    "umbilical.diameter": (1e-3, 1.0),            # [m] a cable, not a riser
    "umbilical.still_water_drag_coefficient": (0.0, 10.0), "umbilical.strumming_factor": (1.0, 10.0),
    "umbilical.weight_per_length": (-1e3, 1e3),   # [N/m] in water, buoyant (negative) or heavy
    "umbilical.length_ratio": (1.0, 10.0),        # a cable at least as long as the straight line
    "umbilical.attachment": (-10.0, 10.0),        # [m] body axes: on the vehicle (about 1 m long)
    "umbilical.min_flow": (1e-6, 1.0), "umbilical.max_gravity_ratio": (0.0, 1.0),
    "seabed.depth": (0.0, 11000.0),               # [m] the deepest ocean
    "seabed.gradient": (-10.0, 10.0), "seabed.direction": (-2 * math.pi, 2 * math.pi),
    "seabed.points": (-1e5, 1e5),                 # [m] distance and depth pairs
}


def environment_overrides(node) -> dict:
    """Declare ``environment_file`` and every ``environment.*`` leaf (read-only, ranged, strings with their
    allowed values); return the environment mapping they give (validated by :func:`load_environment`)."""
    declare_guarded(node, {"environment_file": ""}, {"environment_file": ParameterDescriptor(
        description="YAML of environment overrides merged over environment/default.yaml", read_only=True)},
        allowed={"environment_file": text("a YAML file of environment overrides, or empty",
                                          lambda v: "" if not v or Path(v).is_file() else "no such file")})
    defaults = default_environment_mapping()
    path = node.get_parameter("environment_file").value
    if path:
        defaults = merge(defaults, load_yaml(path), strict=f"{Path(path).name} over environment/default.yaml")
    flat = flatten(defaults)
    descriptors = {name: ParameterDescriptor(read_only=True, description="environment (see environment/default.yaml);"
                                             " services change the current and sensors at run time")
                   for name in flat}
    if not flat.get("seabed.points"):
        descriptors["seabed.points"].type = ParameterType.PARAMETER_DOUBLE_ARRAY
    allowed = {"seabed.kind": one_of("flat", "slope", "polyline"), "sensors": one_of(*sensor_profiles())}
    declared = declare_guarded(node, {f"environment.{k}": v for k, v in flat.items()},
                               {f"environment.{k}": d for k, d in descriptors.items()},
                               {f"environment.{k}": r for k, r in ENVIRONMENT_RANGES.items() if k in flat},
                               {f"environment.{k}": a for k, a in allowed.items() if k in flat},
                               where="environment")
    out: dict = {}
    for name, value in declared.items():
        *parents, leaf = name.split(".")[1:]
        level = out
        for key in parents:
            level = level.setdefault(key, {})
        level[leaf] = value
    return out


def _events_problem(value: str) -> str:
    try:
        events_parameter(value)
    except ValueError as exc:
        return str(exc).splitlines()[0]
    return ""


def events_parameter(text: str) -> list:
    """The ``events`` parameter (YAML text) as plain data; checked by the simulator's configuration."""
    try:
        events = yaml.safe_load(text) if text else []
    except yaml.YAMLError as exc:
        raise ValueError(f"events is not YAML: {exc}") from None
    return [] if events is None else events


def declare_simulator_parameters(node) -> dict:
    """Declare the simulator's own parameters (``config/simulator.yaml``, section ``simulator``) with their
    descriptors, ranges and allowed values; return their values by name."""
    ro = dict(read_only=True)
    return declare_from_package_file(node, "seapup_sim", "simulator.yaml", {
        "mode": ParameterDescriptor(description="lockstep | realtime", **ro),
        "real_time_factor": _float_range(0.0, 1e4, "realtime speed-up (0 = as fast as possible)"),
        "lockstep_timeout": _float_range(0.001, 60.0, "wall seconds to wait for the t_k command"),
        "lockstep_pace": _float_range(0.0, 1e4, "lockstep: publish no faster than this many times real time, "
                                                "to be watched (0: as fast as the graph answers; settable at "
                                                "run time; simulated results are the same at any pace)"),
        "control_period": _float_range(0.01, 10.0, "controller sample period T [s]", **ro),
        "physics_step": _float_range(0.001, 1.0, "integration step [s]", **ro),
        "vehicle": ParameterDescriptor(description="vehicle configuration (~/set_configuration "
                                                   "changes it)", **ro),
        "dynamics": ParameterDescriptor(description="nonlinear (ch. 2) | linearised (eq. 3.2 about hover)",
                                        **ro),
        "seed": ParameterDescriptor(description="random seed (~/reset changes it)", read_only=True,
                                    integer_range=[IntegerRange(from_value=0, to_value=2**31 - 1)]),
        "blade_pitch_limit": _float_range(0.01, BLADE_PITCH_LIMIT, "blade-pitch limit [rad]", **ro),
        "watchdog_timeout": _float_range(0.01, 3600.0, "sim seconds without a valid command"),
        "watchdog_action": ParameterDescriptor(description="hover | neutral"),
        "start_depth": _float_range(0.0, 6000.0, "initial depth [m]", **ro),
        "publish_clock": ParameterDescriptor(description="publish /clock (the simulator owns time)", **ro),
        "publish_tf": ParameterDescriptor(description="publish /tf (REP-105 odom -> base_link, each sample) "
                                                      "and /tf_static (odom -> odom_ned, base_link -> "
                                                      "base_link_frd)", **ro),
        "diagnostics_period": _float_range(0.05, 60.0, "diagnostics period [s wall]", **ro),
        "end_time": _float_range(0.0, 1e9, "the last sample [s sim]: no step past it; 0 = run on (settable at "
                                           "run time: a later value resumes a held graph)"),
        "start_held": ParameterDescriptor(description="hold at the first sample t_0 until end_time is set "
                                                      "at run time (to a later sample; 0: run on)", **ro),
        "wait_for_subscribers": ParameterDescriptor(
            type=ParameterType.PARAMETER_STRING_ARRAY, read_only=True,
            description="published topics that need a matched subscriber (e.g. a recorder's) before "
                        "the first sample is published; a topic listed k times needs k"),
        "discovery_grace": _float_range(0.0, 10.0, "wall seconds the awaited subscribers must stay matched "
                                                   "before the first sample", **ro),
        "events": ParameterDescriptor(description="scheduled changes, YAML list of {time, kind, detail} "
                                                  "(configuration, thruster_efficiency, current)", **ro),
    }, defaults={"blade_pitch_limit": BLADE_PITCH_LIMIT}, section="simulator", allowed={
        "mode": one_of("lockstep", "realtime"), "vehicle": one_of(*available_configs()),
        "dynamics": one_of(*DYNAMICS), "watchdog_action": one_of("hover", "neutral"),
        "wait_for_subscribers": topic_names(), "events": text("YAML text: a list of {time, kind, detail}",
                                                               _events_problem)})


def refusal(name: str, value, simulator, control_period: float) -> str:
    """Why the simulator refuses ``name`` := ``value`` at run time ('' if it takes it)."""
    if name == "use_sim_time" and value:
        return "use_sim_time refused: the simulator is the clock source (it publishes /clock)"
    if name == "watchdog_action" and value not in ("hover", "neutral"):
        return "watchdog_action must be hover or neutral"
    if name == "real_time_factor":
        try:
            simulator.limits.check_real_time_factor(value, control_period)
        except (TypeError, ValueError) as exc:
            return str(exc)
    return ""
