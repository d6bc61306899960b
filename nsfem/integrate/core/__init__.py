"""Which event core runs: compiled kernels or the pure-Python reference (issue 33).

The exact method's per-event work (the search's sampling, screening and roots; the LCPs; the
closed-form energy) has a compiled version in the Cython modules ``_<part>.pyx`` of this package,
built by ``pip install .`` when a C compiler is present (setup.py; without one the package
installs and runs the pure-Python path). The Python functions stay the reference: the suite checks
that both give the same events (tests/test_core_equivalence.py).

``NSFEM_PURE_PYTHON=1`` in the environment forces the reference path for a whole process;
:func:`reference` does it for a block (the equivalence tests). Callers ask :func:`compiled` for a
part's module at the start of their work and fall back to Python when it is None.
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType

#: the parts of the event core that have a compiled module ``_<part>``
PARTS = ("search", "phase", "lcp")
#: environment variable that forces the pure-Python reference path
SWITCH = "NSFEM_PURE_PYTHON"


def _load(part: str) -> ModuleType | None:
    try:
        return importlib.import_module(f"{__name__}._{part}")
    except ImportError:
        return None


_built = {part: _load(part) for part in PARTS}
_forced = os.environ.get(SWITCH, "").strip() not in ("", "0")
_active = {part: (None if _forced else mod) for part, mod in _built.items()}


def compiled(part: str) -> ModuleType | None:
    """The compiled module of ``part`` (one of :data:`PARTS`), or None when the Python reference runs
    (not built, or forced)."""
    return _active[part]


def built() -> dict[str, bool]:
    """Per part, whether its compiled module is installed (whatever the switch says)."""
    return {part: mod is not None for part, mod in _built.items()}


def name() -> str:
    """Which core runs, for the info line and --json: "compiled", "pure Python (...why)", or
    "compiled (parts), pure Python (the others)"."""
    on = [p for p in PARTS if _active[p] is not None]
    if len(on) == len(PARTS):
        return "compiled"
    if _forced or (not on and any(_built.values())):
        return f"pure Python ({SWITCH}=1)" if _forced else "pure Python (reference path)"
    if not on:
        return "pure Python (no compiled core installed: no C compiler at install time)"
    off = [p for p in PARTS if _active[p] is None]
    return f"compiled ({', '.join(on)}), pure Python ({', '.join(off)}: not built)"


@contextmanager
def reference() -> Iterator[None]:
    """Run the block on the pure-Python reference path (then restore what ran before)."""
    saved = dict(_active)
    _active.update({part: None for part in PARTS})
    try:
        yield
    finally:
        _active.update(saved)
