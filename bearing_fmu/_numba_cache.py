"""Numba on-disk cache that survives the FMU's fresh extraction directory.

Why: numba's default locator keeps compiled kernels in ``__pycache__`` beside the source
file. A bearing FMU carries its own copy of ``bearing_fmu`` in ``resources/`` and the master
extracts it into a new directory for every run, so that cache is always empty and every run
recompiled every kernel: measured 7 s CPU of start-up on the 40 x 40 film at load ~10 (9.8 s
from a fresh copy against 2.9 s with a filled cache), a quarter of a 30 s run-up.

What: :class:`ContentCacheLocator`, registered in front of numba's own locators when
``bearing_fmu`` is imported (before any kernel is decorated), keeps the cache of a module in
``<cache root>/<module>-<sha256 of its package's sources>[:20]`` (:func:`_package_hash`: all
``.py`` files of the module's folder, because a cached kernel holds the compiled code of the
kernels it calls in other modules), so every copy of the same sources shares one cache
wherever it lies, and a change to any of them gets a new directory (the old one is never
read again; each is a few MB). Cache root: ``$ROTORCOSIM_NUMBA_CACHE``, else
``$NUMBA_CACHE_DIR/rotorcosim``, else ``<user cache>/rotorcosim/numba`` with the platform's
per-user cache folder from platformdirs (Linux: ``$XDG_CACHE_HOME``, default ``~/.cache``;
the same without platformdirs). A root that cannot be written makes the locator step aside (numba then uses
its defaults). ``ROTORCOSIM_NUMBA_CACHE=off`` switches it off.

Concurrency: numba writes each cache file to a temporary name and renames it into place
(``numba.core.caching.IndexDataCacheFile``), so processes that compile the
same kernel at once each write a complete file and the last rename wins; a reader never sees
half a file. The index carries the source hash (numba's own source stamp), so a stale entry
is recompiled, not loaded.

This uses numba's documented locator protocol (``_CacheLocator``: ``get_cache_path``,
``get_source_stamp``, ``get_disambiguator``, ``from_function``) through the class attribute
``numba.core.caching.CacheImpl._locator_classes`` (``_CacheImpl`` before numba 0.59); if that list is absent,
nothing is registered and numba's defaults apply.
"""

from __future__ import annotations

import hashlib
import os
import tempfile

__all__ = ["ContentCacheLocator", "cache_root", "njit_cached", "register"]


def cache_root() -> str | None:
    """The cache root directory (module doc), or None when switched off."""
    env = os.environ.get("ROTORCOSIM_NUMBA_CACHE", "")
    if env.lower() == "off":
        return None
    if env:
        return env
    if os.environ.get("NUMBA_CACHE_DIR"):
        return os.path.join(os.environ["NUMBA_CACHE_DIR"], "rotorcosim")
    try:                          # the per-user cache folder of the platform (honours XDG_CACHE_HOME)
        from platformdirs import user_cache_dir
        base = user_cache_dir("rotorcosim", appauthor=False)
    except ImportError:           # an FMU imported by a Python without platformdirs
        base = os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"),
                            "rotorcosim")
    return os.path.join(base, "numba")


#: (folder, its .py files with mtime and size) -> digest: one hash of a package per import,
#: not one per decorated kernel
_DIGESTS: dict = {}


def _package_hash(py_file: str) -> str:
    """sha256 of the source of every ``.py`` file in ``py_file``'s folder (names and
    contents, sorted by name). A compiled kernel carries the machine code of every kernel
    it calls, and numba's own stamp covers only the caller's file: keyed by its file alone,
    ``fused.advance_fused`` kept running the old ``film.assemble`` after film.py changed
    (measured, issue 16). So the key is the package, in which the kernels call each other;
    a change to any of its files gives every module of it a new cache directory."""
    folder = os.path.dirname(os.path.abspath(py_file))
    names = sorted(n for n in os.listdir(folder) if n.endswith(".py"))
    stats = []
    for n in names:
        st = os.stat(os.path.join(folder, n))
        stats.append((n, st.st_mtime_ns, st.st_size))
    key = (folder, tuple(stats))
    digest = _DIGESTS.get(key)
    if digest is None:
        h = hashlib.sha256()
        for n in names:
            with open(os.path.join(folder, n), "rb") as f:
                h.update(n.encode() + b"\0" + f.read() + b"\0")
        digest = _DIGESTS[key] = h.hexdigest()
    return digest


try:
    from numba.core import caching as _caching
    _CacheLocator = _caching._CacheLocator
    # the base class holding the locator list: CacheImpl (numba >= 0.59), _CacheImpl before
    _CacheImpl = getattr(_caching, "CacheImpl", None) or getattr(_caching, "_CacheImpl")
except (ImportError, AttributeError):   # pragma: no cover - numba layout changed: its defaults
    _CacheImpl = _CacheLocator = None


if _CacheLocator is not None:
    class ContentCacheLocator(_CacheLocator):
        """numba cache locator keyed by the content of the source file (module doc)."""

        def __init__(self, py_func, py_file, digest, root):
            self._lineno = py_func.__code__.co_firstlineno
            self._digest = digest
            mod = os.path.splitext(os.path.basename(py_file))[0]
            self._path = os.path.join(root, f"{mod}-{digest[:20]}")

        def get_cache_path(self):
            return self._path

        def get_source_stamp(self):
            return self._digest

        def get_disambiguator(self):
            return str(self._lineno)

        @classmethod
        def from_function(cls, py_func, py_file):
            root = cache_root()
            if root is None or not os.path.isfile(py_file):
                return None
            try:
                self = cls(py_func, py_file, _package_hash(py_file), root)
                os.makedirs(self._path, exist_ok=True)
                tempfile.TemporaryFile(dir=self._path).close()
            except OSError:
                return None
            return self
else:                    # pragma: no cover
    ContentCacheLocator = None


def register() -> bool:
    """Put :class:`ContentCacheLocator` first in numba's locator list (idempotent); True if
    it is registered."""
    if _CacheImpl is None or not isinstance(getattr(_CacheImpl, "_locator_classes", None), list):
        return False
    classes = _CacheImpl._locator_classes
    if not any(getattr(c, "__name__", "") == "ContentCacheLocator"
               and getattr(c, "__module__", "").endswith("_numba_cache") for c in classes):
        classes.insert(0, ContentCacheLocator)
    return True


def njit_cached(func, **options):
    """``numba.njit(cache=True, **options)(func)`` through :class:`ContentCacheLocator`; a
    function whose source file is gone is compiled without the on-disk cache instead.

    Why: numba picks the cache location when the function is decorated, from the file of
    its source, and raises "cannot cache function ...: no locator available" when no locator
    accepts that file. A process that ran a Python FMU and removed its extraction folder (an
    importer freeing the FMU, fmpy's ``extract`` into a temporary folder) keeps that FMU's
    modules imported; a kernel decorated later from one of them (``rotor_fmu.ij_kernel``
    compiles the speed table of ``rotor_fmu.linear_rotor``) then failed the FMU's
    ``fmi2DoStep`` with that error. Without the cache the kernel is compiled in memory: the same
    code, only not kept for the next process."""
    import numba
    register()
    try:
        return numba.njit(cache=True, **options)(func)
    except RuntimeError as exc:
        if "no locator" not in str(exc):
            raise
        return numba.njit(cache=False, **options)(func)
