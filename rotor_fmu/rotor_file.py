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

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from .beam import Disc, Element

DATA_DIR = Path(__file__).parent / "data"


class RotorFileError(ValueError):
    """A rotor file is invalid; ``problems`` lists every problem."""

    def __init__(self, source: str, problems: list[str]):
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


_NUM = (int, float)


def _num(d, key, where, problems, *, positive=False, nonneg=False, default=None):
    if key not in d:
        if default is not None:
            return default
        problems.append(f"'{where}.{key}' is required (a number in SI units)")
        return np.nan
    v = d[key]
    if isinstance(v, str):          # PyYAML reads 2.1e11 (no exponent sign) as a string
        try:
            v = float(v)
        except ValueError:
            pass
    if isinstance(v, bool) or not isinstance(v, _NUM) or not np.isfinite(v):
        problems.append(f"'{where}.{key}' must be a finite number (got {v!r})")
        return np.nan
    if positive and not v > 0:
        problems.append(f"'{where}.{key}' must be > 0 (got {v!r})")
    if nonneg and not v >= 0:
        problems.append(f"'{where}.{key}' must be >= 0 (got {v!r})")
    return float(v)


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
    for mname, m in (data.get("materials") or {}).items():
        if not isinstance(m, dict):
            p.append(f"'materials.{mname}' must be a mapping with E, nu, rho")
            continue
        _unknown(m, {"E", "nu", "rho", "G"}, f"materials.{mname}", p)
        E = _num(m, "E", f"materials.{mname}", p, positive=True)
        nu = _num(m, "nu", f"materials.{mname}", p, default=0.3)
        rho = _num(m, "rho", f"materials.{mname}", p, positive=True)
        G = _num(m, "G", f"materials.{mname}", p, default=E / (2 * (1 + nu)))
        mats[mname] = (E, G, rho, nu)
    if not mats:
        p.append("'materials' must define at least one material, e.g. steel: {E: 2.1e11, nu: 0.3, rho: 7850}")
    shaft = data.get("shaft")
    if not isinstance(shaft, dict) or not isinstance(shaft.get("sections"), list) or not shaft["sections"]:
        raise RotorFileError(source, p + ["'shaft.sections' must be a non-empty list of "
                                          "{length, d_outer, material} mappings"])
    _unknown(shaft, {"z_start", "max_element_length", "sections"}, "shaft", p)
    z0 = _num(shaft, "z_start", "shaft", p, default=0.0)
    hmax = _num(shaft, "max_element_length", "shaft", p, positive=True, default=np.inf)

    # point features that must be nodes
    discs, dz = [], []
    for i, d in enumerate(data.get("discs") or []):
        w = f"discs[{i}]"
        if not isinstance(d, dict):
            p.append(f"'{w}' must be a mapping")
            continue
        _unknown(d, {"name", "z", "mass", "Ip", "Id", "unbalance", "unbalance_phase"}, w, p)
        spec = DiscSpec(name=str(d.get("name", f"disc{i + 1}")), z=_num(d, "z", w, p),
                        mass=_num(d, "mass", w, p, nonneg=True), Ip=_num(d, "Ip", w, p, nonneg=True),
                        Id=_num(d, "Id", w, p, nonneg=True),
                        unbalance=_num(d, "unbalance", w, p, nonneg=True, default=0.0),
                        unbalance_phase=_num(d, "unbalance_phase", w, p, default=0.0))
        discs.append(spec)
        dz.append(spec.z)
    bnames, bz = [], []
    for i, b in enumerate(data.get("bearings") or []):
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
        L = _num(s, "length", w, p, positive=True)
        do = _num(s, "d_outer", w, p, positive=True)
        di = _num(s, "d_inner", w, p, nonneg=True, default=0.0)
        if di >= do:
            p.append(f"'{w}.d_inner' must be < d_outer (got {di} >= {do})")
        mat = s.get("material")
        if mat not in mats:
            p.append(f"'{w}.material' must be one of {sorted(mats)} (got {mat!r})")
            continue
        nel = s.get("n_elements")
        if not np.isfinite(L):
            continue
        E, G, rho, nu = mats[mat]
        # split at interior feature points, then into equal elements
        cuts = [z] + [q for q in points if z + 1e-12 < q < z + L - 1e-12] + [z + L]
        for a, b in zip(cuts[:-1], cuts[1:]):
            n = int(nel) if nel else max(1, int(np.ceil((b - a) / hmax - 1e-9)))
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
    beta = _num(data, "internal_damping", "<top>", p, nonneg=True, default=0.0)
    red = data.get("reduction") or {}
    n_modes = int(red.get("n_modes", 6)) if isinstance(red, dict) else 6
    if n_modes < 0:
        p.append(f"'reduction.n_modes' must be >= 0 (got {n_modes})")
    if p:
        raise RotorFileError(source, p)
    return RotorDefinition(name=str(data.get("name", "rotor")), elements=elements, z_nodes=zn,
                           discs=discs, disc_nodes=disc_nodes, bearing_names=bnames,
                           bearing_nodes=bearing_nodes, internal_damping=beta, n_modes=n_modes,
                           source=source, raw=data)


def load_rotor_file(path=None) -> RotorDefinition:
    """Read and validate a rotor YAML file (default: the shipped turbocharger)."""
    path = DATA_DIR / "turbocharger.yaml" if path is None else Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise RotorFileError(str(path), [f"cannot read the file ({exc}); check the path"]) from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise RotorFileError(str(path), [f"not valid YAML: {exc}"]) from None
    return parse_rotor(data, source=str(path))
