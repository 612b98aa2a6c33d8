"""Checks of a parsed scenario against its FMUs' model descriptions.

:class:`FmuChecks` is mixed into the loader (it reports through ``self.err``): every
parameter, connection end, output signal and analysis signal must name a variable
of the right causality and type in a readable FMU.
"""

from __future__ import annotations

import logging
import math

import yaml

from orchestrator.errors import CosimError
from orchestrator.fmi.archive import cached_model_description
from orchestrator.scenario.coupling_sections import (check_atol_patterns, check_capabilities, check_until,
                                                       interpolated_inputs, interpolation_warning)
from orchestrator.fmi.values import check_value, declared_range, settable_problem
from orchestrator.scenario.analysis_clearance import complete_analysis_clearance
from orchestrator.scenario.analysis_sampling import check_analysis_sampling
from orchestrator.scenario.completion import Completion
from orchestrator.scenario.model import ANALYSIS_KEYS, JOURNAL_KEYS
from orchestrator.scenario.nodes import FLOAT_RE, article, did_you_mean, ranked, yaml_float

log = logging.getLogger(__name__)


_WARNED: set[str] = set()

#: the film grids (n_phi, n_z) of our bearing FMUs, by model name (bearing_fmu/journal_bearing.py,
#: floating_ring_bearing.py), whose cells are bounded by bearing_fmu.limits.MAX_FILM_CELLS
FILM_GRIDS = {"JournalBearing": (("n_phi", "n_z"),),
              "FloatingRingBearing": (("n_phi_inner", "n_z_inner"), ("n_phi_outer", "n_z_outer"))}


#: the loader's warning for ``scheme: iterative`` with ``interpolation_order: 0`` (docs/coupling.md,
#: "Iterative coupling"; measured in docs/runups.md, "The contact phase")
ITERATIVE_HELD_WARNING = (
    "'coupling.interpolation_order' 0 under scheme iterative: every input is held at its end-of-step "
    "iterate over the whole step, an implicit-Euler-like coupling of first order that damps oscillations "
    "(the Jeffcott run-up from rest: whirl onset 440 Hz against 359-373 Hz with order 1 or the explicit "
    "schemes; on the stiff two-mass oscillator unstable); set interpolation_order: 1 (the line through "
    "the iterate, second order)")


def warn_once(text: str) -> None:
    """A loader warning, once per process (a sweep loads its scenario once per run)."""
    if text not in _WARNED and len(_WARNED) < 10_000:
        _WARNED.add(text)
        log.warning("%s", text)


class FmuChecks(Completion):
    """Checks against the FMUs (a mixin of :class:`orchestrator.scenario.loader.ScenarioLoader`)."""

    mds: dict

    def check_draft(self, draft) -> dict | None:
        """Read every FMU of ``draft`` and check it; the checked parameters per instance.

        Also completes the draft from the FMUs: DefaultExperiment values the scenario omits
        (``draft.kw["defaults"]`` says which), array connections element by element and
        ``output.signals`` patterns expanded."""
        self.mds = {}
        self.fmu_caps = {}
        self.des = {}
        self.fixed_step = []
        for f in draft.fmus:
            self.read_fmu(f)
        draft.kw["defaults"] = self.apply_defaults(draft)
        self.check_fixed_step(draft)
        check_until(self, draft.coupling_node, draft.coupling, draft.kw.get("start_time"), draft.kw.get("stop_time"),
                    draft.interval)
        params = {f["name"]: self.check_parameters(f) for f in draft.fmus}
        self.check_film_grids(draft.fmus, params)
        draft.connections = self.expand_arrays(draft.connections)
        self.check_connections(draft.connections)
        check_atol_patterns(self, draft.coupling, draft.connections)
        if len(self.fmu_caps) == len(draft.fmus):
            check_capabilities(self, draft.coupling_node, draft.coupling, self.fmu_caps)
        self.check_interpolation_order(draft)
        draft.signals = self.expand_patterns(draft.signals)
        self.check_signals(draft.signals, "output.signals")
        if getattr(draft, "output_format", "csv") == "csv":
            self.check_row_width(draft)
        if draft.analysis_node is not None and isinstance(draft.kw.get("analysis"), dict):
            self.check_analysis(draft.analysis_node, draft.signals)
            draft.kw["analysis_origins"] = self.key_origins(draft.analysis_node, "analysis")
            complete_analysis_clearance(self, draft, params)
            check_analysis_sampling(self, draft, params, warn_once)
        return params

    def read_fmu(self, f: dict) -> None:
        name, path = f["name"], f["path"]
        if path is None:
            return
        node = f["path_node"]
        try:
            exists = path.exists()
        except (OSError, ValueError) as exc:           # e.g. a name too long for the file system
            self.err(node, f"FMU path of '{name}' cannot be used: {path}: {exc}; fix 'fmus.{name}.path'")
            return
        if not exists and f.get("ours"):
            self.err(node, f"our FMU {f['ours']} of '{name}' is not built yet ({path}); build it with "
                           "`rotorcosim build-fmus` (or run/validate without --no-build; in Python: "
                           "load_scenario(..., build_fmus=True))")
            return
        if not exists:
            self.err(node, f"FMU file of '{name}' not found: {path} (paths are relative to the scenario's "
                           f"folder {self.path.parent.resolve()}); fix 'fmus.{name}.path', or build our FMUs "
                           "with `rotorcosim build-fmus`")
            return
        try:
            md = cached_model_description(path)
        except CosimError as exc:                      # unreadable, unsafe, not FMI 2.0 CS
            self.err(node, f"FMU of '{name}' cannot be used: {exc}")
            return
        except Exception as exc:                        # an unexpected failure is still a problem of the file
            self.err(node, f"FMU of '{name}' cannot be read: {path}: {type(exc).__name__}: {exc}; check that it "
                           "is an FMI 2.0 co-simulation FMU (`rotorcosim info FILE` shows what it contains)")
            return
        self.mds[name] = dict(md.variables)
        self.fmu_caps[name] = md
        self.des[name] = dict(md.default_experiment)
        if not md.can_handle_variable_step:
            self.fixed_step.append(name)
        if md.can_be_instantiated_only_once_per_process:
            # one instance in the master's process; instances in worker processes have a process each
            iso = getattr(self, "default_isolation", "none")
            users = [g["name"] for g in self.fmu_specs if g["path"] == path and (g["isolation"] or iso) == "none"]
            if len(users) > 1 and name in users[1:]:
                self.err(node, f"FMU {path.name} declares canBeInstantiatedOnlyOncePerProcess, but instances "
                               f"{', '.join(users)} all use it in the master's process; use it for one instance "
                               "only, or give the others 'isolation: process' (a worker process each)")

    def check_parameters(self, f: dict) -> dict:
        name, out = f["name"], {}
        variables = self.mds.get(name)
        settable = None                                # once per FMU (not per parameter: 200k variables)
        for pname, (value, node) in f["parameters"].items():
            if variables is None:
                out[pname] = value
                continue
            if settable is None:
                settable = [v.name for v in variables.values() if settable_problem(v) is None]
            var = variables.get(pname)
            if var is None:
                self.err(node, f"'{name}' has no parameter '{pname}'; parameters of '{name}' (closest first): "
                               f"{ranked(pname, settable)}")
                continue
            why = settable_problem(var)
            if why is not None:
                self.err(node, f"'{name}.{pname}' is {article(var.variability)} {var.causality}, not a parameter, "
                               f"and cannot be given a value before initialization: it is {why}; variables that "
                               f"can (closest first): {ranked(pname, settable)}")
                continue
            conv = convert(value, var.type) if var.type != "Enumeration" or not isinstance(value, str) else value
            if conv is None:
                example = {"Real": "1.5", "Integer": "3", "Enumeration": "1", "Boolean": "true",
                           "String": '"text"'}.get(var.type, "a value")
                self.err(node, f"parameter '{name}.{pname}' is {var.type} (got {self.got(node)}); write "
                               f"{article(var.type)} value such as {example}")
                continue
            conv, problem = check_value(var, conv, f"{name}.{pname}")
            if problem is not None:
                self.err(node, f"parameter {problem}")
                continue
            out[pname] = conv
        return out

    def check_film_grids(self, fmus: list[dict], params: dict) -> None:
        """Our bearings' film grids within :data:`bearing_fmu.limits.MAX_FILM_CELLS` cells: the product
        n_phi x n_z, which modelDescription.xml cannot declare (each factor's range it does), of the
        scenario's values (a ``--set`` included) and the FMU's defaults for the factor not given. It
        was found only when the FMU started (BearingParams), without the scenario's line."""
        from bearing_fmu.limits import MAX_FILM_CELLS
        for f in fmus:
            name, md, variables = f["name"], self.fmu_caps.get(f["name"]), self.mds.get(f["name"])
            if md is None or variables is None:
                continue
            given = f["parameters"]
            for pair in FILM_GRIDS.get(md.model_name, ()):
                if any(p in given and p not in params.get(name, {}) for p in pair):
                    continue                                    # refused by the parameter checks
                values = [params[name][p] if p in given else getattr(variables.get(p), "start", None) for p in pair]
                if not all(isinstance(v, int) and not isinstance(v, bool) for v in values) or not any(
                        p in given for p in pair):
                    continue                                    # not ours after all, or the FMU's own defaults
                n_phi, n_z = values
                if n_phi * n_z <= MAX_FILM_CELLS:
                    continue
                written = [p for p in pair if p in given and id(given[p][1]) not in self.origins]
                node = given[written[0]][1] if written else f.get("node")
                where = []
                for p, v in zip(pair, values):
                    if p not in given:
                        where.append(f"{p} = {v} is the FMU's default")
                    elif p not in written:
                        where.append(f"{p} from {self.loc(given[p][1])}")
                    elif p != written[0]:
                        where.append(f"{p} at {self.loc(given[p][1])}")
                self.err(node, f"fmus.{name}.parameters.{pair[0]} x {pair[1]} = {n_phi} x {n_z} = {n_phi * n_z} "
                               f"film cells, more than the {MAX_FILM_CELLS} a film grid may have "
                               f"(MAX_FILM_CELLS, bearing_fmu/limits.py)" + "".join(f"; {w}" for w in where)
                               + f"; use a coarser grid: {pair[0]} <= {MAX_FILM_CELLS // n_z} at {pair[1]} = {n_z}, "
                               f"or {pair[1]} <= {MAX_FILM_CELLS // n_phi} at {pair[0]} = {n_phi} (the finest "
                               "grids we use: 1536 x 40, 160 x 160)")

    def check_connections(self, connections: list[dict]) -> None:
        fed: dict[str, int | None] = {}
        for c in connections:
            ends = {}
            for side, want in (("from", "output"), ("to", "input")):
                if c.get(side) is None:
                    continue
                var = self.variable(c[side], c[side + "_node"], f"'{side}' of a connection", want)
                if var is not None and var.causality != want:
                    names = [v.name for v in self.mds[c[side].split(".", 1)[0]].values() if v.causality == want]
                    self.err(c[side + "_node"], f"'{c[side]}' is {article(var.causality)}, but the '{side}' side of a "
                                                f"connection must be an {want}; {want}s of "
                                                f"'{c[side].split('.', 1)[0]}': {ranked(var.name, names)}")
                    var = None
                ends[side] = var
            if c.get("to") is not None:
                if c["to"] in fed:
                    also = (self.line_origins.get(fed[c["to"]], self.display) if self.line_origins
                            else f"on line {fed[c['to']]}")
                    self.err(c["to_node"], f"input '{c['to']}' is connected twice (also {also}); "
                                           "an input takes exactly one source: remove one of the connections")
                fed.setdefault(c["to"], c["line"])
            src, dst = ends.get("from"), ends.get("to")
            if src is None or dst is None:
                continue
            if src.type != dst.type:
                self.err(c["node"], f"type mismatch: '{c['from']}' is {src.type} but '{c['to']}' is {dst.type}; "
                                    "connect variables of the same type (Real to Real, Integer to Integer, ...)")
            elif src.type == "Enumeration" and (foreign := foreign_items(src, dst)):
                shown = ", ".join(f"{v} ({n})" for n, v in foreign[:10]) + (", ..." if len(foreign) > 10 else "")
                self.err(c["node"], f"enumeration mismatch: '{c['from']}' is of type {src.declared_type or '?'} "
                                    f"{declared_range(src)} but '{c['to']}' is of type {dst.declared_type or '?'} "
                                    f"{declared_range(dst)}: the values {shown} that '{c['from']}' may give are no "
                                    f"items of '{c['to']}', whose FMU would get values it does not declare; connect "
                                    "an output of an enumeration type whose items the input has (or the same type)")
            elif src.type == "Real":
                if "gain_node" not in c and "offset_node" not in c:
                    self.check_units(c, src, dst)
            else:
                for key in ("gain", "offset"):
                    if key + "_node" in c:
                        self.err(c[key + "_node"], f"'{key}' of the connection '{c['from']}' -> '{c['to']}': gain "
                                                   f"and offset apply to Real connections only (this one is "
                                                   f"{src.type}, held over the macro step); remove '{key}'")

    def check_interpolation_order(self, draft) -> None:
        """Warn when Gauss-Seidel's interpolation order q < extrapolation order k caps the order
        of the coupling at q + 1 (:func:`interpolated_inputs`); only Real connections count (the
        others are held whatever q is)."""
        c = draft.coupling
        if not c:
            return
        k, q = c.get("extrapolation_order", 0), c.get("interpolation_order", 0)
        real = []
        for conn in draft.connections:
            src, dst = conn.get("from"), conn.get("to")
            if src and dst:
                inst, _, var = src.partition(".")
                v = self.mds.get(inst, {}).get(var)
                if v is not None and v.type == "Real":
                    real.append((src, dst))
        inputs = interpolated_inputs(c.get("scheme", "gauss-seidel"), k, q, c.get("sequence", ()), real)
        node = draft.coupling_node
        where = self.loc(node) if node is not None else self.display
        if inputs:
            warn_once(f"{where}: {interpolation_warning(k, q, inputs)}")
        if c.get("scheme") == "iterative" and q == 0 and real:
            warn_once(f"{where}: {ITERATIVE_HELD_WARNING}")

    def check_units(self, c: dict, src, dst) -> None:
        """Warn (not refuse: the FMUs may mean the same) when a Real connection without gain or
        offset joins variables of different declared units: the input gets the output's number
        as it is. From the FMUs' ``<UnitDefinitions>``: the same unit under two names is fine,
        different dimensions are said so, a scale or offset gives the gain and offset to write."""
        su, du = src.unit, dst.unit
        if not su or not du or su == du:
            return
        mds = getattr(self, "fmu_caps", {})
        md_s, md_d = mds.get(c["from"].split(".", 1)[0]), mds.get(c["to"].split(".", 1)[0])
        us = md_s.units.get(su) if md_s is not None else None
        ud = md_d.units.get(du) if md_d is not None else None
        head = f"connection '{c['from']}' [{su}] -> '{c['to']}' [{du}]"
        if us is not None and ud is not None:
            conv = us.to(ud)
            if conv is None:
                text = (f"{head}: the units have different dimensions (from the FMUs' unit definitions), yet "
                        "the input gets the output's number as it is; check that these are the variables to "
                        "connect")
            elif conv == (1.0, 0.0):
                return                                  # one unit, two names
            else:
                gain, offset = conv
                fix = f"gain: {gain:.12g}" + (f", offset: {offset:.12g}" if offset else "")
                text = (f"{head}: the input gets the output's number unconverted; to convert {su} to {du} "
                        f"write {{{fix}}} in the connection (from the FMUs' unit definitions)")
        else:
            text = (f"{head}: the units differ and the FMUs do not define both, so the input gets the output's "
                    "number as it is; add gain/offset to the connection if it needs a conversion")
        warn_once(f"{self.loc(c['node'])}: {text}")

    def variable(self, signal: str, node, what: str, want: str | None = None):
        """The model variable named by ``instance.variable`` or None (problem reported)."""
        inst, _, var = signal.partition(".")
        names = [f for f in self.instances]
        if inst not in names:
            self.err(node, f"{what} names the instance '{inst}', which is not in 'fmus' (got {signal!r}); "
                           f"{did_you_mean(inst, names)}instances: {', '.join(names)}")
            return None
        variables = self.mds.get(inst)
        if variables is None:
            return None                                  # FMU unreadable: reported already
        if var not in variables:
            pool = [v.name for v in variables.values() if want is None or v.causality == want] \
                or list(variables)
            kind = f"{want}s" if want else "variables"
            self.err(node, f"{what}: '{inst}' has no variable '{var}'; {kind} of '{inst}' (closest first): "
                           f"{ranked(var, pool)}")
            return None
        return variables[var]

    def check_row_width(self, draft) -> None:
        """The header and the widest row of results.csv within the line limit of its reader
        (``MAX_LINE_BYTES``, 1 MiB: ``plot``, ``compare``, ``CoSimResult.load`` and the run-up
        analysis read it): a run recording 50 000 outputs (every output of an FMU that has them,
        the default) finished, but wrote a file none of them reads. A Real, Integer or Boolean
        value takes at most 25 bytes (repr and comma); String values are not counted."""
        from orchestrator.results.run_directory import MAX_LINE_BYTES
        if draft.signals is None:
            cols = [(f"{inst}.{v.name}", v.type) for inst, md in self.mds.items() for v in md.values()
                    if v.causality == "output"]
            node = None
        else:
            cols = []
            for s, _ in draft.signals:
                inst, _, var = s.partition(".")
                v = self.mds.get(inst, {}).get(var)
                cols.append((s, v.type if v is not None else "Real"))
            node = draft.signals[0][1] if draft.signals else None
        header = len("time") + sum(len(name.encode("utf-8")) + 1 for name, _ in cols)
        row = 25 + sum(3 if kind == "String" else 25 for _, kind in cols)
        if max(header, row) > MAX_LINE_BYTES:
            what = "the header" if header > row else "a row"
            default = " (output.signals not given: every output of every FMU)" if draft.signals is None else ""
            self.err(node, f"results.csv would have {len(cols)} columns{default}: {what} can be {max(header, row)} bytes "
                           f"long, more than the {MAX_LINE_BYTES} bytes a line of results.csv may have for plot, "
                           "compare, CoSimResult.load and the analysis to read it (orchestrator.results."
                           "run_directory.MAX_LINE_BYTES); record fewer signals ('output.signals', e.g. "
                           "'bearing1.*' patterns) or write 'output.format: parquet'")

    def check_signals(self, signals, what: str) -> None:
        for s, node in signals or ():
            if "." not in s:
                self.err(node, f"'{what}' entries must be 'instance.variable' (got {s!r}); add the instance name")
                continue
            self.variable(s, node, f"'{what}' entry {s!r}")

    def check_analysis(self, node, signals) -> None:
        """The ``analysis`` section (docs/analysis.md): known keys only, ``speed`` and every
        journal's ``x``, ``y``, ``eps`` recorded signals, ``clearance`` a positive number,
        ``fields`` a name, ``whirl`` the detection parameters (checked as the analysis will)."""
        recorded = None if signals is None else {s for s, _ in signals}
        section = self.mapping(node, "analysis", ANALYSIS_KEYS, ("speed", "journals"),
                               fix="see docs/analysis.md") or {}
        found = []
        if "speed" in section:
            found.append(("analysis.speed", section["speed"][1]))
        if "journals" in section:
            journals = self.mapping(section["journals"][1], "analysis.journals",
                                    fix="write one entry per journal, e.g. bearing1: {x: rotor.x_1, y: rotor.y_1, "
                                        "clearance: 1.0e-5}") or {}
            if not journals and isinstance(section["journals"][1], yaml.MappingNode):
                self.err(section["journals"][1], "'analysis.journals' is empty; name at least one journal, e.g. "
                                                 "bearing1: {x: rotor.x_1, y: rotor.y_1, clearance: 1.0e-5}")
            for jname, (_, jnode) in journals.items():
                where = f"analysis.journals.{jname}"
                entry = self.mapping(jnode, where, JOURNAL_KEYS, ("x", "y"),
                                     fix="write {x: SIGNAL, y: SIGNAL, eps: SIGNAL, clearance: METRES}") or {}
                for key in ("x", "y", "eps"):
                    if key in entry:
                        found.append((f"{where}.{key}", entry[key][1]))
                if "clearance" in entry:
                    self.number(entry["clearance"][1], f"{where}.clearance", positive=True,
                                fix="give the radial clearance c = psi R in m, e.g. 1.372e-5")
                elif entry and "eps" not in entry:
                    self.err(jnode, f"'{where}' needs 'clearance' [m] (or an 'eps' signal to estimate it from); "
                                    "add clearance: c = psi R, e.g. 1.372e-5")
        if "fields" in section:
            self.string(section["fields"][1], "analysis.fields", "name the instance whose fields file "
                                                                   "(<instance>_fields.npz) is plotted")
        if "whirl" in section:
            self.check_whirl(section["whirl"][1])
        for what, vnode in found:
            s = self.string(vnode, what, "name a signal as 'instance.variable'")
            if s is None:
                continue
            if "." not in s:
                self.err(vnode, f"'{what}' must be 'instance.variable' (got {s!r}); add the instance name")
            elif self.variable(s, vnode, f"'{what}'") is not None and recorded is not None and s not in recorded:
                self.err(vnode, f"'{what}' is {s!r}, which is not recorded (not in output.signals); add it to "
                                "output.signals")

    def check_whirl(self, node) -> None:
        """``analysis.whirl``: keys of :class:`~orchestrator.results.whirl.WhirlParams`, numbers
        (``band``/``growth_band``: two numbers), then the ranges the analysis checks."""
        from dataclasses import fields

        from orchestrator.results.whirl import WhirlParams
        known = tuple(f.name for f in fields(WhirlParams))
        entry = self.mapping(node, "analysis.whirl", known, fix="see docs/analysis.md, 'Method'")
        if entry is None:
            return
        values, ok = {}, True
        for key, (_, vnode) in entry.items():
            what = f"analysis.whirl.{key}"
            if key in ("band", "growth_band"):
                items = vnode.value if isinstance(vnode, yaml.SequenceNode) else None
                if items is None or len(items) != 2:
                    self.err(vnode, f"'{what}' must be a list of two orders [low, high] (got {self.got(vnode)}); "
                                    "e.g. [0.15, 0.85]")
                    ok = False
                    continue
                pair = [self.number(v, f"{what} entry", fix="write two numbers such as [0.15, 0.85]") for v in items]
                ok = ok and None not in pair
                values[key] = tuple(pair)
            else:
                v = self.number(vnode, what)
                ok = ok and v is not None
                values[key] = v
        if ok and values:
            try:
                WhirlParams.from_mapping(values)
            except ValueError as exc:
                self.err(node, f"{exc}; fix the values (docs/analysis.md, 'Method')")


def _item_values(var) -> dict[int, str]:
    """The values an Enumeration variable takes: its type's items within its own min/max."""
    lo = var.min if var.min is not None else -math.inf
    hi = var.max if var.max is not None else math.inf
    return {v: n for n, v, _ in var.items if lo <= v <= hi}


def foreign_items(src, dst) -> list[tuple[str, int]]:
    """The (name, value) items output ``src`` may give that input ``dst`` does not declare (two
    Enumeration variables of different types); empty when either declares no items."""
    if not src.items or not dst.items:
        return []
    have = _item_values(dst)
    return [(n, v) for v, n in sorted(_item_values(src).items()) if v not in have]


def convert(value, fmi_type: str):
    """``value`` as the Python type of an FMI variable type, or None if it does not fit."""
    if fmi_type == "Real":
        if isinstance(value, str) and FLOAT_RE.match(value.strip()):
            return yaml_float(value)
        return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None
    if fmi_type in ("Integer", "Enumeration"):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        return value if isinstance(value, int) and not isinstance(value, bool) else None
    if fmi_type == "Boolean":
        return value if isinstance(value, bool) else None
    if fmi_type == "String":
        return value if isinstance(value, str) else None
    return value
