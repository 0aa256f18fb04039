"""The graph runner: a :class:`~seapup_runs.spec.RunSpec` flown through the ROS graph, in lockstep.

:func:`run_on_graph` designs the spec's controllers as the in-process runner
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
from pathlib import Path
from typing import Callable

import yaml

from seapup_common.topics import typed
from seapup_runs.run_graph import graph_document
from seapup_runs.logs import RECORDED_TOPICS, series_from_logs
from seapup_runs.metrics import compute
from seapup_runs.result import RunResult
from seapup_runs.runner import design
from seapup_runs.spec import RunSpec

__all__ = ["run_on_graph", "GRAPH_TRANSPORT"]

GRAPH_TRANSPORT = "ros graph (lockstep)"


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
    from seapup_bringup.graph.sil import SilError, SilGraph

    spec = design(spec)
    out = Path(out_dir) if out_dir is not None else Path(tempfile.mkdtemp(prefix="seapup_run_"))
    out.mkdir(parents=True, exist_ok=True)
    graph = out / "graph.launch.yaml"
    # the harness's probe and recorder are the graph's extra listeners: the simulator waits for both before t = 0
    graph.write_text(yaml.safe_dump(graph_document(spec, _write_documents(spec, out)),
                                    sort_keys=False))
    limit = 60.0 + 2.0 * spec.duration if timeout is None else float(timeout)
    with SilGraph(graph, out_dir=out, ready_status=None, ready_timeout=60.0, instruments=True,
                  record=typed(*RECORDED_TOPICS) if record else None) as sil:
        end = spec.duration - 1e-6
        flown = sil.spin_until(lambda: _report(progress, sil.t / spec.duration) or sil.t >= end, limit)
        if not flown:
            raise SilError(f"the graph flew {sil.t:.1f} of {spec.duration:g} s in {limit:g} s; node logs in {out}"
                           + sil._dead())
        # the simulator stops at the spec's end (end_time): once nothing more arrives, the probe has it all
        counts = [-1]

        def quiet() -> bool:
            now = sum(len(v) for v in sil.log.values())
            settled, counts[0] = now == counts[0], now
            return settled
        sil.spin_until(lambda: min(len(sil.log[name]) for name in ("applied", "velocity", "imu", "depth")) > spec.samples
                       and min(len(sil.log["command"]), len(sil.log["reference"])) >= spec.samples, 5.0)
        deadline = time.monotonic() + 5.0
        while not quiet() and time.monotonic() < deadline:
            sil.spin_until(lambda: False, 0.2)
        logs = sil.logs()
        _check_heard(sil, spec, out)
    result = RunResult(spec, series_from_logs(spec, logs), transport=GRAPH_TRANSPORT)
    result.metrics = compute(result)
    return result


#: Per-sample topics every run graph publishes at each sample it flies (name in the probe's log, samples
#: expected beyond the spec's count): the simulator's, at t_0 ... t_N, and the reference schedule's, at
#: t_0 ... t_N-1. (The commands are not: a controller may take charge after the start.)
_EVERY_SAMPLE = {"truth": 1, "applied": 1, "velocity": 1, "imu": 1, "depth": 1, "reference": 0}


def _check_heard(sil, spec: RunSpec, out: Path) -> None:
    """Raise :class:`SilError` if the probe missed a sample of a topic the graph published at every sample: a
    result with a hole would differ from the flight without saying why (the message names the topic, what
    was heard and what the transport said of it)."""
    from seapup_bringup.graph.sil import SilError
    from seapup_bringup.graph.sil_probe import TOPICS, stamp_s
    short = []
    for name, extra in _EVERY_SAMPLE.items():
        heard = len({round(stamp_s(m), 6) for m in sil.log[name]})
        if heard < spec.samples + extra:
            short.append(f"{TOPICS[name][0]}: {heard} of {spec.samples + extra} samples heard "
                         f"({sil.probe.account(name)})")
    if short:
        raise SilError("the harness's probe missed samples the graph published -- " + "; ".join(short)
                       + f"; node logs in {out}")


def _report(progress, fraction: float) -> bool:
    if progress is not None:
        progress(min(max(fraction, 0.0), 1.0))
    return False
