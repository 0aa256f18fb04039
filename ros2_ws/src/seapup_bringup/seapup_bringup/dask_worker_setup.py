"""Dask worker preload of the LocalCluster that ``./seapup campaign`` starts: Ctrl-C is the command's.

Ctrl-C reaches every process of the terminal's foreground group, the cluster's worker processes too; a
worker that takes it prints a screen of KeyboardInterrupt and CancelledError tracebacks while the command
stops it anyway (:func:`seapup_bringup.campaign_runner.run_campaign` ends its workers itself). The
workers started with the cluster inherit an ignored SIGINT from the command
(:func:`seapup_bringup.campaign_runner._client`); this preload ignores it in a worker the nanny starts
later (a restart), before the worker registers with the scheduler. It also keeps the worker's own error
log to one line a record (:class:`OneLine`): a worker whose scheduler went while it said its heartbeat logged
a screen of ``StreamClosedError`` traceback into the command's terminal (seen once in a fresh-clone suite, a
Ctrl-C'd campaign's killed worker restarting).
"""
from __future__ import annotations

import logging
import signal
import threading

__all__ = ["dask_setup", "OneLine"]


class OneLine(logging.Filter):
    """A handler filter that keeps a record to one line: an exception logged with it becomes ``(Type: reason)``
    after the message, its traceback dropped."""

    def filter(self, record: logging.LogRecord) -> bool:
        if record.exc_info:
            exc = record.exc_info[1]
            record.msg, record.args = f"{record.getMessage()} ({type(exc).__name__}: {exc})", ()
            record.exc_info, record.exc_text, record.stack_info = None, None, None
        return True


def dask_setup(worker) -> None:
    """Dask's preload hook, run in the worker process before it registers: ignore SIGINT there."""
    if threading.current_thread() is threading.main_thread():   # signal.signal works only there
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    one_line = OneLine()
    for name in ("", "distributed"):
        for handler in logging.getLogger(name).handlers:
            handler.addFilter(one_line)
