"""When a node answers a sample: the lockstep timing policy, written once and without ROS.

A lockstep simulator publishes ``/clock`` t_k and the sensor samples stamped
t_k, then waits for a command stamped t_k; until the first answer it repeats
``/clock`` t_k (its graph-ready handshake). Every node that answers samples
(a velocity controller, the self-test) and every in-process flight of the
graph's timing asks the same questions, answered here:

- **which sample is pending**: each sample is answered once; a sample older
  than the newest ``/clock`` is past (another node answered it and the
  simulator has moved on: its answer would be refused as stale); a ``/clock``
  that goes back is a reset, and the samples ahead of it are pending again;
- **whether to answer it now or wait**, and until when (wall time: simulated
  time stands still while a lockstep sample waits):

  * a controller activated before it heard the vehicle's applied blade pitch
    waits up to ``applied_wait`` for it (its bumpless start), then starts from
    its fallback;
  * before any reference was heard, the first sample may wait up to
    ``first_reference_wait`` for the first one (a reference publisher started
    with the graph sets the first sample's reference);
  * while stamped references stream in (the newest two stamped within
    ``reference_stream`` of each other and of the sample), sample t_k waits up
    to ``reference_wait`` for the reference stamped t_k, so the simulator
    waits for the whole hierarchy, not only this loop;
  * a law that estimates from the applied pitch (``needs_applied``) waits up
    to ``applied_wait`` for the applied pitch stamped t_k, once the vehicle
    has been heard to publish one.

  A sample that waited its limit goes on and is counted late.

- **where a controller activated mid-run starts**: a node that hears the
  vehicle's command topic (:meth:`SamplePolicy.on_vehicle_command`) knows
  when the newest sample was already answered by the controller it
  replaces (a switch made while the graph is held at that sample): it
  leaves that sample alone and starts at the next one, from that sample's
  own applied pitch -- the command actually in force -- instead of
  answering a sample whose answer the vehicle already has (the manager
  would drop it, and the law would have stepped once on a command never
  applied).

The caller feeds events in and asks :meth:`SamplePolicy.decide` with the wall
time ``now`` [s, monotonic]; nothing here reads a clock, sleeps or spins, so
every rule is unit-tested with explicit times. With ``lockstep`` false (a
timer samples on the node's clock) nothing ever waits.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["SamplePolicy", "Decision", "WaitSettings", "ANSWER", "WAIT", "SKIP", "StampGate"]

ANSWER, WAIT, SKIP = "answer", "wait", "skip"


@dataclass(frozen=True)
class WaitSettings:
    """How long a lockstep sample may wait for what it needs [s wall] (0: not at all).

    Parameters
    ----------
    applied_wait : float
        For the applied blade pitch (at activation; every sample for a law that needs it).
    reference_wait : float
        For the reference stamped for the sample while references stream.
    reference_stream : float
        References stamped within this of each other and of the sample make a stream [s simulated].
    first_reference_wait : float
        For the first reference ever (0: start with the reference in force at once).
    needs_applied : bool
        Every sample waits for the applied pitch stamped with it.
    reference_every_sample : bool
        References come one per sample (a reference publisher answering every ``/clock``): once a
        stamped reference was heard, every sample waits up to ``reference_wait`` for the one stamped
        for it, stream or not.
    start_at, stop_at : float
        Lockstep: answer only the samples in [start_at, stop_at) [s simulated] (stop_at 0: no end). A
        law that takes over at ``start_at`` starts there, bumpless from the applied pitch stamped
        with that sample (waited for up to ``applied_wait``): a controller switch that falls on one
        sample whatever the wall-clock timing, as a run's scheduled controller event.
    """

    applied_wait: float = 2.0
    reference_wait: float = 0.2
    reference_stream: float = 1.0
    first_reference_wait: float = 0.0
    needs_applied: bool = False
    reference_every_sample: bool = False
    start_at: float = 0.0
    stop_at: float = 0.0

    def __post_init__(self):
        for name in ("applied_wait", "reference_wait", "reference_stream", "first_reference_wait", "start_at",
                     "stop_at"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0 s, got {value!r}")
        if 0 < self.stop_at <= self.start_at:
            raise ValueError(f"stop_at ({self.stop_at} s) must be after start_at ({self.start_at} s)")


@dataclass(frozen=True)
class Decision:
    """What to do with a sample now.

    ``action`` is :data:`ANSWER` (compute and send the command), :data:`WAIT` (come back at
    ``wake_at`` or when what it waits for arrives) or :data:`SKIP` (answered already, past, outside
    the node's window, or the node is not active: a policy starts inactive, :meth:`SamplePolicy.activate`
    makes it answer). ``start``: reset the law bumpless first (from the applied pitch when
    ``heard_applied``, else from its fallback). ``late``: what the sample waited for in vain.
    """

    action: str
    wake_at: float | None = None
    start: bool = False
    late: tuple[str, ...] = ()
    waiting_for: str = ""


@dataclass
class _Wait:
    sample_ns: int
    since: float


class SamplePolicy:
    """The lockstep timing of one answering node (see the module docstring).

    Parameters
    ----------
    lockstep : bool
        Samples are the simulator's (True) or a timer's (False: never wait, every time pending).
    settings : WaitSettings
        How long to wait for what.

    Examples
    --------
    >>> policy = SamplePolicy(True, WaitSettings(applied_wait=0.25))
    >>> policy.on_sample(0), policy.activate(heard_applied=False)
    (0, False)
    >>> policy.decide(0, now=10.0).action          # waits for the applied pitch to start from
    'wait'
    >>> policy.on_applied(0)
    True
    >>> d = policy.decide(0, now=10.01); d.action, d.start
    ('answer', True)
    """

    def __init__(self, lockstep: bool = True, settings: WaitSettings | None = None):
        self.lockstep = bool(lockstep)
        self.settings = settings or WaitSettings()
        self.latest_ns: int | None = None      # newest sample heard
        self.answered_ns: int | None = None
        self.clock_ns: int | None = None       # newest /clock heard
        self.active = False                    # a node answers nothing until activated (lifecycle)
        self.applied_ns: int | None = None     # stamp of the newest applied pitch heard
        self.heard_reference = False
        self.commanded_ns: int | None = None   # newest sample the vehicle's command topic answered
        self._start_pending = False
        self._start_own_applied = False        # the start needs the applied pitch of its own sample
        self._start_wait: _Wait | None = None
        self._first_wait: float | None = None
        self._reference_wait: _Wait | None = None
        self._applied_wait: _Wait | None = None
        self._newest_reference: float | None = None
        self._previous_reference: float | None = None
        self.late = {"references": 0, "applied": 0}

    # -- events --------------------------------------------------------------------------
    def on_sample(self, t_ns: int) -> int | None:
        """A sample's (velocity) reading arrived: the sample to answer now, or None (timer mode)."""
        self.latest_ns = int(t_ns)
        return self.pending(self.latest_ns) if self.lockstep else None

    def on_clock(self, t_ns: int) -> int | None:
        """A ``/clock`` t_k: the sample to answer when it is the latest and not answered (handshake)."""
        if self.clock_ns is not None and t_ns < self.clock_ns:
            self.commanded_ns = None  # a reset: the commands heard were for the samples of before
        self.clock_ns = int(t_ns)  # the newest (one reliable topic arrives in order; a reset goes back)
        return self.pending(self.clock_ns) if self.clock_ns == self.latest_ns else None

    def on_applied(self, t_ns: int) -> bool:
        """The applied pitch stamped ``t_ns`` arrived; True if a waiting sample should be decided again."""
        waiting = self._start_pending or self._applied_wait is not None
        self.applied_ns = int(t_ns)
        return bool(waiting and self.active)

    def on_reference(self, at: float | None) -> bool:
        """A reference arrived (stamped ``at`` [s], None: at once); True if a waiting sample should be
        decided again."""
        first = not self.heard_reference
        self.heard_reference = True
        retry = first and self._first_wait is not None
        if at is None and self.settings.reference_every_sample and self._newest_reference is None:
            # one reference a sample: the first, stamped 0 (which a node reads as no stamp), is t = 0's, so the
            # stream starts with it and the next sample waits for its own (else a slow publisher is raced past
            # until its next reference is heard)
            at = 0.0
        if at is not None and (self._newest_reference is None or at > self._newest_reference):
            self._previous_reference, self._newest_reference = self._newest_reference, float(at)
            retry = retry or self._reference_wait is not None
        return bool(retry and self.active)

    def on_vehicle_command(self, t_ns: int) -> None:
        """The vehicle's command topic carried an answer to sample ``t_ns`` (this node's or another's)."""
        self.commanded_ns = int(t_ns) if self.commanded_ns is None else max(self.commanded_ns, int(t_ns))

    def activate(self, heard_applied: bool) -> bool:
        """The node becomes active; True: start the law at once (from the applied pitch if heard,
        else its fallback); False: a sample starts it (the first one, when it has the applied pitch, or
        the first of the window ``start_at``, with its own applied pitch; after a newest sample the
        vehicle already has a command for, the next one, with its own applied pitch)."""
        self.active = True
        self._start_wait = None
        answered_elsewhere = (self.lockstep and self.latest_ns is not None and self.commanded_ns is not None
                              and self.commanded_ns >= self.latest_ns)
        if answered_elsewhere:
            self.answered_ns = self.latest_ns
        self._start_own_applied = answered_elsewhere
        self._start_pending = self.lockstep and (not heard_applied or self._windowed or answered_elsewhere)
        return not self._start_pending

    @property
    def _windowed(self) -> bool:
        return self.settings.start_at > 0

    def in_window(self, t_ns: int) -> bool:
        """Whether sample ``t_ns`` is this node's to answer (always outside lockstep)."""
        if not self.lockstep:
            return True
        t = t_ns * 1e-9
        s = self.settings
        return t >= s.start_at - 1e-9 and (s.stop_at <= 0 or t < s.stop_at - 1e-9)

    def deactivate(self) -> None:
        self.active = False
        self._start_pending = self._start_own_applied = False
        self._reference_wait = self._applied_wait = self._start_wait = None

    def answered(self, t_ns: int) -> None:
        """Sample ``t_ns`` was answered."""
        self.answered_ns = int(t_ns)
        self._reference_wait = self._applied_wait = None

    # -- questions -----------------------------------------------------------------------
    def pending(self, t_ns: int) -> int | None:
        """``t_ns`` if that sample still needs an answer, else None."""
        past = self.lockstep and self.clock_ns is not None and t_ns < self.clock_ns
        return None if t_ns == self.answered_ns or past else t_ns

    def decide(self, t_ns: int, now: float) -> Decision:
        """Answer sample ``t_ns`` now, wait for something (until ``wake_at``), or skip it.

        Parameters
        ----------
        t_ns : int
            The sample [ns simulated].
        now : float
            Wall time [s, monotonic].
        """
        if not self.active or self.pending(t_ns) is None or not self.in_window(t_ns):
            return Decision(SKIP)
        s = self.settings
        start, late = False, []
        if self._start_pending:
            if self._start_wait is None or self._start_wait.sample_ns != t_ns:
                self._start_wait = _Wait(t_ns, now)
            # a windowed start needs the applied pitch of its own sample; otherwise any will do
            own = self._windowed or self._start_own_applied
            have = self.applied_ns is not None and (not own or self.applied_ns >= t_ns)
            if not have and now - self._start_wait.since < s.applied_wait:
                return Decision(WAIT, self._start_wait.since + s.applied_wait, waiting_for="applied pitch to start from")
            if not have:
                late.append("applied")
            self._start_pending, self._start_wait, start = False, None, True
            self._start_own_applied = False
        if not self.lockstep:
            return Decision(ANSWER, start=start)
        if not self.heard_reference and s.first_reference_wait > 0:
            if self._first_wait is None:
                self._first_wait = now
            if now - self._first_wait < s.first_reference_wait:
                return Decision(WAIT, self._first_wait + s.first_reference_wait, start, waiting_for="first reference")
            self.heard_reference = True  # waited once: go on with the reference in force
            late.append("reference")
        wait = self._reference_wait_for(t_ns, now)
        if wait is not None:
            return Decision(WAIT, wait, start, tuple(late), "reference stamped for the sample")
        if self._reference_wait is not None:  # waited its limit
            late.append("reference")
            self._reference_wait = None
        if s.needs_applied and self.applied_ns is not None and self.applied_ns < t_ns:
            if self._applied_wait is None or self._applied_wait.sample_ns != t_ns:
                self._applied_wait = _Wait(t_ns, now)
            if now - self._applied_wait.since < s.applied_wait:
                return Decision(WAIT, self._applied_wait.since + s.applied_wait, start, tuple(late),
                                "applied pitch of the sample")
            late.append("applied")
            self._applied_wait = None
        for what in late:
            self.late["references" if what == "reference" else "applied"] += 1
        return Decision(ANSWER, start=start, late=tuple(late))

    def _reference_wait_for(self, t_ns: int, now: float) -> float | None:
        """The wall time to wait until for sample t_k's reference, or None (do not wait)."""
        t = t_ns * 1e-9
        newest, previous, stream = self._newest_reference, self._previous_reference, self.settings.reference_stream
        if self.settings.reference_every_sample:
            streaming = newest is not None and newest < t - 1e-9
        else:
            streaming = not (newest is None or previous is None or newest - previous > stream or newest >= t - 1e-9
                             or newest < t - stream)
        if not streaming:
            self._reference_wait = None
            return None
        if self._reference_wait is None or self._reference_wait.sample_ns != t_ns:
            self._reference_wait = _Wait(t_ns, now)
        until = self._reference_wait.since + self.settings.reference_wait
        return until if now < until else None


class StampGate:
    """Refuse a message stamped far ahead of the graph's time, so that one bad stamp cannot stall a node.

    A velocity reading stamped 10^6 s ahead used to be answered by the controller (the controller
    manager then dropped every real command as older) and taken by the navigator as its newest sample
    (every real one after it was "late" and ignored: the estimate froze). The graph's time is the
    newest accepted stamp (a node need not hear ``/clock``): a stamp more than ``max_jump`` s beyond
    it is refused and counted. Time may go back (a simulator reset): a stamp behind is accepted and
    becomes the new reference. If the graph's time really jumped ahead (a long dropout, a restarted
    source), ``resync_after`` refusals in a row, each within ``max_jump`` of the one before, re-anchor
    the gate there.

    Parameters
    ----------
    max_jump : float
        [s] the largest step ahead accepted.
    resync_after : int
        Consecutive consistent refusals that re-anchor the gate.

    Examples
    --------
    >>> gate = StampGate(max_jump=60.0)
    >>> gate.accept(10_000_000_000), gate.accept(10**6 * 10**9), gate.accept(10_200_000_000)
    (True, False, True)
    >>> gate.refused
    1
    """

    def __init__(self, max_jump: float = 60.0, resync_after: int = 25):
        if not (math.isfinite(max_jump) and max_jump > 0 and resync_after >= 1):
            raise ValueError("max_jump must be a positive number of seconds and resync_after >= 1")
        self.max_jump_ns = int(max_jump * 1e9)
        self.resync_after = int(resync_after)
        self.latest_ns: int | None = None
        self.refused = 0
        self._streak: list[int] = []

    def accept(self, stamp_ns: int) -> bool:
        """True if a message stamped ``stamp_ns`` may be used (then it is the graph's newest time)."""
        stamp_ns = int(stamp_ns)
        if self.latest_ns is None or stamp_ns <= self.latest_ns + self.max_jump_ns:
            if self.latest_ns is None or stamp_ns > self.latest_ns or stamp_ns < self.latest_ns - self.max_jump_ns:
                self.latest_ns = stamp_ns  # newer, or far back (a reset); a little older changes nothing
            self._streak = []
            return True
        if self._streak and abs(stamp_ns - self._streak[-1]) > self.max_jump_ns:
            self._streak = []
        self._streak.append(stamp_ns)
        if len(self._streak) >= self.resync_after:
            self.latest_ns, self._streak = stamp_ns, []
            return True
        self.refused += 1
        return False

    def why(self, stamp_ns: int) -> str:
        """The refusal's reason, for a log line."""
        ahead = (int(stamp_ns) - (self.latest_ns or 0)) * 1e-9
        return (f"stamped {ahead:.6g} s ahead of the graph's time ({(self.latest_ns or 0) * 1e-9:.3f} s), more "
                f"than {self.max_jump_ns * 1e-9:g} s: refused")
