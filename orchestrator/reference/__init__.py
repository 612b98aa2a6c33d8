"""The monolithic reference: the scenario's plain-Python models integrated as one ODE (BDF2 / solve_ivp).

Model adapters are looked up by the FMU's modelName in :data:`orchestrator.reference.models.MODELS`.
"""

from orchestrator.reference.models import MODELS, ModelAdapter
from orchestrator.reference.monolithic import MonolithicSystem, run_monolithic

__all__ = ["run_monolithic", "MonolithicSystem", "MODELS", "ModelAdapter"]
