"""Worker pools and Ctrl-C: the parent sees an interruption promptly and never outlives it.

Both tests reproduce, in-process and deterministically, the two ways a command could hang after
Ctrl-C (see ``hlaid._workers``).
"""

from __future__ import annotations

import signal
import sys
import threading
import time

import pytest

from hlaid._workers import process_pool, result, stop, worker_pool

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="fork and pthread_kill are POSIX-specific here")


def test_ctrl_c_on_another_thread_is_seen_while_waiting_for_a_job():
    """SIGINT delivered to a thread other than the main one only sets Python's flag: a main thread
    blocked in ``AsyncResult.get()`` would see it when the 5 s job ends; ``result`` within 0.1 s."""

    def interrupt_from_here():
        time.sleep(0.3)
        signal.pthread_kill(threading.get_ident(), signal.SIGINT)  # the C handler runs on this thread

    t0 = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        with worker_pool(2) as pool:
            job = pool.apply_async(time.sleep, (5.0,))
            threading.Thread(target=interrupt_from_here, daemon=True).start()
            result(job)
    assert time.monotonic() - t0 < 2.0


def test_stop_does_not_wait_for_stuck_pool_bookkeeping():
    """A lock left held by an interrupted main thread blocks the pool's result handler, and with
    it ``Pool.terminate``; ``stop`` returns after its grace period with the workers gone."""
    pool = process_pool(2)
    workers = list(pool._pool)
    job = pool.apply_async(time.sleep, (0.1,))
    job._event._cond.acquire()  # as if a Ctrl-C had struck inside Event.wait's `with self._cond`
    try:
        time.sleep(0.5)  # the job is done; the result handler now waits for that lock
        t0 = time.monotonic()
        stop(pool, grace=1.0)
        assert time.monotonic() - t0 < 2.0
        assert any(t.name == "hlaid-pool-stop" and t.is_alive() for t in threading.enumerate()), \
            "Pool.terminate did not get stuck: the test no longer reproduces the hang"
        for w in workers:
            w.join(2.0)
            assert w.exitcode is not None
    finally:
        job._event._cond.release()  # let the stuck bookkeeping finish
    for t in threading.enumerate():
        if t.name == "hlaid-pool-stop":
            t.join(5.0)
            assert not t.is_alive()


def test_worker_pool_returns_results_and_joins():
    with worker_pool(2) as pool:
        jobs = [pool.apply_async(pow, (k, 2)) for k in range(5)]
        assert [result(j) for j in jobs] == [0, 1, 4, 9, 16]
        assert result(pool.map_async(abs, [-1, 2, -3])) == [1, 2, 3]
    assert all(p.exitcode is not None for p in pool._pool)
