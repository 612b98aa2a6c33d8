"""Signal names: wildcards and array elements.

A pattern is a signal name in which ``*`` stands for any run of characters
(including none); every other character, brackets and dots included, is
literal. So ``osc.x[*]`` matches ``osc.x[0]``, ``osc.x[1,2]``; ``bearing1.*``
matches every variable of ``bearing1``; ``*.omega`` the ``omega`` of every
instance. (Shell-style ``?`` and ``[abc]`` classes are deliberately not
supported: FMI names use brackets for array indices.)

``array_elements(name, names)`` gives the elements ``name[i]``, ``name[i,j]``
of an array variable ``name`` in ``names``, in file order, for element-wise
connections ``drv.f -> osc.f``.
"""

from __future__ import annotations

import re
from typing import Iterable, Sequence


def is_pattern(text: str) -> bool:
    return "*" in text


def _regex(pattern: str) -> re.Pattern:
    return re.compile("".join(".*" if ch == "*" else re.escape(ch) for ch in pattern) + r"\Z", re.DOTALL)


def match(pattern: str, names: Iterable[str]) -> list[str]:
    """The names matching ``pattern`` (a literal name matches itself only), in the order given."""
    if not is_pattern(pattern):
        return [n for n in names if n == pattern]
    rx = _regex(pattern)
    return [n for n in names if rx.match(n)]


def array_elements(name: str, names: Sequence[str]) -> list[str]:
    """Elements ``name[...]`` of the array ``name`` among ``names`` (empty if ``name`` is no array)."""
    prefix = name + "["
    return [n for n in names if n.startswith(prefix) and n.endswith("]") and "]" not in n[len(prefix):-1]]


def index_of(element: str) -> str:
    """The index part of an array element name, ``"f[1,2]"`` -> ``"1,2"``."""
    return element[element.rindex("[") + 1:-1]
