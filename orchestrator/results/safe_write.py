"""Writing run files without following symbolic links (results.csv, summary.json).

A link planted at ``out_dir/results.csv`` must not make a run overwrite the file it points to.
"""

from __future__ import annotations

import contextlib
import errno
import os
from pathlib import Path

from orchestrator.errors import LifecycleError


def open_no_follow(path: Path | str, mode: str = "w", *, newline: str | None = "", encoding: str | None = None):
    """``open(path, mode)`` for writing, refusing a symbolic link at ``path`` (O_NOFOLLOW)."""
    path = Path(path)
    flags = os.O_WRONLY | os.O_CREAT | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0)
    flags |= os.O_APPEND if "a" in mode else os.O_TRUNC
    try:
        fd = os.open(path, flags, 0o644)
    except OSError as e:
        if e.errno == errno.ELOOP:
            raise LifecycleError(f"{path} is a symbolic link; rotorcosim does not write results through a link "
                                 f"(it would overwrite {os.path.realpath(path)}); remove the link or choose "
                                 "another output folder") from None
        raise
    return os.fdopen(fd, mode, newline=newline, encoding=encoding)


def write_text_no_follow(path: Path | str, text: str) -> None:
    """Write ``path`` atomically (temporary file + rename) without following links at either name."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    with contextlib.suppress(FileNotFoundError):
        tmp.unlink()                          # removes a planted link itself, not its target
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0), 0o644)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)                 # rename replaces a link at ``path``, never its target
    except BaseException:                     # disk full: no empty or partial .tmp file left behind
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
