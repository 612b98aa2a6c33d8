"""results.csv reader: this tree's ``read_results`` against another version, interleaved.

Each round reads every file once with the old module and once with the new one, in turn
(which goes first alternates), in this one process; reported are the median and minimum
wall time and the median CPU time (process) per file and reader, and the ratios of the
medians (new / old); on a shared machine the CPU time is the steadier of the two. The old module is a
copy of orchestrator/results/run_directory.py from another commit, e.g.

    git show 89e36ea:orchestrator/results/run_directory.py > /tmp/old_reader.py
    PYTHONPATH=. .venv/bin/python benchmarks/bench_results_reader.py --old /tmp/old_reader.py \\
        runs/quickstart/results.csv big/results.csv

``--synthesize PATH --rows N`` writes a results.csv of N rows in the format of a run (16
columns, ``repr`` floats, time in 0.1 ms steps) first, from the rows of the first file given.
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import time

import numpy as np


def load_module(path):
    spec = importlib.util.spec_from_file_location("old_run_directory", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def synthesize(src, dst, rows, seed=0):
    from orchestrator.results.run_directory import read_results
    data = read_results(src)
    names = list(data)
    base = np.column_stack([data[k] for k in names])
    rng = np.random.default_rng(seed)
    out = base[np.arange(rows) % len(base)].copy()
    t = names.index("time")
    out[:, t] = out[0, t] + np.arange(rows) * 1e-4
    others = [j for j in range(len(names)) if j != t]
    out[:, others] *= 1 + 1e-9 * rng.standard_normal((rows, len(others)))   # full-length reprs
    with open(dst, "w", newline="") as fh:
        fh.write(",".join(names) + "\n")
        for r in out:
            fh.write(",".join(map(repr, r.tolist())) + "\n")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+")
    ap.add_argument("--old", required=True, help="the other version of run_directory.py")
    ap.add_argument("--rounds", type=int, default=11)
    ap.add_argument("--synthesize", help="write this results.csv first (from the first file's rows)")
    ap.add_argument("--rows", type=int, default=200_000)
    a = ap.parse_args(argv)
    from orchestrator.results import run_directory as new
    old = load_module(a.old)
    files = list(a.files)
    if a.synthesize:
        synthesize(files[0], a.synthesize, a.rows)
        files.append(a.synthesize)
    for f in files:
        x, y = old.read_results(f), new.read_results(f)       # warm (page cache) and equal
        assert list(x) == list(y) and all(np.array_equal(x[k], y[k], equal_nan=True) for k in x), f
    print(f"# bench_results_reader  {time.strftime('%Y-%m-%d %H:%M:%S')}  rounds={a.rounds}  old={a.old}")
    print("| file | rows x cols | old median s | new median s | old min | new min | new / old (medians) | "
          "CPU old s | CPU new s | CPU new / old |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for f in files:
        times = {"old": [], "new": []}
        cpu = {"old": [], "new": []}
        for r in range(a.rounds):
            order = (("old", old), ("new", new)) if r % 2 == 0 else (("new", new), ("old", old))
            for name, mod in order:
                t0, c0 = time.perf_counter(), time.process_time()
                d = mod.read_results(f)
                times[name].append(time.perf_counter() - t0)
                cpu[name].append(time.process_time() - c0)
        mo, mn = statistics.median(times["old"]), statistics.median(times["new"])
        co, cn = statistics.median(cpu["old"]), statistics.median(cpu["new"])
        print(f"| {f} | {len(d['time'])} x {len(d)} | {mo:.4f} | {mn:.4f} | {min(times['old']):.4f} | "
              f"{min(times['new']):.4f} | {mn / mo:.3f} | {co:.4f} | {cn:.4f} | {cn / co:.3f} |", flush=True)


if __name__ == "__main__":
    main()
