"""Input paths checked before anything is read: light (the standard library only), so the
command line checks them before it imports the numerical libraries."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import InputError


def check_input_file(path, *, option: str = "input") -> Path:
    """``path`` exists, is a regular file and can be read; else an :class:`InputError` naming it."""
    path = Path(path)
    if not path.exists():
        raise InputError("file not found", source=str(path))
    if path.is_dir():
        raise InputError(f"is a folder; the {option} must be a file", source=str(path))
    if not path.is_file():
        raise InputError(f"is not a regular file; the {option} must be a file", source=str(path))
    if not os.access(path, os.R_OK):
        raise InputError("cannot be read (permission denied)", source=str(path))
    return path
