"""Build rotorcosim's own FMUs (JournalBearing, JeffcottRotor, TurbochargerRotor).

``build_fmus`` packs each PythonFMU slave module together with a clean copy of
the package it imports (``bearing_fmu`` or ``rotor_fmu``: ``*.py`` files and
data files, no caches) into ``resources/`` of the FMU, so an FMU runs wherever
numpy, scipy and numba are importable, without rotorcosim installed. The FMU's
C loader (PythonFMU 0.7.0) prepends ``resources/`` to ``sys.path``.

Staleness: a SHA-256 over the bundled sources, the slave script, the build
options, this file and the PythonFMU version is written to
``<out_dir>/<Name>.stamp`` (JSON) and into the FMU as
``resources/rotorcosim_build.json``. ``ensure_fmus`` rebuilds an FMU that a
scenario references in the repository's ``fmus/`` folder when it is missing,
has no stamp, or the hash changed.

Where a scenario's ``fmu: JournalBearing`` (one of ours, by name) lives,
:func:`fmu_location`: in a source checkout (``pyproject.toml`` and
``fmus/README.md`` beside the packages) the repository's ``fmus/`` folder; in an
installed package a per-user cache (``platformdirs.user_cache_dir("rotorcosim")``,
``fmus/<first 16 hex digits of the source hash>/<Name>.fmu``), so a changed
source gets a new folder and nothing is written into site-packages or the
working directory.

Each build runs in a fresh Python subprocess: the PythonFMU builder imports
the slave module by its bare name and instantiates the class, which would
otherwise leave a stale ``journal_bearing`` module in ``sys.modules`` of the
calling process (and the FMU loader would pick that one up).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Mapping

from orchestrator.errors import FmuError

log = logging.getLogger(__name__)

REPO = Path(__file__).resolve().parents[2]
FMU_DIR = REPO / "fmus"


def in_checkout() -> bool:
    """True when running from a source checkout (the repository's fmus/ folder and pyproject.toml exist)."""
    return (REPO / "pyproject.toml").is_file() and (FMU_DIR / "README.md").is_file()


def cache_dir() -> Path:
    """Per-user cache of our built FMUs for an installed package (``ROTORCOSIM_CACHE`` overrides it)."""
    env = os.environ.get("ROTORCOSIM_CACHE")
    if env:
        return Path(env).expanduser() / "fmus"
    import platformdirs
    return Path(platformdirs.user_cache_dir("rotorcosim")) / "fmus"


def fmu_location(name: str) -> Path:
    """Where our FMU ``name`` (a key of :data:`RECIPES`) is built on demand (see the module docstring)."""
    recipe = RECIPES[name]
    if in_checkout():
        return FMU_DIR / f"{name}.fmu"
    return cache_dir() / source_hash(recipe)[:16] / f"{name}.fmu"

# Capabilities we really have (see docs/fmus.md): variable step sizes, full
# state save/restore (model arrays included) and pickle serialization; no
# input derivatives (PythonFMU does not implement fmi2SetRealInputDerivatives).
_OPTIONS = {
    "canHandleVariableCommunicationStepSize": True,
    "canInterpolateInputs": False,
    "canBeInstantiatedOnlyOncePerProcess": False,
    "canGetAndSetFMUstate": True,
    "canSerializeFMUstate": True,
    "needsExecutionTool": True,   # a Python interpreter with numpy/scipy/numba
}

# Files of a bundled package that are copied (besides *.py): data only.
_DATA_SUFFIXES = (".yaml", ".yml", ".json", ".toml", ".csv", ".txt", ".npz", ".npy")
_SKIP_DIRS = {"__pycache__", ".pytest_cache", ".mypy_cache"}


@dataclass(frozen=True)
class FmuRecipe:
    """How to build one FMU: the slave script and the packages bundled with it."""

    name: str                      # model identifier == file stem of the FMU
    script: Path                   # PythonFMU slave module
    packages: tuple[Path, ...]     # package folders copied into resources/
    options: Mapping[str, bool] = field(default_factory=lambda: dict(_OPTIONS))


# the slave plumbing shared by our slaves (fmu_common/slave.py), bundled into each FMU
SLAVE_PLUMBING = REPO / "fmu_common"

RECIPES: dict[str, FmuRecipe] = {
    "JournalBearing": FmuRecipe("JournalBearing", REPO / "bearing_fmu" / "journal_bearing.py",
                                (REPO / "bearing_fmu", SLAVE_PLUMBING)),
    "FloatingRingBearing": FmuRecipe("FloatingRingBearing", REPO / "bearing_fmu" / "floating_ring_bearing.py",
                                     (REPO / "bearing_fmu", SLAVE_PLUMBING)),
    "JeffcottRotor": FmuRecipe("JeffcottRotor", REPO / "rotor_fmu" / "jeffcott_rotor.py",
                               (REPO / "rotor_fmu", SLAVE_PLUMBING)),
    "TurbochargerRotor": FmuRecipe("TurbochargerRotor", REPO / "rotor_fmu" / "turbocharger_rotor.py",
                                   (REPO / "rotor_fmu", SLAVE_PLUMBING)),
}


def _package_files(pkg: Path) -> list[Path]:
    files = []
    for path in sorted(pkg.rglob("*")):
        rel = path.relative_to(pkg)
        if any(part in _SKIP_DIRS or part.startswith(".") for part in rel.parts):
            continue
        if path.is_file() and (path.suffix == ".py" or path.suffix in _DATA_SUFFIXES):
            files.append(path)
    return files


def source_hash(recipe: FmuRecipe) -> str:
    """SHA-256 of everything that goes into ``recipe``'s FMU."""
    import pythonfmu

    h = hashlib.sha256()
    h.update(f"pythonfmu {pythonfmu.__version__}\n".encode())
    h.update(json.dumps(dict(recipe.options), sort_keys=True).encode())
    for path in [Path(__file__).resolve(), recipe.script]:
        h.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    for pkg in recipe.packages:
        for path in _package_files(pkg):
            h.update(f"{pkg.name}/{path.relative_to(pkg).as_posix()}".encode() + b"\0")
            h.update(path.read_bytes() + b"\0")
    return h.hexdigest()


def _stamp_path(fmu: Path) -> Path:
    return fmu.with_suffix(".stamp")


def is_stale(fmu: Path | str, recipe: FmuRecipe | None = None) -> bool:
    """True when ``fmu`` is missing, has no readable stamp, or its sources changed."""
    fmu = Path(fmu)
    recipe = recipe or RECIPES[fmu.stem]
    stamp = _stamp_path(fmu)
    if not fmu.is_file() or not stamp.is_file():
        return True
    try:
        recorded = json.loads(stamp.read_text())["source_sha256"]
    except (OSError, ValueError, KeyError):
        return True
    return recorded != source_hash(recipe)


_BUILD_SNIPPET = """
import json, sys
from pythonfmu.builder import FmuBuilder
args = json.loads(sys.argv[1])
path = FmuBuilder.build_FMU(args["script"], dest=args["dest"], project_files=args["project_files"],
                            **args["options"])
print(path)
"""


def build_one(recipe: FmuRecipe, out_dir: Path) -> Path:
    """Build ``recipe`` into ``out_dir`` (atomically replacing an old FMU); return its path."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    digest = source_hash(recipe)
    target = out_dir / f"{recipe.name}.fmu"
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix=f"rotorcosim_build_{recipe.name}_") as tmp:
        tmp = Path(tmp)
        stage = tmp / "stage"
        project_files = []
        for pkg in recipe.packages:
            for path in _package_files(pkg):
                dst = stage / pkg.name / path.relative_to(pkg)
                dst.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(path, dst)
            project_files.append(str(stage / pkg.name))
        built = tmp / f"{recipe.name}.fmu"
        args = dict(script=str(recipe.script), dest=str(built), project_files=project_files,
                    options=dict(recipe.options))
        env = dict(os.environ)
        env["PYTHONDONTWRITEBYTECODE"] = "1"
        proc = subprocess.run([sys.executable, "-c", _BUILD_SNIPPET, json.dumps(args)],
                              capture_output=True, text=True, cwd=tmp, env=env)
        if proc.returncode != 0 or not built.is_file():
            raise FmuError(f"building {recipe.name}.fmu from {recipe.script} failed "
                           f"(exit code {proc.returncode}):\n{proc.stderr.strip()[-4000:]}\n"
                           "fix the slave module or the model it imports, then run `rotorcosim build-fmus`")
        info = {"name": recipe.name, "source_sha256": digest, "script": recipe.script.name,
                "packages": [p.name for p in recipe.packages], "options": dict(recipe.options),
                "built_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
        with zipfile.ZipFile(built, "a") as zf:
            zf.writestr("resources/rotorcosim_build.json", json.dumps(info, indent=1))
        tmp_target = out_dir / f".{recipe.name}.fmu.{os.getpid()}.tmp"
        stamp_tmp = out_dir / f".{recipe.name}.stamp.{os.getpid()}.tmp"
        try:
            shutil.copyfile(built, tmp_target)
            os.replace(tmp_target, target)
            stamp_tmp.write_text(json.dumps(info, indent=1) + "\n")
            os.replace(stamp_tmp, _stamp_path(target))  # atomic: concurrent runs may check it
        except BaseException as e:
            # a full disk left an empty .tmp file and named the build's temporary FMU, not the target;
            # Ctrl-C during the copy left the .tmp file too
            for p in (tmp_target, stamp_tmp):
                with contextlib.suppress(OSError):
                    p.unlink()
            if not isinstance(e, OSError):
                raise
            from orchestrator.results.safe_write import space_fix
            raise FmuError(f"cannot write {target} ({e.strerror or e}); {space_fix(e)} or give build-fmus --out another "
                           "folder, then build again") from None
    log.info("built %s in %.1f s", target, time.perf_counter() - t0)
    return target


def build_fmus(out_dir: str | Path = "fmus", force: bool = False,
               names: Iterable[str] | None = None) -> list[Path]:
    """Build (or reuse up-to-date) rotorcosim FMUs into ``out_dir``.

    Parameters
    ----------
    out_dir
        Destination folder; a relative path is taken relative to the current
        working directory (``rotorcosim build-fmus`` is run from the repository).
    force
        Rebuild even when the stamp says the FMU is up to date.
    names
        Subset of ``RECIPES`` (default: all three).

    Returns
    -------
    list of Path
        The FMU paths (built or already up to date), in ``RECIPES`` order.
    """
    out_dir = Path(out_dir)
    wanted = list(RECIPES) if names is None else list(names)
    unknown = [n for n in wanted if n not in RECIPES]
    if unknown:
        raise ValueError(f"unknown FMU name(s) {unknown}; known: {sorted(RECIPES)}")
    paths = []
    for name in wanted:
        recipe = RECIPES[name]
        target = out_dir / f"{name}.fmu"
        if force or is_stale(target, recipe):
            build_one(recipe, out_dir)
        paths.append(target)
    return paths


def _our_recipes(scenario) -> list[FmuRecipe]:
    """The recipes of our FMUs that ``scenario`` uses (built here or in the per-user cache)."""
    out = []
    for spec in scenario.fmus:
        try:
            resolved = Path(spec.path).resolve()
        except OSError:
            continue
        name = resolved.stem
        if (name in RECIPES and resolved.suffix == ".fmu" and RECIPES[name] not in out
                and (resolved.parent == FMU_DIR.resolve() or resolved == fmu_location(name).resolve())):
            out.append(RECIPES[name])
    return out


def uncompiled_kernels(scenario) -> list[str]:
    """The packages of our FMUs in ``scenario`` (``bearing_fmu``, ``rotor_fmu``) whose numba
    kernels of this source version are not in the on-disk cache yet
    (:mod:`bearing_fmu._numba_cache`): their first run compiles them before its first step,
    15-60 s that a new user would otherwise take for a hang. [] when the cache is off."""
    from bearing_fmu._numba_cache import _package_hash, cache_root
    root = cache_root()
    if root is None:
        return []
    missing = []
    for recipe in _our_recipes(scenario):
        for pkg in recipe.packages:
            files = sorted(pkg.glob("*.py"))
            if pkg.name in missing or not files:
                continue
            suffix = f"-{_package_hash(str(files[0]))[:20]}"
            try:
                cached = any(d.name.endswith(suffix) and any(d.glob("*.nbi")) for d in Path(root).iterdir())
            except OSError:
                cached = False
            if not cached and any("numba" in f.read_text(errors="replace") for f in files):
                missing.append(pkg.name)
    return missing


def ensure_fmus(scenario) -> list[Path]:
    """Build the repository FMUs that ``scenario`` uses and that are missing or stale.

    Only FMU paths inside the repository's ``fmus/`` folder whose file name is
    one of ours (``JournalBearing.fmu``, ``JeffcottRotor.fmu``,
    ``TurbochargerRotor.fmu``) are considered; third-party FMUs are never touched.
    Returns the paths that were (re)built.
    """
    rebuilt = []
    seen = set()
    for spec in scenario.fmus:
        path = Path(spec.path)
        try:
            resolved = path.resolve()
        except OSError:
            continue
        name = resolved.stem
        if name not in RECIPES or resolved.suffix != ".fmu" or resolved in seen:
            continue
        ours = resolved.parent == FMU_DIR.resolve() or resolved == fmu_location(name).resolve()
        if not ours:
            continue
        seen.add(resolved)
        if is_stale(resolved, RECIPES[name]):
            log.info("%s is missing or stale: building it", resolved)
            rebuilt.append(build_one(RECIPES[name], resolved.parent))
    return rebuilt
