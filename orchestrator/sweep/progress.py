"""The progress of a sweep's runs on stderr: a tqdm bar on a terminal, a line per run done
when stderr is a file or a pipe (docs/sweeps.md section 2, "Progress")."""

from __future__ import annotations

import sys
import time

__all__ = ["progress_bar"]


class _Lines:
    """Progress as one stderr line per run done, for a sweep whose stderr is not a terminal (a
    batch job, ``nohup ... 2> log``): tqdm is off there, and a sweep of hours said nothing until
    its end. The same calls as the tqdm bar (update, set_postfix_str, close)."""

    def __init__(self, total: int):
        self.total, self.done, self.postfix, self.t0 = total, 0, "", time.monotonic()

    def update(self, n: int = 1) -> None:
        self.done += n
        spent = time.monotonic() - self.t0
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
    """A tqdm bar on a terminal; with ``enabled`` None and stderr not a terminal, a line per run."""
    if enabled is None and not sys.stderr.isatty():
        return _Lines(total)
    from tqdm import tqdm
    return tqdm(total=total, unit="run", desc="sweep", disable=not enabled if enabled is not None else None,
                dynamic_ncols=True)
