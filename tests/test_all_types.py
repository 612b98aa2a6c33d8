"""Every FMI 2.0 variable type through the master, with the native AllTypes test FMU (tests/fmus_c).

AllTypes is compiled with gcc at test time. Two instances are coupled with Real, Integer,
Boolean, Enumeration and String connections. Closed forms: with ``b.n_in`` fed by ``a.count``
(a.count(T(k)) = k) and ``b.count += 1 + b.n_in`` per step,

* Jacobi (zero-order hold, b sees a's value at T(k) during step k): b.count(n) = n + n(n-1)/2;
* Gauss-Seidel [a, b] (b sees a's new value at T(k+1)): b.count(n) = n + n(n+1)/2.

The Jacobi run is also compared with libcosim (in a subprocess, as tests/test_interop.py does)
for the Integer and Boolean signals: libcosim's fixed-step algorithm is Jacobi with zero-order hold.
"""

from __future__ import annotations

import csv
import importlib.util
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve()
H, N = 0.1, 20

pytestmark = [pytest.mark.integration,
              pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed (native test FMU)")]


def _builder():
    spec = importlib.util.spec_from_file_location("build_c_fmu", HERE.parent / "fmus_c" / "build_c_fmu.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("alltypes")
    b = _builder()
    b.build_c_fmu(d, "AllTypes")
    b.build_c_fmu(d, "AllTypes", fixed_step=True)
    return d


CONNECTIONS = [("a.count", "b.n_in"), ("a.b_out", "b.b_in"), ("b.b_out", "a.b_in"), ("a.e_out", "b.e_in"),
               ("a.s_out", "b.s_in"), ("a.y", "b.u")]
SIGNALS = ["a.count", "b.count", "a.b_out", "b.b_out", "b.e_out", "b.s_out", "b.x", "b.n_out"]


def _yaml(d: Path, scheme: str = "jacobi", extra: str = "", params_a: str = "", stop: float = H * N) -> Path:
    conns = "\n".join(f"  - {{from: {s}, to: {t}}}" for s, t in CONNECTIONS)
    seq = ", sequence: [a, b]" if scheme == "gauss-seidel" else ""
    p = d / f"s_{scheme}.yaml"
    p.write_text(f"""name: alltypes
stop_time: {stop}
fmus:
  a: {{path: AllTypes.fmu, parameters: {{u: 1.0, e_in: Fast, label: alpha{params_a}}}}}
  b: {{path: AllTypes.fmu, parameters: {{x: 1.5, label: beta}}}}
connections:
{conns}
coupling: {{scheme: {scheme}{seq}, macro_step: {H}, extrapolation_order: 0{extra}}}
output: {{signals: [{', '.join(SIGNALS)}]}}
""")
    return p


def _run(path: Path, out: Path):
    import orchestrator
    sc = orchestrator.load_scenario(path)
    return orchestrator.run(sc, out_dir=out, progress=False)


@pytest.mark.parametrize("scheme, delay", [("jacobi", 1), ("gauss-seidel", 0)])
def test_non_real_signals_held_with_the_scheme_delay(fmus, tmp_path, scheme, delay):
    res = _run(_yaml(fmus, scheme), tmp_path / scheme)
    assert res.success, res.message
    n = np.arange(N + 1)
    np.testing.assert_array_equal(res.outputs["a.count"], n)
    expected = n + n * (n - 1) // 2 if delay else n + n * (n + 1) // 2
    np.testing.assert_array_equal(res.outputs["b.count"], expected)
    assert set(res.outputs["b.e_out"]) == {3.0}                        # Enumeration item Fast travelled
    assert list(res.outputs["b.s_out"]) == ["alpha"] * (N + 1)          # String travelled
    np.testing.assert_allclose(res.outputs["b.x"], 1.5 + 2.0 * H * n, rtol=0, atol=1e-12)   # start value of a state
    rows = list(csv.reader(open(tmp_path / scheme / "results.csv")))
    assert rows[0] == ["time", *SIGNALS]
    assert rows[4][0] == "0.3"                                          # time from the step index
    assert rows[4][SIGNALS.index("b.s_out") + 1] == "alpha"
    assert rows[4][SIGNALS.index("a.b_out") + 1] in ("0", "1")
    assert rows[4][SIGNALS.index("b.count") + 1] == str(expected[3])


def test_fmu_requested_stop_finishes_cleanly_without_retries(fmus, tmp_path):
    import orchestrator
    path = _yaml(fmus, "jacobi", extra=", discard_retries: 3", params_a=", stop_after: 7")
    res = _run(path, tmp_path / "stop")
    assert res.status is orchestrator.Status.STOPPED_BY_FMU and res.success
    assert "FMU instance 'a' ended the simulation at t=0.7 s" in res.message
    assert res.end_time == pytest.approx(0.7)
    assert res.stats["retried_steps"] == 0 and res.stats["rejected_steps"] == 0
    np.testing.assert_array_equal(res.outputs["a.count"], np.arange(8))
    summary = json.loads((tmp_path / "stop" / "summary.json").read_text())
    assert summary["status"] == "stopped_by_fmu"


def test_value_outside_the_declared_range_is_a_load_error(fmus):
    import orchestrator
    from orchestrator.errors import ScenarioError
    path = _yaml(fmus, "jacobi", params_a=", gain: 200, mode: Auto")
    with pytest.raises(ScenarioError) as info:
        orchestrator.load_scenario(path)
    text = str(info.value)
    assert "'a.gain' = 200.0 is outside its declared range [0.0, 100.0] (min/max of type Gain)" in text
    assert "'a.mode' is an Enumeration of type Mode with items {Off=1, Slow=2, Fast=3}; got 'Auto'" in text


def test_terminate_is_not_called_in_initialization_mode(fmus, tmp_path):
    """FMI 2.0 allows fmi2Terminate only after initialization; AllTypes logs an illegal call otherwise."""
    from orchestrator.fmi.subsystem import Subsystem
    sub = Subsystem("a", fmus / "AllTypes.fmu", work_dir=tmp_path)
    try:
        sub.setup_experiment(0.0, 1.0)
        sub.enter_initialization_mode()
        sub.terminate()
        assert sub.calls["terminate"] == 0
        assert not any("illegal" in m for m in sub._log_messages)
    finally:
        sub.free()


# ------------------------------------------------------------------ libcosim cross-check
def _libcosim_main(cfg_path: str, out_path: str) -> None:
    from fmpy import read_model_description
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    cfg = json.loads(Path(cfg_path).read_text())
    ex = CosimExecution.from_step_size(round(cfg["step"] * 1e9))
    index, mds = {}, {}
    for inst in ("a", "b"):
        index[inst] = ex.add_local_slave(CosimLocalSlave(fmu_path=cfg["fmu"], instance_name=inst))
        mds[inst] = {v.name: v for v in read_model_description(cfg["fmu"]).modelVariables}
    vr = lambda sig: mds[sig.split(".")[0]][sig.split(".")[1]].valueReference
    ex.real_initial_value(index["a"], vr("a.u"), 1.0)
    ex.integer_initial_value(index["a"], vr("a.e_in"), 3)
    ex.real_initial_value(index["b"], vr("b.x"), 1.5)
    for s, t in cfg["connections"]:
        kind = mds[s.split(".")[0]][s.split(".")[1]].type
        # libcosimpy 0.0.6's connect_integer_variables calls a misspelt private attribute
        connect = {"Real": ex.connect_real_variables, "Boolean": ex.connect_boolean_variables,
                   "Integer": ex._CosimExecution__connect_int_variables}[kind]
        args = (index[s.split(".")[0]], vr(s), index[t.split(".")[0]], vr(t))
        rc = connect(ex._CosimExecution__ptr, *args) if kind == "Integer" else connect(*args)
        assert rc == 0, f"libcosim refused {s} -> {t}"
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    out = {k: [] for k in cfg["record"]}
    for _ in range(cfg["n"]):
        assert ex.step(1)
        for sig in cfg["record"]:
            inst = sig.split(".")[0]
            kind = mds[inst][sig.split(".")[1]].type
            get = obs.last_boolean_values if kind == "Boolean" else obs.last_integer_values
            out[sig].append(int(get(index[inst], [vr(sig)])[0]))
    np.savez(out_path, **{k: np.asarray(v) for k, v in out.items()})


if __name__ == "__main__" and len(sys.argv) == 4 and sys.argv[1] == "--libcosim":
    _libcosim_main(sys.argv[2], sys.argv[3])
    sys.exit(0)


def test_jacobi_integer_and_boolean_match_libcosim(fmus, tmp_path):
    pytest.importorskip("libcosimpy")
    record = ["a.count", "b.count", "a.b_out", "b.b_out", "b.n_out"]
    conns = [c for c in CONNECTIONS if c[0].split(".")[1] in ("count", "b_out", "y")]
    cfg = tmp_path / "cfg.json"
    cfg.write_text(json.dumps({"fmu": str(fmus / "AllTypes.fmu"), "step": H, "n": N, "connections": conns,
                               "record": record}))
    proc = subprocess.run([sys.executable, str(HERE), "--libcosim", str(cfg), str(tmp_path / "lc.npz")],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    lc = np.load(tmp_path / "lc.npz")
    res = _run(_yaml(fmus, "jacobi"), tmp_path / "ours")
    assert res.success, res.message
    for sig in record:
        np.testing.assert_array_equal(np.asarray(res.outputs[sig])[1:], lc[sig], err_msg=sig)
    assert len(set(lc["b.b_out"])) == 2                  # the Boolean loop really toggles


def test_parquet_output_has_the_same_columns_and_values(fmus, tmp_path):
    pq = pytest.importorskip("pyarrow.parquet")
    csv_run = _run(_yaml(fmus, "jacobi"), tmp_path / "csv")
    path = _yaml(fmus, "jacobi")
    path.write_text(path.read_text().replace("output: {signals:", "output: {format: parquet, signals:"))
    pq_run = _run(path, tmp_path / "pq")
    assert pq_run.success, pq_run.message
    table = pq.read_table(tmp_path / "pq" / "results.parquet")
    assert table.column_names == ["time", *SIGNALS]
    assert table.column("b.count").to_pylist() == [int(v) for v in csv_run.outputs["b.count"]]
    assert table.column("b.s_out").to_pylist() == ["alpha"] * (N + 1)
    np.testing.assert_array_equal(pq_run.t, csv_run.t)
    for sig in SIGNALS:
        np.testing.assert_array_equal(pq_run.outputs[sig], csv_run.outputs[sig], err_msg=sig)


def test_default_experiment_fills_what_the_scenario_omits(fmus, tmp_path):
    import orchestrator
    p = fmus / "defaults.yaml"
    p.write_text("name: defaults\nfmus:\n  a: {path: AllTypes.fmu}\noutput: {signals: [a.count]}\n")
    sc = orchestrator.load_scenario(p)
    assert (sc.start_time, sc.stop_time, sc.coupling.macro_step) == (0.0, 1.0, 0.1)
    assert sc.defaults == {"start_time": "0.0 (DefaultExperiment startTime of 'a')",
                           "stop_time": "1.0 (DefaultExperiment stopTime of 'a')",
                           "coupling.macro_step": "0.1 (DefaultExperiment stepSize of 'a')"}
    res = orchestrator.run(sc, out_dir=tmp_path / "run", progress=False)
    assert res.success and list(res.outputs["a.count"]) == list(range(11))
    assert [r[0] for r in csv.reader(open(tmp_path / "run" / "results.csv"))][1:4] == ["0.0", "0.1", "0.2"]


def test_fixed_step_fmu_gets_no_shortened_step(fmus, tmp_path):
    import orchestrator
    from orchestrator.errors import ScenarioError
    p = fmus / "fixed.yaml"
    p.write_text("name: fixed\nstop_time: 1.05\nfmus:\n  a: {path: AllTypesFixed.fmu}\n"
                 "coupling: {macro_step: 0.1}\n")
    with pytest.raises(ScenarioError) as info:
        orchestrator.load_scenario(p)
    text = str(info.value)
    assert "stop_time 1.05 is not on the macro-step grid" in text and "'a' cannot vary" in text
    assert "use stop_time 1 or 1.1" in text
    p.write_text(p.read_text().replace("1.05", "1.0"))
    res = orchestrator.run(orchestrator.load_scenario(p), out_dir=tmp_path / "fixed", progress=False)
    assert res.success, res.message
    # discard retries would halve the step: refused too
    p.write_text(p.read_text().replace("macro_step: 0.1}", "macro_step: 0.1, discard_retries: 2}"))
    with pytest.raises(ScenarioError, match="discard_retries = 2 redoes discarded steps with halved"):
        orchestrator.load_scenario(p)


def test_info_shows_declared_types_ranges_items_references_and_aliases(fmus, capsys):
    from orchestrator.cli import main
    assert main(["info", str(fmus / "AllTypes.fmu")]) == 0
    out = capsys.readouterr().out
    lines = {ln.split()[0]: ln for ln in out.splitlines() if ln.startswith("  ") and ln.split()}
    assert lines["u"].split()[1:7] == ["input", "continuous", "Real", "0.0", "m/s", "1"]   # unit via declaredType
    assert "Speed" in lines["u"].split()
    assert "[0.0, 100.0]" in lines["gain"] and " 2 " in lines["gain"]     # min/max and nominal of type Gain
    assert "{Off=1, Slow=2, Fast=3}" in lines["mode"] and "Mode" in lines["mode"].split()
    assert lines["count"].split()[:5] == ["count", "output", "discrete", "Integer", "0"] and "11" in lines["count"].split()
    assert "[alias of y_alias]" in lines["y"]


def test_arrays_connect_element_by_element_and_signals_take_wildcards(fmus, tmp_path):
    import orchestrator
    from orchestrator.errors import ScenarioError
    p = fmus / "arrays.yaml"
    p.write_text("""name: arrays
stop_time: 0.3
fmus:
  a: {path: AllTypes.fmu, parameters: {"f[0]": 1.0, "f[1]": 2.0, "f[2]": 3.0}}
  b: {path: AllTypes.fmu, parameters: {gain: 3.0}}
connections:
  - {from: a.g, to: b.f}
  - a.y -> b.u
  - from: a.count
    to: b.n_in
coupling: {scheme: jacobi, macro_step: 0.1}
output: {signals: ["b.g[*]", "*.n_out", b.y]}
""")
    sc = orchestrator.load_scenario(p)
    assert [(c.src, c.dst) for c in sc.connections] == [
        ("a.g[0]", "b.f[0]"), ("a.g[1]", "b.f[1]"), ("a.g[2]", "b.f[2]"), ("a.y", "b.u"), ("a.count", "b.n_in")]
    assert sc.output.signals == ("b.g[0]", "b.g[1]", "b.g[2]", "a.n_out", "b.n_out", "b.y")
    res = orchestrator.run(sc, out_dir=tmp_path / "arrays", progress=False)
    assert res.success, res.message
    for i, f in enumerate((1.0, 2.0, 3.0)):                   # b.g = 3 * a.g = 3 * 2 * a.f
        assert res.outputs[f"b.g[{i}]"][-1] == pytest.approx(6.0 * f)
    assert list(res.outputs["b.n_out"]) == [0, 0, 2, 4]       # 2 * a.count one step late (Jacobi)
    p.write_text(p.read_text().replace("to: b.f}", "to: b.g}").replace('"b.g[*]"', '"b.q[*]"'))
    with pytest.raises(ScenarioError) as info:
        orchestrator.load_scenario(p)
    assert "pattern 'b.q[*]' matches no output" in str(info.value)


def test_plot_draws_the_signals_of_any_run(fmus, tmp_path):
    from orchestrator.cli import main
    res = _run(_yaml(fmus, "jacobi"), tmp_path / "run")
    assert res.success
    assert main(["plot", str(tmp_path / "run")]) == 0
    pngs = sorted(p.name for p in (tmp_path / "run" / "plots").glob("*.png"))
    assert pngs == ["signals_a.png", "signals_b.png"]
    assert (tmp_path / "run" / "plots" / "signals_b.png").stat().st_size > 5000
    for p in (tmp_path / "run" / "plots").glob("*.png"):
        p.unlink()
    with pytest.warns(UserWarning, match="'b.s_out' has no numeric values"):
        main(["plot", str(tmp_path / "run"), "--signals", "b.*"])
    assert sorted(p.name for p in (tmp_path / "run" / "plots").glob("*.png")) == ["signals_b.png"]


def test_memory_is_flat_in_rows_during_a_run(fmus, tmp_path):
    """run() streams rows and keeps none: traced memory between row 2000 and row 20000 stays flat."""
    import tracemalloc

    import orchestrator
    from orchestrator.coupling.observers import Observer

    class Probe(Observer):
        def __init__(self):
            self.at = {}

        def on_step_complete(self, view):
            if view.n in (2000, 20000):
                self.at[view.n] = tracemalloc.get_traced_memory()[0]

    path = _yaml(fmus, "jacobi", stop=2000.0)
    sc = orchestrator.load_scenario(path, ["coupling.macro_step=0.1"])
    probe = Probe()
    tracemalloc.start()
    try:
        res = orchestrator.run(sc, out_dir=tmp_path / "long", progress=False, observers=[probe])
    finally:
        tracemalloc.stop()
    assert res.success and len(res.t) == 20001
    grown = probe.at[20000] - probe.at[2000]
    assert grown < 300_000, f"memory grew by {grown} bytes over 18000 rows"


def _run_with_label(fmus, tmp_path, isolation: str, label: str, caplog):
    """The Jacobi run of a and b with a's String parameter ``label`` (which its s_out echoes), a.s_out
    recorded, warnings captured."""
    import logging
    path = _yaml(fmus, "jacobi", extra=f", isolation: {isolation}")
    text = path.read_text().replace("label: alpha", f'label: "{label}"')
    text = text.replace("output: {signals: [", "output: {signals: [a.s_out, ")
    path.write_text(text)
    with caplog.at_level(logging.WARNING):
        return _run(path, tmp_path / isolation)


@pytest.mark.parametrize("isolation", ["none", "process"])
def test_a_null_string_from_the_fmu_is_recorded_empty_and_reported_once(fmus, tmp_path, isolation, caplog):
    """fmi2GetString giving a NULL pointer (AllTypes returns NULL for the value "<NULL>") was
    recorded as "" without a word; now a warning names the instance and the variable, once."""
    res = _run_with_label(fmus, tmp_path, isolation, "<NULL>", caplog)
    assert res.success, res.message
    assert list(res.outputs["a.s_out"]) == [""] * (N + 1)
    assert list(res.outputs["b.s_out"]) == ["beta"] * (N + 1)      # b got "": its own label
    said = [r.getMessage() for r in caplog.records if "NULL pointer" in r.getMessage()]
    assert len(said) == 1 and "FMU instance 'a'" in said[0] and "'s_out'" in said[0], said


@pytest.mark.parametrize("isolation", ["none", "process"])
def test_an_unreadable_string_pointer_from_the_fmu_is_recorded_empty_not_a_crash(fmus, tmp_path, isolation, caplog):
    """fmi2GetString giving a pointer that cannot be read (AllTypes gives the address 16 for the
    value "<BADPTR>"): the master read it with strlen and died by SIGSEGV (in process; in a worker
    process the run stopped with a crash report). Now the value is read through the safe library,
    recorded and passed on as "", and a warning names the instance and variable once."""
    from orchestrator.fmi import safe_log
    if safe_log.library() is None:
        pytest.skip("no C compiler: the safe string reader cannot be built here")
    res = _run_with_label(fmus, tmp_path, isolation, "<BADPTR>", caplog)
    assert res.success, res.message
    assert list(res.outputs["a.s_out"]) == [""] * (N + 1)
    said = [r.getMessage() for r in caplog.records if "an address that cannot be read" in r.getMessage()]
    assert len(said) == 1 and "FMU instance 'a'" in said[0] and "'s_out'" in said[0], said


@pytest.mark.parametrize("isolation", ["none", "process"])
def test_a_string_running_into_unreadable_memory_is_kept_to_there_and_reported_once(fmus, tmp_path, isolation,
                                                                                   caplog):
    """fmi2GetString giving text without its NUL that ends where readable memory ends (AllTypes
    gives "ends at an unreadable page" at the end of a page followed by a PROT_NONE page for the
    value "<EDGE>"): the safe reader kept the 26 readable bytes and said nothing, so the recorded
    value looked like a good one. Now it is kept as before and a warning names the instance, the
    variable and the bytes kept, once per variable."""
    from orchestrator.fmi import safe_log
    if safe_log.library() is None:
        pytest.skip("no C compiler: the safe string reader cannot be built here")
    res = _run_with_label(fmus, tmp_path, isolation, "<EDGE>", caplog)
    assert res.success, res.message
    assert list(res.outputs["a.s_out"]) == ["ends at an unreadable page"] * (N + 1)
    said = [r.getMessage() for r in caplog.records if "cannot be read before its end" in r.getMessage()]
    assert len(said) == 1, said
    assert said[0].startswith("FMU instance 'a' gave a string that runs into memory that cannot be read before its "
                              "end (no NUL byte; 26 bytes kept, cut there) for the String 's_out' in "
                              "fmi2GetString"), said[0]


def test_cli_run_says_which_fmu_ended_the_run(fmus, tmp_path, capsys):
    """`rotorcosim run` of a run an FMU ended before stop_time prints why, not only the status
    (the Reference FMU Stair ends a 20 s run at 9 s: the output said `status: stopped_by_fmu`)."""
    from orchestrator.cli import main
    path = _yaml(fmus, "jacobi", params_a=", stop_after: 7")
    assert main(["run", str(path), "--out", str(tmp_path / "stop"), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "status: stopped_by_fmu: FMU instance 'a' ended the simulation at t=0.7 s" in out, out
