"""Build the native (C) test FMUs ``LinearBearing``, ``AllTypes`` and ``MisbehavingBearing`` with gcc.

``build_c_fmu(dest_dir, name) -> Path`` compiles ``<name>/*.c`` (e.g. ``LinearBearing/linear_bearing.c``)
against the FMI 2.0 headers shipped with fmpy (``fmpy/c-code``) into
``binaries/linux64/LinearBearing.so`` (``gcc -shared -fPIC -O2``) and zips it with
``modelDescription.xml`` (and the C source under ``sources/``) into
``dest_dir/LinearBearing.fmu``. Nothing is committed in binary form: tests build
the FMU into a temporary folder. Linux x86_64 only (the platform rotorcosim runs on).

Run as a script to build into a folder: ``python tests/fmus_c/build_c_fmu.py OUT_DIR [NAME]``.

``MisbehavingBearing`` is LinearBearing's source compiled with ``-DMISBEHAVING`` and its own
``MisbehavingBearing/modelDescription.xml``: a LinearBearing that aborts, segfaults,
``_exit``s, hangs, outputs NaN or returns fmi2Error at a chosen step (parameters
``fault``, ``fault_step``), for the crash tests of FMUs in worker processes; or floods its
log, logs a hostile message, returns fmi2Pending or status 42, gives no FMU state, or floods its log under
another instance name (faults 9-14, tests/test_hostile_probe3.py); or logs with printf arguments, from a
thread of its own, or after it freed its instance (faults 16-18, tests/test_hostile_probe5.py and
tests/test_safe_logger.py). Compiled with ``-pthread``.

``build_c_fmu(dest, "AllTypes", fixed_step=True)`` builds ``AllTypesFixed.fmu``: the same
model compiled with ``-DFIXED_STEP`` (it refuses a step size other than its first one) and
declaring ``canHandleVariableCommunicationStepSize="false"``.
"""

from __future__ import annotations

import platform
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
MODEL = "LinearBearing"
MODELS = ("LinearBearing", "AllTypes", "MisbehavingBearing")
# MisbehavingBearing: LinearBearing's C source compiled with -DMISBEHAVING, its own modelDescription.xml
SOURCES = {"MisbehavingBearing": "LinearBearing"}
SRC_DIR = HERE / MODEL


def fmi2_headers() -> Path:
    """Folder holding fmi2Functions.h (fmpy ships the FMI 2.0 standard headers)."""
    import fmpy

    inc = Path(fmpy.__file__).resolve().parent / "c-code"
    if not (inc / "fmi2Functions.h").is_file():
        raise FileNotFoundError(f"FMI 2.0 headers not found in {inc}; fmpy installation incomplete?")
    return inc


def gcc() -> str | None:
    """Path of gcc, or None."""
    return shutil.which("gcc")


def build_c_fmu(dest_dir: str | Path, name: str = MODEL, *, fixed_step: bool = False) -> Path:
    """Compile and zip the C FMU ``name`` into ``dest_dir``; return the .fmu path."""
    if name not in MODELS:
        raise ValueError(f"unknown C FMU {name!r}; known: {list(MODELS)}")
    if fixed_step and name != "AllTypes":
        raise ValueError("fixed_step=True is implemented by AllTypes only")
    src_dir = HERE / name
    xml = (src_dir / "modelDescription.xml").read_text()
    if fixed_step:
        xml = xml.replace('canHandleVariableCommunicationStepSize="true"',
                          'canHandleVariableCommunicationStepSize="false"')
    cc = gcc()
    if cc is None:
        raise RuntimeError("gcc not found on PATH; install gcc to build the native test FMU")
    if sys.platform != "linux" or platform.machine() not in ("x86_64", "AMD64"):
        raise RuntimeError(f"build_c_fmu builds linux64 binaries only (this is {sys.platform}/{platform.machine()})")
    dest_dir = Path(dest_dir)
    dest_dir.mkdir(parents=True, exist_ok=True)
    sources = sorted((HERE / SOURCES.get(name, name)).glob("*.c"))
    flags = ["-Wno-unused-parameter"] if name == "AllTypes" else []
    flags += ["-DMISBEHAVING", "-pthread"] if name == "MisbehavingBearing" else []
    flags += ["-DFIXED_STEP"] if fixed_step else []
    with tempfile.TemporaryDirectory(prefix=f"{name}-build-") as tmp:
        so = Path(tmp) / f"{name}.so"
        cmd = [cc, "-shared", "-fPIC", "-O2", "-std=c99", "-Wall", "-Wextra", "-Werror",
               "-fvisibility=default", *flags, "-I", str(fmi2_headers()), "-o", str(so), *map(str, sources), "-lm"]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"gcc failed ({proc.returncode}):\n{' '.join(cmd)}\n{proc.stderr}")
        fmu = dest_dir / f"{name}{'Fixed' if fixed_step else ''}.fmu"
        tmp_fmu = fmu.with_suffix(".fmu.part")
        with zipfile.ZipFile(tmp_fmu, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.writestr("modelDescription.xml", xml)
            zf.write(so, f"binaries/linux64/{name}.so")
            for src in sources:
                zf.write(src, f"sources/{src.name}")
        tmp_fmu.replace(fmu)
    return fmu


if __name__ == "__main__":
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(".")
    print(build_c_fmu(out, sys.argv[2] if len(sys.argv) > 2 else MODEL))
