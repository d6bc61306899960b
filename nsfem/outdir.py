"""An output folder holds one run: a lock while a command writes it, and a manifest of what it wrote.

:func:`claim` takes a folder for a command (``nsfem run``, ``export``, ``fit``, ``sweep``):

* **lock**: ``fcntl.flock`` on ``.nsfem.lock`` in the folder, held until the command ends; the
  OS releases it when the process dies, so a killed run leaves no stale lock. A second command
  that wants the folder meanwhile gets a one-line error naming the folder and the other process.
* **leftovers**: the temporary files of a killed earlier write (``.<name>.XXXXXXXX.tmp``, see
  :func:`nsfem.atomic.write_atomic`) are removed.
* **manifest** (``.nsfem-files.json``): the files nsfem wrote there, by kind (``run``: result.npz,
  plots, sensors; ``series``: the .pvd and its VTU frames; ``fit``: fit.json, evaluations.csv and
  its plots). A command replaces its kinds: at the start the files of those kinds that it will
  not rewrite are removed (and the old .pvd, whose frames are about to be replaced), at the end
  those it did not rewrite after all (an interrupted run). Only files named in a manifest are
  ever removed: a user's own files in the folder are left alone.

>>> import tempfile, pathlib
>>> from nsfem.atomic import write_text_atomic
>>> d = pathlib.Path(tempfile.mkdtemp())
>>> with claim(d, "run", {"run": ["result.npz", "gap.png"]}, "--out"):
...     _ = write_text_atomic(d / "result.npz", "1"), write_text_atomic(d / "gap.png", "2")
>>> with claim(d, "run", {"run": ["result.npz"]}, "--out"):   # a run without plots
...     _ = write_text_atomic(d / "result.npz", "3")
>>> sorted(p.name for p in d.iterdir())
['.nsfem-files.json', 'result.npz']
"""

from __future__ import annotations

import contextlib
import datetime
import fcntl
import json
import os
from pathlib import Path
from typing import Iterable, Iterator, Mapping

from .atomic import PROBE_NAME, TMP_NAME, journal, signals_deferred, write_text_atomic
from .errors import NsfemError

LOCK = ".nsfem.lock"
MANIFEST = ".nsfem-files.json"
#: the kinds of output each command replaces
REPLACES = {"run": ("run", "series"), "export": ("series",), "fit": ("fit",), "sweep": ()}


class FolderBusy(NsfemError):
    """Another nsfem process is writing the folder."""


def _lock(path: Path, what: str) -> int:
    """An exclusive lock on ``path/LOCK`` (its descriptor); FolderBusy when another process holds it."""
    lock = path / LOCK
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            try:
                other = os.read(fd, 4096).decode("utf-8", "replace").strip()
            finally:
                os.close(fd)
            raise FolderBusy(f"{what}: {path} is being written by another nsfem process ({other or 'starting'}); "
                             "wait for it to end or choose another folder") from None
        except OSError as exc:  # a file system without locks
            os.close(fd)
            raise NsfemError(f"{what}: cannot lock {lock}: {exc.strerror or exc}") from None
        try:  # the holder before us may have removed the file: then lock the new one
            if os.stat(lock).st_ino == os.fstat(fd).st_ino:
                return fd
        except FileNotFoundError:
            pass
        os.close(fd)


def _read_manifest(path: Path) -> dict[str, set[str]]:
    try:
        data = json.loads((path / MANIFEST).read_text(encoding="utf-8"))
        kinds = data["files"]
        return {str(k): {str(n) for n in v if isinstance(n, str) and "/" not in n and n not in (LOCK, MANIFEST)}
                for k, v in kinds.items() if isinstance(v, list)}
    except (OSError, ValueError, TypeError, KeyError, AttributeError):
        return {}


def _write_manifest(path: Path, files: Mapping[str, Iterable[str]]) -> None:
    files = {k: sorted(v) for k, v in files.items() if v}
    if files:
        write_text_atomic(path / MANIFEST, json.dumps({"files": files}, indent=0) + "\n")
    else:
        with contextlib.suppress(FileNotFoundError):
            (path / MANIFEST).unlink()


def _remove(path: Path, names: Iterable[str]) -> None:
    for name in names:
        with contextlib.suppress(FileNotFoundError, IsADirectoryError, PermissionError):
            (path / name).unlink()


def remove_leftovers(path: Path) -> list[str]:
    """Remove the temporary files of killed writes (and probes) in folder ``path``; their names."""
    gone = []
    with contextlib.suppress(OSError):
        for entry in os.scandir(path):
            if entry.is_file(follow_symlinks=False) and (TMP_NAME.match(entry.name) or PROBE_NAME.match(entry.name)):
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(entry.path)
                    gone.append(entry.name)
    return gone


@contextlib.contextmanager
def claim(path, command: str, expected: Mapping[str, Iterable[str]] | None = None,
          what: str = "--out") -> Iterator[set]:
    """Hold folder ``path`` for ``command`` (a key of :data:`REPLACES`) within the block; yields the
    set of paths written in it so far (:func:`nsfem.atomic.journal`).

    ``expected``: per kind, the names the command may write (what it will not write is removed at
    the start). ``what`` names the folder in messages (``--out``, ``--vtu``, ``output.dir``). The
    folder is created if missing and removed again if the command leaves it empty.
    """
    path = Path(path)
    created = not path.exists()
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise NsfemError(f"{what}: cannot create {path}: {exc.strerror or exc}") from None
    fd = None
    try:
        fd = _lock(path, what)
        os.ftruncate(fd, 0)
        started = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
        os.write(fd, f"pid {os.getpid()}, nsfem {command} started {started}\n".encode())
        with signals_deferred():  # the folder's bookkeeping is never left half done
            remove_leftovers(path)
            old = _read_manifest(path)
            kinds = REPLACES[command]
            expected = {k: set(v) for k, v in (expected or {}).items()}
            existing = {e.name for e in os.scandir(path)}
            mine = set().union(*(old.get(k, set()) for k in kinds))
            # the old .pvd goes in any case: its frames are about to be replaced
            stale = {n for n in mine if n not in expected.get(_kind(old, n, kinds), set()) or n.endswith(".pvd")}
            _remove(path, stale)
            old = {k: (v - stale) & existing for k, v in old.items()}
            # before writing, the manifest names whatever the command may write (but a user's own
            # files of those names): a killed command's files are known to the next one
            ahead = {k: v - (existing - set().union(*old.values(), set())) for k, v in expected.items()}
            _write_manifest(path, {k: old.get(k, set()) | ahead.get(k, set()) for k in set(old) | set(ahead)})
        with journal() as written:
            try:
                yield written
            finally:
                with signals_deferred():
                    _finish(path, kinds, old, written)
    finally:
        if fd is not None:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(path / LOCK)
            os.close(fd)
        if created:
            with contextlib.suppress(OSError):
                path.rmdir()  # only when empty


def _kind(old: Mapping[str, set[str]], name: str, kinds: Iterable[str]) -> str:
    return next((k for k in kinds if name in old.get(k, ())), "")


def _finish(path: Path, kinds: Iterable[str], old: dict[str, set[str]], written: set) -> None:
    """The manifest after a command: its kinds hold what it wrote; when it wrote anything, the older
    files of those kinds it did not rewrite are removed (they belong to another run)."""
    remove_leftovers(path)  # a write cut short in a window write_atomic cannot close
    here = path.resolve()
    names = {Path(p).name for p in written if Path(p).parent.resolve() == here} - {MANIFEST, LOCK}
    if not names:
        _write_manifest(path, old)
        return
    from .export.vtu import SERIES_FRAME

    def kind_of(name: str) -> str:
        if name.endswith(".pvd") or SERIES_FRAME.match(name):
            return "series"
        return "fit" if name in FIT_FILES else "run"

    new = {k: set(v) for k, v in old.items()}
    for k in kinds:
        _remove(path, old.get(k, set()) - names)
        new[k] = {n for n in names if kind_of(n) == k}
    for k in set(new) - set(kinds):  # a file this command rewrote is no longer another kind's
        new[k] -= names
    _write_manifest(path, new)


#: the files of ``nsfem fit`` (:func:`nsfem.fit.result._write`)
FIT_FILES = frozenset({"fit.json", "evaluations.csv", "fit.png", "landscape.png"})
