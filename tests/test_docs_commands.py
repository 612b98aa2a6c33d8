"""What README.md and docs/ show a user to type or import exists as shown.

Static and cheap (a few seconds, nothing is run and no scenario is loaded), so the
documentation cannot rot silently when a verb, option, script, test or module is renamed:

* every ``rotorcosim VERB ...`` (and ``python -m orchestrator VERB ...``) in a code block or
  an inline code span names a verb of ``orchestrator.cli.build_parser()``, and every ``--option``
  after it is an option of that verb; a shipped scenario given by name exists;
* every ``python -m MODULE`` of ours is a module that runs as a script;
* every script ``benchmarks/X.py``, ``docs/.../X.py``, ``compare/X.py`` exists, and every
  ``--option`` shown after it appears in its source (argparse or its own argv parsing);
* every ``tests/test_x.py`` and ``tests/test_x.py::test_name`` exists, and every test name
  in backticks (``test_name``, ``test_prefix_*``) is defined in tests/;
* every dotted ``orchestrator.`` / ``bearing_fmu.`` / ``rotor_fmu.`` / ``fmu_common.`` name in
  an inline code span, and every name a ``python`` block imports, resolves by import + getattr;
* every repository path in an inline code span or a command line exists;
* every relative Markdown link points to a file (and heading) that exists.

Whether the commands *work* (``--set`` keys, scenario contents, run results) is checked by
running them, which is not cheap; see the commit that added this file for how that was done.
"""

from __future__ import annotations

import argparse
import glob
import importlib
import importlib.util
import re
from functools import lru_cache
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

# docs/dev/requests.md is a message board between contributors (commands of the day, paths on
# their hosts), not documentation; everything else a reader may copy from is checked.
DOC_FILES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md")),
             *sorted(p for p in (REPO / "docs" / "dev").glob("*.md") if p.name != "requests.md")]

# Allowed exceptions, each a placeholder or a name the text says is gone:
PLACEHOLDER_PATHS = {
    "scenarios/x.yaml",             # "load_scenario('scenarios/x.yaml')": any scenario of yours
    "tests/test_x.py",              # docs/dev/contracts.md: "pytest tests/test_x.py"
    "compare/coupling_stiff.yaml",  # docs/coupling.md says it was folded into another file and removed
}
# docs/dev/architecture.md, "Where things moved": the first column lists the names *before* the move.
MOVED_SECTION = ("architecture.md", "## Where things moved")

OUR_PACKAGES = ("orchestrator", "bearing_fmu", "rotor_fmu", "fmu_common")
TOP_DIRS = ("orchestrator", "bearing_fmu", "rotor_fmu", "fmu_common", "scenarios", "compare", "tests",
            "docs", "benchmarks", ".ci")


def _rel(path: Path) -> str:
    return str(path.relative_to(REPO))


def _substitute(line: str, env: dict[str, str]) -> str:
    return re.sub(r"\$(\w+)", lambda v: env.get(v.group(1), v.group(0)), line)


@lru_cache(maxsize=None)
def segments(path: Path) -> tuple[tuple[int, str, str], ...]:
    """(line, text, kind) of a Markdown file: kind 'code:LANG' for each line of a fenced block (with
    backslash continuations joined and $VAR of NAME="..." lines of the block substituted), 'span'
    for each inline code span of the prose."""
    text = path.read_text(encoding="utf-8")
    out = []
    for m in re.finditer(r"^```(\w*)[^\n]*\n(.*?)^```", text, re.S | re.M):
        first = text[:m.start()].count("\n") + 2
        env: dict[str, str] = {}
        lines = m.group(2).split("\n")
        i = 0
        while i < len(lines):
            line, n0 = lines[i], i
            while line.endswith("\\") and i + 1 < len(lines):
                i += 1
                line = line[:-1] + " " + lines[i]
            i += 1
            a = re.match(r'^\s*(\w+)="(.*)"\s*$', line)
            if a:
                env[a.group(1)] = a.group(2)
                continue
            line = _substitute(line, env)
            out.append((first + n0, line, f"code:{m.group(1)}"))
    prose = re.sub(r"^```.*?^```", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.S | re.M)
    moved = path.name == MOVED_SECTION[0]
    section = ""
    for n, line in enumerate(prose.split("\n"), 1):
        if line.startswith("## "):
            section = line
        if moved and section.startswith(MOVED_SECTION[1]) and line.startswith("|"):
            line = "|" + line.split("|", 2)[-1]          # drop the "before" column
        for m in re.finditer(r"`([^`]+)`", line):
            out.append((n, m.group(1), "span"))
    return tuple(out)


def all_segments():
    for path in DOC_FILES:
        for line, text, kind in segments(path):
            yield f"{_rel(path)}:{line}", text, kind


def command_part(text: str) -> str:
    """A shell line up to its comment or the next command."""
    return re.split(r"\s#|;|&&|\|\|?", text)[0]


@lru_cache(maxsize=None)
def cli():
    from orchestrator.cli import build_parser
    parser = build_parser()
    subs = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices

    def options(p):
        return {o for a in p._actions for o in a.option_strings}
    return options(parser), {verb: options(p) | options(parser) for verb, p in subs.items()}


CLI_RE = re.compile(r"(?:^|[\s/\"'=(])(?:rotorcosim|python3? -m orchestrator)\s+([-\w.]+)(.*)")


def test_cli_commands_name_existing_verbs_and_options():
    top, verbs = cli()
    bad, n = [], 0
    for where, text, _ in all_segments():
        for m in CLI_RE.finditer(text):
            word, rest = m.group(1), command_part(m.group(2))
            if word == "...":
                continue
            n += 1
            if word.startswith("-"):
                if word not in top:
                    bad.append(f"{where}: rotorcosim has no option {word}: {text}")
                continue
            if word not in verbs:
                bad.append(f"{where}: rotorcosim has no verb '{word}' (verbs: {sorted(verbs)}): {text}")
                continue
            for opt in re.findall(r"(?<![\w-])--[a-z][\w-]*", rest):
                if opt not in verbs[word]:
                    bad.append(f"{where}: 'rotorcosim {word}' has no option {opt} "
                               f"({sorted(verbs[word])}): {text}")
            args = rest.split()
            if word in ("run", "validate", "export-ssp") and args and re.fullmatch(r"[a-z0-9_]+", args[0]):
                if not (REPO / "scenarios" / f"{args[0]}.yaml").is_file():
                    bad.append(f"{where}: no shipped scenario named '{args[0]}': {text}")
    assert n > 100, f"found only {n} rotorcosim commands: is the extraction broken?"
    assert not bad, "\n".join(bad)


def _runs_as_script(module: str) -> bool:
    spec = importlib.util.find_spec(module)
    if spec is None:
        return False
    if spec.submodule_search_locations:                  # a package: needs __main__.py
        return importlib.util.find_spec(module + ".__main__") is not None
    return re.search(r"^if __name__ == [\"']__main__[\"']:", Path(spec.origin).read_text(encoding="utf-8"),
                     re.M) is not None


def test_python_m_modules_run_as_scripts():
    bad, n = [], 0
    for where, text, _ in all_segments():
        for m in re.finditer(r"python3? -m ([\w.]+)", text):
            module = m.group(1)
            if module.split(".")[0] not in OUR_PACKAGES:
                continue
            n += 1
            if not _runs_as_script(module):
                bad.append(f"{where}: 'python -m {module}' is no module of ours that runs as a script")
    assert n >= 3
    assert not bad, "\n".join(bad)


SCRIPT_RE = re.compile(r"(?<![\w/.])((?:benchmarks|docs|compare|tests/fmus_c)/(?:[\w-]+/)*[\w-]+\.py)\b(.*)")


def test_scripts_exist_with_the_options_shown():
    bad, n = [], 0
    for where, text, kind in all_segments():
        for m in SCRIPT_RE.finditer(text):
            script, rest = m.group(1), command_part(m.group(2))
            n += 1
            path = REPO / script
            if not path.is_file():
                bad.append(f"{where}: {script} does not exist")
                continue
            source = path.read_text(encoding="utf-8")
            for opt in re.findall(r"(?<![\w-])--[a-z][\w-]*", rest):
                if f'"{opt}"' not in source and f"'{opt}'" not in source:
                    bad.append(f"{where}: {script} takes no option {opt}: {text}")
    assert n > 50, f"found only {n} script references"
    assert not bad, "\n".join(bad)


@lru_cache(maxsize=None)
def sources_of_tests() -> dict[str, str]:
    return {p.name: p.read_text(encoding="utf-8") for p in (REPO / "tests").glob("*.py")}


def test_referenced_tests_exist():
    sources = sources_of_tests()
    defined = set(re.findall(r"^\s*(?:async\s+)?def\s+(test_\w+)", "\n".join(sources.values()), re.M))
    bad, n = [], 0
    for path in DOC_FILES:
        text = path.read_text(encoding="utf-8")
        for m in re.finditer(r"tests/([\w*]+\.py)(?:::(\w+))?", text):
            where = f"{_rel(path)}:{text[:m.start()].count(chr(10)) + 1}"
            name, test = m.groups()
            n += 1
            if f"tests/{name}" in PLACEHOLDER_PATHS:
                continue
            if not glob.glob(str(REPO / "tests" / name)):
                bad.append(f"{where}: tests/{name} does not exist")
            elif test and not re.search(rf"^\s*def {test}\(", sources.get(name, ""), re.M):
                bad.append(f"{where}: tests/{name} defines no {test}")
    for where, text, kind in all_segments():
        if kind == "span" and re.fullmatch(r"test_[\w*]+", text):
            n += 1
            pattern = re.compile(text.replace("*", r"\w*"))
            if not any(pattern.fullmatch(d) for d in defined):
                bad.append(f"{where}: no test named {text} in tests/")
    assert n > 80
    assert not bad, "\n".join(bad)


def resolve(name: str) -> str | None:
    """None when ``name`` (a.b.c) is a module or an attribute of one, else why not."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        module = ".".join(parts[:i])
        try:
            obj = importlib.import_module(module)
        except ModuleNotFoundError as e:
            if e.name is not None and module.startswith(e.name) and i > 1:
                continue                                  # a shorter prefix may be the module
            return f"import {module}: {e}"
        for attr in parts[i:]:
            if not hasattr(obj, attr):
                return f"{'.'.join(parts[:parts.index(attr)])} has no attribute {attr!r}"
            obj = getattr(obj, attr)
        return None
    return "not importable"


DOTTED_RE = re.compile(r"(?<![\w./])((?:%s)(?:\.[A-Za-z_]\w*)+)" % "|".join(OUR_PACKAGES))


def test_dotted_names_resolve():
    bad, n = [], 0
    for where, text, kind in all_segments():
        names = []
        if kind == "span":
            names = DOTTED_RE.findall(text)
        elif kind == "code:python":
            m = re.match(r"\s*from\s+([\w.]+)\s+import\s+([\w\s,]+)", text.split("#")[0])
            if m and m.group(1).split(".")[0] in OUR_PACKAGES:
                names = [f"{m.group(1)}.{a.strip()}" for a in m.group(2).split(",") if a.strip()]
        for name in names:
            n += 1
            why = resolve(name)
            if why:
                bad.append(f"{where}: {name}: {why}")
    assert n > 100, f"found only {n} dotted names"
    assert not bad, "\n".join(bad)


PATH_RE = re.compile(r"(?<![\w/.$~-])(?:%s)/" % "|".join(re.escape(d) for d in TOP_DIRS))


def _expand(token: str) -> list[str]:
    """Glob patterns for a path as a shell or a reader sees it: $VAR, ${...} and <placeholder>
    stand for any text, {a,b} for each of its words."""
    token = re.sub(r"\$\{[^}]*\}|\$\w+|<[^>]*>", "*", token)
    m = re.search(r"\{([^{}]*,[^{}]*)\}", token)
    if m:
        return [p for word in m.group(1).split(",") for p in _expand(token[:m.start()] + word + token[m.end():])]
    return [token]


def _exists(p: str) -> bool:
    if glob.glob(str(REPO / p)):
        return True
    # an output prefix handed to a script (docs/img/NAME -> docs/img/NAME_waterfall.png, ...)
    return "." not in Path(p).name and bool(glob.glob(str(REPO / p) + "_*"))


def test_repository_paths_exist():
    bad, n = [], 0
    for where, text, kind in all_segments():
        if kind != "span" and not re.search(r"rotorcosim|python|\.py\b", text):
            continue                                      # only command lines of code blocks
        for m in PATH_RE.finditer(text):
            token = re.match(r"(?:\$\{[^}]*\}|\{[^}\s]*\}|[^\s`'\"(),;:{])+", text[m.start():]).group(0).rstrip(".")
            if "..." in token or token in PLACEHOLDER_PATHS:
                continue
            if re.fullmatch(r"[\w/]+\.[a-z_]+[A-Z_(]?.*", token) and not re.search(r"\.[a-z]+$", token):
                continue                                  # module.attribute written with slashes
            n += 1
            for p in _expand(token):
                if not _exists(p.rstrip("/")):
                    bad.append(f"{where}: {p} does not exist: {text}")
    assert n > 150, f"found only {n} paths"
    assert not bad, "\n".join(bad)


def _slug(heading: str) -> str:
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def test_markdown_links_resolve():
    bad = []
    for path in DOC_FILES:
        text = path.read_text(encoding="utf-8")
        for m in re.finditer(r"\]\(([^)\s]+)\)", text):
            target = m.group(1)
            if re.match(r"[a-z]+:", target):
                continue
            file, _, anchor = target.partition("#")
            dest = (path.parent / file).resolve() if file else path
            where = f"{_rel(path)}:{text[:m.start()].count(chr(10)) + 1}"
            if not dest.exists():
                bad.append(f"{where}: link to {target}: no such file")
            elif anchor and dest.suffix == ".md":
                body = re.sub(r"^```.*?^```", "", dest.read_text(encoding="utf-8"), flags=re.S | re.M)
                if anchor not in {_slug(h) for h in re.findall(r"^#+\s+(.*)$", body, re.M)}:
                    bad.append(f"{where}: link to {target}: no such heading")
    assert not bad, "\n".join(bad)


def test_every_cli_option_is_shown_in_a_command_of_its_verb():
    """The converse of test_cli_commands_name_existing_verbs_and_options: every option that
    ``rotorcosim VERB --help`` lists is shown in some ``rotorcosim VERB ... --option`` of
    README.md or docs/ (-h/--help and --debug, which every verb takes, are described once in
    README.md's prose), and every option of ``rotorcosim`` itself in a ``rotorcosim --option``;
    ``run --progress`` and ``rotorcosim --version`` were in --help and in no document."""
    top, verbs = cli()
    common = {"-h", "--help", "--debug"}
    shown: dict[str, set[str]] = {}
    for _, text, _ in all_segments():
        for m in CLI_RE.finditer(text):
            word, rest = m.group(1), m.group(2)
            rest = re.split(r"\s#|;|&&|\|\|", rest)[0]     # an "a|b" choice is one option list
            key = "" if word.startswith("-") else word
            shown.setdefault(key, set()).update(re.findall(r"(?<![\w-])--[a-z][\w-]*", word + " " + rest))
    missing = [f"rotorcosim {o}" for o in sorted(top - common) if o.startswith("--") and o not in shown.get("", ())]
    for verb, opts in sorted(verbs.items()):
        for o in sorted(opts - top - common):
            if o.startswith("--") and o not in shown.get(verb, ()):
                missing.append(f"rotorcosim {verb} {o}")
    assert not missing, "options in --help that no document shows in a command: " + ", ".join(missing)
