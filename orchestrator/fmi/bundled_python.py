"""FMUs that bundle their own Python packages (PythonFMU FMUs) side by side in one process.

A PythonFMU FMU carries its slave module and often its own copy of ``pythonfmu``
and of the packages it needs under ``resources/``; PythonFMU's native loader
puts that folder at the front of ``sys.path`` and imports the slave module. In
one process, Python's module cache (``sys.modules``) then hands the *second*
FMU the packages the *first* one imported, so an FMU bundling pythonfmu 0.6.9
(and an older helper package) listed before one built with 0.7.0 makes the
second fail ("No module named ...") or run with the wrong code, depending on
the order of the instances.

:func:`own_imports` wraps the instantiation of an FMU: for every top-level
package or module the FMU bundles in ``resources/``, entries of ``sys.modules``
that were loaded from somewhere else are set aside, so the FMU imports its own
copies; afterwards the entries set aside are put back, so the rest of the
process (our FMU builder, which imports ``pythonfmu``, included) sees the modules
it saw before. Instances keep the module objects they imported (Python keeps them
alive through their references), so each runs on with its own code.
"""

from __future__ import annotations

import importlib
import logging
import sys
from pathlib import Path

log = logging.getLogger(__name__)


def bundled_names(resources: Path) -> list[str]:
    """Top-level importable names in ``resources`` (packages with ``__init__.py`` and ``.py`` modules)."""
    if not resources.is_dir():
        return []
    names = []
    for p in sorted(resources.iterdir()):
        if p.is_dir() and (p / "__init__.py").is_file():
            names.append(p.name)
        elif p.suffix == ".py" and p.stem.isidentifier():
            names.append(p.stem)
    return names


def _origin(mod) -> Path | None:
    f = getattr(mod, "__file__", None)
    if f is None:
        paths = list(getattr(mod, "__path__", []) or [])
        f = paths[0] if paths else None
    try:
        return Path(f).resolve() if f else None
    except (OSError, TypeError):
        return None


def set_aside(unzip_dir: Path) -> dict:
    """Remove from ``sys.modules`` the cached modules that the FMU in ``unzip_dir`` bundles itself but that
    were loaded from elsewhere; return them (``{name: module}``) for :func:`put_back`."""
    resources = (Path(unzip_dir) / "resources").resolve()
    if not (resources / "pythonfmu").is_dir():      # not a PythonFMU FMU with its own runtime
        return {}
    aside = {}
    for name in bundled_names(resources):
        for key in [k for k in sys.modules if k == name or k.startswith(name + ".")]:
            origin = _origin(sys.modules[key])
            if origin is not None and resources not in origin.parents:
                aside[key] = sys.modules.pop(key)
    if aside:
        log.debug("%s bundles %s; its own copies are imported", unzip_dir, sorted({k.split(".")[0] for k in aside}))
    return aside


def put_back(aside: dict, names=(), before=frozenset()) -> None:
    """Restore ``sys.modules`` for the bundled ``names``: drop the entries the FMU added (its own copies stay
    alive through the FMU's references), then put back those :func:`set_aside` removed."""
    for key in [k for k in sys.modules if k.split(".", 1)[0] in names and k not in before]:
        del sys.modules[key]
    sys.modules.update(aside)


def forget_imports_under(root: Path) -> list[str]:
    """Drop from ``sys.modules`` the modules loaded from files under ``root``, and ``root``'s folders
    from ``sys.path``; return the module names dropped.

    Called before a run folder of extracted FMUs is removed. A Python FMU's slave module
    imports its packages from the extracted ``resources/`` (our rotor FMUs import ``rotor_fmu``
    from there when the process has not imported it yet). Left in ``sys.modules`` after the
    folder is gone, such a package breaks every later import of its submodules and data files
    in the same process (a notebook, a test session, a sweep worker). Measured: after a
    turbocharger run, ``rotor_fmu.floating_ring_growth.turbocharger_floating_ring()`` failed
    with "cannot read the file .../resources/rotor_fmu/data/turbocharger.yaml". Instances
    still alive keep their module objects (Python keeps them alive through their references).
    The warm sweep processes do the same after each run (``orchestrator.sweep.warm_child.forget_vanished``)."""
    try:
        root = Path(root).resolve()
    except OSError:
        return []

    def under(path) -> bool:
        return path is not None and (path == root or root in path.parents)

    def entry_under(entry) -> bool:            # a sys.path / importer-cache key
        try:
            return isinstance(entry, str) and bool(entry) and under(Path(entry).resolve())
        except (OSError, ValueError):
            return False

    dropped = [key for key, mod in list(sys.modules.items()) if under(_origin(mod))]
    for key in dropped:
        del sys.modules[key]
    sys.path[:] = [e for e in sys.path if not entry_under(e)]
    for entry in [e for e in sys.path_importer_cache if entry_under(e)]:
        del sys.path_importer_cache[entry]
    importlib.invalidate_caches()
    if dropped:
        log.debug("forgot %d modules imported from %s", len(dropped), root)
    return dropped


class own_imports:
    """``with own_imports(unzip_dir): instantiate()`` (see the module docstring)."""

    def __init__(self, unzip_dir: Path):
        self.unzip_dir = unzip_dir
        self.aside: dict = {}

    def __enter__(self):
        resources = Path(self.unzip_dir) / "resources"
        self.names = set(bundled_names(resources)) if (resources / "pythonfmu").is_dir() else set()
        self.aside = set_aside(self.unzip_dir)
        self.before = frozenset(k for k in sys.modules if k.split(".", 1)[0] in self.names)
        return self

    def __exit__(self, *exc):
        put_back(self.aside, self.names, self.before)
        return False
