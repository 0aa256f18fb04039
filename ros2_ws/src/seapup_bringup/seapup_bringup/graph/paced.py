"""Paced driving of a held lockstep graph: where to hold it next, and stepping it there.

A driver that acts on a graph (sends a goal, switches a controller) does so
while the graph is held at a sample every node has answered, so what it does
takes effect at that sample however busy the machine is. Between its actions
:class:`PacedGraph` steps the graph (:class:`~seapup_bringup.graph.graph_stepper.GraphStepper`,
``SimulateSteps``) in chunks of ``chunk`` simulated seconds, holding it at each
chunk's end; something the driver waits for (a goal's result, heard on
another channel at a wall time that depends on the machine) is acted on at
the first chunk boundary a whole chunk after the graph time it says it ended
at (:func:`next_boundary`), so when the driver hears it does not matter -- as long as it is heard before the
graph is a chunk past it: at each hold the driver may first ``settle`` (wait until it has heard either that
the held sample was processed without the thing ending, or the thing's end: a task's feedback for the held
sample or its result), so the boundary never depends on the machine's load. When
nobody answers a sample once that something is done (a self-test ended with
no controller active: the graph waits for its driver), the step is given up
and the graph stays held right there ("blocked").

The arithmetic (:func:`samples_to`, :func:`next_boundary`, :func:`stamp_of`)
is pure and unit-tested (``tests/test_paced.py``).
"""
from __future__ import annotations

import math
import time

__all__ = ["PacedGraph", "samples_to", "next_boundary", "stamp_of", "result_end_time", "task_settle"]


def samples_to(until: float, k: int, period_ns: int) -> int:
    """Samples from sample ``k`` to the first sample at or after ``until`` [s] (at least one).

    Examples
    --------
    >>> samples_to(10.0, 0, 200_000_000)
    50
    >>> samples_to(10.05, 50, 200_000_000), samples_to(10.0, 50, 200_000_000)
    (1, 1)
    """
    return max(1, math.ceil((until - 1e-6) * 1e9 / period_ns - 1e-9) - k)


def next_boundary(t: float, chunk: float) -> float:
    """The first chunk boundary (a multiple of ``chunk``) after ``t`` by at least a whole chunk [s].

    Examples
    --------
    >>> next_boundary(12.0, 1.0), next_boundary(12.2, 1.0)
    (13.0, 14.0)
    """
    return math.ceil((t + chunk) / chunk - 1e-9) * chunk


def stamp_of(k: int, period_ns: int) -> float:
    """Sample ``k``'s time [s] as a header stamp of it reads (``sec + 1e-9 * nanosec``).

    Examples
    --------
    >>> stamp_of(51, 200_000_000)
    10.2
    """
    ns = k * period_ns
    return ns // 10**9 + 1e-9 * (ns % 10**9)


def result_end_time(future) -> float | None:
    """The graph time [s] a finished action's result says it ended at (its ``end_time``; None: not finished,
    or it does not say)."""
    if not future.done():
        return None
    end = getattr(future.result().result, "end_time", 0.0)
    return float(end) if end else None


def task_settle(spin_until, ended, elapsed, accepted: float, period: float, timeout: float = 5.0):
    """A ``settle`` for :meth:`PacedGraph.advance` while a task goal runs: at hold ``at``, wait (``spin_until(
    predicate, timeout)``, true if it held) until the task controller has stepped the held sample -- its feedback's
    ``elapsed()`` values [s] count from its first step, the sample after ``accepted`` -- or the goal ``ended()``;
    then whether it ended by the held sample is known, not a race with its result's transport. At the acceptance's
    own hold there is nothing to wait for (the task has no sample to step yet). A feedback stream that does not
    come within ``timeout`` is not waited for again (a lost stream costs one timeout, not one per hold; the
    boundary is then as late as the result's transport: :attr:`PacedGraph.late_results` counts it)."""
    first_step = accepted + period
    heard = [True]

    def stepped(at: float) -> bool:
        values = elapsed()
        return ended() or (bool(values) and first_step + max(values) >= at - 1e-6)

    def settle(at: float) -> None:
        if at >= first_step - 1e-6 and heard[0] and not spin_until(lambda: stepped(at), timeout):
            heard[0] = False
    return settle


class PacedGraph:
    """A lockstep graph held at sample ``k`` and stepped from hold to hold (see the module docstring).

    Parameters
    ----------
    stepper : GraphStepper
        The simulator's control surface.
    period : float
        The control period T [s].
    chunk : float
        The run between holds [s simulated] while waiting for something.
    hear : callable
        ``hear(t, since, answered)``: let the driver's listener hear the held sample ``t`` (the previous hold
        ``since``; ``answered``: every node has answered it).
    k : int
        The sample the graph is held at now.
    """

    def __init__(self, stepper, period: float, chunk: float, hear, k: int = 0):
        self.stepper, self.period_ns, self.chunk, self.hear, self.k = stepper, int(round(period * 1e9)), chunk, hear, k
        self.late_results = 0   # results heard more than a chunk after their end: acted on late

    @property
    def held(self) -> float:
        """The sample [s] the graph is held at."""
        return stamp_of(self.k, self.period_ns)

    def step_to(self, until: float, give_up=None, deadline: float = math.inf) -> bool:
        """Step to the first sample at or after ``until`` [s] (given up as :meth:`GraphStepper.step` says),
        then let the listener hear it; True if the step was given up (the graph blocked).

        Raises
        ------
        StepFailed
            If the simulator refuses the step or it does not end by ``deadline`` [s monotonic].
        """
        before = self.held
        stepped = self.stepper.step(samples_to(until, self.k, self.period_ns), give_up=give_up,
                                    timeout=max(1.0, deadline - time.monotonic()))
        self.k += stepped.completed
        self.hear(self.held, before, not stepped.canceled)
        return stepped.canceled

    def advance(self, until: float | None, done=None, end_time=None, timeout: float = 600.0, settle=None) -> str:
        """Step chunk by chunk and hold at ``until`` [s], or (``done()`` true) at the first chunk boundary a
        whole chunk after ``end_time()`` (the graph time of what ``done`` waited for; None: here); when the
        graph blocks once ``done()`` holds, right there. ``settle(held)``, if given, is called at each hold
        before ``done()`` is asked (module docstring). "held" or "blocked"."""
        deadline, target = time.monotonic() + timeout, None
        while True:
            if settle is not None and done is not None and target is None:
                settle(self.held)
            if done is not None and target is None and done():
                end = end_time() if end_time is not None else None
                target = self.held if end is None else next_boundary(end, self.chunk)
                if target < self.held - 1e-6:
                    self.late_results += 1
                    target = self.held
            goal = target if target is not None else until
            if goal is not None and self.held >= goal - 1e-6:
                return "held"
            chunk = self.held + self.chunk if goal is None or (done is not None and target is None) else math.inf
            if self.step_to(min(goal if goal is not None else math.inf, chunk), done, deadline):
                return "blocked"   # held right here, however long the driver takes to act
