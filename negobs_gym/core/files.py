"""Atomic file writes: every result the package writes appears whole or not at all.

A reader (a resumed campaign, a plot script, a second process) never sees a partial file: the
content goes to a temp file in the target's folder, is flushed to disk, and ``os.replace`` puts it
in place, which is atomic on one file system. A failed write leaves the old file, if any, as it was.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["atomic_target", "write_atomic", "write_bytes_atomic", "write_text_atomic"]


@contextmanager
def atomic_target(path: str | Path) -> Iterator[Path]:
    """A temp file's path to fill inside the ``with`` block, for writers that stream over time (a
    video); on a clean exit it is fsynced and renamed over ``path``, on an exception removed. The
    temp file is in ``path``'s folder (created if missing) and keeps its suffix, for writers that
    choose the format by it; the file gets the usual umask permissions."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp{path.suffix}")
    try:
        yield tmp
        with open(tmp, "rb+") as written:
            os.fsync(written.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_atomic(path: str | Path, write: Callable[[Path], object]) -> Path:
    """Create or replace ``path`` atomically: ``write(tmp)`` fills the temp file of
    :func:`atomic_target`. Returns ``path``."""
    with atomic_target(path) as tmp:
        write(tmp)
    return Path(path)


def write_bytes_atomic(path: str | Path, data: bytes) -> Path:
    """``data`` written to ``path`` with :func:`write_atomic`."""
    return write_atomic(path, lambda tmp: tmp.write_bytes(data))


def write_text_atomic(path: str | Path, text: str) -> Path:
    """UTF-8 ``text`` written to ``path`` with :func:`write_atomic`."""
    return write_bytes_atomic(path, text.encode("utf-8"))
