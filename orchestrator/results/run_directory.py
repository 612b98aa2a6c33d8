"""The one reader of a run folder: results.csv (or results.parquet), summary.json and the field files.

:class:`RunDirectory` reads what a run wrote (``rotorcosim run``, the monolithic
reference, a compare variant); analysis, plots and compare read runs through it only.
"""

from __future__ import annotations

import csv
import logging
import warnings
from pathlib import Path
from typing import Any

import numpy as np

RESULTS = "results.csv"
RESULTS_PARQUET = "results.parquet"     # output.format: parquet (same columns)
SUMMARY = "summary.json"

log = logging.getLogger(__name__)


def read_results(path: str | Path) -> dict[str, np.ndarray]:
    """Read ``results.csv`` into ``{column: array}`` (the header names the columns).

    Tolerates a truncated last line (runs stream the file): rows with the wrong
    number of fields are skipped. Raises ``ValueError`` / ``OSError`` with the
    file name on an empty or unreadable file.
    """
    from orchestrator.untrusted import InputError, open_regular

    path = Path(path)
    try:                    # a run folder may come from anyone: no FIFO or device behind the name
        open_regular(path, what="results file").close()
    except InputError as exc:
        raise ValueError(str(exc)) from None
    with path.open(newline="") as fh:
        header = next(csv.reader(fh), None)
    if not header:
        raise ValueError(f"{path}: empty file, expected a header 'time,<instance>.<variable>,...'")
    header = [h.strip() for h in header]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        except ValueError:
            data = np.genfromtxt(path, delimiter=",", skip_header=1, invalid_raise=False)
            data = np.atleast_2d(data) if data.size else np.empty((0, len(header)))
    for w in caught:   # skipped malformed rows (a truncated last line of a streamed file)
        log.info("%s: %s", path, str(w.message).strip().replace("\n", " "))
    if data.size == 0:
        data = np.empty((0, len(header)))
    if data.shape[1] != len(header):
        raise ValueError(f"{path}: {data.shape[1]} columns of data, header names {len(header)}")
    return {h: data[:, j] for j, h in enumerate(header)}


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
    try:
        table = pq.read_table(path)
    except Exception as exc:                 # pyarrow raises its own ArrowInvalid / OSError
        raise ValueError(f"{path}: not a readable Parquet file ({type(exc).__name__}: {exc})") from None
    if "time" not in table.column_names:
        raise ValueError(f"{path}: no 'time' column (columns: {', '.join(table.column_names[:8])})")
    import pyarrow as pa
    out = {}
    for name in table.column_names:
        col = table.column(name)
        if pa.types.is_integer(col.type) or pa.types.is_floating(col.type) or pa.types.is_boolean(col.type):
            # whole columns at once (no Python list per row); nulls become NaN
            out[name] = np.asarray(col.cast(pa.float64()).to_numpy(zero_copy_only=False), dtype=float)
        else:
            out[name] = np.asarray(col.to_pylist(), dtype=object)
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
        return pq_path if pq_path.is_file() and not csv_path.is_file() else csv_path

    @property
    def summary_json(self) -> Path:
        return self.path / SUMMARY

    def has_results(self) -> bool:
        return self.results_file.is_file()

    def has_summary(self) -> bool:
        return self.summary_json.is_file()

    def columns(self) -> dict[str, np.ndarray]:
        """results.csv or results.parquet (raises OSError / ValueError naming the file)."""
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
