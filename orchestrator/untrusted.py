"""Reading files users get from others: the one bounded reader, YAML, XML, names.

A scenario, a compare spec, an FMU's model description and a run folder's
summary.json are untrusted input. Every reader of such a file goes through
this module, which bounds memory and time *before* anything builds on the
content:

* :func:`read_bytes` / :func:`read_text` / :func:`open_regular`: regular files
  only (a FIFO, ``/dev/zero`` or a directory is refused without reading or
  blocking), at most ``limit`` bytes, text strictly UTF-8 (a clear error with
  line and column of the first bad byte);
* :func:`compose_yaml`: PyYAML composition with the nesting depth bounded
  while composing (PyYAML's composer recurses), then the tree checked as it
  would be after alias expansion (``*anchor`` references): expanded node
  count, expanded depth, no recursive alias, no integer literal longer than
  :data:`MAX_INT_DIGITS`; only then may anything construct or copy it;
* :func:`parse_xml`: XML through defusedxml with DOCTYPE, entity declarations
  and external references refused *after* the parser decoded the bytes (so a
  UTF-16 document cannot hide its DOCTYPE from a byte search);
* :func:`check_name` / :func:`name_problem`: the one check of names that
  become file or folder names (scenario names, instance names, compare
  variants);
* :func:`format_template`: ``str.format`` restricted to plain field names and
  small format specs (no ``{x.__class__}``, ``{x[0]}`` or ``{x:999999999}``).

Every problem raises :class:`InputError` (a :class:`CosimError`) whose message
names the file (and line), what is wrong, what came and the fix; loaders that
collect problems wrap it in their own error type. The limits are module
constants read at call time; ``docs/limits.md`` lists them.
"""

from __future__ import annotations

import functools
import math
import os
import re
import stat
import string
import unicodedata
from pathlib import Path
from typing import Any, BinaryIO, Mapping

from orchestrator import read_log
from orchestrator.errors import CosimError

MAX_TEXT_BYTES = 8 * 2**20          # a scenario, compare spec or summary.json
MAX_YAML_DEPTH = 64                 # nesting of mappings/lists, also through aliases
MAX_YAML_NODES = 200_000            # nodes of the tree with every alias expanded
MAX_INT_DIGITS = 40                 # digits of an integer literal in YAML
MAX_NAME_CHARS = 100                # a name that becomes a file or folder name
MAX_FORMAT_WIDTH = 3                # digits of a width/precision in a name template

_CHUNK = 1 << 20


class InputError(CosimError):
    """An input file (or a value in it) cannot be used; the message says why and the fix."""


class SettingError(InputError, ValueError):
    """An environment variable rotorcosim reads has a value it cannot use (also a ValueError,
    as before it was one)."""


# --------------------------------------------------------------------------- environment
def env_number(name: str, default: float, *, minimum: float, maximum: float, integer: bool = False,
               meaning: str = "") -> float:
    """The number in environment variable ``name`` (``default`` when unset or empty), which must
    be finite (an integer with ``integer=True``) and lie in ``minimum..maximum``; a
    :class:`SettingError` naming the variable, what it expects, the value and the fix otherwise."""
    raw = os.environ.get(name, "")
    if not raw.strip():
        return default
    kind = "an integer" if integer else "a number"
    shown_n = (lambda x: str(int(x))) if integer else "{:g}".format
    expected = f"{kind} from {shown_n(minimum)} to {shown_n(maximum)}" + (f" ({meaning})" if meaning else "")
    try:
        value = int(raw.strip()) if integer else float(raw)
    except ValueError:
        value = None
    if value is None or not math.isfinite(value) or not minimum <= value <= maximum:
        shown = raw if len(raw) <= 40 else raw[:40] + "..."
        raise SettingError(f"environment variable {name}={shown!r}: expected {expected}; "
                           f"set it to such a value or unset it for the default {shown_n(default)}")
    return value


# --------------------------------------------------------------------------- files
def file_kind(mode: int) -> str:
    """What a file of ``st_mode`` is, in words ("a named pipe (FIFO)"), for one wording in
    every message about something that is not a regular file."""
    for test, word in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a named pipe (FIFO)"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return word
    return "not a regular file"


def open_regular(path: str | os.PathLike, *, what: str = "file") -> BinaryIO:
    """Open ``path`` for binary reading if it is a regular file (symlinks followed).

    Opens with ``O_NONBLOCK`` so that a FIFO does not block, then checks the
    opened file itself (no race between check and open). A scenario load that
    is recording (:mod:`orchestrator.read_log`) notes the file. Raises
    :class:`InputError` for a missing file, a directory, a FIFO, a device or a
    socket, or a permission problem.
    """
    path = Path(path)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise InputError(f"{path}: {what} not found; check the path") from None
    except IsADirectoryError:
        raise InputError(f"{path}: {what} is a directory, expected a regular file; give the file "
                         "itself") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot open the {what} ({exc.strerror or exc}); check the path "
                         "and its permissions") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise InputError(f"{path}: the {what} is {file_kind(st.st_mode)}, expected a regular file; "
                             "give a regular file (rotorcosim reads no pipes or devices)")
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        read_log.note(path)            # a scenario load records the files it reads (sweep --resume)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_bytes(path: str | os.PathLike, *, what: str = "file", limit: int | None = None,
               limit_name: str = "orchestrator.untrusted.MAX_TEXT_BYTES") -> bytes:
    """The content of regular file ``path``, at most ``limit`` bytes (default
    :data:`MAX_TEXT_BYTES`); never reads more than ``limit + 1`` bytes."""
    limit = MAX_TEXT_BYTES if limit is None else limit
    with open_regular(path, what=what) as f:
        data = read_bounded(f.read, limit)
    if data is None:
        raise InputError(f"{path}: the {what} is larger than {limit} bytes (the limit); a real "
                         f"{what} is far smaller: check the file (or raise {limit_name} if you "
                         "trust it)")
    return data


def read_bounded(read, limit: int) -> bytes | None:
    """What ``read(n)`` (a file's read, or ``lambda n: os.read(fd, n)``) gives up to its end, or
    None once it has given more than ``limit`` bytes; never asks for more than ``limit + 1``."""
    chunks, n = [], 0
    while True:
        b = read(min(_CHUNK, limit + 1 - n))
        if not b:
            return b"".join(chunks)
        chunks.append(b)
        n += len(b)
        if n > limit:
            return None


def decode_utf8(data: bytes, display: str, what: str = "file") -> str:
    """``data`` as UTF-8 text (a leading BOM dropped); InputError naming line and column
    of the first byte that is not UTF-8."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        col = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise InputError(f"{display}:{line}:{col}: the {what} is not UTF-8 text (byte "
                         f"0x{data[exc.start]:02x}: {exc.reason}); save it as UTF-8") from None
    return text[1:] if text.startswith("\ufeff") else text


def read_text(path: str | os.PathLike, *, what: str = "file", limit: int | None = None) -> str:
    """:func:`read_bytes` decoded as strict UTF-8 (see :func:`decode_utf8`)."""
    return decode_utf8(read_bytes(path, what=what, limit=limit), str(path), what)


def load_json(path: str | os.PathLike, *, what: str = "JSON file", limit: int | None = None,
              fix: str = "rewrite it (or rerun what wrote it)") -> Any:
    """The value of JSON file ``path`` read with :func:`read_text`; InputError for bad JSON
    (including nesting too deep for the parser)."""
    import json

    text = read_text(path, what=what, limit=limit)
    try:
        value = json.loads(text)
    except ValueError as exc:
        raise InputError(f"{path}: the {what} is not valid JSON ({exc}); {fix}") from None
    except RecursionError:
        raise InputError(f"{path}: the {what} is nested too deeply to read; {fix}") from None
    todo = [value]                    # a lone "\ud800" escape is valid JSON but no character
    while todo:
        v = todo.pop()
        if isinstance(v, dict):
            todo.extend(v)
            todo.extend(v.values())
        elif isinstance(v, list):
            todo.extend(v)
        elif isinstance(v, str) and (why := surrogate_problem(v, yaml_fix=False)) is not None:
            raise InputError(f"{path}: the {what} cannot be used: a text in it {why}; {fix}")
    return value


# --------------------------------------------------------------------------- YAML
@functools.lru_cache(maxsize=None)
def _bounded_composer(loader_cls: type) -> type:
    """A subclass of ``loader_cls`` whose composer stops at :data:`MAX_YAML_DEPTH` levels and
    at :data:`MAX_YAML_NODES` values written out (without aliases: a file that is simply too
    big is told so, not taken for an alias bomb, and stops before the rest is composed)."""
    import yaml

    class Bounded(loader_cls):
        _depth = 0
        _nodes = 0

        def compose_node(self, parent, index):
            alias = self.check_event(yaml.AliasEvent)
            if self._depth >= MAX_YAML_DEPTH and not alias:
                mark = self.peek_event().start_mark
                raise _DepthError(mark)
            if not alias:
                self._nodes += 1
                if self._nodes > MAX_YAML_NODES:
                    raise _SizeError(self.peek_event().start_mark)
            self._depth += 1
            try:
                return super().compose_node(parent, index)
            finally:
                self._depth -= 1

    Bounded.__name__ = Bounded.__qualname__ = f"Bounded{loader_cls.__name__}"
    return Bounded


class _DepthError(Exception):
    def __init__(self, mark):
        super().__init__(mark)
        self.mark = mark


class _SizeError(_DepthError):
    pass


def _where(display: str, node_or_mark) -> str:
    mark = getattr(node_or_mark, "start_mark", node_or_mark)
    line = getattr(mark, "line", None)
    return f"{display}:{line + 1}" if line is not None else display


def compose_yaml(text: str, *, display: str, loader_cls: type | None = None):
    """The YAML node tree of ``text`` (one document; None when empty), bounded.

    ``loader_cls`` is the caller's PyYAML loader (its resolvers decide the
    tags, e.g. YAML 1.2 numbers); composition runs in a subclass that bounds
    the nesting depth. Then :func:`check_yaml_tree` bounds the tree as it
    would be with every alias expanded. Raises :class:`InputError` for the
    bounds; PyYAML's own syntax errors (``yaml.YAMLError``) pass through for
    the caller to format.
    """
    import yaml

    key = (text, display, loader_cls or yaml.SafeLoader, MAX_YAML_NODES, MAX_YAML_DEPTH, MAX_INT_DIGITS)
    if len(text) <= _COMPOSED_MAX_CHARS:
        known = _COMPOSED.get(key)
        if known is not None:
            return _clone(known[0])
    loader = _bounded_composer(loader_cls or yaml.SafeLoader)(text)
    try:
        root = loader.get_single_node()
    except _SizeError as exc:
        raise InputError(f"{_where(display, exc.mark)}: the YAML has more than {MAX_YAML_NODES} values (the "
                         "limit; a scenario has a few hundred): shorten it or split it into several "
                         "files") from None
    except _DepthError as exc:
        raise InputError(f"{_where(display, exc.mark)}: the YAML is nested more than {MAX_YAML_DEPTH} levels "
                         "deep (the limit); a scenario needs a handful of levels: flatten it") from None
    finally:
        loader.dispose()
    if root is not None:
        check_yaml_tree(root, display=display)
    if len(text) <= _COMPOSED_MAX_CHARS:
        _COMPOSED[key] = (root,)
        while len(_COMPOSED) > _COMPOSED_ENTRIES:
            _COMPOSED.pop(next(iter(_COMPOSED)))
        return _clone(root)
    return root


#: the last few YAML texts composed, by (text, display, loader class, the bounds checked): a sweep loads the same
#: scenario once per run (twice per load, plus once per ``--set``), and PyYAML's pure-Python
#: composer took 80 % of that (about 10 ms of a 12 ms load of a shipped scenario); a copy of
#: the node tree costs 0.2 ms. Callers change the tree they get (overrides, merge keys), so
#: every caller gets its own copy, with the sharing of aliases kept.
_COMPOSED: dict = {}
_COMPOSED_ENTRIES = 8
_COMPOSED_MAX_CHARS = 1 << 20


def _clone(root):
    """A copy of a composed node tree (new node objects; marks, tags and values shared; a
    node that appears in several places, through an alias, is one copy in those places)."""
    import yaml

    if root is None:                     # an empty document
        return None
    memo: dict[int, Any] = {}

    def copy_node(n):
        c = memo.get(id(n))
        if c is not None:
            return c
        if isinstance(n, yaml.ScalarNode):
            c = memo[id(n)] = yaml.ScalarNode(n.tag, n.value, n.start_mark, n.end_mark, n.style)
            return c
        if isinstance(n, yaml.SequenceNode):
            c = memo[id(n)] = yaml.SequenceNode(n.tag, [], n.start_mark, n.end_mark, n.flow_style)
            c.value = [copy_node(k) for k in n.value]
            return c
        c = memo[id(n)] = yaml.MappingNode(n.tag, [], n.start_mark, n.end_mark, n.flow_style)
        c.value = [(copy_node(k), copy_node(v)) for k, v in n.value]
        return c
    return copy_node(root)


def read_yaml_tree(path: str | os.PathLike, *, what: str, loader_cls: type | None = None,
                   limit: int | None = None):
    """The bounded node tree of YAML file ``path`` (None when empty).

    :func:`read_text` then :func:`compose_yaml`; YAML syntax errors become
    :class:`InputError` with ``file:line:column`` and a hint.
    """
    import yaml

    text = read_text(path, what=what, limit=limit)
    try:
        return compose_yaml(text, display=str(path), loader_cls=loader_cls)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"{path}:{mark.line + 1}:{mark.column + 1}" if mark else str(path)
        context = ""
        if exc.context:
            at = f" (line {exc.context_mark.line + 1})" if exc.context_mark is not None else ""
            context = f"{exc.context}{at}, "
        hint = "(indentation, a missing ':' or a closing bracket)"
        if "flow" in (exc.context or "") and "'['" in (exc.problem or ""):
            # {x[0]: 1.0}: a bracket inside { } or [ ] starts a list; the crane-fmu FMUs' arrays hit it
            hint = ("(a name with brackets, such as x[0], needs quotes inside { } or [ ]: {\"x[0]\": 1.0}, "
                    "[\"osc.x[0]\"]; or write it in block style on its own line)")
        raise InputError(f"{where}: malformed YAML: {context}{exc.problem}; fix the syntax there {hint}") from None
    except yaml.reader.ReaderError as exc:      # a character YAML does not allow (NUL, other controls)
        before = text[:exc.position]
        line, column = before.count("\n") + 1, exc.position - (before.rfind("\n") + 1) + 1
        code = exc.character if isinstance(exc.character, int) else ord(str(exc.character)[:1] or "\0")
        raise InputError(f"{path}:{line}:{column}: a character YAML does not allow (U+{code:04X})"
                         f"{_reader_hint(code)}") from None
    except yaml.YAMLError as exc:
        raise InputError(f"{path}: malformed YAML ({exc}); fix the syntax") from None


def _reader_hint(code) -> str:
    return ("; the file may be binary or in another encoding than UTF-8: save it as UTF-8 text"
            if code == 0 else "; delete it or write it as an escape in a double-quoted string")


def check_yaml_tree(root, *, display: str) -> None:
    """Bound a composed YAML tree as if every alias were expanded.

    Aliases make PyYAML share one node in many places; whatever later copies
    the constructed value (``dataclasses.asdict``, ``json.dumps``,
    ``copy.deepcopy``) copies it once per place. This walks the shared graph
    once (linear in its size) and computes, per node, the expanded node count
    and depth. Raises :class:`InputError` for a recursive alias, more than
    :data:`MAX_YAML_NODES` expanded nodes, more than :data:`MAX_YAML_DEPTH`
    expanded levels, or an integer literal longer than :data:`MAX_INT_DIGITS`.
    """
    import yaml

    size: dict[int, int] = {}
    depth: dict[int, int] = {}
    on_stack: set[int] = set()
    stack = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        kids = _children(node)
        if done:
            on_stack.discard(key)
            size[key] = min(1 + sum(size[id(k)] for k in kids), MAX_YAML_NODES + 1)
            depth[key] = 1 + max((depth[id(k)] for k in kids), default=0)
            if size[key] > MAX_YAML_NODES:
                raise InputError(f"{_culprit(node, size, display)}: the YAML expands to more than {MAX_YAML_NODES} "
                                 "values through aliases ('*name' repeating an '&name' anchor), the limit; this "
                                 "looks like an alias bomb: write the values out or use fewer aliases")
            if depth[key] > MAX_YAML_DEPTH:
                raise InputError(f"{_where(display, node)}: the YAML is nested more than {MAX_YAML_DEPTH} levels deep "
                                 "once its aliases are expanded (the limit); use fewer nested aliases")
            continue
        if key in size:
            continue
        if key in on_stack:
            raise InputError(f"{_where(display, node)}: a YAML alias refers to a mapping or list that contains "
                             "it (a recursive alias); remove the '*name' inside its own '&name' block")
        if isinstance(node, yaml.ScalarNode):
            if node.tag == "tag:yaml.org,2002:int" and len(node.value) > MAX_INT_DIGITS:
                raise InputError(f"{_where(display, node)}: an integer of {len(node.value)} characters (the limit is "
                                 f"{MAX_INT_DIGITS} digits); write a number in range, e.g. 1.0e40")
            why = surrogate_problem(node.value)
            if why is not None:
                raise InputError(f"{_where(display, node)}: the text {why}")
            size[key], depth[key] = 1, 1
            continue
        on_stack.add(key)
        stack.append((node, True))
        stack.extend((k, False) for k in kids if id(k) not in size)


_SURROGATE = re.compile("[\ud800-\udfff]")


def surrogate_problem(text: str, *, yaml_fix: bool = True) -> str | None:
    """Why ``text`` cannot be written as UTF-8, or None: it holds a UTF-16 surrogate (U+D800 to
    U+DFFF), which is no character. A '\\u' escape in a double-quoted YAML string or in JSON
    makes one (YAML does not join a pair of them into one character, and no '\\u' escape of a
    lone one is a character); anything that later writes, prints or hands the text to an FMU
    then failed (``UnicodeEncodeError``). The words fit after "the text"; ``yaml_fix``: end with
    how to write the character in YAML."""
    m = _SURROGATE.search(text) if isinstance(text, str) else None
    if m is None:
        return None
    i = m.start()
    pair = text[i:i + 2]
    if len(pair) == 2 and "\ud800" <= pair[0] <= "\udbff" and "\udc00" <= pair[1] <= "\udfff":
        cp = 0x10000 + ((ord(pair[0]) - 0xD800) << 10) + (ord(pair[1]) - 0xDC00)
        fix = f"write the character itself, or the pair as one escape of its code point: \\U{cp:08X}"
    else:
        fix = "write the character itself, or its code point as an escape: \\U and 8 hex digits"
    return (f"holds \\u{ord(text[i]):04x} (character {i + 1}), half of a UTF-16 surrogate pair written as a "
            f"'\\u' escape, which is no character and cannot be written as UTF-8" + (f"; {fix}" if yaml_fix else ""))


def _children(node) -> list:
    import yaml

    if isinstance(node, yaml.MappingNode):
        return [n for pair in node.value for n in pair]
    if isinstance(node, yaml.SequenceNode):
        return list(node.value)
    return []


def _culprit(node, size: dict[int, int], display: str) -> str:
    """Location of the innermost node whose expansion alone exceeds the limit."""
    while True:
        big = [k for k in _children(node) if size.get(id(k), 0) > MAX_YAML_NODES]
        if not big:
            return _where(display, node)
        node = big[0]


def construct_yaml(root, *, display: str, loader_cls: type | None = None):
    """Python value of a composed (and checked) node tree, with ``loader_cls``'s constructors."""
    import yaml

    loader = (loader_cls or yaml.SafeLoader)("")
    try:
        return loader.construct_document(root)
    finally:
        loader.dispose()


def load_yaml(text: str, *, display: str, loader_cls: type | None = None):
    """:func:`compose_yaml` then construct: the bounded replacement of ``yaml.load``."""
    root = compose_yaml(text, display=display, loader_cls=loader_cls)
    return None if root is None else construct_yaml(root, display=display, loader_cls=loader_cls)


# --------------------------------------------------------------------------- XML
def parse_xml(data: bytes, *, display: str, what: str = "XML file"):
    """The root element of XML ``data`` (``xml.etree.ElementTree.Element``).

    Parsed by defusedxml with ``forbid_dtd``, ``forbid_entities`` and
    ``forbid_external``: the parser refuses a DOCTYPE (hence any entity
    declaration) when it meets it, after decoding, whatever the encoding.
    Raises :class:`InputError`.
    """
    from xml.etree.ElementTree import ParseError

    import defusedxml
    from defusedxml.ElementTree import fromstring

    try:
        return fromstring(data, forbid_dtd=True, forbid_entities=True, forbid_external=True)
    except defusedxml.DefusedXmlException as exc:
        raise InputError(f"{display}: the {what} contains a DOCTYPE, entity declaration or external reference "
                         f"({type(exc).__name__}), which can expand or fetch content; rotorcosim refuses it: "
                         "remove the DOCTYPE (FMI model descriptions never need one)") from None
    except ParseError as exc:
        raise InputError(f"{display}: the {what} is not well-formed XML ({exc}); re-export it") from None
    except (ValueError, LookupError) as exc:        # e.g. an encoding expat does not know
        raise InputError(f"{display}: the {what} cannot be decoded ({exc}); write it as UTF-8") from None


# --------------------------------------------------------------------------- names
_WINDOWS_RESERVED = re.compile(r"^(con|prn|aux|nul|com[0-9]|lpt[0-9])(\..*)?$", re.I)


def name_problem(name: Any) -> str | None:
    """Why ``name`` cannot be a file or folder name (None: it can).

    A name is one path component: a non-empty text of at most
    :data:`MAX_NAME_CHARS` characters, not starting with '.' or ending with
    '.' or a space, without '/', '\\', ':', control characters or the
    characters ``<>"|?*``, and not a Windows device name (``con``, ``nul``...).
    """
    if not isinstance(name, str) or not name:
        return f"it is not a non-empty text (got {name!r})"
    if len(name) > MAX_NAME_CHARS:
        return f"it has {len(name)} characters (the limit is {MAX_NAME_CHARS})"
    bad = sorted({c for c in name if c in '/\\:<>"|?*' or ord(c) < 32 or ord(c) == 127})
    if bad:
        return f"it contains {', '.join(repr(c) for c in bad)} (got {name!r})"
    # invisible and direction-changing characters (U+202E shows the rest of a name reversed,
    # U+200B is not seen at all): a folder name must read as it is
    hidden = sorted({c for c in name if unicodedata.category(c) in ("Cc", "Cf", "Cs", "Zl", "Zp")})
    if hidden:
        codes = ", ".join(f"U+{ord(c):04X} ({unicodedata.name(c, 'unnamed')})" for c in hidden)
        return f"it contains invisible or direction-changing characters: {codes} (got {name!r})"
    if name.startswith("."):
        return f"it starts with '.' (got {name!r}; '..' and hidden names are not allowed)"
    if name.endswith((".", " ")) or name.startswith(" "):
        return f"it starts or ends with a space or ends with '.' (got {name!r})"
    if _WINDOWS_RESERVED.match(name):
        return f"it is a reserved device name on Windows (got {name!r})"
    return None


def check_name(name: Any, *, what: str, where: str = "") -> str:
    """``name`` if it can be a file or folder name, else :class:`InputError` saying why."""
    problem = name_problem(name)
    if problem is not None:
        prefix = f"{where}: " if where else ""
        raise InputError(f"{prefix}{what} becomes a file or folder name, but {problem}; use letters, digits, "
                         "'-', '_' and '.' (e.g. 'gs-e0-h0.001')")
    return name


def child_path(base: str | os.PathLike, name: str, *, what: str, where: str = "") -> Path:
    """``base / name`` after :func:`check_name`, guaranteed to lie directly in ``base``."""
    check_name(name, what=what, where=where)
    base = Path(base)
    target = base / name
    if target.parent != base:                     # defensive: check_name already excludes separators
        raise InputError(f"{where + ': ' if where else ''}{what} {name!r} leaves {base}; rename it")
    return target


# --------------------------------------------------------------------------- templates
_SPEC_RE = re.compile(r"^(?:.?[<>=^])?[-+ ]?#?0?(?P<w>[0-9]*)[,_]?(?:\.(?P<p>[0-9]*))?[bcdeEfFgGnosxX%]?$")


def format_template(template: str, fields: Mapping[str, Any], *, what: str, where: str = "") -> str:
    """``template.format(**fields)`` allowing only ``{field}`` and ``{field:spec}``.

    Plain field names from ``fields`` only (no attribute access ``{x.a}``, no
    index ``{x[0]}``, no positional ``{}`` or ``{0}``, no ``!r``/``!s``
    conversion), and a simple format spec (no nested ``{}``; width and
    precision of at most :data:`MAX_FORMAT_WIDTH` digits). Raises
    :class:`InputError` listing the valid fields.
    """
    prefix = f"{where}: " if where else ""
    valid = ", ".join("{" + k + "}" for k in sorted(fields))
    if not isinstance(template, str):
        raise InputError(f"{prefix}{what} must be a text such as 'gs-h{{macro_step:g}}' (got {template!r})")
    try:
        parts = list(string.Formatter().parse(template))
    except ValueError as exc:
        raise InputError(f"{prefix}{what} {template!r} is not a valid template ({exc}); write '{{{{' for a "
                         f"literal brace; fields: {valid}") from None
    for _, field_name, spec, conversion in parts:
        if field_name is None:
            continue
        if field_name not in fields:
            raise InputError(f"{prefix}{what} {template!r} uses {{{field_name}}}, which is not a field (only plain "
                             f"field names are allowed, no '.', '[]' or positions); fields: {valid}")
        if conversion is not None:
            raise InputError(f"{prefix}{what} {template!r} uses the conversion '!{conversion}'; remove it "
                             f"(fields: {valid})")
        m = _SPEC_RE.match(spec or "")
        if m is None or "{" in (spec or "") or len(m.group("w") or "") > MAX_FORMAT_WIDTH or \
                len(m.group("p") or "") > MAX_FORMAT_WIDTH:
            raise InputError(f"{prefix}{what} {template!r} has the format spec {spec!r} for {{{field_name}}}; "
                             f"use a simple one such as ':g' or ':.3f' (width and precision of at most "
                             f"{MAX_FORMAT_WIDTH} digits)")
    try:
        return template.format(**fields)
    except (ValueError, TypeError) as exc:          # e.g. ':d' applied to a float
        raise InputError(f"{prefix}{what} {template!r} cannot be formatted ({exc}); use ':g' for numbers "
                         f"(fields: {valid})") from None


OUT_DIR_FIELD = "{out_dir}"


def out_dir_escape(value: str) -> str | None:
    """Why a String parameter written as a path in the run folder (``{out_dir}/...``, which the
    master replaces by the run folder) would leave it (None: it stays inside, or it is no such
    path). ``{out_dir}/../x`` would write beside the run folder, wherever the run is."""
    if not isinstance(value, str) or not value.startswith(OUT_DIR_FIELD):
        return None
    rest = value[len(OUT_DIR_FIELD):].replace("\\", "/")
    parts = [q for q in rest.split("/") if q not in ("", ".")]
    depth = 0
    for q in parts:
        depth += -1 if q == ".." else 1
        if depth < 0:
            return (f"'..' climbs out of the run folder (got {value!r}); write a path below it, "
                    f"e.g. '{OUT_DIR_FIELD}/name.npz'")
    if OUT_DIR_FIELD in rest:
        return f"'{OUT_DIR_FIELD}' may appear once, at the start (got {value!r})"
    return None


# characters of FMU text (log messages, descriptions) that a terminal would act on rather than
# show: C0/C1 controls (ESC starts sequences that clear the screen, retitle the window or hide
# text; a bare CR overwrites the line) and the bidirectional overrides that show text reversed
UNSHOWN = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u202a-\u202e\u2066-\u2069]")


def shown_char(m: re.Match) -> str:
    c = ord(m.group())
    return f"\\x{c:02x}" if c < 0x100 else f"\\u{c:04x}"


def terminal_text(text: str) -> str:
    """``text`` (from an FMU or a file) with the characters a terminal would act on shown
    escaped (``\\x1b``, ``\\u202e``), tabs and line breaks included (for one-line fields)."""
    return re.sub("[\t\n]", lambda m: "\\t" if m.group() == "\t" else "\\n", UNSHOWN.sub(shown_char, text))

