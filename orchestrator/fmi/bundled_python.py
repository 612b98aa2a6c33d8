"""FMUs that bundle their own Python packages (PythonFMU FMUs) side by side in one process.

A PythonFMU FMU carries its slave module and often its own copy of ``pythonfmu``
and of the packages it needs under ``resources/``; PythonFMU's native loader
puts that folder at the front of ``sys.path`` and imports the slave module. In
one process, Python's module cache (``sys.modules``) then hands the *second*
FMU the packages the *first* one imported, so an FMU bundling pythonfmu 0.6.9
(and an older helper package) listed before one built with 0.7.0 makes the
second fail ("No module named ...") or run with the wrong code, depending on
the order of the instances.

:func:`prepare_imports` is called before an FMU is instantiated: for every
top-level package or module the FMU bundles in ``resources/``, entries of
``sys.modules`` that were loaded from somewhere else are dropped, so the FMU
imports its own copies. Instances created earlier keep the module objects they
already hold (Python keeps them alive through their references), so they run
on with their own code.
"""

from __future__ import annotations

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


def prepare_imports(unzip_dir: Path) -> list[str]:
    """Drop cached modules that the FMU in ``unzip_dir`` bundles itself; return the names dropped."""
    resources = (Path(unzip_dir) / "resources").resolve()
    if not (resources / "pythonfmu").is_dir():      # not a PythonFMU FMU with its own runtime
        return []
    dropped = []
    for name in bundled_names(resources):
        for key in [k for k in sys.modules if k == name or k.startswith(name + ".")]:
            origin = _origin(sys.modules[key])
            if origin is not None and resources not in origin.parents:
                del sys.modules[key]
                dropped.append(key)
    if dropped:
        log.debug("%s bundles %s; dropped the cached copies loaded from elsewhere", unzip_dir,
                  sorted({k.split(".")[0] for k in dropped}))
    return dropped
