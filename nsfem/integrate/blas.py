"""One BLAS thread while a time integrator runs.

The integrators make tens of thousands of small dense products and solves (a configuration of
the shipped scene has a state of 50-90 components). OpenBLAS splits such products over its
threads; on a machine whose cores are busy (two cores shared with other processes, or a sweep's
parallel workers) every call then waits for a descheduled thread. Measured on 2 shared cores
(issue 16, ``--set delamination.0.restitution=1 --set delamination.0.friction=1.5 --set
rotation.gravity=1000 --set simulation.t_end=0.2``, 328 events either way): 63-91 s with two
threads, 2.5 s with one. One thread also makes the order of every sum independent of the
thread count, so a run gives the same events on every core count.

:func:`single_threaded_blas` limits the OpenBLAS libraries loaded in the process (numpy's and
scipy's) to one thread and restores their counts afterwards: through threadpoolctl when it is
installed, else by calling OpenBLAS's own ``openblas_set_num_threads`` (Linux, found through
/proc/self/maps). Where neither applies (another BLAS, another system) it does nothing.
"""

from __future__ import annotations

import contextlib
import ctypes
from collections.abc import Iterator

#: (setter, getter) symbol names of OpenBLAS builds: scipy-openblas (64-bit and 32-bit ints), plain
_SYMBOLS = (("scipy_openblas_set_num_threads64_", "scipy_openblas_get_num_threads64_"),
            ("scipy_openblas_set_num_threads", "scipy_openblas_get_num_threads"),
            ("openblas_set_num_threads64_", "openblas_get_num_threads64_"),
            ("openblas_set_num_threads", "openblas_get_num_threads"))

_controls: list | None = None


def _openblas_controls() -> list:
    """(set, get) function pairs of the OpenBLAS libraries loaded in this process."""
    global _controls
    if _controls is not None:
        return _controls
    found = []
    try:
        with open("/proc/self/maps") as maps:
            paths = sorted({line.split()[-1] for line in maps
                            if "openblas" in line.rsplit("/", 1)[-1].lower() and ".so" in line})
    except OSError:
        paths = []
    for path in paths:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for set_name, get_name in _SYMBOLS:
            setter, getter = getattr(lib, set_name, None), getattr(lib, get_name, None)
            if setter is not None and getter is not None:
                setter.argtypes, setter.restype, getter.restype = [ctypes.c_int], None, ctypes.c_int
                found.append((setter, getter))
                break
    _controls = found
    return found


@contextlib.contextmanager
def single_threaded_blas() -> Iterator[None]:
    """Run the body with one BLAS thread (see the module docstring)."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        threadpool_limits = None
    if threadpool_limits is not None:
        with threadpool_limits(limits=1, user_api="blas"):
            yield
        return
    import numpy  # noqa: F401  (load numpy's and scipy's OpenBLAS before looking for them)
    import scipy.linalg  # noqa: F401

    controls = _openblas_controls()
    previous = [get() for _, get in controls]
    for (setter, _), n in zip(controls, previous):
        if n > 1:
            setter(1)
    try:
        yield
    finally:
        for (setter, _), n in zip(controls, previous):
            if n > 1:
                setter(n)
