"""Rotor definition files (YAML) for flexible rotors: load, validate, build elements.

Format (SI units; positions z along the shaft axis, any origin, increasing)::

    name: heavy turbocharger
    materials:
      steel: {E: 2.1e11, nu: 0.3, rho: 7850}          # G = E / (2 (1 + nu)) unless given
    shaft:                                            # consecutive sections from z_start
      z_start: 0.0
      max_element_length: 0.012                       # sections are split into elements
      sections:
        - {length: 0.060, d_outer: 0.025, material: steel}
        - {length: 0.032, d_outer: 0.040, d_inner: 0.0, material: steel, n_elements: 3}
    discs:                                            # rigid wheels
      - {name: comp, z: 0.030, mass: 1.3, Ip: 2.2e-3, Id: 1.3e-3,
         unbalance: 1.5e-6, unbalance_phase: 0.0}      # unbalance m e [kg m], phase [rad]
    bearings:                                         # bearing stations, in order 1, 2, ...
      - {name: bearing1, z: 0.096}
    internal_damping: 0.0                             # stiffness-proportional rotating damping [s]
    reduction: {n_modes: 6}                           # Craig-Bampton fixed-interface modes per plane

Every disc and bearing position must coincide with a node: section ends, and the
points where a section is split into equal elements.  A node is also inserted at
every disc/bearing z inside a section (the section is split there first).
Errors list every problem: ``file: 'discs[1].z' ... (got ...); fix``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from fmu_common.safe_yaml import SafeLoader

from .beam import Disc, Element

DATA_DIR = Path(__file__).parent / "data"

#: bounds of a rotor file (it is untrusted input: a scenario names it, the FMU reads it)
MAX_FILE_BYTES = 1 << 20          # the shipped file is 6 kB
MAX_YAML_NODES = 100_000          # after aliases are expanded (an alias bomb is refused)
MAX_LIST_ITEMS = 1000             # materials, sections, discs, bearings
MAX_ELEMENTS = 2000               # beam elements in all (the shipped rotor has 33)
MAX_MODES = 500                   # Craig-Bampton modes per plane
MAX_INT_DIGITS = 40               # of an integer literal (Python refuses more than 4300 digits)

#: accepted range (inclusive), unit and meaning of each physical field of a rotor file: wide enough
#: for any machine from a micro turbine to a turbogenerator, narrow enough to refuse a value in the
#: wrong unit (E in GPa, rho in g/cm^3, a diameter in mm, a phase in degrees) or one that makes
#: the element matrices overflow (E: 1e300, a length of 1e300 m)
RANGES: dict[str, tuple[float, float, str, str]] = {
    "E": (1e7, 1e14, "Pa", "Young's modulus in Pa: steel 2.1e11 (210 GPa)"),
    "G": (1e6, 1e14, "Pa", "shear modulus in Pa: steel 8.1e10 (81 GPa)"),
    "nu": (0.0, 0.5, "", "Poisson's ratio of an isotropic material: steel 0.3"),
    "rho": (100.0, 3e4, "kg/m^3", "density in kg/m^3: steel 7850 (7.85 g/cm^3)"),
    "length": (1e-6, 100.0, "m", "section length in m: 56 mm is 0.056"),
    "d_outer": (1e-4, 5.0, "m", "outer diameter in m: 7 mm is 0.007"),
    "d_inner": (0.0, 5.0, "m", "bore diameter in m (0: a solid section)"),
    "z_start": (-1000.0, 1000.0, "m", "axial position of the first section's left end in m"),
    "z": (-1000.0, 1000.0, "m", "axial position in m, on the shaft"),
    "mass": (0.0, 1e6, "kg", "disc mass in kg"),
    "Ip": (0.0, 1e7, "kg m^2", "polar moment of inertia in kg m^2"),
    "Id": (0.0, 1e7, "kg m^2", "diametral moment of inertia in kg m^2"),
    "unbalance": (0.0, 1e3, "kg m", "unbalance m e in kg m: 1.5 g mm is 1.5e-6"),
    "unbalance_phase": (-2 * math.pi, 2 * math.pi, "rad", "phase in radians: 90 degrees is 1.5708"),
    "internal_damping": (0.0, 0.1, "s", "stiffness-proportional rotating damping coefficient in s, "
                                        "typically 1e-5 to 1e-3"),
}
#: largest eccentricity ``unbalance / mass`` of a disc [m] (a larger one is an unbalance in another
#: unit: g mm for kg m)
MAX_ECCENTRICITY = 0.1


class RotorFileError(ValueError):
    """A rotor file is invalid; ``problems`` lists every problem."""

    def __init__(self, source: str, problems: list[str]):
        self.source = source
        self.problems = problems
        super().__init__(f"invalid rotor file {source}:\n  " + "\n  ".join(problems))


@dataclass(frozen=True, kw_only=True)
class DiscSpec:
    name: str
    z: float
    mass: float
    Ip: float
    Id: float
    unbalance: float = 0.0
    unbalance_phase: float = 0.0


@dataclass(frozen=True, kw_only=True)
class RotorDefinition:
    """A validated rotor: elements (node i -> i+1), discs and bearing nodes."""

    name: str
    elements: list
    z_nodes: np.ndarray
    discs: list                      # DiscSpec
    disc_nodes: list                 # node index per disc
    bearing_names: list
    bearing_nodes: list
    internal_damping: float = 0.0
    n_modes: int = 6
    source: str = "<dict>"
    raw: dict = field(default_factory=dict, repr=False)

    def fe_discs(self) -> list[Disc]:
        return [Disc(node=n, mass=d.mass, Ip=d.Ip, Id=d.Id) for d, n in zip(self.discs, self.disc_nodes)]

    def shaft_mass(self) -> float:
        return float(sum(el.rho * np.pi / 4 * (el.d_outer**2 - el.d_inner**2) * el.length
                         for el in self.elements))

    def total_mass(self) -> float:
        return self.shaft_mass() + float(sum(d.mass for d in self.discs))


def _num(d, key, where, problems, *, positive=False, default=None):
    """The number ``d[key]`` (``where``: the path of ``d`` in the file, '' at the top), checked
    finite and, for a field of :data:`RANGES`, inside its range; NaN after a problem."""
    name = f"{where}.{key}" if where else key
    if key not in d:
        if default is not None:
            return default
        problems.append(f"'{name}' is required (a number in SI units)")
        return np.nan
    v = d[key]
    if isinstance(v, str):          # PyYAML reads 2.1e11 (no exponent sign) as a string
        try:
            v = float(v)
        except ValueError:
            pass
    if isinstance(v, int) and not isinstance(v, bool):
        v = float(v) if abs(v) < 1e300 else math.inf      # (at most 40 digits: load_rotor_file)
    if isinstance(v, bool) or not isinstance(v, float) or not math.isfinite(v):
        shown = repr(d[key])
        problems.append(f"'{name}' must be a finite number in SI units (got "
                        f"{shown if len(shown) <= 80 else shown[:80] + '...'})")
        return np.nan
    if positive and not v > 0:
        problems.append(f"'{name}' must be > 0 (got {v!r})")
        return np.nan
    if key in RANGES:
        lo, hi, unit, what = RANGES[key]
        if not lo <= v <= hi:
            head = f"'{name}' must be > 0 (got {v:g}): it" if lo > 0 >= v else f"'{name}' = {v:g}"
            problems.append(f"{head} is outside the accepted range [{lo:g}, {hi:g}]"
                            f"{' ' + unit if unit else ''} ({what}); give a value inside the range")
            return np.nan
    return v


def _mapping(d, key, problems) -> dict:
    v = d.get(key)
    if v is None:
        return {}
    if not isinstance(v, dict):
        problems.append(f"'{key}' must be a mapping of names to entries (got {type(v).__name__})")
        return {}
    if len(v) > MAX_LIST_ITEMS:
        problems.append(f"'{key}' has {len(v)} entries, more than {MAX_LIST_ITEMS}")
        return {}
    return v


def _list(d, key, problems) -> list:
    v = d.get(key)
    if v is None:
        return []
    if not isinstance(v, list):
        problems.append(f"'{key}' must be a list of mappings (got {type(v).__name__})")
        return []
    if len(v) > MAX_LIST_ITEMS:
        problems.append(f"'{key}' has {len(v)} entries, more than {MAX_LIST_ITEMS}")
        return []
    return v


def _unknown(d, allowed, where, problems):
    for k in d:
        if k not in allowed:
            problems.append(f"'{where}': unknown key '{k}' (allowed: {sorted(allowed)})")


def parse_rotor(data: dict, source: str = "<dict>") -> RotorDefinition:
    """Validate a rotor definition mapping (as read from YAML) and build the elements."""
    p: list[str] = []
    if not isinstance(data, dict):
        raise RotorFileError(source, [f"top level must be a mapping (got {type(data).__name__})"])
    _unknown(data, {"name", "materials", "shaft", "discs", "bearings", "internal_damping",
                    "reduction", "description", "sources"}, "<top>", p)
    mats = {}
    materials = _mapping(data, "materials", p)
    discs_in, bearings_in = _list(data, "discs", p), _list(data, "bearings", p)
    for mname, m in materials.items():
        if not isinstance(mname, str):          # a section names it by a text ('1:' is the number 1)
            p.append(f"'materials': the name {mname!r:.40} is not a text; name each material, e.g. steel, or quote "
                     f"it: '{mname!s:.40}'")
            continue
        if not isinstance(m, dict):
            p.append(f"'materials.{mname}' must be a mapping with E, nu, rho")
            continue
        _unknown(m, {"E", "nu", "rho", "G"}, f"materials.{mname}", p)
        E = _num(m, "E", f"materials.{mname}", p)
        nu = _num(m, "nu", f"materials.{mname}", p, default=0.3)
        rho = _num(m, "rho", f"materials.{mname}", p)
        G = _num(m, "G", f"materials.{mname}", p, default=E / (2 * (1 + nu)))   # nu in [0, 0.5]: G in range
        mats[mname] = (E, G, rho, nu)
    if not mats:
        p.append("'materials' must define at least one material, e.g. steel: {E: 2.1e11, nu: 0.3, rho: 7850}")
    shaft = data.get("shaft")
    if not isinstance(shaft, dict) or not isinstance(shaft.get("sections"), list) or not shaft["sections"]:
        raise RotorFileError(source, p + ["'shaft.sections' must be a non-empty list of "
                                          "{length, d_outer, material} mappings"])
    if len(shaft["sections"]) > MAX_LIST_ITEMS:
        raise RotorFileError(source, p + [f"'shaft.sections' has {len(shaft['sections'])} entries, more than "
                                          f"{MAX_LIST_ITEMS}; join sections of the same diameter"])
    _unknown(shaft, {"z_start", "max_element_length", "sections"}, "shaft", p)
    z0 = _num(shaft, "z_start", "shaft", p, default=0.0)
    hmax = _num(shaft, "max_element_length", "shaft", p, positive=True, default=np.inf)
    if np.isnan(z0) or np.isnan(hmax):                 # the elements cannot be laid out
        raise RotorFileError(source, p)

    # point features that must be nodes
    discs, dz = [], []
    for i, d in enumerate(discs_in):
        w = f"discs[{i}]"
        if not isinstance(d, dict):
            p.append(f"'{w}' must be a mapping")
            continue
        _unknown(d, {"name", "z", "mass", "Ip", "Id", "unbalance", "unbalance_phase"}, w, p)
        spec = DiscSpec(name=str(d.get("name", f"disc{i + 1}")), z=_num(d, "z", w, p),
                        mass=_num(d, "mass", w, p), Ip=_num(d, "Ip", w, p), Id=_num(d, "Id", w, p),
                        unbalance=_num(d, "unbalance", w, p, default=0.0),
                        unbalance_phase=_num(d, "unbalance_phase", w, p, default=0.0))
        if spec.mass > 0 and spec.unbalance > MAX_ECCENTRICITY * spec.mass:
            p.append(f"'{w}.unbalance' = {spec.unbalance:g} kg m on a disc of {spec.mass:g} kg is an "
                     f"eccentricity of {spec.unbalance / spec.mass:g} m, more than {MAX_ECCENTRICITY:g} m: "
                     "the unbalance is m e in kg m (1.5 g mm is 1.5e-6); give it in kg m")
        if re.fullmatch(r"\s*[0-9]+\s*", spec.name):     # x_1 ... are the bearing stations' outputs
            p.append(f"'{w}.name' is {spec.name!r}, a number: the disc's outputs x_{spec.name.strip()}, ... would "
                     f"be those of bearing station {spec.name.strip()} (and replace them); give it a name, "
                     f"e.g. 'wheel{i + 1}'")
        elif spec.name in [q.name for q in discs]:      # x_<name> would be the later disc's, silently
            p.append(f"'{w}.name' is {spec.name!r}, the name of an earlier disc too: its outputs x_{spec.name}, "
                     f"... would be this disc's only; give each disc its own name")
        pos = re.fullmatch(r"disc(\d+)", spec.name)
        if pos and int(pos.group(1)) != i + 1:
            p.append(f"'{w}.name' is {spec.name!r}, the name of the outputs of the disc at position "
                     f"{int(pos.group(1))} in the file (x_{spec.name}, ...: every disc is also output "
                     f"as disc<k> by its place k); rename it, e.g. 'wheel{i + 1}', or move it to that place")
        discs.append(spec)
        dz.append(spec.z)
    bnames, bz = [], []
    for i, b in enumerate(bearings_in):
        w = f"bearings[{i}]"
        if not isinstance(b, dict):
            p.append(f"'{w}' must be a mapping")
            continue
        _unknown(b, {"name", "z"}, w, p)
        bnames.append(str(b.get("name", f"bearing{i + 1}")))
        bz.append(_num(b, "z", w, p))
    if len(bz) < 1:
        p.append("'bearings' must list at least one bearing station {name, z}")
    points = sorted(set(dz + bz))

    elements: list[Element] = []
    z = z0
    for i, s in enumerate(shaft["sections"]):
        w = f"shaft.sections[{i}]"
        if not isinstance(s, dict):
            p.append(f"'{w}' must be a mapping")
            continue
        _unknown(s, {"length", "d_outer", "d_inner", "material", "n_elements"}, w, p)
        L = _num(s, "length", w, p)
        do = _num(s, "d_outer", w, p)
        di = _num(s, "d_inner", w, p, default=0.0)
        if di >= do:
            p.append(f"'{w}.d_inner' must be < d_outer (got {di} >= {do})")
        mat = s.get("material")
        if not isinstance(mat, str) or mat not in mats:          # a mapping or list: no name (unhashable)
            shown = repr(mat)
            p.append(f"'{w}.material' must be one of {sorted(mats)} (got "
                     f"{shown if len(shown) <= 80 else shown[:80] + '...'})")
            continue
        nel = s.get("n_elements")
        if nel is not None and (isinstance(nel, bool) or not isinstance(nel, int) or not 1 <= nel <= MAX_ELEMENTS):
            p.append(f"'{w}.n_elements' must be a whole number from 1 to {MAX_ELEMENTS} (got {nel!r})")
            continue
        if not np.isfinite(L):
            continue
        E, G, rho, nu = mats[mat]
        # split at interior feature points, then into equal elements
        cuts = [z] + [q for q in points if z + 1e-12 < q < z + L - 1e-12] + [z + L]
        for a, b in zip(cuts[:-1], cuts[1:]):
            n = nel if nel else max(1, math.ceil(min((b - a) / hmax - 1e-9, 2.0 * MAX_ELEMENTS)))
            if len(elements) + n > MAX_ELEMENTS:
                raise RotorFileError(source, p + [
                    f"the shaft would have more than {MAX_ELEMENTS} beam elements (at '{w}'); use a larger "
                    f"'shaft.max_element_length' (now {hmax:g} m) or fewer 'n_elements'"])
            for k in range(n):
                elements.append(Element(z0=a + k * (b - a) / n, length=(b - a) / n, d_outer=do,
                                        d_inner=di, E=E, G=G, rho=rho, nu=nu))
        z = z + L
    if p:
        raise RotorFileError(source, p)
    zn = np.concatenate([[elements[0].z0], [el.z0 + el.length for el in elements]])

    def node_of(zz, what):
        j = int(np.argmin(np.abs(zn - zz)))
        if abs(zn[j] - zz) > 1e-9:
            p.append(f"'{what}' z={zz} is outside the shaft [{zn[0]}, {zn[-1]}] m; "
                     f"move it onto the shaft")
        return j

    disc_nodes = [node_of(d.z, f"discs[{i}].z") for i, d in enumerate(discs)]
    bearing_nodes = [node_of(zz, f"bearings[{i}].z") for i, zz in enumerate(bz)]
    if len(set(bearing_nodes)) != len(bearing_nodes):
        p.append(f"'bearings' must be at distinct positions (got z={bz})")
    beta = _num(data, "internal_damping", "", p, default=0.0)
    red = data.get("reduction") or {}
    if not isinstance(red, dict):
        p.append(f"'reduction' must be a mapping such as {{n_modes: 6}} (got {red!r})")
        red = {}
    n_modes = red.get("n_modes", 6)
    if isinstance(n_modes, bool) or not isinstance(n_modes, int) or not 0 <= n_modes <= MAX_MODES:
        p.append(f"'reduction.n_modes' must be a whole number from 0 to {MAX_MODES} (got {n_modes!r})")
        n_modes = 0
    if p:
        raise RotorFileError(source, p)
    return RotorDefinition(name=str(data.get("name", "rotor")), elements=elements, z_nodes=zn,
                           discs=discs, disc_nodes=disc_nodes, bearing_names=bnames,
                           bearing_nodes=bearing_nodes, internal_damping=beta, n_modes=n_modes,
                           source=source, raw=data)


def load_rotor_file(path=None) -> RotorDefinition:
    """Read and validate a rotor YAML file (default: the shipped turbocharger).

    The file is untrusted: it must be a regular file (a link to one is followed) of at most
    :data:`MAX_FILE_BYTES`, in UTF-8, and its YAML at most :data:`MAX_YAML_NODES` nodes with
    aliases expanded; :func:`parse_rotor` bounds the lists and the elements."""
    import stat
    path = DATA_DIR / "turbocharger.yaml" if path is None else Path(path)
    try:
        st = path.stat()
        if not stat.S_ISREG(st.st_mode):
            kind = "a folder" if stat.S_ISDIR(st.st_mode) else "not a regular file (a device or a pipe)"
            raise RotorFileError(str(path), [f"the rotor file is {kind}; give a YAML file"])
        if st.st_size > MAX_FILE_BYTES:
            raise RotorFileError(str(path), [f"the file has {st.st_size} bytes, more than a rotor file may "
                                             f"have ({MAX_FILE_BYTES}); check the path"])
        with open(path, "rb") as f:
            raw = f.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise RotorFileError(str(path), [f"cannot read the file ({exc}); check the path"]) from None
    if len(raw) > MAX_FILE_BYTES:
        raise RotorFileError(str(path), [f"the file has more than {MAX_FILE_BYTES} bytes; check the path"])
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RotorFileError(str(path), [f"the file is not UTF-8 text (byte {exc.start}); save it as UTF-8"]) from None
    try:
        loader = SafeLoader(text)      # unreadable tagged values: YAMLError
        try:
            node = loader.get_single_node()
            if node is not None and _expanded_nodes(node) > MAX_YAML_NODES:
                raise RotorFileError(str(path), [f"the YAML has more than {MAX_YAML_NODES} values with its "
                                                 "aliases expanded; write the rotor out plainly"])
            if node is not None and (long := _long_integer(node)) is not None:
                raise RotorFileError(str(path), [
                    f"line {long.start_mark.line + 1}: an integer of {len(long.value)} digits (more than "
                    f"{MAX_INT_DIGITS}); write the number in SI units, e.g. 2.1e11"])
            data = loader.construct_document(node) if node is not None else None
        finally:
            loader.dispose()
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        if isinstance(exc, yaml.constructor.ConstructorError) and mark is not None:     # a value: its line
            raise RotorFileError(str(path), [f"line {mark.line + 1}: cannot read this value ({exc.problem}); write "
                                             "a plain number, text, list or mapping"]) from None
        raise RotorFileError(str(path), [f"not valid YAML: {exc}"]) from None
    except yaml.YAMLError as exc:
        raise RotorFileError(str(path), [f"not valid YAML: {exc}"]) from None
    except RecursionError:
        raise RotorFileError(str(path), ["the YAML is nested too deeply; write the rotor out plainly"]) from None
    try:
        return parse_rotor(data, source=str(path))
    except RotorFileError as exc:          # each problem with the line of the field it names
        lines = _field_lines(node) if node is not None else {}
        raise RotorFileError(exc.source, [_with_line(q, lines) for q in exc.problems]) from None


def _field_lines(root) -> dict[str, int]:
    """The line (1-based) of each field of the file by its path as the problems name it
    (``materials.steel.E``, ``shaft.sections[2].length``); an alias's fields keep their anchor's
    lines. At most :data:`MAX_YAML_NODES` paths (the file was counted before)."""
    lines: dict[str, int] = {}
    stack = [("", root)]
    while stack and len(lines) <= MAX_YAML_NODES:
        where, node = stack.pop()
        if isinstance(node, yaml.MappingNode):
            for key, value in node.value:
                if isinstance(key, yaml.ScalarNode):
                    name = f"{where}.{key.value}" if where else str(key.value)
                    lines.setdefault(name, key.start_mark.line + 1)
                    stack.append((name, value))
        elif isinstance(node, yaml.SequenceNode):
            for i, item in enumerate(node.value):
                name = f"{where}[{i}]"
                lines.setdefault(name, item.start_mark.line + 1)
                stack.append((name, item))
    return lines


def _with_line(problem: str, lines: dict[str, int]) -> str:
    """``problem`` as ``line N: problem`` when it starts with a quoted field path that the file
    has (or, for a field that is missing, its mapping)."""
    m = re.match(r"'([^']+)'", problem)
    name = m.group(1) if m else ""
    while name:
        if name in lines:
            return f"line {lines[name]}: {problem}"
        name = re.sub(r"(\.[^.\[]*|\[\d+\])$", "", name) if re.search(r"[.\[]", name) else ""
    return problem


def _long_integer(root):
    """The first integer scalar of more than :data:`MAX_INT_DIGITS` digits, or None (each node
    visited once)."""
    seen: set[int] = set()
    stack = [root]
    while stack:
        node = stack.pop()
        if id(node) in seen:
            continue
        seen.add(id(node))
        if isinstance(node, yaml.ScalarNode):
            if node.tag == "tag:yaml.org,2002:int" and len(node.value) > MAX_INT_DIGITS:
                return node
        elif isinstance(node, yaml.SequenceNode):
            stack.extend(node.value)
        elif isinstance(node, yaml.MappingNode):
            stack.extend(x for kv in node.value for x in kv)
    return None


def _expanded_nodes(root) -> int:
    """The number of YAML nodes of ``root`` with every alias expanded (memoised per node, so an
    alias bomb is counted, not walked); a cycle counts as too many."""
    sizes: dict[int, int] = {}
    on_path: set[int] = set()
    stack = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        if isinstance(node, yaml.SequenceNode):
            children = node.value
        elif isinstance(node, yaml.MappingNode):
            children = [x for kv in node.value for x in kv]
        else:
            children = []
        if done:
            on_path.discard(key)
            sizes[key] = min(1 + sum(sizes[id(c)] for c in children), MAX_YAML_NODES + 1)
            continue
        if key in sizes:
            continue
        if key in on_path:                     # a recursive alias
            return MAX_YAML_NODES + 1
        on_path.add(key)
        stack.append((node, True))
        stack.extend((c, False) for c in children if id(c) not in sizes)
    return sizes[id(root)]
