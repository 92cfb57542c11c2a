"""Fan-out over a Ray cluster: a Monte-Carlo in blocks of run indices and
one generation of a tuning population, one Ray task per block or row.

Every task runs the same hil-sim functions as a single process does, and
each result depends only on its inputs (run i is seeded from the sweep's
seed and i; a cost sums its scenarios in index order), so the results are
identical to ``MonteCarlo.run()`` and ``TuneSet.costs()``, number for
number, on one machine or many.

    import ray, wmrsim
    from wmrsim.distributed import montecarlo, tune_generation
    ray.init()                      # or ray.init(address="auto") on a cluster
    stats = montecarlo(wmrsim.MonteCarlo(1000), blocks=16)

Start a multi-node cluster with ``ray start --head`` on one machine and
``ray start --address=HEAD:6379`` on the others (each with this package
installed); the same calls then spread over every node (book/src/how-to/python.md).
"""

from typing import Any, List, Optional, Sequence

import numpy as np

from . import MonteCarlo, TuneSet

__all__ = ["blocks_of", "montecarlo", "montecarlo_records", "tune_generation"]


def blocks_of(runs: int, blocks: int) -> List[range]:
    """Run indices ``0..runs`` in ``blocks`` contiguous blocks, block i being
    ``[i*runs//blocks, (i+1)*runs//blocks)`` (as ``montecarlo --shard
    i/blocks`` splits them)."""
    if blocks < 1:
        raise ValueError(f"blocks must be at least 1, got {blocks}")
    return [range(i * runs // blocks, (i + 1) * runs // blocks) for i in range(blocks)]


def _ray() -> Any:
    try:
        import ray
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError("wmrsim.distributed needs ray: pip install 'ray==2.60.0'") from e
    if not ray.is_initialized():
        # A local cluster on loopback (Ray otherwise probes 8.8.8.8 for this
        # machine's outward address); call ray.init(address=...) first to
        # use a real cluster.
        ray.init(_node_ip_address="127.0.0.1")
    return ray


def _records_task(mc: MonteCarlo, start: int, stop: int, threads: Optional[int]) -> list:
    return mc.records(start, stop, threads=threads)


def _cost_task(ts: TuneSet, controller: str, x: Sequence[float], part: str) -> float:
    return ts.cost(controller, np.asarray(x, dtype=np.float64), part=part)["objective"]


def montecarlo_records(
    mc: MonteCarlo, blocks: int, *, threads_per_task: Optional[int] = 1
) -> list:
    """The records of every run of ``mc``, computed in ``blocks`` Ray tasks
    (each ``mc.records(start, stop)`` on ``threads_per_task`` threads and
    one CPU of the cluster); in run order."""
    ray = _ray()
    task = ray.remote(num_cpus=threads_per_task or 1)(_records_task)
    refs = [
        task.remote(mc, b.start, b.stop, threads_per_task)
        for b in blocks_of(mc.runs, blocks)
        if len(b)
    ]
    out: list = []
    for part in ray.get(refs):
        out.extend(part)
    return out


def montecarlo(mc: MonteCarlo, blocks: int, *, threads_per_task: Optional[int] = 1) -> list:
    """``mc.run()["stats"]`` computed over the Ray cluster in ``blocks``
    tasks: the same statistics, number for number."""
    return MonteCarlo.stats(montecarlo_records(mc, blocks, threads_per_task=threads_per_task))


def tune_generation(
    ts: TuneSet, controller: str, population: Any, *, part: str = "training"
) -> List[float]:
    """The objective of each row of ``population`` (n x len(TuneSet.dims(
    controller)) unit-box points), one Ray task per row: what
    ``ts.costs(controller, population)`` returns in one process."""
    pop = np.asarray(population, dtype=np.float64)
    if pop.ndim != 2:
        raise ValueError(
            f"population must be a 2-D array (one unit-box point per row), got shape {pop.shape}"
        )
    ray = _ray()
    task = ray.remote(num_cpus=1)(_cost_task)
    ts_ref = ray.put(ts)
    return ray.get([task.remote(ts_ref, controller, row.tolist(), part) for row in pop])
