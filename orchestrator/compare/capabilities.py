"""Can the FMUs of a comparison take every run it asks for? Checked when the file is loaded.

A variant (or a co-simulation reference) changes the coupling of the base scenario after the
scenario loader checked it against its FMUs' capability flags, so the flags are checked again
here, per run, by the loader's own rules: ``capability_issues`` in
``orchestrator/scenario/coupling_sections.py`` (which the loader's ``check_capabilities`` calls)
and ``completion.fixed_step_problem``, so that the two cannot drift apart. They say, e.g.:

* ``scheme: iterative`` and ``discard_retries > 0`` need ``canGetAndSetFMUstate`` in every FMU;
* ``step_control: {type: error}`` cannot be combined with ``discard_retries > 0``, whatever the FMUs,
  unless ``step_control.until`` is set (the retries then act on the constant steps after it);
* ``step_control.until`` must be an output time after ``start_time``; at or after ``stop_time`` the
  whole run is error-controlled (``coupling_sections.until_problem``, the loader's rule);
* ``step_control: {type: error}`` needs ``canHandleVariableCommunicationStepSize``, and an FMU
  without it needs ``stop_time`` on the macro-step grid and no ``discard_retries``.

Before, such a variant ran after the reference and came back as an *unstable* variant with
infinite error (``iterative`` with FMUs that cannot save their state), which reads as a verdict
on the coupling scheme when the FMUs simply cannot run it. Now the file is refused (exit 2)
before any run, naming the variant group's line, the variant, the FMUs and the fix. (This
module had its own copy of the rules, which had drifted: an error-controlled variant with
``discard_retries: 1`` over FMUs that save their state loaded, and failed when its run started.)

An error-controlled step whose FMUs cannot save their state is not refused (it adapts forward
only): the loader's warning is logged with the variant's line, and the report says so per variant
(``forward_only``, read from the run's summary.json by ``orchestrator/compare/runner.py``).
"""

from __future__ import annotations

from typing import Any, Callable, Mapping

from orchestrator.scenario import Scenario


def model_descriptions(scenario: Scenario) -> dict[str, Any]:
    """Instance -> model description of every FMU of ``scenario`` that can be read (an unreadable
    one is left out: the run reports it)."""
    from orchestrator.errors import FmuError
    from orchestrator.fmi.archive import cached_model_description

    out = {}
    for f in scenario.fmus:
        try:
            out[f.name] = cached_model_description(f.path)
        except (FmuError, OSError, TypeError, ValueError):
            continue
    return out


def capability_problems(sc: Scenario, mds: Mapping[str, Any]) -> tuple[list[str], list[str]]:
    """What in ``sc``'s coupling its FMUs (``mds``: instance -> model description) cannot do, by
    the scenario loader's rules: (errors, warnings), one text per problem, each saying what the
    coupling needs, which FMUs lack it and the fix. A monolithic run does not step the FMUs."""
    from orchestrator.scenario.completion import fixed_step_problem
    from orchestrator.scenario.coupling_sections import capability_issues, until_problem

    c = sc.coupling
    if c.scheme == "monolithic":
        return [], []
    errors, warnings = [], []
    why = until_problem(c.step_control, sc.start_time, sc.stop_time, sc.output.interval or c.macro_step)
    if why:
        errors.append(why)
    fixed = [n for n, md in mds.items() if not md.can_handle_variable_step]
    why = fixed_step_problem(sc.start_time, sc.stop_time, c.macro_step, fixed, c.discard_retries,
                             c.defect_retries)
    if why:
        errors.append(why)
    coupling = {"scheme": c.scheme, "step_control": c.step_control, "discard_retries": c.discard_retries,
                "defect_retries": c.defect_retries}
    for issue in capability_issues(coupling, mds):
        (warnings if issue.warning else errors).append(issue.text)
    return errors, warnings


def monolithic_problem(mds: Mapping[str, Any], variant_steps) -> str | None:
    """Why the monolithic reference cannot be built for FMUs with these model descriptions (it
    knows our rotor and bearing models and those registered by ``build_fmus``), or None.

    Before, a comparison that left ``reference`` out (monolithic is the default) over
    third-party FMUs ran every variant and then failed with "the reference run failed"."""
    from orchestrator.reference.models import MODELS

    unknown = {n: md.model_name for n, md in mds.items() if md.model_name not in MODELS}
    if not unknown:
        return None
    steps = sorted({float(h) for h in variant_steps})
    h = steps[0] / 10 if steps else None
    example = (f"{{scheme: gauss-seidel, extrapolation_order: 1, interpolation_order: 1, macro_step: {h:g}}}"
               if h else "{scheme: gauss-seidel, macro_step: H}")
    return (f"is the monolithic reference (the default when 'reference' is left out), which has no model of "
            + ", ".join(f"'{n}' (modelName '{m}')" for n, m in unknown.items())
            + f" (it knows {sorted(MODELS)}); give a fine co-simulation as the reference, e.g. 'reference: "
            f"{example}' (its macro step must divide every variant's, docs/compare.md \"Reference\")")


def check_run_capabilities(base: Scenario, reference, variants, group_of: Mapping[str, int],
                           bad: Callable[..., None], warn: Callable[..., None] | None = None) -> None:
    """Report (through ``bad(key, msg)``) every run of the comparison that its FMUs cannot take:
    the reference at ``reference`` (a monolithic one: a model of every FMU), each variant at
    ``variants[i]`` of its group, one line per problem and variant; the loader's warnings (an
    error-controlled step that adapts forward only) through ``warn(key, msg)``, the same way."""
    from orchestrator.compare.spec import apply_changes

    mds = model_descriptions(base)
    if not mds:
        return
    if reference.monolithic:
        steps = [v.changes.get("coupling.macro_step", base.coupling.macro_step) for v in variants]
        why = monolithic_problem(mds, steps) if len(mds) == len(base.fmus) else None
        if why:
            bad("reference", why)
    runs = [("reference", "", apply_changes(base, reference.changes))] if not reference.monolithic else []
    runs += [(f"variants[{group_of.get(v.name, 0)}]", f"variant '{v.name}' ", apply_changes(base, v.changes))
             for v in variants]
    for key, who, sc in runs:
        errors, warnings = capability_problems(sc, mds)
        for p in errors:
            bad(key, f"{who}cannot run with these FMUs: {p}")
        for p in warnings if warn is not None else ():
            warn(key, f"{who}runs with a warning: {p}")
