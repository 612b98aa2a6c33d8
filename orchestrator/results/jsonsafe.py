"""The one JSON sanitiser of rotorcosim's result files (summary.json, report.json, baselines).

:func:`plain` turns nested mappings, sequences, numpy scalars/arrays and paths into
JSON types. Non-finite floats have no JSON form; ``nonfinite`` says what they become,
per file format (each kept as it was before the sanitisers were merged):

* ``"string"``: ``"nan"``, ``"inf"``, ``"-inf"`` (summary.json of a run);
* ``"null"``: ``null`` (the ``analysis`` block of summary.json);
* ``"null-nan"``: NaN -> ``null``, +-inf -> ``"inf"`` / ``"-inf"`` (compare report and baseline).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np

NONFINITE = ("string", "null", "null-nan")


def _nonfinite(v: float, how: str):
    if how == "string":
        return str(v)
    if how == "null" or math.isnan(v):
        return None
    return "inf" if v > 0 else "-inf"


def plain(x: Any, nonfinite: str = "string") -> Any:
    """``x`` with JSON types only (see the module docstring for ``nonfinite``)."""
    if nonfinite not in NONFINITE:
        raise ValueError(f"nonfinite must be one of {NONFINITE} (got {nonfinite!r})")
    return _plain(x, nonfinite)


def _plain(x: Any, how: str) -> Any:
    if isinstance(x, Mapping) or hasattr(x, "items"):
        return {str(k): _plain(v, how) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v, how) for v in x]
    if isinstance(x, bool) or x is None or isinstance(x, str):
        return x
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if math.isfinite(v) else _nonfinite(v, how)
    if isinstance(x, (np.integer, np.bool_)):
        return x.item()
    if isinstance(x, int):
        return x
    if isinstance(x, np.ndarray):
        return _plain(x.tolist(), how)
    if isinstance(x, Path):
        return str(x)
    return str(x)
