"""Shared fixtures: test FMUs built once per session with pythonfmu.

``test_fmus`` builds every ``tests/fmus_src/*.py`` into a session temporary
directory and returns ``{class_name: Path}``, e.g. ``test_fmus["LeftMass"]``.
Other owners may use it (it is the documented way to get small real FMUs).
"""

from __future__ import annotations

import os

# The tests' matrices are small (the linear fakes' expm is 14x14): BLAS threads only contend with
# each other on a shared machine (measured: 3.9 ms instead of 0.064 ms per expm at load 8 on 2
# cores). Set before numpy is first imported (below, via orchestrator).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from pathlib import Path  # noqa: E402

import pytest

from orchestrator.reference.models import load_model_file
from tests.exit_plugin import pytest_sessionfinish, pytest_unconfigure  # noqa: F401  (hooks: leave without teardown)

# the monolithic reference's adapters of the two-mass test FMUs (not in production code)
load_model_file(Path(__file__).parent / "fmus_src" / "_reference_models.py")

FMU_SRC = Path(__file__).parent / "fmus_src"

# Build options per source file (FMI CoSimulation capability flags).
_OPTIONS = {
    "integrator": {"canGetAndSetFMUstate": True},
    "left_mass": {"canGetAndSetFMUstate": True},
    "right_mass": {"canGetAndSetFMUstate": True},
    # a LeftMass subclass: left_mass.py goes into the FMU's resources (on its sys.path)
    "step_limited_mass": {"project_files": {FMU_SRC / "left_mass.py"}},
}


def build_test_fmus(dest: Path) -> dict[str, Path]:
    """Build every test FMU source into ``dest``; return ``{model_name: fmu_path}``."""
    from pythonfmu.builder import FmuBuilder

    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    out = {}
    for src in sorted(FMU_SRC.glob("*.py")):
        if src.name.startswith("_"):
            continue
        path = Path(FmuBuilder.build_FMU(src, dest=dest, **_OPTIONS.get(src.stem, {})))
        out[path.stem] = path
    return out


@pytest.fixture(scope="session", autouse=True)
def our_fmus_built():
    """Our own FMUs (``fmus/`` of the checkout) built and up to date once per session:
    loading a scenario does not build them (issue 12), ``rotorcosim run``/``validate`` do."""
    from orchestrator.fmi.build import FMU_DIR, build_fmus, in_checkout
    if in_checkout():
        build_fmus(FMU_DIR)


@pytest.fixture(scope="session")
def test_fmus(tmp_path_factory) -> dict[str, Path]:
    """Paths of the test FMUs (LeftMass, RightMass, Gain, Integrator, Faulty, Trivial, Params)."""
    return build_test_fmus(tmp_path_factory.mktemp("test_fmus"))


@pytest.fixture
def figures(monkeypatch):
    """The figures ``orchestrator.sweep.plot`` saves (still saved for real), for tests that look at
    the axes of a sweep map."""
    from orchestrator.sweep import plot as sweep_plot
    saved = []
    real = sweep_plot.save_figure

    def keep(fig, path):
        saved.append(fig)
        return real(fig, path)
    monkeypatch.setattr(sweep_plot, "save_figure", keep)
    return saved
