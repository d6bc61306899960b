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
PARTS = ("search", "phase", "lcp", "resolve")
#: environment variable that forces the pure-Python reference path
SWITCH = "NSFEM_PURE_PYTHON"


def _load(part: str) -> ModuleType | None:
    try:
        return importlib.import_module(f"{__name__}._{part}")
    except ImportError:
        return _installed(part)


def _installed(part: str) -> ModuleType | None:
    """The compiled module of the installed copy of nsfem when it was built from these very sources, or None.

    A source checkout imported in place (``python -m pytest`` run in it after ``pip install .``: the
    working folder comes first on sys.path) has no compiled modules of its own; the installed build is
    used when every Cython source next to it (``_*.pyx``, ``*.pxi``) is byte for byte the checkout's."""
    from importlib.metadata import distributions
    from pathlib import Path

    here = Path(__file__).resolve().parent
    sources = sorted(here.glob("_*.pyx")) + sorted(here.glob("*.pxi"))
    if not sources:
        return None
    for dist in distributions(name="nsfem"):   # (the checkout's own metadata, if any, among them)
        try:
            there = Path(dist.locate_file("nsfem/integrate/core")).resolve()
            if there == here or not there.is_dir():
                continue
            if any(src.read_bytes() != (there / src.name).read_bytes() for src in sources):
                continue
        except (OSError, TypeError):
            continue
        module = _extension(there, part)
        if module is not None:
            return module
    return None


def _extension(there, part: str) -> ModuleType | None:
    """The extension module ``_<part>`` in the folder ``there``, loaded as this package's, or None."""
    import importlib.util
    import sys
    from importlib.machinery import EXTENSION_SUFFIXES

    for suffix in EXTENSION_SUFFIXES:
        path = there / f"_{part}{suffix}"
        if path.is_file():
            name = f"{__name__}._{part}"
            spec = importlib.util.spec_from_file_location(name, path)
            if spec is None or spec.loader is None:
                return None
            module = importlib.util.module_from_spec(spec)
            try:
                spec.loader.exec_module(module)
            except ImportError:
                return None
            sys.modules[name] = module
            return module
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
        return ("pure Python (no compiled core built from these sources: no C compiler at install time, or a "
                "source checkout changed since `pip install .`)")
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
