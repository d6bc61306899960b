"""An output folder holds one run: a lock while a command writes it, and a manifest of what it wrote.

:func:`claim` takes a folder for a command (``nsfem run``, ``export``, ``fit``, ``sweep``):

* **lock**: ``fcntl.flock`` on ``.nsfem.lock`` in the folder, held until the command ends; the
  OS releases it when the process dies, so a killed run leaves no stale lock. A second command
  that wants the folder meanwhile gets a one-line error naming the folder and the other process.
* **leftovers**: the temporary files of a killed earlier write (``.<name>.XXXXXXXX.tmp``, see
  :func:`nsfem.atomic.write_atomic`) are removed.
* **manifest** (``.nsfem-files.json``): the files nsfem wrote there, by kind (``run``: result.npz,
  plots, sensors, render.png; ``series``: the .pvd and its frames, ``vtu/...``: the files of the
  subfolders in :data:`SUBFOLDERS` are listed by their path in the folder; ``fit``: fit.json,
  evaluations.csv and its plots; ``periodic``: periodic.json, orbit.npz and its plots). A command replaces its kinds: once its first file is written the
  files of those kinds that it will not rewrite are removed (and the old .pvd, whose frames are
  about to be replaced), at the end those it did not rewrite after all (an interrupted run). Only
  files named in a manifest are ever removed: a user's own files in the folder are left alone.
* **planned** names: while a command writes, the manifest also lists what it may still write, and
  the lock file logs each file once written. A command killed outright (SIGKILL, power loss) leaves
  both; the next one counts as nsfem's only the planned names the log confirms, so a file the user
  later gives a planned name is never taken for the killed command's.

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
import errno
import json
import os
import stat
from pathlib import Path
from typing import Iterable, Iterator, Mapping

from .atomic import OUTPUT_SUFFIXES, PROBE_NAME, TMP_NAME, journal, signals_deferred, write_text_atomic
from .errors import NsfemError

try:  # POSIX; elsewhere (Windows) folders are not locked
    import fcntl
except ImportError:  # pragma: no cover - not on the project's machines
    fcntl = None

#: flock's answers on a file system that has no locks (some network and parallel file systems): the
#: folder is then written without one, as on a platform without fcntl
NO_LOCKS = {errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL}

LOCK = ".nsfem.lock"
MANIFEST = ".nsfem-files.json"
#: the subfolders of an output folder that nsfem writes files into (a VTU series' frames,
#: :data:`nsfem.export.vtu.SUBFOLDER`); the manifest names their files ``<subfolder>/<name>``
SUBFOLDERS = ("vtu",)
#: the kinds of output each command replaces
REPLACES = {"run": ("run", "series"), "export": ("series",), "fit": ("fit",), "sweep": (), "render": (),
            "periodic": ("periodic", "series"), "branch": ("branch",)}


class FolderBusy(NsfemError):
    """Another nsfem process is writing the folder."""


def _lock(path: Path, what: str) -> int | None:
    """An exclusive lock on ``path/LOCK`` (its descriptor); FolderBusy when another process holds it.
    Where the file system has no locks the folder is written unlocked (the file, still opened, logs
    the files written); None where the platform has none (no log either)."""
    if fcntl is None:
        return None
    lock = path / LOCK
    while True:
        try:  # never through a link: the file is truncated
            fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o666)
        except OSError as exc:
            raise NsfemError(f"{what}: cannot create the lock file {lock}: {exc.strerror or exc}") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            try:
                other = os.read(fd, 4096).decode("utf-8", "replace").strip()
            finally:
                os.close(fd)
            other = other.splitlines()[0] if other else ""  # its first line: who; then the files it wrote
            raise FolderBusy(f"{what}: {path} is being written by another nsfem process ({other or 'starting'}); "
                             "wait for it to end or choose another folder") from None
        except OSError as exc:
            if exc.errno in NO_LOCKS:  # a file system without locks: written unlocked, the file still
                return fd                # logs the files written (a killed command's, for the next one)
            os.close(fd)
            raise NsfemError(f"{what}: cannot lock {lock}: {exc.strerror or exc}") from None
        try:  # the holder before us may have removed the file: then lock the new one
            if os.stat(lock).st_ino == os.fstat(fd).st_ino:
                return fd
        except FileNotFoundError:
            pass
        os.close(fd)


def _names(name: object) -> bool:
    """A file name of the folder of a kind nsfem writes (a plain name, or one in a subfolder of
    :data:`SUBFOLDERS`; not the bookkeeping files): a manifest edited by hand never costs a scene, a
    mesh or notes, nor a file elsewhere."""
    if isinstance(name, str) and name.count("/") == 1:
        sub, name = name.split("/")
        if sub not in SUBFOLDERS:
            return False
    return (isinstance(name, str) and "/" not in name and "\0" not in name
            and name not in ("", ".", "..", LOCK, MANIFEST) and name.endswith(OUTPUT_SUFFIXES))


def _subfolders(path: Path) -> list[str]:
    """The subfolders of :data:`SUBFOLDERS` that folder ``path`` has (real folders, not links)."""
    return [sub for sub in SUBFOLDERS if (path / sub).is_dir() and not (path / sub).is_symlink()]


def _listing(path: Path) -> set[str]:
    """The names in folder ``path``, and ``<subfolder>/<name>`` of those in its :func:`_subfolders`."""
    names = {e.name for e in os.scandir(path)}
    for sub in _subfolders(path):
        with contextlib.suppress(OSError):
            names |= {f"{sub}/{e.name}" for e in os.scandir(path / sub)}
    return names


def _read_manifest(path: Path, entry: str = "files") -> dict[str, set[str]]:
    """The manifest's ``files`` (written by nsfem) or ``planned`` (that a command still writing may write), by kind."""
    try:
        data = json.loads((path / MANIFEST).read_text(encoding="utf-8"))
        kinds = data.get(entry, {}) if entry != "files" else data["files"]
        return {str(k): {n for n in v if _names(n)} for k, v in kinds.items() if isinstance(v, list)}
    except (OSError, ValueError, TypeError, KeyError, AttributeError):
        return {}


def _write_manifest(path: Path, files: Mapping[str, Iterable[str]],
                    planned: Mapping[str, Iterable[str]] | None = None) -> None:
    files = {k: sorted(v) for k, v in files.items() if v}
    planned = {k: sorted(v) for k, v in (planned or {}).items() if v}
    if files or planned:
        data = {"files": files, **({"planned": planned} if planned else {})}
        write_text_atomic(path / MANIFEST, json.dumps(data, indent=0) + "\n")
    else:
        with contextlib.suppress(FileNotFoundError):
            (path / MANIFEST).unlink()


def _logged(fd: int) -> set[str]:
    """The files a killed earlier command logged in the lock file ``fd`` as written (``wrote <name>`` lines)."""
    chunks = []
    os.lseek(fd, 0, os.SEEK_SET)
    while chunk := os.read(fd, 1 << 20):
        chunks.append(chunk)
    lines = b"".join(chunks).decode("utf-8", "surrogateescape").split("\n")
    return {line[6:] for line in lines if line.startswith("wrote ") and _names(line[6:])}


def _settle(path: Path, logged: set[str]) -> None:
    """A manifest left by a command killed while writing: its planned names that the lock file's log
    confirms join its files; the others are no file of nsfem's (never written, or the user's since)."""
    planned = _read_manifest(path, "planned")
    if not planned:
        return
    files = _read_manifest(path)
    _write_manifest(path, {k: files.get(k, set()) | (planned.get(k, set()) & logged)
                           for k in set(files) | set(planned)})


def _remove(path: Path, names: Iterable[str]) -> None:
    """Remove the files ``names`` of folder ``path``, and a subfolder they leave empty; never through a
    link (a subfolder replaced by a link to another folder keeps that folder's files)."""
    emptied, real = set(), set(_subfolders(path))
    for name in names:
        if "/" in name and name.split("/")[0] not in real:
            continue
        with contextlib.suppress(OSError):  # gone already, a folder of that name, read-only
            (path / name).unlink()
            if "/" in name:
                emptied.add(name.split("/")[0])
    for sub in emptied:
        with contextlib.suppress(OSError):  # not empty: the user's files or the new series
            (path / sub).rmdir()


def replaced_bytes(path, command: str) -> float:
    """Bytes of the files in folder ``path`` that ``command`` replaces (its kinds in the manifest): the
    room a run re-run into its own folder gets back, besides the file system's free space."""
    path = Path(path)
    files = _read_manifest(path)
    total = 0.0
    for name in set().union(set(), *(files.get(k, set()) for k in REPLACES[command])):
        with contextlib.suppress(OSError):
            st = os.lstat(path / name)
            if stat.S_ISREG(st.st_mode):
                total += st.st_size
    return total


def remove_leftovers(path: Path) -> list[str]:
    """Remove the temporary files of killed writes (and probes) in folder ``path`` and its
    :func:`_subfolders`; their names."""
    gone = []
    path = Path(path)
    for folder, where in [(path, "")] + [(path / sub, f"{sub}/") for sub in _subfolders(path)]:
        with contextlib.suppress(OSError):
            for entry in os.scandir(folder):
                if entry.is_file(follow_symlinks=False) and (TMP_NAME.match(entry.name)
                                                             or PROBE_NAME.match(entry.name)):
                    with contextlib.suppress(FileNotFoundError):
                        os.unlink(entry.path)
                        gone.append(where + entry.name)
    return gone


@contextlib.contextmanager
def claim(path, command: str, expected: Mapping[str, Iterable[str]] | None = None,
          what: str = "--out", inputs: Iterable = ()) -> Iterator[set]:
    """Hold folder ``path`` for ``command`` (a key of :data:`REPLACES`) within the block; yields the
    set of paths written in it so far (:func:`nsfem.atomic.journal`).

    ``expected``: per kind, the names the command may write. Once its first file there is written,
    the files of the kinds it replaces that it will not write are removed (a command refused,
    failing or stopped before that leaves the folder as it was); at the end those it did not rewrite. ``what``
    names the folder in messages (``--out``, ``--vtu``, ``output.dir``). ``inputs``: the files the
    command reads (fit's data); one in the folder is the user's from then on, never removed as an
    earlier run's file. The folder is created if missing and removed again if the command leaves it empty.
    """
    path = Path(path)
    created = not path.exists()
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise NsfemError(f"{what}: cannot create {path}: {exc.strerror or exc}") from None
    fd = None
    try:
        with signals_deferred():  # an interrupt while locking leaves no lock file behind
            fd = _lock(path, what)
        logged = _logged(fd) if fd is not None else set()
        with signals_deferred():
            _settle(path, logged)
            _adopt(path, inputs)
        _refuse_users_files(path, expected or {}, what)
        if fd is not None:
            os.ftruncate(fd, 0)
            os.lseek(fd, 0, os.SEEK_SET)
            started = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
            os.write(fd, f"pid {os.getpid()}, nsfem {command} started {started}\n".encode())
        with signals_deferred():
            remove_leftovers(path)
        folder = _Folder(path, REPLACES[command], {k: set(v) for k, v in (expected or {}).items()}, fd)
        with journal(before=folder.before_write, after=folder.log) as written:
            try:
                yield written
            finally:
                with signals_deferred():  # the folder's bookkeeping is never left half done
                    folder.finish(written)
    finally:
        if fd is not None:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(path / LOCK)
            os.close(fd)
        if created:
            with contextlib.suppress(OSError):
                path.rmdir()  # only when empty


def _adopt(path: Path, inputs: Iterable) -> None:
    """Drop from the manifest the files of folder ``path`` among ``inputs``: read by the command, they are the user's."""
    here = path.resolve()
    names = {Path(p).name for p in inputs if Path(p).resolve().parent == here}
    files = _read_manifest(path)
    if names & set().union(set(), *files.values()):
        _write_manifest(path, {k: v - names for k, v in files.items()})


def _refuse_users_files(path: Path, expected: Mapping[str, Iterable[str]], what: str) -> None:
    """A folder nsfem keeps a manifest of, holding a file the command would overwrite that nsfem did
    not write there (the user's data named sensors.csv, a fit's data): refused, saying so. (A folder
    without a manifest, written by an older nsfem, cannot tell: its files are taken as a run's.)"""
    if not (path / MANIFEST).exists():
        return
    ours = set().union(set(), *_read_manifest(path).values())
    names = set().union(set(), *(set(v) for v in expected.values()))
    clash = sorted(n for n in _listing(path) if n in names and n not in ours)
    if clash:
        more = f" (and {len(clash) - 1} more)" if len(clash) > 1 else ""
        raise NsfemError(f"{what}: {path} holds {clash[0]}{more}, which nsfem did not write there and this command "
                         "would overwrite; move it away or choose another folder")


class _Folder:
    """The manifest's side of :func:`claim`: ``kinds`` replaced, ``expected`` names per kind, ``fd``
    the lock file (None: unlocked), where each file written is logged."""

    def __init__(self, path: Path, kinds: tuple[str, ...], expected: dict[str, set[str]], fd: int | None = None):
        self.path, self.here, self.kinds, self.expected, self.fd = path, path.resolve(), kinds, expected, fd
        self.old: dict[str, set[str]] | None = None   # the manifest once writing was tried
        self.planned: dict[str, set[str]] = {}
        self.replaced = False   # the older files replaced: a file was written

    def _name(self, target: Path) -> str | None:
        """``target``'s name in the manifest (``<subfolder>/<name>`` in a subfolder), None when it is
        not a file of the folder of a kind nsfem writes."""
        target = Path(target)
        parent = target.parent.resolve()
        if parent == self.here:
            name = target.name
        elif parent.parent == self.here and parent.name in SUBFOLDERS and not (self.here / parent.name).is_symlink():
            name = f"{parent.name}/{target.name}"
        else:
            return None
        return name if _names(name) else None

    def _ours(self, target: Path) -> bool:
        return self._name(target) is not None

    def before_write(self, target: Path) -> None:
        """Before the first write into the folder: the manifest plans what the command may write (not
        a user's own files of those names), so a killed command's files, its log confirming them,
        are known to the next one. Nothing is removed yet."""
        if self.old is not None or not self._ours(target):
            return
        with signals_deferred():
            old = _read_manifest(self.path)
            existing = _listing(self.path)
            self.old = old = {k: v & existing for k, v in old.items()}
            users = existing - set().union(set(), *old.values())
            self.planned = {k: v - users - old.get(k, set()) for k, v in self.expected.items()}
            _write_manifest(self.path, old, self.planned)

    def log(self, target: Path) -> None:
        """A file just written into the folder: logged in the lock file (read back if this process is
        killed); after the first, the older files this command will not write are removed (and the
        old .pvd, whose frames are about to be replaced): a command that fails or is stopped
        before it has written a file leaves the earlier one's as they were."""
        if not self._ours(target):
            return
        if self.fd is not None:
            with contextlib.suppress(OSError):
                os.write(self.fd, f"wrote {self._name(target)}\n".encode("utf-8", "surrogateescape"))
        if self.replaced or self.old is None:
            return
        with signals_deferred():
            self.replaced = True
            stale = {n for k in self.kinds for n in self.old.get(k, set())
                     if n not in self.expected.get(k, set()) or n.endswith(".pvd")} - {self._name(target)}
            _remove(self.path, stale)
            self.old = {k: v - stale for k, v in self.old.items()}
            if stale:
                _write_manifest(self.path, self.old, self.planned)

    def finish(self, written: set) -> None:
        """The manifest after the command: the kinds it replaces hold what it wrote, and their older
        files it did not rewrite are removed (they belong to another run); other kinds gain what
        it wrote of them. A command that wrote nothing leaves the manifest as it was."""
        remove_leftovers(self.path)  # a write cut short in a window write_atomic cannot close
        for sub in _subfolders(self.path):  # one this command was to write into, left empty
            if any(n.startswith(f"{sub}/") for v in self.expected.values() for n in v):
                with contextlib.suppress(OSError):
                    (self.path / sub).rmdir()
        if self.old is None:  # nothing tried
            return
        # written and still there: a file the command removed again (the frame an interrupt cut short,
        # nsfem.export.vtu.write_series) is not its, so a user's file later of that name never counts as nsfem's
        names = {self._name(Path(p)) for p in written if self._ours(Path(p)) and os.path.lexists(p)}
        if not self.replaced:  # every write failed: the folder is as it was
            _write_manifest(self.path, self.old)
            return
        new = {k: set(v) - names for k, v in self.old.items()}
        for k in self.kinds:
            _remove(self.path, self.old.get(k, set()) - names)
            new[k] = set()
        for k, v in self.expected.items():
            new[k] = new.get(k, set()) | (names & v)
        _write_manifest(self.path, new)


#: the files of ``nsfem fit`` (:func:`nsfem.fit.result._write`)
FIT_FILES = frozenset({"fit.json", "evaluations.csv", "fit.png", "landscape.png"})
