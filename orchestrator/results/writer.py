"""Result files as other tools read them: ``results.csv`` (csv module) and optional Parquet.

:class:`ResultsWriter` streams rows to disk and keeps nothing per row in
memory, so its memory use is flat in the number of rows:

* the header is written by :mod:`csv` (RFC 4180 quoting), so a structured name
  such as ``m[1,2]`` stays one column; the first column is ``time``;
* columns are exactly the recorded signals (no empty column when there are
  none: the header is then ``time`` alone);
* the time of row ``n`` is computed from the step index, ``t0 + n*H``, and
  rounded to the decimals of ``t0`` and ``H`` as written (:class:`TimeGrid`),
  so ``0.1 * 3`` prints as ``0.3`` and joins on time with other tools work;
* Real values are written with ``repr`` (shortest round-trip form), Integer
  and Enumeration as integers, Boolean as ``0``/``1``, String as text (quoted
  by the csv module where needed) on one line: a line break in an FMU's String
  value is written as ``\\n`` / ``\\r``, and a value longer than
  :data:`MAX_STRING_CHARS` is cut (its start and ``...[N characters cut]``),
  each announced by one warning per column, so every row is one line that
  ``rotorcosim plot`` reads;
* the file is flushed at least every ``flush_interval`` seconds of wall time
  (default 1 s) and at :meth:`close`, so a run that stops early keeps its rows;
  the first :data:`FLUSH_FIRST_ROWS` rows are flushed one by one, so a run whose process
  dies at once (an FMU in it that crashes in its first steps) keeps those too (1000 write
  calls: 1.3 ms for the writer alone, up to about 10 ms inside a run; BENCHMARKS.md).

``format="parquet"`` writes ``results.parquet`` with the same columns through
pyarrow (row groups of ``parquet_rows`` rows, so memory stays bounded too);
pyarrow missing is reported with the fix.
"""

from __future__ import annotations

import csv
import logging
import time as _time
from pathlib import Path
from typing import Any, Sequence

KINDS = ("Real", "Integer", "Enumeration", "Boolean", "String")
FORMATS = ("csv", "parquet")
MAX_STRING_CHARS = 4096
"""characters of one String value written to results.csv; the rest is cut (with a warning)"""
SAID_COLUMNS = 5
"""String columns of a file whose change (a line break escaped, a long value cut) is each said in a warning"""
FLUSH_FIRST_ROWS = 1000
"""rows of results.csv written out one by one at the start of a run (then every flush_interval)"""
_STRING_ROOM = 2**20 - 4096
"""bytes a row of results.csv may take (the reader's MAX_LINE_BYTES, 1 MiB, less a margin); the String
values of a longer row are cut to fit (ResultsWriter._fit)"""
_ONE_LINE = str.maketrans({"\n": "\\n", "\r": "\\r"})

log = logging.getLogger(__name__)


class _StringCell:
    """A String value as one bounded line of results.csv (see the module docstring); warns
    once per column when it changes a value."""

    def __init__(self, column: str, said: dict | None = None):
        self.column = column
        self.warned_break = self.warned_long = False
        self.said = said if said is not None else {}      # shared by a writer's String columns

    def _say(self, kind: str, text: str, *args) -> None:
        """One warning per column, for the first SAID_COLUMNS columns of a file; then one line."""
        n = self.said.get(kind, 0)
        self.said[kind] = n + 1
        if n < SAID_COLUMNS:
            log.warning(text, *args)
        elif n == SAID_COLUMNS:
            log.warning("more String signals are changed the same way in results.csv (%s); not each said",
                        "line breaks written as \\n" if kind == "break" else "long values cut")

    def __call__(self, v) -> str:
        text = str(v)
        if "\n" in text or "\r" in text:
            text = text.translate(_ONE_LINE)
            if not self.warned_break:
                self.warned_break = True
                self._say("break", "String signal '%s' holds a line break; results.csv writes it as \\n or \\r "
                          "(one row per line); use output.format: parquet to keep the value as it is", self.column)
        if len(text) > MAX_STRING_CHARS:
            cut = len(text) - MAX_STRING_CHARS
            if not self.warned_long:
                self.warned_long = True
                self._say("long", "String signal '%s' holds %d characters; results.csv keeps the first %d of a "
                          "value (orchestrator.results.writer.MAX_STRING_CHARS) and marks the cut", self.column,
                          len(text), MAX_STRING_CHARS)
            text = f"{text[:MAX_STRING_CHARS]}...[{cut} characters cut]"
        return text


def _decimals(x: float) -> int | None:
    """Digits after the decimal point of ``repr(x)`` (``1e-05`` -> 5, ``0.25`` -> 2); None if ``x`` has
    no short decimal form (e.g. 1/3)."""
    r = repr(float(x)).lower()
    if r in ("inf", "-inf", "nan"):
        return None
    mant, _, exp = r.partition("e")
    frac = mant.partition(".")[2].rstrip("0")
    d = len(frac) - (int(exp) if exp else 0)
    d = max(d, 0)
    if len(mant.replace("-", "").replace(".", "").lstrip("0")) >= 16:
        return None                                  # repr needed all digits: not a short decimal
    return d


class TimeGrid:
    """``time(n) = t0 + n*H`` rounded to the decimals in which ``t0`` and ``H`` are written.

    ``t_stop`` (when given) is returned for ``n >= n_stop`` as it was written,
    the end of a shortened last step. Without a short decimal form (H = 1/3)
    the value is not rounded.
    """

    def __init__(self, t0: float, h: float, *, t_stop: float | None = None, n_stop: int | None = None):
        self.t0, self.h = float(t0), float(h)
        self.t_stop, self.n_stop = t_stop, n_stop
        d0, dh = _decimals(self.t0), _decimals(self.h)
        self.digits = None if d0 is None or dh is None else max(d0, dh)
        if self.digits is not None and self.digits > 15:
            self.digits = None

    def time(self, n: int) -> float:
        if self.n_stop is not None and n >= self.n_stop and self.t_stop is not None:
            return float(self.t_stop)
        t = self.t0 + n * self.h
        return round(t, self.digits) if self.digits is not None else t


def _formatter(kind: str, column: str = "", said: dict | None = None):
    if kind == "Real":
        return lambda v: repr(float(v))
    if kind in ("Integer", "Enumeration"):
        return lambda v: str(int(v))
    if kind == "Boolean":
        return lambda v: "1" if v else "0"
    if kind == "String":
        return _StringCell(column, said)
    raise ValueError(f"unknown column kind {kind!r}; expected one of {list(KINDS)}")


class ResultsWriter:
    """Stream result rows to ``path`` (``results.csv``, or ``results.parquet`` with ``format="parquet"``).

    Call order: ``w = ResultsWriter(path, columns, kinds)``; ``w.open()``;
    ``w.write(t, values)`` per row (``values`` aligned with ``columns``);
    ``w.close()`` (idempotent; also flushes). ``kinds`` gives the FMI type of
    each column (default all Real).
    """

    def __init__(self, path: Path | str, columns: Sequence[str], kinds: Sequence[str] | None = None, *,
                 format: str = "csv", flush_interval: float = 1.0, parquet_rows: int = 65536):
        if format not in FORMATS:
            raise ValueError(f"output.format must be one of {list(FORMATS)} (got {format!r})")
        self.columns = tuple(columns)
        self.kinds = tuple(kinds) if kinds is not None else ("Real",) * len(self.columns)
        if len(self.kinds) != len(self.columns):
            raise ValueError(f"{len(self.columns)} columns but {len(self.kinds)} kinds")
        if "time" in self.columns:
            raise ValueError("a recorded signal may not be called 'time' (the first column)")
        self.format = format
        self.path = Path(path)
        self.flush_interval = flush_interval
        self.rows = 0
        said: dict = {}                   # the String columns' warnings, counted per file
        self._fmt = [_formatter(k, c, said) for k, c in zip(self.kinds, self.columns)]
        self._all_real = all(k == "Real" for k in self.kinds)
        self._strings = [j + 1 for j, k in enumerate(self.kinds) if k == "String"]   # cell index (time first)
        self._warned_fit = False
        self._f = None
        self._csv = None
        self._pq = None
        self._buf: list[list[Any]] = []
        self._parquet_rows = parquet_rows
        self._last_flush = 0.0
        self._t: float | None = None      # time of the last row offered (named when writing fails)

    # -- life cycle -------------------------------------------------------------------
    def open(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self.format == "csv":
            from orchestrator.results.safe_write import open_no_follow
            self._f = open_no_follow(self.path, "w", newline="", encoding="utf-8")   # never through a link
            self._csv = csv.writer(self._f, lineterminator="\n")
            self._csv.writerow(("time", *self.columns))
            self._f.flush()
        else:
            self._pq = _ParquetSink(self.path, self.columns, self.kinds)
        self._last_flush = _time.monotonic()

    def write(self, t: float, values: Sequence[Any]) -> None:
        """Append one row at time ``t`` (already on the grid: see :class:`TimeGrid`).

        An OSError (disk full, quota, I/O error) raises :class:`orchestrator.errors.OutputWriteError`
        naming the file, ``t`` and the rows kept; a partly written last row is cut off, so the
        file stays readable (``rotorcosim plot``) and the writer is closed."""
        self._t = t
        try:
            self._write(t, values)
        except OSError as e:
            raise self._failed(e, t) from None

    def _write(self, t: float, values: Sequence[Any]) -> None:
        if self.format == "csv":
            if self._csv is None:
                raise RuntimeError(f"{self.path}: write() before open() or after close()")
            if self._all_real:
                vals = values.tolist() if hasattr(values, "tolist") else map(float, values)
                self._csv.writerow((repr(float(t)), *map(repr, vals)))
            else:
                cells = [repr(float(t)), *[f(v) for f, v in zip(self._fmt, values)]]
                if self._strings and sum(len(cells[j]) for j in self._strings) * 2 > _STRING_ROOM:
                    cells = self._fit(cells)
                self._csv.writerow(cells)
        else:
            if self._pq is None:
                raise RuntimeError(f"{self.path}: write() before open() or after close()")
            self._buf.append([float(t), *values])
            if len(self._buf) >= self._parquet_rows:
                self._pq.write(self._buf)
                self._buf = []
        self.rows += 1
        if self.rows <= FLUSH_FIRST_ROWS and self._f is not None:
            self._f.flush()
            return
        now = _time.monotonic()
        if now - self._last_flush >= self.flush_interval:
            self.flush()
            self._last_flush = now

    def _fit(self, cells: list[str]) -> list[str]:
        """Cut the String cells of a row whose line would be longer than a line of results.csv may
        be (``run_directory.MAX_LINE_BYTES``, for plot, compare and CoSimResult.load), each to an
        equal share of what the other cells leave, marking the cut; warns once."""
        def size(c: str) -> int:          # bytes in the file: UTF-8, quotes doubled, quoted, a comma
            return len(c.encode("utf-8")) + c.count('"') + 3
        strings = set(self._strings)
        budget = _STRING_ROOM - sum(size(c) for j, c in enumerate(cells) if j not in strings)
        if sum(size(cells[j]) for j in self._strings) <= budget:
            return cells
        share = max(budget // max(len(self._strings), 1) - 40, 0)      # room for the cut's note
        out = list(cells)
        for j in self._strings:
            c = out[j]
            if size(c) > share + 40:
                keep = c.encode("utf-8")[: share // 2].decode("utf-8", "ignore")  # each byte may double
                out[j] = f"{keep}...[{len(c) - len(keep)} characters cut]"
        if not self._warned_fit:
            self._warned_fit = True
            log.warning("a row of %s would be longer than a line of results.csv may be (%d bytes, "
                        "orchestrator.results.run_directory.MAX_LINE_BYTES): its %d String values are cut to "
                        "about %d bytes each, the cut marked; record fewer String signals or use output.format: "
                        "parquet to keep them whole", self.path, _STRING_ROOM, len(self._strings), share // 2)
        return out

    def flush(self) -> None:
        try:
            if self._f is not None:
                self._f.flush()
            if self._pq is not None and self._buf:
                self._pq.write(self._buf)
                self._buf = []
        except OSError as e:
            raise self._failed(e, None) from None

    def close(self) -> None:
        try:
            if self._f is not None:
                self._f.flush()
                self._f.close()
                self._f = None
                self._csv = None
            if self._pq is not None:
                if self._buf:
                    self._pq.write(self._buf)
                    self._buf = []
                self._pq.close()
                self._pq = None
        except OSError as e:
            raise self._failed(e, None) from None

    def _failed(self, e: OSError, t: float | None):
        """Close the file without its unwritten rows, cut a partly written last row off, and return
        the :class:`OutputWriteError` that says so."""
        import contextlib
        import errno

        from orchestrator.errors import OutputWriteError
        from orchestrator.results.safe_write import space_fix
        f, pq = self._f, self._pq
        self._f = self._csv = self._pq = None
        self._buf = []
        with contextlib.suppress(Exception):
            if f is not None:
                f.close()             # its buffer cannot be written either; the descriptor is closed
        with contextlib.suppress(Exception):
            if pq is not None:
                pq.close()
        t = t if t is not None else self._t            # a flush or close: the last row offered
        at = f" at t={t:.12g} s" if t is not None else ""
        why = e.strerror or str(e)
        if e.errno == errno.EFBIG:
            fix = ("the file is larger than that file system allows, or than the file size limit of this process "
                   "(`ulimit -f`): raise that limit, record fewer signals or a coarser output.interval, or give "
                   "another output folder (--out)")
        else:
            fix = f"{space_fix(e, 'check that disk')} or give another output folder (--out)"
        if self.format != "csv":
            kept = "the Parquet file is incomplete (no rows can be read from it)"
        else:
            last = _cut_partial_row(self.path)
            kept = ("no rows are kept" if last is None else f"the rows up to t={last} s are kept in it")
        return OutputWriteError(f"cannot write {self.path}{at} ({why}); the run stopped there and {kept}; {fix}")


def _cut_partial_row(path: Path) -> str | None:
    """Cut ``path`` after its last complete line (a write that failed may have left part of a row);
    return the time of the last row kept (as written), or None (header only, or unreadable)."""
    import os
    try:
        with open(path, "r+b") as f:
            size = f.seek(0, os.SEEK_END)
            start = max(0, size - (1 << 20))         # rows are far shorter than 1 MiB
            f.seek(start)
            tail = f.read()
            end = tail.rfind(b"\n")
            if end < 0:
                return None
            f.truncate(start + end + 1)
            last = tail[:end].rsplit(b"\n", 1)[-1]
    except OSError:
        return None
    first = last.split(b",", 1)[0].decode("ascii", "replace")
    try:
        float(first)
    except ValueError:
        return None                                  # the header: no rows
    return first


class _ParquetSink:
    """pyarrow ParquetWriter with one row group per :meth:`write`."""

    _ARROW = {"Real": "float64", "Integer": "int32", "Enumeration": "int32", "Boolean": "bool_", "String": "string"}

    def __init__(self, path: Path, columns, kinds):
        try:
            import pyarrow as pa
            import pyarrow.parquet as pq
        except ImportError as e:
            raise RuntimeError("output.format: parquet needs pyarrow, which is not installed; "
                               "`pip install pyarrow` or write 'output.format: csv'") from e
        self._pa = pa
        fields = [pa.field("time", pa.float64())]
        fields += [pa.field(c, getattr(pa, self._ARROW[k])()) for c, k in zip(columns, kinds)]
        self.schema = pa.schema(fields)
        self._w = pq.ParquetWriter(str(path), self.schema)

    def write(self, rows) -> None:
        pa = self._pa
        cols = list(zip(*rows))
        arrays = [pa.array([_clean(v, f.type) for v in col], type=f.type) for col, f in zip(cols, self.schema)]
        self._w.write_table(pa.Table.from_arrays(arrays, schema=self.schema))

    def close(self) -> None:
        self._w.close()


def _clean(v, arrow_type):
    if str(arrow_type) == "bool":
        return bool(v)
    if str(arrow_type) == "int32":
        return int(v)
    if str(arrow_type) == "double":
        return float(v)
    return v


def read_back(path: Path | str, columns: Sequence[str], kinds: Sequence[str]):
    """Read a file written by :class:`ResultsWriter` into ``(t, {column: array})``.

    Numeric columns come back as float64 arrays (Integer/Boolean as their
    numbers), String columns as object arrays of str.
    """
    import numpy as np

    path = Path(path)
    columns, kinds = list(columns), list(kinds)
    if path.suffix == ".parquet":
        import pyarrow.parquet as pq
        table = pq.read_table(path)
        t = np.asarray(table.column("time").to_numpy(), dtype=float)
        out = {}
        for c, k in zip(columns, kinds):
            col = table.column(c).to_pylist()
            out[c] = np.asarray(col, dtype=object if k == "String" else float)
        return t, out
    if "String" not in kinds:
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2, dtype=float)
        data = data.reshape(-1, len(columns) + 1)
        return data[:, 0].copy(), {c: data[:, i + 1].copy() for i, c in enumerate(columns)}
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.reader(f)
        next(reader, None)
        rows = list(reader)
    t = np.asarray([float(r[0]) for r in rows])
    out = {}
    for i, (c, k) in enumerate(zip(columns, kinds)):
        vals = [r[i + 1] for r in rows]
        out[c] = np.asarray(vals, dtype=object) if k == "String" else np.asarray(vals, dtype=float)
    return t, out
