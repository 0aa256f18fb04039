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

__all__ = ["SamplePolicy", "Decision", "WaitSettings", "ANSWER", "WAIT", "SKIP", "StampGate", "Pacer"]
