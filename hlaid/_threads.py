"""One torch thread for long chains of tiny operations (SMO, the batched identifiers)."""

from __future__ import annotations

import torch


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
