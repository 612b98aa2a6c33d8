"""Can the FMUs of a comparison take every run it asks for? Checked when the file is loaded.

A variant (or a co-simulation reference) changes the coupling of the base scenario after the
scenario loader checked it against its FMUs' capability flags, so the flags are checked again
here, per run, with the loader's rules (``orchestrator/scenario/coupling_sections.py``
``check_capabilities`` and ``completion.fixed_step_problem``):

* ``scheme: iterative`` and ``discard_retries > 0`` need ``canGetAndSetFMUstate`` in every FMU;
* ``step_control: {type: error}`` and ``discard_retries > 0`` need
  ``canHandleVariableCommunicationStepSize``, and an FMU without it needs ``stop_time`` on the
  macro-step grid.

Before, such a variant ran after the reference and came back as an *unstable* variant with
infinite error (``iterative`` with FMUs that cannot save their state), which reads as a verdict
on the coupling scheme when the FMUs simply cannot run it. Now the file is refused (exit 2)
before any run, naming the variant group's line, the variant, the FMUs and the fix.

An error-controlled step whose FMUs cannot save their state is not refused (it adapts forward
only, as ``rotorcosim run`` warns); the report says so per variant (``forward_only``, read from
the run's summary.json by ``orchestrator/compare/runner.py``).
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


def capability_problems(sc: Scenario, mds: Mapping[str, Any]) -> list[str]:
    """What in ``sc``'s coupling its FMUs (``mds``: instance -> model description) cannot do:
    one text per problem, each saying what the coupling needs, which FMUs lack it and the fix."""
    from orchestrator.scenario.completion import fixed_step_problem

    c = sc.coupling
    if c.scheme == "monolithic":
        return []
    stateless = [n for n, md in mds.items() if not md.can_get_and_set_fmu_state]
    fixed = [n for n, md in mds.items() if not md.can_handle_variable_step]
    who = ", ".join(map(repr, stateless))
    out = []
    if c.scheme == "iterative" and stateless:
        out.append(f"coupling.scheme iterative repeats every macro step from saved FMU states, but {who} "
                   "cannot save them (canGetAndSetFMUstate=\"false\"); compare gauss-seidel or jacobi "
                   "variants instead, or use FMUs built with state support")
    if c.discard_retries and stateless:
        out.append(f"coupling.discard_retries = {c.discard_retries} redoes a discarded step from saved FMU "
                   f"states, but {who} cannot save them (canGetAndSetFMUstate=\"false\"); set "
                   "coupling.discard_retries: 0 for this variant")
    if getattr(c.step_control, "type", "constant") == "error" and fixed:
        out.append(f"coupling.step_control type error varies the macro step, but "
                   f"{', '.join(map(repr, fixed))} cannot take varying steps "
                   "(canHandleVariableCommunicationStepSize=\"false\"); use step_control type constant")
    elif fixed:
        why = fixed_step_problem(sc.start_time, sc.stop_time, c.macro_step, fixed, c.discard_retries)
        if why:
            out.append(why)
    return out


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
                           bad: Callable[..., None]) -> None:
    """Report (through ``bad(key, msg)``) every run of the comparison that its FMUs cannot take:
    the reference at ``reference`` (a monolithic one: a model of every FMU), each variant at
    ``variants[i]`` of its group, one line per problem and variant."""
    from orchestrator.compare.spec import apply_changes

    mds = model_descriptions(base)
    if not mds:
        return
    if reference.monolithic:
        steps = [v.changes.get("coupling.macro_step", base.coupling.macro_step) for v in variants]
        why = monolithic_problem(mds, steps) if len(mds) == len(base.fmus) else None
        if why:
            bad("reference", why)
    else:
        for p in capability_problems(apply_changes(base, reference.changes), mds):
            bad("reference", f"cannot run with these FMUs: {p}")
    for v in variants:
        for p in capability_problems(apply_changes(base, v.changes), mds):
            bad(f"variants[{group_of.get(v.name, 0)}]", f"variant '{v.name}' cannot run with these FMUs: {p}")
