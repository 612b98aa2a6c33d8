"""Results: the CoSimResult of a run, its folder (the one reader), summary.json, the whirl analysis, plots.

Everything that reads a run folder goes through :class:`RunDirectory`.
"""

from orchestrator.results.result import CoSimResult, Status
from orchestrator.results.run_directory import RunDirectory, read_results

__all__ = ["CoSimResult", "Status", "RunDirectory", "read_results"]
