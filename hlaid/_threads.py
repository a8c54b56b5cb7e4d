"""One torch thread for long chains of tiny operations (SMO, the batched identifiers); BLAS
limited to one thread where the compiled simulator or a thread pool already holds the cores."""

from __future__ import annotations

import contextlib

import torch

_CONTROLLER = None


class one_thread:
    """Context manager: one torch thread on the CPU, restored on exit.

    The solver is a long chain of small operations: a second OpenMP thread
    only adds synchronisation, and on a busy machine every parallel region
    can stall on a descheduled thread (measured: 10-20x slower fits with two
    threads on a loaded 2-core machine, see ``docs/svm.md``).

    Parameters
    ----------
    device : torch.device or str
        Only the CPU is affected (default "cpu").
    """

    def __init__(self, device: torch.device | str = "cpu") -> None:
        device = torch.device(device)
        self.active = device.type == "cpu"
        self.saved = torch.get_num_threads()

    def __enter__(self) -> None:
        if self.active and self.saved != 1:
            torch.set_num_threads(1)

    def __exit__(self, *exc) -> None:
        if self.active and torch.get_num_threads() != self.saved:
            torch.set_num_threads(self.saved)


def blas_threads(limit: int | None):
    """Context manager: BLAS on at most ``limit`` threads (None: as it is), restored on exit.

    One ``threadpoolctl.ThreadpoolController`` serves every call (10 us a call, against 1.5 ms for
    ``threadpool_limits``, which inspects the loaded libraries each time): the refinement enters
    it once per residual evaluation. OpenBLAS's threads spin while they wait, so with the
    replays' threads or another job on the other core, a tall, narrow SVD or a whitening product
    on two threads took 10-20x its one-thread time (docs/identification.md, "Speed").
    """
    global _CONTROLLER
    if limit is None:
        return contextlib.nullcontext()
    if _CONTROLLER is None:
        import scipy.linalg  # noqa: F401  (its BLAS loaded before the controller lists the libraries)
        from threadpoolctl import ThreadpoolController

        _CONTROLLER = ThreadpoolController()
    return _CONTROLLER.limit(limits=limit, user_api="blas")
