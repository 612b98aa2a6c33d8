"""The life cycle of a run folder: one run at a time, no stale files, a summary on every exit path.

Call order (``orchestrator.run`` does this)::

    with RunFolder(out_dir, scenario) as folder:   # lock; earlier run's files -> previous/; summary "running"
        ... build FMUs, set up the master ...        # an exception here: summary "failed", "setup failed: ..."
        with folder.stop_signals(master):          # SIGINT / SIGTERM stop after the current macro step
            result = master.run()
        folder.finish(summary)                     # the final summary.json (started_at/finished_at added)
    # leaving the block unlocks the folder; an exception before finish() writes a failed summary

Rules:

* **Lock**: ``out_dir/.rotorcosim.lock`` is held with ``flock`` for the whole run (the
  kernel drops it when the process dies, however it dies). A second run into the folder is
  refused with a :class:`~orchestrator.errors.LifecycleError` that names the first
  (scenario, pid, start time). The lock file stays; it holds the current holder. The holder
  writes its details right after it takes the lock and clears them before it lets go, so the
  refused run waits up to :data:`HOLDER_WAIT_S` for them (and takes the lock if it is freed
  meanwhile); a holder that never writes them is named as "another process".
* **Earlier runs**: ``results.csv`` and ``summary.json`` left by an earlier run are moved
  into ``out_dir/previous/`` (replacing what was there) before anything is written, with its
  figures (``plots/``), film fields (``*_fields.npz``) and, for a run that died, its FMI call
  record (``.rotorcosim.calls``, which ``plot DIR/previous`` reads), so a
  run that fails early never sits beside another run's results, and a run killed hard
  leaves a summary that says ``running``, never another run's ``finished``.
* **summary.json** is written at the start (``status: running``, the scenario, its file,
  ``started_at`` in UTC, the pid) and rewritten at the end; written atomically (temporary
  file + rename) and never through a symbolic link
  (:func:`orchestrator.results.safe_write.write_text_no_follow`).
* **results.csv** is opened with :func:`orchestrator.results.safe_write.open_no_follow`:
  never written through a link.
* **Signals**: inside :meth:`RunFolder.stop_signals` the first SIGINT (Ctrl-C) or SIGTERM
  asks the master to stop after the current macro step (``master.interrupt_requested``);
  the run then keeps its rows and the summary says "interrupted by the user at t=..." or
  "terminated by signal SIGTERM at t=...". A second signal stops at once. The exception
  that leaves :func:`orchestrator.run` is :class:`RunStopped` (a KeyboardInterrupt) with
  ``exit_code`` 130 (SIGINT) or 143 (SIGTERM).
"""

from __future__ import annotations

import contextlib
import datetime
import fcntl
import json
import logging
import os
import signal
import socket
import sys
import threading
from pathlib import Path
from typing import Any

from orchestrator.errors import CosimError, LifecycleError, OutputWriteError
from orchestrator.fmi.call_record import CallRecord, read_calls

RUN_FILES = ("results.csv", "results.parquet", "summary.json")
PLOTS = "plots"                   # rotorcosim plot's figures of the run (moved aside with it)
FIELDS_GLOB = "*_fields.npz"      # film fields a bearing wrote into the run folder (moved aside with it)
LOCK_NAME = ".rotorcosim.lock"
HOLDER_WAIT_S = 0.5               # a refused run waits this long for the lock holder's details
PREVIOUS = "previous"
log = logging.getLogger(__name__)
CALLS_NAME = ".rotorcosim.calls"   # which FMI call each FMU in the run's process is in (fmi/call_record.py)


def open_calls(out_dir: Path | str) -> list[tuple[str, str, float]]:
    """The FMI calls that a run in ``out_dir`` was in and that never returned
    (:mod:`orchestrator.fmi.call_record`): meaningful when the run's process is gone without a
    final summary (:func:`folder_in_use` False). Empty when there is no record."""
    return read_calls(Path(out_dir) / CALLS_NAME)


def folder_in_use(out_dir: Path | str) -> bool | None:
    """Is a run writing into ``out_dir`` now? True while a process holds the folder's lock,
    False when the lock file is there and free (a run that wrote summary "running" and is gone
    was killed or crashed), None without a lock file. Reads nothing; never blocks."""
    path = Path(out_dir) / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        return None
    try:
        import stat as _stat
        if not _stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        except OSError:
            return None
        fcntl.flock(fd, fcntl.LOCK_UN)
        return False
    finally:
        os.close(fd)


class RunStopped(KeyboardInterrupt):
    """The run was stopped by a signal; ``exit_code`` is 128 + the signal number."""

    def __init__(self, signum: int = signal.SIGINT):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum
        self.exit_code = 128 + int(signum)


def _remove(path: Path) -> None:
    """Remove ``path`` (a file, a link - never what it points to - or a folder), if it is there."""
    import shutil
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()


def _raise_stopped(signum, frame):
    raise RunStopped(signum)


class StopRequests:
    """Ctrl-C (SIGINT) and SIGTERM as a flag that a loop checks between its pieces of work, not a
    KeyboardInterrupt raised wherever the main thread happens to be (``with StopRequests() as
    stop: ... if stop.requested: ...``).

    The first signal sets :attr:`requested` and :attr:`signum` (and, with ``notice``, says on
    stderr "interrupt: stopping after NOTICE (Ctrl-C again to stop at once)"); the loop then
    stops where it can keep what it did. A second one raises :class:`RunStopped` (a
    KeyboardInterrupt, exit code 128 + the signal) at once. Outside the main thread (the Python
    API called from a thread) Python delivers no signals and nothing is installed. The previous
    handlers are back when the block is left.

    One object can see a command through its parts (``rotorcosim stability``: loading, the
    search, writing what it computed), so that no signal lands between two handlers (where
    SIGTERM killed the process without a word and Ctrl-C ended in a bare "interrupted"):

    * :attr:`at_once` True (``at_once=True``): the first signal too raises RunStopped at once,
      for the part before anything worth keeping is computed (loading, building);
    * :attr:`abandon` False: a later signal is held as well (counted, nothing raised), for the
      bookkeeping between the pieces of work, which ends at the next check of :attr:`requested`
      anyway; the loop sets it True around a piece of work that a second signal abandons
      (:meth:`abandoning`);
    * :meth:`phase`: a new part with its own notice, whose first signal is held again (the
      signals before stay in :attr:`requested`, :attr:`signum` and :attr:`received`).

    Users: the sweep (:mod:`orchestrator.sweep.runner`: Python raised KeyboardInterrupt inside
    Dask's client code, where it was printed and dropped, and SIGTERM killed the sweep outright)
    and ``rotorcosim stability`` (:mod:`orchestrator.cli.stability`, the scan of
    :mod:`orchestrator.stability.search`: a stop kept none of the speeds done). A run's master
    has its own (:meth:`RunFolder.stop_signals`).
    """

    def __init__(self, notice: str | None = None, *, at_once: bool = False):
        self.requested = False
        self.signum: int | None = None
        self.notice = notice
        self.at_once = at_once          # the first signal stops at once too (nothing to keep yet)
        self.abandon = True             # a second signal (of the phase) stops at once; False: held
        self.received = 0               # stop signals seen
        self._in_phase = 0              # of them, since the last phase()
        self._previous: dict = {}

    def __enter__(self) -> "StopRequests":
        if threading.current_thread() is threading.main_thread():
            self._previous = {s: signal.signal(s, self._handler) for s in (signal.SIGINT, signal.SIGTERM)}
        return self

    def phase(self, notice: str | None, *, at_once: bool = False) -> None:
        """Begin a new part of the work: ``notice`` is what the next first signal waits for, and
        the next signal counts as the first of this part (held, unless ``at_once``)."""
        self.notice, self.at_once, self.abandon, self._in_phase = notice, at_once, True, 0

    @contextlib.contextmanager
    def abandoning(self):
        """A piece of work that a second signal abandons (raises :class:`RunStopped` in it), while
        :attr:`abandon` is False around it."""
        before = self.abandon
        self.abandon = True
        try:
            yield
        finally:
            self.abandon = before

    def _handler(self, signum, frame):
        self.received += 1
        self._in_phase += 1
        first = not self.requested
        if first:
            self.requested = True
            self.signum = signum
        if self.at_once or (self._in_phase > 1 and self.abandon):
            raise RunStopped(signum)
        if self.notice and self._in_phase == 1:
            what = "interrupt" if signum == signal.SIGINT else signal.Signals(signum).name
            again = "Ctrl-C" if signum == signal.SIGINT else "the signal"
            print(f"\n{what}: stopping after {self.notice} ({again} again to stop at once)", file=sys.stderr,
                  flush=True)

    def __exit__(self, *exc) -> None:
        for s, h in self._previous.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)
        self._previous = {}


def _now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def _read_holder(fd: int) -> dict | None:
    """The details a lock holder wrote into the lock file (scenario, pid, start time, host), or
    None while there are none: empty (a run between taking the lock and writing them, or one
    ending: it clears them before it unlocks), half written, or not a run's."""
    try:
        holder = json.loads(os.pread(fd, 4096, 0).decode())
    except (OSError, ValueError, RecursionError):     # a crafted record nested deep
        return None
    return holder if isinstance(holder, dict) and isinstance(holder.get("pid"), int) else None


def _ended(holder: dict) -> bool:
    """Are ``holder``'s details those of a run on this machine whose process is gone? A run
    killed hard leaves its details in the lock file; the next run overwrites them right after
    taking the lock. Details from another machine (a shared folder) are taken as they are."""
    if holder.get("host", socket.gethostname()) != socket.gethostname():
        return False
    try:
        os.kill(holder["pid"], 0)
    except ProcessLookupError:
        return True
    except (OSError, OverflowError, ValueError):     # alive but another user's (EPERM), or no pid
        return False
    return False


def _wait_for_holder(fd: int) -> tuple[dict | None, bool]:
    """After the lock on ``fd`` was refused: ``(details, False)`` once the holder's details can be
    read, ``(None, True)`` when the holder let go meanwhile (then ``fd`` holds the lock), or
    ``(None, False)`` after :data:`HOLDER_WAIT_S` without them. A run writes its details
    microseconds after it takes the lock (and clears them as it ends), so a refusal that reads
    them at once may find the file empty, half written, or still naming a run that ended."""
    import time
    deadline = time.monotonic() + HOLDER_WAIT_S
    pause = 0.001
    while True:
        holder = _read_holder(fd)
        if holder is not None and not _ended(holder):
            return holder, False
        if time.monotonic() >= deadline:
            return None, False
        time.sleep(pause)
        pause = min(2 * pause, 0.05)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            continue
        return None, True


def _in_use_message(out_dir: Path, holder: dict | None) -> str:
    fix = "wait until it ends or stop it, or choose another output folder (--out)"
    if holder is not None:
        return (f"output folder {out_dir} is in use by another run: scenario '{holder.get('scenario')}' "
                f"({holder.get('scenario_file')}), pid {holder.get('pid')}, started {holder.get('started_at')} UTC; "
                f"{fix}")
    lock = out_dir / LOCK_NAME
    return (f"output folder {out_dir} is in use by another process: it holds {lock} but had not written "
            f"which run it is after {HOLDER_WAIT_S:g} s (a run writes its scenario, pid and start time there "
            "right after it takes the lock and clears them as it ends, so it is starting or ending, or it "
            f"is not a rotorcosim run; `fuser -v {lock}` names it); {fix}")


class RunFolder:
    """One run's hold on its output folder (see the module docstring for the rules)."""

    def __init__(self, out_dir: Path | str, scenario, *, write_summary=None):
        self.out_dir = Path(out_dir)
        self.scenario = scenario
        self.started_at: str | None = None
        self.finished = False
        self.write_error: OutputWriteError | None = None    # the final summary.json could not be written
        self.stop_signal: int | None = None      # the signal that asked the run to stop
        self._lock_fd: int | None = None
        self.calls = None                         # CallRecord of the FMUs in this process (after __enter__)
        self._term_handler = None
        if write_summary is None:
            from orchestrator.results.summary import write_summary
        self._write_summary = write_summary

    # -- entering ---------------------------------------------------------------
    def __enter__(self) -> "RunFolder":
        if self.out_dir.exists() and not self.out_dir.is_dir():
            from orchestrator.errors import CosimError
            raise CosimError(f"output folder {self.out_dir}: there is a file of that name, not a folder; "
                             "give --out a new folder (or a run folder of rotorcosim, whose results "
                             "are moved aside)")
        self.out_dir.mkdir(parents=True, exist_ok=True)
        if not os.path.lexists(self.out_dir / LOCK_NAME):   # every run leaves its lock file
            self._refuse_foreign()                   # before the lock: a refused folder stays as it was
        self._lock()
        try:
            self.started_at = _now()
            self._move_aside()
            self._open_calls()
            self._write(self._head("running", "the run is in progress (or was killed hard: no final summary)"))
        except BaseException:
            self._unlock()
            raise
        if threading.current_thread() is threading.main_thread():
            # until stop_signals takes over (and after it), SIGTERM stops the run at once, like a
            # first Ctrl-C outside the stepping loop; __exit__ then writes the failed summary
            self._term_handler = signal.signal(signal.SIGTERM, _raise_stopped)
        return self

    def _holder(self) -> dict:
        sc = self.scenario
        return {"scenario": getattr(sc, "name", None),
                "scenario_file": str(sc.source) if getattr(sc, "source", None) else None,
                "pid": os.getpid(), "started_at": self.started_at or _now()}

    def _lock(self) -> None:
        path = self.out_dir / LOCK_NAME
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0), 0o644)
        except OSError as e:
            raise LifecycleError(f"cannot create the lock file {path} ({e.strerror}); check the output folder "
                                 "(it must be writable, and the lock file no symbolic link)") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            try:
                holder, got_lock = _wait_for_holder(fd)
            except BaseException:
                os.close(fd)
                raise
            if not got_lock:
                os.close(fd)
                raise LifecycleError(_in_use_message(self.out_dir, holder)) from None
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, json.dumps({**self._holder(), "host": socket.gethostname()}).encode(), 0)
        except OSError as e:
            # a full disk: this was a bare "error: No space left on device", and the descriptor (and
            # so the lock) stayed open, so the next run() of the same process into this folder, once
            # there was room, was refused as "in use by another run" - by itself
            os.close(fd)
            from orchestrator.results.safe_write import space_fix
            raise OutputWriteError(f"cannot write the lock file {path} ({e.strerror or e}); "
                                   f"{space_fix(e, 'check the output folder (it must be writable)')} or give "
                                   "another output folder (--out)") from None
        self._lock_fd = fd

    def _open_calls(self) -> None:
        """This run's FMI call record (after :meth:`_move_aside` moved the earlier run's away)."""
        names = [str(getattr(f, "name", "")) for f in getattr(self.scenario, "fmus", ())]
        try:        # where each FMU in this process is, readable after a crash (plot, sweeps)
            self.calls = CallRecord(self.out_dir / CALLS_NAME, names, {"pid": os.getpid()})
        except (OSError, ValueError) as e:          # e.g. a file system without shared mappings
            self.calls = None
            log.debug("no FMI call record in %s: %s", self.out_dir, e)

    def _refuse_foreign(self) -> None:
        """Refuse a folder holding results.csv / results.parquet / summary.json that no run wrote
        (no lock file, no summary.json of a run): the first run moved such a file (someone's
        own results.csv) into previous/ without a word, the second one deleted it."""
        present = [n for n in RUN_FILES if os.path.lexists(self.out_dir / n)]
        if not present:
            return
        try:
            from orchestrator.results.run_directory import RunDirectory
            summary = RunDirectory(self.out_dir).summary() if "summary.json" in present else {}
        except (OSError, ValueError, CosimError):   # unreadable (InputError): not a run's
            summary = {}
        if "status" in summary and "scenario" in summary:
            return                                  # a run's summary (from before lock files)
        raise LifecycleError(f"output folder {self.out_dir} holds {' and '.join(present)}, which no rotorcosim "
                             f"run wrote (no {LOCK_NAME}, no summary.json of a run); a run would move "
                             f"{'it' if len(present) == 1 else 'them'} into previous/ and the next run would "
                             "delete it: give --out a new or empty folder, or move those files away")

    def _move_aside(self) -> None:
        present = [n for n in RUN_FILES if os.path.lexists(self.out_dir / n)]
        if not present:
            return
        prev = self.out_dir / PREVIOUS
        if prev.is_symlink() or (prev.exists() and not prev.is_dir()):
            raise LifecycleError(f"{prev} is not a folder; rotorcosim moves an earlier run's files there before a "
                                 "new run. Remove or rename it")
        prev.mkdir(exist_ok=True)
        # the earlier run's figures (`rotorcosim plot`) and film fields (`<instance>_fields.npz`, which
        # plot draws) go with it: left behind, they sat beside the new run's results as if they were its own
        extra = [p.name for p in sorted(self.out_dir.glob(FIELDS_GLOB))]
        extra += [PLOTS] if os.path.lexists(self.out_dir / PLOTS) else []
        # and its FMI call record, left only by a run that died (one ending in order removes it): it
        # was truncated by the new run's, so `plot DIR/previous` could not say which call the run died in
        extra += [CALLS_NAME] if os.path.lexists(self.out_dir / CALLS_NAME) else []
        for n in (*RUN_FILES, *(p.name for p in prev.glob(FIELDS_GLOB)), PLOTS, CALLS_NAME):
            _remove(prev / n)
        for n in (*present, *extra):
            os.replace(self.out_dir / n, prev / n)     # moves a link itself, never its target

    # -- summaries --------------------------------------------------------------
    def _head(self, status: str, message: str) -> dict:
        h = self._holder()
        return {"scenario": h["scenario"], "scenario_file": h["scenario_file"], "status": status, "message": message,
                "started_at": self.started_at, "pid": h["pid"]}

    def _write(self, summary: dict) -> None:
        path = self.out_dir / "summary.json"
        try:
            self._write_summary(path, summary)
        except OSError as e:
            from orchestrator.results.safe_write import space_fix
            raise OutputWriteError(f"cannot write {path} ({e.strerror or e}); {space_fix(e, 'check that disk')} or "
                                   "give another output folder (--out)") from None

    def finish(self, summary: dict) -> None:
        """Write the final summary.json (``started_at``, ``finished_at`` added).

        When it cannot be written (disk full) the run's outcome is logged as an error instead (the
        file keeps saying "running") and kept in :attr:`write_error`; leaving the ``with`` block
        without another exception then raises it."""
        full = dict(summary)
        full.setdefault("started_at", self.started_at)
        full["finished_at"] = _now()
        try:
            self._write(full)
        except OutputWriteError as e:
            said = self.write_error is not None
            self.write_error = OutputWriteError(
                f"{e}; it still says 'running'. The run's outcome ({full.get('status')}): {full.get('message')}")
            if not said:                          # once (the summary is written again after a failure)
                log.error("%s", self.write_error)
        else:
            self.write_error = None
        self.finished = True

    def fail(self, message: str, **extra: Any) -> None:
        """Write a failed summary.json (used when the run ends before it has a result)."""
        s = self._head("failed", message)
        s.update(extra)
        self.finish(s)

    def stop_message(self, t: float | None) -> str:
        at = f" at t={t:.12g} s" if t is not None else ""
        if self.stop_signal in (None, signal.SIGINT):
            return f"interrupted by the user{at}"
        return f"terminated by signal {signal.Signals(self.stop_signal).name}{at}"

    # -- leaving ----------------------------------------------------------------
    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            if exc is not None and not self.finished:
                if isinstance(exc, KeyboardInterrupt):
                    signum = getattr(exc, "signum", None)
                    if signum is not None:
                        self.stop_signal = signum
                    self.fail(self.stop_message(None) + " before the co-simulation started",
                              stopped_by=signal.Signals(self.stop_signal or signal.SIGINT).name)
                else:
                    extra = {"failure": exc.report()} if callable(getattr(exc, "report", None)) else {}
                    self.fail(f"setup failed: {exc}", error=type(exc).__name__, **extra)
            if exc is None and self.write_error is not None:
                raise self.write_error            # the run ended, but its record could not be written
        finally:
            if self._term_handler is not None:
                signal.signal(signal.SIGTERM, self._term_handler)
                self._term_handler = None
            self._unlock()

    def _unlock(self) -> None:
        if self._lock_fd is not None:
            if self.calls is not None:          # ended in order: no open call to tell about
                self.calls.remove()
            with contextlib.suppress(OSError):
                os.ftruncate(self._lock_fd, 0)
                fcntl.flock(self._lock_fd, fcntl.LOCK_UN)
            os.close(self._lock_fd)
            self._lock_fd = None

    # -- signals ------------------------------------------------------------------
    @contextlib.contextmanager
    def stop_signals(self, master):
        """SIGINT and SIGTERM stop ``master`` after its current macro step; a second one at once.

        The first signal only sets ``master.interrupt_requested`` (``master.run`` then raises
        KeyboardInterrupt before the next macro step, from master code, never inside an FMU:
        a KeyboardInterrupt inside a PythonFMU slave becomes fmi2Fatal and leaks the slave's
        objects, docs/dev/requests.md). Only in the main thread (elsewhere Python delivers no
        signals and nothing changes).
        """
        if threading.current_thread() is not threading.main_thread():
            yield
            return
        handled = [0]                    # stop signals the Python handler has seen (main thread)

        def handler(signum, frame):
            handled[0] += 1
            if master.interrupt_requested:
                raise RunStopped(signum)
            self.stop_signal = signum
            master.interrupt_requested = True
            what = "interrupt" if signum == signal.SIGINT else signal.Signals(signum).name
            again = "Ctrl-C" if signum == signal.SIGINT else "the signal"
            print(f"\n{what}: stopping after this macro step ({again} again to stop at once)",
                  file=sys.stderr, flush=True)

        previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
        watchdog = _StopWatchdog(self, master, handled)
        try:
            yield
        finally:
            watchdog.close()
            for s, h in previous.items():
                signal.signal(s, h)


class _StopWatchdog:
    """The second stop signal while the main thread is stuck inside an FMU call.

    Python runs signal handlers in the main thread between bytecodes, so while an FMU in the
    master's process hangs inside a C call (or takes minutes for one step) neither Ctrl-C nor
    SIGTERM does anything. The C-level handler still writes each signal's number to the wakeup
    fd (:func:`signal.set_wakeup_fd`); this thread reads it. When a second SIGINT/SIGTERM has
    arrived and the Python handler has not run for it within :data:`STOP_GRACE_S`, the run is
    stopped from here: the results file flushed (its rows so far kept), summary.json written
    ``failed`` with the reason and ``stopped_by``, and the process ended with 128 + the signal
    (no clean-up can run: the main thread is in the FMU)."""

    def __init__(self, folder: "RunFolder", master, handled: list):
        self.folder, self.master, self.handled = folder, master, handled
        self.done = threading.Event()
        self._r = self._w = None
        self._previous_fd = None
        try:
            self._r, self._w = os.pipe()
            os.set_blocking(self._w, False)
            self._previous_fd = signal.set_wakeup_fd(self._w, warn_on_full_buffer=False)
        except (OSError, ValueError):            # no wakeup fd here: signals work as before
            self._close_fds()
            return
        self._thread = threading.Thread(target=self._watch, name="rotorcosim-stop-watchdog", daemon=True)
        self._thread.start()

    def _watch(self) -> None:
        seen = 0
        while True:
            try:
                data = os.read(self._r, 64)
            except OSError:
                return
            if not data or self.done.is_set():
                return
            stops = [b for b in data if b in (signal.SIGINT, signal.SIGTERM)]
            seen += len(stops)
            if seen >= 2 and not self.done.wait(STOP_GRACE_S) and self.handled[0] < seen:
                self._stop_now(stops[-1] if stops else signal.SIGINT)

    def _stop_now(self, signum: int) -> None:
        name = signal.Signals(signum).name
        t = getattr(self.master, "t", None)
        at = f" at t={t:.12g} s" if isinstance(t, float) else ""
        message = (f"stopped at once by a second {name}{at}: an FMU call in the master's process had not "
                   f"returned {STOP_GRACE_S:g} s later (an FMU that hangs, or a very long step); the rows "
                   "written so far are kept. Give such an FMU 'isolation: process' and coupling.call_timeout "
                   "(docs/coupling.md)")
        with contextlib.suppress(Exception):
            print(f"\n{message}", file=sys.stderr, flush=True)
        for o in getattr(self.master, "observers", ()):
            with contextlib.suppress(Exception):
                flush = getattr(o, "flush", None)
                if callable(flush):
                    flush()
        with contextlib.suppress(Exception):
            self.folder.fail(message, stopped_by=name, end_time=t, macro_steps=getattr(self.master, "n", None))
        os._exit(128 + int(signum))

    def close(self) -> None:
        self.done.set()
        if self._w is None:
            return
        with contextlib.suppress(ValueError, OSError):
            signal.set_wakeup_fd(self._previous_fd if self._previous_fd is not None else -1)
        with contextlib.suppress(OSError):
            os.write(self._w, b"\0")             # wakes the reader, which sees done and ends
        self._thread.join(timeout=1.0)
        self._close_fds()

    def _close_fds(self) -> None:
        for fd in (self._r, self._w):
            if fd is not None:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._r = self._w = None


#: seconds the main thread has to act on a second stop signal before the watchdog stops the run
STOP_GRACE_S = 3.0
