"""Read FMU archives as untrusted input.

An FMU is a zip file from anyone. Before anything in it is used this module
checks the archive and parses ``modelDescription.xml`` safely:

* member names: no absolute paths, no drive letters, no backslashes, no ``..``
  components, no NUL, no duplicates;
* no symbolic links or other special files;
* sizes: each member at most :data:`MAX_MEMBER_BYTES`, all members together at
  most :data:`MAX_TOTAL_BYTES`, at most :data:`MAX_MEMBERS` members, and no
  member larger than :data:`RATIO_CHECK_MIN_BYTES` whose compression ratio
  exceeds :data:`MAX_COMPRESSION_RATIO` (zip bombs); sizes are enforced while
  extracting too, so a lying header does not help;
* ``modelDescription.xml`` at most :data:`MAX_XML_BYTES`, without a DOCTYPE
  (so no entity declarations, internal or external), FMI version 2.0, with a
  ``CoSimulation`` element.

Every problem raises :class:`orchestrator.errors.FmuError` naming the file,
what is wrong and how to fix it.

The limits are module constants read at call time (tests monkeypatch them).
"""

from __future__ import annotations

import functools
import os
import stat
import sys
import zipfile
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any, Mapping
from xml.etree import ElementTree

from orchestrator.errors import FmuError

MAX_MEMBER_BYTES = 512 * 2**20        # one member, uncompressed
MAX_TOTAL_BYTES = 2 * 2**30           # all members, uncompressed
MAX_MEMBERS = 20000
MAX_XML_BYTES = 32 * 2**20            # modelDescription.xml
MAX_COMPRESSION_RATIO = 1000.0        # uncompressed / compressed, for members above:
RATIO_CHECK_MIN_BYTES = 4 * 2**20

_CHUNK = 1 << 20


@dataclass(frozen=True)
class Variable:
    """One ``ScalarVariable`` of a model description."""

    name: str
    value_reference: int
    type: str                      # "Real" | "Integer" | "Boolean" | "String" | "Enumeration"
    causality: str                 # "parameter" | "calculatedParameter" | "input" | "output" | "local" | "independent"
    variability: str               # "constant" | "fixed" | "tunable" | "discrete" | "continuous"
    start: Any = None              # parsed to float/int/bool/str when given
    description: str = ""
    unit: str = ""


@dataclass(frozen=True)
class ModelDescription:
    """The parts of an FMI 2.0 ``modelDescription.xml`` the orchestrator uses."""

    path: Path                     # the FMU file it came from
    fmi_version: str
    model_name: str
    guid: str
    model_identifier: str          # of the CoSimulation element
    can_interpolate_inputs: bool = False
    max_output_derivative_order: int = 0
    can_get_and_set_fmu_state: bool = False
    can_handle_variable_step: bool = True
    needs_execution_tool: bool = False
    can_be_instantiated_only_once_per_process: bool = False
    description: str = ""
    generation_tool: str = ""
    default_experiment: Mapping[str, float] = field(default_factory=dict)
    variables: Mapping[str, Variable] = field(default_factory=dict)   # name -> Variable, in file order

    def inputs(self) -> list[Variable]:
        return [v for v in self.variables.values() if v.causality == "input"]

    def outputs(self) -> list[Variable]:
        return [v for v in self.variables.values() if v.causality == "output"]

    def parameters(self) -> list[Variable]:
        return [v for v in self.variables.values() if v.causality == "parameter"]


def _fail(path, what: str, fix: str) -> FmuError:
    return FmuError(f"{path}: {what}; {fix}")


def _open_zip(path: Path) -> zipfile.ZipFile:
    path = Path(path)
    if not path.exists():
        raise _fail(path, "FMU file not found", "check the path (relative paths in a scenario are relative to the YAML file)")
    if path.is_dir():
        raise _fail(path, "is a directory, expected an .fmu (zip) file", "point to the .fmu file itself")
    try:
        return zipfile.ZipFile(path)
    except zipfile.BadZipFile as e:
        raise _fail(path, f"not a valid zip archive ({e})", "rebuild or re-export the FMU") from None
    except OSError as e:
        raise _fail(path, f"cannot be read ({e})", "check permissions and that the file is complete") from None


def _check_name(path: Path, name: str) -> PurePosixPath:
    bad = None
    if not name or "\x00" in name:
        bad = "an empty name or a NUL character"
    elif "\\" in name:
        bad = "a backslash (Windows path separator)"
    elif name.startswith("/"):
        bad = "an absolute path"
    elif len(name) >= 2 and name[1] == ":":
        bad = "a drive letter"
    else:
        parts = PurePosixPath(name).parts
        if ".." in parts:
            bad = "a '..' component (path traversal)"
    if bad:
        raise _fail(path, f"unsafe member name {name!r} in the archive: it has {bad}",
                    "do not use this FMU; ask its author to rebuild it with plain relative member names")
    return PurePosixPath(name)


def check_archive(path: Path | str) -> list[zipfile.ZipInfo]:
    """Check every member header of the FMU at ``path``; return the member list.

    Raises :class:`FmuError` for unsafe names, links, too many or too large
    members, or absurd compression ratios.
    """
    path = Path(path)
    with _open_zip(path) as zf:
        infos = zf.infolist()
    if len(infos) > MAX_MEMBERS:
        raise _fail(path, f"has {len(infos)} members (limit {MAX_MEMBERS})",
                    "this is not a plausible FMU; raise orchestrator.fmi.archive.MAX_MEMBERS if you trust it")
    seen = set()
    total = 0
    for info in infos:
        name = info.filename
        _check_name(path, name)
        key = name.rstrip("/")
        if key in seen:
            raise _fail(path, f"member {name!r} appears twice in the archive", "rebuild the FMU")
        seen.add(key)
        mode = info.external_attr >> 16
        ftype = stat.S_IFMT(mode)
        if ftype and ftype not in (stat.S_IFREG, stat.S_IFDIR):
            kind = "a symbolic link" if stat.S_ISLNK(mode) else "a special file"
            raise _fail(path, f"member {name!r} is {kind}",
                        "FMUs must contain regular files only; ask the author to rebuild it without links")
        if info.file_size > MAX_MEMBER_BYTES:
            raise _fail(path, f"member {name!r} is {info.file_size} bytes uncompressed (limit {MAX_MEMBER_BYTES})",
                        "raise orchestrator.fmi.archive.MAX_MEMBER_BYTES if you trust this FMU")
        if (info.file_size > RATIO_CHECK_MIN_BYTES
                and info.file_size > MAX_COMPRESSION_RATIO * max(info.compress_size, 1)):
            ratio = info.file_size / max(info.compress_size, 1)
            raise _fail(path, f"member {name!r} has compression ratio {ratio:.0f} (limit {MAX_COMPRESSION_RATIO:.0f}); "
                        "this looks like a zip bomb", "do not use this FMU")
        total += info.file_size
        if total > MAX_TOTAL_BYTES:
            raise _fail(path, f"members add up to more than {MAX_TOTAL_BYTES} bytes uncompressed",
                        "raise orchestrator.fmi.archive.MAX_TOTAL_BYTES if you trust this FMU")
    if "modelDescription.xml" not in seen:
        raise _fail(path, "has no modelDescription.xml at the top level of the archive",
                    "this is not an FMU; export it again as an FMI 2.0 co-simulation FMU")
    return infos


def _read_member(zf: zipfile.ZipFile, path: Path, info: zipfile.ZipInfo, limit: int) -> bytes:
    chunks = []
    n = 0
    with zf.open(info) as f:
        while True:
            b = f.read(_CHUNK)
            if not b:
                break
            n += len(b)
            if n > limit:
                raise _fail(path, f"member {info.filename!r} is larger than {limit} bytes when decompressed "
                            "(its header says less)", "do not use this FMU")
            chunks.append(b)
    return b"".join(chunks)


def safe_extract(path: Path | str, dest: Path | str) -> Path:
    """Extract the FMU at ``path`` into directory ``dest`` after :func:`check_archive`.

    Sizes are re-checked while decompressing. Returns ``dest`` as a Path.
    """
    path = Path(path)
    dest = Path(dest)
    infos = check_archive(path)
    dest.mkdir(parents=True, exist_ok=True)
    root = dest.resolve()
    total = 0
    with _open_zip(path) as zf:
        for info in infos:
            rel = PurePosixPath(info.filename)
            target = (root / Path(*rel.parts)).resolve() if rel.parts else root
            if target != root and root not in target.parents:
                raise _fail(path, f"member {info.filename!r} would be written outside {root}", "do not use this FMU")
            if info.is_dir():
                target.mkdir(parents=True, exist_ok=True)
                continue
            target.parent.mkdir(parents=True, exist_ok=True)
            n = 0
            with zf.open(info) as src, open(target, "wb") as out:
                while True:
                    b = src.read(_CHUNK)
                    if not b:
                        break
                    n += len(b)
                    total += len(b)
                    if n > MAX_MEMBER_BYTES or total > MAX_TOTAL_BYTES:
                        out.close()
                        target.unlink(missing_ok=True)
                        raise _fail(path, f"member {info.filename!r} decompresses beyond the size limits "
                                    f"({MAX_MEMBER_BYTES} per member, {MAX_TOTAL_BYTES} total)", "do not use this FMU")
                    out.write(b)
            mode = (info.external_attr >> 16) & 0o777
            if mode & 0o100:
                os.chmod(target, 0o755)
    return dest


def _bool(s: str | None, default: bool) -> bool:
    if s is None:
        return default
    return s.strip().lower() in ("true", "1")


def _start(type_: str, s: str | None):
    if s is None:
        return None
    try:
        if type_ == "Real":
            return float(s)
        if type_ in ("Integer", "Enumeration"):
            return int(s)
        if type_ == "Boolean":
            return _bool(s, False)
    except ValueError:
        return s
    return s


def parse_model_description(xml: bytes, path: Path | str = "<memory>") -> ModelDescription:
    """Parse the bytes of an FMI 2.0 ``modelDescription.xml`` (see module doc for the rules)."""
    path = Path(path)
    if len(xml) > MAX_XML_BYTES:
        raise _fail(path, f"modelDescription.xml is {len(xml)} bytes (limit {MAX_XML_BYTES})",
                    "raise orchestrator.fmi.archive.MAX_XML_BYTES if you trust this FMU")
    head = xml[:4096].lower()
    if b"<!doctype" in xml.lower() or b"<!entity" in head:
        raise _fail(path, "modelDescription.xml contains a DOCTYPE/ENTITY declaration, which FMI does not use "
                    "and which can expand or fetch content", "remove the DOCTYPE from the model description")
    try:
        root = ElementTree.fromstring(xml)
    except ElementTree.ParseError as e:
        raise _fail(path, f"modelDescription.xml is not well-formed XML ({e})", "re-export the FMU") from None
    if root.tag != "fmiModelDescription":
        raise _fail(path, f"modelDescription.xml has root element <{root.tag}>, expected <fmiModelDescription>",
                    "re-export the FMU")
    version = root.get("fmiVersion", "")
    if not version.startswith("2."):
        raise _fail(path, f"is an FMI {version or '?'} FMU, expected FMI 2.0",
                    "export the model as an FMI 2.0 co-simulation FMU")
    cs = root.find("CoSimulation")
    if cs is None:
        raise _fail(path, "has no <CoSimulation> element (it is a Model Exchange only FMU)",
                    "export the model as an FMI 2.0 co-simulation FMU")
    ident = cs.get("modelIdentifier", "")
    if not ident or any(c in ident for c in "/\\\x00") or ident in (".", ".."):
        raise _fail(path, f"has an invalid modelIdentifier {ident!r}", "re-export the FMU")

    variables: dict[str, Variable] = {}
    mv = root.find("ModelVariables")
    for sv in (mv if mv is not None else []):
        if sv.tag != "ScalarVariable":
            continue
        name = sv.get("name")
        vr = sv.get("valueReference")
        if name is None or vr is None:
            raise _fail(path, "a ScalarVariable lacks name or valueReference", "re-export the FMU")
        type_el = None
        for child in sv:
            if child.tag in ("Real", "Integer", "Boolean", "String", "Enumeration"):
                type_el = child
                break
        if type_el is None:
            raise _fail(path, f"variable {name!r} has no type element", "re-export the FMU")
        try:
            vr_int = int(vr)
        except ValueError:
            raise _fail(path, f"variable {name!r} has a non-integer valueReference {vr!r}", "re-export the FMU") from None
        causality = sv.get("causality", "local")
        variability = sv.get("variability", "continuous")
        if name in variables:
            raise _fail(path, f"variable {name!r} is declared twice", "re-export the FMU")
        variables[name] = Variable(
            name=name, value_reference=vr_int, type=type_el.tag, causality=causality,
            variability=variability, start=_start(type_el.tag, type_el.get("start")),
            description=sv.get("description", "") or "", unit=type_el.get("unit", "") or "")

    de = root.find("DefaultExperiment")
    default_experiment = {}
    if de is not None:
        for k in ("startTime", "stopTime", "tolerance", "stepSize"):
            if de.get(k) is not None:
                try:
                    default_experiment[k] = float(de.get(k))
                except ValueError:
                    pass
    try:
        mod = int(cs.get("maxOutputDerivativeOrder", "0"))
    except ValueError:
        mod = 0
    return ModelDescription(
        path=path, fmi_version=version, model_name=root.get("modelName", ident), guid=root.get("guid", ""),
        model_identifier=ident,
        can_interpolate_inputs=_bool(cs.get("canInterpolateInputs"), False),
        max_output_derivative_order=mod,
        can_get_and_set_fmu_state=_bool(cs.get("canGetAndSetFMUstate"), False),
        can_handle_variable_step=_bool(cs.get("canHandleVariableCommunicationStepSize"), False),
        needs_execution_tool=_bool(cs.get("needsExecutionTool"), False),
        can_be_instantiated_only_once_per_process=_bool(cs.get("canBeInstantiatedOnlyOncePerProcess"), False),
        description=root.get("description", "") or "", generation_tool=root.get("generationTool", "") or "",
        default_experiment=default_experiment, variables=variables)


def read_model_description(path: Path | str) -> ModelDescription:
    """Check the archive at ``path`` and parse its ``modelDescription.xml``.

    Does not extract anything to disk. Raises :class:`FmuError`.
    """
    path = Path(path)
    infos = check_archive(path)
    info = next(i for i in infos if i.filename == "modelDescription.xml")
    with _open_zip(path) as zf:
        xml = _read_member(zf, path, info, MAX_XML_BYTES)
    return parse_model_description(xml, path)


def platform_dir() -> str:
    """FMI 2.0 binaries folder name of this platform (e.g. ``linux64``)."""
    from fmpy import platform
    return platform


def binary_path(extracted: Path, md: ModelDescription) -> Path:
    """Path of the shared library of ``md`` in an extracted FMU; FmuError if missing."""
    from fmpy import sharedLibraryExtension
    lib = Path(extracted) / "binaries" / platform_dir() / (md.model_identifier + sharedLibraryExtension)
    if not lib.is_file():
        have = sorted(p.name for p in (Path(extracted) / "binaries").glob("*")) if (Path(extracted) / "binaries").is_dir() else []
        raise _fail(md.path, f"has no binary for this platform (expected binaries/{platform_dir()}/"
                    f"{lib.name}; platforms in the FMU: {have or 'none'})",
                    f"export the FMU with a {platform_dir()} binary ({sys.platform})")
    return lib


def cached_model_description(path: Path | str) -> ModelDescription:
    """:func:`read_model_description`, cached per file path, size and modification time
    (the scenario checks and the master read the same FMUs)."""
    path = Path(path)
    try:
        st = path.stat()
    except OSError:
        return read_model_description(path)          # raises FmuError naming the missing file
    return _read_cached(str(path), st.st_mtime_ns, st.st_size)


@functools.lru_cache(maxsize=64)
def _read_cached(path: str, mtime_ns: int, size: int) -> ModelDescription:
    return read_model_description(path)
