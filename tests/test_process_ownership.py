"""Every process seapup starts dies with its parent, however the parent dies; a leased domain stays
taken while a child that uses it lives; a bag whose writer lives is never "recovered".

Independent truth: the kernel's process table (``/proc``) after killing the parent with SIGKILL
(no handler runs), SIGHUP (a closed terminal) or SIGTERM.
"""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from seapup_common.bag import BagError, BagWriter, make_typestore, recover_bag, storage_files, writer_alive
from seapup_common.processes import DomainLease, NoFreeDomainError

PARENT = """
import signal, subprocess, sys, time
signal.signal(signal.SIGHUP, signal.SIG_DFL)   # as in a terminal: a runner under nohup hands SIGHUP down ignored
from seapup_common.processes import DomainLease, NodeProcess, child_options, ros_environment
lease = DomainLease(lock_dir=sys.argv[1], candidates=[int(sys.argv[2])])
lease.acquire()
child = NodeProcess([sys.executable, "-c", sys.argv[3]], ros_environment(lease.domain_id), sys.argv[4])
if sys.argv[5] == "release-and-exit":  # tied to us (death signal, leases) but not reaped: it may outlive us
    child.popen = subprocess.Popen(child.command, env=child.env, stdout=open(sys.argv[4], "wb"), **child_options())
    while "ready" not in child.log_text():   # once the child ignores SIGTERM (the log says so)
        time.sleep(0.01)
else:
    child.start()
    while sys.argv[5] == "wait-ready" and "ready" not in child.log_text():
        time.sleep(0.01)
print(child.popen.pid, flush=True)
if sys.argv[5] == "release-and-exit":
    lease.release()
    sys.exit(0)
time.sleep(120)
"""
SLEEPER = "import time; time.sleep(120)"
STUBBORN = "import signal, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); print('ready', flush=True); time.sleep(120)"


def alive(pid: int) -> bool:
    """A process that exists and is not a zombie (an orphan's zombie waits for its reaper)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False
    return state not in ("Z", "X")


def descendants(pid: int) -> list[int]:
    """Every process below ``pid`` (children of all its threads, recursively)."""
    found, todo = [], [pid]
    while todo:
        p = todo.pop()
        for task in Path(f"/proc/{p}/task").glob("*"):
            try:
                kids = [int(k) for k in (task / "children").read_text().split()]
            except (FileNotFoundError, ProcessLookupError):
                continue
            found += kids
            todo += kids
    return found


def gone_within(pids, seconds: float) -> bool:
    deadline = time.monotonic() + seconds
    while any(alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.02)
    return not any(alive(p) for p in pids)


def start_parent(tmp_path, domain, child_code, mode="hold"):
    parent = subprocess.Popen([sys.executable, "-c", PARENT, str(tmp_path / "locks"), str(domain), child_code,
                               str(tmp_path / "child.log"), mode], stdout=subprocess.PIPE, text=True,
                              start_new_session=True)
    child = int(parent.stdout.readline())
    assert alive(child)
    return parent, child


@pytest.mark.process
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGHUP, signal.SIGTERM])
def test_a_child_dies_within_two_seconds_of_its_parent(tmp_path, sig):
    parent, child = start_parent(tmp_path, 150, SLEEPER)
    os.kill(parent.pid, sig)
    parent.wait(10)
    assert gone_within([child], 2.0), f"child {child} outlived its parent killed by {sig.name}"


@pytest.mark.process
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_a_child_that_ignores_sigterm_still_dies_within_two_seconds_of_its_parent(tmp_path, sig):
    """Issue 40: children hung where no signal handler runs (simulators interrupted while starting, in a
    futex) ignored the SIGTERM of their parent's death and lived on under PID 1 for minutes. The parent's
    reaper sends SIGKILL after its grace, whatever killed the parent."""
    parent, child = start_parent(tmp_path, 152, STUBBORN, "wait-ready")
    os.kill(parent.pid, sig)
    parent.wait(10)
    assert gone_within([child], 2.0), f"child {child} (ignoring SIGTERM) outlived its parent killed by {sig.name}"


OWNER_GONE_AT_ONCE = """
import os, sys
from seapup_common import processes
child = processes.spawn([sys.executable, "-c", "import time; time.sleep(60)"])
print(child.pid, processes._REAPER_OF_THIS_PROCESS.pid, flush=True)
os._exit(0)   # before the reaper has even started, most likely
"""


@pytest.mark.process
def test_a_reaper_whose_owner_is_gone_at_once_signals_its_children_only(tmp_path):
    """The reaper notes its owner's descendants while the owner lives; one that found its owner already gone
    (adopted by PID 1) once walked PID 1's descendants -- every process of the machine -- and stopped them
    all. Now it takes its owner's pid from its command line and walks only while that owner is its parent:
    a bystander (this test's own child) lives on, the owner's child is gone."""
    bystander = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        owner = subprocess.run([sys.executable, "-c", OWNER_GONE_AT_ONCE], capture_output=True, text=True, timeout=60)
        child, reaper = (int(x) for x in owner.stdout.split())
        assert gone_within([reaper], 10.0) and gone_within([child], 1.0)
        assert bystander.poll() is None and alive(bystander.pid)
    finally:
        bystander.kill()
        bystander.wait()


NODE_HUNG_WHILE_STARTING = """
import os, sys
import seapup_common.ros.node as node
node.STOP_BUDGET = 1.0
def make_node():
    read, _ = os.pipe()
    print("starting", flush=True)
    os.read(read, 1)   # blocks for ever, as a node hung while starting (a handler runs, the read goes on)
sys.exit(node.run_node(make_node, ["hung"]))
"""


@pytest.mark.process
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_node_told_to_stop_while_it_is_starting_stops_even_if_it_hangs(tmp_path, sig):
    """Issue 40: a node told to stop while starting only set a flag nobody read (its construction never
    returned), and in its clean-up it ignored SIGINT/SIGTERM outright: it never ended. A stop now arms a
    watchdog below Python (faulthandler's thread) that ends the process once the stop budget is spent."""
    from seapup_common.processes import NodeProcess, ros_environment
    proc = NodeProcess([sys.executable, "-c", NODE_HUNG_WHILE_STARTING], ros_environment(153),
                       tmp_path / "hung.log").start()
    deadline = time.monotonic() + 60
    while "starting" not in proc.log_text() and time.monotonic() < deadline and proc.running:
        time.sleep(0.02)
    assert proc.running, proc.log_text()
    os.kill(proc.popen.pid, sig)
    try:
        code = proc.popen.wait(timeout=10.0)  # 1 s of budget, and a loaded machine's margin
    finally:
        proc.stop(grace=0.1)
    assert code == 1 and "Traceback" not in proc.log_text(), (code, proc.log_text())


@pytest.mark.process
def test_a_leased_domain_stays_taken_while_a_child_lives(tmp_path):
    """The parent releases its lease and exits; its child (which ignores the SIGTERM of its parent's
    death) still holds the domain: a second run cannot lease it until the child is gone."""
    parent, child = start_parent(tmp_path, 151, STUBBORN, "release-and-exit")
    assert parent.wait(10) == 0
    time.sleep(0.2)
    assert alive(child)
    with pytest.raises(NoFreeDomainError):
        DomainLease(lock_dir=tmp_path / "locks", candidates=[151]).acquire()
    os.kill(child, signal.SIGKILL)
    assert gone_within([child], 2.0)
    with DomainLease(lock_dir=tmp_path / "locks", candidates=[151]) as lease:
        assert lease.domain_id == 151


def test_recover_refuses_a_bag_whose_writer_is_alive_and_touches_nothing(tmp_path):
    from std_msgs.msg import String
    from rclpy.serialization import serialize_message

    writer = BagWriter(tmp_path / "bag", make_typestore()).open()
    writer.add_topic("/chatter", "std_msgs/msg/String")
    writer.write("/chatter", serialize_message(String(data="hello")), 1, 1)
    writer.flush()
    before = sorted(p.name for p in (tmp_path / "bag").iterdir())
    assert writer_alive(tmp_path / "bag")
    with pytest.raises(BagError, match="still being written"):
        recover_bag(tmp_path / "bag")
    assert sorted(p.name for p in (tmp_path / "bag").iterdir()) == before  # nothing renamed
    writer.close()
    assert not writer_alive(tmp_path / "bag")
    assert recover_bag(tmp_path / "bag")["messages"] == 1
    assert [p.name for p in storage_files(tmp_path / "bag")] == ["bag_0.mcap"]


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGHUP])
def test_a_launched_graph_dies_with_the_launcher(tmp_path, ros_env, sig):
    """``./seapup launch`` killed outright (SIGKILL: no handler runs) or by a closed terminal (SIGHUP):
    none of its nodes is left running."""
    from tests.test_launch import Launched
    proc = Launched(ros_env, "seapup_bringup", "simulator_controller.launch.yaml")
    proc.wait_for(r"started simulator \(pid (\d+)\)")
    proc.wait_for(r"started \S*controller\S* \(pid (\d+)\)")
    nodes = descendants(proc.pid)
    assert len(nodes) >= 2
    os.kill(proc.pid, sig)
    proc.finish(30)
    assert gone_within(nodes, 2.0), [p for p in nodes if alive(p)]


@pytest.mark.graph
def test_the_controller_manager_exits_promptly_on_sigint_in_a_transition_that_is_never_answered(
        ros_context, node_process, spin):
    """Issue 28 5(j): the manager took up to 2.6 s to exit on SIGINT under load, waiting inside a lifecycle
    call. Here its controller's change_state service exists but never answers (the serving node is never
    spun), so a switch waits its whole 30 s timeout; a SIGINT then ends the process within 2 s (its
    stop flag is checked every 0.05 s inside the wait), with exit code 0 and no traceback."""
    import rclpy
    from lifecycle_msgs.srv import ChangeState, GetState
    from rclpy.executors import SingleThreadedExecutor
    from seapup_msgs.srv import SwitchController

    ghost = rclpy.create_node("ghost", namespace="/seapup", context=ros_context)  # serves, never spun
    ghost.create_service(ChangeState, "/seapup/ghost/change_state", lambda request, response: response)
    ghost.create_service(GetState, "/seapup/ghost/get_state", lambda request, response: response)
    manager = node_process(package="seapup_control", executable="controller_manager",
                           args=["--ros-args", "-p", "controllers:=['ghost']", "-p", "types:=['mfol']",
                                 "-p", "fallback:=ghost"])
    client_node = rclpy.create_node("client", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(client_node)
    client = client_node.create_client(SwitchController, "/seapup/controller_manager/switch_controller")
    assert spin(executor, client.service_is_ready, 20.0), manager.log_text()
    client.call_async(SwitchController.Request(activate_controllers=["ghost"], strictness=2, timeout=30.0))
    # the manager's own GetState call is in flight (its log says nothing yet): give the request a moment
    spin(executor, lambda: False, 1.5)
    assert manager.running
    start = time.monotonic()
    manager.popen.send_signal(signal.SIGINT)
    manager.popen.wait(timeout=10.0)
    took = time.monotonic() - start
    assert took < 2.0 and manager.popen.returncode == 0, (took, manager.popen.returncode, manager.log_text())
    assert "Traceback" not in manager.log_text()
    executor.shutdown()


# -- every long-running verb, killed outright at random moments (issue 40, item 4) ------------------------------
#
# Each verb runs as ``python -m seapup_bringup.cli VERB ...`` (what ./seapup execs) in its own session, on a domain
# of its worker's own; it is killed with SIGKILL at a moment drawn in its start-up window and early run, and every
# descendant seen until then (walked through /proc children, polled every 20 ms, plus its session) must be gone
# within 2 s. A moment after the verb ended would test nothing: the verbs are given work that outlasts WINDOW.
# The first kill of each verb is drawn in the second after its first descendant appeared instead: WINDOW is wall
# time, and on a loaded machine a verb's imports can outlast it, so every verb is killed with processes to take.
# Cost: 10 verbs x 10 kills, three trials at a time.
KILLS_PER_VERB = int(os.environ.get("SEAPUP_OWNERSHIP_KILLS", "10"))
WINDOW = (0.2, 3.5)    # [s] after the start: imports, node start-up, the first samples
OWNERSHIP_SEED = int(os.environ.get("SEAPUP_OWNERSHIP_SEED", "40"))
SHORT_RUN = {"name": "short", "duration": 600.0, "controller": {"type": "hold"},
             "reference": [[0.0, 0.0, 0.0, 0.0, 0.0]], "metrics": ["step_response"]}


def _verbs(tmp: Path, port: int) -> dict[str, list[str]]:
    import yaml
    spec = tmp / "long.yaml"
    spec.write_text(yaml.safe_dump(SHORT_RUN))
    campaign = tmp / "campaign.yaml"
    campaign.write_text(yaml.safe_dump({"name": "kill-trial", "doc": "long runs", "base": {"spec": SHORT_RUN},
                                        "grid": {"vehicle": ["baseline", "camera"]}, "seeds": [5],
                                        "runs_per_task": 1}))
    bag = Path(__file__).resolve().parents[1] / "bags" / "selftest_5hz"
    return {
        "demo": ["demo", "--out", str(tmp / "demo"), "--no-plots"],
        "launch": ["launch", "seapup_bringup", "simulator_controller.launch.yaml"],
        "fly --graph": ["fly", str(spec), "--graph", "--out", str(tmp / "fly")],
        "campaign": ["campaign", str(campaign), "--out", str(tmp / "campaign"), "--workers", "1"],
        # --environment-file given: without it the view's command line is refused by rcl today (cli.py, another part
        # of issue 40); the seabed file changes nothing of the processes
        "view": ["view", "--port", str(port), "--environment-file",
                 str(Path(__file__).resolve().parents[1] / "ros2_ws/src/seapup_sim/seapup_sim/environment/default.yaml")],
        "record": ["record", "--topics", "/seapup/truth/odometry", "--wall-time", "-o", str(tmp / "bag")],
        "replay": ["replay", str(bag), "--view", "--view-port", str(port)],
        "ident experiment": ["ident", "experiment", "--duration", "600", "--out", str(tmp / "ident")],
        "open-loop": ["open-loop", "--duration", "600", "--out", str(tmp / "open_loop")],
        "selftest": ["selftest", "--out", str(tmp / "selftest")],
    }


def _session_members(sid: int) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except (OSError, IndexError):
                continue
            if int(fields[3]) == sid and fields[0] not in ("Z", "X"):
                found.append(int(entry.name))
    return found


def _started(pid: int) -> str | None:
    """A process's start time (field 22 of /proc/PID/stat): with its pid, who it is (pids are reused)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[19]
    except (OSError, IndexError):
        return None


def _still(pid: int, started: str) -> bool:
    """The same process (pid and start time) exists and is not a zombie."""
    return _started(pid) == started and alive(pid)


def _kill_trial(verb: str, argv: list[str], moment: float, env: dict, log: Path, after_child: bool = False) -> str:
    """Run ``argv``, SIGKILL it ``moment`` s after its start (``after_child``: after its first descendant appeared,
    waited for at most 120 s); '' if every descendant died within 2 s."""
    with open(log, "wb") as out:
        proc = subprocess.Popen([sys.executable, "-m", "seapup_bringup.cli", *argv], env=env, stdout=out,
                                stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True)
    seen: dict[int, str] = {}   # pid -> start time, noted when first seen

    def note(pids):
        for p in pids:
            if p not in seen and (started := _started(p)) is not None:
                seen[p] = started
    start = time.monotonic()
    while after_child and not seen and proc.poll() is None and time.monotonic() - start < 120.0:
        note(descendants(proc.pid))
        time.sleep(0.02)
    if after_child:
        start = time.monotonic()
    while time.monotonic() - start < moment:
        note(descendants(proc.pid))
        time.sleep(0.02)
    note(descendants(proc.pid))
    note(p for p in _session_members(proc.pid) if p != proc.pid)
    if proc.poll() is not None:
        return f"{verb} ended (exit {proc.returncode}) before its kill at {moment:.2f} s: {log.read_text()[-300:]}"
    proc.kill()
    proc.wait()
    deadline = time.monotonic() + 2.0
    while any(_still(p, t) for p, t in seen.items()) and time.monotonic() < deadline:
        time.sleep(0.02)
    left = [p for p, t in seen.items() if _still(p, t)]
    if left:
        names = [Path(f"/proc/{p}/cmdline").read_bytes().replace(b"\0", b" ")[:100].decode(errors="replace")
                 for p in left]
        for p in left:   # not left for the next trial (the same processes only: pid and start time)
            if _still(p, seen[p]):
                os.kill(p, signal.SIGKILL)
        return f"{verb} killed at {moment:.2f} s: {len(left)} of {len(seen)} descendants alive 2 s later: {names}"
    SEEN[verb] = SEEN.get(verb, 0) + len(seen)
    return ""


#: Descendants seen at the kills, by verb (a verb whose kills never saw one would test nothing).
SEEN: dict[str, int] = {}


@pytest.mark.graph
def test_every_long_running_verb_takes_its_processes_with_it_when_killed_at_random_moments(tmp_path):
    """Issue 40 item 4: for each long-running verb, SIGKILL at ten random moments of its start-up and early run
    leaves no descendant alive 2 s later. Seeded (SEAPUP_OWNERSHIP_SEED); a failure names the seed and moments."""
    import random
    import socket
    from concurrent.futures import ThreadPoolExecutor

    from seapup_common.processes import ros_environment
    rng = random.Random(OWNERSHIP_SEED)
    workers = 3
    leases = [DomainLease() for _ in range(workers)]
    ports = []
    for _ in range(workers):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            ports.append(s.getsockname()[1])
    trials = []
    for k in range(KILLS_PER_VERB):
        for verb in _verbs(tmp_path, 0):
            trials.append((verb, k, round(rng.uniform(*((0.0, 1.0) if k == 0 else WINDOW)), 2)))
    rng.shuffle(trials)
    slots = list(range(workers))
    lock = __import__("threading").Lock()

    def run(trial):
        verb, k, moment = trial
        with lock:
            slot = slots.pop()
        try:
            where = tmp_path / f"{verb.replace(' ', '_')}-{k}"
            where.mkdir()
            argv = _verbs(where, ports[slot])[verb]
            env = ros_environment(leases[slot].domain_id)
            return _kill_trial(verb, argv, moment, env, where / "verb.log", after_child=k == 0 and verb != "view")
        finally:
            with lock:
                slots.append(slot)
    started = time.monotonic()
    try:
        for lease in leases:
            lease.acquire()
        with ThreadPoolExecutor(workers) as pool:
            problems = [p for p in pool.map(run, trials) if p]
    finally:
        for lease in leases:
            lease.release()
    print(f"ownership: {len(trials)} kills (seed {OWNERSHIP_SEED}) in {time.monotonic() - started:.0f} s; "
          f"descendants seen: {SEEN}")
    assert not problems, f"seed {OWNERSHIP_SEED}:\n" + "\n".join(problems)
    # every verb had processes to take, but view: it execs the live_view node (the verb's process is the node)
    assert all(SEEN.get(verb, 0) > 0 for verb in _verbs(tmp_path, 0) if verb != "view"), SEEN
