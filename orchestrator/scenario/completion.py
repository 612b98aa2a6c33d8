"""Completing a parsed scenario from its FMUs: defaults, fixed-step FMUs, arrays and signal patterns.

:class:`Completion` is mixed into the loader's FMU checks (it reports through
``self.err``, reads ``self.mds``, ``self.des`` and ``self.fixed_step`` filled by
``read_fmu``):

* :meth:`apply_defaults`: ``start_time``, ``stop_time`` and ``coupling.macro_step``
  the scenario omits come from the first FMU in ``fmus`` whose ``DefaultExperiment``
  declares them;
* :meth:`check_fixed_step`: an FMU with ``canHandleVariableCommunicationStepSize="false"``
  gets neither a shortened last step nor halved retry steps;
* :meth:`expand_arrays`: ``drv.f -> osc.f`` between arrays becomes one connection per element;
* :meth:`expand_patterns`: ``output.signals`` entries with ``*`` become the matching outputs.
"""

from __future__ import annotations

import math
from typing import Sequence

from orchestrator.names import array_elements, index_of, is_pattern, match
from orchestrator.scenario.limits import step_slack
from orchestrator.scenario.model import CouplingSpec
from orchestrator.scenario.sections import FROM_FMUS

INVALID = "(invalid)"        # a DefaultExperiment value that is not a usable number (reported)


def fixed_step_problem(t0: float, t_stop: float, h: float, fixed: Sequence[str], discard_retries: int = 0,
                       defect_retries: int = 0) -> str | None:
    """Why a run cannot honour FMUs that cannot vary their communication step size, or None.

    ``fixed`` names the instances whose model description says
    ``canHandleVariableCommunicationStepSize="false"``. Such an FMU must get the
    same step every time (FMI 2.0 sec. 4.3.1), so the run needs ``stop_time`` on
    the grid ``start_time + n*macro_step`` (no shortened last step) and no discard
    retries (which halve the step), nor defect retries.
    """
    if not fixed:
        return None
    who = ", ".join(repr(f) for f in fixed)
    why = (f"FMU instance{'s' if len(fixed) > 1 else ''} {who} cannot vary the communication step size "
           "(canHandleVariableCommunicationStepSize=\"false\")")
    steps = (t_stop - t0) / h
    if abs(steps - round(steps)) > max(1e-9 * max(1.0, steps), step_slack(t0, t_stop, h)):
        lo, hi = t0 + math.floor(steps) * h, t0 + math.ceil(steps) * h
        return (f"stop_time {t_stop!r} is not on the macro-step grid start_time + n*{h!r}, so the last step would "
                f"be shortened, but {why}; use stop_time {lo:.12g} or {hi:.12g}, or a macro_step that divides "
                "stop_time - start_time")
    if discard_retries:
        return (f"coupling.discard_retries = {discard_retries} redoes discarded steps with halved step sizes, but "
                f"{why}; set coupling.discard_retries: 0")
    if defect_retries:
        return (f"coupling.defect_retries = {defect_retries} redoes steps whose coupling defect is over the limit with "
                f"halved step sizes, but {why}; set coupling.defect_retries: 0")
    return None


class Completion:
    """Mixin of the FMU checks (see the module docstring)."""

    def apply_defaults(self, draft) -> dict:
        """Fill the omitted start/stop time and macro step of ``draft``; return ``{key: "value (source)"}``."""
        kw, coupling, taken = draft.kw, draft.coupling, {}
        top = getattr(self, "top_keys", set())

        def first(attr, key, positive=False):
            """The first FMU's DefaultExperiment ``attr`` and its instance; a value that is not
            a finite number (or not > 0 with ``positive``) is reported against ``key`` and
            gives (None, INVALID)."""
            for f in draft.fmus:
                de = self.des.get(f["name"], {})
                if attr in de:
                    v, who = de[attr], f["name"]
                    if not (isinstance(v, float) and math.isfinite(v) and (v > 0 or not positive)):
                        need = "a finite number > 0" if positive else "a finite number"
                        self.err(getattr(self, "root_node", None),
                                 f"'{key}' is missing and the DefaultExperiment {attr} of '{who}' is {v!r}, not "
                                 f"{need}; add '{key}: <seconds>' to the scenario (or fix the FMU's "
                                 "modelDescription.xml)")
                        return None, INVALID
                    return v, who
            return None, None

        if "start_time" not in top:
            v, who = first("startTime", "start_time")
            if v is not None:
                kw["start_time"] = v
                taken["start_time"] = f"{v!r} (DefaultExperiment startTime of '{who}')"
        if kw.get("stop_time") is FROM_FMUS:
            self._default_stop(kw, lambda attr: first(attr, "stop_time"), taken)
        if coupling is not None and "macro_step" not in coupling:
            v, who = first("stepSize", "coupling.macro_step", positive=True)
            if v is not None:
                coupling["macro_step"] = v
                taken["coupling.macro_step"] = f"{v!r} (DefaultExperiment stepSize of '{who}')"
        return taken

    def _default_stop(self, kw: dict, first, taken: dict) -> None:
        root = getattr(self, "root_node", None)
        v, who = first("stopTime")
        if v is None:
            kw["stop_time"] = None
            if who is not INVALID and (self.mds or not self.fmu_specs):   # FMUs unreadable: reported already
                self.err(root, "top level: missing the required key 'stop_time' (no FMU declares a "
                               "DefaultExperiment stopTime to take it from); add 'stop_time: <seconds>'")
        elif kw.get("start_time") is not None and v <= kw["start_time"]:
            kw["stop_time"] = None
            self.err(root, f"'stop_time' is missing and the DefaultExperiment stopTime {v!r} of '{who}' is not "
                           f"after start_time {kw['start_time']!r}; add 'stop_time: <seconds>' to the scenario")
        else:
            kw["stop_time"] = v
            taken["stop_time"] = f"{v!r} (DefaultExperiment stopTime of '{who}')"

    def check_fixed_step(self, draft) -> None:
        t0, t1, coupling = draft.kw.get("start_time"), draft.kw.get("stop_time"), draft.coupling
        if coupling is None or not isinstance(t0, float) or not isinstance(t1, float):
            return
        why = fixed_step_problem(t0, t1, coupling.get("macro_step", CouplingSpec.macro_step), self.fixed_step,
                                 coupling.get("discard_retries", 0) or 0, coupling.get("defect_retries", 0) or 0)
        if why:
            from orchestrator.scenario.coupling_sections import value_place
            root = getattr(self, "root_node", None)
            key = why.split(" ", 1)[0].removeprefix("coupling.")
            paths = ([("coupling", key)] if key in ("discard_retries", "defect_retries") else
                     [("stop_time",), ("coupling", "macro_step"), ("start_time",)])
            at, then = value_place(self, root, *paths)
            self.err(at, why + then)

    def expand_arrays(self, connections: list[dict]) -> list[dict]:
        """``drv.f -> osc.f`` between two arrays (no variable ``f``, elements ``f[...]``) becomes one
        connection per element; both sides must have the same index set."""
        out = []
        for c in connections:
            ends = [c.get("from"), c.get("to")]
            if None in ends or any(e.split(".", 1)[0] not in self.mds for e in ends):
                out.append(c)
                continue
            (si, sv), (di, dv) = (e.split(".", 1) for e in ends)
            if sv in self.mds[si] or dv in self.mds[di]:
                out.append(c)
                continue
            se, de = array_elements(sv, list(self.mds[si])), array_elements(dv, list(self.mds[di]))
            if not se or not de:
                out.append(c)                            # reported as an unknown variable by the checks
                continue
            si_set, di_set = [index_of(e) for e in se], [index_of(e) for e in de]
            if sorted(si_set) != sorted(di_set):
                common = [i for i in si_set if i in set(di_set)]
                pairs = ", ".join(f"'{si}.{sv}[{i}] -> {di}.{dv}[{i}]'" for i in common[:6])
                how = (f"connect the elements one by one, e.g. those both have: {pairs}"
                       + (", ..." if len(common) > 6 else "") + " (one list entry each)"
                       if common else "connect the elements one by one ('a.y[0] -> b.u[1]')")
                self.err(c["node"], f"'{c['from']}' -> '{c['to']}' connects two arrays element by element, but "
                                    f"their index sets differ ({', '.join(si_set)} vs {', '.join(di_set)}); {how}")
                continue
            for idx in si_set:
                out.append({**c, "from": f"{si}.{sv}[{idx}]", "to": f"{di}.{dv}[{idx}]"})
        return out

    def expand_patterns(self, signals):
        """``output.signals`` entries with ``*`` (e.g. ``osc.x[*]``, ``bearing1.*``, ``*.omega``) become the
        matching outputs, in file order; a pattern that matches nothing is a problem."""
        if signals is None:
            return None
        out, seen = [], set()
        for sig, node in signals:
            if not is_pattern(sig):
                if sig not in seen:
                    out.append((sig, node))
                    seen.add(sig)
                continue
            inst_pat, _, var_pat = sig.partition(".")
            hits = []
            for inst in match(inst_pat, self.instances):
                outs = [v.name for v in self.mds.get(inst, {}).values() if v.causality == "output"]
                hits += [f"{inst}.{v}" for v in match(var_pat or "*", outs)]
            if not hits and all(i in self.mds for i in match(inst_pat, self.instances)):
                self.err(node, f"'output.signals' pattern {sig!r} matches no output ('*' stands for any "
                               "characters, e.g. 'osc.x[*]' or 'bearing1.*'); check the names with "
                               "`rotorcosim info FMU`")
            for h in hits:
                if h not in seen:
                    out.append((h, node))
                    seen.add(h)
        return out
