"""Paced driving (``paced.py``): where a held graph is stepped to, checked against the simulator's own step rules
(:class:`seapup_common.lockstep.server.LockstepServer`, driven as the graph would: every node answers each
sample at once, until the graph falls silent)."""
import pytest

from seapup_bringup.graph.graph_stepper import StepFailed, Stepped
from seapup_bringup.graph.paced import PacedGraph, next_boundary, samples_to, stamp_of, task_settle
from seapup_common.lockstep.server import STEP_DONE, LockstepServer

T = 0.2


class ServerStepper:
    """:class:`GraphStepper`'s contract over the pure server: a step is answered at its ``STEP_DONE``; nobody
    answers a sample from ``silent_from`` on (then ``give_up()`` cancels, as the stepper does after a stall)."""

    def __init__(self, silent_from: int | None = None):
        self.server = LockstepServer(T, timeout=1e9, start_held=True)
        self.silent_from, self.requests = silent_from, []
        self.server.gate_ready(now=0.0)
        self._answer()  # t_0, answered while held

    def _answer(self) -> list:
        if self.silent_from is not None and self.server.k >= self.silent_from:
            return []
        return self.server.command(self.server.t_ns, accepted=True, now=0.0)

    def step(self, n, give_up=None, stall=2.0, timeout=600.0) -> Stepped:
        self.requests.append(n)
        start, actions = self.server.k, self.server.step(n, now=0.0)
        while not any(a.kind == STEP_DONE for a in actions):
            actions = self._answer()
            if not actions:
                if give_up is None or not give_up():
                    raise StepFailed("the graph fell silent and nothing says to give up")
                self.server.cancel_step(now=0.0)
                return Stepped(n, self.server.k - start, True)
        done = next(a.step for a in actions if a.kind == STEP_DONE)
        assert done.outcome == "completed" and self.server.held
        return Stepped(n, done.done, False)


def paced(stepper, heard=None, chunk=1.0):
    return PacedGraph(stepper, T, chunk, lambda t, since, answered: (heard if heard is not None else []).append(
        (t, since, answered)))


def test_arithmetic_matches_the_stamps_of_the_samples():
    assert samples_to(10.0, 0, 200_000_000) == 50
    assert samples_to(10.1, 0, 200_000_000) == 51      # the first sample at or after it
    assert samples_to(3.0, 50, 200_000_000) == 1       # already past: one sample on, never zero
    assert next_boundary(13.0, 1.0) == 14.0 and next_boundary(12.3, 1.0) == 14.0
    # a stamp reads sec + 1e-9 * nanosec: the held time equals what the probe hears, bit for bit
    for k in (0, 1, 3, 51, 57, 12345):
        ns = k * 200_000_000
        assert stamp_of(k, 200_000_000) == ns // 10**9 + 1e-9 * (ns % 10**9)


def test_run_on_holds_at_the_first_sample_at_or_after_the_target():
    stepper, heard = ServerStepper(), []
    graph = paced(stepper, heard)
    assert graph.advance(10.0) == "held"
    assert graph.k == stepper.server.k == 50 and graph.held == 10.0 and stepper.requests == [50]
    assert graph.advance(10.0 + 0.3) == "held" and graph.k == 52   # 10.3 s: the sample at 10.4 s
    assert heard == [(10.0, 0.0, True), (10.4, 10.0, True)]


def test_a_result_is_acted_on_a_whole_chunk_after_its_end_at_a_chunk_boundary():
    stepper = ServerStepper()
    graph = paced(stepper)
    graph.advance(10.0)
    # a goal that ends at 12.3 s graph time, heard once the graph has flown past 12.4 s
    state = graph.advance(None, done=lambda: stepper.server.k >= 62, end_time=lambda: 12.3)
    assert state == "held" and graph.held == 14.0 and stepper.requests[1:] == [5, 5, 5, 5]
    assert graph.late_results == 0


def test_a_result_heard_after_its_boundary_is_acted_on_where_heard_and_counted_late():
    stepper = ServerStepper()
    graph = paced(stepper, chunk=1.0)
    graph.advance(10.0)
    assert graph.advance(None, done=lambda: stepper.server.k >= 80, end_time=lambda: 12.3) == "held"
    assert graph.held == 16.0 and graph.late_results == 1


def test_settling_at_each_hold_makes_a_slow_result_land_on_its_boundary_all_the_same():
    """The late result of the test above, but the driver settles at each hold: there it learns whether the task
    ended by the held sample (here: the result is heard as soon as settle looks at a hold at or after the end),
    so the graph is held on the result's boundary however slowly the result travelled."""
    stepper = ServerStepper()
    graph = paced(stepper, chunk=1.0)
    graph.advance(10.0)
    heard, settled = [], []

    def settle(held):
        settled.append(held)
        if held >= 12.3 - 1e-9:
            heard.append(held)
    state = graph.advance(None, done=lambda: bool(heard), end_time=lambda: 12.3, settle=settle)
    assert state == "held" and graph.held == 14.0 and graph.late_results == 0
    assert settled == [10.0, 11.0, 12.0, 13.0]     # once per hold until the end was known, never after


def test_a_task_settles_on_the_feedback_of_the_held_sample_or_its_end():
    """Accepted at 10.0 s (first step 10.2 s): at the acceptance's hold nothing is awaited; at 11.0 s the wait
    ends once feedback for 11.0 s (elapsed 0.8 s) is heard -- not for 10.8 s; after the end the result ends it."""
    feedback, ended, waited = [], [False], []

    def spin_until(predicate, timeout):
        waited.append(timeout)
        for value in (0.0, 0.2, 0.4, 0.6, 0.8, 1.0):   # the feedback arriving while the driver spins
            if predicate():
                return True
            feedback.append(value)
        return predicate()
    settle = task_settle(spin_until, lambda: ended[0], lambda: list(feedback), accepted=10.0, period=0.2)
    settle(10.0)
    assert waited == [] and feedback == []
    settle(11.0)
    assert waited == [5.0] and max(feedback) == pytest.approx(0.8)
    ended[0] = True
    feedback.clear()
    settle(20.0)
    assert feedback == []          # the result is in: nothing more to wait for


def test_a_feedback_stream_that_never_comes_is_waited_for_once():
    """No feedback at all (a lost stream): the first hold waits its timeout, later holds not at all."""
    waited = []

    def spin_until(predicate, timeout):
        waited.append(timeout)
        return predicate()
    settle = task_settle(spin_until, lambda: False, lambda: [], accepted=10.0, period=0.2, timeout=3.0)
    for at in (11.0, 12.0, 13.0, 14.0):
        settle(at)
    assert waited == [3.0]


def test_a_graph_that_waits_for_its_driver_is_held_where_it_stopped():
    # a self-test that ends at 11.1 s with no controller active: nobody answers from 11.4 s (sample 57) on
    stepper, heard = ServerStepper(silent_from=57), []
    graph = paced(stepper, heard)
    graph.advance(10.0)
    state = graph.advance(None, done=lambda: stepper.server.k >= 56, end_time=lambda: 11.1)
    assert state == "blocked" and graph.k == stepper.server.k == 57 and graph.held == pytest.approx(11.4)
    assert stepper.server.held and stepper.server.stepping is None      # held there, no step running
    assert heard[-1] == (graph.held, 11.0, False)                       # not answered: only the truth is heard


def test_a_silent_graph_with_nothing_done_is_an_error_not_a_hold():
    graph = paced(ServerStepper(silent_from=3))
    with pytest.raises(StepFailed, match="silent"):
        graph.advance(10.0)
