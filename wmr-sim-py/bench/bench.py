"""Budgets of the Python package (issue 36; BENCHMARKS.md): prints numbers,
asserts nothing (a benchmark, not a test).

1. Per-run overhead of `wmrsim.run` against the same run called from Rust
   in the same process (`_native.native_seconds`: the limits checks
   `hil-sim run` makes, then the simulation): a 40 s paper Case 2 run, no
   trace, the fastest of interleaved repetitions of each; the checks' own
   share printed beside it.
2. `run_batch` of N such runs on 2 threads against 1 thread.
3. Memory of a traced 40 s run: the resident growth per run held (the
   result, its trace in Rust) and per trace taken as a numpy array (20 of
   each, in a fresh process).

    python bench.py [--reps 50] [--batch 24]
"""

import argparse
import statistics
import subprocess
import sys
import time

import wmrsim
from wmrsim import _native


def per_run_overhead(reps: int) -> None:
    scn = wmrsim.Scenario.paper_case(2, 1)
    for c in ("smc", "proposed"):
        py, native, sim_only = [], [], []
        wmrsim.run(scn, c, trace=False)  # warm
        for _ in range(reps):
            t0 = time.perf_counter()
            r = wmrsim.run(scn, c, trace=False)
            _ = r.metrics
            py.append(time.perf_counter() - t0)
            native.extend(_native.native_seconds(scn, c, 1))
            sim_only.extend(_native.native_seconds(scn, c, 1, checks=False))
        p, n, s = min(py), min(native), min(sim_only)
        pairs = statistics.median(a / b for a, b in zip(py, native))
        print(f"run overhead, {c:>8}: python {1e3 * p:.3f} ms, native {1e3 * n:.3f} ms, "
              f"overhead {100 * (p - n) / n:+.2f} % (fastest of {reps}; budget 5 %), "
              f"median of the {reps} adjacent pairs {100 * (pairs - 1):+.2f} %; "
              f"the CLI's limits checks in both: {1e3 * (n - s):.3f} ms")


def batch_speedup(n: int, repeats: int = 3) -> None:
    scns = [wmrsim.Scenario.paper_case(2, s) for s in range(1, n + 1)]
    best, cpu = {}, {}
    for _ in range(repeats):
        for threads in (1, 2):
            t0, c0 = time.perf_counter(), time.process_time()
            wmrsim.run_batch(scns, "proposed", threads=threads)
            dt, dc = time.perf_counter() - t0, time.process_time() - c0
            if dt < best.get(threads, float("inf")):
                best[threads], cpu[threads] = dt, dc
    print(f"run_batch of {n} 40 s runs: 1 thread {best[1]:.3f} s, 2 threads {best[2]:.3f} s, "
          f"speed-up {best[1] / best[2]:.2f}x (best of {repeats}; budget >= 1.8x); "
          f"CPU/wall on 2 threads {cpu[2] / best[2]:.2f} (2.00 = both cores all the time)")


MEMORY_CHILD = r"""
import os, wmrsim
def rss():  # resident bytes now
    return int(open("/proc/self/statm").read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
scn = wmrsim.Scenario.paper_case(2, 1)
wmrsim.run(scn).trace                             # imports and first-run allocations
N = 20
r0 = rss()
held = [wmrsim.run(scn) for _ in range(N)]        # traced runs, trace kept in Rust
r1 = rss()
traces = [r.trace for r in held]                  # and as numpy arrays
r2 = rss()
a = traces[0].array
print(a.shape[0], a.shape[1], a.nbytes, (r1 - r0) // N, (r2 - r1) // N, r2)
"""


def traced_memory() -> None:
    out = subprocess.run([sys.executable, "-c", MEMORY_CHILD], capture_output=True, text=True, check=True)
    rows, cols, nbytes, per_run, per_array, total = map(int, out.stdout.split())
    print(f"traced 40 s run: {rows} rows x {cols} columns; per run held: {per_run / 1e6:.2f} MB in Rust "
          f"(the result with its trace) + {per_array / 1e6:.2f} MB once .trace is taken "
          f"(the array: {nbytes / 1e6:.2f} MB); resident after 20 held: {total / 1e6:.1f} MB")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=50)
    ap.add_argument("--batch", type=int, default=24)
    a = ap.parse_args()
    print(f"wmrsim over hil-sim {wmrsim.HIL_SIM_VERSION}, python {sys.version.split()[0]}")
    per_run_overhead(a.reps)
    batch_speedup(a.batch)
    traced_memory()


if __name__ == "__main__":
    main()
