"""The node processes of a SIL graph: started one process group each, stopped together, read back.

:class:`GraphProcesses` is a dict label -> :class:`seapup_common.processes.NodeProcess`
(what :attr:`seapup_bringup.graph.sil.SilGraph.processes` is), with what the harness
does to them as a whole: start a node, say which have exited, stop them all
(the recorder last, so it has everything), kill one (a crash), and read the
reason a node logged for refusing a goal.
"""
from __future__ import annotations

import os
import re
import signal
import time
from pathlib import Path

__all__ = ["GraphProcesses", "SilError", "RECORDER"]

#: The label of the recorder's process: stopped after the graph's nodes.
RECORDER = "recorder"


class SilError(RuntimeError):
    """The graph did not come up, a node died, or a goal was never answered."""


class GraphProcesses(dict):
    """The graph's node processes by label (see the module docstring).

    Parameters
    ----------
    env : dict
        The environment of every node (its ROS domain, loopback DDS).
    out_dir : Path
        Where each node's log (``<label>.log``) goes.
    """

    def __init__(self, env: dict, out_dir: Path):
        super().__init__()
        self.env, self.out_dir = env, Path(out_dir)

    def start(self, label: str, command: list[str]):
        """Start a node (its own process group, its output in ``out_dir/<label>.log``); its process."""
        from seapup_common.processes import NodeProcess
        self[label] = NodeProcess(command, self.env, self.out_dir / f"{label}.log", label).start()
        return self[label]

    def start_recorder(self, bag: Path, record: list[str], missing, spin_until, timeout: float = 30.0):
        """Start the ``recorder`` (``record``: ``/t`` or ``/t:pkg/msg/Type``) into ``bag`` and wait until
        ``missing()`` (the typed topics it has not subscribed to yet) is empty: it subscribes to every typed
        topic at once, and a lockstep simulator can fly a minute in a second -- it would otherwise run ahead
        of the recorder's discovery.

        Raises
        ------
        SilError
            If the recorder exits (a bag that exists already, say) or does not subscribe within ``timeout`` s.
        """
        from seapup_common.processes import find_executable
        recorder = self.start(RECORDER, [str(find_executable("seapup_common", "recorder")), "--ros-args",
                                         "-p", f"bag_path:={bag}", "-p", "use_sim_time:=true", "-p",
                                         f"topics:={record}"])
        log = self.out_dir / f"{RECORDER}.log"
        if not spin_until(lambda: not recorder.running or not missing(), timeout) or not recorder.running:
            if not recorder.running:
                raise SilError(f"the recorder exited: {recorder.log_text().strip().splitlines()[-1:]}; "
                               f"its log is {log}")
            raise SilError(f"the recorder did not subscribe to {', '.join(missing())} within {timeout:g} s; "
                           f"its log is {log}" + self.dead())
        return recorder

    def dead(self) -> str:
        """``"; exited: name (exit n), ..."`` for the nodes that are no longer running, or ""."""
        dead = [f"{name} (exit {p.returncode})" for name, p in self.items() if not p.running]
        return f"; exited: {', '.join(dead)}" if dead else ""

    def stop(self, hurry: bool = False) -> None:
        """Stop the graph's nodes together (each takes a moment; one after another added up to seconds per
        run), then the recorder, so it has everything. ``hurry`` (the command was interrupted): SIGTERM, and
        SIGKILL for what still runs a second later, instead of SIGINT -- a node inside a long callback (seen:
        2 s) must not hold up a user's Ctrl-C."""
        from seapup_common.processes import stop_process_groups
        nodes = [p for name, p in self.items() if name != RECORDER and p.popen is not None]
        stop_process_groups([p.popen for p in nodes], 8.0, 1.0 if hurry else 2.0, hurry=hurry)
        for process in nodes:
            process.popen.wait()
        if RECORDER in self:
            self[RECORDER].stop(grace=10.0)

    def kill(self, label: str) -> None:
        """Kill one node's process group at once (SIGKILL: a crash)."""
        process = self[label]
        os.killpg(process.popen.pid, signal.SIGKILL)
        process.popen.wait(5.0)

    def refusal_reason(self, wait: float = 2.0) -> str:
        """``": <why>"`` from the newest "goal refused: ..." line a node logged, or "" (the line may land a
        moment after the node's answer: looked for up to ``wait`` s)."""
        deadline = time.monotonic() + wait
        while True:
            found = [line for p in self.values() for line in re.findall(r"goal refused: (.*)", p.log_text())]
            if found or time.monotonic() >= deadline:
                return f": {found[-1].strip()}" if found else ""
            time.sleep(0.1)
