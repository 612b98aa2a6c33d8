"""The scenario: frozen dataclasses of a co-simulation and their loading from YAML.

Reads a scenario file (YAML nodes, ``--set`` overrides, sections) and checks it against its FMUs.
"""

from orchestrator.scenario.loader import load_scenario, validate_scenario
from orchestrator.scenario.model import (
    SCENARIO_VERSION, SCHEMES, ConnectionSpec, CouplingSpec, FmuSpec, OutputSpec, Scenario)

__all__ = ["load_scenario", "validate_scenario", "Scenario", "FmuSpec", "ConnectionSpec", "CouplingSpec",
           "OutputSpec", "SCENARIO_VERSION", "SCHEMES"]
