"""bearing_fmu: journal-bearing film models (model.py) and their FMU (journal_bearing.py)."""

from ._numba_cache import register as _register_numba_cache

# before any kernel module is imported: the numba cache of a copy of this package (the FMU's
# resources/, extracted afresh for every run) is found by content, not by path
_register_numba_cache()
