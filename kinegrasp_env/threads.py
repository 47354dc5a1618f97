"""One BLAS thread inside the engines.

The engines multiply many tiny matrices; OpenBLAS answers that with a second thread that
spins on the other core and buys nothing (measured: no wall time saved, more CPU time
spent), so two worker processes on two cores fought over four busy threads. The engines
run with BLAS limited to one thread for the duration of a batch (threadpoolctl; the
limit is lifted afterwards, so the caller's own BLAS work is untouched).
"""

from __future__ import annotations

from contextlib import AbstractContextManager

_CONTROLLER = None


def single_blas_thread() -> AbstractContextManager:
    """Context manager: BLAS libraries loaded so far use one thread inside it (cheap: the
    controller that finds them is built once and reused)."""
    global _CONTROLLER
    if _CONTROLLER is None:
        from threadpoolctl import ThreadpoolController

        _CONTROLLER = ThreadpoolController()
    return _CONTROLLER.limit(limits=1, user_api="blas")
