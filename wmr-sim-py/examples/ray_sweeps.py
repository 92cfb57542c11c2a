"""A Monte-Carlo and one generation of a tuning population over a Ray
cluster, checked against the single-process run (book/src/how-to/python.md).

On one machine this starts a local cluster (`ray.init()`, real worker
processes); with `--address auto` it joins the cluster `ray start` made
(every node needs this package installed), and the same code spreads the
tasks over all nodes.

    python ray_sweeps.py [--address auto] [--runs 20] [--blocks 4]
                         [--population 8] [--duration 10]
"""

import argparse
import time

import numpy as np
import ray

import wmrsim
from wmrsim.distributed import montecarlo, tune_generation


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--address", help="Ray cluster address [default: start a local one]")
    ap.add_argument("--cpus", type=int, help="CPUs of the local cluster [default: all]")
    ap.add_argument("--runs", type=int, default=20, help="Monte-Carlo runs per controller")
    ap.add_argument("--blocks", type=int, default=4, help="Ray tasks of the Monte-Carlo")
    ap.add_argument("--population", type=int, default=8, help="gain vectors of the generation")
    ap.add_argument("--duration", type=float, default=10.0, help="run length [s]")
    a = ap.parse_args()

    if a.address:
        ray.init(address=a.address)
    else:
        # A local cluster on loopback: without the node address Ray probes
        # 8.8.8.8 to find this machine's outward IP (the project talks to
        # nothing but loopback).
        ray.init(num_cpus=a.cpus, include_dashboard=False, _node_ip_address="127.0.0.1")
    print(f"ray: {ray.cluster_resources().get('CPU', 0):g} CPUs on {len(ray.nodes())} node(s)")

    mc = wmrsim.MonteCarlo(a.runs, duration_s=a.duration, seed=1, vary_mass=True)
    t0 = time.perf_counter()
    stats = montecarlo(mc, blocks=a.blocks)
    t_ray = time.perf_counter() - t0
    local = mc.run()
    assert stats == local["stats"], "Ray and one process differ"
    for s in stats:
        m = s["metrics"]["rms_pos_err_m"]
        print(f"{s['controller']:>9}: RMS position error mean {1e3 * m['mean']:.2f} mm, p95 {1e3 * m['p95']:.2f} mm")
    print(f"Monte-Carlo: {3 * a.runs} runs in {a.blocks} Ray tasks ({t_ray:.1f} s), "
          f"identical to one process ({local['elapsed_s']:.1f} s)")

    # The tuner's cost is the error in the perturbation window from 10 s on:
    # its runs last at least 15 s (hil-sim tune refuses shorter ones, D205).
    ts = wmrsim.TuneSet(wmrsim.Robot.paper(), sensing=["mocap"], train=4, validate=2,
                        duration_s=max(a.duration, 15.0))
    d = len(wmrsim.TuneSet.dims("proposed"))
    rng = np.random.default_rng(1)
    population = np.clip(np.array(ts.start("proposed")) + 0.1 * rng.standard_normal((a.population, d)), 0, 1)
    t0 = time.perf_counter()
    costs = tune_generation(ts, "proposed", population)
    t_ray = time.perf_counter() - t0
    assert costs == ts.costs("proposed", population), "Ray and one process differ"
    best = int(np.argmin(costs))
    print(f"tuning generation: {a.population} gain vectors in {t_ray:.1f} s, identical to one process; "
          f"best objective {costs[best]:.4f} m (row {best})")
    ray.shutdown()


if __name__ == "__main__":
    main()
