"""Third-party FMUs fetched at test time (never committed): the crane-fmu wheel from PyPI."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

CRANE_FMU = "crane-fmu==0.2.0"       # two PythonFMU FMUs by another author (PythonFMU 0.6.9 and 0.7.0)


def crane_fmus(d: Path) -> dict[str, Path]:
    """The FMUs of the crane-fmu wheel, written into ``d``: ``{stem: path}``; skips the test when
    the wheel cannot be fetched (offline)."""
    proc = subprocess.run([sys.executable, "-m", "pip", "download", "--no-deps", "-q", "-d", str(d), CRANE_FMU],
                          capture_output=True, text=True, timeout=300)
    wheels = list(d.glob("crane_fmu-*.whl"))
    if proc.returncode != 0 or not wheels:
        pytest.skip(f"cannot fetch the crane-fmu wheel from PyPI (offline?): {proc.stderr.strip()[-300:]}")
    out = {}
    with zipfile.ZipFile(wheels[0]) as zf:
        for name in zf.namelist():
            if name.startswith("examples/") and name.endswith(".fmu"):
                target = d / Path(name).name
                target.write_bytes(zf.read(name))
                out[target.stem] = target
    return out
