"""The files that ``stability --json OUT`` and ``--plot PNG`` may replace: an existing OUT is checked
before the computation (minutes with ``--film mc``), so that the scenario or another file is not
written over."""

from __future__ import annotations

from pathlib import Path

from orchestrator.errors import CosimError


def _check_json_target(out: str, scenario_file: str) -> None:
    """``stability --json OUT`` replaces OUT only when it is an earlier JSON report (or empty, or a
    link, which is replaced, not written through): ``--json s.yaml`` replaced the scenario itself
    with the report. A folder, FIFO or device is refused when the report is written."""
    import os
    import stat

    from orchestrator.untrusted import InputError, load_json
    try:
        st = os.lstat(out)
    except OSError:                       # a new name: the write names a missing folder
        return
    if not stat.S_ISREG(st.st_mode) or st.st_size == 0:
        return
    why = None
    if os.path.samefile(out, scenario_file):
        why = "it is the scenario file"
    else:
        try:
            old = load_json(out, what="file")
        except InputError:
            old, why = None, "it does not read as JSON, e.g. a scenario or a results file"
        if why is None and not (isinstance(old, dict) and {"film", "speed_range_hz", "status"} <= set(old)):
            why = "it is JSON of something else, e.g. a run's summary.json"
    if why:
        raise CosimError(f"{out}: exists and is not a stability report ({why}); --json replaces only an earlier "
                         f"report of `stability --json` (or an empty file): give a new name, e.g. "
                         f"{Path(out).with_suffix('.json') if Path(out).suffix != '.json' else 'stability.json'}"
                         ", or remove the file first")


# the first bytes of a figure file matplotlib writes, by suffix (others are not checked)
_FIGURE_MAGIC = {"png": (b"\x89PNG\r\n\x1a\n",), "pdf": (b"%PDF",), "svg": (b"<?xml", b"<svg"),
                 "eps": (b"%!PS",), "ps": (b"%!PS",), "jpg": (b"\xff\xd8\xff",), "jpeg": (b"\xff\xd8\xff",),
                 "tif": (b"II*\x00", b"MM\x00*"), "tiff": (b"II*\x00", b"MM\x00*"), "webp": (b"RIFF",)}


def _check_plot_target(out: str, scenario_file: str) -> None:
    """``stability --plot OUT`` replaces OUT only when it is an earlier figure of its suffix's format (or
    empty, or a link, which is replaced): ``--plot s.yaml.png`` is fine, ``--plot s.yaml`` is refused by
    its missing suffix, and ``--plot notes.png`` naming a text file is refused here, before the computation."""
    import os
    import stat
    try:
        st = os.lstat(out)
    except OSError:
        return
    if not stat.S_ISREG(st.st_mode) or st.st_size == 0:
        return
    why = None
    if os.path.samefile(out, scenario_file):
        why = "it is the scenario file"
    else:
        suffix = Path(out).suffix.lower().lstrip(".")
        magic = _FIGURE_MAGIC.get(suffix)
        if magic:
            with open(out, "rb") as fh:
                head = fh.read(16)
            if not head.startswith(magic):
                why = f"its content is not a .{suffix} figure"
    if why:
        raise CosimError(f"{out}: exists and is not a figure ({why}); --plot replaces only an earlier figure "
                         "(or an empty file): give a new name, e.g. stability.png, or remove the file first")
