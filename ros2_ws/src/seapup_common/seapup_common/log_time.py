"""The log time of a recorded message under sim time: pure (no rclpy), so every rule is unit-tested.

A sim-time recorder (``seapup_common.recorder_node``) logs each message at
the graph's time when DDS received it. :class:`SimLogTime` keeps what that
takes and decides it:

- **/clock at receipt**: the ``/clock`` value current at the message's DDS
  receive (wall) time, placed among the receive times of the ``/clock``
  samples heard (:meth:`SimLogTime.on_clock`), so a busy recorder's callback
  lag does not shift it. Before anything says the graph's time (no
  ``/clock``, no stamp yet) the first header stamp, else the node's clock.
- **The time so far** (a floor): a header stamp is a lower bound of the
  graph's time -- the graph has reached every sample it sent. A stamp at
  most ``max_stamp_lead`` ahead of the time so far (the ``/clock`` at
  receipt or the floor, the later) raises the floor. Measured from the time
  so far, not from ``/clock`` alone: ``/clock``'s own queue can lag the
  sample topics by many samples (seen: 60 s of graph time, a recorder
  starved of CPU beside an unpaced graph), and the samples' stamps then
  carry the time on step by step.
- **Never before its own stamp**: a message of t_k was sent at t_k or later,
  whatever order the topics' queues are served in -- unless its stamp is more
  than ``max_stamp_jump`` ahead of the time so far: a wrong stamp, logged at
  the time so far and counted (:attr:`SimLogTime.distrusted`).

All times are integers [ns].
"""
from __future__ import annotations

import bisect

__all__ = ["SimLogTime", "CLOCK_HISTORY"]

#: /clock samples kept to place receive times among (at least; a few seconds even at thousands of
#: samples per second: far more than any callback lag).
CLOCK_HISTORY = 10_000


class SimLogTime:
    """The log times of one recorder under sim time (module docstring).

    Parameters
    ----------
    max_stamp_lead_ns, max_stamp_jump_ns : int
        How far ahead of the time so far a header stamp may be to raise it, and to be trusted at all [ns].
    """

    def __init__(self, max_stamp_lead_ns: int, max_stamp_jump_ns: int):
        if max_stamp_lead_ns < 0 or max_stamp_jump_ns < 0:
            raise ValueError(f"max_stamp_lead and max_stamp_jump must be >= 0, got {max_stamp_lead_ns} and "
                             f"{max_stamp_jump_ns} ns")
        self.max_stamp_lead_ns = int(max_stamp_lead_ns)
        self.max_stamp_jump_ns = int(max_stamp_jump_ns)
        self.floor_ns: int | None = None   # the latest stamp that raised the graph's time so far
        self.distrusted = 0    # messages whose stamp was too far ahead to be believed
        self._clock_wall: list[int] = []  # DDS receive wall times of the /clock samples (increasing)
        self._clock_sim: list[int] = []   # and their values

    def on_clock(self, received_wall_ns: int, value_ns: int) -> None:
        """A /clock sample heard: DDS received it at ``received_wall_ns``; ``value_ns`` is the graph's time.
        One received before the newest already placed (served out of order) is not placed."""
        if not self._clock_wall or received_wall_ns >= self._clock_wall[-1]:
            self._clock_wall.append(int(received_wall_ns))
            self._clock_sim.append(int(value_ns))
            if len(self._clock_wall) > 2 * CLOCK_HISTORY:  # bounded memory: keep the recent ones
                del self._clock_wall[:CLOCK_HISTORY], self._clock_sim[:CLOCK_HISTORY]

    def graph_time_at(self, received_wall_ns: int) -> int | None:
        """The /clock value current at a DDS receive (wall) time; None before the first /clock."""
        k = bisect.bisect_right(self._clock_wall, received_wall_ns) - 1
        return self._clock_sim[k] if k >= 0 else None

    def log_time(self, received_wall_ns: int, stamp_ns: int | None, now_ns: int) -> tuple[int, bool]:
        """The log time of a message DDS received at ``received_wall_ns`` with header stamp ``stamp_ns`` (None:
        no header), ``now_ns`` the node's clock; and whether its stamp was distrusted (too far ahead)."""
        at_receipt = self.graph_time_at(received_wall_ns)
        if at_receipt is None and self.floor_ns is None:
            # nothing heard yet says the graph's time (no /clock, no stamp): the first stamp is the time, else
            # the node's clock (a busy start's callback ran 1.4 s of graph time after the message came)
            if stamp_ns is None:
                return now_ns, False
            self.floor_ns = stamp_ns
            return stamp_ns, False
        so_far = (self.floor_ns if at_receipt is None else at_receipt if self.floor_ns is None
                  else max(at_receipt, self.floor_ns))   # per message: no generator
        if stamp_ns is None or stamp_ns <= so_far:
            return so_far, False
        if stamp_ns - so_far <= self.max_stamp_lead_ns:
            self.floor_ns = stamp_ns
            return stamp_ns, False
        if stamp_ns - so_far <= self.max_stamp_jump_ns:
            return stamp_ns, False   # never before its own stamp (the 1 Hz fixes once came 5-12 s "early")
        self.distrusted += 1
        return so_far, True
