"""The verbs around a scenario's files: ``plot`` (the figures of a finished run, a sweep or a
comparison), ``scenarios`` and ``init`` (the shipped scenarios) and ``export-ssp``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from orchestrator.cli import common
from orchestrator.cli.common import PROG, _add_set
from orchestrator.errors import CosimError


def _add_plot(sub) -> None:
    p = sub.add_parser("plot", help="draw the figures of a finished run")
    p.add_argument("dir", metavar="DIR", help="output folder of a run (holds results.csv, summary.json) or of "
                                              "a sweep (holds sweep.csv: draws the map)")
    p.add_argument("--signals", nargs="+", metavar="SIGNAL",
                   help="recorded signals to draw over time (names or '*' patterns, e.g. 'osc.x[*]' 'drv.*'); "
                        "default: every signal of a run without journals")
    p.set_defaults(func=_cmd_plot)


def _cmd_plot(args) -> int:
    run_dir = Path(args.dir)
    if not run_dir.is_dir():
        what = "is a file, not a folder" if run_dir.exists() else "no such run folder"
        raise CosimError(f"{run_dir}: {what}; give the --out folder of a run (it holds "
                         "results.csv and summary.json)")
    if (run_dir / "sweep.csv").is_file():              # a sweep folder: draw its map
        return _print_paths(common._feature("orchestrator.sweep.plot", "plot_sweep", "plot")(run_dir))
    if (run_dir / "report.json").is_file() and (run_dir / "runs").is_dir() and not (
            (run_dir / "results.csv").exists() or (run_dir / "summary.json").exists()):
        return _comparison_folder(run_dir)
    plot_run = common._feature("orchestrator.results.plots", "plot_run", "plot")
    for path in plot_run(run_dir, signals=args.signals):
        print(path)
    return 0


def _comparison_folder(cmp_dir: Path) -> int:
    """`plot` of a `compare` output folder: its figure is error_vs_cost.png, its runs are in runs/ (it
    used to say "results.csv not found (the run wrote no results)", twice, and exit 1)."""
    try:
        runs = sorted(p.name for p in (cmp_dir / "runs").iterdir() if p.is_dir())
    except OSError:
        runs = []
    shown = ", ".join(runs[:8]) + (", ..." if len(runs) > 8 else "")
    example = cmp_dir / "runs" / ("reference" if "reference" in runs or not runs else runs[0])
    hint = (f"{cmp_dir} is the folder of a comparison (rotorcosim compare): its report is report.md; to draw the "
            f"signals of one of its runs give that run's folder, e.g. rotorcosim plot {example}"
            + (f" (runs: {shown})" if runs else ""))
    figure = cmp_dir / "error_vs_cost.png"
    if not figure.is_file():
        raise CosimError(f"{hint}; it has no error_vs_cost.png (matplotlib was missing when it was written)")
    print(f"note: {hint}", file=sys.stderr)
    print(figure)
    return 0


def _print_paths(paths) -> int:
    for path in paths:
        print(path)
    return 0


def _add_scenarios(sub) -> None:
    p = sub.add_parser("scenarios", help="list the scenarios shipped with rotorcosim (run one by name)")
    p.set_defaults(func=_cmd_scenarios)


def _cmd_scenarios(args) -> int:
    from orchestrator.shipped import describe, scenario_dir, shipped

    files = shipped()
    width = max((len(n) for n in files), default=0)
    for name, path in files.items():
        print(f"{name.ljust(width)}  {describe(path)}")
    print(f"({len(files)} scenarios in {scenario_dir()}; `{PROG} run NAME` runs one, `{PROG} init DIR` copies "
          "them for editing)")
    return 0


def _add_init(sub) -> None:
    p = sub.add_parser("init", help="copy the shipped scenarios into a folder for editing")
    p.add_argument("dir", metavar="DIR", type=_init_folder, help="folder to create (or fill)")
    p.add_argument("--force", action="store_true", help="overwrite scenario files that exist already")
    p.set_defaults(func=_cmd_init)


def _cmd_init(args) -> int:
    from orchestrator.shipped import init

    files = init(args.dir, force=args.force)
    # the example is the quick start (seconds), not the first file by name: that was a full
    # floating-ring run-up (jeffcott_runup_floating_ring_free_to_air, minutes of wall time)
    names = [f.name for f in files]
    first = "quickstart.yaml" if "quickstart.yaml" in names else (names[0] if names else "X.yaml")
    print(f"{args.dir}: {len(files)} scenarios copied; edit one and run it with `{PROG} run {args.dir}/{first}`"
          + (" (a few seconds; the paper's run-ups take a minute or more)" if first == "quickstart.yaml" else ""))
    return 0


def _init_folder(value: str) -> str:
    """argparse type of ``init DIR``: not empty (an empty one filled the current folder and
    suggested `rotorcosim run /X.yaml`)."""
    if not value.strip():
        raise argparse.ArgumentTypeError("an empty folder name: give the folder to copy the scenarios into, "
                                         "e.g. `rotorcosim init my-scenarios` (or `.` for this folder)")
    return value


def _add_export_ssp(sub) -> None:
    p = sub.add_parser("export-ssp", help="write a scenario as an SSP 1.0 archive (runs in libcosim; what SSP "
                                          "has no element for travels in an org.rotorcosim.scenario annotation)")
    p.add_argument("file", metavar="SCENARIO", help="scenario YAML file (or a shipped scenario's name)")
    p.add_argument("out", metavar="OUT.ssp", help="archive to write: a new file in an existing folder, or an "
                                                  "earlier .ssp archive to replace")
    _add_set(p)
    p.add_argument("--carry-files-from", metavar="DIR", action="append", default=[],
                   help="a folder whose files the archive may carry when the scenario's String parameters name "
                        "them (repeatable); by default only files in the scenario's own folder are carried, "
                        "and those a --set value names")
    p.set_defaults(func=_cmd_export_ssp)


def _cmd_export_ssp(args) -> int:
    from orchestrator.scenario import load_scenario
    from orchestrator.scenario.analysis_clearance import check_analysis_clearance
    from orchestrator.shipped import resolve
    from orchestrator.scenario.ssp import check_carry_folders, check_output_path, export_ssp

    check_output_path(args.out)          # before loading (and maybe building FMUs): a bad OUT fails at once
    carry = check_carry_folders(args.carry_files_from)
    scenario = load_scenario(str(resolve(args.file)), args.set, build_fmus=True)
    check_analysis_clearance(scenario)   # the archive carries the analysis section: a run of it would refuse it
    print(export_ssp(scenario, args.out, carry_files_from=carry))
    return 0
