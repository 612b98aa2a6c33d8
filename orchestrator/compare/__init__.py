"""Coupling-scheme comparison (``rotorcosim compare``): spec, runner, metrics, report.

Runs a scenario in variants against a reference, fits convergence orders, gates on tolerances and a baseline.
"""

from orchestrator.compare.metrics import check_report, fit_order, signal_errors
from orchestrator.compare.report import write_report
from orchestrator.compare.runner import CompareReport, default_runner, main_compare, run_comparison
from orchestrator.compare.spec import (
    CompareSpec, CompareSpecError, ReferenceSpec, VariantSpec, apply_changes, expand_variants, load_compare,
    parse_compare)

__all__ = ["CompareSpecError", "CompareSpec", "VariantSpec", "ReferenceSpec", "load_compare",
           "parse_compare", "expand_variants", "apply_changes", "run_comparison", "main_compare",
           "CompareReport", "default_runner", "check_report", "fit_order", "signal_errors", "write_report"]
