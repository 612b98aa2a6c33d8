"""Parameter sweeps and stability maps on Dask distributed (``rotorcosim sweep``, docs/sweeps.md).

```python
from orchestrator.sweep import sweep
df = sweep("scenarios/sweeps/jeffcott_hs_onset_map.yaml", out_dir="runs/hs_map")   # pandas DataFrame
df[df.status == "finished"][["psi", "eta0", "onset_hz"]]
```

Pieces: :mod:`~orchestrator.sweep.spec` (the sweep file), :mod:`~orchestrator.sweep.plan`
(runs and their ids, every run's scenario validated first), :mod:`~orchestrator.sweep.task`
(one run in a run process of its worker, the Dask task), :mod:`~orchestrator.sweep.warm`
(the warm run processes), :mod:`~orchestrator.sweep.runner` (the cluster,
progress, resume, Ctrl-C), :mod:`~orchestrator.sweep.table` (sweep.csv / sweep.parquet),
:mod:`~orchestrator.sweep.plot` (the map).
"""

from __future__ import annotations

from pathlib import Path

from orchestrator.errors import CosimError, path_arg
from orchestrator.sweep.spec import SweepError, SweepSpec, load_sweep

__all__ = ["sweep", "load_sweep", "prepare", "SweepError", "SweepSpec", "default_out_dir"]


def default_out_dir(path: str | Path) -> Path:
    """``runs/sweep_<file stem>`` under the current folder."""
    return Path("runs") / f"sweep_{Path(path).stem}"


def prepare(path: str | Path, *, progress: bool | None = False):
    """(spec, runs): the checked sweep file and its runs, every run's scenario validated
    (``progress``: a bar while validating many runs, as :func:`~orchestrator.sweep.plan.plan_sweep`;
    more than :data:`~orchestrator.sweep.plan.MAX_RUNS` runs raise :class:`SweepError` first)."""
    from orchestrator.sweep.plan import plan_sweep
    spec = load_sweep(path_arg(path, "prepare(path)", "prepare('scenarios/sweeps/x.yaml')"))
    return spec, plan_sweep(spec, progress=progress)


def sweep(path: str | Path, out_dir: str | Path | None = None, *, scheduler: str | None = None,
          workers: int | None = None, resume: bool = False, progress: bool | None = False, warm: bool = True):
    """Run the sweep file ``path`` and return its table as a pandas DataFrame (one row per run).

    Same options as ``rotorcosim sweep``: ``out_dir`` (default ``runs/sweep_<stem>``),
    ``scheduler`` (address of a running Dask scheduler; default ``DASK_SCHEDULER_ADDRESS`` or
    a LocalCluster), ``workers`` (LocalCluster size, default one per core), ``resume``,
    ``progress``, ``warm`` (False: a fresh process per run, ``--fresh-processes``). Raises :class:`SweepError` for a bad sweep file or run scenario (before
    anything runs); failed runs are rows (``status`` column), not exceptions. On
    KeyboardInterrupt the table of what finished is written, then the interrupt propagates.
    pandas is imported only here (the CLI does not need it).
    """
    path = path_arg(path, "sweep(path)", "sweep('scenarios/sweeps/x.yaml')")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)):
        # "4" ended in "'<' not supported between instances of 'str' and 'int'", 2.5 reached Dask
        raise TypeError(f"sweep(workers=...) takes a whole number of at least 1, or None for one per core "
                        f"(got {workers!r}); e.g. workers=4")
    if scheduler is not None and not isinstance(scheduler, str):
        raise TypeError(f"sweep(scheduler=...) takes the address of a Dask scheduler as a text, or None for a "
                        f"local cluster (got {type(scheduler).__name__} {scheduler!r:.60}); e.g. "
                        "scheduler='tcp://10.0.0.5:8786'")
    if out_dir is not None:
        out_dir = path_arg(out_dir, "sweep(out_dir=...)", "sweep('scenarios/sweeps/x.yaml', out_dir='runs/x')")
    try:
        import pandas as pd
    except ModuleNotFoundError:
        raise CosimError("orchestrator.sweep.sweep() returns a pandas DataFrame and pandas is not installed; "
                         "install it (pip install pandas), or use `rotorcosim sweep` and read sweep.csv") from None
    from orchestrator.sweep.runner import run_sweep
    from orchestrator.sweep.table import columns

    spec, runs = prepare(path)
    outcome = run_sweep(spec, runs, out_dir or default_out_dir(path), scheduler=scheduler, workers=workers,
                        resume=resume, progress=progress, warm=warm)
    if outcome.interrupted:
        raise KeyboardInterrupt(f"sweep interrupted; finished runs are in {outcome.table}")
    df = pd.DataFrame(outcome.rows, columns=columns(spec))
    for name, _ in spec.collect:                  # a column no run has a value in: NaN, not None objects
        if df[name].isna().all():
            df[name] = df[name].astype(float)
    return df
