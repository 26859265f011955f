"""The sessions of the page's browsers: each in a temporary folder of its own, known only by
an unguessable token in its cookie, removed when the page says it is closed, after an idle
hour, or when the server stops.
"""

from __future__ import annotations

import re
import secrets
import shutil
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from .jobs import Job

#: A session not heard from for this long (seconds) is ended and its folder removed.
IDLE_SECONDS = 3600
#: Characters kept in the name of an uploaded file (others become ``_``): letters, digits,
#: space, ``.``, ``(``, ``)``, ``-``; the name is the file's only path element.
_UNSAFE_IN_NAME = re.compile(r"[^\w .()-]")


def safe_file_name(name: str) -> str:
    """The name an uploaded file is stored under: its last path element, with characters
    other than letters, digits, space and ``.()-`` replaced by ``_``, at most 100 characters."""
    last = re.split(r"[\\/]", str(name))[-1].strip()
    stem, dot, suffix = last.rpartition(".")
    safe_stem = _UNSAFE_IN_NAME.sub("_", stem if dot else last)[:90].lstrip(".") or "upload"
    return f"{safe_stem}.{_UNSAFE_IN_NAME.sub('_', suffix)[:8]}" if dot else safe_stem


@dataclass
class Upload:
    """A table a session dropped: its stored path, the name as the browser sent it, its sheets,
    its kind and the commands that read it (told from its columns, the default first)."""

    path: Path
    shown_name: str
    sheets: list[str]
    kind: str = "unknown"
    commands: tuple[tuple[str, ...], ...] = (("fit",),)


@dataclass
class Session:
    """One browser's work: its folder, its table (the last one dropped), the flowsheet and the
    survey of a circuit (the last of each, kept until a table of another kind is dropped), its
    current run."""

    token: str
    folder: Path
    upload: Upload | None = None
    circuit: dict[str, Upload] = field(default_factory=dict)
    job: Job | None = None
    runs: int = 0
    uploads: int = 0
    last_seen: float = field(default_factory=time.monotonic)

    def upload_folder(self) -> Path:
        """A new, empty folder for the next file dropped (two files may share a name)."""
        self.uploads += 1
        folder = self.folder / "upload" / str(self.uploads)
        folder.mkdir(parents=True)
        return folder

    def forget_unused_uploads(self) -> None:
        """Remove the files dropped before that the session no longer works on."""
        kept = {upload.path.parent for upload in (self.upload, *self.circuit.values()) if upload is not None}
        for folder in (self.folder / "upload").iterdir():
            if folder not in kept:
                shutil.rmtree(folder, ignore_errors=True)

    def job_folder(self) -> Path:
        """A new, empty folder for the next run."""
        self.runs += 1
        folder = self.folder / f"run{self.runs}"
        folder.mkdir()
        return folder

    def end(self) -> None:
        if self.job is not None:
            self.job.stop()
        shutil.rmtree(self.folder, ignore_errors=True)


class Sessions:
    """The server's sessions, each in a folder under one temporary root removed by :meth:`close`."""

    def __init__(self, *, idle_seconds: float = IDLE_SECONDS):
        self.root = Path(tempfile.mkdtemp(prefix="tromplab-app-"))
        self.idle_seconds = idle_seconds
        self._sessions: dict[str, Session] = {}
        self._lock = threading.Lock()

    def new(self) -> Session:
        token = secrets.token_urlsafe(32)
        folder = self.root / secrets.token_hex(8)  # not the token: a folder's name is no key
        folder.mkdir(mode=0o700)
        session = Session(token, folder)
        with self._lock:
            self._sessions[token] = session
        return session

    def get(self, token: str | None) -> Session | None:
        with self._lock:
            session = self._sessions.get(token or "")
        if session is not None:
            session.last_seen = time.monotonic()
        return session

    def end(self, token: str | None) -> bool:
        with self._lock:
            session = self._sessions.pop(token or "", None)
        if session is not None:
            session.end()
        return session is not None

    def sweep(self) -> int:
        """End the sessions idle longer than ``idle_seconds``; returns how many."""
        now = time.monotonic()
        with self._lock:
            idle = [token for token, session in self._sessions.items() if now - session.last_seen > self.idle_seconds]
        return sum(self.end(token) for token in idle)

    def __len__(self) -> int:
        return len(self._sessions)

    def close(self) -> None:
        """End every session and remove the root folder."""
        with self._lock:
            tokens = list(self._sessions)
        for token in tokens:
            self.end(token)
        shutil.rmtree(self.root, ignore_errors=True)
