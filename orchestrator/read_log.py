"""The files a scenario load reads, recorded where they are opened (for ``sweep --resume``).

:func:`orchestrator.load_scenario` runs inside :func:`recording`; every file opened through
:func:`orchestrator.untrusted.open_regular` (the one reader of untrusted files: the scenario
YAML, an SSP archive, its .ssd and .ssv files, every FMU archive) and every model description
taken from the cache (:func:`orchestrator.fmi.archive.cached_model_description`) is noted in
the active :class:`ReadLog`. A new kind of file the loader learns to read is therefore covered
without a list to keep up to date. Files under a folder rotorcosim made itself while loading
(the extracted SSP archive, the generated scenario) are not inputs: :func:`made_here` excludes
them (the archive they came from is recorded).

:func:`fingerprint` is the digest the sweep records per file: SHA-256 of the content, or for a
file larger than :data:`MAX_DIGEST_BYTES` its size and modification time (bounded time per
file); only regular files are read (a FIFO or device put in a file's place does not block).
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import stat
import threading
from pathlib import Path
from typing import Iterator

__all__ = ["ReadLog", "recording", "note", "made_here", "fingerprint", "MAX_DIGEST_BYTES", "MAX_LOGGED_FILES"]

MAX_DIGEST_BYTES = 256 * 2**20     # larger files are fingerprinted by size and modification time
MAX_LOGGED_FILES = 10_000          # distinct files one load may note (a scenario reads a few dozen)

_local = threading.local()


class ReadLog:
    """The distinct regular files one load read (absolute, resolved), in the order first read."""

    def __init__(self) -> None:
        self.files: dict[str, None] = {}
        self.skipped_folders: list[str] = []
        self.overflow = False           # more than MAX_LOGGED_FILES files: the rest were not noted

    def add(self, path: str | os.PathLike) -> None:
        try:
            full = str(Path(path).resolve())
        except (OSError, RuntimeError, ValueError):
            return
        if full in self.files:
            return
        if any(full == d or full.startswith(d + os.sep) for d in self.skipped_folders):
            return
        if len(self.files) >= MAX_LOGGED_FILES:
            self.overflow = True
            return
        self.files[full] = None


def _stack() -> list[ReadLog]:
    stack = getattr(_local, "stack", None)
    if stack is None:
        stack = _local.stack = []
    return stack


@contextlib.contextmanager
def recording() -> Iterator[ReadLog]:
    """Note every file read through the bounded reader in this thread until the block ends
    (nested recordings each see the reads made while they are active)."""
    log = ReadLog()
    stack = _stack()
    stack.append(log)
    try:
        yield log
    finally:
        stack.remove(log)


def note(path: str | os.PathLike) -> None:
    """Record that ``path`` was read (a no-op when nothing is recording)."""
    for log in _stack():
        log.add(path)


def made_here(folder: str | os.PathLike) -> None:
    """Files under ``folder`` are rotorcosim's own (made while loading): not the user's inputs."""
    try:
        full = str(Path(folder).resolve())
    except (OSError, RuntimeError, ValueError):
        return
    for log in _stack():
        log.skipped_folders.append(full)
        for f in [f for f in log.files if f == full or f.startswith(full + os.sep)]:
            del log.files[f]


def fingerprint(path: str | os.PathLike, cache: dict | None = None) -> str:
    """SHA-256 of regular file ``path`` (hex, as sweeps recorded it before), or ``"size:N mtime_ns:T"`` when it is
    larger than :data:`MAX_DIGEST_BYTES`; cached by path, size and modification time.

    Raises OSError (also for a file that is no longer a regular file: a FIFO in its place is not
    opened for reading, so it cannot block)."""
    st = os.stat(path)
    if not stat.S_ISREG(st.st_mode):
        raise OSError(f"{path} is not a regular file")
    key = (str(Path(path).resolve()), st.st_size, st.st_mtime_ns)
    if cache is not None and key in cache:
        return cache[key]
    if st.st_size > MAX_DIGEST_BYTES:
        value = f"size:{st.st_size} mtime_ns:{st.st_mtime_ns}"
    else:
        h = hashlib.sha256()
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        with os.fdopen(fd, "rb") as fh:
            if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
                raise OSError(f"{path} is not a regular file")
            left = MAX_DIGEST_BYTES + 1
            while left > 0 and (block := fh.read(min(1 << 20, left))):
                h.update(block)
                left -= len(block)
        value = h.hexdigest()
    if cache is not None:
        cache[key] = value
    return value
