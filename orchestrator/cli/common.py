"""What the verbs of the command line share: the program's name, ``--set`` and ``--out DIR``, and
:func:`_feature`, which imports the module that implements a verb when the verb runs."""

from __future__ import annotations

import argparse
import importlib
from typing import Callable

from orchestrator.errors import CosimError


PROG = "rotorcosim"


class _Unavailable(CosimError):
    """A verb whose implementing module is not installed (yet)."""


def _feature(module: str, attr: str, verb: str) -> Callable:
    """``module.attr``, imported when a verb needs it; a clear error if it is not there."""
    try:
        mod = importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name == module:
            raise _Unavailable(f"`{PROG} {verb}` is not available in this installation: the module {module} "
                               "is missing; update rotorcosim (pip install -e . in the repository)") from None
        if exc.name and not exc.name.startswith("orchestrator"):
            pkg = exc.name.split(".")[0]
            raise _Unavailable(f"`{PROG} {verb}` needs the Python package '{pkg}', which is not installed; "
                               f"install it (pip install {pkg})") from None
        raise
    func = getattr(mod, attr, None)
    if func is None:
        raise _Unavailable(f"`{PROG} {verb}` is not available in this installation: {module}.{attr} is "
                           "missing; update rotorcosim")
    return func


def _add_set(p) -> None:
    p.add_argument("--set", metavar="KEY=VALUE", action="append", default=[],
                   help="override a scenario value, e.g. --set coupling.macro_step=5e-5 (repeatable)")


def _folder(value: str) -> str:
    """argparse type of the ``--out DIR`` options: not empty (an empty one silently meant the
    default folder)."""
    if not value.strip():
        raise argparse.ArgumentTypeError("an empty folder name: give a folder, or leave --out out "
                                         "for the default")
    return value
