"""FMI: FMU archives (untrusted input), the subsystem adapter (the only caller of FMI), our FMU builds.

Nothing outside this package opens an FMU archive or calls an FMI function.
"""

from orchestrator.fmi.archive import ModelDescription, Variable, read_model_description
from orchestrator.fmi.subsystem import RealBatch, Subsystem, SubsystemBase

__all__ = ["ModelDescription", "Variable", "read_model_description", "RealBatch", "Subsystem", "SubsystemBase"]
