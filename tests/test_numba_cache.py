"""The content-addressed numba cache (bearing_fmu/_numba_cache.py): a second copy of the
package in another directory (what every FMU extraction is) loads the kernels compiled by the
first instead of recompiling them."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

# the source packages of the checkout (an in-process FMU run of an earlier test can leave
# bearing_fmu / rotor_fmu imported from its extraction folder, deleted since)
PKG = Path(__file__).resolve().parents[1] / "bearing_fmu"

PROBE = """
import numpy as np, bearing_fmu, bearing_fmu.cavitation as c
u = np.linspace(-1, 1, 7); o = [np.empty(7) for _ in range(4)]
c.law_eval(u, 9.9e4, 1e7, 0.05, *o)
s = c.law_eval.stats
print(bearing_fmu.__file__, sum(s.cache_hits.values()), sum(s.cache_misses.values()), s.cache_path)
"""


def _copy(dst):
    shutil.copytree(PKG, dst / "bearing_fmu", ignore=shutil.ignore_patterns("__pycache__"))


def _probe(where, env):
    out = subprocess.run([sys.executable, "-c", PROBE], cwd=where, env=env, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    f, hits, misses, path = out.stdout.split()
    assert f.startswith(str(where)), f           # the copy, not the installed package
    return int(hits), int(misses), path


def test_second_copy_loads_the_cache(tmp_path):
    a, b, root = tmp_path / "a", tmp_path / "b", tmp_path / "cache"
    _copy(a)
    _copy(b)
    env = dict(os.environ, ROTORCOSIM_NUMBA_CACHE=str(root), PYTHONPATH="")
    h1, m1, p1 = _probe(a, env)
    h2, m2, p2 = _probe(b, env)
    assert (h1, m1) == (0, 1)                    # compiled in the first copy
    assert (h2, m2) == (1, 0)                    # loaded from the cache in the second
    assert p1 == p2 and p1.startswith(str(root))


def test_changed_source_gets_its_own_cache(tmp_path):
    a, root = tmp_path / "a", tmp_path / "cache"
    _copy(a)
    env = dict(os.environ, ROTORCOSIM_NUMBA_CACHE=str(root), PYTHONPATH="")
    _, _, p1 = _probe(a, env)
    with open(a / "bearing_fmu" / "cavitation.py", "a") as f:
        f.write("\n# changed\n")
    h, m, p2 = _probe(a, env)
    assert p2 != p1 and (h, m) == (0, 1)         # new content: recompiled, not a stale load


def test_switched_off_uses_numba_default(tmp_path):
    a = tmp_path / "a"
    _copy(a)
    env = dict(os.environ, ROTORCOSIM_NUMBA_CACHE="off", PYTHONPATH="")
    _, _, p = _probe(a, env)
    assert p == str(a / "bearing_fmu" / "__pycache__")


ROTOR_PROBE = """
import numpy as np, rotor_fmu.linear_rotor as l
t = np.array([0.0, 1.0]); w = np.array([0.0, 10.0]); a = np.array([0.0, 5.0])
l._drive_eval(0.5, t, w, a)
s = l._drive_eval.stats
print(l.__file__, sum(s.cache_hits.values()), sum(s.cache_misses.values()), s.cache_path)
"""


def test_rotor_numba_kernels_share_the_cache_across_copies(tmp_path):
    """The rotor FMU's numba kernels (ROTORCOSIM_ROTOR_KERNEL=numba) are extracted afresh with
    their FMU for every run too: a second copy loads what the first compiled."""
    root, hits = tmp_path / "cache", []
    env = dict(os.environ, ROTORCOSIM_NUMBA_CACHE=str(root), PYTHONPATH="", ROTORCOSIM_ROTOR_KERNEL="numba")
    for name in ("a", "b"):
        shutil.copytree(PKG.parent / "rotor_fmu", tmp_path / name / "rotor_fmu",
                        ignore=shutil.ignore_patterns("__pycache__", "data"))
        out = subprocess.run([sys.executable, "-c", ROTOR_PROBE], cwd=tmp_path / name, env=env,
                             capture_output=True, text=True, timeout=300)
        assert out.returncode == 0, out.stderr
        f, h, m, path = out.stdout.split()
        assert f.startswith(str(tmp_path / name)) and path.startswith(str(root)), (f, path)
        hits.append((int(h), int(m)))
    assert hits == [(0, 1), (1, 0)]


def test_processes_compiling_at_once_all_succeed_and_leave_a_loadable_cache(tmp_path):
    """Four processes with an empty cache compile the same kernel at the same time (what the
    first runs of a sweep do); each succeeds, and a fifth loads the cache they left."""
    copies, root = [tmp_path / f"c{i}" for i in range(5)], tmp_path / "cache"
    for c in copies:
        _copy(c)
    env = dict(os.environ, ROTORCOSIM_NUMBA_CACHE=str(root), PYTHONPATH="")
    procs = [subprocess.Popen([sys.executable, "-c", PROBE], cwd=c, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for c in copies[:4]]
    for p in procs:
        out, err = p.communicate(timeout=600)
        assert p.returncode == 0, err
        assert int(out.split()[1]) + int(out.split()[2]) == 1        # compiled or loaded, never failed
    assert _probe(copies[4], env)[:2] == (1, 0)


CALLER_PROBE = """
import numpy as np, bearing_fmu, bearing_fmu.fused as fz
print(bearing_fmu.__file__, fz.advance_fused._cache._cache_path)
"""


def test_changed_callee_in_another_module_gets_a_new_cache_for_the_caller(tmp_path):
    """A cached kernel holds the compiled code of the kernels it calls: ``fused.advance_fused``
    calls ``film.assemble``. Keyed by its own file only, a change to film.py alone left the
    fused kernel loading its old machine code (the film's old residual) from the cache; the
    key now covers the package's sources, so the caller's cache directory changes too."""
    a, root = tmp_path / "a", tmp_path / "cache"
    _copy(a)
    env = dict(os.environ, ROTORCOSIM_NUMBA_CACHE=str(root), PYTHONPATH="")

    def cache_dir():
        out = subprocess.run([sys.executable, "-c", CALLER_PROBE], cwd=a, env=env,
                             capture_output=True, text=True, timeout=300)
        assert out.returncode == 0, out.stderr
        f, path = out.stdout.split()
        assert f.startswith(str(a)), f
        return path

    p1 = cache_dir()
    assert p1.startswith(str(root)) and os.path.basename(p1).startswith("fused-")
    with open(a / "bearing_fmu" / "film.py", "a") as f:      # the callee's file, not fused.py
        f.write("\n# changed\n")
    p2 = cache_dir()
    assert p2 != p1 and os.path.basename(p2).startswith("fused-")


GONE_PROBE = """
import importlib, shutil, sys, numba
from bearing_fmu._numba_cache import njit_cached
sys.path.insert(0, sys.argv[1])
m = importlib.import_module("gone_kernels")
shutil.rmtree(sys.argv[1])                      # the folder goes, the module stays imported
try:
    numba.njit(cache=True)(m.twice)
    print("plain-ok")
except RuntimeError as exc:
    print("plain-fails" if "no locator" in str(exc) else "plain-other")
print(njit_cached(m.twice)(21.0))
"""


def test_kernel_from_a_deleted_source_folder_compiles_without_the_cache(tmp_path):
    """A module whose folder was removed after its import (an FMU's extraction folder freed while
    its modules stay imported): ``njit_cached`` compiles its function in memory, where numba's
    ``cache=True`` stops with "no locator available"."""
    src = tmp_path / "src"
    src.mkdir()
    (src / "gone_kernels.py").write_text("def twice(x):\n    return 2.0 * x\n")
    env = dict(os.environ, ROTORCOSIM_NUMBA_CACHE=str(tmp_path / "cache"),
               PYTHONPATH=str(PKG.parent))
    out = subprocess.run([sys.executable, "-c", GONE_PROBE, str(src)], env=env, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["plain-fails", "42.0"]


FREED_FMU_PROBE = """
import shutil, sys
from dataclasses import replace
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from orchestrator import load_scenario, run
fmu, scenario, out = sys.argv[1:4]
md = read_model_description(fmu)
folder = extract(fmu)
s = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier=md.coSimulation.modelIdentifier,
              instanceName="r")
s.instantiate(); s.setupExperiment(startTime=0.0); s.enterInitializationMode(); s.exitInitializationMode()
s.doStep(0.0, 1e-4); s.terminate(); s.freeInstance()
shutil.rmtree(folder)
sc = load_scenario(scenario)
res = run(replace(sc, stop_time=sc.start_time + 1e-3), out_dir=out, progress=False)
print(res.success, res.message)
from orchestrator.cli import exit_process
exit_process(0)     # as rotorcosim leaves: PythonFMU 0.7 can abort in the interpreter's teardown (cli.console_main)
"""


def test_run_after_a_freed_rotor_fmu_whose_folder_is_gone(tmp_path):
    """A process runs the rotor FMU, frees it and deletes its extraction folder (its modules stay
    imported), then runs a scenario whose rotor steps through the interface-Jacobian kernel. That
    kernel compiles the speed table of the stale ``rotor_fmu.linear_rotor``: the run failed in
    the rotor's fmi2DoStep ("cannot cache function '_drive_eval': no locator available") and
    now completes (``pytest tests/test_fmus.py tests/test_floating_ring_fmu.py`` did this)."""
    from orchestrator.fmi.build import build_fmus
    fmu, = build_fmus(tmp_path / "fmus", force=True, names=["JeffcottRotor"])
    scenario = PKG.parent / "scenarios" / "jeffcott_runup_floating_ring_half_sommerfeld.yaml"
    out = subprocess.run([sys.executable, "-c", FREED_FMU_PROBE, str(fmu), str(scenario), str(tmp_path / "run")],
                         env=dict(os.environ, PYTHONPATH=str(PKG.parent)), capture_output=True,
                         text=True, timeout=600, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.startswith("True"), out.stdout[-3000:]


def test_run_says_when_our_kernels_are_compiled_first(tmp_path, monkeypatch):
    """A first run (or the first after an update) spends 15-60 s compiling the film kernels
    before its first step, silently: it looked like a hang. `run` now says so, and only then."""
    from orchestrator import load_scenario
    from orchestrator.fmi.build import uncompiled_kernels
    from bearing_fmu._numba_cache import _package_hash
    sc = load_scenario(Path(__file__).resolve().parents[1] / "scenarios" / "quickstart.yaml")
    monkeypatch.setenv("ROTORCOSIM_NUMBA_CACHE", str(tmp_path))
    assert sorted(uncompiled_kernels(sc)) == ["bearing_fmu", "rotor_fmu"]
    for pkg in ("bearing_fmu", "rotor_fmu"):
        first = sorted((PKG.parent / pkg).glob("*.py"))[0]
        d = tmp_path / f"somemodule-{_package_hash(str(first))[:20]}"
        d.mkdir()
        (d / "kernel.nbi").write_bytes(b"")
    assert uncompiled_kernels(sc) == []
    monkeypatch.setenv("ROTORCOSIM_NUMBA_CACHE", "off")
    assert uncompiled_kernels(sc) == []
    # the note in the CLI's words
    monkeypatch.setenv("ROTORCOSIM_NUMBA_CACHE", str(tmp_path / "empty"))
    (tmp_path / "empty").mkdir()
    from orchestrator.cli import run as cli_run
    import io
    import contextlib
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        cli_run._first_compile_note(sc)
    assert buf.getvalue().startswith("note: first run of these ") and "numba compiles their kernels" in buf.getvalue()
