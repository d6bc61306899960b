"""Atomic file writes: nothing a run computed is lost to an interruption.

Every file nsfem writes (results, VTU/PVD, PNG, sweep tables) goes through
:func:`write_atomic`: written in full to a temporary file next to its target, then renamed
onto it, so a reader (ParaView, a resumed sweep) sees the old file or the new one, never half.

>>> import tempfile, pathlib
>>> p = pathlib.Path(tempfile.mkdtemp()) / "a.txt"
>>> write_atomic(p, lambda tmp: pathlib.Path(tmp).write_text("done")) == p, p.read_text()
(True, 'done')
"""

from __future__ import annotations

import contextlib
import os
import random
import re
import signal
import string
import tempfile
import threading
from pathlib import Path
from typing import Callable, Iterator

#: the temporary names :func:`write_atomic` makes for nsfem's outputs: ``.<target name>.<8 random
#: characters>.tmp``, the target one of the kinds of file nsfem writes
#: the suffixes of the files nsfem writes
OUTPUT_SUFFIXES = (".npz", ".vtu", ".vtm", ".pvd", ".png", ".csv", ".json", ".txt")
TMP_NAME = re.compile(r"^\.(?P<target>.+(" + "|".join(map(re.escape, OUTPUT_SUFFIXES)) + r"))\.[A-Za-z0-9_]{8}\.tmp$")
_LETTERS = string.ascii_lowercase + string.digits + "_"
#: the probe files of :func:`check_folder`
PROBE_NAME = re.compile(r"^\.nsfem-probe\.[A-Za-z0-9_]{8}$")
#: (set, before, after): :func:`write_atomic` calls each ``before`` with a path before writing it, and
#: once written adds the path to each set and calls each ``after`` with it (see :func:`journal`)
_JOURNALS: list[tuple[set, Callable[[Path], None] | None, Callable[[Path], None] | None]] = []


def write_atomic(path: str | Path, write: Callable[[str], object]) -> Path:
    """Call ``write(tmp)`` on a temporary file in ``path``'s folder (created if missing), then
    rename it onto ``path`` with the usual permissions (0666 less the umask); on any error or
    interruption the temporary file is removed and ``path`` is left as it was."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    for _, before, _ in list(_JOURNALS):
        if before is not None:
            before(path)
    tmp = None
    try:
        while True:  # the name is known before the file exists: an interruption right after
            tmp = str(path.parent / f".{path.name}.{''.join(random.choices(_LETTERS, k=8))}.tmp")
            try:  # its creation still finds it to remove
                os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
                break
            except FileExistsError:
                tmp = None
        write(tmp)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # created private (0600)
        os.replace(tmp, path)
        for written, _, after in list(_JOURNALS):
            written.add(path)
            if after is not None:
                after(path)
    except BaseException:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


@contextlib.contextmanager
def journal(before: Callable[[Path], None] | None = None,
            after: Callable[[Path], None] | None = None) -> Iterator[set]:
    """Within the block, the set of every path :func:`write_atomic` wrote (this process); ``before(path)``
    is called before each write, ``after(path)`` once the file is in place."""
    entry: tuple = (set(), before, after)
    _JOURNALS.append(entry)
    try:
        yield entry[0]
    finally:
        del _JOURNALS[next(i for i, e in enumerate(_JOURNALS) if e is entry)]


@contextlib.contextmanager
def _blocked(sigs) -> Iterator[None]:
    """``sigs`` held pending by the operating system within the block (where it can: POSIX)."""
    mask = getattr(signal, "pthread_sigmask", None)
    if mask is None:
        yield
        return
    before = mask(signal.SIG_BLOCK, sigs)
    try:
        yield
    finally:
        mask(signal.SIG_SETMASK, before)


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """SIGINT and SIGTERM that arrive within the block are delivered once it is done (to the
    handlers that were in place: Ctrl-C's KeyboardInterrupt, the command line's SIGTERM as one),
    so a file being written is finished, not cut short. Outside the main thread (where handlers
    cannot be set) the block runs as it is."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    sigs = (signal.SIGINT, signal.SIGTERM)
    # the handlers are swapped with both signals blocked: one arriving between the two swaps would run
    # the old SIGTERM handler (a KeyboardInterrupt) with the new SIGINT one left in place for good
    with _blocked(sigs):
        previous = {sig: signal.signal(sig, lambda signum, frame: caught.append(signum)) for sig in sigs}
    try:
        yield
    finally:
        with _blocked(sigs):
            for sig, handler in previous.items():
                signal.signal(sig, handler)
        for sig in dict.fromkeys(caught):
            signal.raise_signal(sig)


def write_text_atomic(path: str | Path, text: str) -> Path:
    """:func:`write_atomic` for text (UTF-8, newlines as given)."""
    def write(tmp):
        with open(tmp, "w", encoding="utf-8", newline="") as fh:
            fh.write(text)

    return write_atomic(path, write)


def check_folder(path: str | Path, what: str) -> Path:
    """Raise :class:`~nsfem.errors.NsfemError` unless files can be written into folder ``path``.

    Checked by doing, not by permission bits (root passes ``os.access`` everywhere, also on
    /proc): a folder that exists gets a probe file written and removed; one that does not is
    created with its missing parents and removed again, so a refused run leaves nothing behind.
    ``what`` names the folder in the message (``--out``, ``output.dir``, ...).
    """
    from .errors import NsfemError

    path = Path(path)
    if path.exists() and not path.is_dir():
        raise NsfemError(f"{what}: {path} is a file, not a folder")
    missing = []
    p = path
    while not p.exists():
        missing.append(p)
        if p.parent == p:
            break
        p = p.parent
    if p.exists() and not p.is_dir():
        raise NsfemError(f"{what}: {p} is a file, so the folder {path} cannot be created")
    try:
        path.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".nsfem-probe.", dir=path)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise NsfemError(f"{what}: cannot write into {path}: {exc.strerror or exc}") from None
    finally:
        for q in missing:  # innermost first
            try:
                q.rmdir()
            except OSError:
                pass
    return path


def check_file(path: str | Path, what: str) -> Path:
    """Raise :class:`~nsfem.errors.NsfemError` unless file ``path`` can be written (see
    :func:`check_folder`; a folder of that name is refused)."""
    from .errors import NsfemError

    path = Path(path)
    if path.is_dir():
        raise NsfemError(f"{what}: {path} is a folder, not a file")
    check_folder(path.parent if str(path.parent) else Path("."), what)
    return path
