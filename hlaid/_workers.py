"""Worker process pools that leave Ctrl-C to the parent.

Ctrl-C in a terminal sends SIGINT to the whole process group. A pool worker that gets it
dies inside its task with a traceback; the pool starts a replacement and the parent waits
forever for the lost result. Workers made here ignore SIGINT, so only the parent sees the
``KeyboardInterrupt``; it then stops the pool (:func:`stop`) and the command line exits with
status 130.

Two ways the parent can still miss or outlive a Ctrl-C, both handled here:

* The kernel may deliver the process-wide SIGINT to another thread of the parent (numba's,
  OpenMP's). Python then only sets a flag, and a main thread blocked without a timeout in
  ``AsyncResult.get()`` sees it when that job ends, seconds or minutes later. :func:`result`
  waits in short slices instead, so the interruption is raised within a fraction of a second.
* ``Pool.terminate`` joins the pool's handler threads; one of them can be stuck on a lock that
  the interrupted main thread held (a ``KeyboardInterrupt`` between acquiring a lock and the
  ``try`` that releases it). :func:`stop` gives the bookkeeping a few seconds, then kills the
  workers and moves on.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import multiprocessing.pool
import signal
import threading
from typing import Any

from . import _interrupt

_POLL_S = 0.1  # how often a waiting parent looks at its signal flag
_GRACE_S = 3.0  # how long Pool.terminate may take before the workers are killed

_MASK = hasattr(signal, "pthread_sigmask")  # POSIX only
_SIGNALS = {signal.SIGINT, signal.SIGTERM}


def _ignore_sigint() -> None:
    """Pool initializer: SIGINT is the parent's business (SIGTERM, which the parent's clean-up
    sends, ends the worker); one torch thread per worker.

    The workers are one per core, so a second intra-op thread each would only oversubscribe;
    and a forked child must not enter an OpenMP parallel region of the parent's thread pool
    (libgomp is not fork-safe: the first large tensor copy in the worker hung for ever).
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if hasattr(signal, "SIGTERM"):  # Pool.terminate's SIGTERM ends a worker at once, quietly
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if _MASK:
        signal.pthread_sigmask(signal.SIG_UNBLOCK, _SIGNALS)
    import torch

    torch.set_num_threads(1)


def process_pool(n_jobs: int) -> multiprocessing.pool.Pool:
    """A pool of ``n_jobs`` worker processes (forked where the platform can) that ignore SIGINT.

    SIGINT and SIGTERM are blocked while the workers start, so a signal between a fork and the
    worker's initializer reaches the parent (once unblocked) rather than the new worker.
    """
    ctx = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else mp.get_context()
    if not _MASK:
        return ctx.Pool(n_jobs, initializer=_ignore_sigint)
    old = signal.pthread_sigmask(signal.SIG_BLOCK, _SIGNALS)
    try:
        return ctx.Pool(n_jobs, initializer=_ignore_sigint)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


@contextlib.contextmanager
def worker_pool(n_jobs: int):
    """:func:`process_pool` of ``n_jobs`` workers (None for one job: work in this process),
    terminated at once on an error or Ctrl-C rather than left to finish its tasks, joined on exit."""
    pool = process_pool(n_jobs) if n_jobs > 1 else None
    try:
        yield pool
    except BaseException:
        if pool:
            stop(pool)
        raise
    if pool:
        pool.close()
        pool.join()


def result(job: multiprocessing.pool.AsyncResult) -> Any:
    """``job.get()``, waiting in slices of 0.1 s so that a Ctrl-C is raised here promptly even when
    the signal was delivered to another thread of this process (see the module docstring)."""
    while not job.ready():
        job.wait(_POLL_S)
        _interrupt.check()
    return job.get()


def stop(pool: multiprocessing.pool.Pool, grace: float = _GRACE_S) -> None:
    """Terminate ``pool`` now: :meth:`~multiprocessing.pool.Pool.terminate` in a helper thread,
    given ``grace`` seconds; if its bookkeeping is stuck, the worker processes are killed and the
    helper (a daemon thread) is left behind, so the caller's exit is never held up."""
    helper = threading.Thread(target=pool.terminate, name="hlaid-pool-stop", daemon=True)
    helper.start()
    helper.join(grace)
    if helper.is_alive():
        for proc in getattr(pool, "_pool", []):  # the pool's worker processes (stdlib attribute)
            if proc.exitcode is None:
                proc.kill()
