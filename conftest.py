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

import os
import time
from pathlib import Path

import pytest

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.pop("ROS_STATIC_PEERS", None)
os.environ.setdefault("MPLBACKEND", "Agg")

REPO_ROOT = Path(__file__).resolve().parent


ROS_FIXTURES = {"ros_domain", "ros_context", "ros_env", "node_process"}


def pytest_collection_modifyitems(config, items):
    """Every test is ``unit`` (pure cores, message conversions: seconds) or ``graph``
    (a ROS graph, child processes or a build: ``./seapup test -m unit`` skips them)."""
    for item in items:
        if item.get_closest_marker("graph") is None and not ROS_FIXTURES & set(item.fixturenames):
            item.add_marker(pytest.mark.unit)
        elif item.get_closest_marker("graph") is None:
            item.add_marker(pytest.mark.graph)


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
    for node in nodes:
        try:
            node.destroy_node()
        except Exception:  # noqa: BLE001 - already destroyed by the test
            pass
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
