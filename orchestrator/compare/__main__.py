"""``python -m orchestrator.compare JOB``: the worker process of one comparison run."""

import logging
import os
import sys

from orchestrator.compare.runner import worker_main

if __name__ == "__main__":   # worker of run_comparison (one run per process)
    try:
        rc = worker_main(sys.argv[1])
    except KeyboardInterrupt as exc:   # stopped by the comparison (Ctrl-C, SIGTERM): the run's
        rc = getattr(exc, "exit_code", 130)   # summary says so; no traceback on the terminal
    # Leave without the interpreter's teardown: the run is complete and its files (results,
    # summary, compare_job.json) are closed; the teardown only frees the FMUs' Python
    # objects, and PythonFMU-built FMUs abort there intermittently ("corrupted
    # double-linked list", signal 6: 4 of 7 runs of compare/ci_jeffcott_mc.yaml), which
    # would turn a finished run into a "worker process died". A crash DURING a run still
    # fails that run (no compare_job.json).
    sys.stdout.flush()
    sys.stderr.flush()
    logging.shutdown()
    os._exit(rc)
