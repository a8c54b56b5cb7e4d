"""Worker process pools that leave Ctrl-C to the parent.

Ctrl-C in a terminal sends SIGINT to the whole process group. A pool worker that gets it
dies inside its task with a traceback; the pool starts a replacement and the parent waits
forever for the lost result. Workers made here ignore SIGINT, so only the parent sees the
``KeyboardInterrupt``; it then stops the pool with :func:`multiprocessing.pool.Pool.terminate`
(the caller's ``except BaseException``) and the command line exits with status 130.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import multiprocessing.pool
import signal

_MASK = hasattr(signal, "pthread_sigmask")  # POSIX only


def _ignore_sigint() -> None:
    """Pool initializer: SIGINT is the parent's business; one torch thread per worker.

    The workers are one per core, so a second intra-op thread each would only oversubscribe;
    and a forked child must not enter an OpenMP parallel region of the parent's thread pool
    (libgomp is not fork-safe: the first large tensor copy in the worker hung for ever).
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if _MASK:
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    import torch

    torch.set_num_threads(1)


def process_pool(n_jobs: int) -> multiprocessing.pool.Pool:
    """A pool of ``n_jobs`` worker processes (forked where the platform can) that ignore SIGINT.

    SIGINT is blocked while the workers start, so a Ctrl-C between a fork and the worker's
    initializer reaches the parent (once unblocked) rather than the new worker.
    """
    ctx = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else mp.get_context()
    if not _MASK:
        return ctx.Pool(n_jobs, initializer=_ignore_sigint)
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
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
            pool.terminate()
        raise
    finally:
        if pool:
            pool.close()
            pool.join()
