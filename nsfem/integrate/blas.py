"""One BLAS thread while a time integrator runs.

The integrators make tens of thousands of small dense products and solves (a configuration of
the shipped scene has a state of 50-90 components). OpenBLAS splits such products over its
threads; on a machine whose cores are busy (two cores shared with other processes, or a sweep's
parallel workers) every call then waits for a descheduled thread. Measured on 2 shared cores
(issue 16, ``--set delamination.0.restitution=1 --set delamination.0.friction=1.5 --set
rotation.gravity=1000 --set simulation.t_end=0.2``, 328 events either way): 63-91 s with two
threads, 2.5 s with one. One thread also makes the order of every sum independent of the
thread count, so a run gives the same events on every core count.

:func:`single_threaded_blas` limits the BLAS libraries loaded in the process (numpy's and
scipy's) to one thread through threadpoolctl, and restores their counts afterwards.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator

from threadpoolctl import threadpool_limits

#: per thread, how deep it is in single_threaded_blas blocks (an inner block changes nothing: threadpoolctl's scan
#: of the loaded libraries costs ~0.4 ms a block, a tenth of a rub's equilibrium period)
_depth = threading.local()
#: the BLAS thread count is the process's, not a thread's: the threads' outermost blocks are counted under a lock,
#: the first to enter sets one thread and the last to leave restores the counts (each thread restoring its own
#: entry's count would let a block that ends first raise the count under a running one, and the last to end restore
#: the 1 it found: the process left at one thread)
_lock = threading.Lock()
_active = 0
_limiter = None


@contextlib.contextmanager
def single_threaded_blas() -> Iterator[None]:
    """Run the body with one BLAS thread (see the module docstring); inside another such block, as it is. Safe
    from several threads at once (a Dask worker's): one BLAS thread while any of them is inside a block (the other
    threads' products too: a count of the process), the counts restored when the last block ends."""
    import scipy.linalg  # noqa: F401  (load scipy's BLAS too, so that both are limited)

    depth = getattr(_depth, "n", 0)
    if depth:
        _depth.n = depth + 1
        try:
            yield
        finally:
            _depth.n = depth
        return
    _enter()
    _depth.n = 1
    try:
        yield
    finally:
        _depth.n = 0
        _leave()


def _enter() -> None:
    global _active, _limiter
    with _lock:
        if not _active:
            _limiter = threadpool_limits(limits=1, user_api="blas")
        _active += 1


def _leave() -> None:
    global _active, _limiter
    with _lock:
        _active -= 1
        if not _active:
            _limiter.restore_original_limits()
            _limiter = None
