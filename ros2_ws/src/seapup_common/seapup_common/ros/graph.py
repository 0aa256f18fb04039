"""Graph-ready handshakes and QoS as rosbag2 sees it (rclpy shell code).

- :class:`SubscriberGate`: a node does not start its work (a lockstep
  simulator its first sample, a controller its first answer) until each of
  its publishers has the subscribers it was told to wait for -- so a recorder
  started beforehand misses nothing. Launchers and SIL graphs configure it
  with each node's ``wait_for_subscribers`` parameter.
- :func:`send_goal`: an action goal that survives discovery races (a goal
  request sent while the server has not yet matched the client is lost
  without a trace; it is sent again).
- :func:`call_idempotent`: a service call whose request may safely be made
  twice, sent again when its answer does not come (the same discovery race
  on the response path).
- :func:`qos_to_rosbag2` and :func:`adapted_qos`: the offered QoS of a topic's
  publishers in rosbag2's metadata keys, and the subscription QoS rosbag2
  would choose for them (reliable only if every publisher is reliable,
  transient-local only if every publisher is).
"""
from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ["SubscriberGate", "qos_to_rosbag2", "adapted_qos", "send_goal", "GoalNotAnswered", "spin_until",
           "call_idempotent", "ServiceNotAnswered"]

_INT64_MAX = 2**63 - 1


def _duration(d) -> dict:
    ns = int(d.nanoseconds)
    if ns >= _INT64_MAX or ns < 0:
        ns = _INT64_MAX
    sec, nsec = divmod(ns, 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def qos_to_rosbag2(qos) -> dict:
    """A QoS profile (from ``get_publishers_info_by_topic``) in rosbag2's metadata keys.

    History and depth are not visible across the graph (DDS does not announce
    them): like rosbag2 Jazzy we write what the endpoint info says
    (``unknown``, 0).
    """
    return {"history": qos.history.name.lower(), "depth": int(qos.depth),
            "reliability": qos.reliability.name.lower(), "durability": qos.durability.name.lower(),
            "deadline": _duration(qos.deadline), "lifespan": _duration(qos.lifespan),
            "liveliness": qos.liveliness.name.lower(),
            "liveliness_lease_duration": _duration(qos.liveliness_lease_duration),
            "avoid_ros_namespace_conventions": bool(qos.avoid_ros_namespace_conventions)}


def adapted_qos(publisher_infos, depth: int = 1000) -> QoSProfile:
    """The subscription QoS that receives everything the publishers offer.

    Reliable if every publisher is reliable (else best effort, or nothing would
    match the best-effort ones), transient-local if every publisher is (so late
    joining still gets their latched messages); keep-last ``depth``.
    """
    infos = list(publisher_infos)
    reliable = bool(infos) and all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
    latched = bool(infos) and all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


#: Wall seconds a gate's subscribers must stay matched before it opens (see :class:`SubscriberGate`).
DISCOVERY_GRACE = 0.25


class SubscriberGate:
    """Open once every listed publisher has had at least its required matched subscribers for ``grace`` s.

    A publisher counts a subscription as matched as soon as *it* has
    discovered the reader; the reader may discover the writer a little later
    and, being volatile, drops what was sent before that. ``grace`` covers
    that second half of discovery, so the first message reaches every awaited
    subscriber.

    Parameters
    ----------
    requirements : list of (publisher, int)
        Each publisher and how many subscriptions must be matched to it.
    grace : float
        Wall seconds the requirements must hold before the gate opens.
    """

    def __init__(self, requirements, grace: float = DISCOVERY_GRACE):
        self.requirements = [(p, int(n)) for p, n in requirements if int(n) > 0]
        self.grace = float(grace)
        self._open = not self.requirements
        self._met_since: float | None = None

    def ready(self) -> bool:
        """True once every requirement was met for ``grace`` seconds (it then stays open)."""
        import time
        if not self._open:
            if not all(p.get_subscription_count() >= n for p, n in self.requirements):
                self._met_since = None
            elif self._met_since is None:
                self._met_since = time.monotonic()
            self._open = self._met_since is not None and time.monotonic() - self._met_since >= self.grace
        return self._open

    def missing(self) -> list[str]:
        """``topic (have/need)`` for every requirement not yet met."""
        return [f"{p.topic_name} ({p.get_subscription_count()}/{n})" for p, n in self.requirements
                if p.get_subscription_count() < n]


def spin_until(executor, predicate, timeout: float, step: float = 0.05) -> bool:
    """Spin ``executor`` until ``predicate()`` holds or ``timeout`` seconds pass; the predicate's last value."""
    import time
    deadline = time.monotonic() + timeout
    while not predicate() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=step)
    return bool(predicate())


class GoalNotAnswered(RuntimeError):
    """An action server that never answered a goal request."""


def send_goal(executor, client, goal, feedback_callback=None, *, ready_timeout: float = 30.0,
              response_timeout: float = 5.0, attempts: int = 4):
    """Send an action goal and return its goal handle (accepted or not).

    ``server_is_ready`` says the *client* has matched the server's services;
    until the server has matched the client too, a request is dropped by the
    middleware without an error (seen on a loaded machine). A request that
    gets no response within ``response_timeout`` s is therefore sent again,
    up to ``attempts`` times -- unless the server did take it and only its
    answer was lost (rmw: "failed to send response (timeout)", seen under
    load: the retry then started a second goal and the caller's handle named
    one the server never ran). Before a retry the action's status topic is
    read: a goal listed there is the server's, and its handle is returned.

    Raises
    ------
    GoalNotAnswered
        If the server never became ready or never answered.
    """
    import uuid

    from unique_identifier_msgs.msg import UUID
    if not spin_until(executor, client.server_is_ready, ready_timeout):
        raise GoalNotAnswered(f"no action server {client._action_name!r} within {ready_timeout:g} s")
    for _ in range(attempts):
        goal_id = UUID(uuid=list(uuid.uuid4().bytes))
        future = client.send_goal_async(goal, feedback_callback=feedback_callback, goal_uuid=goal_id)
        if spin_until(executor, future.done, response_timeout):
            return future.result()
        adopted = _taken_goal(executor, client, goal_id)
        if adopted is not None:
            return adopted
    raise GoalNotAnswered(f"the action server {client._action_name!r} did not answer {attempts} goal requests")


def _taken_goal(executor, client, goal_id, wait: float = 2.0):
    """The handle of goal ``goal_id`` if the server lists it on its status topic (it took the goal and its
    answer was lost), else None."""
    import weakref

    from action_msgs.msg import GoalStatusArray
    from rclpy.action.client import ClientGoalHandle
    from rclpy.qos import qos_profile_action_status_default
    wanted, seen = bytes(goal_id.uuid), []

    def on_status(msg):
        seen.extend(bytes(s.goal_info.goal_id.uuid) for s in msg.status_list)
    subscription = client._node.create_subscription(GoalStatusArray, f"{client._action_name}/_action/status",
                                                    on_status, qos_profile_action_status_default)
    try:
        if not spin_until(executor, lambda: wanted in seen, wait):
            return None
    finally:
        client._node.destroy_subscription(subscription)
    handle = ClientGoalHandle(client, goal_id, client._action_type.Impl.SendGoalService.Response(accepted=True))
    client._goal_handles[wanted] = weakref.ref(handle)   # status, feedback and result reach it as any
    return handle


class ServiceNotAnswered(RuntimeError):
    """A service that never became ready or never answered."""


def call_idempotent(executor, client, request, *, ready_timeout: float = 30.0, response_timeout: float = 5.0,
                    attempts: int = 4):
    """Call a service whose request may be made more than once (a set, a query) and return the response.

    ``service_is_ready`` says the client has matched the server; the server may not yet have matched the
    client's response reader, and then drops its answer ("failed to send response (timeout)", seen on a
    loaded machine: the server did the work, the caller waits forever). A request unanswered within
    ``response_timeout`` s is therefore sent again, up to ``attempts`` times. Not for requests that must not
    happen twice (a switch, a goal: :func:`send_goal` handles those).

    Raises
    ------
    ServiceNotAnswered
        If the server never became ready or never answered.
    """
    if not spin_until(executor, client.service_is_ready, ready_timeout):
        raise ServiceNotAnswered(f"no service {client.srv_name!r} within {ready_timeout:g} s")
    for _ in range(attempts):
        future = client.call_async(request)
        if spin_until(executor, future.done, response_timeout):
            return future.result()
        client.remove_pending_request(future)
    raise ServiceNotAnswered(f"the service {client.srv_name!r} did not answer {attempts} requests")
