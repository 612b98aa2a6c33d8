"""The files that ``stability --json OUT`` and ``--plot PNG`` may replace: an existing OUT is checked
before the computation (minutes with ``--film mc``), so that the scenario or another file is not
written over."""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import Callable

from orchestrator.errors import CosimError


def _why_not_replaced(out: str, scenario_file: str, not_of_its_format: Callable[[str], str | None]) -> str | None:
    """Why the existing file ``out`` may not be replaced by a report or figure, or None when it may.

    A new name, an empty file and anything that is not a regular file (a link, which is replaced,
    not written through; a folder, FIFO or device, refused when the file is written) may; the
    scenario itself never; an earlier file of the format when ``not_of_its_format(out)`` (the
    format's own check, for a regular non-empty file) returns None, else its reason."""
    try:
        st = os.lstat(out)
    except OSError:                       # a new name (its folder: _check_folder_of)
        return None
    if not stat.S_ISREG(st.st_mode) or st.st_size == 0:
        return None
    if os.path.samefile(out, scenario_file):
        return "it is the scenario file"
    return not_of_its_format(out)


def _check_folder_of(option: str, out: str) -> None:
    """The folder of ``out`` is there (``--json nosuch/r.json`` was found only when the result was
    written, after the whole search: minutes with --film mc, and a stopped search's JSON lost)."""
    from orchestrator.results.safe_write import folder_problem
    why = folder_problem(out)
    if why:
        raise CosimError(f"{option} {out}: {why}")


def _check_json_target(out: str, scenario_file: str) -> None:
    """``stability --json OUT`` replaces OUT only when it is an earlier JSON report (or empty, or a
    link, which is replaced, not written through): ``--json s.yaml`` replaced the scenario itself
    with the report. A folder, FIFO or device is refused when the report is written."""
    _check_folder_of("--json", out)
    why = _why_not_replaced(out, scenario_file, _not_a_report)
    if why:
        raise CosimError(f"{out}: exists and is not a stability report ({why}); --json replaces only an earlier "
                         f"report of `stability --json` (or an empty file): give a new name, e.g. "
                         f"{Path(out).with_suffix('.json') if Path(out).suffix != '.json' else 'stability.json'}"
                         ", or remove the file first")


def _not_a_report(out: str) -> str | None:
    """Why the file ``out`` is not an earlier report of ``stability --json`` (None: it is one)."""
    from orchestrator.untrusted import InputError, load_json
    try:
        old = load_json(out, what="file")
    except InputError:
        return "it does not read as JSON, e.g. a scenario or a results file"
    if not (isinstance(old, dict) and {"film", "speed_range_hz", "status"} <= set(old)):
        return "it is JSON of something else, e.g. a run's summary.json"
    return None


# the first bytes of a figure file matplotlib writes, by suffix (others are not checked)
_FIGURE_MAGIC = {"png": (b"\x89PNG\r\n\x1a\n",), "pdf": (b"%PDF",), "svg": (b"<?xml", b"<svg"),
                 "eps": (b"%!PS",), "ps": (b"%!PS",), "jpg": (b"\xff\xd8\xff",), "jpeg": (b"\xff\xd8\xff",),
                 "tif": (b"II*\x00", b"MM\x00*"), "tiff": (b"II*\x00", b"MM\x00*"), "webp": (b"RIFF",)}


def _check_plot_target(out: str, scenario_file: str) -> None:
    """``stability --plot OUT`` replaces OUT only when it is an earlier figure of its suffix's format (or
    empty, or a link, which is replaced): ``--plot s.yaml.png`` is fine, ``--plot s.yaml`` is refused by
    its missing suffix, and ``--plot notes.png`` naming a text file is refused here, before the computation."""
    _check_folder_of("--plot", out)
    why = _why_not_replaced(out, scenario_file, _not_a_figure)
    if why:
        raise CosimError(f"{out}: exists and is not a figure ({why}); --plot replaces only an earlier figure "
                         "(or an empty file): give a new name, e.g. stability.png, or remove the file first")


def _not_a_figure(out: str) -> str | None:
    """Why the file ``out`` is not a figure of its suffix's format (None: it is one, or the format's
    first bytes are not known)."""
    suffix = Path(out).suffix.lower().lstrip(".")
    magic = _FIGURE_MAGIC.get(suffix)
    if magic:
        with open(out, "rb") as fh:
            head = fh.read(16)
        if not head.startswith(magic):
            return f"its content is not a .{suffix} figure"
    return None
