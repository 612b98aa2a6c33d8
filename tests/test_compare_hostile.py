"""Hostile comparison files: the baseline path, non-finite numbers, the reference's step and
the compared signals are checked when the file is loaded, before any run.

Each case writes a comparison over the two-mass test FMUs, calls ``main_compare`` with a
runner that records calls, and checks the exit code, that nothing ran, and that the message
names the file and line (or field), what came and the fix.
"""

from __future__ import annotations

import os

import pytest

from hostile_builders import two_mass_dir
from orchestrator.compare import load_compare, main_compare

needs_fifo = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs os.mkfifo")
needs_symlink = pytest.mark.skipif(os.name == "nt", reason="symbolic links")


def compare_file(tmp, body: str, *, signals: str = "[left.x1]", reference: str = "{macro_step: 1.0e-4}",
                 variants: str = "[{macro_step: 1.0e-3}]") -> os.PathLike:
    """Lines: 1 compare, 2 scenario, 3 signals, 4 reference, 5 variants, 6.. ``body``."""
    p = tmp / "cmp.yaml"
    p.write_text(f"compare:\n  scenario: two_mass.yaml\n  signals: {signals}\n  reference: {reference}\n"
                 f"  variants: {variants}\n{body}")
    return p


def refused(capsys, tmp, line: int, words: str, body: str = "", **parts) -> str:
    """The compare file of :func:`compare_file` is refused (exit 2) with ``file:line: words``;
    the whole output."""
    p = compare_file(tmp, body, **parts)
    rc, text = run_compare(capsys, p, tmp)
    assert rc == 2 and f"{p}:{line}: {words}" in text, text
    return text


def run_compare(capsys, path, tmp, **kw) -> tuple[int, str]:
    """``main_compare`` with a runner that must not be called (every case fails before a run)."""
    calls = []

    def runner(scenario, out_dir):
        calls.append(out_dir)
    rc = main_compare(path, out_dir=tmp / "out", runner=runner, workers=1, **kw)
    cap = capsys.readouterr()
    text = cap.out + cap.err
    assert "internal error" not in text and "Traceback" not in text, text
    assert calls == [], f"runs started: {calls}"
    return rc, text


@pytest.fixture
def base(tmp_path, test_fmus):
    return two_mass_dir(tmp_path, test_fmus)


# --------------------------------------------------------------------------- baseline path
@needs_fifo
@pytest.mark.parametrize("update", [True, False])
def test_baseline_fifo_is_refused_before_any_run(base, capsys, update):
    """With --update-baseline the old code ran everything, then blocked forever writing the FIFO."""
    os.mkfifo(base / "b.json")
    p = compare_file(base, "  baseline: b.json\n")
    rc, text = run_compare(capsys, p, base, update_baseline=update)
    assert rc == 2, text
    assert f"{p}:6: 'compare.baseline' names {base / 'b.json'}, which is a named pipe (FIFO)" in text
    assert "baselines/NAME.json" in text
    assert not os.path.isfile(base / "b.json")                  # still the FIFO


def test_baseline_directory_is_refused_before_any_run(base, capsys):
    (base / "bdir").mkdir()
    p = compare_file(base, "  baseline: bdir\n")
    rc, text = run_compare(capsys, p, base, update_baseline=True)
    assert rc == 2 and f"{p}:6: 'compare.baseline'" in text and "which is a directory" in text, text
    assert list((base / "bdir").iterdir()) == []


@needs_symlink
def test_update_baseline_does_not_write_through_a_link(base, capsys):
    victim = base / "victim.json"
    victim.write_text("keep me")
    (base / "b.json").symlink_to(victim)
    p = compare_file(base, "  baseline: b.json\n")
    rc, text = run_compare(capsys, p, base, update_baseline=True)
    assert rc == 2, text
    assert f"{p}: 'compare.baseline': {base / 'b.json'} is a symbolic link" in text
    assert "does not write through a link" in text
    assert victim.read_text() == "keep me" and (base / "b.json").is_symlink()


def test_update_baseline_below_a_file_is_refused_before_any_run(base, capsys):
    (base / "plain").write_text("x")
    p = compare_file(base, "  baseline: plain/b.json\n")
    rc, text = run_compare(capsys, p, base, update_baseline=True)
    assert rc == 2 and f"{base / 'plain'} is not a folder" in text and "'compare.baseline'" in text, text


def test_write_baseline_refuses_a_link_planted_after_the_check(tmp_path):
    """write_baseline checks again (the runs take long) and writes through a temporary file and a
    rename: a link planted at the baseline meanwhile is refused, its target untouched."""
    from orchestrator.compare.metrics import write_baseline
    from orchestrator.errors import CosimError

    class Report:
        variants = [{"name": "v", "stable": True, "fmu_calls": 3, "errors": {"max": 0.5}}]

    class Spec:
        name = "c"
    target = tmp_path / "b.json"
    write_baseline(Report(), Spec(), target)
    assert '"max": 0.5' in target.read_text()
    victim = tmp_path / "victim.json"
    victim.write_text("keep me")
    target.unlink()
    target.symlink_to(victim)
    with pytest.raises(CosimError, match="symbolic link"):
        write_baseline(Report(), Spec(), target)
    assert victim.read_text() == "keep me"


# --------------------------------------------------------------------------- numbers
@pytest.mark.parametrize("line, words", [
    ("  regression_margin: .nan\n", "'compare.regression_margin' must be a finite number >= 0"),
    ("  regression_margin: .inf\n", "'compare.regression_margin' must be a finite number >= 0"),
    ("  order_tolerance: .nan\n", "'compare.order_tolerance' must be a finite number >= 0"),
    ("  order_tolerance: .inf\n", "'compare.order_tolerance' must be a finite number >= 0"),
    ("  regression_floor: .nan\n", "'compare.regression_floor' must be a finite number >= 0"),
    ("  tolerance: {max: .nan}\n", "'compare.tolerance' value of 'max' must be a positive number (got nan)"),
    ("  tolerance: {rms: .inf}\n", "'compare.tolerance' value of 'rms' must be a positive number (got inf)"),
])
def test_non_finite_numbers_are_refused_with_file_and_line(base, capsys, line, words):
    assert "(got " in refused(capsys, base, 6, words, line)


@pytest.mark.parametrize("variants, words", [
    ("[{macro_step: 1.0e-3, tolerance: {max: .nan}}]", "'compare.variants[0].tolerance' value of 'max'"),
    ("[{macro_step: 1.0e-3, expect_order: .nan}]", "'compare.variants[0].expect_order' must be a finite number"),
])
def test_non_finite_variant_values_are_refused(base, capsys, variants, words):
    refused(capsys, base, 5, words, variants=variants)


def test_non_finite_signal_scale_is_refused(base, capsys):
    refused(capsys, base, 3, "'compare.signals' scale of 'left.x1' must be a positive finite number",
            signals="{left.x1: {scale: .nan}}")


# --------------------------------------------------------------------------- reference step
@pytest.mark.parametrize("reference, words", [
    ("{scheme: gauss-seidel, macro_step: 1.0e-2}", "macro_step 0.01 s is not finer than the macro step 0.001 s"),
    ("{macro_step: 1.0e-3}", "macro_step 0.001 s is not finer than the macro step 0.001 s"),
    ("{macro_step: 3.0e-4}", "macro_step 0.0003 s does not divide the macro step 0.001 s"),
    ("{set: {coupling.macro_step: 3.0e-4}}", "macro_step 0.0003 s does not divide the macro step 0.001 s"),
])
def test_reference_must_be_finer_and_divide_every_variant_step(base, capsys, reference, words):
    text = refused(capsys, base, 4, f"'compare.reference' {words}", reference=reference,
                   variants="[{macro_step: [1.0e-3, 2.0e-3]}]")
    assert "e.g. 0.0001" in text and "scheme: monolithic" in text


def test_finer_dividing_reference_is_accepted(base):
    p = compare_file(base, "", reference="{macro_step: 2.5e-4}", variants="[{macro_step: [1.0e-3, 2.0e-3]}]")
    spec = load_compare(p)
    assert spec.reference.changes["coupling.macro_step"] == 2.5e-4 and len(spec.variants) == 2


# --------------------------------------------------------------------------- signals
@pytest.fixture
def base_all_outputs(base):
    """The two-mass base recording its default signals (every output): no output.signals."""
    text = (base / "two_mass.yaml").read_text()
    (base / "two_mass.yaml").write_text(text.replace("  signals: [left.x1, right.F]\n", ""))
    assert "signals" not in (base / "two_mass.yaml").read_text()
    return base


@pytest.mark.parametrize("signals, words", [
    ("[nope.x]", "entry 'nope.x' names the instance 'nope', which is not an FMU of the base scenario; "
                 "instances: left, right"),
    ("[left.nope]", "entry 'left.nope': 'left' has no variable 'nope'; outputs of 'left' (closest first): "),
    ("[left.F]", "entry 'left.F': 'F' of 'left' is an input, and a run records only outputs"),
    ("[x1]", "entry 'x1' must be 'instance.variable'"),
])
def test_unknown_signal_is_refused_before_the_reference_runs(base_all_outputs, capsys, signals, words):
    refused(capsys, base_all_outputs, 3, f"'compare.signals' {words}", signals=signals)


def test_output_of_the_base_is_accepted_as_a_signal(base_all_outputs):
    spec = load_compare(compare_file(base_all_outputs, "", signals="[left.x1, left.v1]"))
    assert list(spec.signals) == ["left.x1", "left.v1"]
