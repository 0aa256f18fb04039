"""The graph runner: every experiment seapup flies on a ROS graph, and a :class:`~seapup_runs.spec.RunSpec`
flown through the graph in lockstep.

**One runner.** A graph experiment is a :class:`GraphSpec` -- data: the graph file, its arguments, what the
recorder writes, which probe topics and readiness the harness waits for, the first hold -- flown by
:func:`fly_graph` with a *flight* (a function of the started harness: fly to an end time, send the
self-test's goal, fly a mission's legs) into one :class:`GraphResult` (the output directory, the bag, the
domain, the simulated and wall time, the probe's logs as arrays, and what the flight returned). The run
specs (:func:`run_on_graph`), the missions and the demo (:mod:`~seapup_bringup.graph.mission_graph`), the
self-test in SIL (:mod:`~seapup_bringup.graph.self_test_graph`), the identification experiment
(:mod:`~seapup_bringup.graph.identification`), the open-loop run (:mod:`~seapup_bringup.graph.open_loop`) and
the hierarchy benchmark (:mod:`~seapup_bringup.graph.graph_bench`) are such specs; this module is the only
product code that starts the SIL harness. A shared flight: :func:`send_goal` (one action goal, its result).

**Run specs.** :func:`run_on_graph` designs the spec's controllers as the in-process runner
does (:func:`seapup_runs.runner.design`), writes their documents and the graph
of :func:`seapup_runs.run_graph.graph_document` into the run's directory, starts
it through the SIL harness (a private domain, a process per node, a probe
that listens to the truth, the instruments, references, commands and applied
pitches) until ``duration`` simulated seconds have been flown, and turns what
the probe heard into the same :class:`~seapup_runs.result.RunResult` the
in-process runner returns, measured by the same metrics. Node logs and the
graph file stay in ``out_dir``.
"""
from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np
import yaml

from seapup_bringup.graph import readiness
from seapup_bringup.graph.sil_probe import stamp_s
from seapup_common.topics import typed
from seapup_runs.run_graph import graph_document
from seapup_runs.logs import RECORDED_TOPICS, series_from_logs
from seapup_runs.metrics import compute
from seapup_runs.result import RunResult
from seapup_runs.runner import design
from seapup_runs.spec import RunSpec

__all__ = ["GraphSpec", "GraphResult", "fly_graph", "send_goal", "run_on_graph", "GRAPH_TRANSPORT"]

GRAPH_TRANSPORT = "ros graph (lockstep)"

#: The whole supervisory hierarchy in lockstep (the SIL harness's default graph).
HIERARCHY_GRAPH = "seapup_bringup hierarchy.launch.yaml"


@dataclass(frozen=True)
class GraphSpec:
    """A graph experiment as data (see the module docstring).

    Parameters
    ----------
    name : str
        What the experiment is (shown in errors and results).
    graph : str or Path
        ``"PACKAGE FILE"`` (a graph in the package's ``launch`` directory) or a graph file's path.
    arguments : mapping
        The graph file's arguments.
    record : tuple of str
        Topics the recorder writes to ``OUT/bag`` (typed ``/t:pkg/msg/Type`` ones are subscribed before the
        graph starts); empty: no recorder.
    instruments : bool
        The probe also logs the instruments (extra listeners of the graph's lockstep roster).
    ready_status : str, tuple or None
        When the graph is ready (:class:`~seapup_bringup.graph.sil.SilGraph`): None, its first truth sample.
    ready_timeout : float
        Wall seconds for the graph to come up.
    start_at : float
        A paced graph's first hold [s simulated] (0: held at t_0).
    extra_nodes : tuple of NodeSpec
        Nodes started with the graph's own (the live view).
    banner : str
        Printed once the graph is up, ``{domain}`` and ``{out}`` filled in.
    """

    name: str
    graph: str | Path = HIERARCHY_GRAPH
    arguments: Mapping[str, Any] = field(default_factory=dict)
    record: tuple[str, ...] = ()
    instruments: bool = False
    ready_status: Any = None
    ready_timeout: float = 120.0
    start_at: float = 10.0
    extra_nodes: tuple = ()
    banner: str = ""


@dataclass
class GraphResult:
    """What :func:`fly_graph` returns, whatever the experiment.

    Attributes
    ----------
    name : str
        The spec's name.
    out : Path
        The output directory (graph file, node logs, the bag).
    bag : Path or None
        The recording (None without ``record``).
    domain : int
        The ROS domain the graph flew on.
    sim_s, wall_s : float
        Simulated seconds flown (the probe's last truth sample) and the wall seconds of the flight.
    held : float or None
        A paced graph: the sample [s] it was held at when it stopped.
    logs : dict of str to ndarray
        What the probe heard, as arrays (:func:`~seapup_bringup.graph.sil_probe.log_arrays`); empty if the
        flight did not ask for them (``logs=False``).
    outcome : any
        What the flight returned (an action's result, a mission's legs, a run's numbers).
    ended_waits : dict
        Which nodes went on without what a lockstep wait waited for, a wall-clock limit having ended it
        (:meth:`~seapup_bringup.graph.sil.SilGraph.ended_waits`): empty when the flight is deterministic.
    ended_wait_events : list of dict
        The same as run-result events (:func:`~seapup_bringup.graph.readiness.ended_wait_events`).
    """

    name: str
    out: Path
    bag: Path | None
    domain: int
    sim_s: float
    wall_s: float
    held: float | None
    logs: dict[str, np.ndarray]
    outcome: Any
    ended_waits: dict = field(default_factory=dict)
    ended_wait_events: list = field(default_factory=list)


def fly_graph(spec: GraphSpec, out: str | Path, flight: Callable[[Any], Any], *, logs: bool = True,
              text=None) -> GraphResult:
    """Start ``spec``'s graph in the SIL harness (:class:`~seapup_bringup.graph.sil.SilGraph`: a private
    domain, a process per node, the recorder, the probe), fly it with ``flight(harness)``, stop it, and
    return the :class:`GraphResult` (``logs``: the probe's logs caught up and as arrays).

    Raises
    ------
    seapup_bringup.graph.sil.SilError
        If the graph does not come up, a node dies, or the flight says the graph stopped.
    """
    from seapup_bringup.graph.sil import SilGraph

    out = Path(out)
    with SilGraph(spec.graph, dict(spec.arguments), out_dir=out, record=list(spec.record) or None,
                  ready_status=spec.ready_status, ready_timeout=spec.ready_timeout, instruments=spec.instruments,
                  start_at=spec.start_at, extra_nodes=spec.extra_nodes) as sil:
        domain = int(sil.env["ROS_DOMAIN_ID"])
        if spec.banner and text is not None:
            print(spec.banner.replace("{domain}", str(domain)).replace("{out}", str(out)), file=text, flush=True)
        wall = time.monotonic()
        outcome = flight(sil)
        wall = time.monotonic() - wall
        arrays = sil.logs() if logs else {}
        result = GraphResult(spec.name, out, getattr(sil, "bag", None), domain, sil.t, wall, sil.held, arrays,
                             outcome, sil.ended_waits(), readiness.ended_wait_events(sil.log["diagnostics"]))
    return result


def send_goal(action: str, kind: str, goal: dict, *, timeout: float = 3600.0, ready_timeout: float = 60.0,
              feedback: Callable | None = None) -> Callable[[Any], Any]:
    """A flight that sends one action goal (``action``: its name; ``kind``: ``pkg/action/Type``; ``goal``:
    its fields) and returns the result once the graph has flown it."""
    def flight(sil):
        return sil.action(action, kind, goal, timeout=timeout, ready_timeout=ready_timeout, feedback=feedback)
    return flight


def _quiet(sil, budget: float = 5.0) -> None:
    """Spin until the probe's logs stop growing for 0.2 s (a graph held at its end: everything in flight
    heard), at most ``budget`` wall seconds."""
    counts = [-1]

    def quiet() -> bool:
        now = sum(len(v) for v in sil.log.values())
        settled, counts[0] = now == counts[0], now
        return settled
    deadline = time.monotonic() + budget
    while not quiet() and time.monotonic() < deadline:
        sil.spin_until(lambda: False, 0.2)


def _write_documents(spec: RunSpec, out: Path) -> list[str]:
    files = []
    for i, (_, controller) in enumerate(spec.controller_timeline()):
        document = controller.load_document()
        if document is None:
            files.append("")
            continue
        path = out / f"controller_{i}.yaml"
        path.write_text(yaml.safe_dump(dict(document), sort_keys=False))
        files.append(str(path.resolve()))
    return files


def run_on_graph(spec: RunSpec, out_dir: str | Path | None = None,
                 progress: Callable[[float], None] | None = None, timeout: float | None = None,
                 record: bool = False) -> RunResult:
    """Fly ``spec`` through the ROS graph in lockstep (see the module docstring).

    Parameters
    ----------
    spec : RunSpec
    out_dir : path, optional
        Where the graph file, controller documents and node logs go (default: a new temporary directory).
    progress : callable, optional
        Called with the fraction of simulated time flown.
    timeout : float, optional
        Wall seconds the graph may take (default: 60 s plus 2 s per simulated second).
    record : bool
        Also record the run's topics (:data:`seapup_runs.logs.RECORDED_TOPICS`) to ``out_dir/bag``
        (rosbag2, MCAP): :func:`seapup_runs.logs.result_from_bag` reads the same result back from it.

    Raises
    ------
    seapup_bringup.graph.sil.SilError
        If the graph does not come up, a node dies, or the run does not finish in time.
    """
    from seapup_bringup.graph.sil import SilError

    spec = design(spec)
    out = Path(out_dir) if out_dir is not None else Path(tempfile.mkdtemp(prefix="seapup_run_"))
    out.mkdir(parents=True, exist_ok=True)
    graph = out / "graph.launch.yaml"
    # the harness's probe and recorder are the graph's extra listeners: the simulator waits for both before t = 0
    graph.write_text(yaml.safe_dump(graph_document(spec, _write_documents(spec, out)),
                                    sort_keys=False))
    limit = 60.0 + 2.0 * spec.duration if timeout is None else float(timeout)

    sent = {"t": None}

    def pilot(sil) -> None:
        """A scripted pilot (spec.pilot): its demand in force sent as a teleop tool sends it
        (:func:`~seapup_bringup.graph.sil.send_pilot`) whenever the graph has reached a new sample."""
        if not spec.pilot or sil.t == sent["t"]:
            return
        demand = spec.pilot_at(sil.t)
        if demand is not None:
            from seapup_bringup.graph.sil import send_pilot
            send_pilot(sil, demand)
        sent["t"] = sil.t

    def flight(sil) -> None:
        end = spec.duration - 1e-6
        if not sil.spin_until(lambda: pilot(sil) or _report(progress, sil.t / spec.duration) or sil.t >= end, limit):
            raise SilError(f"the graph flew {sil.t:.1f} of {spec.duration:g} s in {limit:g} s; node logs in {out}"
                           + sil._dead())
        # the simulator stops at the spec's end (end_time): once nothing more arrives, the probe has it all
        _until_heard(sil, spec)
        _quiet(sil)
        sil.catch_up()
        _check_heard(sil, spec, out)
    flown = fly_graph(GraphSpec(spec.name, graph, ready_timeout=60.0, instruments=True,
                                record=tuple(typed(*RECORDED_TOPICS)) if record else ()), out, flight)
    logs = flown.logs
    result = RunResult(spec, series_from_logs(spec, logs), transport=GRAPH_TRANSPORT)
    # a wall-clock limit that ended a lockstep wait: the run may differ from the same spec flown elsewhere
    result.series.events.extend(flown.ended_wait_events)
    result.metrics = compute(result)
    return result


#: Per-sample topics every run graph publishes at each sample it flies (name in the probe's log, samples
#: expected beyond the spec's count): the simulator's, at t_0 ... t_N, and the reference schedule's, at
#: t_0 ... t_N-1. (The commands are not: a controller may take charge after the start.)
_EVERY_SAMPLE = {"truth": 1, "applied": 1, "velocity": 1, "imu": 1, "depth": 1, "reference": 0}


#: Wall seconds the probe may go without hearing anything new before a run's samples are taken as all heard:
#: a reliable writer repairs what a reader missed (a full shared-memory queue under load) when its next
#: heartbeat comes -- every 3 s by Fast DDS's default -- so more than two of those periods.
REPAIR_STALL = 8.0


def _samples(sil, name: str, period: float) -> set[int]:
    """The samples k (stamped k ``period``) of a topic the probe has heard, each once."""
    return {round(stamp_s(m) / period) for m in sil.log[name]}


def _heard(sil, name: str, period: float) -> int:
    """How many distinct samples of a topic the probe has heard."""
    return len(_samples(sil, name, period))


def _until_heard(sil, spec: RunSpec) -> None:
    """Spin until the probe has heard every sample of every per-sample topic (:data:`_EVERY_SAMPLE`), or nothing
    new has come for :data:`REPAIR_STALL` s (a hole DDS is not repairing: :func:`_check_heard` names it). The
    commands, which a controller taking charge after the start does not send at every sample, are caught up
    with afterwards (:meth:`SilProbe.catch_up`)."""
    expected = {name: spec.samples + extra for name, extra in _EVERY_SAMPLE.items()}

    def done() -> bool:
        return all(len(sil.log[name]) >= n and _heard(sil, name, spec.control_period) >= n
                   for name, n in expected.items())
    size, moved = -1, time.monotonic()
    while not done():
        # the per-sample topics alone: a periodic one (the diagnostics) goes on after the end and would keep a
        # hole's wait alive until an outer timeout
        now = sum(len(sil.log[name]) for name in expected)
        if now != size:
            size, moved = now, time.monotonic()
        elif time.monotonic() - moved > REPAIR_STALL:
            return
        sil.spin_until(lambda: False, 0.05)


def _check_heard(sil, spec: RunSpec, out: Path) -> None:
    """Raise :class:`SilError` if the probe missed a sample of a topic the graph published at every sample: a
    result with a hole would differ from the flight without saying why (the message names the topic, what
    was heard and what the transport said of it)."""
    from seapup_bringup.graph.sil import SilError
    from seapup_bringup.graph.sil_probe import TOPICS
    short = []
    for name, extra in _EVERY_SAMPLE.items():
        stamps = _samples(sil, name, spec.control_period)
        if len(stamps) < spec.samples + extra:
            short.append(f"{TOPICS[name][0]}: {len(stamps)} of {spec.samples + extra} samples heard, "
                         f"{_missing(stamps, spec.samples + extra, spec.control_period)} missing "
                         f"({sil.probe.account(name)})")
    if short:
        raise SilError("the harness's probe missed samples the graph published -- " + "; ".join(short)
                       + f"; node logs in {out}")


def _missing(heard: set[int], count: int, period: float) -> str:
    """The samples of 0 ... ``count`` - 1 not in ``heard`` as spans of simulated time ("t = 0-27.2 s, 40 s")."""
    spans, start = [], None
    for k in range(count + 1):
        if k < count and k not in heard:
            start = k if start is None else start
        elif start is not None:
            spans.append(f"{start * period:g}" + (f"-{(k - 1) * period:g}" if k - 1 > start else ""))
            start = None
    return "t = " + ", ".join(spans[:5]) + (f" and {len(spans) - 5} more spans" if len(spans) > 5 else "") + " s"


def _report(progress, fraction: float) -> bool:
    if progress is not None:
        progress(min(max(fraction, 0.0), 1.0))
    return False
