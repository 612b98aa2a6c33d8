"""Where FMUs are extracted: one folder per run, one extraction per FMU file.

A run extracts each FMU *file* once into its run folder and every instance of
that FMU loads from the same extraction (FMI 2.0 lets one loaded library hold
several instances unless the FMU declares ``canBeInstantiatedOnlyOncePerProcess``,
which the scenario loader already restricts to one instance). All extractions
of a run together stay within :data:`MAX_RUN_EXTRACT_BYTES`, on top of the
per-archive limits of :mod:`orchestrator.fmi.archive`.

Run folders are ``$TMPDIR/rotorcosim-*`` with an owner record (process id,
its start time, host). A run removes its folder when it ends; a crashed or
killed run cannot, so :func:`make_run_dir` first removes the folders whose
owner process is gone (:func:`clean_stale`).
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import socket
import tempfile
import time
from pathlib import Path

from orchestrator.errors import FmuError
from orchestrator.fmi.bundled_python import forget_imports_under

log = logging.getLogger(__name__)

MAX_RUN_EXTRACT_BYTES = 4 * 2**30       # every FMU extracted by one run, together
PREFIX = "rotorcosim-"
OWNER_FILE = ".rotorcosim-owner.json"
LEGACY_MAX_AGE_S = 24 * 3600            # folders of older versions (no owner record)


def _process_start(pid: int) -> str | None:
    """Start time of process ``pid`` in clock ticks since boot (Linux), else None."""
    try:
        raw = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return raw.rsplit(")", 1)[-1].split()[19]          # field 22 of proc(5)


def _alive(pid: int, start: str | None) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:                             # exists, owned by someone else
        return True
    except OSError:
        return True
    now = _process_start(pid)
    return start is None or now is None or now == start


def make_run_dir(base: str | os.PathLike | None = None) -> Path:
    """A new, empty run folder ``rotorcosim-*`` (in ``base``, default the temp folder),
    with this process recorded as its owner; stale folders of dead runs are removed first."""
    base = Path(base or tempfile.gettempdir())
    try:
        clean_stale(base)
    except OSError as exc:                              # never fail a run over housekeeping
        log.debug("cleaning stale run folders in %s failed: %s", base, exc)
    path = Path(tempfile.mkdtemp(prefix=PREFIX, dir=base))
    record = {"pid": os.getpid(), "start": _process_start(os.getpid()), "host": socket.gethostname()}
    (path / OWNER_FILE).write_text(json.dumps(record))
    return path


def clean_stale(base: str | os.PathLike | None = None, *, now: float | None = None) -> list[Path]:
    """Remove run folders in ``base`` whose owner process (on this host) is gone, and
    folders without an owner record older than :data:`LEGACY_MAX_AGE_S`; return them."""
    base = Path(base or tempfile.gettempdir())
    now = time.time() if now is None else now
    host = socket.gethostname()
    removed = []
    for d in base.glob(PREFIX + "*"):
        try:
            if d.is_symlink() or not d.is_dir() or d.stat().st_uid != os.getuid():
                continue
            owner = d / OWNER_FILE
            if owner.is_file():
                rec = json.loads(owner.read_text()[:4096])
                if rec.get("host") != host or _alive(int(rec["pid"]), rec.get("start")):
                    continue
            elif now - d.stat().st_mtime < LEGACY_MAX_AGE_S:
                continue
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            continue
        shutil.rmtree(d, ignore_errors=True)
        removed.append(d)
        log.info("removed the stale run folder %s (its run is gone)", d)
    return removed


def extract_error(fmu_path: Path, dest: Path, exc: OSError) -> FmuError:
    """The error of an extraction the disk refused: the FMU, the folder (in the temporary
    directory, not the output folder) and what to do. It was a bare "error: No space left on
    device" (or "File too large" under a file size limit, ``ulimit -f``) naming neither."""
    import errno
    where = Path(exc.filename) if exc.filename else dest
    tmp = "the temporary folder (TMPDIR, now " + tempfile.gettempdir() + ")"
    fix = {errno.ENOSPC: f"free some space in {tmp}, or set TMPDIR to a folder on a disk with room",
           errno.EDQUOT: f"free some of your disk quota in {tmp}, or set TMPDIR to another disk",
           errno.EFBIG: "one of its files is larger than the file size limit of this process (`ulimit -f`): "
                        "raise that limit (ulimit -f unlimited)",
           errno.EROFS: f"{tmp} is read-only: set TMPDIR to a writable folder",
           errno.EACCES: "set TMPDIR to a folder you can write to"}.get(
        exc.errno, f"check {tmp}: it must be writable and have room for the FMU's files")
    return FmuError(f"{fmu_path}: cannot extract the FMU into {where} ({exc.strerror or exc}); {fix}")


class ExtractionPool:
    """The extractions of one run: ``extract(fmu)`` once per file, shared by instances.

    Files are identified by resolved path, device, inode, size and modification
    time. ``close()`` removes the run folder (when the pool made it).
    """

    def __init__(self, root: str | os.PathLike | None = None, *, budget: int | None = None):
        self._own = root is None
        self.root = make_run_dir() if root is None else Path(root)
        self.budget = MAX_RUN_EXTRACT_BYTES if budget is None else budget
        self.used = 0
        self._done: dict[tuple, Path] = {}
        self.extractions = 0

    def extract(self, fmu_path: str | os.PathLike) -> Path:
        """The folder holding ``fmu_path`` extracted (extracting it on first use)."""
        from orchestrator.fmi import archive as fmu_archive

        fmu_path = Path(fmu_path)
        try:
            st = fmu_path.stat()
        except OSError as exc:
            raise FmuError(f"{fmu_path}: cannot read the FMU ({exc.strerror or exc}); check the path") from None
        key = (str(fmu_path.resolve()), st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)
        if key in self._done:
            return self._done[key]
        dest = self.root / f"fmu{len(self._done)}-{fmu_path.stem[:40]}"
        left = self.budget - self.used
        try:
            fmu_archive.safe_extract(fmu_path, dest, budget=left)
        except OSError as exc:
            shutil.rmtree(dest, ignore_errors=True)
            raise extract_error(fmu_path, dest, exc) from None
        self.used += sum(f.stat().st_size for f in dest.rglob("*") if f.is_file() and not f.is_symlink())
        self.extractions += 1
        self._done[key] = dest
        return dest

    def close(self) -> None:
        if self._own:
            forget_imports_under(self.root)             # modules the FMUs imported from there
            shutil.rmtree(self.root, ignore_errors=True)
        self._done.clear()
