"""Seapup's deterministic lockstep protocol, pure (no rclpy, no clock reads, no sleeps).

Modules:

- :mod:`.policy`: when an answering node (a velocity controller, the self-test) answers a sample.
- :mod:`.pacing`: how fast a lockstep graph may run against the wall clock.
- :mod:`.server`: the simulator's side, a state machine (events in, actions out).
- :mod:`.roster`: who answers each sample and who must hear it, derived from the launch document.

Node shells only execute what these decide; every rule is unit-tested with explicit times.
"""
from seapup_common.lockstep.pacing import Pacer
from seapup_common.lockstep.policy import (ANSWER, SKIP, WAIT, Decision, SamplePolicy, StampGate,
                                           WaitSettings)

#: The ``/diagnostics`` counters by which a node reports that a wall-clock limit ended one of its lockstep waits:
#: it went on without what it waited for (a velocity controller without its sample's reference or applied
#: pitch, the position controller without its setpoint, the task controller without its altitude reading,
#: the simulator without the sample's command, the manager failing a controller over, a stream's first message
#: not acknowledged by every reader within its wait: ``seapup_common.ros.node.acknowledge_stream_start``). A lockstep run none of
#: whose nodes reports any of them flew deterministically; one that reports some may differ from a quieter
#: run of the same graph. Each node publishes its status at once when one of its counters grows.
ENDED_WAITS = ("late_references", "late_applied", "late_setpoints", "late_altitudes", "lockstep_timeouts",
               "failovers", "unacknowledged_stream_starts")

__all__ = ["SamplePolicy", "Decision", "WaitSettings", "ANSWER", "WAIT", "SKIP", "StampGate", "Pacer",
           "ENDED_WAITS"]
