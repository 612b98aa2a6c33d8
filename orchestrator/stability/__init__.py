"""The linear stability threshold of a scenario's rotor-bearing system, the library side of
``rotorcosim stability`` (docs/analysis.md, "Linear stability threshold").

``system.py`` reads what is linearised from the scenario (the rotor, the bearing at each station,
their static loads), ``films.py`` linearises each station's film at a speed, ``search.py`` finds
where the system crosses into instability over the speed range and assembles the result,
``partial.py`` says why and where a search stopped before its end (Ctrl-C, SIGTERM, an error at
one speed) and what it kept.
"""

from orchestrator.stability.films import MC_SOLVERS
from orchestrator.stability.films import _failed, _HSFilm, _MCFilm, _RingMCFilm, _ShortFilm  # noqa: F401 (tests, docs/scripts)
from orchestrator.stability.search import FILMS, MAX_SPEED_HZ, MC_SCAN, later_crossings, stability
from orchestrator.stability.system import RING_MODEL, SUPPORTED, Bearing, StabilityError, System, build_system

__all__ = ["FILMS", "MAX_SPEED_HZ", "MC_SCAN", "MC_SOLVERS", "RING_MODEL", "SUPPORTED", "Bearing", "StabilityError",
           "System", "build_system", "later_crossings", "stability"]
