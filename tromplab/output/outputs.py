"""Writing outputs all-or-nothing, without ever destroying a previous result.

An output folder (``tromplab fit -o OUT``) is built in a staging folder beside it,
``.OUT.tmp-<pid>-<random>``, and swapped into place only after every file was written:
on Linux in one atomic ``renameat2(RENAME_EXCHANGE)`` call, elsewhere in two renames
(``OUT`` -> ``.OUT.old-<pid>``, staging -> ``OUT``) that the next run completes or
rolls back if the process died between them.  A killed run (SIGINT, SIGTERM, SIGKILL)
therefore leaves ``OUT`` holding either the previous outputs or the new ones, never a
mix.  Staging folders of dead runs are recognised by their pid and removed by the next
run into the same place.  A lock (``fcntl.flock``) serialises the swap of concurrent runs
into one folder, so the folder holds one run's outputs; its file lies in a private folder of
the user outside the working tree (:func:`lock_folder`), named by a hash of the resolved
output path, so a run leaves nothing beside its outputs.

SIGINT and SIGTERM are held back during the swap itself and the record of it
(:func:`written_outputs`), so an interrupt that arrives then or later says truthfully that
the new outputs were written.

The folder keeps files the previous run did not write (a report, the user's notes): a
hidden manifest (:data:`MANIFEST`) lists what the run wrote, and the next run replaces
exactly those and carries the others over.  Single files (``points -o FILE``) go to a
temporary file in the same folder and are moved into place with one ``os.replace``.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import logging
import os
import re
import shutil
import signal
import stat
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterable
from pathlib import Path

from ..errors import OutputError

logger = logging.getLogger(__name__)

#: Hidden file in an output folder listing the files the run wrote, one a line.
MANIFEST = ".tromplab-manifest"
#: Test-only hook: seconds (at most 60) to sleep just before the swap, with everything staged
#: and the lock held, so a test can kill a run in that moment (tests/test_signals.py).  Unset
#: or not a number: no pause.  It changes nothing but the timing.
SWAP_PAUSE_VARIABLE = "TROMPLAB_TEST_SWAP_PAUSE"
_RENAME_EXCHANGE = 2
#: Output folders and files this process has put in place (:func:`written_outputs`).
_WRITTEN: list[Path] = []
_STAGING = re.compile(r"^\.(?P<name>.+)\.(?P<what>tmp|old)-(?P<pid>\d+)(?:-[A-Za-z0-9_]+)?$")


def check_output_folder(outdir, *, inputs: Iterable = (), option: str = "--outdir") -> Path:
    """Raise :class:`OutputError` before any work when ``outdir`` cannot take the outputs."""
    outdir = Path(outdir)
    if outdir.exists() and not outdir.is_dir():
        raise OutputError(f"{option} names a file, not a folder", source=str(outdir))
    resolved = outdir.resolve()
    if resolved == Path.cwd().resolve() or resolved == Path(resolved.anchor) or resolved == Path.home().resolve():
        raise OutputError(
            f"{option} must name a folder for the outputs, not the working, home or root folder", source=str(outdir)
        )
    for path in inputs:
        if Path(path).resolve().is_relative_to(resolved):
            raise OutputError(f"{option} holds the input {path}; write the outputs to another folder", source=str(outdir))
    _check_writable_parent(outdir, option)
    if outdir.is_dir() and not os.access(outdir, os.R_OK | os.X_OK):
        raise OutputError(f"{option}: the folder cannot be read (permission denied)", source=str(outdir))
    return outdir


def check_output_file(path, *, inputs: Iterable = (), option: str = "--output") -> Path:
    """Raise :class:`OutputError` before any work when ``path`` cannot be (over)written."""
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"{option} names a folder; give a file name", source=str(path))
    if path.exists() and not path.is_file():
        raise OutputError(f"{option} names something that is not a regular file", source=str(path))
    for source in inputs:
        if Path(source).resolve() == path.resolve():
            raise OutputError(f"{option} is the input file; it would be overwritten", source=str(path))
    if path.exists() and not os.access(path, os.W_OK):
        raise OutputError(f"{option}: the file is read-only", source=str(path))
    _check_writable_parent(path, option)
    return path


def _check_writable_parent(path: Path, option: str) -> None:
    parent = path.absolute().parent
    while not parent.exists():  # folders to create: the first existing ancestor must be writable
        parent = parent.parent
    if not parent.is_dir():
        raise OutputError(f"{option}: {parent} is a file, so no folder can be made under it", source=str(path))
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{option}: cannot write into {parent} (permission denied)", source=str(path))


# --- writing ----------------------------------------------------------------------------
def staging_folder_beside(outdir) -> Path:
    """A new empty folder beside ``outdir`` (its parent made when missing), named as a staging
    folder, ``.OUT.tmp-<pid>-<random>``, so that :func:`clean_stale` removes it when this process
    has died; ``outdir`` is checked first (:func:`check_output_folder`)."""
    outdir = check_output_folder(outdir)
    parent = outdir.absolute().parent
    parent.mkdir(parents=True, exist_ok=True)
    return Path(tempfile.mkdtemp(dir=parent, prefix=f".{outdir.name}.tmp-{os.getpid()}-"))


def replace_folder(outputs: dict[str, Callable[[Path], None]], outdir) -> dict[str, Path]:
    """Write ``outputs`` (file name -> writer taking a path) as the new content of ``outdir``.

    Files of the previous run (listed in its manifest) are replaced as a whole; other
    files in ``outdir`` are carried over.  If a writer fails or the process is killed,
    ``outdir`` is left as it was.

    Returns
    -------
    dict
        File name -> path in ``outdir``.
    """
    outdir = Path(outdir)
    staging = staging_folder_beside(outdir)
    try:
        for name, writer in outputs.items():
            _check_name(name)
            writer(staging / name)
        (staging / MANIFEST).write_text("".join(f"{name}\n" for name in sorted(outputs)), encoding="utf-8")
        logger.info("wrote %d file(s) into the staging folder %s", len(outputs), staging)
        with _folder_lock(staging.parent, outdir.name):
            clean_stale(outdir)
            if outdir.is_dir():
                _carry_over(outdir, staging, set(outputs))
            _pause_for_tests()
            with _interrupts_held():  # the swap and its record are one step for an interrupt
                _swap_into_place(staging, outdir)
                _WRITTEN.append(outdir)
            logger.info("swapped the new outputs into %s", outdir)
    finally:
        shutil.rmtree(staging, ignore_errors=True)  # after the swap it holds the previous run
    return {name: outdir / name for name in outputs}


def write_files(outputs: dict[str, Callable[[Path], None]], outdir) -> dict[str, Path]:
    """Write each output to a temporary file in ``outdir``, then move them all into place.

    For single files beside other things (a points CSV, a report): if a writer fails,
    nothing is moved; each file is replaced in one step.
    """
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    clean_stale(outdir / ".tromplab")  # staging of dead runs of this function
    staging = Path(tempfile.mkdtemp(dir=outdir, prefix=f"..tromplab.tmp-{os.getpid()}-"))
    try:
        for name, writer in outputs.items():
            _check_name(name)
            writer(staging / name)
        written = {}
        with _folder_lock(outdir, ".tromplab"), _interrupts_held():
            for name in outputs:
                os.replace(staging / name, outdir / name)
                written[name] = outdir / name
                _WRITTEN.append(outdir / name)
                logger.info("wrote %s", outdir / name)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return written


def clean_stale(outdir) -> list[Path]:
    """Remove staging folders of dead runs beside ``outdir``; finish an interrupted swap.

    Returns the paths removed or restored.
    """
    outdir = Path(outdir)
    parent = outdir.absolute().parent
    if not parent.is_dir():
        return []
    handled = []
    for entry in sorted(parent.iterdir()):
        match = _STAGING.match(entry.name)
        if not match or match["name"] != outdir.name or _alive(int(match["pid"])):
            continue
        if match["what"] == "old" and not outdir.exists():
            os.rename(entry, outdir)  # killed between the two renames: put the previous run back
        else:
            shutil.rmtree(entry, ignore_errors=True)
        logger.info("removed %s, left by a run that ended before its swap", entry)
        handled.append(entry)
    return handled


def _check_name(name: str) -> None:
    if not name or name in (".", "..") or "/" in name or "\\" in name or "\0" in name or name == MANIFEST:
        raise OutputError(f"output file name {name!r} is not a plain file name")


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's live process
        return True
    return True


def written_outputs() -> list[Path]:
    """The output folders and files this process has put in place since :func:`forget_written`
    (the command line says so when it is interrupted after them)."""
    return list(_WRITTEN)


def forget_written() -> None:
    """Start a new record for :func:`written_outputs` (each command does)."""
    _WRITTEN.clear()


@contextlib.contextmanager
def _interrupts_held():
    """SIGINT and SIGTERM that arrive inside the block are held and handed to their handlers
    when it is left.  Python runs signal handlers in the main thread whichever thread the
    kernel delivered the signal to, so the handlers are swapped there (masking the signal in
    one thread would not hold it: the pools' threads take it).  Elsewhere: nothing to hold."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []
    previous = {}
    for signum in (signal.SIGINT, signal.SIGTERM):
        handler = signal.getsignal(signum)
        if handler is not None and handler is not signal.SIG_IGN:  # None: set outside Python, left alone
            previous[signum] = signal.signal(signum, lambda number, frame: caught.append((number, frame)))
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        for signum, frame in caught[:1]:  # the first one decides, as it would have
            handler = previous[signum]
            if callable(handler):
                handler(signum, frame)
            else:  # the default action (end the process): deliver it again now
                os.kill(os.getpid(), signum)


def lock_folder() -> Path:
    """The private folder of this user's lock files: ``tromplab-locks-<uid>`` in
    ``$XDG_RUNTIME_DIR`` (a per-user folder emptied at log-out) or else the system's
    temporary folder; made with mode 0700 and refused if it is another user's or open to others."""
    runtime = os.environ.get("XDG_RUNTIME_DIR", "")
    base = Path(runtime) if runtime and os.path.isdir(runtime) else Path(tempfile.gettempdir())
    folder = base / f"tromplab-locks-{os.getuid()}"
    with contextlib.suppress(FileExistsError):
        folder.mkdir(mode=0o700)
    info = os.lstat(folder)
    if not stat.S_ISDIR(info.st_mode) or info.st_uid != os.getuid() or info.st_mode & 0o077:
        raise OutputError(f"the lock folder {folder} is not a private folder of this user (mode 0700); remove it")
    return folder


def lock_path(target) -> Path:
    """The lock file of the output path ``target`` (resolved, so every spelling of one
    folder shares one lock)."""
    key = hashlib.sha256(os.fsencode(Path(target).resolve())).hexdigest()[:32]
    return lock_folder() / f"{key}.lock"


@contextlib.contextmanager
def _folder_lock(parent: Path, name: str):
    import fcntl

    descriptor = os.open(lock_path(parent / name), os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o600)
    with os.fdopen(descriptor, "r+b") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)  # released when the handle closes, also when killed
        yield


def _pause_for_tests() -> None:
    try:
        seconds = float(os.environ.get(SWAP_PAUSE_VARIABLE, ""))
    except ValueError:
        return
    if 0 < seconds:  # also False for nan
        time.sleep(min(seconds, 60.0))


def _carry_over(outdir: Path, staging: Path, new_names: set[str]) -> None:
    manifest = outdir / MANIFEST
    previous = set(manifest.read_text(encoding="utf-8").splitlines()) if manifest.is_file() else set()
    for entry in outdir.iterdir():
        name = entry.name
        if name in new_names or name in previous or name == MANIFEST or name.startswith(".tromplab-"):
            continue  # replaced, or a staging folder of the version before this module
        target = staging / name
        if entry.is_dir() and not entry.is_symlink():
            shutil.copytree(entry, target, symlinks=True, copy_function=_link_or_copy)
        else:
            _link_or_copy(entry, target)


def _link_or_copy(source, target) -> None:
    if os.path.islink(source):
        os.symlink(os.readlink(source), target)
        return
    try:
        os.link(source, target)  # no copy: the same file, in both folders until the swap
    except OSError:
        shutil.copy2(source, target)


def _swap_into_place(staging: Path, outdir: Path) -> None:
    if not outdir.exists():
        os.rename(staging, outdir)
        os.mkdir(staging)  # the caller removes it
        return
    if _exchange(staging, outdir):
        return
    old = outdir.absolute().parent / f".{outdir.name}.old-{os.getpid()}"
    os.rename(outdir, old)
    os.rename(staging, outdir)
    os.rename(old, staging)


def _exchange(first: Path, second: Path) -> bool:
    """Swap two paths in one atomic step (Linux ``renameat2``); False where unsupported."""
    if not sys.platform.startswith("linux"):
        return False
    import ctypes  # here: 5 ms of start-up a command that writes no folder over another does not pay

    try:
        # the C library the interpreter runs on, by the process's own symbols: looking its file
        # up (ctypes.util.find_library) runs ldconfig in a subprocess, 15 ms of every swap
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):  # a C library without renameat2 (glibc before 2.28, musl)
        return False
    at_fdcwd = -100
    result = renameat2(at_fdcwd, os.fsencode(first.absolute()), at_fdcwd, os.fsencode(second.absolute()), _RENAME_EXCHANGE)
    if result == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP, errno.EOPNOTSUPP):
        return False  # this file system cannot exchange: fall back to two renames
    raise OSError(code, os.strerror(code), str(second))


# --- file names from experiment names --------------------------------------------------
#: Longest file-name stem kept from an experiment name (file systems allow 255 bytes).
MAX_STEM = 60


def figure_file_names(experiments: Iterable[str], *, prefix: str = "curves_", suffix: str = ".png") -> dict[str, str]:
    """Distinct, safe file names for experiment names, stable from run to run.

    Letters and digits (any script) are kept; path separators, ``..``, control and other
    characters become ``_``; long names are cut to :data:`MAX_STEM` characters.  When the
    result differs from the name, or two names would give the same file (also when they
    differ only in case, for case-insensitive file systems), a short hash of the full name
    is appended, so different experiments never share a file.

    Examples
    --------
    >>> figure_file_names(["A1", "Проба 1", "Образец 1"])
    {'A1': 'curves_A1.png', 'Проба 1': 'curves_Проба_1_7f5e3113.png', 'Образец 1': 'curves_Образец_1_950341bc.png'}
    """
    import hashlib
    import unicodedata

    names = list(dict.fromkeys(str(e) for e in experiments))
    stems = {}
    for name in names:
        text = unicodedata.normalize("NFC", name)
        stem = re.sub(r"[^\w.-]+", "_", text, flags=re.UNICODE).strip("._-")[:MAX_STEM].strip("._-")
        stems[name] = stem or "experiment"
    folded = {}
    for name, stem in stems.items():
        folded.setdefault(stem.casefold(), []).append(name)
    files = {}
    for name, stem in stems.items():
        if stem != name or len(folded[stem.casefold()]) > 1:
            stem = f"{stem}_{hashlib.sha256(name.encode('utf-8')).hexdigest()[:8]}"
        files[name] = f"{prefix}{stem}{suffix}"
    return files
