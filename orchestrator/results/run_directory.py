"""The one reader of a run folder: results.csv (or results.parquet), summary.json and the field files.

:class:`RunDirectory` reads what a run wrote (``rotorcosim run``, the monolithic
reference, a compare variant); analysis, plots and compare read runs through it only.
"""

from __future__ import annotations

import csv
import io
import logging
import os
from pathlib import Path
from typing import Any

import numpy as np

RESULTS = "results.csv"
RESULTS_PARQUET = "results.parquet"     # output.format: parquet (same columns)
SUMMARY = "summary.json"

log = logging.getLogger(__name__)


MAX_LINE_BYTES = 2**20     # one line of results.csv (the header or one row); 1 MiB is ~40 000 columns
_CHUNK_BYTES = 4 * 2**20   # read and parsed by numpy at once (a chunk with a bad row is read again row by row)


def read_results(path: str | Path) -> dict[str, np.ndarray]:
    """Read ``results.csv`` into ``{column: array}`` (the header names the columns).

    A run folder may come from anyone: the file must be regular (no FIFO, device or
    directory behind the name), every line at most :data:`MAX_LINE_BYTES` bytes and
    strict UTF-8, the header must name ``time`` and no column twice, every row must
    have one value per column, a column is numbers (``nan``/``inf`` included) or text
    in every row (a String signal, read as NaN), and time must be finite and never run
    backwards. Tolerates a truncated last line without its newline (runs stream the
    file; it is dropped with a log message) and trailing empty lines. Raises
    ``ValueError`` whose message names the file and line, what was expected, what
    came and the fix.
    """
    from orchestrator.untrusted import InputError, open_regular

    path = Path(path)
    try:                    # a run folder may come from anyone: no FIFO or device behind the name
        fh = open_regular(path, what="results file")
    except InputError as exc:
        raise ValueError(str(exc)) from None
    with fh:
        return _ResultsReader(fh, path).read()


class _ResultsReader:
    """One pass over an open results.csv (see :func:`read_results`): chunks of whole lines,
    parsed by numpy a chunk at once; a chunk with a bad row is read again row by row to name it.

    A chunk that is plain ASCII without carriage returns or an overlong line (the usual case:
    checked on its bytes, :meth:`clean`) goes to numpy as bytes, without becoming a list of
    lines, and is taken when numpy finds one row of n numbers per line; any other chunk is
    decoded and split into lines first (:meth:`lines`), which names the line of a problem."""

    def __init__(self, fh, path: Path):
        self.fh, self.path = fh, path
        self.lineno = 0            # lines handed out so far
        self._rest = b""
        self._eof = False

    def fail(self, line: int, what: str) -> ValueError:
        return ValueError(f"{self.path}:{line}: {what}")

    def blank_line(self, line: int) -> ValueError:
        return self.fail(line, "empty line between rows; every line after the header is one row: the file is "
                         "damaged or edited, rerun the scenario (or delete the line)")

    def too_long(self, line: int) -> ValueError:
        return self.fail(line, f"the line is longer than {MAX_LINE_BYTES} bytes (the limit); a line of results.csv "
                         "is one row of numbers: this is not a results file of a run (or raise "
                         "orchestrator.results.run_directory.MAX_LINE_BYTES if you trust it)")

    def too_many_rows(self, most: int) -> ValueError:
        """A file longer than any run writes (a tampered one of 10^9 rows filled the memory)."""
        from orchestrator.scenario import limits
        return self.fail(most + 2, f"more than {most} rows; a run writes one row per output interval, at most "
                         f"{limits.MAX_OUTPUT_ROWS:.0e} + 2 (orchestrator.scenario.limits.MAX_OUTPUT_ROWS): this is "
                         "not the results file of a run (or raise that limit if you trust it)")

    def next_chunk(self) -> tuple[int, bytes, bool, int] | None:
        """``(number of the first line, the lines as bytes without the last line break, last
        line complete, number of lines)`` for the next chunk of whole lines; None at the end.
        The line after the chunk (still being read) is no longer than MAX_LINE_BYTES."""
        while not self._eof:
            chunk = self.fh.read(_CHUNK_BYTES)
            self._eof = not chunk
            cut = chunk.rfind(b"\n")
            if cut < 0:                              # (the last line of the file, or a long one)
                self._rest += chunk
                if len(self._rest) > MAX_LINE_BYTES:
                    raise self.too_long(self.lineno + 1)
                if self._eof and self._rest:         # the last line, without its line break
                    return self.take(self._rest, complete=False)
                continue
            body = b"".join((self._rest, memoryview(chunk)[:cut])) if self._rest else chunk[:cut]
            self._rest = chunk[cut + 1:]
            count = body.count(b"\n") + 1
            if len(self._rest) > MAX_LINE_BYTES:
                raise self.too_long(self.lineno + count + 1)
            return self.take(body, complete=True, count=count)
        return None

    def take(self, data: bytes, complete: bool, count: int | None = None) -> tuple[int, bytes, bool, int]:
        first = self.lineno + 1
        count = data.count(b"\n") + 1 if count is None else count
        self.lineno += count
        return first, data, complete, count

    def lines(self, first: int, data: bytes) -> list[str]:
        """The lines of ``data`` (line ``first`` onwards) as text without line breaks: strict
        UTF-8, none longer than MAX_LINE_BYTES."""
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError as exc:
            line = first + data.count(b"\n", 0, exc.start)
            col = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
            raise ValueError(f"{self.path}:{line}:{col}: results.csv is not UTF-8 text (byte "
                             f"0x{data[exc.start]:02x}: {exc.reason}); a run writes it as UTF-8: the file is "
                             "damaged or not a results file, rerun the scenario") from None
        if first == 1 and text.startswith("\ufeff"):
            text = text[1:]
        if "\r" in text:
            text = text.replace("\r\n", "\n")
        out = text.split("\n")
        if max(map(len, out)) > MAX_LINE_BYTES // 4:        # a character is 1 to 4 bytes: count the long ones
            for k, line in enumerate(out):
                if len(line.encode("utf-8")) > MAX_LINE_BYTES:
                    raise self.too_long(first + k)
        return out

    @staticmethod
    def clean(data: bytes) -> bool:
        """May numpy parse the bytes of ``data`` as they are: ASCII (so UTF-8), no carriage
        return, no line longer than MAX_LINE_BYTES? Else the lines are decoded and checked one
        by one (:meth:`lines`). An empty line is not looked for here: numpy skips it, and the
        rows then fall short of the lines (:meth:`parse_clean`)."""
        if not data or not data.isascii() or b"\r" in data:
            return False
        start, size = 0, len(data)
        while size - start > MAX_LINE_BYTES:    # start is a line's first byte: its line ends within the limit
            end = data.rfind(b"\n", start, start + MAX_LINE_BYTES + 1)
            if end < 0:
                return False
            start = end + 1
        return True

    def header(self) -> tuple[list[str], tuple[int, bytes, bool] | None]:
        """The column names and the rest of the first chunk."""
        got = self.next_chunk()
        if got is not None:
            _, data, complete, count = got
            head, sep, rest = data.partition(b"\n")
            # a chunk that is not clean is checked as text as a whole first (bad UTF-8 or an
            # overlong line after the header is named before the header's problems)
            line = self.lines(1, head if self.clean(rest) else data)[0]
        if got is None or not line.strip():
            raise ValueError(f"{self.path}: empty file, expected a header 'time,<instance>.<variable>,...'")
        try:
            names = [h.strip() for h in next(csv.reader([line], strict=True))]
        except csv.Error as exc:
            raise self.fail(1, f"the header is not valid CSV ({exc}); expected 'time,<instance>.<variable>,...'") \
                from None
        if "time" not in names:
            shown = ", ".join(repr(n[:40]) for n in names[:4]) + (", ..." if len(names) > 4 else "")
            raise self.fail(1, f"the header has no 'time' column (got {shown}); a run writes "
                            "'time,<instance>.<variable>,...': give the results.csv of a run (or add the time "
                            "column)")
        seen: dict[str, int] = {}
        for j, name in enumerate(names):
            if name in seen:
                raise self.fail(1, f"column '{name[:80]}' appears twice in the header (columns {seen[name] + 1} "
                                f"and {j + 1}); each column is one signal: remove or rename one")
            seen[name] = j
        return names, ((2, rest, complete, count - 1) if sep else None)

    def read(self) -> dict[str, np.ndarray]:
        names, got = self.header()
        n = len(names)
        self.numeric_seen = np.zeros(n, bool)          # a column with a number somewhere
        self.text_seen: dict[int, tuple[int, str]] = {}  # column -> (line, value) of its first text value
        blocks: list[np.ndarray] = []
        blank = 0                                       # an empty line not yet followed by a row
        from orchestrator.scenario import limits
        most = limits.MAX_OUTPUT_ROWS + 2               # a run's rows: one per output interval, t0 and stop
        while True:
            if got is None:
                got = self.next_chunk()
                if got is None:
                    break
            first, data, complete, count = got
            if first - 2 >= most:                       # (before parsing it: the file is read in chunks)
                raise self.too_many_rows(most)
            got = None
            if not blank and not self.text_seen:
                arr = self.parse_clean(data, count, n)
                if arr is not None:
                    blocks.append(arr)
                    continue
            lines = self.lines(first, data)
            empty = [i for i, line in enumerate(lines) if not line] if "" in lines else []
            if empty:
                rows = [i for i, line in enumerate(lines) if line]
                if rows and (blank or empty[0] < rows[-1]):
                    raise self.blank_line(blank or first + empty[0])
                blank = blank or first + empty[0]
                lines = [lines[i] for i in rows]
            elif blank and lines:
                raise self.blank_line(blank)
            if lines:
                blocks.append(self.parse(first, lines, complete, names))
        for j, (line, value) in sorted(self.text_seen.items(), key=lambda kv: kv[1][0]):
            if self.numeric_seen[j] or names[j] == "time":
                raise self.fail(line, f"column '{names[j]}' has {value[:40]!r}, expected a number"
                                f"{' as in its other rows' if self.numeric_seen[j] else ''}; the file is damaged "
                                "or edited: rerun the scenario (or fix that line)")
        data = np.concatenate(blocks) if blocks else np.empty((0, n))
        if len(data) > most:
            raise self.too_many_rows(most)
        self.check_time(data[:, names.index("time")])
        return {h: data[:, j] for j, h in enumerate(names)}

    def parse_clean(self, data: bytes, rows: int, n: int) -> np.ndarray | None:
        """The ``rows`` lines of a chunk that :meth:`clean` passes, parsed by numpy from its bytes,
        when each is n numbers; else None (then :meth:`parse` reads its lines)."""
        if not self.clean(data):
            return None
        try:
            arr = np.loadtxt(io.BytesIO(data), delimiter=",", ndmin=2, dtype=float, comments=None,
                             encoding="ascii")
        except ValueError:
            return None
        if arr.shape != (rows, n):
            return None
        self.numeric_seen[:] = True
        return arr

    def parse(self, first: int, lines: list[str], complete: bool, names: list[str]) -> np.ndarray:
        """The rows of ``lines`` (the first is line ``first``; no empty lines) as floats: numpy at
        once, else row by row with the line of a problem. ``complete``: the last line had its
        line break (a truncated last line of a streamed file is dropped)."""
        n = len(names)
        if not self.text_seen:
            try:
                arr = np.loadtxt(lines, delimiter=",", ndmin=2, dtype=float, comments=None)
                if arr.shape == (len(lines), n):
                    self.numeric_seen[:] = True
                    return arr
            except ValueError:
                pass
        rows = []
        last = len(lines) - 1
        for k, text in enumerate(lines):
            line, truncated = first + k, k == last and not complete
            try:
                fields = next(csv.reader([text], strict=True))
            except csv.Error as exc:
                if truncated:
                    log.info("%s:%d: dropped the truncated last line (%s)", self.path, line, exc)
                    continue
                raise self.fail(line, f"the row is not valid CSV ({exc}); the file is damaged or edited: rerun "
                                "the scenario (or fix that line)") from None
            if len(fields) != n:
                if truncated:
                    log.info("%s:%d: dropped the truncated last line (%d of %d values)", self.path, line,
                             len(fields), n)
                    continue
                raise self.fail(line, f"{len(fields)} values, but the header names {n} columns; every row has one "
                                "value per column: the file is damaged or edited, rerun the scenario (or fix that "
                                "line)")
            row = np.empty(n)
            bad = []
            for j, f in enumerate(fields):
                try:
                    row[j] = float(f)
                except ValueError:
                    row[j] = np.nan
                    bad.append((j, f))
            if bad and truncated:
                log.info("%s:%d: dropped the truncated last line (%r is no number)", self.path, line, bad[0][1])
                continue
            for j, f in bad:
                self.text_seen.setdefault(j, (line, f))
            mask = np.ones(n, bool)
            mask[[j for j, _ in bad]] = False
            self.numeric_seen |= mask
            rows.append(row)
        return np.array(rows).reshape(-1, n)

    def check_time(self, t: np.ndarray) -> None:
        """Rows are lines 2, 3, ... (empty lines only at the end, a truncated one only last)."""
        bad = time_problem(t, lambda i: f"line {i + 2}")
        if bad is not None:
            raise self.fail(bad[0] + 2, bad[1])


def time_problem(t: np.ndarray, where) -> tuple[int, str] | None:
    """``(row, what is wrong)`` of the first row whose time is not finite or runs backwards
    (``where(row)`` names a row in the text), else None."""
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        return int(bad[0]), (f"time is {float(t[bad[0]])!r}, expected a finite number ({bad.size} row(s) without "
                             "a valid time); the file is damaged or edited: rerun the scenario")
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        i = int(back[0])
        return i + 1, (f"time runs backwards ({float(t[i + 1])!r} after {float(t[i])!r} on {where(i)}; "
                       f"{back.size} place(s)); rows must be in time order: the file is damaged or edited, "
                       "rerun the scenario")
    return None


def read_results_parquet(path: str | Path) -> dict[str, np.ndarray]:
    """Read ``results.parquet`` (``output.format: parquet``) into ``{column: array}`` as
    :func:`read_results` reads the CSV: numbers as float64 (Integer and Boolean as their
    values), String columns as object arrays. Raises ``ValueError`` naming the file when it
    is no Parquet file, lacks a ``time`` column, or pyarrow is not installed."""
    from orchestrator.untrusted import InputError, open_regular

    path = Path(path)
    try:                    # a regular file of bounded size, as every file of a run folder
        open_regular(path, what="results file").close()
    except InputError as exc:
        raise ValueError(str(exc)) from None
    try:
        import pyarrow.parquet as pq
    except ImportError:
        raise ValueError(f"{path}: reading Parquet results needs pyarrow (pip install pyarrow)") from None
    from orchestrator.scenario import limits
    most = limits.MAX_OUTPUT_ROWS + 2                    # a run's rows: one per output interval, t0 and stop
    try:
        rows = pq.ParquetFile(path).metadata.num_rows   # from the footer, before any row is read
        table = pq.read_table(path) if rows <= most else None
    except Exception as exc:                 # pyarrow raises its own ArrowInvalid / OSError
        why = f"{type(exc).__name__}: {exc}"
        if "magic bytes not found in footer" in str(exc):
            # what a run killed hard (SIGKILL, a crash, the machine going down) leaves: a Parquet file
            # is readable only once it is closed, so none of its rows can be read
            raise ValueError(f"{path}: not a readable Parquet file: it has no footer, which a run writes when it "
                             "closes the file, so the run was killed (or its disk filled) before it ended and "
                             "none of its rows can be read; run it again, with output.format: csv if it may be "
                             "killed again (a CSV file keeps every row written before the run was killed) "
                             f"({why})") from None
        raise ValueError(f"{path}: not a readable Parquet file ({why})") from None
    if table is None:       # a tampered file of 10^9 rows would fill the memory, as a results.csv did
        raise ValueError(f"{path}: {rows} rows, more than {most}; a run writes one row per output interval, at most "
                         f"{limits.MAX_OUTPUT_ROWS:.0e} + 2 (orchestrator.scenario.limits.MAX_OUTPUT_ROWS): this is "
                         "not the results file of a run (or raise that limit if you trust it)")
    if "time" not in table.column_names:
        raise ValueError(f"{path}: no 'time' column (columns: {', '.join(table.column_names[:8])})")
    import pyarrow as pa
    out = {}
    for name in table.column_names:
        col = table.column(name)
        if pa.types.is_integer(col.type) or pa.types.is_floating(col.type) or pa.types.is_boolean(col.type):
            # whole columns at once (no Python list per row); nulls become NaN
            out[name] = np.asarray(col.cast(pa.float64()).to_numpy(zero_copy_only=False), dtype=float)
        elif not (pa.types.is_string(col.type) or pa.types.is_large_string(col.type)):
            raise ValueError(f"{path}: column {name!r} holds {col.type}, expected numbers or text (a String "
                             "signal); give the results.parquet of a run")
        else:
            out[name] = np.asarray(col.to_pylist(), dtype=object)
    if out["time"].dtype == object:
        raise ValueError(f"{path}: the 'time' column holds {table.column('time').type}, expected numbers; give the "
                         "results.parquet of a run")
    bad = time_problem(out["time"], lambda i: f"row {i + 1}")
    if bad is not None:
        raise ValueError(f"{path}: row {bad[0] + 1}: {bad[1]}")
    return out


class RunDirectory:
    """A run folder. ``columns()``: results.csv (or results.parquet) as ``{column: array}``
    (``time`` first); ``summary()``: summary.json as a dict; ``field_files()``: the film
    field files."""

    def __init__(self, path: str | Path):
        self.path = Path(path)

    @property
    def results_csv(self) -> Path:
        return self.path / RESULTS

    @property
    def results_file(self) -> Path:
        """results.csv, or results.parquet when only that was written (``output.format:
        parquet``); results.csv when neither exists (for messages)."""
        csv_path, pq_path = self.path / RESULTS, self.path / RESULTS_PARQUET
        return pq_path if os.path.lexists(pq_path) and not os.path.lexists(csv_path) else csv_path

    @property
    def summary_json(self) -> Path:
        return self.path / SUMMARY

    def has_results(self) -> bool:
        """Something is there under the results name (a FIFO, device, directory or dangling link
        too: :meth:`columns` then says what it is instead of "not found")."""
        return os.path.lexists(self.results_file)

    def has_summary(self) -> bool:
        return self.summary_json.is_file()

    def columns(self) -> dict[str, np.ndarray]:
        """results.csv or results.parquet (raises ValueError naming the file, line and fix)."""
        path = self.results_file
        return read_results_parquet(path) if path.suffix == ".parquet" else read_results(path)

    def summary(self) -> dict[str, Any]:
        """summary.json, read with the bounded reader (raises
        :class:`orchestrator.untrusted.InputError`, or ValueError when it is no JSON object)."""
        from orchestrator.untrusted import load_json
        doc = load_json(self.summary_json, what="summary.json")
        if not isinstance(doc, dict):
            raise ValueError(f"{self.summary_json}: expected a JSON object, got {type(doc).__name__}")
        return doc

    def field_files(self) -> list[Path]:
        """The film field files a bearing FMU wrote into the folder (``<instance>_fields.npz``)."""
        return sorted(self.path.glob("*_fields.npz"))

    def field_file(self, instance: str) -> Path:
        return self.path / f"{instance}_fields.npz"
