"""Dask worker preload of the LocalCluster that ``./seapup campaign`` starts: Ctrl-C is the command's.

Ctrl-C reaches every process of the terminal's foreground group, the cluster's worker processes too; a
worker that takes it prints a screen of KeyboardInterrupt and CancelledError tracebacks while the command
stops it anyway (:func:`seapup_bringup.campaign_runner.run_campaign` ends its workers itself). The
workers started with the cluster inherit an ignored SIGINT from the command
(:func:`seapup_bringup.campaign_runner._client`); this preload ignores it in a worker the nanny starts
later (a restart), before the worker registers with the scheduler.
"""
from __future__ import annotations

import signal
import threading

__all__ = ["dask_setup"]


def dask_setup(worker) -> None:
    """Dask's preload hook, run in the worker process before it registers: ignore SIGINT there."""
    if threading.current_thread() is threading.main_thread():   # signal.signal works only there
        signal.signal(signal.SIGINT, signal.SIG_IGN)
