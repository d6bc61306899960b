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

import os
import tempfile
from pathlib import Path
from typing import Callable


def write_atomic(path: str | Path, write: Callable[[str], object]) -> Path:
    """Call ``write(tmp)`` on a temporary file in ``path``'s folder (created if missing), then
    rename it onto ``path`` with the usual permissions (0666 less the umask); on any error or
    interruption the temporary file is removed and ``path`` is left as it was."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes it private
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


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
