"""Command line interface: ``rotorcosim <verb> ...`` (also ``python -m orchestrator``).

Each verb is registered by its own small ``_add_<verb>`` function (the shape of
PythonFMU's ``create_command_parser``). The CLI parses arguments, calls the
library and formats what comes back; it contains no numerics.

Exit codes: 0 success; 1 a failed run, an invalid scenario or any other error
(one readable message on stderr, no traceback unless ``--debug``); 2 bad
command-line usage (argparse); 130 interrupted; 141 stdout's reader went away (``| head``). ``compare`` returns the exit
code of :func:`orchestrator.compare.main_compare`.

Layout: this module is the entry point (:func:`main`, :func:`console_main`); :mod:`.parser` builds the
parser from the verbs' ``_add_<verb>`` / ``_cmd_<verb>`` pairs in :mod:`.run` (run, validate, compare),
:mod:`.sweep`, :mod:`.stability` (with the checks of its output files in :mod:`.targets`), :mod:`.fmus`
(info, build-fmus) and :mod:`.files` (plot, scenarios, init, export-ssp); what they share is in
:mod:`.common`, the messages of failures in :mod:`.messages`. The quick start is ``run quickstart``,
no verb of its own.
"""

from __future__ import annotations

import logging
import sys
import warnings
from typing import Sequence

from orchestrator.cli.messages import _clean_warnings, _describe
from orchestrator.cli.parser import build_parser


#: exit status when the reader of stdout went away (``rotorcosim scenarios | head -1``): 128 + SIGPIPE,
#: what a shell reports for a command that a closed pipe stopped
EXIT_STDOUT_CLOSED = 141


def _stdout_closed() -> bool:
    """True when stdout is a pipe or socket whose reader has gone (poll reports an error or a
    hang-up on it; a failed write need not leave anything to flush, so flushing again tells
    nothing); then stdout is pointed at os.devnull, so that the interpreter's final flush does
    not fail again (Python's signal module documentation, "Note on SIGPIPE"). False when that
    cannot be told (no poll, no file descriptor): the error is then reported as any other."""
    import os
    import select
    try:
        fd = sys.stdout.fileno()
        poller = select.poll()
        poller.register(fd, select.POLLOUT)
        events = poller.poll(0)
    except (AttributeError, OSError, ValueError):
        return False
    if not any(ev & (select.POLLERR | select.POLLHUP) for _, ev in events):
        return False
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, fd)
        os.close(devnull)
    except OSError:
        pass
    return True


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI with ``argv`` (default: ``sys.argv[1:]``); return the exit code."""
    args = build_parser().parse_args(argv)
    args.debug = bool(args.debug or getattr(args, "debug_verb", False))
    previous = _clean_warnings(args.debug)
    logging.basicConfig(level=logging.DEBUG if args.debug else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    if not args.debug:
        logging.getLogger("orchestrator.fmi.build").setLevel(logging.INFO)   # say when FMUs are being built
    try:
        return int(args.func(args) or 0)
    except BrokenPipeError:
        if not _stdout_closed():                  # another pipe (a worker's): a failure like any other
            if args.debug:
                raise
            print(_describe(sys.exc_info()[1]), file=sys.stderr)
            return 1
        return EXIT_STDOUT_CLOSED                 # `| head`: nobody reads the rest; no message, no flush error
    except KeyboardInterrupt as exc:           # Ctrl-C (130) or SIGTERM (143): RunStopped.exit_code
        code = getattr(exc, "exit_code", 130)
        print("interrupted" if code == 130 else f"terminated by signal {exc}", file=sys.stderr)
        return code
    except Exception as exc:                      # every failure becomes one message (traceback: --debug)
        if args.debug:
            raise
        print(_describe(exc), file=sys.stderr)
        return 1
    finally:
        warnings.formatwarning = previous


def console_main() -> None:
    """Entry point of the ``rotorcosim`` command and ``python -m orchestrator``: :func:`main`, then exit.

    When this process loaded an FMU's shared library in-process (any ``isolation: none`` FMU,
    which is the default), it leaves through ``os._exit`` after running the ``atexit``
    handlers (multiprocessing's, which stop worker processes; the temporary folders') and
    flushing the output and the logs, instead of the interpreter's teardown. Why: the
    teardown frees the Python objects of PythonFMU-built FMUs (ours are), and PythonFMU
    0.7.0 aborts there intermittently with glibc's "corrupted double-linked list"
    (SIGABRT, exit 134) although the run has finished and every file is closed: seen in
    compare worker processes (4 of 7 runs of compare/ci_jeffcott_mc.yaml, which leave the
    same way, orchestrator/compare/__main__.py) and once in CI's ``rotorcosim validate`` of a
    shipped scenario (1 in about 170 processes). A crash during a run still shows as one.
    """
    exit_process(main())


def exit_process(code: int) -> None:
    """Leave the process with ``code``: ``sys.exit`` when no FMU library was loaded in-process,
    else ``os._exit`` after the ``atexit`` handlers and flushing the output and the logs (why:
    :func:`console_main`). The test suite leaves the same way (tests/exit_plugin.py)."""
    subsystem = sys.modules.get("orchestrator.fmi.subsystem")
    if subsystem is None or not subsystem.native_fmu_loaded:
        sys.exit(code)
    import atexit
    import os
    try:
        atexit._run_exitfuncs()
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:   # a closed pipe: nothing more can be said
                pass
        logging.shutdown()
        os._exit(code)
