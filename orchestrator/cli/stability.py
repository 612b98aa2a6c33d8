"""The ``stability`` verb: the linear stability threshold of a scenario's rotor in its bearings
(docs/analysis.md, "Linear stability threshold"), with its options' argument types."""

from __future__ import annotations

import argparse
import math
import signal
import sys
from pathlib import Path

from orchestrator.cli import common
from orchestrator.cli.common import _add_set
from orchestrator.cli.targets import _check_json_target, _check_plot_target
from orchestrator.errors import CosimError

#: speeds of the scan the command suggests over a crossing's bracket that Brent could not refine
BRACKET_SCAN = 8


def _add_stability(sub) -> None:
    p = sub.add_parser("stability", help="linear stability threshold of a scenario's rotor in its bearings",
                       description=(
        "The lowest speed at which the scenario's rotor (our JeffcottRotor or TurbochargerRotor) with the linear "
        "film coefficients of its JournalBearings (or FloatingRingBearings, with the rings' degrees of freedom), "
        "at their static equilibrium under gravity (plus any --load), has an eigenvalue "
        "in the right half plane; the whirl frequency ratio of that mode and each bearing's eccentricity there "
        "(docs/analysis.md, \"Linear stability threshold\"). Exit status 1 when no threshold is located in the "
        "speed range (stable throughout, already unstable at its lower end, unstable from between speeds "
        "without a static equilibrium, or a threshold whose bracket could not be refined: a speed inside it "
        "failed)."))
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
    p.add_argument("--unbalance", action="store_true",
                   help="the threshold WITH the rotor's unbalance: at each speed the rotor's synchronous periodic "
                        "orbit under its unbalance (shooting, the films' nonlinear forces; --film hs or short) and "
                        "the Floquet multipliers along it, the growth rate ln|mu| f in place of the eigenvalue's "
                        "real part; the linear threshold is reported beside it (about 0.15 s a speed for the "
                        "turbocharger at 40 x 40 on a quiet host)")
    p.add_argument("--per-rev", metavar="N", type=_per_rev,
                   help="with --unbalance: integration steps (and monodromy factors) per revolution (default 64)")
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


def _whole_number(lo: int, hi: int, what: str, example: str = ""):
    """An argparse type: a whole number from lo to hi, else the message naming ``what`` it counts
    (and ``example``, e.g. ", e.g. 64")."""
    def parse(text: str) -> int:
        try:
            n = int(text)
        except ValueError:
            n = lo - 1
        if not lo <= n <= hi:
            raise argparse.ArgumentTypeError(f"expected a whole number of {what} from {lo} to {hi}{example} "
                                             f"(got {text!r})")
        return n
    return parse


_scan_count = _whole_number(2, 2000, "speeds")
_per_rev = _whole_number(8, 4096, "steps per revolution", ", e.g. 64")


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
    # one holder of Ctrl-C and SIGTERM from here to the last line of output, never a gap between two
    # (SIGTERM there killed the command without a word, a second Ctrl-C ended in a bare "interrupted"):
    # until the first speed a signal stops at once (nothing to keep), then the search's (stability()),
    # then the output's (written_holding_signals)
    from orchestrator.coupling.lifecycle import RunStopped, StopRequests
    stage = ["loading the scenario"]
    with StopRequests(at_once=True) as requests:
        try:
            r = _computed(args, requests, stage)
        except RunStopped as exc:
            if not requests.at_once:         # past the first speed: the search keeps what it did
                raise
            return _stopped_before_any_speed(args, exc, stage[0])
        from orchestrator.stability.partial import written_holding_signals     # a signal while writing: after it
        return written_holding_signals(lambda: _stability_report(args, r), r, requests)


def _computed(args, requests, stage: list) -> dict:
    """The threshold search of the command's arguments (``requests``: the command's stop requests;
    ``stage``: set to what is being done before the first speed)."""
    from orchestrator.scenario import load_scenario
    from orchestrator.shipped import resolve
    stability = common._feature("orchestrator.stability", "stability", "stability")

    args.file = str(resolve(args.file))
    if args.json:
        _check_json_target(args.json, args.file)     # before the computation (minutes with --film mc)
    if args.plot:
        _check_plot_target(args.plot, args.file)
    if args.json and args.plot and Path(args.json).resolve() == Path(args.plot).resolve():   # the figure replaced it
        raise CosimError(f"--json and --plot name one file ({args.plot}): the figure would replace the report; give "
                         "each its own, e.g. --json stability.json --plot stability.png")
    # the linear threshold does not use analysis.journals.*.clearance: a --set psi is not refused for it
    scenario = load_scenario(args.file, args.set, build_fmus=True)
    stage[0] = "setting up the linear model of the rotor in its bearings"
    loads: dict[str, tuple[float, float]] = {}
    for name, fx, fy in args.load:          # repeated for one bearing: the forces add
        ox, oy = loads.get(name, (0.0, 0.0))
        loads[name] = (ox + fx, oy + fy)
    if args.per_rev is not None and not args.unbalance:
        raise CosimError(f"--per-rev {args.per_rev}: the steps per revolution of the periodic orbit under the "
                         "unbalance; it needs --unbalance (add it, or leave --per-rev out)")
    extra = {"unbalance": True, "n_per_rev": args.per_rev} if args.unbalance else {}
    return stability(scenario, film=args.film, speeds=args.speeds, ring_spin=args.ring_spin, loads=loads,
                     n_scan=args.scan, progress=args.progress, requests=requests, **extra)


def _stopped_before_any_speed(args, exc, stage: str) -> int:
    """A signal before the first speed: one line on stderr (nothing was computed, so nothing is kept
    and no --json or --plot written); the exit code 128 + the signal."""
    name = signal.Signals(exc.signum).name
    head = "interrupted" if name == "SIGINT" else f"terminated by signal {name}"
    files = [f"{option} {out}" for option, out in (("--json", args.json), ("--plot", args.plot)) if out]
    unwritten = f" ({' and '.join(files)} not written)" if files else ""
    print(f"{head} while {stage}: stopped before any speed was computed, nothing to keep{unwritten}",
          file=sys.stderr)
    return exc.exit_code


def _stability_report(args, r: dict) -> int:
    """``rotorcosim stability``'s output of the result ``r`` (stdout, --json, --plot, stderr); the exit code."""
    import json

    from orchestrator.stability.partial import speed_range, widened
    lo, hi = r["speed_range_hz"]
    what = "stability with the unbalance (Floquet)" if r.get("unbalance") else "linear stability"
    print(f"{what} of {r['scenario']} ({args.file}): rotor '{r['rotor']['instance']}' "
          f"({r['rotor']['model']}), {speed_range(lo, hi)} Hz")
    if r.get("unbalance"):
        print(f"method: {r['floquet']['method']}; the films' coefficients and static equilibria of the {r['method']}")
    else:
        print(f"method: eigenvalues of the rotor's linear model with the bearing coefficients of the {r['method']}")
    for note in r["notes"]:
        print(f"note: {note}")
    if r.get("unbalance"):
        _floquet_report(r)
    elif r["status"] == "threshold":
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
    elif r["status"] == "threshold_bracketed" and not r["stopped"]:      # Brent failed in it (a stop: its message)
        a, b = r["threshold_between_hz"]
        print(f"threshold speed: not refined, between {speed_range(a, b, ' and ')} Hz "
              f"({r['threshold_bracket_width_hz']:.3g} Hz wide; an eigenvalue crosses into the right half plane there)")
    _later(r)
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
    if r["status"] == "threshold_bracketed":      # not stopped: Brent gave up on it (the search went on)
        a, b = r["threshold_between_hz"]
        start, end = widened(a, b)
        why = r["crossings_bracketed"][0].get("not_refined") or "not refined"
        print(f"error: the system {'with its unbalance ' if r.get('unbalance') else ''}becomes unstable between "
              f"{speed_range(a, b, ' and ')} Hz, but that crossing is not refined: {why}; `--speeds {start:.10g}:"
              f"{end:.10g} --scan {BRACKET_SCAN}` scans that bracket on a finer grid (a speed that fails there is left "
              "out, and the crossing is refined between the speeds done), or mend what the reason names",
              file=sys.stderr)
        return 1
    if r["status"] == "stable" and r.get("unbalance"):
        print(f"error: the Floquet growth rate along the periodic orbit under the unbalance stays negative between "
              f"{speed_range(lo, hi, ' and ')} Hz: the system with its unbalance is stable in that range; give a "
              "wider --speeds LO:HI", file=sys.stderr)
        return 1
    if r["status"] == "stable":
        print(f"error: no eigenvalue crosses into the right half plane between {speed_range(lo, hi, ' and ')} Hz: the "
              "system is linearly stable in that range; give a wider --speeds LO:HI", file=sys.stderr)
        return 1
    if r["status"] == "threshold_not_located":
        a, b = r["threshold_between_hz"]
        across, fix = (("left out (where a film has no static equilibrium, or whose eigenvalues were not computed: "
                        "the notes say why)", "follow the notes' fix") if r.get("speeds_without_eigenvalues_hz") else
                       ("where a film has no static equilibrium", "bearing parameters that carry the load there"))
        print(f"error: the system becomes unstable between {a:.4g} and {b:.4g} Hz, across speeds {across}, so the "
              f"threshold is not located; give a --speeds LO:HI on one side of them, or {fix}", file=sys.stderr)
        return 1
    if r["status"] == "unstable_at_lower_bound":
        first = r["scan"][0]["speed_hz"] if r.get("scan") else lo
        no_eig = [f for f in r.get("speeds_without_eigenvalues_hz") or [] if f < first]
        if first > lo * (1 + 1e-9) and no_eig:     # some speeds below it left out without eigenvalues
            print(f"error: already unstable at the lowest speed computed ({first:.4g} Hz; the speeds from {lo:g} Hz "
                  "below it were left out: no static equilibrium, or eigenvalues not computed), so the threshold is "
                  "below it or among those speeds (the notes say why they were left out)", file=sys.stderr)
        elif first > lo * (1 + 1e-9):      # the speeds below it left out (no static equilibrium there)
            print(f"error: already unstable at the lowest speed with a static equilibrium ({first:.4g} Hz; the speeds "
                  f"from {lo:g} Hz below it have none), so the threshold is below it or among those speeds (the note "
                  "says why they have none)", file=sys.stderr)
        else:
            print(f"error: already unstable at the lower end of the range ({lo:g} Hz), so the threshold is below it; "
                  "give a lower --speeds LO", file=sys.stderr)
        return 1
    return 0


def _later(r: dict) -> None:
    """The "then ..." lines: the crossings after the threshold (or all, already unstable at the lower
    end), and, for a search not stopped (a stopped one's message names them), the later brackets
    Brent could not refine, with why; in order of speed."""
    from orchestrator.stability import later_crossings
    from orchestrator.stability.partial import speed_range
    lines = [(c["speed_hz"], f"then {c['becomes']} from {c['speed_hz']:.2f} Hz on (the least-damped mode at "
              f"{c['whirl_hz']:.2f} Hz)") for c in later_crossings(r)]
    if not r["stopped"]:
        skip = 1 if r["status"] == "threshold_bracketed" else 0
        lines += [(c["between_hz"][0], f"then {c['becomes']} from between {speed_range(*c['between_hz'], ' and ')} Hz "
                   + (f"(not refined: Brent's step at {c['failed_at_hz']:.6g} Hz failed; the note says why)"
                      if c.get("failed_at_hz") is not None else "(not refined)"))
                  for c in r["crossings_bracketed"][skip:]]
    for _, line in sorted(lines, key=lambda x: x[0]):
        print(line)


def _floquet_report(r: dict) -> None:
    """The --unbalance lines of the report: the threshold with the unbalance, its multiplier and
    orbits, the linear threshold beside it, the cost."""
    fq, lin = r["floquet"], r.get("linear") or {}
    if r["status"] == "threshold_bracketed" and not r["stopped"]:      # Brent failed in it (a stop: its message)
        from orchestrator.stability.partial import speed_range
        a, b = r["threshold_between_hz"]
        print(f"threshold speed with the unbalance: not refined, between {speed_range(a, b, ' and ')} Hz "
              f"({r['threshold_bracket_width_hz']:.3g} Hz wide; a Floquet multiplier leaves the unit circle there)")
    if r["status"] == "threshold":
        mu = fq["threshold_multiplier"]
        print(f"threshold speed with the unbalance: {r['threshold_hz']:.2f} Hz (a Floquet multiplier leaves the unit "
              f"circle: mu = {mu[0]:+.4f}{mu[1]:+.4f}j, {fq['multiplier_kind']})")
        print(f"whirl frequency: {r['whirl_hz']:.2f} Hz (|arg mu| f, modulo the speed), ratio {r['whirl_ratio']:.3f}")
        for name, b in (fq["orbit_at_threshold"] or {}).items():
            print(f"  {name}: synchronous orbit {b['amplitude_x_c']:.4f} x {b['amplitude_y_c']:.4f} c (half peak to "
                  f"peak in x, y), eccentricity ratio up to {b['eps_max']:.3f} (static {b['eps_static']:.3f})")
    if lin.get("threshold_hz") is not None:
        below = (f"; the unbalance moves the threshold by {-fq['below_linear_hz']:+.2f} Hz" if "below_linear_hz" in fq
                 else "")
        print(f"linear threshold (static equilibrium, no unbalance): {lin['threshold_hz']:.2f} Hz (whirl "
              f"{lin['whirl_hz']:.2f} Hz){below}")
    elif lin.get("threshold_between_hz"):        # Brent could not refine it (the search went on)
        from orchestrator.stability.partial import speed_range
        print(f"linear threshold (static equilibrium, no unbalance): not refined, between "
              f"{speed_range(*lin['threshold_between_hz'], ' and ')} Hz ({lin['status']})")
    else:
        print(f"linear threshold (static equilibrium, no unbalance): none located in the range ({lin.get('status')})")
    for s in fq["speeds_without_orbit"][:3]:
        print(f"  no periodic orbit at {s['speed_hz']:.4g} Hz: {s['reason']}")
    if fq["seconds_per_speed"] is not None:
        print(f"{fq['speeds_computed']} periodic orbits, {fq['seconds_per_speed']:.2f} s a speed "
              f"({fq['n_per_rev']} steps per revolution)")
