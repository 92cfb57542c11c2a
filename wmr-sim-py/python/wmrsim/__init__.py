"""wmrsim: the hil-sim simulator from Python.

The paper's differential-drive robot (slip, skid, disturbance, actuator
fault) under the firmware's own controllers (SMC, ASMC, the proposed fault
observer + ESO + adaptive SMC), simulated by hil-sim's library: the same
functions its command line calls, so every number equals the CLI's for the
same inputs and seed.

- ``Robot``: a robot file (``Robot.from_file("robots/paper.toml")``).
- ``Scenario``: one run's knobs (``Scenario.paper_case(2, seed=1)``,
  ``Scenario.from_file(...)``, ``scn.replace({"duration_s": 5})``).
- ``run(scn, "proposed")`` -> ``RunResult`` (``.metrics``, ``.report``,
  ``.trace``); ``run_batch([...], threads=2)`` across threads.
- ``compare(seed=1)``: the paper comparison (``hil-sim compare --json``).
- ``MonteCarlo(runs=100).run()``: ``hil-sim montecarlo --json``;
  ``.records(start, stop)`` and ``MonteCarlo.stats(records)`` for blocks
  computed anywhere (``wmrsim.distributed`` fans them out over Ray).
- ``TuneSet(robot).cost("proposed", x)``: the tuner's cost of one gain
  vector; ``.costs(controller, population)`` for a generation.

Bad input raises ``InvalidInputError`` (a ``ValueError``; ``err.field``
names the field when known) with the CLI's message; a run that cannot
finish raises ``SimulationError``; a missing file ``FileNotFoundError``.
See book/src/how-to/python.md.
"""

from typing import Any, Dict, Iterator, Sequence, Tuple

import numpy as np

from ._native import (
    HIL_SIM_VERSION,
    InvalidInputError,
    MonteCarlo,
    Robot,
    RunResult,
    Scenario,
    SimulationError,
    TuneSet,
    compare,
    run,
    run_batch,
)

__all__ = [
    "HIL_SIM_VERSION",
    "InvalidInputError",
    "MonteCarlo",
    "Robot",
    "RunResult",
    "Scenario",
    "SimulationError",
    "Trace",
    "TuneSet",
    "compare",
    "run",
    "run_batch",
]

__version__ = "0.1.0"


class Trace:
    """A run's trace: ``array`` (float64, one row per sample) and its
    ``columns``, the header of ``hil-sim run --csv`` (``t_s``, ``x_m``,
    ``pos_err_m``, ``tau_r_nm``, ... ``health_reason``; ``saturated``,
    ``health`` and ``health_reason`` as 0/1 and small integers).

    ``trace["x_m"]`` is a column (a view), ``trace.to_pandas()`` a
    DataFrame (pandas installed), ``trace.to_records()`` a numpy
    structured array.
    """

    __slots__ = ("columns", "array", "_index")

    def __init__(self, columns: Sequence[str], array: np.ndarray) -> None:
        array = np.asarray(array, dtype=np.float64)
        if array.ndim != 2 or array.shape[1] != len(columns):
            raise ValueError(
                f"trace array of shape {array.shape} does not have {len(columns)} columns"
            )
        self.columns: Tuple[str, ...] = tuple(columns)
        self.array: np.ndarray = array
        self._index: Dict[str, int] = {c: i for i, c in enumerate(self.columns)}

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.array[:, self._index[name]]
        except KeyError:
            raise KeyError(
                f"no trace column {name!r}; the columns are: {', '.join(self.columns)}"
            ) from None

    def __len__(self) -> int:
        return self.array.shape[0]

    def __iter__(self) -> Iterator[str]:
        return iter(self.columns)

    def __contains__(self, name: object) -> bool:
        return name in self._index

    def __repr__(self) -> str:
        t = self.array[:, 0]
        span = f", t_s {t[0]:g}..{t[-1]:g}" if len(t) else ""
        return f"Trace({len(self)} rows x {len(self.columns)} columns{span})"

    def to_dict(self) -> Dict[str, np.ndarray]:
        """The columns as a dict of 1-D arrays (views)."""
        return {c: self.array[:, i] for i, c in enumerate(self.columns)}

    def to_records(self) -> np.ndarray:
        """A numpy structured array, one float64 field per column."""
        return np.rec.fromarrays(self.array.T, names=list(self.columns))

    def to_pandas(self) -> Any:
        """A pandas DataFrame with the named columns (needs pandas)."""
        try:
            import pandas as pd
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError("Trace.to_pandas needs pandas: pip install pandas") from e
        return pd.DataFrame(self.array, columns=list(self.columns))


def _rebuild(cls: type, args: tuple, kwargs: dict) -> Any:
    """Unpickles a class built from keyword arguments (MonteCarlo, TuneSet)."""
    return cls(*args, **kwargs)
