"""Under Ray (a local cluster of real worker processes, 2 CPUs): a
Monte-Carlo fanned out in blocks and one generation of a tuning
population, one task per row, give exactly the single-process results.
Skipped without ray unless WMRSIM_REQUIRE_RAY=1 (CI sets it)."""

import os

import numpy as np
import pytest

import wmrsim

if os.environ.get("WMRSIM_REQUIRE_RAY") == "1":
    import ray
else:
    ray = pytest.importorskip("ray")

from wmrsim.distributed import blocks_of, montecarlo, montecarlo_records, tune_generation


@pytest.fixture(scope="module")
def cluster():
    # Loopback only (the project's rule for servers in tests), 2 CPUs.
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, _node_ip_address="127.0.0.1")
    yield
    ray.shutdown()


def test_blocks_cover_every_run_once():
    for runs in (1, 7, 10):
        for n in (1, 3, 4):
            idx = [i for b in blocks_of(runs, n) for i in b]
            assert idx == list(range(runs))


def test_montecarlo_over_ray_equals_one_process(cluster):
    mc = wmrsim.MonteCarlo(6, duration_s=3.0, seed=21, vary_mass=True)
    local = mc.run(threads=1)
    recs = montecarlo_records(mc, blocks=4)
    assert [(r["run"], r["controller"]) for r in recs] == [
        (r["run"], r["controller"]) for r in mc.records(0, 6)
    ]
    assert montecarlo(mc, blocks=4) == local["stats"]
    # The tasks ran in worker processes, not in this one.
    def pid():  # nested: pickled by value, no import of this file needed
        import os

        return os.getpid()

    pids = ray.get([ray.remote(pid).remote() for _ in range(2)])
    assert os.getpid() not in pids


def test_tuning_generation_over_ray_equals_one_process(cluster):
    ts = wmrsim.TuneSet(wmrsim.Robot.paper(), sensing=["mocap"], train=2, validate=1,
                        duration_s=15.0, seed=4)
    d = len(wmrsim.TuneSet.dims("proposed"))
    pop = np.random.default_rng(7).uniform(-0.1, 1.1, size=(4, d))
    remote = tune_generation(ts, "proposed", pop)
    assert remote == ts.costs("proposed", pop)
    assert len(set(remote)) == 4
