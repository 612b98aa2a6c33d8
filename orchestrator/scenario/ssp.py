"""SSP 1.0 (System Structure and Parameterization) import and export.

Import (:func:`scenario_from_ssp`): an ``.ssp`` archive (``SystemStructure.ssd`` at
the top, FMUs and ``.ssv`` files inside) or a bare ``.ssd`` file (sources relative
to its folder) becomes a scenario document: the top-level system's components
(FMU instances; ``source`` resolved to the extracted file), its connections
(with ``LinearTransformation`` factor/offset as gain/offset, composed with the unit
conversion SSP implies between Real connectors of different units unless
``suppressUnitConversion``), the parameter bindings of each component and of the system
(``component.variable``; the system's take precedence) (inline ``ssv:ParameterSet`` or a
``source`` ``.ssv``, values of every SSP type, ``prefix`` prepended to the names) and the system's
``DefaultExperiment`` (start/stop time). The document goes through the ordinary
scenario loader, so every check and message of a YAML scenario applies. Nested
systems, signal dictionaries, parameter mappings (``.ssm``) and mapping transformations are reported as
unsupported rather than dropped.

Export (:func:`export_ssp`): a loaded scenario as an ``.ssp`` archive that libcosim
runs (``CosimExecution.from_ssp_file``): components with ``resources/<file>.fmu``,
typed connectors, connections (gain/offset as ``LinearTransformation``), inline
parameter values (Enumeration values as ``ssv:Integer``: libcosim cannot read
``ssv:Enumeration``), ``DefaultExperiment`` with the macro step as libcosim's
``osp:FixedStepAlgorithm`` annotation. It encodes what libcosim's fixed-step
algorithm does: Jacobi with zero-order hold; our extrapolation and sub-step
settings have no SSP equivalent (a warning says libcosim runs Jacobi with zero-order hold).

A file a String parameter names (a rotor file; :func:`orchestrator.scenario.loader.named_files`)
travels in the archive as ``resources/files/<instance>/<file name>`` (SSP 1.0: "additional
entries with the prefix resources/ ... to bundle resources referenced from the System Structure
Description"), the parameter's value in the SSD being that member's name, and the annotation's
``files`` key saying so; reading the SSP sets the parameter to the extracted copy, after checking
the member as untrusted (:func:`_carried_files`: under ``resources/``, no ``..``, not absolute,
no link, a regular file of at most :data:`MAX_NAMED_FILE_BYTES`). A file larger than that is not
carried, and export-ssp says so. Before, no named file was carried: an exported turbocharger
scenario with its own rotor file did not run from the archive anywhere else. A scenario file is
untrusted too (:func:`_named_files`): a file it names is carried only when it is a regular file
(a FIFO, device or socket is never opened) whose real path lies in the scenario's folder (for a
scenario read from an SSP also the folder it was extracted to) or in a ``--carry-files-from``
folder; a value given with ``--set`` names the user's own choice, carried from anywhere. Before,
a scenario from someone else naming ``~/.ssh/id_rsa`` had export-ssp pack that file.

What a scenario holds that SSP 1.0 has no element for (the whole ``coupling`` section,
``output``: signals, interval, format; ``analysis``; ``compare``; each instance's ``substeps`` and
``isolation``) is written as an ``ssc:Annotation`` of type ``org.rotorcosim.scenario`` on the
SSD (``orchestrator/scenario/ssp_annotation.py``: YAML text in an ``rc:Scenario`` element), which
SSP 1.0 lets other tools ignore and libcosim does; the import reads it back (bounded like the
rest of the SSD), so ``export-ssp`` then ``run x.ssp`` runs the scenario that was exported.
Before, ``output.signals`` and everything else without an SSP element were dropped silently.

The output is a regular ``.ssp`` file or a new name in an existing folder
(:func:`check_output_path`): a directory, FIFO, device or socket at ``out``, a symbolic link,
an existing file that is not an SSP archive (the scenario itself, an FMU) or a missing folder
is refused before anything is written. The archive is written to a
temporary file created exclusively beside ``out`` (no link can be planted there) and renamed
over ``out``, so an existing file is replaced atomically and nothing is left on failure.

An SSP is untrusted: the archive is checked and extracted by the FMU archive rules
(:func:`orchestrator.fmi.archive.safe_extract`: names, links, sizes, ratios, CRC), its XML
files are read by the bounded reader and parsed by :func:`orchestrator.untrusted.parse_xml`
(DOCTYPE and entities refused after decoding, as for model descriptions).
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import shlex
import stat
import tempfile
import warnings
import zipfile
from pathlib import Path, PurePosixPath
from typing import Any, Mapping
from xml.etree import ElementTree as ET

from orchestrator.errors import ScenarioError
from orchestrator.scenario.ssp_annotation import (ANNOTATION_TYPE, RC_NS, baseline_outside, read_annotation,
                                                write_annotation)
from orchestrator.untrusted import InputError, file_kind, parse_xml, read_bounded, read_bytes

log = logging.getLogger(__name__)

NS = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
      "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
      "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
      "osp": "https://opensimulationplatform.com/SSP/OSPAnnotations",
      "rc": RC_NS}
TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration")
MAX_XML_BYTES = 16 * 2**20
#: largest file a String parameter names that export-ssp carries in the archive, and that reading an
#: SSP accepts as one (a rotor file is at most 1 MiB, ``rotor_fmu.rotor_file.MAX_FILE_BYTES``; the
#: shipped one has 6 kB)
MAX_NAMED_FILE_BYTES = 16 * 2**20
#: where the archive carries them: ``resources/files/<instance>/<file name>``
NAMED_FILES_DIR = "resources/files"


def _parse(data: bytes, where: str) -> ET.Element:
    if len(data) > MAX_XML_BYTES:
        raise ScenarioError(f"{where}: {len(data)} bytes of XML (limit {MAX_XML_BYTES}); not a plausible SSP file")
    try:                  # defusedxml: DOCTYPE/entities refused after decoding (UTF-16 too)
        return parse_xml(data, display=where, what="SSP file")
    except InputError as e:
        raise ScenarioError(str(e)) from None


def _read(path: Path, display: str | None = None) -> bytes:
    """The bytes of an SSP's XML file: a regular file of at most MAX_XML_BYTES (a problem named
    by ``display``, e.g. the archive rather than the temporary folder it was extracted to)."""
    try:
        return read_bytes(path, what="SSP file", limit=MAX_XML_BYTES,
                          limit_name="orchestrator.scenario.ssp.MAX_XML_BYTES")
    except InputError as e:
        raise ScenarioError(str(e).replace(str(path), display) if display else str(e)) from None


def _safe_member(name: str, where: str) -> PurePosixPath:
    p = PurePosixPath(name)
    if not name or name.startswith("/") or "\\" in name or ".." in p.parts or (len(name) > 1 and name[1] == ":"):
        raise ScenarioError(f"{where}: unsafe path {name!r} (absolute, '..' or a drive letter); "
                            "SSP sources must be relative paths inside the package")
    return p


class _Source:
    """Files of an SSP: an archive (extracted into ``work``) or the folder of a bare .ssd."""

    def __init__(self, path: Path, work: Path):
        self.path = Path(path)
        self.archive = self.path.suffix.lower() == ".ssp"
        if self.archive:
            from orchestrator.errors import FmuError
            from orchestrator.fmi.archive import safe_extract
            try:          # the FMU archive rules: regular file, names, links, sizes, ratios, CRC
                safe_extract(self.path, work, required="SystemStructure.ssd")
            except FmuError as e:
                raise ScenarioError(f"SSP archive: {e}") from None
            self.root = work
            self.ssd = work / "SystemStructure.ssd"
            # what messages call it: the archive, not the temporary folder it was extracted to (gone
            # when the command ends)
            self.name = f"{self.path} (SystemStructure.ssd)"
        else:
            self.root = self.path.parent
            self.ssd = self.path
            self.name = str(self.path)

    def shown(self, rel: str) -> str:
        """What messages call the member ``rel``: in an archive, the archive and the member's name
        (not the temporary folder it was extracted to), else its path."""
        return f"{self.path} ({rel})" if self.archive else str(self.root / rel)

    def file(self, rel: str, what: str) -> Path:
        _safe_member(rel, f"{self.name} ({what})")
        p = (self.root / rel).resolve()
        with contextlib.suppress(OSError):
            mode = os.stat(p).st_mode
            if not stat.S_ISREG(mode):
                raise ScenarioError(f"{self.name}: {what} {rel!r} is {file_kind(mode)}, expected a regular file; "
                                    "add the file to the SSP or fix the 'source'")
        if not p.is_file():
            where = "in the archive" if self.archive else f"looked in {self.root}"
            raise ScenarioError(f"{self.name}: {what} {rel!r} not found ({where}); "
                                "add the file to the SSP or fix the 'source'")
        return p


def _number(raw: str, what: str) -> float:
    """``raw`` (an XML attribute) as a float; ScenarioError naming ``what`` if it is none."""
    try:
        return float(raw)
    except (TypeError, ValueError):
        raise ScenarioError(f"{what} is {raw!r}, not a number; write a decimal number such as 1.5") from None


def _value(el: ET.Element, what: str) -> tuple[str, Any] | None:
    """The (type, value) of a ssv:Parameter, None if it has none; ScenarioError naming ``what``
    when the value is not of its type (xs:double, xs:int, xs:boolean)."""
    for t in TYPES:
        v = el.find(f"ssv:{t}", NS)
        if v is not None:
            raw = v.get("value")
            if raw is None:
                return None
            if t == "Real":
                return t, _number(raw, f"{what}: ssv:Real value")
            if t == "Integer" or (t == "Enumeration" and raw.strip().lstrip("-").isdigit()):
                try:
                    return t, int(raw.strip())
                except ValueError:
                    raise ScenarioError(f"{what}: ssv:{t} value is {raw!r}, not an integer; write a whole number "
                                        "such as 3") from None
            if t == "Boolean":
                if raw.strip().lower() not in ("true", "false", "1", "0"):
                    raise ScenarioError(f"{what}: ssv:Boolean value is {raw!r}; write true, false, 1 or 0")
                return t, raw.strip().lower() in ("true", "1")
            return t, raw
    return None


def _binding_values(owner: ET.Element, what: str, src: _Source, problems: list[str]) -> list[tuple]:
    """The (name, value, unit, units of its parameter set) of the parameter bindings of ``owner`` (a
    component or a system), in document order (a later binding wins); ``unit`` is the ``ssv:Real``
    value's unit attribute or None (:func:`_in_fmu_unit` converts). SSP 1.0: a binding's ``prefix``
    is *prepended* to the names of its parameter source ("supplying the name of the element plus a
    dot as a prefix on the binding" at a system level targets one element)."""
    out: list[tuple] = []
    for b in owner.findall("ssd:ParameterBindings/ssd:ParameterBinding", NS):
        prefix = b.get("prefix", "") or ""
        sets = []
        if b.get("source"):
            if b.get("source").startswith("#"):
                problems.append(f"{src.name}: {what}: parameter binding source "
                                f"{b.get('source')!r} (a reference into the SSD) is not supported; use an .ssv file "
                                "or inline ParameterValues")
                continue
            if (b.get("sourceBase") or "SSD") != "SSD":
                problems.append(f"{src.name}: {what}: parameter binding source {b.get('source')!r} with "
                                f"sourceBase={b.get('sourceBase')!r} (a file inside the component) is not supported; "
                                "put the .ssv file into the SSP beside SystemStructure.ssd")
                continue
            shown = src.shown(b.get("source"))
            sets.append(_parse(_read(src.file(b.get("source"), "parameter values"), shown), shown))
        sets += b.findall("ssd:ParameterValues/ssv:ParameterSet", NS)
        if b.find("ssd:ParameterMapping", NS) is not None:
            problems.append(f"{src.name}: {what}: parameter mappings (.ssm) are not "
                            "supported; write the values under the variables' own names")
        for ps in sets:
            set_units = _units_of(ps, "ssv:Units/ssc:Unit")
            for p in ps.findall("ssv:Parameters/ssv:Parameter", NS):
                name = prefix + p.get("name", "")
                try:
                    v = _value(p, f"{src.name}: parameter {name!r} of {what}")
                except ScenarioError as e:
                    problems.extend(e.problems)
                    continue
                if v is None:
                    problems.append(f"{src.name}: parameter {name!r} of {what} has no value")
                else:
                    real = p.find("ssv:Real", NS)
                    out.append((name, v[1], real.get("unit") if real is not None else None, set_units))
    return out


def _in_fmu_unit(value: Any, unit: str | None, set_units: dict, ssd_units: dict, path: str, var: str,
                 where: str, problems: list[str]) -> Any:
    """``value`` given in ``unit`` (an ssv:Real's) in the unit the FMU at ``path`` declares for
    ``var`` (SSP 1.0: a parameter value with a unit is converted to the variable's unit): from the
    parameter set's, the SSD's or the FMU's unit definitions. Unchanged without a unit, when the units
    agree or the FMU declares none; a problem when they cannot be converted. (Before, the number was
    applied as it is: 5 mm set a variable in m to 5 m.)"""
    if not unit or not isinstance(value, float):
        return value
    from orchestrator.fmi.archive import cached_model_description
    try:
        md = cached_model_description(path)
    except Exception:      # noqa: BLE001 - unreadable FMU: reported by the scenario checks
        return value
    v = md.variables.get(var)
    if v is None or not v.unit or v.unit == unit:
        return value
    us = set_units.get(unit) or ssd_units.get(unit) or md.units.get(unit)
    ud = md.units.get(v.unit) or ssd_units.get(v.unit)
    head = f"{where}: parameter {var!r} = {value!r} {unit}, for a variable in {v.unit}"
    if us is None or ud is None:
        missing = " and ".join(repr(u) for u, d in ((unit, us), (v.unit, ud)) if d is None)
        problems.append(f"{head}: {missing} is defined neither in the parameter set's <ssv:Units>, the SSD's "
                        "<ssd:Units> nor the FMU's <UnitDefinitions>; define it, or give the value in the "
                        "variable's unit")
        return value
    conv = us.to(ud)
    if conv is None:
        problems.append(f"{head}: the units have different dimensions; give the value in the variable's unit")
        return value
    return conv[0] * value + conv[1]


def _parameters(comp: ET.Element, path: str, ssd_units: dict, src: _Source, problems: list[str]) -> dict[str, Any]:
    what = f"component {comp.get('name')!r}"
    return {name: _in_fmu_unit(value, unit, set_units, ssd_units, path, name, f"{src.name}: {what}", problems)
            for name, value, unit, set_units in _binding_values(comp, what, src, problems)}


def _system_parameters(system: ET.Element, fmus: dict[str, dict], ssd_units: dict, src: _Source,
                       problems: list[str]) -> None:
    """The system's own parameter bindings into ``fmus``: a hierarchical name ``element.variable``
    (prefix prepended) sets that component's variable, over a value of the component's own
    bindings (SSP 1.0: bindings at a system level take precedence). A name of a connector of the
    system, or of no component, is reported (system connectors are not supported)."""
    what = f"system {system.get('name')!r}"
    for name, value, unit, set_units in _binding_values(system, what, src, problems):
        inst, dot, var = name.partition(".")
        if dot and var and inst in fmus:
            fmus[inst].setdefault("parameters", {})[var] = _in_fmu_unit(
                value, unit, set_units, ssd_units, fmus[inst]["path"], var, f"{src.name}: {what}", problems)
        else:
            problems.append(f"{src.name}: parameter {name!r} of the system's parameter bindings names no component "
                            f"variable (components: {', '.join(fmus) or 'none'}); write it as 'component.variable' "
                            "(or give the binding prefix=\"component.\"): parameters of the system's own connectors "
                            "are not supported")


def _ssd_units(root: ET.Element) -> dict:
    """``{unit name: UnitDef}`` of the SSD's ``<ssd:Units>`` (ssc:Unit with ssc:BaseUnit, as FMI's)."""
    return _units_of(root, "ssd:Units/ssc:Unit")


def _units_of(el: ET.Element, where: str) -> dict:
    """``{unit name: UnitDef}`` of the ssc:Unit elements at ``where`` under ``el`` (an SSD's
    ``ssd:Units``, a parameter set's ``ssv:Units``)."""
    from orchestrator.fmi.model_description import base_unit
    out = {}
    for u in el.findall(where, NS):
        found = base_unit(u.find("ssc:BaseUnit", NS)) if u.get("name") else None
        if found is not None:
            out[u.get("name")] = found
    return out


def _end_unit(comps: dict, fmus: dict, inst: str, var: str, ssd: str = "the SSD"):
    """(type, unit, unit definitions) of the connection end ``inst.var``: the unit the FMU declares for
    the variable, else the one the component's connector declares (``ssc:Real unit``); None when the
    FMU cannot be read (the loader reports that)."""
    from orchestrator.fmi.archive import cached_model_description     # read once per FMU, not per end
    try:
        md = cached_model_description(fmus[inst]["path"])
    except Exception:      # noqa: BLE001 - unreadable FMU: reported by the scenario checks
        return None
    v = md.variables.get(var)
    if v is None:
        return None
    unit = v.unit
    for con in comps[inst].findall("ssd:Connectors/ssd:Connector", NS):
        real = con.find("ssc:Real", NS) if con.get("name") == var else None
        declared = real.get("unit") if real is not None else None
        if declared and not unit:
            unit = declared
        elif declared and declared != unit:
            # the FMU's own unit is what its numbers are in; the SSD contradicting it is said, once
            log.warning("%s: connector %s.%s declares unit %r, but its FMU declares %r for the variable; the "
                        "FMU's unit is used (correct the connector's unit in the SSD)", ssd, inst, var, declared, unit)
    return v.type, unit, md.units


def _unit_conversion(conn: dict, c: ET.Element, comps: dict, fmus: dict, units: dict, where: str,
                     problems: list[str]) -> tuple[float, float] | None:
    """The (factor, offset) SSP 1.0 applies to a Real connection between connectors of different
    units before its LinearTransformation (``suppressUnitConversion`` absent or false; with it true
    ``(1, 0)``), None when the units agree or are not both known; a problem when the units differ
    and cannot be converted."""
    ends = [_end_unit(comps, fmus, *conn[k].split(".", 1), where) for k in ("from", "to")]
    if None in ends or ends[0][0] != "Real" or ends[1][0] != "Real":
        return None
    (_, su, sdefs), (_, du, ddefs) = ends
    if not su or not du or su == du:
        return None
    if (c.get("suppressUnitConversion") or "").strip().lower() in ("true", "1"):
        return 1.0, 0.0           # the number as it is, by the SSP's choice (an explicit gain: no unit warning)
    us, ud = units.get(su) or sdefs.get(su), units.get(du) or ddefs.get(du)
    head = f"{where}: connection {conn['from']} [{su}] -> {conn['to']} [{du}]"
    fix = ("or set suppressUnitConversion=\"true\" on the connection to pass the number as it is (then its "
           "LinearTransformation, if any, is the whole conversion)")
    if us is None or ud is None:
        missing = " and ".join(repr(u) for u, d in ((su, us), (du, ud)) if d is None)
        problems.append(f"{head}: SSP converts between the connectors' units, but {missing} is defined neither in "
                        f"the SSD's <ssd:Units> nor in the FMU's <UnitDefinitions>; define it, {fix}")
        return None
    conv = us.to(ud)
    if conv is None:
        problems.append(f"{head}: SSP converts between the connectors' units, but they have different dimensions; "
                        f"connect variables of the same dimension, {fix}")
        return None
    return None if conv == (1.0, 0.0) else conv      # None: one unit, two names


def scenario_from_ssp(path: Path | str, work: Path | str) -> dict:
    """The scenario document (a dict in the YAML format) of an SSP archive or .ssd file.

    ``work`` is a folder the archive is extracted into (FMU paths point there).
    Raises :class:`ScenarioError` listing what cannot be read or is unsupported.

    Length: the SSD read in document order (system, components, parameter bindings,
    connections, experiment), each part's unsupported forms reported where they are met.
    """
    src = _Source(Path(path), Path(work))
    root = _parse(_read(src.ssd, src.name), src.name)
    if root.tag != f"{{{NS['ssd']}}}SystemStructureDescription":
        raise ScenarioError(f"{src.name}: root element is {root.tag}, expected ssd:SystemStructureDescription")
    system = root.find("ssd:System", NS)
    if system is None:
        raise ScenarioError(f"{src.name}: no ssd:System element; re-export the SSP")
    problems: list[str] = []
    if system.find("ssd:Elements/ssd:System", NS) is not None:
        problems.append(f"{src.name}: nested systems are not supported; flatten the system into one level")
    if system.find("ssd:Elements/ssd:SignalDictionaryReference", NS) is not None or \
            system.find("ssd:SignalDictionaries", NS) is not None:
        problems.append(f"{src.name}: signal dictionaries are not supported; connect the components' connectors "
                        "directly")
    fmus: dict[str, dict] = {}
    comps: dict[str, ET.Element] = {}
    units = _ssd_units(root)
    for comp in system.findall("ssd:Elements/ssd:Component", NS):
        name, source = comp.get("name"), comp.get("source")
        if not name or not source:
            problems.append(f"{src.name}: a component lacks 'name' or 'source'")
            continue
        if name in fmus:
            problems.append(f"{src.name}: two components are called {name!r} (the second would replace the "
                            "first); give each component its own name")
            continue
        if comp.get("type") not in (None, "application/x-fmu-sharedlibrary"):
            problems.append(f"{src.name}: component {name!r} has type {comp.get('type')!r}; only FMUs "
                            "(application/x-fmu-sharedlibrary) are supported")
            continue
        entry: dict[str, Any] = {"path": str(src.file(source, f"FMU of component {name!r}"))}
        params = _parameters(comp, entry["path"], units, src, problems)
        if params:
            entry["parameters"] = params
        fmus[name] = entry
        comps[name] = comp
    _system_parameters(system, fmus, units, src, problems)
    connections = []
    for c in system.findall("ssd:Connections/ssd:Connection", NS):
        s_el, s_con, d_el, d_con = (c.get(k) for k in ("startElement", "startConnector", "endElement",
                                                      "endConnector"))
        if not (s_el and d_el):
            problems.append(f"{src.name}: connection {s_con} -> {d_con} touches the system's own connectors; "
                            "only component-to-component connections are supported")
            continue
        conn: dict[str, Any] = {"from": f"{s_el}.{s_con}", "to": f"{d_el}.{d_con}"}
        for kind in ("BooleanMappingTransformation", "IntegerMappingTransformation",
                     "EnumerationMappingTransformation"):
            if c.find(f"ssc:{kind}", NS) is not None or c.find(f"ssd:{kind}", NS) is not None:
                problems.append(f"{src.name}: connection {conn['from']} -> {conn['to']}: a {kind} is not supported "
                                "(the input would get the output's value unmapped); map the values in an FMU, or "
                                "connect variables that need no mapping")
        lt = c.find("ssc:LinearTransformation", NS)
        if lt is None:
            lt = c.find("ssd:LinearTransformation", NS)
        if lt is not None:
            try:
                for attr, key, default in (("factor", "gain", 1.0), ("offset", "offset", 0.0)):
                    conn[key] = _number(lt.get(attr, default), f"{src.name}: connection {conn['from']} -> "
                                        f"{conn['to']}: LinearTransformation {attr}")
            except ScenarioError as e:
                problems.extend(e.problems)
                continue
        if s_el in fmus and d_el in fmus:
            # SSP 1.0: a Real connection between different units converts them, then applies its
            # LinearTransformation: target = factor * convert(source) + offset
            conv = _unit_conversion(conn, c, comps, fmus, units, src.name, problems)
            if conv is not None:
                factor, off = conn.get("gain", 1.0), conn.get("offset", 0.0)
                conn["gain"], conn["offset"] = factor * conv[0], factor * conv[1] + off
        connections.append(conn)
    if problems:
        raise ScenarioError(problems)
    doc: dict[str, Any] = {"name": root.get("name") or Path(path).stem, "fmus": fmus, "connections": connections}
    if system.get("description"):
        doc["description"] = system.get("description")
    de = root.find("ssd:DefaultExperiment", NS)
    if de is not None:
        for attr, key in (("startTime", "start_time"), ("stopTime", "stop_time")):
            if de.get(attr) is not None:
                doc[key] = _number(de.get(attr), f"{src.name}: DefaultExperiment {attr}")
        fixed = de.find("ssd:Annotations/ssc:Annotation/osp:Algorithm/osp:FixedStepAlgorithm", NS)
        if fixed is not None and fixed.get("baseStepSize"):
            doc["coupling"] = {"scheme": "jacobi", "macro_step": _number(
                fixed.get("baseStepSize"), f"{src.name}: osp:FixedStepAlgorithm baseStepSize")}
    _carried_files(read_annotation(root, doc, src.name), doc, src)
    return doc


def _carried_files(files: dict[tuple[str, str], str], doc: dict, src: _Source) -> None:
    """Set each String parameter the annotation's ``files`` lists to the extracted copy of the
    archive member it names (for a bare .ssd: the file beside it). Untrusted: the parameter's value
    in the SSD must be the member's name; the member must be a relative path under ``resources/``
    (no ``..``, not absolute, no backslash or drive letter), no component of it a symbolic link, and
    a regular file of at most :data:`MAX_NAMED_FILE_BYTES`. Every problem names the archive and the
    member; ScenarioError listing them all."""
    problems: list[str] = []
    where = f'{src.name}: ssc:Annotation type="{ANNOTATION_TYPE}"'
    root = src.root.resolve()
    for (inst, name), member in files.items():
        key = f"'files.{inst}.{name}'"
        value = doc["fmus"][inst].get("parameters", {}).get(name)
        if value != member:
            problems.append(f"{where}: {key} = {member!r:.200} but the SSD sets {inst}.{name} = {value!r:.200}; make "
                            "them equal (export the SSP again), or remove the entry from 'files'")
            continue
        parts = PurePosixPath(member).parts
        if not member.startswith("resources/") or ".." in parts or "\\" in member or ":" in member \
                or "\0" in member or len(parts) < 2:
            problems.append(f"{where}: {key} = {member!r:.200} is no file inside the package: a carried file is a "
                            "relative path under resources/ (no '..', not absolute, no backslash or drive letter); "
                            "export the SSP again")
            continue
        shown = src.shown(member)
        what = f"the file fmus.{inst}.parameters.{name} names"
        path, problem = root, None
        for part in parts:          # no link anywhere on the way (an archive has none; a folder may)
            path = path / part
            try:
                st = os.lstat(path)
            except FileNotFoundError:
                problem = f"{shown}: {what} is not in the {'archive' if src.archive else 'folder'}; add it, or " \
                          "export the SSP again"
                break
            except OSError as e:
                problem = f"{shown}: cannot inspect {what} ({e.strerror or e})"
                break
            if stat.S_ISLNK(st.st_mode):
                problem = f"{shown}: {what} is a symbolic link (to {os.readlink(path)!r:.200}); a file an SSP " \
                          "carries must be a regular file inside it: put the file itself there"
                break
        else:
            if not stat.S_ISREG(st.st_mode):
                problem = f"{shown}: {what} is {file_kind(st.st_mode)}, expected a regular file"
            elif st.st_size > MAX_NAMED_FILE_BYTES:
                problem = f"{shown}: {what} has {st.st_size} bytes, more than an SSP may carry for a String " \
                          f"parameter ({MAX_NAMED_FILE_BYTES}, orchestrator.scenario.ssp.MAX_NAMED_FILE_BYTES); " \
                          "check the archive"
        if problem:
            problems.append(problem)
        else:
            doc["fmus"][inst]["parameters"][name] = str(path)
    if problems:
        raise ScenarioError(problems)


# ------------------------------------------------------------------------------------ export
def _type_el(parent: ET.Element, ns: str, fmi_type: str, value=None) -> None:
    # Enumeration values travel as fmi2Integer; libcosim (0.10) cannot read ssc:/ssv:Enumeration, so they
    # are written as Integer (our reader takes an Integer value for an Enumeration variable too)
    el = ET.SubElement(parent, f"{{{NS[ns]}}}{'Integer' if fmi_type == 'Enumeration' else fmi_type}")
    if value is not None:
        el.set("value", "true" if value is True else "false" if value is False else repr(value)
               if isinstance(value, float) else str(value))


def check_output_path(out: Path | str) -> Path:
    """``out`` as a place to write the archive: an existing SSP archive or empty file (replaced) or a
    new name in an existing folder. Raises :class:`InputError` for a directory, FIFO, device or
    socket, a symbolic link (never written through), an existing file that is not an SSP archive
    (a scenario YAML, an FMU: never replaced) or a missing folder (not created)."""
    out = Path(out)
    expected = "expected a new or existing regular .ssp file"
    try:
        st = os.lstat(out)
    except (FileNotFoundError, NotADirectoryError):     # a new name (its folder is checked below)
        st = None
    except OSError as e:
        raise InputError(f"{out}: cannot inspect the output path ({e.strerror or e}); {expected}") from None
    if st is not None:
        if stat.S_ISLNK(st.st_mode):
            raise InputError(f"{out}: is a symbolic link (to {os.readlink(out)}); export-ssp does not write through "
                             f"a link; {expected}: remove the link or give another path")
        if not stat.S_ISREG(st.st_mode):
            fix = f"name the file inside it, e.g. {out / 'system.ssp'}" if stat.S_ISDIR(st.st_mode) else \
                "give another path (export-ssp writes no pipes or devices)"
            raise InputError(f"{out}: is {file_kind(st.st_mode)}; {expected}: {fix}")
        what = _not_an_ssp(out, st.st_size)
        if what:       # `export-ssp s.yaml s.yaml` replaced the scenario itself with the archive
            raise InputError(f"{out}: exists and is not an SSP archive ({what}); export-ssp replaces only an "
                             "earlier .ssp file (or an empty file): give a new name, e.g. "
                             f"{out.with_suffix('.ssp') if out.suffix != '.ssp' else out.with_name(out.stem + '-new.ssp')}"
                             ", or remove the file first")
        return out
    parent = out.parent
    if not parent.is_dir():
        what = "does not exist" if not parent.exists() else "is not a folder"
        raise InputError(f"{out}: the folder {parent} {what}; export-ssp does not create folders: create it "
                         f"(mkdir -p {parent}) or give a path in an existing folder")
    return out


def _not_an_ssp(out: Path, size: int) -> str | None:
    """Why the existing regular file ``out`` is no SSP archive that export-ssp may replace (None: it is
    one, or it is empty): a zip with ``SystemStructure.ssd`` at the top. Only the zip's central
    directory is read (its size is bounded by the file's)."""
    if size == 0:
        return None
    try:
        with open(out, "rb") as f:
            head = f.read(4)
            if head != b"PK\x03\x04":
                text = head.isascii() and all(32 <= b < 127 or b in (9, 10, 13) for b in head)
                return "it holds text, e.g. a scenario" if text else "it is no zip archive"
            f.seek(0)
            with zipfile.ZipFile(f) as zf:
                names = zf.namelist()
    except (OSError, zipfile.BadZipFile, ValueError, EOFError) as e:
        return f"it cannot be read as a zip archive: {e}"
    if "SystemStructure.ssd" not in names:
        kind = "an FMU" if "modelDescription.xml" in names else "a zip archive"
        return f"it is {kind} without SystemStructure.ssd"
    return None


def _write_archive(out: Path, root: ET.Element, files: dict[str, Path], blobs: dict[str, bytes]) -> None:
    """The archive written to an exclusively created temporary file beside ``out``, then renamed
    over it (``os.replace`` replaces a name, never writes through it); removed on failure.
    ``files``: member -> file (the FMUs), ``blobs``: member -> content (the named files)."""
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".part", dir=out.parent)
    except OSError as e:
        raise InputError(f"{out}: cannot create a file in {out.parent} ({e.strerror or e}); give a path in a "
                         "folder you may write to") from None
    try:
        os.fchmod(fd, 0o644)
        with os.fdopen(fd, "wb") as f, zipfile.ZipFile(f, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.writestr("SystemStructure.ssd", ET.tostring(root, encoding="utf-8", xml_declaration=True))
            for member, path in files.items():
                zf.write(path, member)
            for member, data in blobs.items():
                zf.writestr(member, data)
        os.replace(tmp, out)
    except BaseException as e:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(e, OSError) and (not e.filename or str(e.filename) == str(tmp)):
            # a write error (disk full) named no file: "error: No space left on device"
            from orchestrator.results.safe_write import space_fix
            raise InputError(f"{out}: cannot write the archive ({e.strerror or e}); {space_fix(e, 'check that folder')} "
                             "or give a path on another "
                             "disk (nothing was written; an earlier file there is left as it was)") from None
        raise


#: names Windows reserves for devices (``con.yaml`` cannot be created there)
_WINDOWS_DEVICES = {"CON", "PRN", "AUX", "NUL", *(f"COM{i}" for i in range(1, 10)), *(f"LPT{i}" for i in range(1, 10))}


def _member_name(inst: str, filename: str, taken: Mapping[str, bytes]) -> str:
    """``resources/files/<inst>/<filename>``, the name made portable (letters, digits, ``._-``; no
    leading or trailing dot, no Windows device name) and unique among ``taken`` ignoring case: on
    Windows and macOS ``R.yaml`` and ``r.yaml`` (or instances ``Rotor`` and ``rotor``) extract to one
    file, and one parameter would read the other's."""
    stem = re.sub(r"[^A-Za-z0-9._-]", "_", filename)[:100].strip(".") or "file"
    if stem.split(".")[0].upper() in _WINDOWS_DEVICES:
        stem = f"_{stem}"
    base, dot, ext = stem.rpartition(".") if "." in stem else (stem, "", "")
    folded = {t.casefold() for t in taken}
    member, n = f"{NAMED_FILES_DIR}/{inst}/{stem}", 1
    while member.casefold() in folded:
        n += 1
        member = f"{NAMED_FILES_DIR}/{inst}/{base}_{n}{dot}{ext}"
    return member


def check_carry_folders(folders) -> tuple[Path, ...]:
    """The folders of ``--carry-files-from`` (``export_ssp(carry_files_from=...)``) as real paths
    (``~`` expanded, links resolved); InputError naming one that is no existing folder."""
    if isinstance(folders, (str, os.PathLike)):
        folders = [folders]
    out = []
    for d in folders:
        try:
            real = Path(d).expanduser().resolve()
            ok = real.is_dir()
        except (OSError, RuntimeError, ValueError):
            ok = False
        if not ok:
            raise InputError(f"--carry-files-from {d}: no such folder; give an existing folder whose files the "
                             "SSP may carry (the folder itself, not a file in it)")
        out.append(real)
    return tuple(out)


def _carry_folders(scenario, extra: tuple[Path, ...]) -> list[tuple[Path, str]]:
    """``(real folder, what it is)``: where a file that the scenario file's String parameters name
    may lie for export-ssp to carry it (see :func:`_named_files`)."""
    folders = []
    if scenario.source is not None:
        folders.append((Path(scenario.source).resolve().parent, "the scenario's folder"))
    if getattr(scenario, "extracted", None) is not None:
        folders.append((Path(scenario.extracted).resolve(), "the folder its SSP was extracted to"))
    return folders + [(d, "a --carry-files-from folder") for d in extra]


def _read_named(real: Path, checked: os.stat_result) -> bytes:
    """The content of the regular file ``real`` (links resolved) that export-ssp carries: opened
    without following a link and without blocking, then the opened file checked to be the regular
    file that was checked before (a FIFO or a link planted in between is not read), at most
    :data:`MAX_NAMED_FILE_BYTES`. InputError saying why not (the warning's reason)."""
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
    fd = os.open(real, flags)
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode) or (st.st_dev, st.st_ino) != (checked.st_dev, checked.st_ino):
            raise InputError("it was replaced while export-ssp read it; export again")
        if st.st_size > MAX_NAMED_FILE_BYTES:
            raise InputError(f"it has {st.st_size} bytes, more than export-ssp carries ({MAX_NAMED_FILE_BYTES}, "
                             "orchestrator.scenario.ssp.MAX_NAMED_FILE_BYTES)")
        data = read_bounded(lambda k: os.read(fd, k), MAX_NAMED_FILE_BYTES)     # bounded even if it grows
        if data is None:
            raise InputError(f"it grew past {MAX_NAMED_FILE_BYTES} bytes while export-ssp read it "
                             "(orchestrator.scenario.ssp.MAX_NAMED_FILE_BYTES)")
        return data
    finally:
        os.close(fd)


def _named_files(scenario, carry_files_from=()) -> tuple[dict[tuple[str, str], str], dict[str, bytes]]:
    """The files the scenario's String parameters name (a rotor file, ``loader.named_files``) that
    the archive carries: ``{(instance, parameter): member}`` and ``{member: content}`` (a file named
    twice is carried once).

    Which: a scenario file is untrusted (one from someone else could name ``~/.ssh/id_rsa`` and
    the user's export-ssp would pack it into the SSP they share), so a file is carried only when
    it is a regular file (a FIFO, device or socket is never opened) and, for a value the scenario
    file sets, when its real path (links resolved) lies in the scenario's folder (the folder of
    the YAML, .ssp or .ssd; for an SSP also the folder it was extracted to) or in a folder of
    ``carry_files_from`` (``--carry-files-from``, :func:`check_carry_folders`). A value the caller
    gave (``--set``, ``load_scenario(overrides=...)``: its origin a
    :class:`~orchestrator.scenario.model.SetOrigin`) names the caller's own choice: its file is
    carried wherever it lies. A folder is never carried. A file that is not carried (a folder,
    outside, not regular, larger than
    :data:`MAX_NAMED_FILE_BYTES`, unreadable) keeps its value, and a warning names the parameter,
    the path, why, and the fix (copy it next to the scenario, or the option; for a file too large,
    where the FMU opens it when the SSP runs: a relative path from the working directory there, an
    absolute one on that machine)."""
    from orchestrator.fmi.archive import read_model_description
    from orchestrator.scenario.loader import named_files
    from orchestrator.scenario.model import SetOrigin
    variables = {f.name: read_model_description(f.path).variables for f in scenario.fmus}
    folders = _carry_folders(scenario, check_carry_folders(carry_files_from))
    values: dict[tuple[str, str], str] = {}
    blobs: dict[str, bytes] = {}
    carried: dict[Path, str] = {}
    for inst, name, path in named_files(scenario, variables, special=True):
        spec = scenario.fmu(inst)
        value, origin = spec.parameters[name], spec.parameter_origins.get(name)
        key = f"fmus.{inst}.parameters.{name}"
        if path.is_absolute():
            how = ("the FMU opens it at that absolute path where the SSP runs; run the SSP on a machine that "
                   "has the file there")
        else:
            how = ("the FMU opens that relative path from the working directory where the SSP runs; run the "
                   "SSP where that path resolves, or give an absolute path in the scenario")
        thing = "a file"
        try:
            real = path.resolve()
            st = os.stat(real)                     # never opened before it is known to be regular
            refusal = None
            if stat.S_ISDIR(st.st_mode):
                thing = "a folder"
                where = "at that absolute path" if path.is_absolute() else "from the working directory"
                refusal = ("export-ssp carries files, not folders",
                           f"the SSD keeps the value as written, and the FMU looks for the folder {where} "
                           f"where the SSP runs: put a copy there before running it, or, if the FMU needs "
                           f"only one file in it, set {key} to that file (export-ssp then carries it)")
            elif not isinstance(origin, SetOrigin) and not any(real.is_relative_to(d) for d, _ in folders):
                refusal = _outside(key, origin, real, path, folders)
            elif not stat.S_ISREG(st.st_mode):
                at = folders[0][0] if folders else real.parent
                refusal = (f"it is {file_kind(st.st_mode)}, not a regular file, and export-ssp opens no pipes, "
                           "devices or sockets",
                           f"the SSD keeps the value as written; to carry its content, save it as a regular file "
                           f"next to the scenario (in {at}) and set {key} to that file")
            if refusal:
                why, how = refusal
                raise InputError(why)
            if real not in carried:
                data = _read_named(real, st)
                carried[real] = _member_name(inst, path.name, blobs)
                blobs[carried[real]] = data
        except (InputError, OSError, RuntimeError) as e:
            relative = "" if path.is_absolute() else " (relative)"
            warnings.warn(f"export-ssp: {key} = {value!r}{relative} names {thing} the SSP does not carry "
                          f"({e}): {how}", stacklevel=3)
            continue
        values[(inst, name)] = carried[real]
    return values, blobs


def _outside(key: str, origin: str | None, real: Path, path: Path,
             folders: list[tuple[Path, str]]) -> tuple[str, str]:
    """(why, fix) of the warning for a file outside every folder export-ssp carries from."""
    shown = f"{real}" if real == path.absolute() else f"its real path {real}"
    where = "; ".join(f"{what} {d}" for d, what in folders)
    set_at = f"; the value is set at {origin}" if origin else ""
    if folders:
        why = (f"{shown} is outside {where}: export-ssp carries a file that the scenario file names only from "
               f"there, so that a scenario from elsewhere cannot pack your files into the archive you share{set_at}")
        copy = f"copy the file next to the scenario (into {folders[0][0]}) and set {key} to that copy, or "
    else:
        why = (f"{shown}: the scenario has no file (made in code), so export-ssp carries a file its values name "
               f"only from a --carry-files-from folder{set_at}")
        copy = ""
    return why, (f"the SSD keeps the value as written; to carry the file, {copy}give --carry-files-from "
                 f"{shlex.quote(str(real.parent))} (export_ssp(..., carry_files_from=[...])) if you mean to share "
                 "what it holds")


def export_ssp(scenario, out: Path | str, *, carry_files_from=()) -> Path:
    """Write ``scenario`` as an SSP 1.0 archive ``out`` (see the module docstring); return its path.
    ``carry_files_from``: folders (besides the scenario's own) whose files the archive may carry
    when the scenario file's String parameters name them (:func:`_named_files`).

    Length: the SSD document written top to bottom as SSP 1.0 lays it out (components and
    connectors, connections, parameter bindings, default experiment), then the archive."""
    from orchestrator.fmi.archive import read_model_description
    out = check_output_path(out)
    carry_files_from = check_carry_folders(carry_files_from)
    c = scenario.coupling
    if c.scheme != "jacobi" or c.extrapolation_order or c.substeps != 1 or any(f.substeps for f in scenario.fmus):
        warnings.warn(f"export-ssp: SSP has no coupling scheme; libcosim runs the exported system as Jacobi with "
                      f"zero-order hold (this scenario: {c.scheme}, extrapolation_order {c.extrapolation_order}, "
                      f"substeps {c.substeps}); rotorcosim itself reads the whole coupling section back from "
                      f"the archive's {ANNOTATION_TYPE} annotation", stacklevel=2)
    starts = [f"{f.name}.{n}" for f in scenario.fmus for n in f.parameters
              if read_model_description(f.path).variables[n].causality not in ("parameter", "input")]
    if starts:
        warnings.warn(f"export-ssp: {', '.join(starts)} are start values of outputs or locals (initial=\"exact\"); "
                      "the SSP carries them, but libcosim's SSP loader sets only parameters and inputs and "
                      "ignores them", stacklevel=2)
    carried, blobs = _named_files(scenario, carry_files_from)
    if scenario.compare and "build_fmus" in scenario.compare:
        b = scenario.compare["build_fmus"]
        warnings.warn(f"export-ssp: compare.build_fmus (from {b.get('from') if isinstance(b, Mapping) else b!r}) "
                      "is not written into the archive's annotation: the archive carries the FMUs, not the sources "
                      "they were built from nor the monolithic-reference models a _reference_models.py there "
                      f"registers, so `rotorcosim compare {out}` needs a co-simulation reference for those FMUs",
                      stacklevel=2)
    _warn_baseline(scenario, out)
    for ns, uri in NS.items():
        ET.register_namespace(ns, uri)
    root = ET.Element(f"{{{NS['ssd']}}}SystemStructureDescription", {"version": "1.0", "name": scenario.name,
                                                                     "generationTool": "rotorcosim export-ssp"})
    system = ET.SubElement(root, f"{{{NS['ssd']}}}System", {"name": scenario.name})
    if scenario.description:
        system.set("description", scenario.description)
    elements = ET.SubElement(system, f"{{{NS['ssd']}}}Elements")
    used: dict[str, set[str]] = {f.name: set() for f in scenario.fmus}
    for cn in scenario.connections:
        used[cn.src_instance].add(cn.src_variable)
        used[cn.dst_instance].add(cn.dst_variable)
    files: dict[str, Path] = {}
    for f in scenario.fmus:
        md = read_model_description(f.path)
        member = f"resources/{Path(f.path).name}"
        if member in files and files[member] != Path(f.path).resolve():
            member = f"resources/{f.name}_{Path(f.path).name}"
        files[member] = Path(f.path).resolve()
        comp = ET.SubElement(elements, f"{{{NS['ssd']}}}Component",
                             {"name": f.name, "source": member, "type": "application/x-fmu-sharedlibrary"})
        conns = ET.SubElement(comp, f"{{{NS['ssd']}}}Connectors")
        for var in sorted(used[f.name], key=lambda v: md.variables[v].value_reference):
            v = md.variables[var]
            con = ET.SubElement(conns, f"{{{NS['ssd']}}}Connector", {"name": var, "kind": v.causality})
            _type_el(con, "ssc", v.type)
        if f.parameters:
            pv = ET.SubElement(ET.SubElement(ET.SubElement(comp, f"{{{NS['ssd']}}}ParameterBindings"),
                                             f"{{{NS['ssd']}}}ParameterBinding"), f"{{{NS['ssd']}}}ParameterValues")
            ps = ET.SubElement(pv, f"{{{NS['ssv']}}}ParameterSet", {"version": "1.0", "name": "parameters"})
            plist = ET.SubElement(ps, f"{{{NS['ssv']}}}Parameters")
            for name, value in f.parameters.items():
                p = ET.SubElement(plist, f"{{{NS['ssv']}}}Parameter", {"name": name})
                # a carried file: its member's name (relative to the package), set to the extracted copy on reading
                _type_el(p, "ssv", md.variables[name].type, carried.get((f.name, name), value))
    cel = ET.SubElement(system, f"{{{NS['ssd']}}}Connections")
    for cn in scenario.connections:
        el = ET.SubElement(cel, f"{{{NS['ssd']}}}Connection", {
            "startElement": cn.src_instance, "startConnector": cn.src_variable,
            "endElement": cn.dst_instance, "endConnector": cn.dst_variable,
            # our connection is exactly gain * value + offset: no unit conversion on top (SSP 1.0
            # converts between different units unless told not to)
            "suppressUnitConversion": "true"})
        if cn.gain != 1.0 or cn.offset != 0.0:
            ET.SubElement(el, f"{{{NS['ssc']}}}LinearTransformation",
                          {"factor": repr(float(cn.gain)), "offset": repr(float(cn.offset))})
    de = ET.SubElement(root, f"{{{NS['ssd']}}}DefaultExperiment",
                       {"startTime": repr(float(scenario.start_time)), "stopTime": repr(float(scenario.stop_time))})
    ann = ET.SubElement(ET.SubElement(de, f"{{{NS['ssd']}}}Annotations"), f"{{{NS['ssc']}}}Annotation",
                        {"type": "com.opensimulationplatform"})
    ET.SubElement(ET.SubElement(ann, f"{{{NS['osp']}}}Algorithm"), f"{{{NS['osp']}}}FixedStepAlgorithm",
                  {"baseStepSize": repr(float(c.macro_step))})
    write_annotation(root, scenario, carried)
    _check_xml_chars(root)
    _write_archive(check_output_path(out), root, files, blobs)
    return out


def _warn_baseline(scenario, out: Path) -> None:
    """``compare.baseline`` is read relative to the comparison file, so `compare OUT` looks for it
    beside the archive: warn when that is not the file the scenario's comparison reads (the archive
    does not carry it: --update-baseline writes it)."""
    baseline = (scenario.compare or {}).get("baseline")
    if not isinstance(baseline, str) or not baseline.strip() or scenario.source is None:
        return
    if baseline_outside(baseline):
        warnings.warn(f"export-ssp: compare.baseline {baseline!r} is outside the comparison file's folder, which "
                      f"`rotorcosim compare {out}` refuses (an archive's annotation must not name a file "
                      "--update-baseline writes elsewhere); give a path such as baselines/NAME.json in the "
                      "scenario, or compare the scenario file itself", stacklevel=3)
        return
    mine = (Path(scenario.source).parent / baseline).resolve()
    there = (out.parent / baseline).resolve()
    if mine != there:
        state = "exists" if there.is_file() else "does not exist"
        warnings.warn(f"export-ssp: compare.baseline {baseline!r} is read relative to the comparison file: "
                      f"`rotorcosim compare {out}` reads {there}, which {state}, not {mine} (the archive does not "
                      f"carry the baseline: --update-baseline writes it); copy the baseline there, or write the "
                      f"archive beside the scenario", stacklevel=3)


_NOT_XML = re.compile("[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def _check_xml_chars(root: ET.Element) -> None:
    """Refuse a text the SSD cannot hold: XML 1.0 has no control characters but tab, newline and
    carriage return (a description "bell \\x07" was written as is, and the archive could then not
    be read back, by rotorcosim or any SSP tool: "not well-formed (invalid token)"). Each problem
    names the scenario field it came from."""
    problems: list[str] = []
    component = parameter = None
    for el in root.iter():
        tag = el.tag.split("}")[-1]
        if tag == "Component":
            component = el.get("name")
        elif tag == "Parameter":
            parameter = el.get("name")
        for attr, text in [*el.attrib.items(), ("text", el.text or "")]:
            m = _NOT_XML.search(text)
            if m is None:
                continue
            if tag in ("SystemStructureDescription", "System") and attr in ("name", "description"):
                where = f"'{attr}'"                       # the scenario's own name and description
            elif tag in ("String", "Real", "Integer", "Boolean") and attr == "value":
                where = f"'fmus.{component}.parameters.{parameter}'"
            else:
                where = f"the {attr} of the SSD element {tag}"
            problem = f"{where} holds the control character U+{ord(m.group()):04X} at character {m.start() + 1}"
            if problem not in problems:                   # the name is the SSD's and the System's
                problems.append(problem)
    if problems:
        raise InputError(f"export-ssp: {'; '.join(problems[:5])}, which an SSP (XML 1.0) cannot hold; remove "
                         f"{'it' if len(problems) == 1 else 'them'} from the scenario (nothing was written)")
