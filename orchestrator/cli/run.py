"""The verbs that run a scenario or check it: ``run`` (with the lines it prints of the run-up
analysis), ``validate`` and ``compare``."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Callable

from orchestrator.cli import common
from orchestrator.cli.common import _add_set, _folder
from orchestrator.errors import ScenarioError


def _add_run(sub) -> None:
    p = sub.add_parser("run", help="run a scenario", description=(
        "Run a scenario. Writes DIR/results.csv and DIR/summary.json; our own FMUs are built first when "
        "missing or stale."))
    p.add_argument("file", metavar="FILE", help="scenario YAML file, or the name of a shipped scenario "
                                                "(`rotorcosim scenarios` lists them), e.g. quickstart")
    p.add_argument("--out", metavar="DIR", type=_folder, help="output folder (default: runs/<scenario name> under the "
                                                "current folder)")
    _add_set(p)
    p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="show progress and time left (default: when stderr is a terminal and the run "
                        "takes more than a few seconds)")
    p.set_defaults(func=_cmd_run)


def _first_compile_note(scenario) -> None:
    """Say so when our FMUs' numba kernels are compiled first (a silent pause otherwise)."""
    from orchestrator.fmi.build import uncompiled_kernels
    try:
        missing = uncompiled_kernels(scenario)
    except OSError:                 # a note only: never the reason a run does not start
        return
    if missing:
        their = "its" if len(missing) == 1 else "their"
        print(f"note: first run of these {' and '.join(missing)} sources on this machine: numba compiles {their} "
              "kernels before the first step (about 15-60 s, once; later runs load them from the cache)", flush=True)


def _cmd_run(args) -> int:
    from orchestrator.results.run_directory import RunDirectory
    from orchestrator.scenario import load_scenario
    from orchestrator.scenario.analysis_clearance import check_analysis_clearance
    from orchestrator.shipped import resolve

    args.file = str(resolve(args.file))
    scenario = load_scenario(args.file, args.set, build_fmus=True)
    check_analysis_clearance(scenario)             # the run analyses its run-up: refused before any line
    out_dir = Path(args.out) if args.out else Path("runs") / scenario.name
    run = _run_function()
    print(f"running {scenario.name} ({args.file}): {scenario.start_time:g} s -> {scenario.stop_time:g} s, "
          f"{scenario.coupling.scheme}, macro step {scenario.coupling.macro_step:g} s", flush=True)
    for key, text in scenario.defaults.items():
        print(f"{key} = {text}")
    _first_compile_note(scenario)
    t0 = time.perf_counter()
    result = run(scenario, out_dir=out_dir, progress=args.progress)
    wall = time.perf_counter() - t0
    stats = dict(result.stats or {})
    status_text = result.status.short
    where = result.out_dir or out_dir
    steps = stats.get("macro_steps", "?")
    rows = RunDirectory(where).results_file.name
    try:
        fields = sorted(p.name for p in Path(where).glob("*_fields.npz"))[:4]     # stationary scenarios
    except OSError:
        fields = []
    print(f"results: {where} ({', '.join([rows, 'summary.json', *fields])})")
    if result.success and result.status.short != "finished" and result.message:
        # stopped_by_fmu: which FMU ended the run, and when (the bare status left the user to open
        # summary.json to learn why a 20 s run ended at 8.99 s)
        print(f"status: {status_text}: {result.message}")
    else:
        print(f"status: {status_text}")
    wall_s = stats.get("wall_time_s")
    print(f"macro steps: {steps}, wall time: {wall_s if isinstance(wall_s, (int, float)) else wall:.2f} s")
    line = _defect_line(stats.get("coupling_defect"))
    if line:
        print(line)
    if result.analysis:
        for line in _analysis_lines(result.analysis):
            print(line)
    if not result.success:
        end = result.end_time
        at = f" at t = {end:g} s" if isinstance(end, (int, float)) else ""
        print(f"error: the run stopped{at}: {result.message or status_text}; the rows written so far are kept in "
              f"{where}/{rows} and the reason in {where}/summary.json", file=sys.stderr)
        return 1
    return 0


def _defect_line(cd) -> str | None:
    """One line on the coupling defect (summary.json ``coupling_defect``): the largest over the
    journals against its typical force, and how many steps were flagged (the warning says more)."""
    from orchestrator.coupling.defect import relative_defects
    rows = relative_defects(cd)
    if not rows:
        return None
    name, j, ratio, _ = max(rows, key=lambda r: r[2])
    unit = f" {j['unit']}" if j.get("unit") else ""
    flagged = sum(int(r.get("steps_over") or 0) for _, r, _, _ in rows)
    r = cd.get("retries") if isinstance(cd, dict) else None
    redone = ""
    if isinstance(r, dict) and isinstance(r.get("retried_steps"), int) and r["retried_steps"]:
        redone = (f"; {r['retried_steps']} step(s) redone in halves (coupling.defect_retries), "
                  f"{_num(r.get('unresolved_steps'), 'd')} still over the limit at the smallest")
    return (f"coupling defect: largest {j['max_defect']:.4g}{unit} ({ratio:.3g}x the "
            f"typical {j['typical']:.4g}{unit}, {name}, t = {_num(j.get('t_max_defect'), '.6g', ' s')}); "
            + (f"{flagged} step(s) flagged, see the warning above" if flagged else "no step flagged") + redone)


def _num(value, fmt: str, unit: str = "") -> str:
    return format(value, fmt) + unit if isinstance(value, (int, float)) else "?"


def _analysis_lines(analysis) -> list[str]:
    """Readable lines of the run-up analysis stored in summary.json (formatting only)."""
    if not isinstance(analysis, dict):
        return []
    if analysis.get("error"):
        return [f"analysis: not available: {analysis['error']}"]
    lines = ["oil whirl (details in summary.json, \"analysis\"):"]
    for name, j in (analysis.get("journals") or {}).items():
        if not isinstance(j, dict) or j.get("error"):
            lines.append(f"  {name}: not analysed: {j.get('error') if isinstance(j, dict) else j}")
            continue
        eps = f"max eps {_num(j.get('max_eps'), '.3f')} at {_num(j.get('max_eps_speed_hz'), '.1f', ' Hz')}"
        if not j.get("whirl"):
            lines.append(f"  {name}: no sub-synchronous whirl; {eps}")
            continue
        before = (" (already in the first analysis window: it may start earlier)"
                  if (j.get("onset") or {}).get("present_at_start") else "")
        vanish = (f"vanishes at {_num(j.get('vanish_speed_hz'), '.1f', ' Hz')}"
                  if j.get("vanish_speed_hz") is not None else "does not vanish in this run")
        lines.append(f"  {name}: onset at {_num(j.get('onset_speed_hz'), '.1f', ' Hz')} (t = "
                     f"{_num(j.get('onset_time_s'), '.4f', ' s')}){before}, whirl/speed ratio "
                     f"{_num(j.get('dominant_ratio'), '.2f')}, {vanish}; {eps}")
        lines.append("    " + _threshold_line(j, analysis.get("parameters")))
        if j.get("warnings"):
            lines.append(f"    ({len(j['warnings'])} warning(s) in summary.json)")
    return lines


def _threshold_line(j: dict, parameters) -> str:
    """What the onset is, and the run's estimate of the linear stability threshold: the onset
    is where the whirl has *grown* to a fraction of the clearance, well above the speed where the
    rotor became unstable on a ramp (docs/analysis.md, "Instability threshold")."""
    level = (parameters or {}).get("threshold") if isinstance(parameters, dict) else None
    reached = (f"{level * 100:g} % of the clearance" if isinstance(level, (int, float))
               and not isinstance(level, bool) else "the detection level (analysis.whirl.threshold)")
    what = f"the onset is where the whirl orbit reached {reached}"
    th = j.get("threshold_speed_hz")
    if th is None:
        return f"({what}; no instability threshold found before it, see warnings in summary.json)"
    snr = j.get("threshold_snr")
    weak = (f"; unreliable, the growing mode is within the noise floor there (threshold_snr "
            f"{_num(snr, '.1f')} < 3)") if isinstance(snr, (int, float)) and snr < 3 else ""
    return (f"({what}; it became unstable earlier: the whirl's growth rate turns positive at "
            f"{_num(th, '.1f', ' Hz')} (t = {_num(j.get('threshold_time_s'), '.4f', ' s')}), the "
            f"estimate of the linear stability threshold{weak})")


def _run_function() -> Callable:
    from orchestrator.workflow import run
    return run


def _add_validate(sub) -> None:
    p = sub.add_parser("validate", help="check a scenario and its FMUs without running", description=(
        "Check a scenario and its FMUs without running; prints every problem, exit status 1 if any. "
        "Our own FMUs (in the repository's fmus/) are built first when missing or stale, as `run` does."))
    p.add_argument("file", metavar="FILE", help="scenario YAML file, or the name of a shipped scenario")
    _add_set(p)
    p.add_argument("--no-build", action="store_true", help="do not build missing or stale FMUs; report them")
    p.set_defaults(func=_cmd_validate)


def _cmd_validate(args) -> int:
    from orchestrator.scenario import load_scenario
    from orchestrator.scenario.analysis_clearance import check_analysis_clearance
    from orchestrator.shipped import resolve

    args.file = str(resolve(args.file))
    try:
        scenario = load_scenario(args.file, args.set, build_fmus=not args.no_build)
        check_analysis_clearance(scenario)         # what the run's analysis refuses, listed as the loader's problems
    except ScenarioError as exc:
        for problem in exc.problems:
            print(problem)
        n = len(exc.problems)
        print(f"{args.file}: {n} problem{'s' if n != 1 else ''} found", file=sys.stderr)
        return 1
    from orchestrator.preflight import preflight
    problems, notes = preflight(scenario)
    for line in (*problems, *notes):
        print(line)
    if problems:
        n = len(problems)
        print(f"{args.file}: {n} problem{'s' if n != 1 else ''} found (the checks `run` makes before its "
              "first step)", file=sys.stderr)
        return 1
    for key, text in scenario.defaults.items():
        print(f"{key} = {text}")
    n_fmus, n_conn = len(scenario.fmus), len(scenario.connections)
    print(f"{args.file}: valid ({n_fmus} FMU instance{'s' if n_fmus != 1 else ''}, "
          f"{n_conn} connection{'s' if n_conn != 1 else ''}, "
          f"{scenario.coupling.scheme}, macro step {scenario.coupling.macro_step:g} s)")
    return 0


def _add_compare(sub) -> None:
    p = sub.add_parser("compare", help="compare coupling schemes against a reference (CI regression gate)",
                       description=("Run a scenario with several coupling schemes and macro steps, measure each "
                                    "one's error against a reference, and name the cheapest variant within the "
                                    "accuracy needed (compare.goal; docs/compare.md). Exit 1 when a check fails "
                                    "(a tolerance, an expected order, the baseline), 2 when the file is invalid."))
    p.add_argument("file", metavar="FILE", help="comparison YAML file (or a scenario with a compare: section, or an "
                                                "SSP archive export-ssp wrote from one)")
    p.add_argument("--out", metavar="DIR", type=_folder,
                   help="report folder (default: out/compare/<name> under the current folder; "
                        "name: the file's compare.name, else its file name without the suffix)")
    p.add_argument("--update-baseline", action="store_true", help="rewrite the stored baseline from this run")
    p.set_defaults(func=_cmd_compare)


def _cmd_compare(args) -> int:
    main_compare = common._feature("orchestrator.compare", "main_compare", "compare")
    return int(main_compare(args.file, out_dir=args.out, update_baseline=args.update_baseline))
