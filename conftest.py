"""Test fixtures shared by every seapup test (package tests and SIL tests).

ROS isolation rules, applied to every test:

- ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` in this process and every child,
  so no DDS traffic leaves loopback;
- each ROS test leases its own ``ROS_DOMAIN_ID`` (machine-wide lock files, see
  :class:`seapup_common.processes.DomainLease`), so tests never hear each
  other, whatever the order or parallelism;
- in-process ROS work uses a private rclpy Context on that domain;
- child nodes run in their own process groups and are stopped (SIGINT, SIGTERM,
  SIGKILL) at teardown even when the test fails; their logs are printed only
  for failed tests.
"""
from __future__ import annotations

import gc
import html
import json
import os
import subprocess
import time
from pathlib import Path

import pytest

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
# Fast DDS's heartbeat every 100 ms, as ./seapup sets it (ros2_ws/src/seapup_common/config/fastdds_profiles.xml)
os.environ.setdefault("FASTRTPS_DEFAULT_PROFILES_FILE",
                      str(Path(__file__).resolve().parent / "ros2_ws/src/seapup_common/config/fastdds_profiles.xml"))
os.environ.pop("ROS_STATIC_PEERS", None)
os.environ.setdefault("MPLBACKEND", "Agg")

REPO_ROOT = Path(__file__).resolve().parent


ROS_FIXTURES = {"ros_domain", "ros_context", "ros_env", "node_process"}


def pytest_sessionstart(session):
    """Matplotlib builds its font cache the first time it is imported on a machine, and runs ``fc-list`` to do
    it: done here, before any test, so the unit test that happens to draw first on a fresh machine does not
    start that process (:class:`_ProcessGuard` would fail it; seen on a fresh machine's first suite)."""
    import matplotlib.font_manager  # noqa: F401  (builds the cache if missing; reads it otherwise)


#: Each test file's measured seconds (setup, call and teardown of its tests, summed), written by
#: ``./seapup test --store-durations``: the suite's workers take the longest files first (below).
DURATIONS = REPO_ROOT / "tests" / "durations.json"


def pytest_addoption(parser):
    parser.addoption("--store-durations", action="store_true",
                     help=f"seapup: after the run, write each test file's seconds into {DURATIONS.relative_to(REPO_ROOT)} "
                          "(the files the run went through; the others are kept)")


def _file_of(nodeid: str) -> str:
    return nodeid.split("::", 1)[0]


def _file_weights() -> dict:
    try:
        weights = json.loads(DURATIONS.read_text())
    except (OSError, ValueError):
        return {}
    return {k: float(v) for k, v in weights.items() if isinstance(v, (int, float))} if isinstance(weights, dict) else {}


def _longest_files_first(items) -> None:
    """Order the files by their measured seconds, longest first, each file's tests in their own order: the
    workers (``--dist loadfile``: a file to a worker) then start with the long files and end with the short
    ones, so neither waits long for the other at the end (longest-processing-time first). A file not measured
    yet goes last."""
    weights = _file_weights()
    if not weights:
        return
    first: dict[str, int] = {}
    for i, item in enumerate(items):
        first.setdefault(_file_of(item.nodeid), i)
    items.sort(key=lambda item: (-weights.get(_file_of(item.nodeid), 0.0), first[_file_of(item.nodeid)]))


_MEASURED: dict[str, float] = {}


def pytest_runtest_logreport(report):
    _MEASURED[_file_of(report.nodeid)] = _MEASURED.get(_file_of(report.nodeid), 0.0) + report.duration


def pytest_sessionfinish(session, exitstatus):
    config = session.config
    if not config.getoption("--store-durations") or hasattr(config, "workerinput") or not _MEASURED:
        return
    weights = {**_file_weights(), **{k: round(v, 1) for k, v in _MEASURED.items()}}
    DURATIONS.write_text(json.dumps(dict(sorted(weights.items())), indent=0) + "\n")


def pytest_collection_modifyitems(config, items):
    """Every test is ``unit`` (pure cores, message conversions: seconds), ``sweep`` (pure, but a sweep over
    many runs: tens of seconds), ``process`` (it starts child processes -- a command, Chromium, a Dask
    cluster, a process pool -- but no ROS graph) or ``graph`` (a ROS graph or a build): ``./seapup test -m
    unit`` runs the first kind only, and a unit test that starts a process fails
    (:func:`pytest_runtest_protocol`)."""
    both = []
    for item in items:
        if item.get_closest_marker("graph") is None and ROS_FIXTURES & set(item.fixturenames):
            item.add_marker(pytest.mark.graph)
        elif not any(item.get_closest_marker(kind) for kind in ("graph", "process", "sweep")):
            item.add_marker(pytest.mark.unit)
        elif item.get_closest_marker("unit") is not None:   # e.g. a module's pytestmark = unit, the test sweep
            both.append(item.nodeid)
    if both:   # -m unit would run it: a test is of one kind
        raise pytest.UsageError("marked unit and also sweep, process or graph (a test is of one kind; a module's "
                                "pytestmark = pytest.mark.unit counts): " + ", ".join(both))
    _longest_files_first(items)


class _ProcessGuard:
    """While installed, starting a process (``subprocess``, ``multiprocessing``, ``os.fork``/``posix_spawn``:
    every way down to the one system call) raises and is noted, so a ``unit`` test that does is failed even
    if it swallowed the error."""

    def __init__(self):
        self.started: list[str] = []
        self._saved: list = []

    def _refuse(self, name):
        def refused(*args, **kwargs):
            self.started.append(name)
            raise RuntimeError(f"a unit test started a process ({name}): mark it pytest.mark.process")
        return refused

    def __enter__(self):
        import _posixsubprocess
        targets = [(_posixsubprocess, "fork_exec"), (subprocess, "_fork_exec"), (os, "fork"), (os, "forkpty"),
                   (os, "posix_spawn"), (os, "posix_spawnp"), (os, "system"), (os, "execv"), (os, "execve")]
        for module, name in targets:
            if hasattr(module, name):
                self._saved.append((module, name, getattr(module, name)))
                setattr(module, name, self._refuse(f"{module.__name__}.{name}"))
        return self

    def __exit__(self, *exc):
        for module, name, original in reversed(self._saved):
            setattr(module, name, original)
        self._saved.clear()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """A ``unit`` test (its fixtures' set-up and tear-down included) starts no process: see :class:`_ProcessGuard`."""
    if item.get_closest_marker("unit") is None:
        yield
        return
    guard = _ProcessGuard()
    with guard:
        yield
    if guard.started:
        item.add_report_section("call", "process guard", ", ".join(guard.started))
        item.config.hook.pytest_runtest_logreport(report=pytest.TestReport(
            item.nodeid, item.location, {}, "failed",
            f"{item.nodeid} is marked unit but started a process ({', '.join(sorted(set(guard.started)))}): "
            "mark it pytest.mark.process", "teardown"))


@pytest.hookimpl(tryfirst=True, hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    setattr(item, f"rep_{report.when}", report)


@pytest.fixture
def ros_domain():
    """A ROS_DOMAIN_ID leased for this test alone."""
    from seapup_common.processes import DomainLease

    with DomainLease() as lease:
        yield lease.domain_id


@pytest.fixture
def ros_context(ros_domain, monkeypatch):
    """A private rclpy Context on the test's domain; at teardown every node made in it is destroyed
    and the context shut down and destroyed.

    Destroying the nodes matters: a failed test's traceback keeps its nodes alive, and a live node
    keeps the context's DDS participant announcing itself on a domain the next test reuses (seen: a
    later test's probe overheard nothing from child processes)."""
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node

    context = Context()
    rclpy.init(context=context, domain_id=ros_domain)
    nodes = []
    original = Node.__init__

    def tracked(self, *args, **kwargs):
        original(self, *args, **kwargs)
        if self.context is context:
            nodes.append(self)
    monkeypatch.setattr(Node, "__init__", tracked)
    yield context
    from seapup_common.ros.node import destroy_actions
    for node in nodes:
        try:
            destroy_actions(node)  # a test's own action servers too (they crash the collector otherwise)
            node.destroy_node()
        except Exception:  # noqa: BLE001 - already destroyed by the test
            pass
    # the test's cyclic garbage that holds rclpy handles (a publisher whose monkeypatched publish refers back
    # to it, say) goes now, while its context lives: collected later, after the context is destroyed, it
    # crashed the test process in the garbage collector (a stressed full run, SIGSEGV in an unrelated test)
    gc.collect()
    context.try_shutdown()
    context.destroy()


@pytest.fixture
def ros_env(ros_domain):
    """Environment for child processes of this test (its domain, loopback only)."""
    from seapup_common.processes import ros_environment

    return ros_environment(ros_domain)


@pytest.fixture
def node_process(request, ros_env, tmp_path):
    """Factory that starts commands/nodes as child processes, stopped at teardown.

    ``node_process(["./seapup", "run", ...])`` or
    ``node_process(package="seapup_sim", executable="simulator", args=[...])``.
    """
    from seapup_common.processes import NodeProcess, find_executable

    started: list[NodeProcess] = []

    def start(command=None, *, package=None, executable=None, args=(), env=None, name=None):
        if command is None:
            command = [str(find_executable(package, executable))]
        command = list(command) + list(args)
        proc = NodeProcess(command, env or ros_env,
                           tmp_path / f"{name or Path(command[0]).name}-{len(started)}.log", name)
        started.append(proc.start())
        return proc

    yield start
    for proc in started:
        proc.stop()
    failed = getattr(request.node, "rep_call", None)
    if failed is not None and failed.failed:
        for proc in started:
            print(f"\n----- log of {proc.name} (exit {proc.returncode}) -----\n{proc.log_text()}")


def spin_until(executor, predicate, timeout: float, step: float = 0.05) -> bool:
    """Spin ``executor`` until ``predicate()`` is true or ``timeout`` [s] passes."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        executor.spin_once(timeout_sec=step)
    return bool(predicate())


@pytest.fixture
def spin():
    """``spin(executor, predicate, timeout)``: wait on graph state or data, never sleep blindly."""
    return spin_until


# -- pages in a real browser -------------------------------------------------------------------------------------
# Render a page of ours in headless Chromium (Debian's package) and report what a reader sees: a copy of the
# page gets a probe -- console errors and uncaught errors (a broken image included) are collected from the
# start, and at load the rows with a ``data-status``, the images (decoded size), the sections and the errors
# are written into the DOM, which Chromium dumps. A screenshot of the page itself is kept beside the copy.
_CHROMIUM = os.environ.get("SEAPUP_CHROMIUM", "chromium")
_HEAD = """<script>window.__errors=[];window.addEventListener('error',e=>{__errors.push(String(e.message||
(e.target&&e.target.src&&'failed to load '+e.target.src.slice(0,40))||e.type))},true);(function(){const ce=
console.error;console.error=function(...a){__errors.push(a.map(String).join(' '));ce.apply(console,a)}})();</script>"""
_TAIL = """<script>window.addEventListener('load',()=>{const rows=[...document.querySelectorAll('tr[data-status]')]
.map(r=>{const s=r.querySelector('td.status');return [r.id?r.id.slice(2):r.dataset.leg,r.dataset.status,
s.firstChild.textContent,getComputedStyle(s).backgroundColor,r.offsetHeight>0]});const imgs=[...document.images]
.map(i=>[i.alt,i.complete,i.naturalWidth,i.naturalHeight]);const sections=[...document.querySelectorAll('section')]
.map(s=>s.id);const p=document.createElement('pre');p.id='__probe';p.textContent=JSON.stringify({rows,imgs,sections,
title:document.title,errors:window.__errors});document.body.appendChild(p)})</script>"""


def _render_page(page: Path, out: Path) -> dict:
    """Open ``page`` in headless Chromium: ``rows`` ([id or leg, status, status text, background colour,
    visible]), ``imgs`` ([alt, complete, natural width, height]), ``sections``, ``title``, ``errors`` and
    ``screenshot`` (a PNG of the page, kept in ``out``)."""
    out.mkdir(parents=True, exist_ok=True)
    probed = out / f"probed_{page.stem}.html"
    probed.write_text(page.read_text().replace("<head>", "<head>" + _HEAD, 1).replace("</body>", _TAIL + "</body>", 1))
    flags = [_CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             f"--user-data-dir={out / 'chromium'}", "--virtual-time-budget=10000"]
    dom = subprocess.run(flags + ["--dump-dom", probed.as_uri()], capture_output=True, text=True, timeout=180)
    assert dom.returncode == 0, dom.stderr[-2000:]
    start = dom.stdout.index('<pre id="__probe">') + len('<pre id="__probe">')
    probe = json.loads(html.unescape(dom.stdout[start:dom.stdout.index("</pre>", start)]))
    shot = out / f"{page.stem}.png"
    subprocess.run(flags + ["--hide-scrollbars", "--window-size=1300,2200", f"--screenshot={shot}", page.as_uri()],
                   capture_output=True, timeout=180)
    probe["screenshot"] = shot
    return probe


@pytest.fixture
def browser():
    """``render(page, out)``: what a reader of ``page`` sees in headless Chromium (see :func:`_render_page`)."""
    import shutil
    if shutil.which(_CHROMIUM) is None:
        pytest.fail(f"{_CHROMIUM} not found: apt-get install chromium (the bootstrap checks for it)")
    return _render_page
