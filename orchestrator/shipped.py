"""The scenarios shipped inside the package: list them, find one by name, copy them for editing.

In a source checkout they are the files of ``scenarios/``; an installed package
carries the same files as the package ``rotorcosim_scenarios`` (pyproject maps the
folder). They name our FMUs with ``fmu: NAME`` (built on demand, see
:func:`orchestrator.build.fmu_location`), so they run from wherever they are,
copies made by ``rotorcosim init DIR`` included.
"""

from __future__ import annotations

from pathlib import Path

from orchestrator.errors import CosimError


def scenario_dir() -> Path:
    """The folder holding the shipped scenario files."""
    from importlib.resources import files
    try:
        root = files("rotorcosim_scenarios")
    except ModuleNotFoundError:
        root = None
    if root is not None:
        path = Path(str(root))
        if path.is_dir():
            return path
    here = Path(__file__).resolve().parents[1] / "scenarios"
    if here.is_dir():
        return here
    raise CosimError("the shipped scenarios are missing from this installation (package 'rotorcosim_scenarios'); "
                     "reinstall rotorcosim")


def shipped() -> dict[str, Path]:
    """``{name: file}`` of the shipped scenarios, sorted by name."""
    return {p.stem: p for p in sorted(scenario_dir().glob("*.yaml"))}


def describe(path: Path) -> str:
    """The start of the scenario's ``description`` (at most 90 characters), or ''."""
    import yaml
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError):
        return ""
    text = " ".join(str(doc.get("description", "") if isinstance(doc, dict) else "").split())
    head = text.split(": ", 1)[-1] if text.startswith("Paper section") else text
    return head if len(head) <= 90 else head[:87].rsplit(" ", 1)[0] + " ..."


def resolve(arg: str) -> Path:
    """``arg`` as a scenario file: an existing file as it is, else a shipped scenario of that name
    (``quickstart`` or ``quickstart.yaml``), else the path as given (the loader reports it missing);
    a bare name close to a shipped scenario's is refused with that name (a typo, not a file to look for)."""
    path = Path(arg)
    if path.exists():
        return path
    name = path.name[:-5] if path.name.endswith(".yaml") else path.name
    if path.parent == Path(".") and name in shipped():
        return shipped()[name]
    if path.parent == Path("."):                  # a bare name, neither a file here nor shipped: a typo?
        import difflib
        close = difflib.get_close_matches(name, list(shipped()), n=1, cutoff=0.75)
        if close:
            raise CosimError(f"{arg}: no such scenario file here, and no shipped scenario of that name; "
                             f"did you mean '{close[0]}'? (`rotorcosim scenarios` lists them)")
    return path


def init(dest: str | Path, *, force: bool = False) -> list[Path]:
    """Copy every shipped scenario into ``dest`` (created); existing files are kept unless ``force``.

    A name in ``dest`` that is a symbolic link counts as an existing file and is replaced by the
    copy (``force``), never written through: ``init DIR`` wrote the scenario into whatever file a
    (dangling) link ``DIR/quickstart.yaml`` pointed to, without ``--force`` too. A folder, FIFO or
    device under a scenario's name is refused."""
    import os
    import stat

    from orchestrator.results.safe_write import write_report_file
    from orchestrator.untrusted import file_kind
    dest = Path(dest)
    files = shipped()
    clash = []
    for p in files.values():
        try:
            mode = os.lstat(dest / p.name).st_mode
        except OSError:                          # a new name (or dest is no folder: mkdir says so)
            continue
        if not (stat.S_ISREG(mode) or stat.S_ISLNK(mode)):
            raise CosimError(f"{dest / p.name}: is {file_kind(mode)}, where init would write the scenario "
                             f"{p.name}; remove it or pick another folder")
        clash.append(dest / p.name)
    if clash and not force:
        raise CosimError(f"{dest}: {len(clash)} scenario file(s) exist already ({', '.join(c.name for c in clash[:5])}"
                         f"{', ...' if len(clash) > 5 else ''}); remove them, pick another folder or use --force")
    dest.mkdir(parents=True, exist_ok=True)
    out = []
    for p in files.values():            # atomically, replacing a link at the name, never its target
        out.append(write_report_file(dest / p.name, p.read_text(encoding="utf-8")))
    return out
