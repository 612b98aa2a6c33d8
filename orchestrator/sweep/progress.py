"""The progress of a sweep's runs on stderr: a tqdm bar on a terminal, lines of runs done
(at most about a hundred, or one a minute) when stderr is a file or a pipe (docs/sweeps.md
section 2, "Progress")."""

from __future__ import annotations

import sys
import time

__all__ = ["progress_bar"]


MAX_LINES = 100                       # lines per sweep off a terminal, beside one a minute
LINE_EVERY_S = 60.0


class _Lines:
    """Progress as stderr lines, for a sweep whose stderr is not a terminal (a batch job,
    ``nohup ... 2> log``): tqdm is off there, and a sweep of hours said nothing until its end.
    A line per run done when there are at most :data:`MAX_LINES` runs; otherwise a line each
    ``total / MAX_LINES`` runs or :data:`LINE_EVERY_S` seconds, whichever comes first, and the
    last run's (a sweep of 10 000 runs wrote 10 000 lines). The same calls as the tqdm bar
    (update, set_postfix_str, close)."""

    def __init__(self, total: int):
        self.total, self.done, self.postfix, self.t0 = total, 0, "", time.monotonic()
        self.every = max(1, -(-total // MAX_LINES))
        self.said, self.said_at = 0, self.t0

    def update(self, n: int = 1) -> None:
        self.done += n
        now = time.monotonic()
        if (self.done < self.total and self.done - self.said < self.every
                and now - self.said_at < LINE_EVERY_S):
            return
        self.said, self.said_at = self.done, now
        spent = now - self.t0
        eta = spent / self.done * (self.total - self.done)
        print(f"sweep: {self.done}/{self.total} runs done after {_duration(spent)}"
              + (f", about {_duration(eta)} to go" if self.done < self.total else "")
              + (f" ({self.postfix})" if self.postfix else ""), file=sys.stderr, flush=True)

    def set_postfix_str(self, text: str) -> None:
        self.postfix = text

    def close(self) -> None:
        pass


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.1f} min" if seconds < 7200 else \
        f"{seconds / 3600:.1f} h"


def progress_bar(total: int, enabled: bool | None):
    """A tqdm bar on a terminal; with ``enabled`` None and stderr not a terminal, lines (:class:`_Lines`)."""
    if enabled is None and not sys.stderr.isatty():
        return _Lines(total)
    from tqdm import tqdm
    return tqdm(total=total, unit="run", desc="sweep", disable=not enabled if enabled is not None else None,
                dynamic_ncols=True)
