"""The sweep table: one row per run, ``DIR/sweep.csv`` (and ``DIR/sweep.parquet`` with pyarrow).

Columns, in order: ``run_id``, each parameter by its name, each collected value by its
``collect`` name, ``status`` (``finished`` / ``failed`` / ``crashed`` / ``cancelled``),
``message``, ``wall_time_s``, ``run_dir`` (relative to DIR). A collected path that a
finished run's summary.json lacks gives an empty cell and one warning per column; so does a
value that is null there (the run computed none, e.g. no onset), with its own warning.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
import warnings
from pathlib import Path
from typing import Any

from orchestrator.results.safe_write import write_report_file
from orchestrator.sweep.plan import RunPlan
from orchestrator.sweep.spec import SweepSpec

__all__ = ["lookup", "build_rows", "write_table", "read_table", "columns", "META_FILE"]

META_FILE = "sweep.json"
_MISSING = object()
_INDEX_RE = re.compile(r"-?[0-9]{1,18}")      # a list index in a collected path


def lookup(summary: Any, path: str):
    """The value at dotted ``path`` in a parsed summary.json (integer parts index lists), or
    ``_MISSING``. A key that itself contains dots (a column ``crane.boom.end[0]`` of
    ``output.final``) is matched too: every run of parts joined by dots that is a key is tried,
    the single part first."""
    return _lookup_parts(summary, path.split("."))


def _lookup_parts(node: Any, parts: list[str]):
    if not parts:
        return node
    if isinstance(node, dict):
        for j in range(1, len(parts) + 1):
            key = ".".join(parts[:j])
            if key in node:
                found = _lookup_parts(node[key], parts[j:])
                if found is not _MISSING:
                    return found
        return _MISSING
    part = parts[0]
    # ASCII digits only, and few: str.isdigit() also takes '²' (int() refuses it) and 5000 digits exceed
    # int()'s limit; either ended the sweep, after every run, in an internal error without sweep.csv
    if isinstance(node, list) and _INDEX_RE.fullmatch(part) and -len(node) <= int(part) < len(node):
        return _lookup_parts(node[int(part)], parts[1:])
    return _MISSING


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
            hint = ""
            first = next((r for r in runs if (records.get(r.run_id) or {}).get("summary")), None)
            final = lookup(records[first.run_id]["summary"], "output.final") if first is not None else _MISSING
            if isinstance(final, dict) and path in final:      # a recorded column named as it is
                hint = f"; the last value of the recorded signal '{path}' is 'output.final.{path}'"
            warnings.warn(f"collect '{name}': {n} finished run(s) have no '{path}' in their summary.json; their "
                          f"cells are empty (check the path against one run's summary.json{hint})", stacklevel=2)
    for (name, path), n in zip(spec.collect, null.values(), strict=True):
        if n:
            warnings.warn(f"collect '{name}': {n} finished run(s) have '{path}' = null in their summary.json (the "
                          f"run computed no value there, e.g. no whirl onset within its speed range); their cells "
                          f"are empty", stacklevel=2)
    return rows


def write_table(rows: list[dict], spec: SweepSpec, out_dir: Path, units: tuple[dict, dict] = ({}, {}),
                value_names: dict[str, dict[int, str]] | None = None) -> Path:
    """Write ``sweep.csv`` (always), ``sweep.parquet`` (when pyarrow is installed) and
    ``sweep.json`` (the parameter and collect names, which ``rotorcosim plot`` reads, and the
    ``units`` and ``value_names`` found for them, :func:`orchestrator.sweep.units.sweep_labels`,
    for the map's labels: ``"value_names": {"0": "half-Sommerfeld", "1": "mass-conserving"}`` in
    the entry of a parameter that sets a switch whose FMU names its values)."""
    cols = columns(spec)
    path = out_dir / "sweep.csv"
    fh = io.StringIO(newline="")
    w = csv.DictWriter(fh, fieldnames=cols)
    w.writeheader()
    for row in rows:
        w.writerow({k: ("" if row.get(k) is None else row.get(k)) for k in cols})
    write_report_file(path, fh.getvalue())
    names = value_names or {}
    meta = {"sweep": 1, "source": str(spec.source), "scenario": str(spec.scenario), "mode": spec.mode,
            "parameters": [{"name": p.name, "set": list(p.paths),
                            **({"unit": units[0][p.name]} if p.name in units[0] else {}),
                            **({"value_names": {str(v): n for v, n in sorted(names[p.name].items())}}
                               if names.get(p.name) else {})}
                           for p in spec.parameters],
            "collect": dict(spec.collect), "collect_units": dict(units[1])}
    write_report_file(out_dir / META_FILE, json.dumps(meta, indent=1))
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


# sweep.csv as `rotorcosim plot` reads it: one row per run (at most plan.MAX_RUNS rows), each row
# a few hundred bytes (a failed run's message is cut to 600 characters by the task).
MAX_TABLE_BYTES = 64 * 2**20
STATUSES = ("finished", "failed", "crashed", "cancelled")
_FIX = "rerun the sweep (or fix the file)"


def _meta_problem(meta) -> str | None:
    """Why a parsed sweep.json cannot describe the map (None: it can)."""
    from orchestrator.sweep.spec import _NAME_RE

    def got(v) -> str:
        kind = {str: "a text", int: "an integer", float: "a number", bool: "a boolean", list: "a list",
                dict: "an object", type(None): "null"}.get(type(v), type(v).__name__)
        return f"{v!r:.60}, {kind}" if isinstance(v, (str, int, float, bool)) else kind

    if not isinstance(meta, dict):
        return f"expected a JSON object with 'parameters' and 'collect' (got {got(meta)})"
    params = meta.get("parameters")
    if not isinstance(params, list) or not params:
        return f"'parameters' must be a non-empty list of {{\"name\": ...}} objects (got {got(params)})"
    for i, entry in enumerate(params):
        name = entry.get("name") if isinstance(entry, dict) else None
        if not isinstance(name, str) or not _NAME_RE.match(name):
            return (f"'parameters[{i}]' must be an object whose 'name' is a sweep.csv column name (letters, "
                    f"digits, '_') (got {got(name if isinstance(entry, dict) else entry)})")
    collect = meta.get("collect", {})
    if not isinstance(collect, dict):
        return f"'collect' must be an object {{column: summary.json path}} (got {got(collect)})"
    for name, path in collect.items():
        if not _NAME_RE.match(name) or not isinstance(path, str):
            return (f"'collect' must map column names (letters, digits, '_') to summary.json paths (got "
                    f"{name!r:.60}: {got(path)})")
    names = [e["name"] for e in params] + list(collect)
    dup = next((n for n in names if names.count(n) > 1), None)
    if dup is not None:
        return f"the column '{dup}' is named twice in 'parameters' and 'collect'"
    return None


def _number(text: str):
    """A cell as a float (True/False as 1/0), or None when it is no number."""
    if text in ("True", "False"):
        return float(text == "True")
    try:
        return float(text)
    except ValueError:
        return None


def read_table(out_dir: str | Path):
    """(rows as dicts with numbers parsed, meta dict) of a sweep folder, for the map.

    Both files are untrusted (a sweep folder may come from anyone): ``sweep.json`` through
    ``untrusted.load_json`` and checked (parameters and collect columns named as the sweep file
    names them), ``sweep.csv`` a regular UTF-8 file of at most :data:`MAX_TABLE_BYTES` and
    ``orchestrator.sweep.plan.MAX_RUNS`` rows, every row as many fields as the header, the
    columns sweep.json names present, collected values and ``wall_time_s`` numbers (or empty),
    parameter values present and no two rows with the same ones. Raises
    :class:`orchestrator.untrusted.InputError` naming the file and line, what was expected,
    what came and the fix. Warns (``file:line``) for an unknown status (drawn as not
    finished), a non-finite collected value (drawn as no value) and a parameter column that
    mixes numbers and texts (the texts drawn after the numbers).
    """
    from orchestrator.sweep import plan
    from orchestrator.untrusted import InputError, decode_utf8, load_json, read_bytes

    out_dir = Path(out_dir)
    meta_path, path = out_dir / META_FILE, out_dir / "sweep.csv"
    if not meta_path.exists():
        raise InputError(f"{meta_path}: not found; `rotorcosim sweep` writes it next to sweep.csv (the "
                         "parameters and collected columns the map needs): rerun the sweep (--resume reruns "
                         "only what did not finish)")
    meta = load_json(meta_path, what="sweep.json", fix=_FIX)
    problem = _meta_problem(meta)
    if problem is not None:
        raise InputError(f"{meta_path}: {problem}; {_FIX}")
    params = [e["name"] for e in meta["parameters"]]
    collect = list(meta.get("collect", {}))
    text = decode_utf8(read_bytes(path, what="sweep table", limit=MAX_TABLE_BYTES,
                                  limit_name="orchestrator.sweep.table.MAX_TABLE_BYTES"), str(path), "sweep table")
    reader = csv.reader(io.StringIO(text, newline=""))
    rows: list[dict] = []
    seen: dict[tuple, int] = {}
    mixed: dict[str, int] = {}
    odd_status: list[tuple[int, str]] = []
    nonfinite: dict[str, tuple[int, int]] = {}
    texts: dict[str, tuple[int, str, int]] = {}     # collected column -> (first line, its text, count)
    try:
        header = next(reader, None)
        if not header:
            raise InputError(f"{path}:1: empty; expected the header run_id,{','.join(params + collect)},status,... "
                             f"and one row per run; {_FIX}")
        dup = next((h for h in header if header.count(h) > 1), None)
        if dup is not None:
            raise InputError(f"{path}:1: the column '{dup:.60}' appears twice in the header; {_FIX}")
        for name in ["status"] + params + collect:
            if name not in header:
                role = ("a parameter" if name in params else "a collected value" if name in collect
                        else "the runs' status")
                raise InputError(f"{path}:1: no column '{name}' ({role} in {META_FILE}); sweep.csv and "
                                 f"{META_FILE} are not from the same sweep: {_FIX}")
        for fields in reader:
            line = reader.line_num
            if not fields:
                continue
            if len(rows) >= plan.MAX_RUNS:
                raise InputError(f"{path}:{line}: more than {plan.MAX_RUNS} rows, more than a sweep has runs (the "
                                 f"limit, orchestrator.sweep.plan.MAX_RUNS); a sweep writes one row per run: check "
                                 "the file, or read it with pandas for other views")
            if len(fields) != len(header):
                raise InputError(f"{path}:{line}: {len(fields)} fields, but the header names {len(header)} "
                                 f"columns; {_FIX}")
            row = dict(zip(header, fields))
            raw = dict(row)
            for name in params:
                v = row[name]
                if v == "":
                    raise InputError(f"{path}:{line}: parameter '{name}' has no value; every run has one: {_FIX}")
                x = _number(v)
                row[name] = x if x is not None and math.isfinite(x) and v not in ("True", "False") else v
                if isinstance(row[name], str):
                    mixed.setdefault(name, line)
            for name in collect + ["wall_time_s"]:
                v = row.get(name, "")
                if v == "":
                    row[name] = None
                    continue
                x = _number(v)
                if x is None and name != "wall_time_s":
                    # a sweep writes the collected value as it finds it in summary.json: a text, or a
                    # list/object as JSON (`collect: {onset: analysis.journals.b1.onset}`); such a
                    # table was refused whole, so a sweep made a folder that `plot` would not draw
                    first, value, n = texts.get(name, (line, v, 0))
                    texts[name] = (first, value, n + 1)
                    row[name] = None
                    continue
                if x is None:
                    raise InputError(f"{path}:{line}: column '{name}' must be a number (the run's wall time, or "
                                     f"empty for none) (got {v!r:.60}); {_FIX}")
                if not math.isfinite(x):
                    first, n = nonfinite.get(name, (line, 0))
                    nonfinite[name] = (first, n + 1)
                    x = None
                row[name] = x
            if row["status"] not in STATUSES:
                odd_status.append((line, row["status"]))
            key = tuple((type(row[n]).__name__, row[n]) for n in params)
            if key in seen:
                values = ", ".join(f"{n}={raw[n]:.40}" for n in params)
                raise InputError(f"{path}:{line}: a second row for the run {values} (first on line {seen[key]}); "
                                 "a sweep has one row per run: remove the repeated row, or rerun the sweep")
            seen[key] = line
            rows.append(row)
    except csv.Error as exc:
        raise InputError(f"{path}:{reader.line_num}: not a readable CSV row ({exc}); {_FIX}") from None
    for name, line in mixed.items():
        kinds = {type(r[name]) for r in rows}
        if len(kinds) > 1:
            first = next(r[name] for r in rows if isinstance(r[name], str))
            warnings.warn(f"{path}:{line}: parameter '{name}' is {first!r:.60}, a text, where other rows have "
                          f"numbers; the map draws the texts after the numbers (rerun the sweep or fix the "
                          f"row if it is a typo)", stacklevel=2)
    for name, (line, value, n) in texts.items():
        warnings.warn(f"{path}:{line}: column '{name}' holds {n} value(s) that are not numbers (first: "
                      f"{value!r:.60}), which a map cannot show; drawn as no value (collect a number from "
                      "summary.json to map it, e.g. a field of that object)", stacklevel=2)
    for name, (line, n) in nonfinite.items():
        warnings.warn(f"{path}:{line}: column '{name}' holds {n} non-finite value(s) (nan or inf), which a "
                      "sweep never writes; drawn as no value", stacklevel=2)
    if odd_status:
        line, st = odd_status[0]
        warnings.warn(f"{path}:{line}: status {st!r:.60} is none of {', '.join(STATUSES)} ({len(odd_status)} "
                      "row(s)); drawn as runs that did not finish", stacklevel=2)
    return rows, meta
