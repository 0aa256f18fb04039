"""The simulator's side of the lockstep protocol: a pure state machine (events in, actions out).

A lockstep simulator publishes ``/clock`` t_k and the samples stamped t_k,
waits for the command stamped t_k, integrates to t_k + T with it held
(fig. 5.1) and publishes t_k+1. :class:`LockstepServer` decides every step
of that protocol; the node shell (``seapup_sim.simulator_node``) feeds it
events with the wall time ``now`` [s, monotonic] and executes the
:class:`Action` list each event returns. Nothing here reads a clock, sleeps,
spins or publishes, so every rule is unit-tested with explicit times.

Rules
-----
- **Start** (:meth:`LockstepServer.gate_ready`): the first sample t_0 is
  published once every awaited subscriber is matched (the shell's subscriber
  gate; a topic listed k times in ``wait_for_subscribers`` needs k). Until
  then the shell polls the gate every :attr:`LockstepServer.GATE_POLL` s and
  a lockstep command is refused (counted ``rejected_future``).
- **Handshake**: until the first command is accepted, ``/clock`` t_k is said
  again every :attr:`LockstepServer.HANDSHAKE_PERIOD` s (:data:`RESEND_CLOCK`:
  ``/clock`` only, no duplicate data for recorders) -- discovery races.
- **Lockstep** (:meth:`LockstepServer.command`): the accepted command stamped
  t_k answers sample k: step (:data:`STEP`) and publish t_k+1
  (:data:`PUBLISH`). A command for another sample changes nothing here (the
  core took it or refused it).
- **Time-out** (:meth:`LockstepServer.tick`): no command stamped t_k within
  ``timeout`` wall seconds of its publication: :data:`TIME_OUT` (count it,
  hold the last command) and go on. ``unanswered`` counts the time-outs in a
  row (a silent controller).
- **Pace**: with ``pace`` > 0 a step waits until
  :class:`~seapup_common.lockstep.pacing.Pacer` says the next sample is due;
  no time-out runs meanwhile.
- **Holds**: the server holds at the current sample -- publishes nothing new,
  steps nothing, runs no time-out, handshake or catch-up -- while

  * ``end_time`` > 0 and the sample t_k >= ``end_time`` is published (a
    recorded experiment ends at exactly ``end_time`` in graph time, however
    late its driver stops the graph);
  * ``start_held``: at t_0 (or wherever it is) until ``end_time`` is set
    (:meth:`LockstepServer.set_end_time`) or :meth:`LockstepServer.play`;
  * paused (:meth:`LockstepServer.pause`) or stopped
    (:meth:`LockstepServer.stop`: rewound to t_0, :data:`RESET`, and held);

  commands are still taken meanwhile. A step request overrides every hold
  until its last sample (see below).
- **Readers of a hold**: whenever the server is held with no reader baseline
  it asks for the matched-reader counts (:data:`POLL_READERS`, answered by
  :meth:`LockstepServer.readers`): who had the held sample. A hold that
  begins with a publication (``end_time``, ``start_held``, a step's last
  sample, a stop) asks right after it; a pause asks when it begins (a reader
  that matched between the publication and the pause is not known as late).
- **Resume** (a later ``end_time``, :meth:`LockstepServer.play`, a step): if
  the command for the held sample came while held, step on at once; else the
  readers are counted again and the held sample is published again, the same
  messages (:data:`REPUBLISH`), only if a reader matched since the hold's
  baseline -- a node that joined while the graph was held. Usually the
  command is just in flight, and saying the sample again would record it
  twice. Then, until it is answered, the readers are polled
  (:data:`POLL_READERS` every :attr:`LockstepServer.READER_POLL` s;
  discovery may lag) and the sample said again whenever one more matched;
  its time-out counts from the resume (with no baseline, e.g. after a
  republish, the sample is said again at once, as a late joiner needs). A
  step from an unanswered hold always says the sample again: a node may
  have become an answerer at the hold with no new subscription (a self-test
  goal, a controller activated after a cancelled step), and a step is asked
  for only once the last one was answered or given up, so no command is in
  flight. So a driver can hold the whole graph
  at an exact sample, act (send a goal, switch a controller) and go on --
  what it does then takes effect at the same sample however busy the
  machine is.
- **Step** (:meth:`LockstepServer.step`, from a hold): advance exactly n
  samples and hold again at t_k+n; :data:`STEP_PROGRESS` after each sample.
  The step is done (:data:`STEP_DONE`) once the graph is held at t_k+n and
  the command stamped t_k+n has come, or the time-out passed for it (counted
  as any time-out): every answerer has answered the held sample. Cancelling
  (:meth:`LockstepServer.cancel_step`) holds at the present sample.
- **Halt** (:meth:`LockstepServer.halt`): the plant diverged; nothing more
  until :meth:`LockstepServer.reset`.
- **Reset** (:meth:`LockstepServer.reset`): back to t_0 (holds and pace
  settings stay; the pace schedule restarts), the commands heard are
  forgotten, t_0 is published (once the gate is open).
- **Wake** (:data:`WAKE_AT`): whenever the next deadline changes the server
  says when the shell must call :meth:`LockstepServer.tick` next (None:
  only events move it). A tick earlier than the deadline does nothing
  harmful, so a shell may keep an earlier timer armed.
- **Control surface** (:meth:`LockstepServer.set_state`, the rules of
  ``simulation_interfaces/srv/SetSimulationState``): the target state
  already in force is refused (:data:`ALREADY`), pausing a stopped
  simulation is an incorrect transition (:data:`INCORRECT`: play or step
  it), playing or pausing a halted plant or playing past an ``end_time``
  fails (:data:`FAILED`); :meth:`LockstepServer.entity_refusal` says why the
  plant's state may not be set now (halted).
- ``lockstep`` False (realtime): the shell's timer calls
  :meth:`LockstepServer.period` once per wall period; each call steps and
  publishes unless held; commands never step.

Samples are counted by index k (``t_k = k * period_ns``); a command answers
the sample whose index its stamp rounds to.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from seapup_common.lockstep.pacing import Pacer

__all__ = ["LockstepServer", "Action", "StepRecord", "StepRefused", "STOPPED", "PLAYING", "PAUSED",
           "STEP", "PUBLISH", "REPUBLISH", "RESEND_CLOCK", "POLL_READERS", "TIME_OUT", "RESET", "WAKE_AT",
           "STEP_PROGRESS", "STEP_DONE", "TransitionRefused", "ALREADY", "INCORRECT", "FAILED", "UNSUPPORTED",
           "INVALID", "NOT_PAUSED", "BUSY", "HALTED", "NOT_STARTED"]

#: simulation_interfaces/msg/SimulationState values
STOPPED, PLAYING, PAUSED = 0, 1, 2

STEP = "step"                  #: integrate one period with the command in force
PUBLISH = "publish"            #: publish the new sample's messages (and /clock)
REPUBLISH = "republish"        #: publish the held sample's messages once more, unchanged
RESEND_CLOCK = "resend_clock"  #: handshake: /clock t_k again, no data
POLL_READERS = "poll_readers"  #: call :meth:`LockstepServer.readers` with the matched-reader counts now
TIME_OUT = "time_out"          #: count a lockstep time-out; the last command stays in force
RESET = "reset"                #: rewind the plant to its start (stop)
WAKE_AT = "wake_at"            #: call :meth:`LockstepServer.tick` at ``at`` (None: no deadline)
STEP_PROGRESS = "step_progress"  #: a step request advanced one sample (``step``)
STEP_DONE = "step_done"        #: a step request ended (``step.outcome``)


#: Why a request was refused (``kind`` of :class:`StepRefused` / :class:`TransitionRefused`).
ALREADY = "already"            #: the target state is the present one
INCORRECT = "incorrect"        #: a transition the standard forbids (pause a stopped simulation)
FAILED = "failed"              #: the transition cannot be made now (halted, held by end_time)
UNSUPPORTED = "unsupported"    #: a state this simulator has no transition to (quitting, worlds)
INVALID = "invalid"            #: a malformed request (a step of 0 samples)
NOT_PAUSED = "not_paused"      #: a step while playing
BUSY = "busy"                  #: a step while another runs
HALTED = "halted"              #: the plant diverged: reset first
NOT_STARTED = "not_started"    #: the first sample is not published yet


class StepRefused(ValueError):
    """A step request the server cannot take now (the reason says what to do; ``kind`` says which rule)."""

    def __init__(self, reason: str, kind: str = INVALID):
        super().__init__(reason)
        self.kind = kind


class TransitionRefused(ValueError):
    """A state change the server refuses (the reason says why; ``kind``: :data:`ALREADY`, :data:`INCORRECT`,
    :data:`FAILED` or :data:`UNSUPPORTED`)."""

    def __init__(self, reason: str, kind: str):
        super().__init__(reason)
        self.kind = kind


@dataclass(frozen=True)
class Action:
    """One thing the shell must do: ``kind`` (:data:`STEP`, :data:`PUBLISH`, ...), ``at`` for
    :data:`WAKE_AT`, ``step`` for :data:`STEP_PROGRESS` / :data:`STEP_DONE`."""

    kind: str
    at: float | None = None
    step: StepRecord | None = None


@dataclass
class StepRecord:
    """A step request: ``requested`` samples from sample ``start_k``; ``done`` so far; ``outcome``
    ``""`` while running, then ``"completed"``, ``"canceled"``, ``"reset"`` or ``"halted"``."""

    requested: int
    start_k: int
    done: int = 0
    outcome: str = ""
    timed_out: bool = field(default=False)

    @property
    def target_k(self) -> int:
        return self.start_k + self.requested


class LockstepServer:
    """The simulator's lockstep protocol (see the module docstring for the rules).

    Parameters
    ----------
    period : float
        Control period T [s simulated].
    lockstep : bool
        Lockstep (True) or realtime (False: :meth:`period` steps, commands never do).
    timeout : float
        Lockstep time-out [s wall] for the command of a sample.
    pace : float
        Publish no faster than this many times real time (0: as fast as the graph answers).
    end_time : float
        Hold once the sample t_k >= ``end_time`` is published [s simulated] (0: run on).
    start_held : bool
        Hold at t_0 until ``end_time`` is set or :meth:`play`.

    Examples
    --------
    >>> server = LockstepServer(0.2, timeout=1.0)
    >>> [a.kind for a in server.gate_ready(now=0.0)]
    ['publish', 'wake_at']
    >>> [a.kind for a in server.command(0, accepted=True, now=0.01)]
    ['step', 'publish', 'wake_at']
    >>> server.t_ns
    200000000
    """

    GATE_POLL = 0.01         #: [s wall] the subscriber gate is polled this often until it opens
    HANDSHAKE_PERIOD = 0.2   #: [s wall] /clock said again until the first command
    READER_POLL = 0.05       #: [s wall] catch-up: matched readers checked this often

    def __init__(self, period: float, *, lockstep: bool = True, timeout: float = 1.0, pace: float = 0.0,
                 end_time: float = 0.0, start_held: bool = False):
        if not (math.isfinite(period) and period > 0):
            raise ValueError(f"the control period must be finite and > 0 s, got {period!r}")
        self.period_ns = int(round(period * 1e9))
        self.lockstep = bool(lockstep)
        self.timeout = self._checked_timeout(timeout)
        self.pacer = Pacer(pace)
        self.end_ns = 0
        self._set_end_ns(end_time)
        self.start_held = bool(start_held)
        self.k = 0
        self.started = False
        self.halted = ""
        self.unanswered = 0
        self.user_hold: int | None = None
        self.stepping: StepRecord | None = None
        self.catch_up = False
        self._answered_k: int | None = None
        self._waiting_since: float | None = None
        self._due_at: float | None = None
        self._handshake = True
        self._last_resend = 0.0
        self._seen: dict | None = None
        self._baseline_asked = False
        self._next_poll: float | None = None
        self._announced: float | None = None

    # -- state -----------------------------------------------------------------------------------
    @property
    def t_ns(self) -> int:
        """The current (published) sample's time [ns simulated]."""
        return self.k * self.period_ns

    @property
    def at_end(self) -> bool:
        """Held by ``end_time`` (its sample or a later one is published) or by ``start_held``."""
        return 0 < self.end_ns <= self.t_ns or self.start_held

    @property
    def held(self) -> bool:
        """No step past the current sample now (a running step request overrides the holds)."""
        if self.stepping is not None:
            return self.k >= self.stepping.target_k
        return self.user_hold is not None or self.at_end

    @property
    def state(self) -> int:
        """:data:`STOPPED`, :data:`PAUSED` (any hold) or :data:`PLAYING`."""
        if self.stepping is None and self.user_hold == STOPPED:
            return STOPPED
        return PAUSED if self.held else PLAYING

    @property
    def takes_commands(self) -> bool:
        """Whether a command may be offered to the core (lockstep: not before t_0 is published)."""
        return self.started or not self.lockstep

    def next_wake(self, now: float) -> float | None:
        """When :meth:`tick` must run next [s wall], or None."""
        if self.halted or not self.lockstep:
            return None
        if not self.started:
            return now + self.GATE_POLL
        if self._due_at is not None:
            return self._due_at
        if self.held:
            final = self.stepping is not None and self._waiting_since is not None
            return self._waiting_since + self.timeout if final else None
        times = [self._waiting_since + self.timeout] if self._waiting_since is not None else []
        if self._handshake:
            times.append(self._last_resend + self.HANDSHAKE_PERIOD)
        if self.catch_up and self._next_poll is not None:
            times.append(self._next_poll)
        return min(times) if times else None

    # -- settings ----------------------------------------------------------------------------------
    def set_timeout(self, timeout: float, now: float) -> list[Action]:
        """A new lockstep time-out [s wall] (it applies to the sample waiting now)."""
        self.timeout = self._checked_timeout(timeout)
        return self._wake([], now)

    @staticmethod
    def _checked_timeout(timeout: float) -> float:
        if not (math.isfinite(timeout) and timeout > 0):
            raise ValueError(f"the lockstep time-out must be finite and > 0 s, got {timeout!r}")
        return float(timeout)

    def set_pace(self, rate: float, now: float) -> list[Action]:
        """A new pace [x real time] (0: unpaced); the schedule restarts at the next sample."""
        self.pacer.rate = rate
        return self._wake([], now)

    def _set_end_ns(self, end_time: float) -> None:
        if not (math.isfinite(end_time) and end_time >= 0):
            raise ValueError(f"end_time must be finite and >= 0 s, got {end_time!r}")
        self.end_ns = int(round(end_time * 1e9))

    # -- events ------------------------------------------------------------------------------------
    def gate_ready(self, now: float) -> list[Action]:
        """Every awaited subscriber is matched: publish t_0."""
        if self.started:
            return []
        self.started = True
        self._waiting_since = now
        self._last_resend = now
        return self._wake([Action(PUBLISH)], now)

    def command(self, stamp_ns: int, accepted: bool, now: float) -> list[Action]:
        """A command stamped ``stamp_ns`` was offered to the core (``accepted``: it took it)."""
        if not accepted or not self.takes_commands:
            return []
        self._handshake = False
        if not (self.lockstep and self.started) or self._index(stamp_ns) != self.k:
            return self._wake([], now)
        self.unanswered = 0
        self._answered_k = self.k
        return self._wake(self._finish_step() + self._advance(now), now)

    def set_end_time(self, end_time: float, now: float) -> list[Action]:
        """A new ``end_time`` [s simulated] (0: run on); it also ends ``start_held``. A later one resumes
        a graph held at its end."""
        was_held = self.held
        self._set_end_ns(end_time)
        self.start_held = False
        if not was_held or self.held or self.halted:
            return self._wake([], now)
        return self._wake(self._resume(now), now)

    def readers(self, counts: dict, now: float) -> list[Action]:
        """The matched-reader count of each published topic (asked for by :data:`POLL_READERS`): the baseline
        of a hold, or (catching up) a comparison with it."""
        counts = dict(counts)
        if self.halted or self._due_at is not None:
            return []
        if self.held:
            if self._seen is None:
                self._seen = counts      # who had the held sample
            return []
        if not self.catch_up:
            return []
        self._next_poll = now + self.READER_POLL
        if self._seen is None:
            self._seen = counts          # the baseline, just after a republish
            return self._wake([], now)
        if any(n > self._seen.get(topic, 0) for topic, n in counts.items()):
            return self._wake(self._republish(now), now)   # a reader matched late: say the sample again
        return self._wake([], now)

    def tick(self, now: float) -> list[Action]:
        """The wall time reached a deadline announced with :data:`WAKE_AT` (or any time: early is harmless).
        Always ends with :data:`WAKE_AT` (the shell's timer has just fired)."""
        self._announced = math.nan
        if self.halted or not self.started or not self.lockstep:
            return self._wake([], now)
        if self._due_at is not None:
            if now < self._due_at:
                return self._wake([], now)
            self._due_at = None
            return self._wake([] if self.held else self._step_now(now), now)
        timed_out = self._waiting_since is not None and now - self._waiting_since >= self.timeout
        if self.held:
            if self.stepping is not None and timed_out:   # the step's last sample: its answer never came
                self.stepping.timed_out = True
                return self._wake(self._time_out() + self._finish_step(), now)
            return self._wake([], now)
        actions: list[Action] = []
        if self.catch_up and self._next_poll is not None and now >= self._next_poll:
            self._next_poll = now + self.READER_POLL
            self._last_resend = now
            actions.append(Action(POLL_READERS))
        if self._handshake and now - self._last_resend >= self.HANDSHAKE_PERIOD:
            self._last_resend = now
            actions.append(Action(RESEND_CLOCK))     # no controller has answered yet: say t_k again
        if timed_out:
            actions += self._time_out() + self._advance(now)
        return self._wake(actions, now)

    def period(self, now: float) -> list[Action]:
        """Realtime: the wall period elapsed; step and publish unless held (or not started)."""
        if self.lockstep or not self.started or self.halted or self.held:
            return []
        return self._step_now(now) + self._finish_step()

    def halt(self, reason: str, now: float) -> list[Action]:
        """The plant diverged (``reason``): step nothing until :meth:`reset`."""
        self.halted = str(reason) or "halted"
        self._due_at = self._waiting_since = None
        return self._wake(self._end_step("halted"), now)

    def reset(self, now: float) -> list[Action]:
        """The plant was reset to t_0: forget the commands heard, publish t_0 (once started)."""
        actions = self._end_step("reset")
        self.k = 0
        self.halted = ""
        self._answered_k, self.unanswered, self.catch_up = None, 0, False
        self._due_at = self._seen = None
        self._baseline_asked = False
        self.pacer.restart()   # the schedule starts again at t = 0
        if self.started:
            actions.append(Action(PUBLISH))
            self._waiting_since = now
        return self._wake(actions, now)

    # -- the control surface (simulation_interfaces) -----------------------------------------------
    def pause(self, now: float) -> list[Action]:
        """Hold at the current sample (:data:`PAUSED`); a running step request is cancelled."""
        actions = self._end_step("canceled")
        self.user_hold = PAUSED
        self._due_at = self._waiting_since = None
        return self._wake(actions, now)

    def play(self, now: float) -> list[Action]:
        """Run on (:data:`PLAYING`): lifts a pause, a stop and ``start_held``; an ``end_time`` reached
        still holds (set a later one)."""
        was_held = self.held
        self.user_hold = None
        self.start_held = False
        if not was_held or self.held or self.halted:
            return self._wake([], now)
        return self._wake(self._resume(now), now)

    def stop(self, now: float) -> list[Action]:
        """Back to the start and held there (:data:`STOPPED`): :data:`RESET` then t_0 published."""
        actions = self._end_step("canceled")
        self.user_hold = STOPPED
        return [Action(RESET)] + actions + self.reset(now)

    def step(self, n: int, now: float) -> list[Action]:
        """Advance exactly ``n`` samples from a hold, then hold again (see the module docstring).

        Raises
        ------
        StepRefused
            ``n`` < 1, the graph is not held (pause first), a step is running, the plant halted, or the
            first sample is not published yet.
        """
        if isinstance(n, bool) or int(n) != n or n < 1:
            raise StepRefused(f"a step is at least one sample, got {n!r}", INVALID)
        if self.halted:
            raise StepRefused(f"the simulation halted ({self.halted}): reset it first", HALTED)
        if not self.started:
            raise StepRefused("the first sample is not published yet (waiting for subscribers)", NOT_STARTED)
        if self.stepping is not None:
            raise StepRefused(f"a step of {self.stepping.requested} sample(s) is running: cancel it first", BUSY)
        if not self.held:
            raise StepRefused("the simulation is playing: pause it first", NOT_PAUSED)
        self.stepping = StepRecord(int(n), self.k)
        if self.user_hold == STOPPED:
            self.user_hold = PAUSED
        return self._wake([Action(STEP_PROGRESS, step=self.stepping)] + self._resume(now), now)

    def set_state(self, target: int, now: float) -> list[Action]:
        """Go to ``target`` (:data:`STOPPED`, :data:`PLAYING` or :data:`PAUSED`), the rules of
        ``simulation_interfaces/srv/SetSimulationState``.

        Raises
        ------
        TransitionRefused
            Already in ``target`` (:data:`ALREADY`); pausing a stopped simulation (:data:`INCORRECT`); playing or
            pausing a halted plant, or playing at an ``end_time`` hold (:data:`FAILED`); any other target
            (:data:`UNSUPPORTED`).
        """
        names = {STOPPED: "stopped", PLAYING: "playing", PAUSED: "paused"}
        if target not in names:
            raise TransitionRefused(f"state {target!r} is not supported (only stopped {STOPPED}, playing "
                                    f"{PLAYING} and paused {PAUSED})", UNSUPPORTED)
        if target == self.state:
            raise TransitionRefused(f"the simulation is {names[target]} already", ALREADY)
        if target == PAUSED and self.state == STOPPED:
            raise TransitionRefused("a stopped simulation cannot be paused: play it, or step it", INCORRECT)
        if target == STOPPED:
            return self.stop(now)
        if self.halted:
            raise TransitionRefused(f"the simulation halted ({self.halted}): stop or reset it first", FAILED)
        if target == PAUSED:
            return self.pause(now)
        if self.stepping is None and 0 < self.end_ns <= self.t_ns:
            raise TransitionRefused(f"held at end_time {self.end_ns * 1e-9:g} s: set a later end_time (0: none) "
                                    "or step", FAILED)
        return self.play(now)

    def entity_refusal(self) -> str:
        """Why the plant's state may not be set now ('' when it may: any state but halted; the change takes
        effect from the present sample)."""
        if self.halted:
            return f"the simulation halted ({self.halted}): reset it first"
        return ""

    def cancel_step(self, now: float) -> list[Action]:
        """Cancel a running step request: hold at the present sample."""
        if self.stepping is None:
            return []
        actions = self._end_step("canceled")
        if self.user_hold is None:
            self.user_hold = PAUSED
        self._due_at = self._waiting_since = None
        return self._wake(actions, now)

    # -- rules -------------------------------------------------------------------------------------
    def _index(self, stamp_ns: int) -> int:
        return int(round(int(stamp_ns) / self.period_ns))

    def _advance(self, now: float) -> list[Action]:
        """Step on now, or schedule it when the pace says (no time-out meanwhile)."""
        if self.halted or not self.started or self.held or self._due_at is not None:
            return []
        delay = self.pacer.delay((self.k + 1) * self.period_ns * 1e-9, now)
        if delay > 0.0:
            self._due_at = now + delay
            self._waiting_since = None
            return []
        return self._step_now(now)

    def _step_now(self, now: float) -> list[Action]:
        self.k += 1
        self._waiting_since = now
        self.catch_up = False
        self._seen = self._next_poll = None
        self._baseline_asked = False
        actions = [Action(STEP), Action(PUBLISH)]
        if self.stepping is not None:
            self.stepping.done = self.k - self.stepping.start_k
            actions.append(Action(STEP_PROGRESS, step=self.stepping))
        return actions

    def _time_out(self) -> list[Action]:
        self.unanswered += 1
        self._answered_k = self.k      # the time-out is the answer: the last command holds
        self._waiting_since = None
        return [Action(TIME_OUT)]

    def _resume(self, now: float) -> list[Action]:
        """Go on from a hold: step at once if the held sample was answered, else say it again."""
        if not (self.lockstep and self.started) or self.halted:
            return []
        if self._answered_k == self.k:
            return self._finish_step() + self._advance(now)
        self.catch_up = True
        self._waiting_since = now       # its time-out counts from now
        # no baseline (a late joiner may need it), or a step: a node may have become an answerer while held
        # without a new subscription (a self-test goal sent at the hold, a controller activated there after
        # a cancelled step), and only the sample said again reaches it; a step is asked for only once the
        # previous one was answered or given up, so no command of this sample is in flight (a recorder keeps
        # one copy of a sample said again: docs/recording.md)
        if self._seen is None or self.stepping is not None:
            return self._republish(now)
        self._last_resend = now
        self._next_poll = now + self.READER_POLL
        return [Action(POLL_READERS)]   # said again only if a reader matched since the hold began

    def _republish(self, now: float) -> list[Action]:
        self._seen = None               # the counts right after it are the new baseline
        self._baseline_asked = False
        self._last_resend = now
        self._next_poll = now + self.READER_POLL
        return [Action(REPUBLISH), Action(POLL_READERS)]

    def _finish_step(self) -> list[Action]:
        """Done once held at its last sample with that sample answered (or timed out; realtime: reached)."""
        s = self.stepping
        if s is None or self.k < s.target_k:
            return []
        if self.lockstep and self._answered_k != self.k:
            return []
        return self._end_step("completed")

    def _end_step(self, outcome: str) -> list[Action]:
        s, self.stepping = self.stepping, None
        if s is None:
            return []
        s.outcome = outcome
        return [Action(STEP_DONE, step=s)]

    def _wake(self, actions: list[Action], now: float) -> list[Action]:
        if (self.lockstep and self.started and not self.halted and self.held and self._seen is None
                and not self._baseline_asked and self._due_at is None):
            self._baseline_asked = True
            actions.append(Action(POLL_READERS))   # the hold's baseline: who had the held sample
        at = self.next_wake(now)
        if at != self._announced:
            self._announced = at
            actions.append(Action(WAKE_AT, at=at))
        return actions
