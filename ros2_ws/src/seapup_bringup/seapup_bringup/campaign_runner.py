"""A Monte Carlo campaign flown on Dask, its table and its page (issue 26; ``./seapup campaign SPEC.yaml``).

The campaign file (:mod:`seapup_runs.campaign`) expands into runs; they are grouped into tasks of
``runs_per_task`` and each task is flown by a Dask worker (:func:`seapup_runs.campaign.fly_rows`): on a
``LocalCluster`` of ``--workers`` processes (one thread each) by default, or on an existing cluster with
``--scheduler tcp://HOST:PORT`` (its workers need seapup installed: ``./seapup env`` on each machine). Each
finished task is written at once to ``OUT/parts/task-NNNNN.parquet``, so ``--resume`` after an interruption
flies only what is missing (the campaign file must be unchanged: its hash is in ``OUT/campaign.json``).
At the end ``OUT/results.parquet`` holds one row per run -- index, parameters (``param.*``), status and
error, wall and CPU seconds, every scalar metric (``metric.*``) -- and ``OUT/index.html`` shows the
distributions of the summary's metrics by the first grid axis and the worst runs, each with its run spec in
``OUT/worst/run-N.json`` to fly again with ``./seapup fly OUT/worst/run-N.json --plots DIR``.
"""
from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import sys
import threading
import time
from pathlib import Path

from seapup_bringup.output import SIGNALS, progress

__all__ = ["run_campaign", "ship_missions", "attach_hierarchies", "campaign_rates", "mission_campaign_rate",
           "tuner_campaign_rate"]


def _client(scheduler: str | None, workers: int | None, connect_timeout: float = 30.0):
    """A Dask client: to ``scheduler``, or to a LocalCluster of single-threaded worker processes that end
    with this process (its scheduler lives here; workers give up on a lost scheduler after 10 s)."""
    import dask
    from distributed import Client, LocalCluster
    dask.config.set({"distributed.worker.daemon": False, "distributed.comm.timeouts.connect": f"{connect_timeout}s",
                     "distributed.logging.distributed": "error"})
    if scheduler:
        from seapup_runs.campaign import CampaignError
        try:
            return Client(scheduler, timeout=f"{connect_timeout}s"), None
        except (OSError, TimeoutError) as exc:
            raise CampaignError(f"no Dask scheduler at {scheduler}: {exc}") from None
    from seapup_common.processes import watch_descendants
    watch_descendants()   # the cluster's nannies and workers end with this process, however it ends
    _quiet_resource_tracker()
    cluster = None
    try:
        with _sigint_ignored():   # the workers start with Ctrl-C ignored: only this process answers it
            cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                                   dashboard_address=":0", silence_logs=40, death_timeout=10,
                                   preload=["seapup_bringup.dask_worker_setup"])
            client = Client(cluster)
    except KeyboardInterrupt:   # SIGTERM or SIGHUP while it started (the command raises them as Ctrl-C)
        _stop_workers_now(cluster)
        if cluster is not None:
            cluster.close(timeout=2)
        raise
    return client, cluster


def _quiet_resource_tracker() -> None:
    """Start multiprocessing's resource tracker (if it is not running yet) with its leak warning off.

    Workers stopped at once (Ctrl-C, SIGTERM) leave the semaphores they made to the tracker, which unlinks them
    when this process ends and says so on the terminal it inherited ("There appear to be 12 leaked semaphore
    objects to clean up"): two more lines after "seapup: interrupted", seen on a loaded machine. The clean-up
    stays; the warning goes (the tracker takes its warning filters from the environment at its start)."""
    entry = "ignore:resource_tracker:UserWarning"
    present = os.environ.get("PYTHONWARNINGS", "")
    if entry not in present.split(","):
        os.environ["PYTHONWARNINGS"] = ",".join(filter(None, [present, entry]))
    from multiprocessing import resource_tracker
    resource_tracker.ensure_running()


@contextlib.contextmanager
def _sigint_ignored():
    """Ignore SIGINT in this process while the LocalCluster starts its worker processes.

    Ctrl-C reaches every process of the terminal's foreground group; Dask's workers then each printed a
    screen of KeyboardInterrupt and CancelledError tracebacks, and now and then (1 run in 10 of
    ``tests/test_cli_conventions.py``'s Ctrl-C test) the command hung past its 120 s. An ignored signal stays
    ignored through fork and exec, and Python keeps an inherited SIG_IGN, so the workers started meanwhile
    never see Ctrl-C (a worker the nanny restarts later ignores it by its preload,
    :mod:`seapup_bringup.dask_worker_setup`). Blocking the signal instead, as before, did not reach them:
    their ``/proc/PID/status`` showed SIGINT neither blocked nor ignored. A Ctrl-C pressed in the second or
    two the cluster takes to start is ignored too (press it again).
    """
    if threading.current_thread() is not threading.main_thread():   # only the main thread may set handlers
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _stop_workers_now(cluster) -> None:
    """Interrupted: end the LocalCluster's worker processes at once (SIGKILL; a task in flight is lost and
    ``--resume`` flies it again) and silence Dask's complaints about them, so the command stops within a
    second or two with its one line instead of waiting for the tasks in flight."""
    import logging
    for name in ("distributed", "tornado", "asyncio"):
        logging.getLogger(name).setLevel(logging.CRITICAL + 1)
    for nanny in list(getattr(cluster, "workers", {}).values()):
        pid = getattr(getattr(getattr(nanny, "process", None), "process", None), "pid", None)
        if isinstance(pid, int) and pid > 0 and pid != os.getpid():
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)


def ship_missions() -> None:
    """Let a campaign name the shipped mission (``base: {mission: demo}``: ``seapup_bringup/config/mission.yaml``)."""
    from seapup_bringup.graph.mission_graph import mission_path
    from seapup_runs.campaign import SHIPPED_MISSIONS
    SHIPPED_MISSIONS.setdefault("demo", mission_path())


def attach_hierarchies(rows: list[dict]) -> None:
    """Each mission row gets the hierarchy's nodes as data for its graph arguments (the launch document and the
    nodes' parameter files, read here: a worker runs the pure core only); a graph argument the launch document
    does not declare is refused (CampaignError, one line) before anything flies."""
    import dataclasses

    from seapup_bringup.graph.hierarchy_config import HIERARCHY, hierarchy_config
    from seapup_common.ros.launch_graph import LaunchError, find_graph, graph_arguments
    from seapup_runs.campaign import CampaignError
    declared = set(graph_arguments(find_graph(*HIERARCHY)))
    made: dict = {}
    for row in rows:
        if row.get("kind") != "mission":
            continue
        graph = row["spec"]["graph"]
        unknown = sorted(set(graph) - declared)
        if unknown:
            raise CampaignError(f"run {row['index']}: graph argument {unknown[0]!r} is not one of "
                                f"{' '.join(HIERARCHY)}'s: {', '.join(sorted(declared))}")
        key = json.dumps(graph, sort_keys=True, default=str)
        if key not in made:
            try:
                made[key] = dataclasses.asdict(hierarchy_config(graph))
            except LaunchError as exc:
                raise CampaignError(f"run {row['index']}: {exc}") from None
        row["hierarchy"] = made[key]


def run_campaign(campaign, out: Path, scheduler: str | None = None, workers: int | None = None,
                 resume: bool = False, limit: int | None = None, text=None, connect_timeout: float = 30.0) -> dict:
    """Fly ``campaign`` into ``out`` (see the module docstring); the JSON summary."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from seapup_runs.campaign import CampaignError, expand, fly_rows, tasks
    text = text or sys.stderr
    start = time.perf_counter()
    rows = expand(campaign)[:limit]
    attach_hierarchies(rows)
    groups = tasks(rows, campaign.runs_per_task)
    digest = f"{campaign.digest}-{len(rows)}"
    parts = out / "parts"
    manifest = out / "campaign.json"
    previous = _manifest(manifest) if resume and manifest.is_file() else None
    if resume and previous is not None and previous.get("digest") != digest:
        raise CampaignError(f"{out} holds another campaign (or a changed file or --limit): resume needs the same; "
                            "choose another --out or drop --resume")
    todo = [k for k in range(len(groups)) if not (resume and _part_done(parts / f"task-{k:05d}.parquet", groups[k],
                                                                        text))]
    reused = len(groups) - len(todo)
    where = scheduler or "a LocalCluster"
    # the cluster first: a scheduler that cannot be reached leaves the output directory as it was
    client, cluster = _client(scheduler, workers, connect_timeout) if todo else (None, None)
    try:
        if not resume and out.exists():
            for stale in (parts, out / "worst"):
                shutil.rmtree(stale, ignore_errors=True)
        parts.mkdir(parents=True, exist_ok=True)
        manifest.write_text(json.dumps({"name": campaign.name, "digest": digest, "runs": len(rows),
                                        "tasks": len(groups), "runs_per_task": campaign.runs_per_task,
                                        "source": campaign.source}, indent=1, default=str))
        print(f"campaign {campaign.name}: {len(rows)} runs in {len(groups)} tasks of up to {campaign.runs_per_task}"
              f"{f'; {reused} tasks already done' if reused else ''}", file=text, flush=True)
        if client is not None:
            from distributed import as_completed
            n_workers = len(client.scheduler_info().get("workers", {}))
            print(f"flying on {where} ({n_workers} workers)...", file=text, flush=True)
            futures = {client.submit(fly_rows, groups[k], key=f"seapup-{digest}-{k}", pure=False): k for k in todo}
            done = 0
            for future in as_completed(futures):
                k = futures[future]
                table = pa.Table.from_pylist(_columns_safe(future.result()))
                pq.write_table(table, parts / f"task-{k:05d}.parquet.tmp")
                (parts / f"task-{k:05d}.parquet.tmp").replace(parts / f"task-{k:05d}.parquet")
                done += 1
                progress("campaign", done / len(todo), stream=text)
    except KeyboardInterrupt:
        _stop_workers_now(cluster)
        raise
    finally:
        quick = {"timeout": 2} if SIGNALS else {}
        if client is not None:
            client.close(**quick)
        if cluster is not None:
            cluster.close(**quick)
    table = _concat([pq.read_table(parts / f"task-{k:05d}.parquet") for k in range(len(groups))])
    pq.write_table(table, out / "results.parquet")
    records = table.to_pylist()
    errors = [r for r in records if r["status"] != "ok"]
    page, worst = _page(campaign, records, rows, out)
    summary = {"name": campaign.name, "runs": len(records), "ok": len(records) - len(errors), "errors": len(errors),
               "tasks": len(groups), "tasks_reused": reused, "where": where, "out": str(out),
               "results": str(out / "results.parquet"), "page": str(page), "worst": worst,
               "wall_s": time.perf_counter() - start,
               "run_cpu_s": float(sum(r["cpu_s"] for r in records))}
    print(f"{summary['ok']} of {summary['runs']} runs flown ({summary['errors']} failed) in {summary['wall_s']:.1f} s; "
          f"table {summary['results']}; page {page}", file=text)
    for r in errors[:5]:
        print(f"  run {r['index']}: {r['error']}", file=text)
    return summary


def _manifest(path: Path) -> dict:
    """``OUT/campaign.json`` as written by an earlier run (bounded, as data); one line if it is not that."""
    from seapup_common.input_files import InputFileError, read_text
    from seapup_runs.campaign import CampaignError
    try:
        previous = json.loads(read_text(path, "data"))
    except (InputFileError, ValueError, RecursionError) as exc:
        reason = exc if isinstance(exc, InputFileError) else f"{path}: not JSON"
        raise CampaignError(f"{reason}: cannot resume from it; choose another --out or drop --resume") from None
    if not isinstance(previous, dict):
        raise CampaignError(f"{path}: not a campaign manifest: cannot resume from it; choose another --out or drop "
                            "--resume")
    return previous


def _part_done(path: Path, group: list[dict], text) -> bool:
    """Whether the task's part is on disk whole: a Parquet table holding exactly the task's runs. A part that is
    not (cut short, corrupted, another task's) is said in one line and flown again, so resuming converges."""
    if not path.is_file():
        return False
    import pyarrow.parquet as pq
    try:
        indices = pq.read_table(path, columns=["index"]).column("index").to_pylist()
    except Exception as exc:   # pyarrow raises ArrowInvalid, OSError, KeyError... for a damaged file
        reason = str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__
        print(f"{path.name}: unreadable ({reason}); flying its {len(group)} runs again", file=text, flush=True)
        return False
    if sorted(indices) != [row["index"] for row in group]:
        print(f"{path.name}: holds runs {indices[:3]}... not the task's {len(group)}; flying them again", file=text,
              flush=True)
        return False
    return True


def _columns_safe(records: list[dict]) -> list[dict]:
    """Rows whose metric columns have one type each across tasks (a metric's numbers as float; parameters as
    given: a seed stays an integer), each with every column of the task (None where a run has no such value):
    ``pa.Table.from_pylist`` takes its columns from the first row alone, and dropped the metrics a task's first
    run did not have -- a run with a change event, or a step on an axis the first run held, lost those figures
    from the table."""
    columns = list(dict.fromkeys(k for r in records for k in r))
    return [{k: (float(v) if k.startswith("metric.") and isinstance(v, int) and not isinstance(v, bool) else v)
             for k, v in ((k, r.get(k)) for k in columns)} for r in records]


def _concat(tables):
    import pyarrow as pa
    return pa.concat_tables(tables, promote_options="permissive").sort_by("index")


def _page(campaign, records: list[dict], rows: list[dict], out: Path) -> tuple[Path, list]:
    """``index.html``: the distributions of the summary's metrics by the first grid axis and the worst runs."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from seapup_runs.pages import CSS, esc, figure, fmt
    summary = campaign.summary
    ok = [r for r in records if r["status"] == "ok"]
    metric_names = sorted({k for r in ok for k, v in r.items() if k.startswith("metric.") and isinstance(v, float)})
    chosen = [f"metric.{m}" for m in summary.get("metrics", [])] or metric_names[:6]
    first = list(rows[0]["parameters"]) if rows else []
    axis = f"param.{first[0]}" if first and first[0] != "seed" else None
    figures = []
    (out / "figures").mkdir(exist_ok=True)
    for name in [m for m in chosen if m in metric_names]:
        groups = {}
        for r in ok:
            value = r.get(name)
            if isinstance(value, float) and np.isfinite(value):
                groups.setdefault(str(r.get(axis, "all")) if axis else "all", []).append(value)
        if not groups:
            continue
        fig, ax = plt.subplots(figsize=(7, 3.2))
        labels = sorted(groups)
        ax.boxplot([groups[k] for k in labels], showfliers=True)
        ax.set_xticks(range(1, len(labels) + 1), [k[:24] for k in labels], rotation=15)
        ax.set_ylabel(name.removeprefix("metric."))
        ax.set_title(f"{name.removeprefix('metric.')} by {axis.removeprefix('param.') if axis else 'run'} "
                     f"({sum(len(v) for v in groups.values())} runs)", fontsize=9)
        ax.grid(alpha=0.3)
        path = out / "figures" / f"{name.removeprefix('metric.').replace('.', '_')}.png"
        fig.tight_layout()
        fig.savefig(path, dpi=90)
        plt.close(fig)
        figures.append(figure(path, f"{name.removeprefix('metric.')}: distribution over the runs"))
    worst = []
    by = summary.get("worst_by")
    if by and f"metric.{by}" in metric_names:
        key = f"metric.{by}"
        scored = [r for r in ok if isinstance(r.get(key), float) and np.isfinite(r[key])]
        scored.sort(key=lambda r: r[key], reverse=bool(summary.get("worst_highest", True)))
        (out / "worst").mkdir(exist_ok=True)
        spec_of = {row["index"]: row["spec"] for row in rows}
        for r in scored[:int(summary.get("worst", 5))]:
            path = out / "worst" / f"run-{r['index']}.json"
            path.write_text(json.dumps(spec_of[r["index"]], indent=1))
            worst.append({"index": r["index"], by: r[key], "spec": str(path),
                          "parameters": {k.removeprefix("param."): v for k, v in r.items() if k.startswith("param.")},
                          "log_lines": int(r.get("log_lines") or 0), "log": r.get("log") or ""})
    failed = [r for r in records if r["status"] != "ok"]
    again = "--graph --out DIR" if rows and rows[0].get("kind") == "mission" else "--plots DIR"   # a mission: on the graph
    worst_rows = "".join(
        f"<tr><td class=num>{w['index']}</td><td class=num>{fmt(w[by])}</td><td>{esc(', '.join(f'{k}={v}' for k, v in w['parameters'].items()))}"
        f"</td><td><code>./seapup fly {esc(os.path.relpath(w['spec'], out))} {again}</code></td>"
        f"<td>{w['log_lines']}{'<br><small>' + '<br>'.join(map(esc, w['log'].splitlines()[:5])) + '</small>' if w['log'] else ''}"
        "</td></tr>" for w in worst)
    failed_rows = "".join(f"<tr><td class=num>{r['index']}</td><td>{esc(r['error'])}</td></tr>" for r in failed[:50])
    html = f"""<!doctype html><html><head><meta charset="utf-8"><title>campaign {esc(campaign.name)}</title>
<style>{CSS}</style></head><body><h1>Campaign {esc(campaign.name)}</h1>
<p>{esc(campaign.doc)}</p>
<p>{len(records)} runs: {len(ok)} flown, {len(failed)} failed. Table: <code>results.parquet</code> (one row per run:
<code>param.*</code>, status, <code>metric.*</code>); campaign file hash {esc(campaign.digest)}.</p>
<h2>Distributions</h2>{''.join(figures) or '<p>no numeric metric to show</p>'}
<h2>Worst runs{f' by {esc(by)}' if by else ''}</h2>
{'<table><tr><th>run</th><th>' + esc(by) + '</th><th>parameters</th><th>fly it again</th><th>lines logged (first five)</th></tr>' + worst_rows + '</table>'
 if worst else '<p>no worst_by metric in the summary</p>'}
<h2>Failed runs</h2>{'<table><tr><th>run</th><th>reason</th></tr>' + failed_rows + '</table>' if failed else '<p>none</p>'}
</body></html>"""
    page = out / "index.html"
    page.write_text(html)
    return page, worst


def workload(spec) -> str:
    """What a run of a benchmark flies, in words: vehicle, law, sensors, current, sample period and length."""
    from seapup_sim.environment_config import load_environment
    env = load_environment(spec.environment)
    current = (f"a {env.current.params.mean_speed:g} m/s Gauss-Markov current" if env.current.enabled
               else "no current")
    parameters = ", ".join(f"{k} {v}" for k, v in sorted(spec.controller.parameters.items()))
    return (f"{spec.vehicle}, {spec.controller.type}{f' ({parameters})' if parameters else ''}, "
            f"{env.sensors.name} sensors, {current}, T = {spec.control_period:g} s over {spec.duration:g} s")


def campaign_rates(runs: int = 256, worker_counts=(1, 2), per_task: int = 64) -> dict:
    """The benchmark of a campaign's throughput (``./seapup bench``): ``runs`` fixed-gain MFOL runs (eq. 4.11,
    schedule off) of square-inspection with the baseline sensors, each its own seed, in tasks of ``per_task``
    (each task's runs flown as one batch, :mod:`seapup_runs.batch_runner`), on a
    LocalCluster of each of ``worker_counts`` worker processes. Each worker first designs the controller (the
    self-test, once per process) and flies a batch of two outside the timing; the timing is the tasks' flight,
    submit to last result.
    Returns ``runs_per_s_<k>_worker(s)``, the scaling from the first count to the last, and the closed-loop
    vehicle-samples per second (control samples of all runs over the wall time) with the most workers."""
    from seapup_runs.campaign import campaign_from_dict, expand, fly_rows, tasks
    from seapup_runs.runner import design
    from seapup_runs.spec import RunSpec
    campaign = campaign_from_dict({"name": "bench", "base": {"scenario": "square-inspection"},
                                   "grid": {"controller.parameters.schedule": [False]}, "seeds": runs,
                                   "runs_per_task": per_task})
    rows = expand(campaign)
    groups = tasks(rows, campaign.runs_per_task)
    samples = sum(RunSpec.from_dict(r["spec"]).samples for r in rows)
    out: dict = {"runs": len(rows), "runs_per_task": campaign.runs_per_task, "samples": samples,
                 "workload": workload(RunSpec.from_dict(rows[0]["spec"]))}
    first_spec = rows[0]["spec"]
    for workers in worker_counts:
        client, cluster = _client(None, workers)
        try:
            # each worker's self-test and first batch (imports, compiled kernels loaded), untimed: a campaign of
            # thousands of runs pays them once per worker
            client.run(lambda: design(RunSpec.from_dict(first_spec)) and fly_rows(groups[0][:2]) and None)
            t0 = time.perf_counter()
            results = client.gather([client.submit(fly_rows, g, pure=False) for g in groups])
            wall = time.perf_counter() - t0
        finally:
            client.close()
            cluster.close()
        flown = [r for task in results for r in task]
        failed = [r for r in flown if r["status"] != "ok"]
        if failed:
            raise RuntimeError(f"campaign benchmark: {len(failed)} runs failed, first: {failed[0]['error']}")
        key = f"runs_per_s_{workers}_worker{'s' if workers > 1 else ''}"
        out[key] = len(flown) / wall
        out[f"wall_s_{workers}"] = wall
        out[f"run_cpu_s_{workers}"] = float(sum(r["cpu_s"] for r in flown))
        if workers == 1:   # what a task costs beyond its runs' CPU: submit, set-up, gather
            out["overhead_s_per_task"] = (wall - out["run_cpu_s_1"]) / len(groups)
        out["closed_loop_samples_per_s"] = samples / wall
    first, last = worker_counts[0], worker_counts[-1]
    out["scaling"] = out[f"wall_s_{first}"] / out[f"wall_s_{last}"]
    # the batch loop alone, in this process: every run of the campaign as one batch
    from seapup_runs.batch_runner import fly_batch
    specs = [RunSpec.from_dict(r["spec"]) for r in rows]
    design(specs[0])   # this process's self-test and a first batch, untimed as the workers' were
    fly_batch(specs[:2])
    wall, cpu = time.perf_counter(), time.process_time()
    fly_batch(specs)
    out["batch_samples_per_s"] = samples / (time.perf_counter() - wall)
    out["batch_samples_per_cpu_s"] = samples / (time.process_time() - cpu)
    return out


def _timed_tasks(groups: list, warm: list, workers: int, what: str) -> tuple[list, float]:
    """Fly the tasks ``groups`` on a fresh LocalCluster of ``workers`` processes, each worker first flying ``warm``
    untimed (imports, compiled kernels); (every row flown, the wall time from submitting to the last result). A
    failed row is the benchmark's failure, said in one line."""
    from seapup_runs.campaign import fly_rows
    client, cluster = _client(None, workers)
    try:
        client.run(lambda: fly_rows(warm) and None)
        t0 = time.perf_counter()
        flown = [r for task in client.gather([client.submit(fly_rows, g, pure=False) for g in groups]) for r in task]
        wall = time.perf_counter() - t0
    finally:
        client.close()
        cluster.close()
    failed = [r for r in flown if r["status"] != "ok"]
    if failed:
        raise RuntimeError(f"{what} benchmark: {len(failed)} of {len(flown)} failed, first: {failed[0]['error']}")
    return flown, wall


def mission_campaign_rate(missions: int = 8, workers: int = 2) -> dict:
    """The benchmark of a campaign over missions (``./seapup bench``): the first ``missions`` of the shipped
    demo-mission-robustness campaign (the demo's whole mission, a fouled thruster and a current drawn) on a
    LocalCluster of ``workers`` processes, a mission per task; each worker first flies one short mission untimed
    (imports, compiled kernels). Missions per minute, CPU beside wall."""
    from seapup_runs.campaign import expand, load_campaign
    ship_missions()
    rows = expand(load_campaign("demo-mission-robustness"))[:missions]
    attach_hierarchies(rows)
    flown, wall = _timed_tasks([[row] for row in rows], rows[:1], workers, "mission campaign")
    return {"missions": len(flown), "workers": workers, "wall_s": wall, "missions_per_min": 60.0 * len(flown) / wall,
            "mission_cpu_s": float(sum(r["cpu_s"] for r in flown)),
            "simulated_s": float(sum(r["metric.held_s"] for r in flown))}


def tuner_campaign_rate(workers: int = 2) -> dict:
    """The benchmark of a self-tuner campaign (``./seapup bench``): the shipped adaptive-500 (ch. 7's explicit and
    GMV cases, randomised) in its tasks on a LocalCluster of ``workers`` processes; each worker first flies two of
    its runs untimed (imports, compiled kernels). Closed-loop vehicle-samples per second over the tasks' flight,
    submit to last result, CPU in the runs beside."""
    from seapup_runs.campaign import expand, load_campaign, tasks
    from seapup_runs.spec import RunSpec
    campaign = load_campaign("adaptive-500")
    rows = expand(campaign)
    groups = tasks(rows, campaign.runs_per_task)
    samples = sum(RunSpec.from_dict(r["spec"]).samples for r in rows)
    flown, wall = _timed_tasks(groups, groups[0][:2], workers, "self-tuner campaign")
    laws = sorted({RunSpec.from_dict(r["spec"]).controller.type for r in rows})
    return {"runs": len(flown), "workers": workers, "tasks": len(groups), "samples": samples, "wall_s": wall,
            "samples_per_s": samples / wall, "run_cpu_s": float(sum(r["cpu_s"] for r in flown)),
            "workload": f"{campaign.name}: {len(rows)} randomised runs of {' and '.join(laws)} (sec. 7.4-7.6 cases "
                        f"under random fouling, camera, current and sensors), T = 0.2 s, {campaign.runs_per_task} "
                        "runs a task"}
