"""Coupling: the co-simulation master - plan, macro step, input delivery, step-size control, schemes, signals.

:class:`MasterAlgorithm` runs the life cycle; observers watch it; the result is a CoSimResult.
"""

from orchestrator.coupling.execution import MasterAlgorithm
from orchestrator.coupling.observers import CsvWriter, Observer, Progress, Recorder, RunView
from orchestrator.coupling.schemes import CouplingScheme, GaussSeidel, Jacobi, scheme_from_spec
from orchestrator.coupling.signals import History, LagrangePredictor
from orchestrator.coupling.step_control import ConstantStep, DiscardHalving, StepSizeController

__all__ = ["MasterAlgorithm", "Observer", "Recorder", "CsvWriter", "Progress", "RunView", "CouplingScheme",
           "Jacobi", "GaussSeidel", "scheme_from_spec", "History", "LagrangePredictor", "StepSizeController",
           "ConstantStep", "DiscardHalving"]
