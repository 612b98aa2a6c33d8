"""Command line interface: ``rotorcosim <verb> ...`` (also ``python -m orchestrator``).

Each verb is registered by its own small ``_add_<verb>`` function (the shape of
PythonFMU's ``create_command_parser``). The CLI parses arguments, calls the
library and formats what comes back; it contains no numerics.

Exit codes: 0 success; 1 a failed run, an invalid scenario or any other error
(one readable message on stderr, no traceback unless ``--debug``); 2 bad
command-line usage (argparse); 130 interrupted; 141 stdout's reader went away (``| head``). ``compare`` returns the exit
code of :func:`orchestrator.compare.main_compare`.

Length: one small ``_add_<verb>`` / ``_cmd_<verb>`` pair per verb (run, validate, info,
build-fmus, plot, compare, scenarios, init, export-ssp, sweep, stability; the quick start is
``run quickstart``, no verb of its own); a file of ~800 lines for that reason, with no logic of its own to split out.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import math
import sys
import time
import warnings
from pathlib import Path
from typing import Callable, Sequence

from orchestrator.errors import CosimError, ScenarioError

PROG = "rotorcosim"


class _Unavailable(CosimError):
    """A verb whose implementing module is not installed (yet)."""


def _feature(module: str, attr: str, verb: str) -> Callable:
    """``module.attr``, imported when a verb needs it; a clear error if it is not there."""
    try:
        mod = importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name == module:
            raise _Unavailable(f"`{PROG} {verb}` is not available in this installation: the module {module} "
                               "is missing; update rotorcosim (pip install -e . in the repository)") from None
        if exc.name and not exc.name.startswith("orchestrator"):
            pkg = exc.name.split(".")[0]
            raise _Unavailable(f"`{PROG} {verb}` needs the Python package '{pkg}', which is not installed; "
                               f"install it (pip install {pkg})") from None
        raise
    func = getattr(mod, attr, None)
    if func is None:
        raise _Unavailable(f"`{PROG} {verb}` is not available in this installation: {module}.{attr} is "
                           "missing; update rotorcosim")
    return func


# --------------------------------------------------------------------------- verbs
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
    from orchestrator.shipped import resolve

    args.file = str(resolve(args.file))
    scenario = load_scenario(args.file, args.set, build_fmus=True)
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
    from orchestrator.shipped import resolve

    args.file = str(resolve(args.file))
    try:
        scenario = load_scenario(args.file, args.set, build_fmus=not args.no_build)
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


def _add_info(sub) -> None:
    p = sub.add_parser("info", help="show an FMU's variables and capability flags")
    p.add_argument("fmu", metavar="FMU", help="FMI 2.0 co-simulation FMU file")
    p.set_defaults(func=_cmd_info)


_CAUSALITY_ORDER = ("parameter", "calculatedParameter", "input", "output", "local", "independent")


def _cmd_info(args) -> int:
    from orchestrator.fmi.archive import cached_model_description as read_model_description

    from orchestrator.untrusted import terminal_text as shown

    md = read_model_description(args.fmu)
    yes = lambda b: "yes" if b else "no"      # noqa: E731
    print(f"FMU: {args.fmu}")
    print(f"model: {shown(md.model_name)} (FMI {md.fmi_version}, co-simulation, modelIdentifier "
          f"{shown(md.model_identifier)})")
    if md.description:                            # the FMU's texts: shown, never acted on by the terminal
        print(f"description: {shown(md.description)}")
    if md.generation_tool:
        print(f"generated by: {shown(md.generation_tool)}")
    print("capabilities:")
    for flag, value in (("canHandleVariableCommunicationStepSize", yes(md.can_handle_variable_step)),
                        ("canInterpolateInputs", yes(md.can_interpolate_inputs)),
                        ("maxOutputDerivativeOrder", md.max_output_derivative_order),
                        ("canGetAndSetFMUstate", yes(md.can_get_and_set_fmu_state)),
                        ("needsExecutionTool", yes(md.needs_execution_tool)),
                        ("canBeInstantiatedOnlyOncePerProcess",
                         yes(md.can_be_instantiated_only_once_per_process))):
        print(f"  {flag}: {value}")
    if md.default_experiment:
        print("default experiment: " + ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v!r} (not a number)"
                                                 for k, v in md.default_experiment.items()))
    for line in _feedthrough_lines(md):
        print(line)
    rank = {c: i for i, c in enumerate(_CAUSALITY_ORDER)}
    variables = sorted(md.variables.values(), key=lambda v: rank.get(v.causality, len(rank)))
    by_ref: dict = {}
    for v in md.variables.values():               # aliases: same type family and value reference
        by_ref.setdefault((_family(v.type), v.value_reference), []).append(v.name)
    rows = [("name", "causality", "variability", "type", "start", "unit", "vr", "declaredType", "range", "nominal",
             "description")]
    for v in variables:
        start = "" if v.start is None else repr(v.start) if isinstance(v.start, str) else f"{v.start}"
        group = by_ref[(_family(v.type), v.value_reference)]     # at most a few names (150 000 aliases: MemoryError)
        aliases = [n for n in group[:_ALIASES_SHOWN + 1] if n != v.name][:_ALIASES_SHOWN]
        more = f" and {len(group) - 1 - len(aliases)} more" if len(group) - 1 > len(aliases) else ""
        desc = (v.description or "") + (f" [alias of {', '.join(aliases)}{more}]" if aliases else "")
        rows.append((v.name, v.causality, v.variability, v.type, shown(start), shown(v.unit or ""),
                     str(v.value_reference), shown(v.declared_type), _range_text(v),
                     "" if v.nominal is None else f"{v.nominal:g}", shown(desc)))
    print(f"variables ({len(variables)}):")
    n = len(rows[0]) - 1
    widths = [max(len(r[i]) for r in rows) for i in range(n)]
    for r in rows:
        print("  " + "  ".join(c.ljust(w) for c, w in zip(r[:n], widths, strict=True)) + "  " + r[n])
    return 0


def _feedthrough_lines(md) -> list[str]:
    """Which inputs each output depends on directly, as ``<ModelStructure><Outputs>`` declares
    it (the dependencies on inputs; nothing when the FMU has no output)."""
    feed = md.direct_feedthrough()
    if not feed:
        return []
    if not md.inputs():
        return ["direct feedthrough: none (the FMU has no inputs)"]
    if all(deps is None for deps in feed.values()):
        return ["direct feedthrough: not declared (ModelStructure/Outputs gives no dependencies: an output may "
                "depend on every input)"]
    if all(deps == () for deps in feed.values()):
        return ["direct feedthrough: none (ModelStructure/Outputs: no output depends directly on an input)"]
    lines = ["direct feedthrough (ModelStructure/Outputs: output <- the inputs it depends on directly):"]
    lines += [f"  {name} <- {', '.join(deps)}" for name, deps in feed.items() if deps]
    for label, names in (("no input", [n for n, d in feed.items() if d == ()]),
                         ("not declared (may depend on every input)", [n for n, d in feed.items() if d is None])):
        if names:
            more = f" and {len(names) - 12} more" if len(names) > 12 else ""
            lines.append(f"  {label}: {', '.join(names[:12])}{more}")
    return lines


_ALIASES_SHOWN = 5    # names listed after "[alias of" in `info`


def _family(fmi_type: str) -> str:
    return "Integer" if fmi_type == "Enumeration" else fmi_type


def _range_text(v) -> str:
    """min/max, or the enumeration items, as declared (empty when nothing is declared)."""
    if v.type == "Enumeration" and v.items:
        return "{" + ", ".join(f"{name}={value}" for name, value, _ in v.items) + "}"
    if v.min is None and v.max is None:
        return ""
    return f"[{'' if v.min is None else v.min}, {'' if v.max is None else v.max}]"


def _add_build_fmus(sub) -> None:
    p = sub.add_parser("build-fmus", help="build rotorcosim's own FMUs (bearing, rotors)")
    p.add_argument("--force", action="store_true", help="rebuild even when up to date")
    p.add_argument("--out", metavar="DIR", type=_folder, help="destination folder, e.g. to hand the FMUs to other tools "
                                                "(default: the repository's fmus/ in a source checkout, else the "
                                                "per-user cache that 'fmu: NAME' in a scenario uses)")
    p.set_defaults(func=_cmd_build_fmus)


def _cmd_build_fmus(args) -> int:
    build_fmus = _feature("orchestrator.fmi.build", "build_fmus", "build-fmus")
    from orchestrator.fmi import build
    logging.getLogger("orchestrator.fmi.build").setLevel(logging.INFO)
    if args.out is None and not build.in_checkout():
        # an installed package: into the per-user cache where `fmu: NAME` finds them (never site-packages)
        for name in build.RECIPES:
            target = build.fmu_location(name)
            print(build_fmus(out_dir=target.parent, force=args.force, names=[name])[0])
        return 0
    for path in build_fmus(out_dir=args.out if args.out is not None else build.FMU_DIR, force=args.force):
        print(path)
    return 0


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
        return _print_paths(_feature("orchestrator.sweep.plot", "plot_sweep", "plot")(run_dir))
    if (run_dir / "report.json").is_file() and (run_dir / "runs").is_dir() and not (
            (run_dir / "results.csv").exists() or (run_dir / "summary.json").exists()):
        return _comparison_folder(run_dir)
    plot_run = _feature("orchestrator.results.plots", "plot_run", "plot")
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
    main_compare = _feature("orchestrator.compare", "main_compare", "compare")
    return int(main_compare(args.file, out_dir=args.out, update_baseline=args.update_baseline))


def _add_sweep(sub) -> None:
    p = sub.add_parser("sweep", help="run a parameter sweep (stability map) on Dask", description=(
        "Run every run of a sweep file (docs/sweeps.md) as a Dask task, in a run process of its worker (not "
        "the worker itself), into DIR/runs/<run_id>/, and write DIR/sweep.csv. Default: a local cluster, one "
        "worker per core."))
    p.add_argument("file", metavar="FILE", help="sweep YAML file")
    p.add_argument("--out", metavar="DIR", type=_folder, help="output folder (default: runs/sweep_<file name>)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="address of a running Dask scheduler, e.g. "
                   "tcp://10.0.0.5:8786 (default: $DASK_SCHEDULER_ADDRESS, else a local cluster)")
    p.add_argument("--workers", metavar="N", type=int, help="runs at once on the local cluster: its workers, "
                   "threads of this process, each running its runs in a run process of its own (default: one "
                   "per core)")
    p.add_argument("--resume", action="store_true", help="skip runs whose folder holds a finished summary")
    p.add_argument("--no-progress", action="store_true", help="no progress bar (on a terminal) and no line per "
                   "run done (otherwise)")
    p.add_argument("--fresh-processes", action="store_true", help="a new Python process for every run instead "
                   "of one warm run process per worker that runs many (slower; docs/sweeps.md section 2)")
    p.set_defaults(func=_cmd_sweep)


def _cmd_sweep(args) -> int:
    from orchestrator.sweep import default_out_dir, load_sweep
    from orchestrator.sweep.plan import PROGRESS_FROM_RUNS, count_runs, plan_sweep
    from orchestrator.sweep.runner import check_cluster_options, run_sweep

    check_cluster_options(args.scheduler, args.workers)   # before validating every run (1-2 min for 10 000)
    spec = load_sweep(args.file)
    n = count_runs(spec)                               # refuses too many runs before expanding any
    if n >= PROGRESS_FROM_RUNS:                        # 5-12 ms per run: say why nothing runs yet
        print(f"sweep {args.file}: validating the scenario of each of its {n} runs before the first starts",
              file=sys.stderr, flush=True)
    runs = plan_sweep(spec, progress=False if args.no_progress else None)
    out = Path(args.out) if args.out else default_out_dir(args.file)
    print(f"sweep {args.file}: {len(runs)} runs of {spec.scenario.name} ({spec.mode}) -> {out}", flush=True)
    o = run_sweep(spec, runs, out, scheduler=args.scheduler, workers=args.workers, resume=args.resume,
                  progress=False if args.no_progress else None, warm=not args.fresh_processes)
    counts = {s: sum(r["status"] == s for r in o.rows) for s in dict.fromkeys(r["status"] for r in o.rows)}
    print(f"table: {o.table}" + (f" ({o.skipped} runs resumed)" if o.skipped else ""))
    print("runs: " + ", ".join(f"{n} {s}" for s, n in counts.items()))
    if spec.collect and not o.interrupted:
        print(f"maps: `{PROG} plot {out}` draws each collected value over the parameters")
    for r in o.rows:
        if r["status"] != "finished" and (r["status"] != "cancelled" or not r["message"].startswith("not run")):
            print(f"  {r['run_id']} {r['status']}: {r['message']}", file=sys.stderr)
    if o.interrupted:
        term = o.stopped_by == "SIGTERM"
        print(f"{'terminated by signal SIGTERM' if term else 'interrupted'}: pending runs cancelled, finished "
              f"runs kept; continue with `{PROG} sweep {args.file} --out {out} --resume`", file=sys.stderr)
        return 143 if term else 130
    return 0 if counts.get("finished", 0) == len(o.rows) else 1


def _add_set(p) -> None:
    p.add_argument("--set", metavar="KEY=VALUE", action="append", default=[],
                   help="override a scenario value, e.g. --set coupling.macro_step=5e-5 (repeatable)")


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


def _add_export_ssp(sub) -> None:
    p = sub.add_parser("export-ssp", help="write a scenario as an SSP 1.0 archive (runs in libcosim; what SSP "
                                          "has no element for travels in an org.rotorcosim.scenario annotation)")
    p.add_argument("file", metavar="SCENARIO", help="scenario YAML file (or a shipped scenario's name)")
    p.add_argument("out", metavar="OUT.ssp", help="archive to write: a new file in an existing folder, or an "
                                                  "earlier .ssp archive to replace")
    _add_set(p)
    p.set_defaults(func=_cmd_export_ssp)


def _cmd_export_ssp(args) -> int:
    from orchestrator.scenario import load_scenario
    from orchestrator.shipped import resolve
    from orchestrator.scenario.ssp import check_output_path, export_ssp

    check_output_path(args.out)          # before loading (and maybe building FMUs): a bad OUT fails at once
    scenario = load_scenario(str(resolve(args.file)), args.set, build_fmus=True)
    print(export_ssp(scenario, args.out))
    return 0


def _add_stability(sub) -> None:
    p = sub.add_parser("stability", help="linear stability threshold of a scenario's rotor in its bearings",
                       description=(
        "The lowest speed at which the scenario's rotor (our JeffcottRotor or TurbochargerRotor) with the linear "
        "film coefficients of its JournalBearings (or FloatingRingBearings, with the rings' degrees of freedom), "
        "at their static equilibrium under gravity (plus any --load), has an eigenvalue "
        "in the right half plane; the whirl frequency ratio of that mode and each bearing's eccentricity there "
        "(docs/analysis.md, \"Linear stability threshold\"). Exit status 1 when no threshold is located in the "
        "speed range (stable throughout, already unstable at its lower end, or unstable from between speeds "
        "without a static equilibrium)."))
    p.add_argument("file", metavar="FILE", help="scenario YAML file, or the name of a shipped scenario")
    _add_set(p)
    p.add_argument("--film", choices=("short", "hs", "mc"), default="hs",
                   help="bearing coefficients: hs = each bearing's own finite-length half-Sommerfeld film on its "
                        "grid (default); short = the short-bearing (Ocvirk) closed form; mc = each mass-conserving "
                        "bearing's own film with its cavity dynamics (film impedance; its least-damped eigenvalue "
                        "counted by the argument principle, about 0.5 s a speed at 40 x 40)")
    p.add_argument("--scan", metavar="N", type=_scan_count,
                   help="number of speeds of the scan over the range before the crossings are refined "
                        "(default 80)")
    p.add_argument("--speeds", metavar="LO:HI", type=_speed_range,
                   help="speed range [Hz] searched (default: 0.1 f_max : f_max of the rotor's ramp)")
    p.add_argument("--load", metavar="BEARING=FX,FY", action="append", default=[], type=_bearing_load,
                   help="a static force [N] on that bearing instance in addition to its share of the rotor's weight "
                        "(the force the rotor puts on it, down is -y: a gear or belt force, a magnetic pull, a "
                        "horizontal rotor with g = 0), e.g. --load bearing1=0,-150 (repeatable)")
    p.add_argument("--ring-spin", action="store_true",
                   help="floating-ring bearings: add each ring's spin perturbation to the linear model (default: the "
                        "ring spin held at its steady value, as the classical analyses do)")
    p.add_argument("--json", metavar="OUT", type=_json_path, help="also write the result as JSON to this file")
    p.add_argument("--plot", metavar="PNG", type=_figure_path,
                   help="also draw the least-damped mode's logarithmic decrement and frequency over the speeds "
                        "searched into this PNG file")
    p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="show the scan's progress (default: when stderr is a terminal and it takes a few seconds)")
    p.set_defaults(func=_cmd_stability)


def _speed_range(text: str) -> tuple[float, float]:
    lo, sep, hi = text.partition(":")
    try:
        a, b = float(lo), float(hi)
    except ValueError:
        a = b = math.nan
    if not sep or not (0.0 < a < b < math.inf):
        raise argparse.ArgumentTypeError(f"expected LO:HI in Hz with 0 < LO < HI, e.g. 50:800 (got {text!r})")
    return a, b


def _json_path(text: str) -> str:
    """``--json OUT``: not empty (``--json ''`` wrote nothing and said nothing, exit 0)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty file name: give the JSON file to write, e.g. --json "
                                         "stability.json, or leave --json out")
    return text


def _check_json_target(out: str, scenario_file: str) -> None:
    """``stability --json OUT`` replaces OUT only when it is an earlier JSON report (or empty, or a
    link, which is replaced, not written through): ``--json s.yaml`` replaced the scenario itself
    with the report. A folder, FIFO or device is refused when the report is written."""
    import os
    import stat

    from orchestrator.untrusted import InputError, load_json
    try:
        st = os.lstat(out)
    except OSError:                       # a new name: the write names a missing folder
        return
    if not stat.S_ISREG(st.st_mode) or st.st_size == 0:
        return
    why = None
    if os.path.samefile(out, scenario_file):
        why = "it is the scenario file"
    else:
        try:
            old = load_json(out, what="file")
        except InputError:
            old, why = None, "it does not read as JSON, e.g. a scenario or a results file"
        if why is None and not (isinstance(old, dict) and {"film", "speed_range_hz", "status"} <= set(old)):
            why = "it is JSON of something else, e.g. a run's summary.json"
    if why:
        raise CosimError(f"{out}: exists and is not a stability report ({why}); --json replaces only an earlier "
                         f"report of `stability --json` (or an empty file): give a new name, e.g. "
                         f"{Path(out).with_suffix('.json') if Path(out).suffix != '.json' else 'stability.json'}"
                         ", or remove the file first")


# the first bytes of a figure file matplotlib writes, by suffix (others are not checked)
_FIGURE_MAGIC = {"png": (b"\x89PNG\r\n\x1a\n",), "pdf": (b"%PDF",), "svg": (b"<?xml", b"<svg"),
                 "eps": (b"%!PS",), "ps": (b"%!PS",), "jpg": (b"\xff\xd8\xff",), "jpeg": (b"\xff\xd8\xff",),
                 "tif": (b"II*\x00", b"MM\x00*"), "tiff": (b"II*\x00", b"MM\x00*"), "webp": (b"RIFF",)}


def _check_plot_target(out: str, scenario_file: str) -> None:
    """``stability --plot OUT`` replaces OUT only when it is an earlier figure of its suffix's format (or
    empty, or a link, which is replaced): ``--plot s.yaml.png`` is fine, ``--plot s.yaml`` is refused by
    its missing suffix, and ``--plot notes.png`` naming a text file is refused here, before the computation."""
    import os
    import stat
    try:
        st = os.lstat(out)
    except OSError:
        return
    if not stat.S_ISREG(st.st_mode) or st.st_size == 0:
        return
    why = None
    if os.path.samefile(out, scenario_file):
        why = "it is the scenario file"
    else:
        suffix = Path(out).suffix.lower().lstrip(".")
        magic = _FIGURE_MAGIC.get(suffix)
        if magic:
            with open(out, "rb") as fh:
                head = fh.read(16)
            if not head.startswith(magic):
                why = f"its content is not a .{suffix} figure"
    if why:
        raise CosimError(f"{out}: exists and is not a figure ({why}); --plot replaces only an earlier figure "
                         "(or an empty file): give a new name, e.g. stability.png, or remove the file first")


def _figure_path(text: str) -> str:
    """A figure file whose suffix matplotlib can write (a name without one is refused); checked before the computation
    (``--plot x.xyz`` ended, after it, in "internal error: ValueError: Format 'xyz' is not supported";
    ``--plot ''`` drew nothing and said nothing)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty file name: give the figure to write, e.g. --plot "
                                         "stability.png, or leave --plot out")
    from matplotlib.backend_bases import FigureCanvasBase
    suffix = Path(text).suffix.lower().lstrip(".")
    formats = FigureCanvasBase.get_supported_filetypes()
    if not suffix:          # a PNG was written under that very name, over whatever file had it
        raise argparse.ArgumentTypeError(f"{text!r}: no suffix; give the figure's format as its suffix, e.g. --plot "
                                         f"{Path(text).name or 'stability'}.png")
    if suffix not in formats:
        raise argparse.ArgumentTypeError(f"{text!r}: a figure cannot be written as '.{suffix}'; give a .png file (or "
                                         f"one of .{', .'.join(sorted(formats))})")
    return text


def _scan_count(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
    if not 2 <= n <= 2000:
        raise argparse.ArgumentTypeError(f"expected a whole number of speeds from 2 to 2000 (got {text!r})")
    return n


def _bearing_load(text: str) -> tuple[str, float, float]:
    name, sep, value = text.partition("=")
    parts = value.split(",")
    try:
        fx, fy = (float(v) for v in parts)
    except ValueError:
        fx = fy = math.nan
    if not sep or not name.strip() or not (math.isfinite(fx) and math.isfinite(fy)):
        raise argparse.ArgumentTypeError("expected BEARING=FX,FY with the bearing instance and two finite forces in "
                                         f"N, e.g. bearing1=0,-150 (got {text!r})")
    return name.strip(), fx, fy


def _cmd_stability(args) -> int:
    import json

    from orchestrator.scenario import load_scenario
    from orchestrator.shipped import resolve
    stability = _feature("orchestrator.stability", "stability", "stability")

    args.file = str(resolve(args.file))
    if args.json:
        _check_json_target(args.json, args.file)     # before the computation (minutes with --film mc)
    if args.plot:
        _check_plot_target(args.plot, args.file)
    # the linear threshold does not use analysis.journals.*.clearance: a --set psi is not refused for it
    scenario = load_scenario(args.file, args.set, build_fmus=True, analysis_used=False)
    loads: dict[str, tuple[float, float]] = {}
    for name, fx, fy in args.load:          # repeated for one bearing: the forces add
        ox, oy = loads.get(name, (0.0, 0.0))
        loads[name] = (ox + fx, oy + fy)
    r = stability(scenario, film=args.film, speeds=args.speeds, ring_spin=args.ring_spin, loads=loads,
                  n_scan=args.scan, progress=args.progress)
    lo, hi = r["speed_range_hz"]
    print(f"linear stability of {r['scenario']} ({args.file}): rotor '{r['rotor']['instance']}' "
          f"({r['rotor']['model']}), {lo:g} - {hi:g} Hz")
    print(f"method: eigenvalues of the rotor's linear model with the bearing coefficients of the {r['method']}")
    for note in r["notes"]:
        print(f"note: {note}")
    if r["status"] == "threshold":
        print(f"threshold speed: {r['threshold_hz']:.2f} Hz (an eigenvalue crosses into the right half plane)")
        print(f"whirl frequency: {r['whirl_hz']:.2f} Hz, whirl frequency ratio {r['whirl_ratio']:.3f}")
        for name, b in r["bearings"].items():
            if b["eps_at_threshold"] is None:         # a search stopped before (r["stopped"])
                continue
            ring = ("" if b["kind"] != "floating_ring" else
                    f", outer film {b['eps_outer_at_threshold']:.3f}, ring speed "
                    f"{b['ring_speed_ratio_at_threshold']:.3f} x journal speed")
            print(f"  {name} (station {b['station']}): static eccentricity ratio {b['eps_at_threshold']:.3f} at the "
                  f"threshold{ring}, load {b['load_n']:.4g} N")
    from orchestrator.stability import later_crossings
    for c in later_crossings(r):
        print(f"then {c['becomes']} from {c['speed_hz']:.2f} Hz on (the least-damped mode at {c['whirl_hz']:.2f} Hz)")
    if r["stopped"]:                        # Ctrl-C, SIGTERM, an error at one speed: what was done
        from orchestrator.stability.partial import scan_table, stop_message
        print(scan_table(r))
    if args.json:
        from orchestrator.results.safe_write import write_report_file
        write_report_file(args.json, json.dumps(r, indent=2) + "\n")   # as compare/sweep: atomic, disk full named
        print(f"written: {args.json}")
    if args.plot:
        from orchestrator.results.plots.stability import draw
        print(f"written: {draw(r, args.plot)}")
    if r["stopped"]:
        print(stop_message(r, kept=[f for f in (args.json, args.plot) if f]), file=sys.stderr)
        return r["stopped"]["exit_code"]
    if r["status"] == "stable":
        print(f"error: no eigenvalue crosses into the right half plane between {lo:g} and {hi:g} Hz: the system is "
              "linearly stable in that range; give a wider --speeds LO:HI", file=sys.stderr)
        return 1
    if r["status"] == "threshold_not_located":
        a, b = r["threshold_between_hz"]
        print(f"error: the system becomes unstable between {a:.4g} and {b:.4g} Hz, across speeds where a film has no "
              "static equilibrium, so the threshold is not located; give a --speeds LO:HI on one side of them, or "
              "bearing parameters that carry the load there", file=sys.stderr)
        return 1
    if r["status"] == "unstable_at_lower_bound":
        print(f"error: already unstable at the lower end of the range ({lo:g} Hz), so the threshold is below it; "
              "give a lower --speeds LO", file=sys.stderr)
        return 1
    return 0


VERBS = (_add_run, _add_validate, _add_info, _add_build_fmus, _add_plot, _add_compare, _add_scenarios, _add_init,
         _add_export_ssp, _add_sweep, _add_stability)


# --------------------------------------------------------------------------- entry point
def build_parser() -> argparse.ArgumentParser:
    # --debug before the verb and after it: two destinations (a sub-parser's defaults would
    # overwrite the value given before the verb), joined in main()
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--debug", action="store_true", dest="debug_verb",
                        help="show debug logging and full tracebacks")
    parser = argparse.ArgumentParser(prog=PROG, description=(
        "Co-simulation of FMI 2.0 co-simulation FMUs (rotors in journal bearings and any other FMUs)."))
    parser.add_argument("--debug", action="store_true", help="show debug logging and full tracebacks")
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = parser.add_subparsers(dest="verb", metavar="VERB", required=True)
    orig = sub.add_parser

    def add_parser(name, **kw):                  # every verb also takes --debug after the verb
        return orig(name, parents=[common], **kw)

    sub.add_parser = add_parser
    for add in VERBS:
        add(sub)
    for verb in sub.choices.values():            # a value option given twice is refused, not overwritten
        for action in verb._actions:
            if type(action) is argparse._StoreAction and action.option_strings:
                action.__class__ = _StoreOnce
    return parser


class _StoreOnce(argparse._StoreAction):
    """An option that takes one value (``--out DIR``): given twice, argparse kept the last one
    silently (``--out A --out B`` wrote to B); now it is a usage error naming both."""

    def __call__(self, parser, namespace, values, option_string=None):
        seen = namespace.__dict__.setdefault("_given_once", {})
        if self.dest in seen:
            raise argparse.ArgumentError(
                self, f"given twice ({seen[self.dest]!r}, then {values!r}); give it once")
        seen[self.dest] = values
        super().__call__(parser, namespace, values, option_string)


def _version() -> str:
    try:
        from importlib.metadata import version
        return version("rotorcosim")
    except Exception:                             # not installed (running from a source tree)
        return "unknown"


import errno as _errno

#: what to do about the operating system's errors that bad paths give (``--out`` a file, a
#: folder without write permission, ...), added to their one-line message
_OS_FIXES = {
    _errno.EEXIST: "a file of that name is in the way where a folder is needed: remove it or choose another name",
    _errno.ENOTDIR: "a part of that path is a file, not a folder: choose another path",
    _errno.EISDIR: "that is a folder where a file is needed: choose a file name",
    _errno.ENOENT: "no such file or folder: check the path (relative paths start in the current folder)",
    _errno.EACCES: "permission denied: choose a place you can write to, or change its permissions",
    _errno.EPERM: "operation not permitted: choose a place you own",
    _errno.EROFS: "that file system is read-only: choose another place",
    _errno.ENOSPC: "the disk is full: free some space or choose another place",
    _errno.EDQUOT: "your disk quota is used up: free some of it or choose another place",
    _errno.ENAMETOOLONG: "the name is too long: choose a shorter one",
}


def _folder(value: str) -> str:
    """argparse type of the ``--out DIR`` options: not empty (an empty one silently meant the
    default folder)."""
    if not value.strip():
        raise argparse.ArgumentTypeError("an empty folder name: give a folder, or leave --out out "
                                         "for the default")
    return value


def _init_folder(value: str) -> str:
    """argparse type of ``init DIR``: not empty (an empty one filled the current folder and
    suggested `rotorcosim run /X.yaml`)."""
    if not value.strip():
        raise argparse.ArgumentTypeError("an empty folder name: give the folder to copy the scenarios into, "
                                         "e.g. `rotorcosim init my-scenarios` (or `.` for this folder)")
    return value


def _memory_limit() -> str:
    """'this process may use at most N MiB of memory (`ulimit -v`)' when such a limit is set, else ''."""
    try:
        import resource
        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
    except (ImportError, OSError, ValueError):     # pragma: no cover - not POSIX
        return ""
    if soft == resource.RLIM_INFINITY:
        return ""
    return f"this process may use at most {soft / 2**20:.0f} MiB of memory (`ulimit -v`): raise that limit"


def _describe(exc: BaseException) -> str:
    if isinstance(exc, CosimError):
        return f"error: {exc}"
    if isinstance(exc, MemoryError):
        # was "internal error: MemoryError ... this is a bug in rotorcosim"
        limit = _memory_limit()
        return ("error: out of memory" + (f" ({exc})" if str(exc) else "") + "; "
                + (limit if limit else "free memory (close other programs) or run a smaller case (a coarser "
                   "film grid, fewer recorded signals)"))
    if isinstance(exc, OSError):
        where = f"{exc.filename}: " if exc.filename else ""
        fix = _OS_FIXES.get(exc.errno, "")
        limit = _memory_limit()
        if not fix and limit and any(w in str(exc) for w in ("shared object", "map segment", "allocate memory")):
            # a library that cannot be mapped under a memory limit: llvmlite says "Could not find/load
            # shared object file 'libllvmlite.so' ... cannot be found, or the permissions are incorrect"
            fix = f"if the file is there, {limit}"
        return f"error: {where}{exc.strerror or exc}" + (f"; {fix}" if fix else "")
    import yaml
    if isinstance(exc, yaml.YAMLError):
        return f"error: malformed YAML: {exc}"
    return (f"internal error: {type(exc).__name__}: {exc}\n"
            f"(this is a bug in rotorcosim: rerun with --debug for the traceback and report it)")


def _clean_warnings(debug: bool):
    """Format warnings as one line, ``warning: message`` (with ``--debug``: also where from);
    returns the previous ``warnings.formatwarning``. (Only the format is replaced, so
    recording warnings, as ``pytest.warns`` does, still works.)"""
    from orchestrator.untrusted import terminal_text

    def one_line(message, category, filename, lineno, line=None):
        # warnings quote files and FMUs (a summary.json, a signal name): nothing in them drives the terminal
        text = terminal_text(" ".join(str(message).split()))
        where = f" ({filename}:{lineno}, {category.__name__})" if debug else ""
        return f"warning: {text}{where}\n"

    previous = warnings.formatwarning
    warnings.formatwarning = one_line
    return previous


#: exit status when the reader of stdout went away (``rotorcosim scenarios | head -1``): 128 + SIGPIPE,
#: what a shell reports for a command that a closed pipe stopped
EXIT_STDOUT_CLOSED = 141


def _stdout_closed() -> bool:
    """True when stdout is a pipe or socket whose reader has gone (poll reports an error or a
    hang-up on it; a failed write need not leave anything to flush, so flushing again tells
    nothing); then stdout is pointed at os.devnull, so that the interpreter's final flush does
    not fail again (Python's signal module documentation, "Note on SIGPIPE"). False when that
    cannot be told (no poll, no file descriptor): the error is then reported as any other."""
    import os
    import select
    try:
        fd = sys.stdout.fileno()
        poller = select.poll()
        poller.register(fd, select.POLLOUT)
        events = poller.poll(0)
    except (AttributeError, OSError, ValueError):
        return False
    if not any(ev & (select.POLLERR | select.POLLHUP) for _, ev in events):
        return False
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, fd)
        os.close(devnull)
    except OSError:
        pass
    return True


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI with ``argv`` (default: ``sys.argv[1:]``); return the exit code."""
    args = build_parser().parse_args(argv)
    args.debug = bool(args.debug or getattr(args, "debug_verb", False))
    previous = _clean_warnings(args.debug)
    logging.basicConfig(level=logging.DEBUG if args.debug else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    if not args.debug:
        logging.getLogger("orchestrator.fmi.build").setLevel(logging.INFO)   # say when FMUs are being built
    try:
        return int(args.func(args) or 0)
    except BrokenPipeError:
        if not _stdout_closed():                  # another pipe (a worker's): a failure like any other
            if args.debug:
                raise
            print(_describe(sys.exc_info()[1]), file=sys.stderr)
            return 1
        return EXIT_STDOUT_CLOSED                 # `| head`: nobody reads the rest; no message, no flush error
    except KeyboardInterrupt as exc:           # Ctrl-C (130) or SIGTERM (143): RunStopped.exit_code
        code = getattr(exc, "exit_code", 130)
        print("interrupted" if code == 130 else f"terminated by signal {exc}", file=sys.stderr)
        return code
    except Exception as exc:                      # every failure becomes one message (traceback: --debug)
        if args.debug:
            raise
        print(_describe(exc), file=sys.stderr)
        return 1
    finally:
        warnings.formatwarning = previous


def console_main() -> None:
    """Entry point of the ``rotorcosim`` command and ``python -m orchestrator``: :func:`main`, then exit.

    When this process loaded an FMU's shared library in-process (any ``isolation: none`` FMU,
    which is the default), it leaves through ``os._exit`` after running the ``atexit``
    handlers (multiprocessing's, which stop worker processes; the temporary folders') and
    flushing the output and the logs, instead of the interpreter's teardown. Why: the
    teardown frees the Python objects of PythonFMU-built FMUs (ours are), and PythonFMU
    0.7.0 aborts there intermittently with glibc's "corrupted double-linked list"
    (SIGABRT, exit 134) although the run has finished and every file is closed: seen in
    compare worker processes (4 of 7 runs of compare/ci_jeffcott_mc.yaml, which leave the
    same way, orchestrator/compare/__main__.py) and once in CI's ``rotorcosim validate`` of a
    shipped scenario (1 in about 170 processes). A crash during a run still shows as one.
    """
    exit_process(main())


def exit_process(code: int) -> None:
    """Leave the process with ``code``: ``sys.exit`` when no FMU library was loaded in-process,
    else ``os._exit`` after the ``atexit`` handlers and flushing the output and the logs (why:
    :func:`console_main`). The test suite leaves the same way (tests/exit_plugin.py)."""
    subsystem = sys.modules.get("orchestrator.fmi.subsystem")
    if subsystem is None or not subsystem.native_fmu_loaded:
        sys.exit(code)
    import atexit
    import os
    try:
        atexit._run_exitfuncs()
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:   # a closed pipe: nothing more can be said
                pass
        logging.shutdown()
        os._exit(code)

