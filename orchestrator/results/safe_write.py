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


def _refuse_special(path: Path, suffix: str = ".txt") -> None:
    """Refuse a device, FIFO or socket at ``path``: the atomic rename would replace it by a regular
    file (``--json /dev/null`` run as root replaced /dev/null itself); a link is replaced, by design.
    A folder is refused with a file in it as the example (``suffix`` when the folder's name has none)."""
    import stat

    from orchestrator.errors import OutputWriteError
    from orchestrator.untrusted import file_kind
    try:
        st = os.lstat(path)
    except OSError:                          # a new name, or a folder that is missing: the write says so
        return
    if stat.S_ISDIR(st.st_mode):             # was "(Is a directory); check that folder (it must be writable)"
        raise OutputWriteError(f"cannot write {path}: it is a directory; give the path of a file, e.g. "
                               f"{path / ('report' + (path.suffix or suffix))}")
    if not (stat.S_ISREG(st.st_mode) or stat.S_ISLNK(st.st_mode)):
        raise OutputWriteError(f"cannot write {path}: it is {file_kind(st.st_mode)}, and rotorcosim writes a file "
                               "by renaming a finished one over the name, which would replace it; give the path of "
                               "a regular file (to discard the output, leave the option out)")


def write_text_no_follow(path: Path | str, text: str, *, encoding: str | None = None) -> None:
    """Write ``path`` atomically (temporary file + rename) without following links at either name."""
    path = Path(path)
    _refuse_special(path)
    tmp = path.with_name(path.name + ".tmp")
    with contextlib.suppress(FileNotFoundError):
        tmp.unlink()                          # removes a planted link itself, not its target
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0), 0o644)
    try:
        with os.fdopen(fd, "w", encoding=encoding) as f:
            f.write(text)
        os.replace(tmp, path)                 # rename replaces a link at ``path``, never its target
    except BaseException:                     # disk full: no empty or partial .tmp file left behind
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def space_fix(e: OSError, otherwise: str = "check that folder (it must be writable)") -> str:
    """What to do about ``e``, an OSError of a write: free space for a full disk (ENOSPC) or an
    exhausted quota (EDQUOT), else ``otherwise``. The one text of that fix for every writer of
    output (the results writer, reports, figures, the lock file, build-fmus, export-ssp); the FMU
    extraction names TMPDIR instead (orchestrator/fmi/extraction.py)."""
    if e.errno == errno.EDQUOT:
        return "free some of your disk quota"
    return "free some space on that disk" if e.errno == errno.ENOSPC else otherwise


def write_report_file(path: Path | str, text: str) -> Path:
    """A report or table file (compare's report.md/.json, a sweep's sweep.csv/.json) written as UTF-8,
    atomically and never through a link; an OSError (disk full) becomes
    :class:`orchestrator.errors.OutputWriteError` naming ``path`` (it was "error: No space left on
    device" without a file, beside a partial sweep.csv.tmp)."""
    from orchestrator.errors import OutputWriteError
    path = Path(path)
    try:
        write_text_no_follow(path, text, encoding="utf-8")
    except OSError as e:
        raise OutputWriteError(f"cannot write {path} ({e.strerror or e}); {space_fix(e)}, then run the command "
                               "again") from None
    return path


def folder_problem(path: Path | str) -> str | None:
    """Why a new file ``path`` cannot be written because of its folder (missing, or not a folder),
    or None: for an output option checked before a long computation, not after it."""
    folder = Path(path).parent
    if not folder.exists():
        return f"its folder {folder} does not exist; create it first, or give a file in an existing folder"
    if not folder.is_dir():
        return f"{folder} is not a folder; give a file in a folder"
    return None


def figure_folder(path: Path | str) -> Path:
    """The folder figures go into (``DIR/plots``), created when missing; a symbolic link there is
    refused (:class:`~orchestrator.errors.LifecycleError`). A run or sweep folder from someone else
    with ``plots`` linked to another folder (``plots -> ~``) made ``rotorcosim plot`` write, and
    replace, its PNGs there."""
    path = Path(path)
    if path.is_symlink():
        raise LifecycleError(f"{path} is a symbolic link (to {os.path.realpath(path)}); rotorcosim writes "
                             "figures only into a folder of the run itself (through a link it would replace "
                             "files elsewhere): remove the link, then run the command again")
    path.mkdir(parents=True, exist_ok=True)
    return path


def save_figure(fig, path: Path | str, **kwargs) -> Path:
    """``fig.savefig(path, **kwargs)`` atomically: into a temporary file created exclusively beside
    ``path``, then renamed over it (never written through a link). On an OSError (disk full) the
    temporary file is removed and :class:`orchestrator.errors.OutputWriteError` names ``path``; a
    full disk used to leave an empty or truncated PNG and "error: No space left on device" without
    a file name. A KeyboardInterrupt (Ctrl-C) while drawing removes the temporary file too."""
    import tempfile

    from orchestrator.errors import OutputWriteError
    path = Path(path)
    kwargs.setdefault("format", path.suffix.lstrip(".") or "png")
    _refuse_special(path, f".{kwargs['format']}")      # a folder: e.g. DIR/report.png, not report.txt
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
        with os.fdopen(fd, "wb") as f:
            fig.savefig(f, **kwargs)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException as e:                # Ctrl-C while drawing left the .part file too
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        if not isinstance(e, OSError):
            raise
        raise OutputWriteError(f"cannot write {path} ({e.strerror or e}); {space_fix(e)}, then run the command "
                               "again") from None
    return path
