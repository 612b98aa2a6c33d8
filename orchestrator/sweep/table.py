"""The sweep table: one row per run, ``DIR/sweep.csv`` (and ``DIR/sweep.parquet`` with pyarrow).

Columns, in order: ``run_id``, each parameter by its name, each collected value by its
``collect`` name, ``status`` (``finished`` / ``failed`` / ``crashed`` / ``cancelled``),
``message``, ``wall_time_s``, ``run_dir`` (relative to DIR). A collected path that a
finished run's summary.json lacks gives an empty cell and one warning per column; so does a
value that is null there (the run computed none, e.g. no onset), with its own warning.
"""

from __future__ import annotations

import csv
import json
import math
import warnings
from pathlib import Path
from typing import Any

from orchestrator.sweep.plan import RunPlan
from orchestrator.sweep.spec import SweepSpec

__all__ = ["lookup", "build_rows", "write_table", "read_table", "columns", "META_FILE"]

META_FILE = "sweep.json"
_MISSING = object()


def lookup(summary: Any, path: str):
    """The value at dotted ``path`` in a parsed summary.json (integer parts index lists), or
    ``_MISSING``."""
    node = summary
    for part in path.split("."):
        if isinstance(node, dict) and part in node:
            node = node[part]
        elif isinstance(node, list) and part.lstrip("-").isdigit() and -len(node) <= int(part) < len(node):
            node = node[int(part)]
        else:
            return _MISSING
    return node


def _cell(value):
    """A table cell: numbers and text as they are, None/NaN empty, anything else as JSON."""
    if value is None or value is _MISSING or (isinstance(value, float) and not math.isfinite(value)):
        return None
    if isinstance(value, (bool, int, float, str)):
        return value
    return json.dumps(value)


def columns(spec: SweepSpec) -> list[str]:
    return (["run_id"] + [p.name for p in spec.parameters] + [name for name, _ in spec.collect]
            + ["status", "message", "wall_time_s", "run_dir"])


def build_rows(spec: SweepSpec, runs: list[RunPlan], records: dict[str, dict], out_dir: Path) -> list[dict]:
    """Rows in sweep order; runs without a record are ``cancelled``."""
    rows, missing, null = [], {name: 0 for name, _ in spec.collect}, {name: 0 for name, _ in spec.collect}
    for run in runs:
        rec = records.get(run.run_id) or {"status": "cancelled", "summary": None, "wall_time_s": None,
                                          "message": "not run: the sweep was interrupted; rerun with --resume"}
        row = {"run_id": run.run_id, **run.values}
        summary = rec.get("summary")
        for name, path in spec.collect:
            value = lookup(summary, path) if summary is not None else _MISSING
            if value is _MISSING and rec["status"] == "finished":
                missing[name] += 1
            elif value is None and rec["status"] == "finished":
                null[name] += 1
            row[name] = _cell(value)
        wall = rec.get("wall_time_s")
        row.update(status=rec["status"], message=rec.get("message") or "",
                   wall_time_s=round(wall, 3) if isinstance(wall, (int, float)) else None,
                   run_dir=f"runs/{run.run_id}")
        rows.append(row)
    for (name, path), n in zip(spec.collect, missing.values(), strict=True):
        if n:
            warnings.warn(f"collect '{name}': {n} finished run(s) have no '{path}' in their summary.json; their "
                          f"cells are empty (check the path against one run's summary.json)", stacklevel=2)
    for (name, path), n in zip(spec.collect, null.values(), strict=True):
        if n:
            warnings.warn(f"collect '{name}': {n} finished run(s) have '{path}' = null in their summary.json (the "
                          f"run computed no value there, e.g. no whirl onset within its speed range); their cells "
                          f"are empty", stacklevel=2)
    return rows


def write_table(rows: list[dict], spec: SweepSpec, out_dir: Path) -> Path:
    """Write ``sweep.csv`` (always), ``sweep.parquet`` (when pyarrow is installed) and
    ``sweep.json`` (the parameter and collect names, which ``rotorcosim plot`` reads)."""
    cols = columns(spec)
    path = out_dir / "sweep.csv"
    tmp = path.with_suffix(".csv.tmp")
    with tmp.open("w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=cols)
        w.writeheader()
        for row in rows:
            w.writerow({k: ("" if row.get(k) is None else row.get(k)) for k in cols})
    tmp.replace(path)
    meta = {"sweep": 1, "source": str(spec.source), "scenario": str(spec.scenario), "mode": spec.mode,
            "parameters": [{"name": p.name, "set": list(p.paths)} for p in spec.parameters],
            "collect": dict(spec.collect)}
    (out_dir / META_FILE).write_text(json.dumps(meta, indent=1), encoding="utf-8")
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ModuleNotFoundError:
        return path
    data = {k: [r.get(k) for r in rows] for k in cols}
    try:
        pq.write_table(pa.table(data), out_dir / "sweep.parquet")
    except (pa.ArrowInvalid, pa.ArrowTypeError):     # a column mixing numbers and text: all as text
        pq.write_table(pa.table({k: [None if v is None else str(v) for v in vs] for k, vs in data.items()}),
                       out_dir / "sweep.parquet")
    return path


def read_table(out_dir: str | Path):
    """(rows as dicts with numbers parsed, meta dict) of a sweep folder; for the plots."""
    out_dir = Path(out_dir)
    with (out_dir / "sweep.csv").open(newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    for row in rows:
        for k, v in row.items():
            if k in ("run_id", "status", "message", "run_dir"):
                continue
            try:
                row[k] = float(v) if v != "" else None
            except ValueError:
                pass
    try:
        meta = json.loads((out_dir / META_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        meta = {}
    return rows, meta
