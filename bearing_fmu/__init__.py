"""bearing_fmu: the transient Reynolds film with mass-conserving cavitation, the journal and floating-ring bearing models.

Physics modules import no FMI; the PythonFMU slaves (journal_bearing.py, floating_ring_bearing.py) wrap them.
"""

from ._numba_cache import register as _register_numba_cache

# before any kernel module is imported: the numba cache of a copy of this package (the FMU's
# resources/, extracted afresh for every run) is found by content, not by path
_register_numba_cache()
