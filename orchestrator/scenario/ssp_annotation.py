"""rotorcosim's own SSP annotation: what a scenario holds that SSP 1.0 has no element for.

``export-ssp`` wrote the components, connections, parameter values, start and stop time and the
macro step (libcosim's ``osp:FixedStepAlgorithm``); ``run x.ssp`` then dropped the rest of the
scenario without a word: ``output.signals`` (every output was recorded), the output interval,
the coupling beyond the macro step (the run was Jacobi, zero-order hold), ``analysis``,
``compare``, and each instance's ``substeps`` and ``isolation``.

Now :func:`write_annotation` adds them to the SSD as::

    <ssd:Annotations>
      <ssc:Annotation type="org.rotorcosim.scenario">
        <rc:Scenario xmlns:rc="https://rotorcosim.org/SSP/ScenarioAnnotation" format="1">
    format: 1
    coupling: {scheme: gauss-seidel, macro_step: 0.1, ...}
    output: {signals: [a.y], interval: 0.05}
        </rc:Scenario>
      </ssc:Annotation>
    </ssd:Annotations>

(the scenario format's YAML, values at their defaults left out; SSP 1.0 lets tools ignore
annotation types they do not know, and libcosim does), and :func:`read_annotation` takes them
back into the scenario document the SSP reader makes (``ssp.scenario_from_ssp``), as untrusted
as the rest of the SSD.

Its ``files`` key lists the files String parameters name that the archive carries
(``files: {rotor: {rotor_file: resources/files/rotor/my_rotor.yaml}}``: the parameter's value in
the SSD is that member's name); the SSP reader checks each member and sets the parameter to the
extracted copy. ``compare`` is what ``rotorcosim compare x.ssp`` runs
(:func:`orchestrator.compare.spec.load_compare`); its ``build_fmus`` is not written (the archive
carries the FMUs it built, not the Python sources it built them from).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping
from xml.etree import ElementTree as ET

from orchestrator.errors import ScenarioError
from orchestrator.untrusted import InputError

RC_NS = "https://rotorcosim.org/SSP/ScenarioAnnotation"
_NS = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
       "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
       "rc": RC_NS}

#: ``ssc:Annotation type`` of what a scenario holds that SSP 1.0 has no element for (SSP 1.0 sec.
#: 2.3.4: tools ignore annotation types they do not know; libcosim does)
ANNOTATION_TYPE = "org.rotorcosim.scenario"
ANNOTATION_FORMAT = 1
#: longest text of the annotation read (characters): a scenario's sections are a few kB
MAX_ANNOTATION_CHARS = 1 << 20
#: the scenario keys the annotation may set, and under ``fmus.<instance>`` the keys it may set
ANNOTATION_KEYS = ("format", "coupling", "output", "analysis", "compare", "fmus", "files")
ANNOTATION_FMU_KEYS = ("substeps", "isolation")


def _plain(value):
    """``value`` (a loaded scenario's mappings, tuples) as plain dicts, lists and scalars for YAML."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    return value


def _changed(spec, skip=()) -> dict:
    """The fields of a frozen spec that differ from the dataclass's defaults (the loader gives
    the defaults back), as plain values."""
    import dataclasses
    default = type(spec)()
    return {f.name: _plain(getattr(spec, f.name)) for f in dataclasses.fields(spec)
            if f.name not in skip and getattr(spec, f.name) != getattr(default, f.name)}


def scenario_annotation(scenario, files: Mapping[tuple[str, str], str] | None = None) -> dict:
    """What ``scenario`` holds that SSP 1.0 has no element for, in the scenario format: the whole
    ``coupling`` section (the SSP's osp:FixedStepAlgorithm holds the macro step only), ``output``,
    ``analysis``, ``compare`` (without ``build_fmus``: the archive carries the FMUs, not their
    sources) and each instance's ``substeps`` and ``isolation``; ``files`` the archive members
    that String parameters name (``{(instance, parameter): member}``). Values at their defaults
    are left out (the loader gives them back)."""
    c = scenario.coupling
    coupling = {"scheme": c.scheme, "macro_step": c.macro_step,
                **_changed(c, skip=("scheme", "macro_step", "iteration", "step_control"))}
    if "atol" in (sc := _changed(c.step_control)) and isinstance(c.step_control.atol, tuple):
        sc["atol"] = {str(k): v for k, v in c.step_control.atol}
    for key, sub in (("iteration", _changed(c.iteration)), ("step_control", sc)):
        if sub:
            coupling[key] = sub
    doc: dict[str, Any] = {"format": ANNOTATION_FORMAT, "coupling": coupling}
    output = _changed(scenario.output)
    if output:
        doc["output"] = output
    if scenario.analysis:
        doc["analysis"] = _plain(scenario.analysis)
    compare = {k: v for k, v in _plain(scenario.compare or {}).items() if k != "build_fmus"}
    if compare:
        doc["compare"] = compare
    fmus = {f.name: {k: getattr(f, k) for k in ANNOTATION_FMU_KEYS if getattr(f, k) is not None}
            for f in scenario.fmus}
    fmus = {k: v for k, v in fmus.items() if v}
    if fmus:
        doc["fmus"] = fmus
    if files:
        carried: dict[str, dict[str, str]] = {}
        for (inst, name), member in files.items():
            carried.setdefault(inst, {})[name] = member
        doc["files"] = carried
    return doc


def baseline_outside(baseline: str) -> bool:
    """Whether an annotation's ``compare.baseline`` leaves the archive's folder (absolute, ``..``, a
    backslash or drive letter): ``compare x.ssp`` refuses it, since ``--update-baseline`` writes that
    file and an archive may come from anyone (``orchestrator.compare.spec``)."""
    from pathlib import PurePosixPath
    p = PurePosixPath(baseline)
    return p.is_absolute() or ".." in p.parts or "\\" in baseline or ":" in baseline


def write_annotation(root: ET.Element, scenario, files: Mapping[tuple[str, str], str] | None = None) -> None:
    """The rotorcosim annotation as the SSD's last element (``ssd:Annotations``), its content YAML
    text in an ``rc:Scenario`` element (``files``: see :func:`scenario_annotation`)."""
    import yaml
    ann = ET.SubElement(ET.SubElement(root, f"{{{_NS['ssd']}}}Annotations"), f"{{{_NS['ssc']}}}Annotation",
                        {"type": ANNOTATION_TYPE})
    el = ET.SubElement(ann, f"{{{_NS['rc']}}}Scenario", {"format": str(ANNOTATION_FORMAT)})
    el.text = "\n" + yaml.safe_dump(scenario_annotation(scenario, files), sort_keys=False)


def _duplicate_keys(node, where: str) -> list[str]:
    """Keys given twice in a mapping of the composed annotation (the scenario loader refuses them;
    constructing the value kept the last one without a word). Each node visited once (aliases)."""
    import yaml
    out, seen, todo = [], set(), [node]
    while todo:
        n = todo.pop()
        if n is None or id(n) in seen:
            continue
        seen.add(id(n))
        if isinstance(n, yaml.MappingNode):
            first: dict = {}
            for k, v in n.value:
                if isinstance(k, yaml.ScalarNode):
                    if k.value in first:
                        out.append(f"{where}:{k.start_mark.line + 1}: key {k.value!r:.60} appears twice in a mapping "
                                   f"(first on line {first[k.value] + 1}); keep one of them")
                    else:
                        first[k.value] = k.start_mark.line
                todo.extend((k, v))
        elif isinstance(n, yaml.SequenceNode):
            todo.extend(n.value)
    return out


def read_annotation(root: ET.Element, doc: dict, ssd: str) -> dict[tuple[str, str], str]:
    """The rotorcosim annotation of an SSD (:func:`scenario_annotation`) into ``doc``: its
    ``coupling`` replaces the one read from osp:FixedStepAlgorithm (whose baseStepSize its
    ``macro_step`` must equal, or takes when it has none), ``output``, ``analysis`` and
    ``compare`` are set, ``fmus.<instance>`` keys are merged. Untrusted like the rest of the SSD:
    at most :data:`MAX_ANNOTATION_CHARS` characters, read by the bounded YAML reader (depth,
    aliases, digits), only :data:`ANNOTATION_KEYS` (per instance :data:`ANNOTATION_FMU_KEYS`, of
    instances the SSD has); the values are then checked by the scenario loader as any scenario's.

    Returns its ``files`` as ``{(instance, parameter): member}`` (instances of the SSD, names and
    members texts; empty without): the caller checks the members and sets the parameters
    (``ssp._carried_files``)."""
    found = [a for a in root.findall("ssd:Annotations/ssc:Annotation", _NS) if a.get("type") == ANNOTATION_TYPE]
    if not found:
        return {}
    where = f"{ssd}: ssc:Annotation type=\"{ANNOTATION_TYPE}\""
    if len(found) > 1:
        raise ScenarioError(f"{where}: given {len(found)} times; keep one")
    el = found[0].find("rc:Scenario", _NS)
    if el is None:
        raise ScenarioError(f"{where}: has no rc:Scenario element ({_NS['rc']}); re-export the SSP, or remove "
                            "the annotation")
    if el.get("format") != str(ANNOTATION_FORMAT):
        raise ScenarioError(f"{where}: format {el.get('format')!r}; this rotorcosim reads format "
                            f"{ANNOTATION_FORMAT}: export the SSP again with this rotorcosim, or remove the annotation")
    text = el.text or ""
    if len(text) > MAX_ANNOTATION_CHARS:
        raise ScenarioError(f"{where}: {len(text)} characters (limit {MAX_ANNOTATION_CHARS}, orchestrator.scenario."
                            "ssp_annotation.MAX_ANNOTATION_CHARS); not a plausible scenario annotation")
    import yaml

    from orchestrator.scenario.nodes import YamlLoader
    from orchestrator.untrusted import compose_yaml, construct_yaml
    try:
        node = compose_yaml(text, display=where, loader_cls=YamlLoader)
        value = None if node is None else construct_yaml(node, display=where, loader_cls=YamlLoader)
    except InputError as e:
        raise ScenarioError(str(e)) from None
    except yaml.YAMLError as e:
        raise ScenarioError(f"{where}: not valid YAML ({e}); re-export the SSP, or remove the annotation") from None
    if not isinstance(value, dict):
        raise ScenarioError(f"{where}: must hold a mapping of scenario sections (got {type(value).__name__})")
    problems = _text_problems(el, node, value, where) + _macro_step_problems(value, doc, where)
    problems += _merge_fmus(value, doc, where)
    files, more = _files(value, doc, where)
    problems += more
    if problems:
        raise ScenarioError(problems)
    for key in ("coupling", "output", "analysis", "compare"):
        if key in value:
            doc[key] = value[key]
    return files


def _files(value: dict, doc: dict, where: str) -> tuple[dict[tuple[str, str], str], list[str]]:
    """The annotation's ``files`` (``{instance: {parameter: member}}``) as ``{(instance, parameter):
    member}``, and the problems of its shape (not a mapping, an instance the SSD lacks, a name or
    member that is not a text). The members themselves are checked where the archive is known."""
    files = value.get("files", {})
    if not isinstance(files, dict):
        return {}, [f"{where}: 'files' must be a mapping of instance names to {{parameter: member}} (got "
                    f"{type(files).__name__})"]
    out, problems = {}, []
    for inst, entry in files.items():
        if inst not in doc["fmus"]:
            problems.append(f"{where}: 'files' names {inst!r:.80}, which is no component of the SSD "
                            f"({', '.join(doc['fmus']) or 'none'})")
        elif not isinstance(entry, dict) or not all(isinstance(k, str) and isinstance(v, str)
                                                    for k, v in entry.items()):
            problems.append(f"{where}: 'files.{inst}' must map parameter names to archive members, e.g. "
                            f"{{rotor_file: resources/files/{inst}/rotor.yaml}} (got {entry!r:.200})")
        else:
            out.update({(inst, name): member for name, member in entry.items()})
    return out, problems


def _text_problems(el: ET.Element, node, value: dict, where: str) -> list[str]:
    """What in the annotation's text (``value``, composed as ``node``) would be read without a word:
    a key given twice, a key the annotation may not set, an element inside rc:Scenario (its text
    dropped), a ``format`` contradicting the element's."""
    problems = _duplicate_keys(node, where)
    problems += [f"{where}: unknown key {k!r}; valid: {', '.join(ANNOTATION_KEYS)}"
                 for k in value if k not in ANNOTATION_KEYS]
    if len(el):           # the content is YAML text; an element inside was dropped without a word
        problems.append(f"{where}: rc:Scenario holds the element <{el[0].tag}>; its content is YAML text only: "
                        "re-export the SSP, or remove the element")
    fmt = value.get("format", ANNOTATION_FORMAT)
    if type(fmt) is not int or fmt != ANNOTATION_FORMAT:
        problems.append(f"{where}: 'format: {fmt!r:.40}' in its text contradicts format=\"{ANNOTATION_FORMAT}\" of "
                        f"the element; this rotorcosim reads format {ANNOTATION_FORMAT}: export the SSP again, or "
                        "remove the annotation")
    return problems


def _macro_step_problems(value: dict, doc: dict, where: str) -> list[str]:
    """The annotation's ``coupling.macro_step`` against the SSD's osp:FixedStepAlgorithm
    baseStepSize (``doc``'s): none given takes the SSD's (into ``value``), another is a problem."""
    coupling, fixed = value.get("coupling"), (doc.get("coupling") or {}).get("macro_step")
    if not isinstance(coupling, dict) or fixed is None:
        return []
    # the SSD's osp:FixedStepAlgorithm baseStepSize is what libcosim runs; the annotation's macro
    # step replaced it silently (an SSP edited by hand, or a tampered annotation)
    step = coupling.get("macro_step")
    if step is None:
        value["coupling"] = {**coupling, "macro_step": fixed}
    elif not (isinstance(step, (int, float)) and not isinstance(step, bool) and step == fixed):
        return [f"{where}: 'coupling.macro_step: {step!r:.40}' contradicts the SSD's "
                f"osp:FixedStepAlgorithm baseStepSize=\"{fixed!r}\" (the step libcosim runs); make them "
                "equal (export the SSP again), or remove macro_step from the annotation"]
    return []


def _merge_fmus(value: dict, doc: dict, where: str) -> list[str]:
    """The annotation's ``fmus.<instance>`` keys merged into ``doc``'s components; the problems
    (an instance the SSD lacks, a key the annotation may not set)."""
    problems = []
    fmus = value.get("fmus", {})
    if not isinstance(fmus, dict):
        problems.append(f"{where}: 'fmus' must be a mapping of instance names (got {type(fmus).__name__})")
        fmus = {}
    for inst, entry in fmus.items():
        if inst not in doc["fmus"]:
            problems.append(f"{where}: 'fmus' names {inst!r}, which is no component of the SSD "
                            f"({', '.join(doc['fmus']) or 'none'})")
        elif not isinstance(entry, dict) or any(k not in ANNOTATION_FMU_KEYS for k in entry):
            problems.append(f"{where}: 'fmus.{inst}' may set only {', '.join(ANNOTATION_FMU_KEYS)} (got "
                            f"{entry!r:.200})")
        else:
            doc["fmus"][inst].update(entry)
    return problems
