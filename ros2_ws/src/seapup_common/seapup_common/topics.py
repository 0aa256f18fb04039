"""The Seapup graph's names: its topics and their message types, and the services and actions called across packages.

One table, so a topic is spelled once. Node shells publish and subscribe with
remappable names relative to their namespace (``sensors/velocity`` in
:data:`NAMESPACE`); code outside a node (bringup's drivers, the recorder, the
identifier's bag, tests' probes) uses the absolute names here.

A recorder told ``/topic:pkg/msg/Type`` subscribes before any publisher exists (nothing of a
fast lockstep run is lost); :func:`typed` builds those entries from :data:`TOPIC_TYPES`.
"""
from __future__ import annotations

__all__ = ["NAMESPACE", "CLOCK", "TF", "TF_STATIC", "DIAGNOSTICS", "COMMAND", "FORWARDED_COMMAND", "APPLIED", "PILOT", "TRUTH_ODOMETRY",
           "VELOCITY", "IMU", "DEPTH", "CURRENT", "UMBILICAL_SHAPE",
           "POSITION", "ALTITUDE", "SAMPLE_MANIFEST", "NAVIGATION_ODOMETRY", "VELOCITY_REFERENCE", "POSITION_REFERENCE",
           "SELF_TEST_SAMPLES", "IDENTIFIED_MODEL", "controller_estimate", "CONTROLLER_ESTIMATE_TYPE", "TASK_REJECTIONS", "SENSORS", "TOPIC_TYPES",
           "SELF_TEST_ACTION", "SET_CURRENT_SERVICE", "SET_THRUSTER_EFFICIENCY_SERVICE", "SIMULATOR_PARAMETERS_SERVICE", "SWITCH_CONTROLLER_SERVICE",
           "SIMULATION_CONTROL", "task_action", "typed"]

#: The vehicle's namespace: every seapup node runs in it.
NAMESPACE = "/seapup"

# -- topics ----------------------------------------------------------------------------------------
#: Simulated time (published by a lockstep or sim-time simulator).
CLOCK = "/clock"
#: The vehicle's pose as transforms (REP-105 odom -> base_link, each sample) and the fixed frames
#: (odom -> odom_ned, base_link -> base_link_frd; latched), where tf2 and ROS viewers look.
TF = "/tf"
TF_STATIC = "/tf_static"
#: Every node's diagnostics.
DIAGNOSTICS = "/diagnostics"
#: Blade pitches commanded by the active controller [rad].
COMMAND = "/seapup/thrusters/command"
#: The commands the controller manager forwarded to the vehicle (a copy of each, for the managed controllers:
#: one activated while the graph is held at a sample already answered starts at the next sample).
FORWARDED_COMMAND = "/seapup/controller_manager/forwarded"
#: Blade pitches the thrusters really applied (limited, held) [rad].
APPLIED = "/seapup/thrusters/applied"
#: A pilot's stick (geometry_msgs/Twist, REP-103 base_link): flown by a manual velocity controller.
PILOT = "/seapup/pilot/cmd_vel"
#: The simulator's true state (NED/FRD).
TRUTH_ODOMETRY = "/seapup/truth/odometry"
#: Body velocity and rates from the velocity sensor.
VELOCITY = "/seapup/sensors/velocity"
#: Attitude and rates.
IMU = "/seapup/sensors/imu"
#: Depth sensor.
DEPTH = "/seapup/sensors/depth"
#: Position fixes.
POSITION = "/seapup/sensors/position"
#: The umbilical's shape (odom_ned, vehicle to ship), from a simulator with an umbilical.
UMBILICAL_SHAPE = "/seapup/umbilical/shape"
#: The water's velocity at the vehicle (NED), from the simulator.
CURRENT = "/seapup/environment/current"
#: Altitude above the seabed.
ALTITUDE = "/seapup/sensors/altitude"
#: What the simulator published for each sample (seapup_msgs/SampleManifest), after the sample.
SAMPLE_MANIFEST = "/seapup/sensors/sample"
#: The navigator's estimate.
NAVIGATION_ODOMETRY = "/seapup/navigation/odometry"
#: Body-velocity reference of the velocity controllers.
VELOCITY_REFERENCE = "/seapup/velocity_controller/reference"
#: Pose set point of the position controller.
POSITION_REFERENCE = "/seapup/position_controller/reference"
#: The self-test's samples.
SELF_TEST_SAMPLES = "/seapup/self_test/samples"
#: Models published by the online identifier.
IDENTIFIED_MODEL = "/seapup/identifier/model"
#: Goals the task controller refused, with the reason.
TASK_REJECTIONS = "/seapup/task/rejections"

#: The simulator's sensor topics.
SENSORS = (VELOCITY, IMU, DEPTH, POSITION, ALTITUDE)

#: Topic -> message type (rosbag2 spelling ``pkg/msg/Type``).
TOPIC_TYPES = {
    PILOT: "geometry_msgs/msg/Twist",
    CLOCK: "rosgraph_msgs/msg/Clock",
    TF: "tf2_msgs/msg/TFMessage",
    TF_STATIC: "tf2_msgs/msg/TFMessage",
    DIAGNOSTICS: "diagnostic_msgs/msg/DiagnosticArray",
    COMMAND: "seapup_msgs/msg/BladePitch",
    FORWARDED_COMMAND: "seapup_msgs/msg/BladePitch",
    APPLIED: "seapup_msgs/msg/BladePitch",
    TRUTH_ODOMETRY: "nav_msgs/msg/Odometry",
    VELOCITY: "geometry_msgs/msg/TwistWithCovarianceStamped",
    IMU: "sensor_msgs/msg/Imu",
    DEPTH: "seapup_msgs/msg/Depth",
    POSITION: "geometry_msgs/msg/PoseWithCovarianceStamped",
    CURRENT: "geometry_msgs/msg/Vector3Stamped",
    UMBILICAL_SHAPE: "nav_msgs/msg/Path",
    ALTITUDE: "sensor_msgs/msg/Range",
    SAMPLE_MANIFEST: "seapup_msgs/msg/SampleManifest",
    NAVIGATION_ODOMETRY: "nav_msgs/msg/Odometry",
    VELOCITY_REFERENCE: "geometry_msgs/msg/TwistStamped",
    POSITION_REFERENCE: "geometry_msgs/msg/PoseStamped",
    SELF_TEST_SAMPLES: "seapup_msgs/msg/SelfTestSample",
    IDENTIFIED_MODEL: "seapup_msgs/msg/IdentifiedModel",
    TASK_REJECTIONS: "std_msgs/msg/String",
}

# -- services and actions --------------------------------------------------------------------------
#: The self-test action (``seapup_msgs/action/SelfTest``).
SELF_TEST_ACTION = "/seapup/self_test"
#: The simulator's current switch (``seapup_msgs/srv/SetCurrent``).
SET_CURRENT_SERVICE = "/seapup/simulator/set_current"
#: The simulator's thruster fouling (``seapup_msgs/srv/SetThrusterEfficiency``).
SET_THRUSTER_EFFICIENCY_SERVICE = "/seapup/simulator/set_thruster_efficiency"
#: The simulator's parameter service (the SIL harness sets ``end_time`` through it to hold the graph).
SIMULATOR_PARAMETERS_SERVICE = "/seapup/simulator/set_parameters"
#: The controller manager's switch (``seapup_msgs/srv/SwitchController``).
SWITCH_CONTROLLER_SERVICE = "/seapup/controller_manager/switch_controller"
#: The simulator's standard control surface (ROS 2 ``simulation_interfaces``, as Gazebo, Isaac Sim and O3DE
#: offer it): name -> (service or action, its type). StepSimulation and the SimulateSteps action answer once the
#: graph is held at the last stepped sample with every answerer's command for it in.
SIMULATION_CONTROL = {name: (f"/seapup/simulator/{name}", f"simulation_interfaces/{kind}") for name, kind in (
    ("get_simulator_features", "srv/GetSimulatorFeatures"), ("get_simulation_state", "srv/GetSimulationState"),
    ("set_simulation_state", "srv/SetSimulationState"), ("step_simulation", "srv/StepSimulation"),
    ("simulate_steps", "action/SimulateSteps"), ("reset_simulation", "srv/ResetSimulation"),
    ("get_entities", "srv/GetEntities"), ("get_entity_state", "srv/GetEntityState"),
    ("set_entity_state", "srv/SetEntityState"))}


def task_action(kind: str) -> str:
    """The task controller's action for a task kind (``hover``, ``goto``, ``follow_seabed``).

    Examples
    --------
    >>> task_action("goto")
    '/seapup/task/goto'
    """
    return f"{NAMESPACE}/task/{kind}"


def controller_estimate(name: str) -> str:
    """A self-tuning velocity controller node's estimate topic (``seapup_msgs/msg/ControllerEstimate``,
    its ``~/estimate``).

    Examples
    --------
    >>> controller_estimate("gmv")
    '/seapup/gmv/estimate'
    """
    return f"{NAMESPACE}/{name}/estimate"


#: The type of :func:`controller_estimate`'s topics.
CONTROLLER_ESTIMATE_TYPE = "seapup_msgs/msg/ControllerEstimate"


def typed(*topics: str) -> list[str]:
    """``["/topic:pkg/msg/Type", ...]`` for a recorder's ``topics`` parameter.

    Raises
    ------
    KeyError
        Naming a topic missing from :data:`TOPIC_TYPES`.

    Examples
    --------
    >>> typed(CLOCK, COMMAND)
    ['/clock:rosgraph_msgs/msg/Clock', '/seapup/thrusters/command:seapup_msgs/msg/BladePitch']
    """
    unknown = [t for t in topics if t not in TOPIC_TYPES]
    if unknown:
        raise KeyError(f"no message type known for {unknown}; add them to seapup_common.topics.TOPIC_TYPES")
    return [f"{t}:{TOPIC_TYPES[t]}" for t in topics]
