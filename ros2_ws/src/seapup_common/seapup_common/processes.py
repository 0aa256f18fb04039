"""Start, isolate and stop ROS 2 node processes without ros2cli or launch.

There are no ros2cli or launch wheels on PyPI, so seapup starts its nodes
itself: for tests, for ``./seapup demo`` and for SIL scenarios. This module is
that machinery, with no rclpy import:

- :class:`DomainLease` hands out a ``ROS_DOMAIN_ID`` that no other seapup
  process on this machine holds (machine-wide lock files), so parallel test
  runs never hear each other;
- :func:`ros_environment` builds the environment of a child process: its
  domain and ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` so no DDS traffic
  leaves loopback;
- :class:`NodeProcess` runs one node in its own process group, logs to a file
  and stops it with SIGINT, then SIGTERM, then SIGKILL;
- :func:`child_options`: how every child seapup starts is tied to its parent.
  The child asks the kernel for SIGTERM when its parent dies
  (``PR_SET_PDEATHSIG``), whatever kills the parent (SIGKILL included, where
  no handler runs), and inherits every domain lease the parent holds, so a
  leased domain stays taken until the last child is gone;
- :func:`spawn` starts a child with those options and registers it with this
  process's *reaper*: a small process (one per owner, started with the first
  child) that waits, on a pipe only the owner holds, for the owner to end --
  however it ends -- and then stops every child still running: SIGTERM to its
  process group, SIGKILL :data:`REAPER_GRACE` s later. The death signal alone
  is not enough: a child that ignores SIGTERM or is hung where no signal
  handler runs (seen: simulators interrupted while starting, in a futex,
  alive under PID 1 for minutes) needs the SIGKILL its dead owner can no
  longer send.
"""
from __future__ import annotations

import ctypes
import fcntl
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

__all__ = [
    "DomainLease",
    "NoFreeDomainError",
    "ros_environment",
    "find_executable",
    "NodeProcess",
    "stop_process_groups",
    "child_options",
    "spawn",
    "watch_descendants",
    "REAPER_GRACE",
]

#: Seconds the reaper gives the children of a dead owner to end after its SIGTERM before SIGKILL.
REAPER_GRACE = 1.2

#: The reaper's program (``python -S -c``): read "PID STARTTIME" lines until the owner's end closes the pipe, then
#: stop each child's process group still running. Meanwhile, every 0.2 s, it notes the owner's descendants
#: (``/proc/PID/task/*/children``, recursively) -- the processes a library starts on its own (Dask's nannies and
#: workers) -- and stops those still running too. A child is identified by its pid and its start time (field 22
#: of /proc/PID/stat), so a pid reused by an unrelated process is never signalled; a leader already gone leaves
#: its group's id unused by anyone else while that group lives, so the group is signalled.
_REAPER = r"""
import os, select, signal, sys, time
fd, grace, owner, me = int(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3]), os.getpid()
groups, procs, rest = {}, {}, b""
for sig in (signal.SIGINT, signal.SIGHUP, signal.SIGTERM):   # its work starts when its owner ends: not before
    signal.signal(sig, signal.SIG_IGN)
def stat(pid):
    try:
        with open("/proc/%d/stat" % pid, "rb") as f:
            return f.read().rsplit(b")", 1)[1].split()
    except (OSError, IndexError):
        return None
def snapshot():
    # only while the owner lives (it is our parent): never a walk from whoever adopted us once it is gone
    if owner <= 1 or os.getppid() != owner:
        return
    todo = [owner]
    while todo:
        pid = todo.pop()
        try:
            tasks = os.listdir("/proc/%d/task" % pid)
        except OSError:
            continue
        for task in tasks:
            try:
                with open("/proc/%d/task/%s/children" % (pid, task)) as f:
                    kids = [int(k) for k in f.read().split()]
            except OSError:
                continue
            for kid in kids:
                if kid > 1 and kid != me:
                    fields = stat(kid)
                    if fields is not None:
                        procs.setdefault(kid, fields[19])
                    todo.append(kid)
last = 0.0
while True:
    ready = select.select([fd], [], [], 0.2)[0]
    if time.monotonic() - last >= 0.2:
        snapshot()
        last = time.monotonic()
    if not ready:
        continue
    chunk = os.read(fd, 65536)
    if not chunk:
        break
    *lines, rest = (rest + chunk).split(b"\n")
    for line in lines:
        pid, start = line.split()
        groups[int(pid)] = start
def ours(pid, start):
    fields = stat(pid)
    return fields is not None and fields[19] == start and fields[0] not in (b"Z", b"X")
def send(sig):
    for pid, start in groups.items():
        if pid <= 1:
            continue
        fields = stat(pid)
        if fields is None or fields[19] == start:
            try:
                os.killpg(pid, sig)
            except (ProcessLookupError, PermissionError):
                pass
    for pid, start in procs.items():
        if pid > 1 and ours(pid, start):
            try:
                os.kill(pid, sig)
            except (ProcessLookupError, PermissionError):
                pass
def running():
    for pid, start in list(groups.items()) + list(procs.items()):
        if ours(pid, start):
            return True
        if pid in groups and stat(pid) is None:
            try:
                os.killpg(pid, 0)
                return True
            except (ProcessLookupError, PermissionError):
                pass
    return False
if running():
    send(signal.SIGTERM)
    deadline = time.monotonic() + grace
    while time.monotonic() < deadline and running():
        time.sleep(0.02)
    send(signal.SIGKILL)
"""


class _Reaper:
    """This process's reaper (module docstring): started with the first child, one per process."""

    def __init__(self):
        self.owner: int | None = None
        self.fd: int | None = None
        self.pid: int | None = None   # the reaper's
        self.lock = threading.Lock()

    def register(self, pid: int) -> None:
        with self.lock:
            if self.owner != os.getpid():   # first child here (or a forked copy of an owner): a reaper of our own
                self._start()
            try:
                os.write(self.fd, f"{pid} {_start_time(pid)}\n".encode())
            except OSError:   # the reaper is gone (killed): the death signal still covers the child
                pass

    def _start(self) -> None:
        read, write = os.pipe()   # neither end is inherited by children (close_fds)
        try:
            self.pid = subprocess.Popen(
                [sys.executable, "-S", "-c", _REAPER, str(read), str(REAPER_GRACE), str(os.getpid())],
                pass_fds=(read,), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                start_new_session=True, close_fds=True).pid
        finally:
            os.close(read)
        self.owner, self.fd = os.getpid(), write


_REAPER_OF_THIS_PROCESS = _Reaper()


def _start_time(pid: int) -> str:
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            return f.read().rsplit(b")", 1)[1].split()[19].decode()
    except (OSError, IndexError):
        return "0"


def watch_descendants() -> None:
    """Start this process's reaper now (it starts with the first :func:`spawn` otherwise), so the processes a
    library starts on its own (a Dask LocalCluster's) are noted and stopped once this process ends."""
    with _REAPER_OF_THIS_PROCESS.lock:
        if _REAPER_OF_THIS_PROCESS.owner != os.getpid():
            _REAPER_OF_THIS_PROCESS._start()


def spawn(command, **popen_kwargs) -> subprocess.Popen:
    """Start ``command`` as a child tied to this process (:func:`child_options`) and registered with its
    reaper: whatever ends this process, the child's process group gets SIGTERM, then SIGKILL
    :data:`REAPER_GRACE` s later. Keyword arguments go to :class:`subprocess.Popen`.
    """
    popen = subprocess.Popen(command, **popen_kwargs, **child_options())
    _REAPER_OF_THIS_PROCESS.register(popen.pid)
    return popen

#: Domain IDs seapup leases. 0 is left to users; the Linux port mapping of
#: DDS allows 0-101 (and 215-232) with the default participant limits.
LEASE_RANGE = range(10, 102)


#: File descriptors of the domain leases this process holds (children inherit them: :func:`child_options`).
_LEASE_FDS: set[int] = set()

_PR_SET_PDEATHSIG = 1
try:
    _prctl = ctypes.CDLL(None, use_errno=True).prctl  # resolved here: nothing is looked up after fork
except (OSError, AttributeError):  # not Linux: children are stopped by their parent's handlers only
    _prctl = None


def child_options(new_session: bool = True, death_signal: int = signal.SIGTERM) -> dict:
    """Keyword arguments for :class:`subprocess.Popen` that tie the child to this process.

    - In the child, before it runs its program: its own session and process
      group (``new_session``: signals reach it once, from its parent, not
      twice from a terminal), and ``PR_SET_PDEATHSIG``: the kernel sends it
      ``death_signal`` when this process (strictly: the thread that started
      it) ends, however it ends. A parent that died before the request
      took effect is caught by comparing the parent's pid.
    - ``pass_fds``: the domain leases this process holds (:class:`DomainLease`),
      so a domain stays leased while any child that uses it lives.
    """
    parent = os.getpid()
    prctl = _prctl

    def setup() -> None:  # runs in the child between fork and exec: no imports, no allocation
        if new_session:
            os.setsid()
        if prctl is not None:
            prctl(_PR_SET_PDEATHSIG, int(death_signal), 0, 0, 0)
        if os.getppid() != parent:
            os.kill(os.getpid(), int(death_signal))
    return {"preexec_fn": setup, "pass_fds": tuple(sorted(_LEASE_FDS))}


class NoFreeDomainError(RuntimeError):
    """Every ROS_DOMAIN_ID in the lease range is held by another process."""


class DomainLease:
    """A ROS_DOMAIN_ID held exclusively by this process until released.

    The lease is an exclusive ``flock`` on ``<lock_dir>/domain-<id>.lock``; the
    kernel drops it when the last process holding it ends, so a crashed test
    never blocks a domain. Children started with :func:`child_options` hold it
    too: released here, the domain stays taken until they are gone (a child
    orphaned by a killed parent is not joined by the next run). Use as a
    context manager.

    Parameters
    ----------
    lock_dir : str or Path, optional
        Directory of the lock files, shared by every seapup process on the
        machine (default ``$SEAPUP_DOMAIN_LOCK_DIR`` or
        ``<tmp>/seapup-ros-domains``).
    candidates : iterable of int, optional
        Domain IDs to try, in order (default :data:`LEASE_RANGE`).
    """

    def __init__(self, lock_dir: str | Path | None = None, candidates=LEASE_RANGE):
        self.lock_dir = Path(lock_dir or os.environ.get("SEAPUP_DOMAIN_LOCK_DIR")
                             or Path(tempfile.gettempdir()) / "seapup-ros-domains")
        self.candidates = list(candidates)
        self.domain_id: int | None = None
        self._fd: int | None = None

    def acquire(self) -> int:
        """Take the free domain released longest ago; raise :class:`NoFreeDomainError` if none.

        Least recently used first (each lock file's modification time is stamped when a lease
        takes or gives it back): a domain just released is the last choice, because a process of
        its last holder that was slow to die (a DDS participant still announcing itself, a node
        finishing its shutdown) would be heard on it for a moment -- a test once listed another
        test's action servers. Ties (never used) go in the PID-dependent order that keeps
        concurrent runs apart.
        """
        if self._fd is not None:
            raise RuntimeError(f"lease already holds domain {self.domain_id}")
        self.lock_dir.mkdir(parents=True, exist_ok=True)
        offset = os.getpid() % len(self.candidates)
        ordered = self.candidates[offset:] + self.candidates[:offset]
        for domain in sorted(ordered, key=lambda d: self._last_used(d)):   # stable: ties keep the order
            fd = os.open(self._path(domain), os.O_RDWR | os.O_CREAT, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                os.close(fd)
                continue
            self._fd, self.domain_id = fd, domain
            _LEASE_FDS.add(fd)
            self._stamp()
            return domain
        raise NoFreeDomainError(
            f"all ROS domains {self.candidates[0]}-{self.candidates[-1]} are leased "
            f"(lock files in {self.lock_dir}); wait for other seapup runs to finish")

    def _path(self, domain: int) -> Path:
        return self.lock_dir / f"domain-{domain}.lock"

    def _last_used(self, domain: int) -> float:
        try:
            return self._path(domain).stat().st_mtime
        except OSError:
            return 0.0

    def _stamp(self) -> None:
        try:
            os.utime(self._fd)
        except OSError:  # another user's lock file: the order is only a preference
            pass

    def release(self) -> None:
        """Give the domain back (idempotent): close this process's hold on the lock. Children that
        inherited it keep the domain taken until they end (no ``LOCK_UN``, which would free it for
        them too)."""
        if self._fd is not None:
            self._stamp()   # released now: the last domain the next lease picks
            _LEASE_FDS.discard(self._fd)
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> "DomainLease":
        self.acquire()
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def ros_environment(domain_id: int, base: dict[str, str] | None = None) -> dict[str, str]:
    """Environment for a ROS process on ``domain_id`` that stays on loopback.

    Parameters
    ----------
    domain_id : int
        The ROS_DOMAIN_ID, 0-232.
    base : dict, optional
        Environment to start from (default: this process's).
    """
    if not 0 <= int(domain_id) <= 232:
        raise ValueError(f"ROS_DOMAIN_ID must be 0-232, got {domain_id}")
    env = dict(os.environ if base is None else base)
    env["ROS_DOMAIN_ID"] = str(int(domain_id))
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_STATIC_PEERS", None)
    env["PYTHONUNBUFFERED"] = "1"
    return env


def find_executable(package: str, executable: str) -> Path:
    """Path of ``lib/<package>/<executable>`` on AMENT_PREFIX_PATH (what ``ros2 run`` runs)."""
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    for prefix in prefixes:
        path = Path(prefix) / "lib" / package / executable
        if path.is_file() and os.access(path, os.X_OK):
            return path
    raise FileNotFoundError(
        f"no executable {executable!r} of package {package!r} on AMENT_PREFIX_PATH "
        f"({len(prefixes)} prefixes); run through ./seapup or source the workspace")


def stop_process_groups(popens, grace: float, term_grace: float, *, hurry: bool = False) -> None:
    """Stop the process groups led by ``popens`` together: SIGINT, then SIGTERM after ``grace`` s,
    then SIGKILL after ``term_grace`` s more (each step only to those still running). ``hurry`` (the owner was
    interrupted by its user): SIGTERM first, which a node takes as a prompt stop (no drain, no waiting for
    acknowledgements: :func:`seapup_common.ros.node.run_node`)."""
    steps = ((signal.SIGINT, grace), (signal.SIGTERM, term_grace), (signal.SIGKILL, 2.0))
    for sig, wait in steps[1:] if hurry else steps:
        running = [p for p in popens if p.poll() is None]
        if not running:
            return
        for p in running:
            try:
                os.killpg(p.pid, sig)
            except ProcessLookupError:
                pass
        deadline = time.monotonic() + wait
        while any(p.poll() is None for p in running) and time.monotonic() < deadline:
            time.sleep(0.02)


class NodeProcess:
    """One node (or any command) in its own process group, logging to a file; it dies with this
    process (:func:`child_options`).

    Parameters
    ----------
    command : list of str
        The command line.
    env : dict
        Its environment (see :func:`ros_environment`).
    log_path : str or Path
        File that receives the process's stdout and stderr.
    name : str, optional
        Name used in messages (default: the command's basename).
    """

    def __init__(self, command: list[str], env: dict[str, str], log_path: str | Path,
                 name: str | None = None):
        self.command = [str(c) for c in command]
        self.env = env
        self.log_path = Path(log_path)
        self.name = name or Path(self.command[0]).name
        self.popen: subprocess.Popen | None = None

    def start(self) -> "NodeProcess":
        self.log_path.parent.mkdir(parents=True, exist_ok=True)
        with open(self.log_path, "wb") as log:
            self.popen = spawn(self.command, env=self.env, stdout=log, stderr=subprocess.STDOUT,
                               stdin=subprocess.DEVNULL)
        return self

    @property
    def running(self) -> bool:
        return self.popen is not None and self.popen.poll() is None

    @property
    def returncode(self) -> int | None:
        return None if self.popen is None else self.popen.poll()

    def log_text(self) -> str:
        try:
            return self.log_path.read_text(errors="replace")
        except FileNotFoundError:
            return ""

    def stop(self, grace: float = 5.0) -> int | None:
        """Stop with SIGINT, then SIGTERM, then SIGKILL; return the exit code."""
        if self.popen is None:
            return None
        stop_process_groups([self.popen], grace, 2.0)
        return self.popen.wait()

    def __enter__(self) -> "NodeProcess":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
