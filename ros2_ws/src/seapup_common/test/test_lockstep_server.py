"""The simulator's side of the lockstep protocol (seapup_common.lockstep.server), with explicit wall times.

First every rule on its own, then whole protocol runs in one process: the server, a trivial plant,
answering controllers built on :class:`~seapup_common.lockstep.SamplePolicy`, a recorder and a
discrete-event loop that delivers every message a millisecond after it is sent. The independent truth
is the unpaced, never-held run of the same plant and law: every hold, pause, step and late joiner must
give exactly its samples and commands.
"""
import heapq
import itertools

import pytest

from seapup_common.lockstep import ANSWER, SamplePolicy, WaitSettings
from seapup_common.lockstep.server import (PAUSED, PLAYING, POLL_READERS, PUBLISH, REPUBLISH, RESEND_CLOCK,
                                           RESET, STEP, STEP_DONE, STEP_PROGRESS, STOPPED, TIME_OUT, WAKE_AT,
                                           LockstepServer, StepRefused)

pytestmark = pytest.mark.unit

T = 0.2
MS = 1_000_000  # ns


def kinds(actions):
    return [a.kind for a in actions if a.kind != WAKE_AT]


def wake(actions):
    """The last WAKE_AT announced in ``actions`` (``...`` if none)."""
    at = [a.at for a in actions if a.kind == WAKE_AT]
    return at[-1] if at else ...


def started(**kwargs) -> LockstepServer:
    server = LockstepServer(T, **kwargs)
    assert kinds(server.gate_ready(now=0.0)) == [PUBLISH]
    return server


# -- the rules, one by one ----------------------------------------------------------------------------
def test_nothing_is_published_before_the_gate_opens_and_the_gate_is_polled_meanwhile():
    server = LockstepServer(T)
    assert not server.takes_commands                          # a lockstep command now is refused
    assert kinds(server.tick(now=0.5)) == [] and wake(server.tick(now=0.5)) == pytest.approx(0.5 + server.GATE_POLL)
    assert kinds(server.command(0, accepted=True, now=0.5)) == []
    actions = server.gate_ready(now=1.0)
    assert kinds(actions) == [PUBLISH] and wake(actions) == pytest.approx(1.0 + server.HANDSHAKE_PERIOD)
    assert server.takes_commands and server.t_ns == 0
    assert server.gate_ready(now=1.1) == []                     # opens once


def test_the_command_stamped_t_k_steps_and_publishes_t_k_plus_1_and_others_do_not():
    server = started()
    assert kinds(server.command(200 * MS, accepted=True, now=0.01)) == []   # for another sample
    assert kinds(server.command(0, accepted=False, now=0.01)) == []         # refused by the core
    assert kinds(server.command(0, accepted=True, now=0.02)) == [STEP, PUBLISH]
    assert server.t_ns == 200 * MS
    assert kinds(server.command(200 * MS + 3, accepted=True, now=0.03)) == [STEP, PUBLISH]  # its stamp rounds to k


def test_the_handshake_says_the_clock_again_until_the_first_accepted_command():
    server = started(timeout=10.0)
    assert kinds(server.tick(now=0.1)) == []
    assert kinds(server.tick(now=0.2)) == [RESEND_CLOCK]
    assert wake(server.tick(now=0.25)) == pytest.approx(0.4)
    assert kinds(server.tick(now=0.4)) == [RESEND_CLOCK]
    server.command(0, accepted=True, now=0.45)
    assert kinds(server.tick(now=1.0)) == [] and kinds(server.tick(now=5.0)) == []   # never again


def test_a_sample_not_answered_within_the_timeout_times_out_and_the_graph_goes_on():
    server = started(timeout=0.5)
    server.command(0, accepted=True, now=0.0)                     # handshake over; t_1 published at 0.0
    assert kinds(server.tick(now=0.49)) == []
    assert wake(server.tick(now=0.49)) == pytest.approx(0.5)
    assert kinds(server.tick(now=0.5)) == [TIME_OUT, STEP, PUBLISH]
    assert server.unanswered == 1 and server.t_ns == 400 * MS
    assert kinds(server.tick(now=1.0)) == [TIME_OUT, STEP, PUBLISH] and server.unanswered == 2
    server.command(600 * MS, accepted=True, now=1.1)
    assert server.unanswered == 0                                 # answered again: not silent any more
    server.set_timeout(2.0, now=1.1)
    assert kinds(server.tick(now=2.0)) == [] and kinds(server.tick(now=3.1)) == [TIME_OUT, STEP, PUBLISH]
    with pytest.raises(ValueError, match="time-out"):
        server.set_timeout(0.0, now=3.2)


def test_a_paced_step_waits_for_its_wall_time_with_no_time_out_meanwhile():
    server = started(timeout=0.05, pace=1.0)
    assert kinds(server.command(0, accepted=True, now=0.0)) == [STEP, PUBLISH]   # the first sets the schedule
    actions = server.command(200 * MS, accepted=True, now=0.01)
    assert kinds(actions) == [] and wake(actions) == pytest.approx(0.2)         # t_2 is due at 0.4 - 0.2
    assert kinds(server.tick(now=0.15)) == []                                     # no time-out while pacing
    assert kinds(server.tick(now=0.2)) == [STEP, PUBLISH] and server.t_ns == 400 * MS
    server.set_pace(0.0, now=0.21)
    assert kinds(server.command(400 * MS, accepted=True, now=0.21)) == [STEP, PUBLISH]


def test_end_time_holds_at_its_sample_and_commands_are_still_taken():
    server = started(timeout=0.5, end_time=0.4)
    server.command(0, accepted=True, now=0.0)
    assert kinds(server.command(200 * MS, accepted=True, now=0.01)) == [STEP, PUBLISH, POLL_READERS]  # baseline
    assert server.held and server.at_end and server.state == PAUSED and server.t_ns == 400 * MS
    assert server.readers({"sensors/velocity": 1}, now=0.01) == []
    assert wake(server.tick(now=0.02)) is None                    # nothing to wake for: no time-out while held
    assert kinds(server.tick(now=100.0)) == []
    assert kinds(server.command(400 * MS, accepted=True, now=100.0)) == []     # taken, not stepped
    assert kinds(server.set_end_time(0.6, now=101.0)) == [STEP, PUBLISH, POLL_READERS]   # answered meanwhile: on
    assert server.t_ns == 600 * MS and server.held
    assert server.readers({"sensors/velocity": 1}, now=101.0) == []
    assert kinds(server.set_end_time(0.6, now=102.0)) == []       # not later than the held sample: still held
    assert kinds(server.set_end_time(0.0, now=103.0)) == [POLL_READERS]   # 0: run on; readers counted again
    assert kinds(server.readers({"sensors/velocity": 1}, now=103.0)) == []   # nobody new: not said again


def test_a_resume_at_an_unanswered_sample_republishes_it_for_late_readers_until_answered():
    server = started(timeout=1.0, end_time=0.2)
    server.command(0, accepted=True, now=0.0)
    actions = server.set_end_time(1.0, now=10.0)
    assert kinds(actions) == [REPUBLISH, POLL_READERS] and server.catch_up
    assert server.readers({"sensors/velocity": 1}, now=10.0) == []                  # the baseline
    assert wake(server.tick(now=10.01)) == pytest.approx(10.0 + server.READER_POLL)
    assert kinds(server.tick(now=10.05)) == [POLL_READERS]
    assert kinds(server.readers({"sensors/velocity": 1}, now=10.05)) == []          # nobody new
    assert kinds(server.readers({"sensors/velocity": 2}, now=10.1)) == [REPUBLISH, POLL_READERS]  # a late reader
    assert kinds(server.tick(now=10.99)) == [POLL_READERS]
    assert kinds(server.tick(now=11.0)) == [TIME_OUT, STEP, PUBLISH]               # counted from the resume
    assert not server.catch_up
    assert server.readers({"sensors/velocity": 3}, now=11.0) == []                # no catch-up any more


def test_start_held_holds_at_t_0_until_end_time_is_set():
    server = LockstepServer(T, start_held=True, timeout=0.5)
    assert kinds(server.gate_ready(now=0.0)) == [PUBLISH, POLL_READERS]     # held: the hold's baseline
    assert server.held and server.at_end
    assert kinds(server.command(0, accepted=True, now=0.1)) == []
    assert kinds(server.tick(now=5.0)) == []
    assert kinds(server.set_end_time(0.4, now=6.0)) == [STEP, PUBLISH]
    assert not server.start_held


def test_a_start_held_lifted_before_the_gate_opens_just_runs():
    server = LockstepServer(T, start_held=True)
    assert kinds(server.set_end_time(0.0, now=0.0)) == []
    assert kinds(server.gate_ready(now=0.1)) == [PUBLISH] and not server.held


def test_pause_holds_and_play_resumes_like_an_end_time():
    server = started(timeout=0.5)
    server.command(0, accepted=True, now=0.0)
    assert server.state == PLAYING
    server.pause(now=0.01)
    assert server.state == PAUSED
    assert kinds(server.command(200 * MS, accepted=True, now=0.02)) == []
    assert kinds(server.tick(now=9.0)) == []
    assert kinds(server.play(now=10.0)) == [STEP, PUBLISH] and server.state == PLAYING
    server.pause(now=10.1)
    assert kinds(server.play(now=11.0)) == [REPUBLISH, POLL_READERS]          # t_2 unanswered: said again
    assert kinds(server.play(now=11.1)) == []                                  # playing already


def test_play_does_not_pass_an_end_time():
    server = started(end_time=0.2)
    server.command(0, accepted=True, now=0.0)
    assert kinds(server.play(now=1.0)) == [] and server.state == PAUSED


def test_stop_rewinds_to_t_0_and_holds():
    server = started()
    server.command(0, accepted=True, now=0.0)
    actions = server.stop(now=0.1)
    assert kinds(actions) == [RESET, PUBLISH, POLL_READERS] and server.t_ns == 0 and server.state == STOPPED
    assert kinds(server.command(0, accepted=True, now=0.2)) == []
    assert kinds(server.play(now=0.3)) == [STEP, PUBLISH]


def test_a_step_advances_exactly_n_samples_and_is_done_when_the_last_is_answered():
    server = started(timeout=0.5)
    server.pause(now=0.0)
    server.command(0, accepted=True, now=0.0)
    with pytest.raises(StepRefused, match="at least one"):
        server.step(0, now=0.0)
    actions = server.step(2, now=0.1)
    assert kinds(actions) == [STEP_PROGRESS, STEP, PUBLISH, STEP_PROGRESS]
    record = actions[0].step
    assert record.requested == 2 and record.done == 1 and server.state == PLAYING
    with pytest.raises(StepRefused, match="running"):
        server.step(1, now=0.1)
    actions = server.command(200 * MS, accepted=True, now=0.2)
    assert kinds(actions) == [STEP, PUBLISH, STEP_PROGRESS, POLL_READERS] and record.done == 2
    assert record.outcome == ""
    assert kinds(server.tick(now=0.3)) == []                      # held at t_k+n, waiting for its answer
    actions = server.command(400 * MS, accepted=True, now=0.4)
    assert kinds(actions) == [STEP_DONE] and record.outcome == "completed" and server.state == PAUSED
    assert kinds(server.play(now=0.5)) == [STEP, PUBLISH]        # its last sample was answered: on at once
    with pytest.raises(StepRefused, match="pause"):
        server.step(1, now=0.5)


def test_a_step_whose_last_answer_never_comes_ends_at_its_time_out():
    server = started(timeout=0.5)
    server.pause(now=0.0)
    server.command(0, accepted=True, now=0.0)
    record = server.step(1, now=1.0)[0].step
    assert wake(server.tick(now=1.1)) == pytest.approx(1.5)
    actions = server.tick(now=1.5)
    assert kinds(actions) == [TIME_OUT, STEP_DONE] and record.outcome == "completed" and record.timed_out
    assert server.t_ns == 200 * MS and server.state == PAUSED
    assert kinds(server.play(now=2.0)) == [STEP, PUBLISH]        # the last command holds


def test_a_step_cancelled_or_reset_holds_where_it_is():
    server = started(timeout=0.5)
    server.pause(now=0.0)
    assert kinds(server.step(3, now=0.0)) == [STEP_PROGRESS, REPUBLISH, POLL_READERS]   # t_0 unanswered yet
    record = server.stepping
    server.command(0, accepted=True, now=0.1)
    actions = server.cancel_step(now=0.2)
    assert kinds(actions) == [STEP_DONE, POLL_READERS] and record.outcome == "canceled" and record.done == 1
    assert server.state == PAUSED and kinds(server.tick(now=5.0)) == []
    record = server.step(2, now=6.0)[0].step
    assert kinds(server.reset(now=6.1)) == [STEP_DONE, PUBLISH, POLL_READERS] and record.outcome == "reset"
    assert server.t_ns == 0 and server.state == PAUSED


def test_a_step_from_stopped_or_from_an_end_time_hold():
    server = started(end_time=0.2, timeout=0.5)
    server.command(0, accepted=True, now=0.0)
    assert server.held and server.state == PAUSED
    record = server.step(2, now=1.0)[0].step
    assert server.t_ns == 200 * MS and record.done == 0          # t_1 unanswered: republished first
    server.command(200 * MS, accepted=True, now=1.1)
    server.command(400 * MS, accepted=True, now=1.2)
    server.command(600 * MS, accepted=True, now=1.3)
    assert record.outcome == "completed" and server.t_ns == 600 * MS and server.held   # end_time holds again
    server.stop(now=2.0)
    assert server.state == STOPPED
    server.step(1, now=2.1)
    assert server.state == PLAYING


def test_a_halted_plant_steps_nothing_until_reset():
    server = started(timeout=0.5)
    assert kinds(server.halt("diverged", now=0.0)) == [] and server.halted
    assert kinds(server.command(0, accepted=True, now=0.1)) == [] and kinds(server.tick(now=9.0)) == []
    with pytest.raises(StepRefused, match="halted"):
        server.step(1, now=9.0)
    assert kinds(server.reset(now=10.0)) == [PUBLISH] and not server.halted
    assert kinds(server.command(0, accepted=True, now=10.1)) == [STEP, PUBLISH]


def test_reset_forgets_the_answer_and_restarts_the_pace():
    server = started(timeout=0.5, pace=1.0)
    server.command(0, accepted=True, now=0.0)
    server.command(200 * MS, accepted=True, now=0.0)
    assert server.t_ns == 200 * MS
    assert kinds(server.reset(now=5.0)) == [PUBLISH]
    assert server.t_ns == 0 and server.unanswered == 0
    assert kinds(server.command(0, accepted=True, now=5.0)) == [STEP, PUBLISH]   # a new schedule


def test_realtime_steps_on_each_period_and_holds_at_end_time():
    server = LockstepServer(T, lockstep=False, end_time=0.4)
    assert server.takes_commands and kinds(server.period(now=0.0)) == []
    server.gate_ready(now=0.0)
    assert kinds(server.command(0, accepted=True, now=0.0)) == []
    assert kinds(server.period(now=0.2)) == [STEP, PUBLISH]
    assert kinds(server.period(now=0.4)) == [STEP, PUBLISH] and kinds(server.period(now=0.6)) == []
    record = server.step(2, now=1.0)[0].step
    server.period(now=1.2)
    assert kinds(server.period(now=1.4)) == [STEP, PUBLISH, STEP_PROGRESS, STEP_DONE]
    assert record.outcome == "completed" and server.t_ns == 800 * MS


def test_settings_are_checked():
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="period"):
            LockstepServer(bad)
    with pytest.raises(ValueError, match="end_time"):
        LockstepServer(T, end_time=-1.0)
    with pytest.raises(ValueError, match="pace"):
        LockstepServer(T, pace=float("inf"))


# -- whole protocol runs ------------------------------------------------------------------------------
class World:
    """The simulator's shell, its plant (x' = u), the middleware (1 ms latency) and a wall clock."""

    LATENCY = 0.001
    TOPIC = "sensors/velocity"

    def __init__(self, server: LockstepServer, x0: float = 1.0):
        self.server, self.x0, self.x, self.u = server, x0, x0, 0.0
        self.now = 0.0
        self._queue: list = []
        self._order = itertools.count()
        self._timer = 0
        self.readers: list = []
        self.sent: tuple | None = None
        self.published: list[tuple[int, float]] = []
        self.commands: list[tuple[int, float]] = []
        self.time_outs = 0
        self.steps: list = []

    # middleware and clock
    def later(self, delay, fn, *args):
        heapq.heappush(self._queue, (self.now + delay, next(self._order), fn, args))

    def run(self, until=None, done=lambda: False, limit=100_000):
        for _ in range(limit):
            if done() or not self._queue or (until is not None and self._queue[0][0] > until):
                break
            at, _, fn, args = heapq.heappop(self._queue)
            self.now = max(self.now, at)
            fn(*args)
        else:
            raise AssertionError("the protocol run did not settle")
        if until is not None:
            self.now = max(self.now, until)

    def counts(self):
        return {self.TOPIC: sum(r.matched for r in self.readers)}

    # the shell: execute the server's actions
    def execute(self, actions):
        for action in actions:
            if action.kind == STEP:
                self.x += T * self.u
            elif action.kind == PUBLISH:
                self.sent = (self.server.t_ns, self.x)
                self.published.append(self.sent)
                self._send(clock=True, sample=True)
            elif action.kind == REPUBLISH:
                self._send(clock=True, sample=True)
            elif action.kind == RESEND_CLOCK:
                self._send(clock=True, sample=False)
            elif action.kind == POLL_READERS:
                self.execute(self.server.readers(self.counts(), self.now))
            elif action.kind == TIME_OUT:
                self.time_outs += 1
            elif action.kind == RESET:
                self.x, self.u = self.x0, 0.0
            elif action.kind in (STEP_PROGRESS, STEP_DONE):
                self.steps.append((action.kind, action.step.done, action.step.outcome))
            elif action.kind == WAKE_AT:
                self._timer += 1
                if action.at is not None:
                    self.later(max(0.0, action.at - self.now), self._tick, self._timer)

    def _tick(self, timer):
        if timer == self._timer:
            self.execute(self.server.tick(self.now))

    def _send(self, clock, sample):
        t_ns, x = self.sent
        for reader in [r for r in self.readers if r.matched]:
            if clock:
                self.later(self.LATENCY, reader.on_clock, t_ns)
            if sample:
                self.later(self.LATENCY, reader.on_sample, t_ns, x)

    def open(self):
        self.execute(self.server.gate_ready(self.now))

    def command(self, stamp_ns, u):
        self.later(self.LATENCY, self._on_command, stamp_ns, u)

    def _on_command(self, stamp_ns, u):
        accepted = self.server.takes_commands and round(stamp_ns / self.server.period_ns) == self.server.k
        if accepted:   # the core: neither stale nor from the future
            self.u = u
            self.commands.append((stamp_ns, u))
        self.execute(self.server.command(stamp_ns, accepted, self.now))

    def call(self, event, *args):
        self.execute(getattr(self.server, event)(*args, now=self.now))


class Controller:
    """A velocity controller's timing (SamplePolicy) with the law u = -x; answers its window."""

    def __init__(self, world: World, start_at=0.0, stop_at=0.0, matched=True):
        self.world, self.matched, self.alive = world, matched, True
        self.policy = SamplePolicy(True, WaitSettings(applied_wait=0.0, reference_wait=0.0, start_at=start_at,
                                                      stop_at=stop_at))
        self.policy.activate(heard_applied=True)
        self.readings: dict[int, float] = {}
        self.answered: list[int] = []
        world.readers.append(self)

    def on_clock(self, t_ns):
        pending = self.policy.on_clock(t_ns)
        if pending is not None:
            self._decide(pending)

    def on_sample(self, t_ns, x):
        self.readings[t_ns] = x
        pending = self.policy.on_sample(t_ns)
        if pending is not None:
            self._decide(pending)

    def _decide(self, t_ns):
        if self.alive and self.policy.decide(t_ns, self.world.now).action == ANSWER:
            self.policy.answered(t_ns)
            self.answered.append(t_ns)
            self.world.command(t_ns, -self.readings[t_ns])

    def die(self):
        self.alive = self.matched = False


class Recorder:
    def __init__(self, world: World):
        self.matched, self.heard = True, []
        world.readers.append(self)

    def on_clock(self, t_ns):
        pass

    def on_sample(self, t_ns, x):
        self.heard.append((t_ns, x))


def reference_run(samples: int, x0: float = 1.0):
    """The unpaced, never-held loop: samples (t_k, x_k) and commands (t_k, u_k) for k < samples."""
    x, published, commands = x0, [], []
    for k in range(samples):
        published.append((k * 200 * MS, x))
        commands.append((k * 200 * MS, -x))
        x += T * -x
    return published, commands


def test_a_whole_run_with_holds_a_late_joiner_a_dying_controller_and_a_recorder():
    server = LockstepServer(T, timeout=0.5, end_time=2.0)
    world = World(server)
    recorder = Recorder(world)
    first = Controller(world, stop_at=2.0)                 # answers [0, 2 s)
    last = Controller(world, start_at=3.0)                 # in the graph from the start, answers [3 s, ...)
    world.open()
    world.run(done=lambda: server.held and server.t_ns == 2_000 * MS and not world._queue)
    assert server.t_ns == 2_000 * MS and world.time_outs == 0
    published, commands = reference_run(10)
    assert world.published == published + [(2_000 * MS, pytest.approx(published[-1][1] * 0.8))]
    assert world.commands == commands                      # every sample answered once, in order

    # held at 2.0 s: nobody answers it; a controller for [2 s, 3 s) is started, its reader matches late
    joiner = Controller(world, start_at=2.0, stop_at=3.0, matched=False)
    world.run(until=world.now + 30.0)
    assert server.t_ns == 2_000 * MS and world.time_outs == 0          # held: no time-out
    world.call("set_end_time", 5.0)                                      # resume: t = 2 s said again ...
    world.later(0.03, setattr, joiner, "matched", True)                  # ... before the joiner matched
    world.run(done=lambda: server.t_ns == 2_400 * MS)
    assert joiner.answered[:2] == [2_000 * MS, 2_200 * MS] and world.time_outs == 0   # heard after a catch-up

    # the joiner dies after answering 2.6 s: 2.8 s times out (last command held), then the other goes on
    world.run(done=lambda: server.t_ns == 2_800 * MS)
    joiner.die()
    world.run(done=lambda: server.held and server.t_ns == 5_000 * MS and not world._queue)
    assert world.time_outs == 1 and server.unanswered == 0
    assert joiner.answered == [t * MS for t in range(2_000, 2_800, 200)]
    assert last.answered == [t * MS for t in range(3_000, 5_001, 200)]   # the held sample too
    assert first.answered == [t * MS for t in range(0, 2_000, 200)]
    assert world.commands[-1][0] == 5_000 * MS and (2_800 * MS) not in dict(world.commands)
    x_held = dict(world.published)[2_800 * MS]
    assert dict(world.published)[3_000 * MS] == pytest.approx(x_held + T * dict(world.commands)[2_600 * MS])

    # the recorder was in the gate: it heard every sample (the republished one twice), missed none
    assert sorted(set(t for t, _ in recorder.heard)) == [t for t, _ in world.published]
    assert len(world.published) == 26


def test_pause_play_and_steps_in_uneven_chunks_give_the_unpaced_run():
    paced = LockstepServer(T, timeout=0.5, start_held=True, pace=2.0)
    world = World(paced)
    Controller(world)
    recorder = Recorder(world)
    world.open()
    world.run(until=1.0)
    for n in (1, 3, 2, 4):
        world.call("step", n)
        world.run(done=lambda: world.steps and world.steps[-1][0] == STEP_DONE)
        assert world.steps[-1] == (STEP_DONE, n, "completed") and paced.state == PAUSED
    assert [s for s in world.steps if s[0] == STEP_PROGRESS][-4:] == [(STEP_PROGRESS, i, "") for i in range(1, 5)]
    assert paced.t_ns == 2_000 * MS
    world.call("play")
    world.run(until=world.now + 0.5)
    world.call("pause")
    world.run(until=world.now + 10.0)
    held = paced.t_ns
    world.call("play")
    world.run(done=lambda: paced.t_ns == 4_000 * MS)
    world.call("pause")
    world.run(until=world.now + 1.0)
    assert world.time_outs == 0 and held < 4_000 * MS
    published, commands = reference_run(21)
    assert world.published[:21] == published             # the same arithmetic: equal bit for bit
    assert world.commands[:21] == commands
    assert sorted(set(t for t, _ in recorder.heard)) == [t for t, _ in world.published]


def test_a_reset_run_repeats_the_first_run():
    server = LockstepServer(T, timeout=0.5, end_time=1.0)
    world = World(server)
    Controller(world)
    world.open()
    world.run(done=lambda: server.held and not world._queue)
    first = list(world.published)
    world.execute([a for a in server.stop(now=world.now)])
    assert server.state == STOPPED and world.published[-1] == first[0]
    world.call("play")
    world.run(done=lambda: server.held and server.t_ns == 1_000 * MS and not world._queue)
    assert world.published[len(first):] == first and world.time_outs == 0


def test_a_resume_at_a_sample_whose_command_is_in_flight_says_nothing_again():
    """The bag-invariance case: held at end_time, resumed before the held sample's command arrived -- nobody
    joined, so the sample is not said again (a recorder would have it twice); the command then steps on."""
    server = started(timeout=1.0, end_time=0.2)
    assert kinds(server.command(0, accepted=True, now=0.0)) == [STEP, PUBLISH, POLL_READERS]
    server.readers({"sensors/velocity": 2}, now=0.0)                       # the hold's baseline
    assert kinds(server.set_end_time(1.0, now=5.0)) == [POLL_READERS] and server.catch_up
    assert kinds(server.readers({"sensors/velocity": 2}, now=5.0)) == []   # nobody new
    assert kinds(server.command(200 * MS, accepted=True, now=5.01)) == [STEP, PUBLISH]


def test_a_reader_that_joined_during_the_hold_gets_the_held_sample_again_at_the_resume():
    server = started(timeout=1.0)
    server.command(0, accepted=True, now=0.0)
    assert kinds(server.pause(now=0.1)) == [POLL_READERS]
    server.readers({"sensors/velocity": 1}, now=0.1)
    assert kinds(server.set_state(PLAYING, now=3.0)) == [POLL_READERS]
    assert kinds(server.readers({"sensors/velocity": 2}, now=3.0)) == [REPUBLISH, POLL_READERS]


def test_set_state_follows_the_standard_transitions():
    from seapup_common.lockstep.server import ALREADY, FAILED, INCORRECT, UNSUPPORTED, TransitionRefused
    server = started(timeout=0.5)
    server.command(0, accepted=True, now=0.0)
    for target, kind in ((PLAYING, ALREADY), (3, UNSUPPORTED)):
        with pytest.raises(TransitionRefused) as refused:
            server.set_state(target, now=0.1)
        assert refused.value.kind == kind
    assert kinds(server.set_state(STOPPED, now=0.2))[:2] == [RESET, PUBLISH] and server.state == STOPPED
    with pytest.raises(TransitionRefused, match="stopped") as refused:
        server.set_state(PAUSED, now=0.3)                          # pausing when stopped
    assert refused.value.kind == INCORRECT and server.state == STOPPED
    server.set_state(PLAYING, now=0.4)
    assert server.state == PLAYING
    server.set_state(PAUSED, now=0.5)
    assert server.state == PAUSED and server.entity_refusal() == ""
    server.halt("diverged", now=0.6)
    assert "halted" in server.entity_refusal()
    with pytest.raises(TransitionRefused, match="halted") as refused:
        server.set_state(PLAYING, now=0.7)
    assert refused.value.kind == FAILED
    server.set_state(STOPPED, now=0.8)                             # a stop resets: the halt is over
    assert not server.halted and server.state == STOPPED and server.t_ns == 0


def test_playing_at_an_end_time_hold_fails_and_changes_nothing():
    from seapup_common.lockstep.server import FAILED, TransitionRefused
    server = started(end_time=0.2)
    server.command(0, accepted=True, now=0.0)
    with pytest.raises(TransitionRefused, match="end_time") as refused:
        server.set_state(PLAYING, now=1.0)
    assert refused.value.kind == FAILED and server.state == PAUSED and server.user_hold is None


def test_step_refusals_say_which_rule():
    from seapup_common.lockstep.server import BUSY, HALTED, INVALID, NOT_PAUSED, NOT_STARTED
    with pytest.raises(StepRefused) as refused:
        LockstepServer(T).step(1, now=0.0)
    assert refused.value.kind == NOT_STARTED
    server = started(timeout=0.5)
    for n, kind in ((0, INVALID), (1, NOT_PAUSED)):
        with pytest.raises(StepRefused) as refused:
            server.step(n, now=0.0)
        assert refused.value.kind == kind
    server.pause(now=0.0)
    server.step(2, now=0.0)
    with pytest.raises(StepRefused) as refused:
        server.step(1, now=0.0)
    assert refused.value.kind == BUSY
    server.halt("diverged", now=0.1)
    with pytest.raises(StepRefused) as refused:
        server.step(1, now=0.2)
    assert refused.value.kind == HALTED


def test_a_step_from_an_unanswered_hold_says_the_held_sample_again_with_no_new_reader():
    """A node that became an answerer at the hold without a new subscription (a self-test goal sent there)
    hears the held sample only if it is said again: a step from an unanswered hold republishes at once, while
    a play with no new reader only polls the readers (a command may be in flight)."""
    from seapup_common.lockstep.server import LockstepServer, REPUBLISH
    for resume in ("step", "play"):
        server = LockstepServer(0.2, timeout=10.0)
        server.gate_ready(now=0.0)
        server.pause(now=0.0)
        server.readers({"/a": 1}, now=0.1)        # the baseline: nobody joins afterwards
        actions = server.step(2, now=0.5) if resume == "step" else server.play(now=0.5)
        kinds = [a.kind for a in actions]
        assert (REPUBLISH in kinds) == (resume == "step"), (resume, kinds)
