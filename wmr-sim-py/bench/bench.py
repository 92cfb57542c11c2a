"""Budgets of the Python package (issue 36; BENCHMARKS.md): prints numbers,
asserts nothing (a benchmark, not a test).

1. Per-run overhead of `wmrsim.run` against the same run called from Rust
   in the same process (`_native.native_seconds`): a 40 s paper Case 2
   run, no trace, the fastest of interleaved repetitions of each.
2. `run_batch` of N such runs on 2 threads against 1 thread.
3. Memory of a traced 40 s run: the trace array's bytes and the growth of
   the process's peak RSS over the run and the array (a fresh process).

    python bench.py [--reps 15] [--batch 24]
"""

import argparse
import resource
import subprocess
import sys
import time

import wmrsim
from wmrsim import _native


def per_run_overhead(reps: int) -> None:
    scn = wmrsim.Scenario.paper_case(2, 1)
    for c in ("smc", "proposed"):
        py, native = [], []
        wmrsim.run(scn, c, trace=False)  # warm
        for _ in range(reps):
            t0 = time.perf_counter()
            r = wmrsim.run(scn, c, trace=False)
            _ = r.metrics
            py.append(time.perf_counter() - t0)
            native.extend(_native.native_seconds(scn, c, 1))
        p, n = min(py), min(native)
        print(f"run overhead, {c:>8}: python {1e3 * p:.3f} ms, native {1e3 * n:.3f} ms, "
              f"overhead {100 * (p - n) / n:+.2f} % (fastest of {reps}; budget 5 %)")


def batch_speedup(n: int, repeats: int = 3) -> None:
    scns = [wmrsim.Scenario.paper_case(2, s) for s in range(1, n + 1)]
    best = {}
    for _ in range(repeats):
        for threads in (1, 2):
            t0 = time.perf_counter()
            wmrsim.run_batch(scns, "proposed", threads=threads)
            dt = time.perf_counter() - t0
            best[threads] = min(best.get(threads, dt), dt)
    print(f"run_batch of {n} 40 s runs: 1 thread {best[1]:.3f} s, 2 threads {best[2]:.3f} s, "
          f"speed-up {best[1] / best[2]:.2f}x (best of {repeats}; budget >= 1.8x)")


MEMORY_CHILD = r"""
import resource, wmrsim
scn = wmrsim.Scenario.paper_case(2, 1)
wmrsim.run(scn, trace=False)                      # imports and first-run allocations
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
r = wmrsim.run(scn)
tr = r.trace
after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(tr.array.shape[0], tr.array.shape[1], tr.array.nbytes, before, after)
"""


def traced_memory() -> None:
    out = subprocess.run([sys.executable, "-c", MEMORY_CHILD], capture_output=True, text=True, check=True)
    rows, cols, nbytes, before, after = map(int, out.stdout.split())
    print(f"traced 40 s run: {rows} rows x {cols} columns, array {nbytes / 1e6:.2f} MB; "
          f"peak RSS {before / 1024:.1f} MB -> {after / 1024:.1f} MB (+{(after - before) / 1024:.2f} MB "
          f"for the run's trace, kept in Rust, and the numpy array)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=15)
    ap.add_argument("--batch", type=int, default=24)
    a = ap.parse_args()
    print(f"wmrsim over hil-sim {wmrsim.HIL_SIM_VERSION}, python {sys.version.split()[0]}")
    per_run_overhead(a.reps)
    batch_speedup(a.batch)
    traced_memory()
    _ = resource  # (ru_maxrss is KiB on Linux)


if __name__ == "__main__":
    main()
