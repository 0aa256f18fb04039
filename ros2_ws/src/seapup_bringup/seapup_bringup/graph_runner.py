"""The graph runner: a :class:`~seapup_runs.spec.RunSpec` flown through the ROS graph, in lockstep.

:func:`run_on_graph` designs the spec's controllers as the in-process runner
does (:func:`seapup_runs.runner.design`), writes their documents and the graph
of :func:`seapup_runs.graph.graph_document` into the run's directory, starts
it through the SIL harness (a private domain, a process per node, a probe
that listens to the truth, the instruments, references, commands and applied
pitches) until ``duration`` simulated seconds have been flown, and turns what
the probe heard into the same :class:`~seapup_runs.result.RunResult` the
in-process runner returns, measured by the same metrics. Node logs and the
graph file stay in ``out_dir``.
"""
from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Callable

import numpy as np
import yaml

from seapup_runs.graph import graph_document
from seapup_runs.metrics import compute
from seapup_runs.result import RunResult, Series
from seapup_runs.runner import design
from seapup_runs.spec import RunEvent, RunSpec

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


def _by_stamp(times: np.ndarray, values: np.ndarray, stamps_ns: np.ndarray, width: int) -> np.ndarray:
    """``values`` at each of ``stamps_ns`` (NaN where nothing was heard for that stamp)."""
    index = {int(round(t * 1e9)): i for i, t in enumerate(times)}
    out = np.full((len(stamps_ns), width), np.nan)
    for k, stamp in enumerate(stamps_ns):
        i = index.get(int(stamp))
        if i is not None:
            out[k] = values[i]
    return out


def series_from_logs(spec: RunSpec, logs: dict) -> Series:
    """The run's series from the SIL probe's logs (:meth:`SilGraph.logs`), one row per sample 0 ... duration."""
    stamps = np.array(sorted({int(round(t * 1e9)) for t in logs["truth_t"]
                              if t <= spec.duration + 1e-6}), dtype=np.int64)
    if len(stamps) != spec.samples + 1:
        raise RuntimeError(f"the graph flew {len(stamps)} samples of the {spec.samples + 1} asked for")
    truth = np.column_stack([_by_stamp(logs["truth_t"], logs["truth_position"], stamps, 3),
                             _by_stamp(logs["truth_t"], logs["truth_attitude"], stamps, 3),
                             _by_stamp(logs["truth_t"], logs["truth_velocity"], stamps, 6)])
    velocity = _by_stamp(logs["velocity_t"], logs["velocity"], stamps, 6)
    attitude = _by_stamp(logs["imu_t"], logs["attitude"], stamps, 3)
    position = _by_stamp(logs["position_t"], logs["position"], stamps, 3)
    depth = _by_stamp(logs["depth_t"], logs["depth"].reshape(-1, 1), stamps, 1)[:, 0]
    altitude = _by_stamp(logs["altitude_t"], logs["altitude"].reshape(-1, 1), stamps, 1)[:, 0]
    measured = {"u": velocity[:, 0], "v": velocity[:, 1], "w": velocity[:, 2], "p": velocity[:, 3],
                "q": velocity[:, 4], "r": velocity[:, 5], "roll": attitude[:, 0], "pitch": attitude[:, 1],
                "yaw": attitude[:, 2], "x": position[:, 0], "y": position[:, 1], "z": position[:, 2],
                "depth": depth, "altitude": altitude}
    reference = _by_stamp(logs["reference_t"], logs["reference"], stamps, 4)
    command = _by_stamp(logs["command_t"], logs["command"], stamps, 4)
    reference[-1] = command[-1] = np.nan  # as in process: no command is asked for at the end
    applied = _by_stamp(logs["applied_t"], logs["applied"], stamps, 4)
    events = [{"time": e.time, "kind": e.kind, "detail": RunEvent.to_dict(e)["detail"]} for e in spec.plant_events()]
    events += [{"time": t, "kind": "controller", "detail": {"type": c.type}}
               for t, c in spec.controller_timeline()[1:]]
    return Series.from_states(stamps * 1e-9, truth, measured, reference, command, applied,
                              sorted(events, key=lambda e: e["time"]))


def run_on_graph(spec: RunSpec, out_dir: str | Path | None = None,
                 progress: Callable[[float], None] | None = None, timeout: float | None = None) -> RunResult:
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

    Raises
    ------
    seapup_bringup.sil.SilError
        If the graph does not come up, a node dies, or the run does not finish in time.
    """
    from seapup_bringup.sil import SilError, SilGraph

    spec = design(spec)
    out = Path(out_dir) if out_dir is not None else Path(tempfile.mkdtemp(prefix="seapup_run_"))
    out.mkdir(parents=True, exist_ok=True)
    graph = out / "graph.yaml"
    graph.write_text(yaml.safe_dump(graph_document(spec, _write_documents(spec, out)), sort_keys=False))
    limit = 60.0 + 2.0 * spec.duration if timeout is None else float(timeout)
    with SilGraph(graph, out_dir=out, ready_status=None, ready_timeout=60.0) as sil:
        end = spec.duration - 1e-6
        flown = sil.spin_until(lambda: _report(progress, sil.t / spec.duration) or sil.t >= end, limit)
        if not flown:
            raise SilError(f"the graph flew {sil.t:.1f} of {spec.duration:g} s in {limit:g} s; node logs in {out}"
                           + sil._dead())
        n = spec.samples  # the probe hears the last samples' commands and references a moment later
        sil.spin_until(lambda: min(len(sil.log["command"]), len(sil.log["reference"])) >= n
                       and min(len(sil.log[name]) for name in ("applied", "velocity", "imu", "depth")) > n, 5.0)
        logs = sil.logs()
    result = RunResult(spec, series_from_logs(spec, logs), transport=GRAPH_TRANSPORT)
    result.metrics = compute(result)
    return result


def _report(progress, fraction: float) -> bool:
    if progress is not None:
        progress(min(max(fraction, 0.0), 1.0))
    return False
