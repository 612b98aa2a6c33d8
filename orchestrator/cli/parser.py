"""The command line's parser: one sub-parser per verb, each registered by its verb's own small
``_add_<verb>`` function (the shape of PythonFMU's ``create_command_parser``)."""

from __future__ import annotations

import argparse

from orchestrator.cli.common import PROG
from orchestrator.cli.files import _add_export_ssp, _add_init, _add_plot, _add_scenarios
from orchestrator.cli.fmus import _add_build_fmus, _add_info
from orchestrator.cli.run import _add_compare, _add_run, _add_validate
from orchestrator.cli.stability import _add_stability
from orchestrator.cli.sweep import _add_sweep


VERBS = (_add_run, _add_validate, _add_info, _add_build_fmus, _add_plot, _add_compare, _add_scenarios, _add_init,
         _add_export_ssp, _add_sweep, _add_stability)


def build_parser() -> argparse.ArgumentParser:
    # --debug before the verb and after it: two destinations (a sub-parser's defaults would
    # overwrite the value given before the verb), joined in main()
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--debug", action="store_true", dest="debug_verb",
                        help="show debug logging and full tracebacks")
    parser = argparse.ArgumentParser(prog=PROG, description=(
        "Co-simulation of FMI 2.0 co-simulation FMUs (rotors in journal bearings and any other FMUs)."))
    parser.add_argument("--debug", action="store_true", help="show debug logging and full tracebacks")
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = parser.add_subparsers(dest="verb", metavar="VERB", required=True)
    orig = sub.add_parser

    def add_parser(name, **kw):                  # every verb also takes --debug after the verb
        return orig(name, parents=[common], **kw)

    sub.add_parser = add_parser
    for add in VERBS:
        add(sub)
    for verb in sub.choices.values():            # a value option given twice is refused, not overwritten
        for action in verb._actions:
            if type(action) is argparse._StoreAction and action.option_strings:
                action.__class__ = _StoreOnce
    return parser


class _StoreOnce(argparse._StoreAction):
    """An option that takes one value (``--out DIR``): given twice, argparse kept the last one
    silently (``--out A --out B`` wrote to B); now it is a usage error naming both."""

    def __call__(self, parser, namespace, values, option_string=None):
        seen = namespace.__dict__.setdefault("_given_once", {})
        if self.dest in seen:
            raise argparse.ArgumentError(
                self, f"given twice ({seen[self.dest]!r}, then {values!r}); give it once")
        seen[self.dest] = values
        super().__call__(parser, namespace, values, option_string)


def _version() -> str:
    try:
        from importlib.metadata import version
        return version("rotorcosim")
    except Exception:                             # not installed (running from a source tree)
        return "unknown"
