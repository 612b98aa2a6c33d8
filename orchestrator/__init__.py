"""rotorcosim orchestrator: load a scenario, run it, get a result.

```python
from orchestrator import load_scenario, run, CoSimResult
sc = load_scenario("scenarios/x.yaml", overrides=["coupling.macro_step=5e-5"])
res = run(sc, out_dir="out/x")          # writes out/x/results.csv and out/x/summary.json
res.status, res.success, res.message, res.t, res.outputs, res.stats
res = CoSimResult.load("out/x")         # the same result read back from the folder
```

For step-by-step control use :class:`orchestrator.coupling.MasterAlgorithm`; the layout
of the packages is in docs/dev/architecture.md.
"""

import importlib

# the public names and where they live; imported on first use (PEP 562), so that
# `rotorcosim --help` or `import orchestrator.errors` do not import numpy and scipy
_EXPORTS = {
    "MasterAlgorithm": "orchestrator.coupling.execution",
    "CosimError": "orchestrator.errors",
    "ScenarioError": "orchestrator.errors",
    "CoSimResult": "orchestrator.results.result",
    "Status": "orchestrator.results.result",
    "load_scenario": "orchestrator.scenario.loader",
    "validate_scenario": "orchestrator.scenario.loader",
    "Scenario": "orchestrator.scenario.model",
    "run": "orchestrator.workflow",
}

__all__ = ["load_scenario", "validate_scenario", "run", "CoSimResult", "Status", "Scenario", "MasterAlgorithm",
           "CosimError", "ScenarioError"]


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'orchestrator' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
