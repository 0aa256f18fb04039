"""The ``task_controller`` node: hover, go to a point, follow the seabed (thesis sec. 4.2) as ROS actions.

A thin shell over :mod:`seapup_control.tasks`. Action servers (namespace
``/seapup``): ``task/hover`` (seapup_msgs/action/Hover), ``task/goto``
(Goto), ``task/follow_seabed`` (FollowSeabed). One task runs at a time; at
each navigation estimate t_k (``navigation/odometry``) it publishes the
task's setpoint on ``position_controller/reference`` (PoseStamped in
``odom_ned``, stamped t_k + T) and the goal's feedback. When a task ends
badly or is cancelled, the vehicle hovers where it is; after a success it
holds the task's last setpoint. A goal that cannot be met -- beyond the
limits of ``config/task_controller.yaml``, no navigation, the altimeter
seeing no seabed, another task running without ``preempt`` -- is rejected;
the reason is logged and published on ``task/rejections``
(std_msgs/String), since an action's goal response has no field for it.

Seabed following steps at estimate t_k with the altimeter's reading of t_k. While the altimeter
streams one reading per sample (the simulator sends every sample, +inf when it hears no echo),
the node waits up to ``altitude_wait`` wall seconds for that reading before it steps: the
altitude and the estimate arrive on different topics, and which comes first must not depend on
how busy the machine is (a lockstep run would otherwise differ under load). A reading that does
not come in time is counted (``late_altitudes``) and the newest earlier one used.
An estimate stamped as the one before it (the navigator says its newest again to readers that
match late) is ignored and counted (``repeated_estimates``): a task steps once per sample.

A task starts at its goal's acceptance, in the same callback that sends the goal response
(rclpy's ``handle_accepted_callback`` runs right after it, with no other callback in between):
its first step is the first estimate after the acceptance whatever the load. Started in the
execute callback instead -- a task rclpy schedules later -- a lockstep graph stepped on as soon
as the client heard the acceptance could reach this node's next estimates first, and the task
then began one or more samples late (a loaded demo's seabed following ended 0.4 s later).
The first task's first setpoint starts the setpoint stream; a harness holding the graph resumes it once the
position controller says it has that setpoint (its ``setpoint_stream_start``).
"""
from __future__ import annotations

import collections
import functools
import math
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.clock import Clock as SteadyClock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Range
from seapup_msgs.action import FollowSeabed, Goto, Hover
from std_msgs.msg import String

from seapup_common.contract import ContractError
from seapup_common.lockstep import StampGate
from seapup_common.ros.messages import (altitude_from_msg, diagnostic_array, estimate_from_odometry,
                                        pose_setpoint_to_msg, stamp_to_ns)
from seapup_common.ros.node import (COMMAND_QOS, RELIABLE_QOS, STREAM_QOS, SERVICE_QOS, declare_from_package_file,
                                    destroy_actions, graph_time_ns, run_node)
from seapup_common.topics import CLOCK, DIAGNOSTICS, NAMESPACE
from seapup_control.tasks import FollowSeabed as FollowSeabedTask
from seapup_control.tasks import Goto as GotoTask
from seapup_control.tasks import Hover as HoverTask
from seapup_control.tasks import TaskLimits, TaskRejected

__all__ = ["TaskControllerNode", "main"]

#: Rejection reasons are kept for late joiners (a client that subscribes just before sending).
REJECTIONS_QOS = QoSProfile(depth=20, reliability=ReliabilityPolicy.RELIABLE,
                            durability=DurabilityPolicy.TRANSIENT_LOCAL)


_ACTIONS = {"hover": Hover, "goto": Goto, "follow_seabed": FollowSeabed}


class _Running:
    """The task in progress with its goal handle and the future its execute callback awaits."""

    def __init__(self, task, handle):
        self.task, self.handle, self.done = task, handle, Future()


class TaskControllerNode(Node):
    """rclpy shell around the tasks of :mod:`seapup_control.tasks` (see the module docstring)."""

    #: Spun by rclpy's EventsExecutor unless told otherwise (seapup_common.ros.node.DEFAULT_EXECUTOR).
    EXECUTOR = "events"

    def __init__(self, **kwargs):
        super().__init__("task_controller", namespace=NAMESPACE, **kwargs)
        p = declare_from_package_file(self, "seapup_control", "task_controller.yaml", section="task_controller", ranges={
            "sample_period": (0.01, 10.0), "navigation_timeout": (0.01, 600.0),
            "limits.min_depth": (0.0, 11000.0), "limits.max_depth": (0.0, 11000.0),  # [m]
            "limits.max_distance": (0.0, 1e5), "limits.min_speed": (0.0, 5.0), "limits.max_speed": (0.0, 5.0),
            "limits.min_altitude": (0.0, 1e3), "limits.max_altitude": (0.0, 1e3), "limits.max_duration": (1.0, 1e7),
            "limits.default_speed": (0.0, 5.0), "limits.default_tolerance": (0.01, 1e3),
            "limits.default_yaw_tolerance": (1e-4, 3.1416), "limits.settle_time": (0.0, 3600.0),
            "limits.timeout_margin": (0.0, 1e6), "limits.altitude_timeout": (0.01, 3600.0),
            "limits.seabed_filter_time": (0.0, 3600.0), "limits.max_estimate_std": (0.0, 1e4),
            "limits.max_lead": (0.0, 3600.0), "altitude_wait": (0.0, 600.0)})
        self.limits = TaskLimits.from_mapping({k.removeprefix("limits."): v for k, v in p.items()
                                               if k.startswith("limits.")})
        self.period = float(p["sample_period"])
        self.navigation_timeout = float(p["navigation_timeout"])
        self.estimate = None
        self._heard_ns: int | None = None  # the newest estimate's stamp heard
        self._estimate_wall = -math.inf
        self._clock_ns: int | None = None  # the graph's /clock, when there is one
        self.create_subscription(Clock, CLOCK, self._on_clock, RELIABLE_QOS)
        self._altitudes = collections.deque(maxlen=100)  # valid altimeter readings, oldest first
        self._newest_altitude: float | None = None  # [s] stamp of the newest altimeter message, valid or not
        self._previous_altitude: float | None = None  # [s] and of the one before it
        self._altitude_stamps = StampGate()
        # an estimate waiting for its sample's altitude reading (seabed following), with its wall deadline
        self._parked: tuple | None = None
        self._park_timer = None  # fires at the parked estimate's deadline (steady: a held graph's time stands still)
        self.running: _Running | None = None
        self.setpoint = None
        self.counts = {"rejected_goals": 0, "rejected_estimates": 0, "setpoints": 0, "late_altitudes": 0,
                       "rejected_altitudes": 0, "repeated_estimates": 0}
        self.setpoints = self.create_publisher(PoseStamped, "position_controller/reference", STREAM_QOS)
        self.rejections = self.create_publisher(String, "task/rejections", REJECTIONS_QOS)
        self.diagnostics = self.create_publisher(DiagnosticArray, DIAGNOSTICS, RELIABLE_QOS)
        self.create_timer(0.5, self._diagnose)
        self.create_subscription(Odometry, "navigation/odometry", self._on_estimate, COMMAND_QOS)
        self.create_subscription(Range, "sensors/altitude", self._on_altitude, COMMAND_QOS)
        # every goal, cancel and result request gets an answer: a storm of them must not overflow the
        # services' default queue of 10 (21-57 of 90 cancels went unanswered)
        self.servers = [ActionServer(self, action, f"task/{kind}",
                                     execute_callback=functools.partial(self._execute, kind),
                                     goal_callback=lambda goal, kind=kind: self._accept(kind, goal),
                                     cancel_callback=lambda _: CancelResponse.ACCEPT,
                                     goal_service_qos_profile=SERVICE_QOS, result_service_qos_profile=SERVICE_QOS,
                                     cancel_service_qos_profile=SERVICE_QOS)
                        for kind, action in _ACTIONS.items()]
        for server, kind in zip(self.servers, _ACTIONS):
            server.register_handle_accepted_callback(functools.partial(self._start, kind))
        self._started: dict[bytes, _Running | str] = {}  # goal id -> its task, or why it could not start

    def destroy_node(self):
        destroy_actions(self)  # before the node's clock goes: see destroy_actions
        return super().destroy_node()

    # -- goals -------------------------------------------------------------------------------
    def _build(self, kind: str, goal):
        estimate = self.estimate if self._fresh() else None
        if kind == "hover":
            return HoverTask(self.limits, estimate, hold_current=goal.hold_current,
                             pose=(goal.x, goal.y, goal.z, goal.yaw), duration=goal.duration, follow=goal.follow)
        if kind == "goto":
            return GotoTask(self.limits, estimate, (goal.x, goal.y, goal.z), goal.yaw, speed=goal.speed,
                            tolerance=goal.tolerance, yaw_tolerance=goal.yaw_tolerance, timeout=goal.timeout)
        altitude = self._altitude_at(estimate.t) if estimate is not None else None
        return FollowSeabedTask(self.limits, estimate, altitude, height=goal.altitude, yaw=goal.yaw,
                                speed=goal.speed, duration=goal.duration)

    def _reject(self, kind: str, reason: str) -> GoalResponse:
        self.counts["rejected_goals"] += 1
        text = f"{kind} goal rejected: {reason}"
        self.get_logger().warn(text)
        self.rejections.publish(String(data=text))
        return GoalResponse.REJECT

    def _accept(self, kind: str, goal) -> GoalResponse:
        if self.setpoints.get_subscription_count() == 0:
            return self._reject(kind, "no position controller listens to the setpoints "
                                      "(position_controller/reference): nothing would fly it")
        if self.running is not None and not goal.preempt:
            return self._reject(kind, f"a {self.running.task.kind} task is running (set preempt to replace it)")
        try:
            self._build(kind, goal)
        except TaskRejected as exc:
            return self._reject(kind, str(exc))
        return GoalResponse.ACCEPT

    def _start(self, kind: str, handle) -> None:
        """The goal was accepted (its response just sent, no callback in between: module docstring): its task
        runs from now on, stepped at the next estimate; then its execute callback awaits the end."""
        try:
            task = self._build(kind, handle.request)
        except TaskRejected as exc:  # cannot happen between acceptance and here; the execute callback says it
            self._started[bytes(handle.goal_id.uuid)] = str(exc)
            handle.execute()
            return
        if self.running is not None:
            self.running.done.set_result(("aborted", f"preempted by a {kind} goal", {}))
        self.running = self._started[bytes(handle.goal_id.uuid)] = _Running(task, handle)
        self.get_logger().info(f"{kind} started")
        if self.setpoint is None and self.estimate is not None:
            # the first task: the setpoint stream starts now, holding where the vehicle is until the task's
            # first step (the next estimate), so the position controller waits for every setpoint of the task
            # (it waits only while setpoints stream) whether or not this process runs late on a busy machine
            self.setpoint = task.hold(self.estimate, self.estimate.t)
            t_ns = int(round((self.estimate.t + self.period) * 1e9))
            self.setpoints.publish(pose_setpoint_to_msg(self.setpoint.position, self.setpoint.yaw, t_ns))
            self.counts["setpoints"] += 1
        handle.execute()

    async def _execute(self, kind: str, handle):
        action = _ACTIONS[kind]
        running = self._started.pop(bytes(handle.goal_id.uuid), "not started")
        if isinstance(running, str):
            handle.abort()
            return action.Result(success=False, message=running)
        status, message, numbers = await running.done
        if self.running is running:
            self.running = None
        out = action.Result(success=status == "succeeded", message=message,
                            end_time=self.estimate.t if self.estimate is not None else 0.0)
        for key, value in numbers.items():
            setattr(out, key, float(value))
        {"succeeded": handle.succeed, "canceled": handle.canceled}.get(status, handle.abort)()
        self.get_logger().info(f"{kind} {status}: {message}")
        return out

    # -- the loop ----------------------------------------------------------------------------
    def _on_altitude(self, msg: Range) -> None:
        try:
            reading = altitude_from_msg(msg)
        except (ContractError, ValueError):
            return
        stamp_ns = stamp_to_ns(msg.header.stamp)
        if not self._altitude_stamps.accept(stamp_ns):  # far from the graph's time: never used, never waited on
            self.counts["rejected_altitudes"] += 1
            self.get_logger().warn(f"altitude rejected: {self._altitude_stamps.why(stamp_ns)}",
                                   throttle_duration_sec=2.0)
            return
        stamp, newest = stamp_ns * 1e-9, self._newest_altitude
        if newest is None or stamp > newest or stamp < newest - 1.0:  # newer, or time went back (a reset)
            self._previous_altitude, self._newest_altitude = newest, stamp
        if reading.valid:
            self._altitudes.append(reading)
        if self._parked is not None and stamp >= self._parked[0].t - 1e-9:
            self._unpark()

    def _altitude_at(self, t: float):
        """The latest altimeter reading taken at or before ``t`` and at most 1 s older (the topics are
        processed in their own order: the altitude may run ahead of the estimate being handled)."""
        for reading in reversed(self._altitudes):
            if reading.stamp <= t + 1e-9:
                return reading if t - reading.stamp <= 1.0 else None
        return None

    def _on_clock(self, msg: Clock) -> None:
        self._clock_ns = stamp_to_ns(msg.clock)

    def _fresh(self) -> bool:
        """Is the navigation estimate current? Judged in the graph's time when it has a /clock (a lockstep
        graph stands still while nobody answers a sample: a wall-clock age would call the newest estimate
        stale and refuse a goal, as a loaded machine made it do), else by its wall-clock age."""
        if self.estimate is None:
            return False
        if self._clock_ns is not None:
            return self._clock_ns * 1e-9 - self.estimate.t <= self.navigation_timeout
        return time.monotonic() - self._estimate_wall <= self.navigation_timeout

    def _on_estimate(self, msg: Odometry) -> None:
        try:
            estimate = estimate_from_odometry(msg)
        except ContractError as exc:
            self.counts["rejected_estimates"] += 1
            self.get_logger().warn(f"estimate rejected: {exc}", throttle_duration_sec=2.0)
            return
        t_ns = round(estimate.t * 1e9)
        if t_ns == self._heard_ns:  # the navigator's newest again, for a reader that matched late
            self.counts["repeated_estimates"] += 1
            return
        self._heard_ns = t_ns
        self._altitude_stamps.accept(t_ns)  # the graph's time, for the altitude's stamp gate
        if self._parked is not None:  # the next estimate overtook the reading the parked one waits for
            self._unpark(late=True)
        if self._needs_altitude(estimate):
            wait = float(self.get_parameter("altitude_wait").value)
            self._parked = (estimate, time.monotonic() + wait)
            self._park_timer = self.create_timer(wait + 1e-3, self._check_parked,
                                                 clock=SteadyClock(clock_type=ClockType.STEADY_TIME))
            return
        self._handle(estimate)

    def _needs_altitude(self, estimate) -> bool:
        """Is seabed following running, the altimeter streaming one reading per sample (its newest two a
        sample apart, the newest a sample before this estimate: a slower altimeter is not waited for) and
        this sample's reading still to come?"""
        running, newest, previous = self.running, self._newest_altitude, self._previous_altitude
        per_sample = (newest is not None and previous is not None and newest - previous <= 1.5 * self.period
                      and estimate.t - 1.5 * self.period <= newest < estimate.t - 1e-9)
        return (per_sample and running is not None and not running.done.done()
                and running.task.kind == "follow_seabed" and float(self.get_parameter("altitude_wait").value) > 0)

    def _unpark(self, late: bool = False) -> None:
        estimate, _ = self._parked
        self._parked = None
        if self._park_timer is not None:
            self.destroy_timer(self._park_timer)
            self._park_timer = None
        if late:
            self.counts["late_altitudes"] += 1
            self.get_logger().warn(f"no altitude reading for t = {estimate.t:.3f} s within altitude_wait: "
                                   "going on with the newest earlier one", throttle_duration_sec=5.0)
        self._handle(estimate)
        if late:
            self._diagnose()  # a wall-clock limit ended the wait: said at once (seapup_common.lockstep.ENDED_WAITS)

    def _check_parked(self) -> None:
        if self._parked is not None and time.monotonic() > self._parked[1]:
            self._unpark(late=True)

    def _handle(self, estimate) -> None:
        """Step the running task at ``estimate`` and send the setpoint for the next sample."""
        self.estimate, self._estimate_wall = estimate, time.monotonic()
        running = self.running
        if running is not None and not running.done.done():
            self._step(running, estimate)
        if self.setpoint is not None:
            t_ns = int(round((estimate.t + self.period) * 1e9))
            self.setpoints.publish(pose_setpoint_to_msg(self.setpoint.position, self.setpoint.yaw, t_ns))
            self.counts["setpoints"] += 1

    def _step(self, running: _Running, estimate) -> None:
        if running.handle.is_cancel_requested:
            self.setpoint = running.task.hold(estimate, estimate.t)
            running.done.set_result(("canceled", "cancelled: hovering where it is", {"end_time": estimate.t}))
            return
        altitude = self._altitude_at(estimate.t)
        step = running.task.step(estimate.t, estimate, altitude)
        self.setpoint = step.setpoint
        fb = _ACTIONS[running.task.kind].Feedback()
        for key, value in step.feedback.items():
            setattr(fb, key, float(value))
        running.handle.publish_feedback(fb)
        if step.done:
            running.done.set_result(("succeeded" if step.success else "aborted", step.message,
                                     {**step.result, "end_time": estimate.t}))


    def _diagnose(self) -> None:
        """``seapup/task_controller``: OK while the navigation is fresh and a position controller listens
        to the setpoints (goals can be accepted and flown), else WARN with the reason."""
        fresh = self._fresh()
        listening = self.setpoints.get_subscription_count() > 0
        running = self.running.task.kind if self.running is not None else ""
        values = {**self.counts, "task": running, "navigation": "fresh" if fresh else "none",
                  "position_controller": "listening" if listening else "none",
                  f"subscribers:{self.setpoints.topic_name}": self.setpoints.get_subscription_count()}
        message = (running or "idle") if fresh and listening else \
            "no navigation estimate" if not fresh else "no position controller listening"
        self.diagnostics.publish(diagnostic_array(
            "seapup/task_controller", DiagnosticStatus.OK if fresh and listening else DiagnosticStatus.WARN,
            message, values, graph_time_ns(self, None if self.estimate is None else round(self.estimate.t * 1e9))))


def main(args=None) -> int:
    return run_node(TaskControllerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
