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

from orchestrator.coupling.execution import MasterAlgorithm
from orchestrator.errors import CosimError, ScenarioError
from orchestrator.results.result import CoSimResult, Status
from orchestrator.scenario.loader import load_scenario, validate_scenario
from orchestrator.scenario.model import Scenario
from orchestrator.workflow import run

__all__ = ["load_scenario", "validate_scenario", "run", "CoSimResult", "Status", "Scenario", "MasterAlgorithm",
           "CosimError", "ScenarioError"]
