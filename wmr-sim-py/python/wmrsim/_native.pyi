"""Type stubs of the native module (wmr-sim-py, pyo3)."""

from os import PathLike
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from . import Trace

HIL_SIM_VERSION: str

_Path = Union[str, PathLike]
Controller = str  # "smc", "asmc" or "proposed"

class InvalidInputError(ValueError):
    """Bad input; the CLI's message (field, value, limit, what to do)."""

    field: Optional[str]

class SimulationError(RuntimeError):
    """A simulation that could not run to its end."""

class Robot:
    """A robot file (book/src/how-to/robot-file.md), validated as `hil-sim --robot FILE`."""

    @staticmethod
    def paper() -> Robot: ...
    @staticmethod
    def from_file(path: _Path) -> Robot: ...
    @staticmethod
    def from_toml(text: str) -> Robot: ...
    @staticmethod
    def from_dict(d: Dict[str, Any]) -> Robot: ...
    def to_toml(self) -> str: ...
    def to_dict(self) -> Dict[str, Any]: ...
    @property
    def name(self) -> str: ...

class Scenario:
    """Every knob of one run except the controller (book/src/reference/scenario-file.md)."""

    @staticmethod
    def paper_case(
        case: int = 2,
        seed: int = 1,
        *,
        beta: Optional[float] = None,
        eps: Optional[float] = None,
        robot: Optional[Robot] = None,
        plant: Optional[Robot] = None,
    ) -> Scenario: ...
    @staticmethod
    def from_file(
        path: _Path, *, robot: Optional[Robot] = None, plant: Optional[Robot] = None
    ) -> Scenario: ...
    @staticmethod
    def from_toml(
        text: str, *, robot: Optional[Robot] = None, plant: Optional[Robot] = None
    ) -> Scenario: ...
    @staticmethod
    def from_dict(
        d: Dict[str, Any], *, robot: Optional[Robot] = None, plant: Optional[Robot] = None
    ) -> Scenario: ...
    @staticmethod
    def sweep_base(robot: Robot, *, seed: int = 1, duration_s: float = 40.0) -> Scenario: ...
    def replace(
        self,
        changes: Optional[Dict[str, Any]] = None,
        *,
        robot: Optional[Robot] = None,
        plant: Optional[Robot] = None,
    ) -> Scenario: ...
    def to_dict(self) -> Dict[str, Any]: ...
    def to_toml(self) -> str: ...
    @property
    def robot(self) -> Robot: ...
    @property
    def plant(self) -> Optional[Robot]: ...
    @property
    def name(self) -> str: ...
    @property
    def duration_s(self) -> float: ...
    @property
    def seed(self) -> int: ...

class RunResult:
    """One run: metrics (the keys of `hil-sim run --json`), report, trace."""

    @property
    def controller(self) -> Controller: ...
    @property
    def rejected_steps(self) -> int: ...
    @property
    def metrics(self) -> Dict[str, Optional[float]]: ...
    @property
    def report(self) -> Dict[str, Any]: ...
    @property
    def scenario(self) -> Scenario: ...
    @property
    def trace(self) -> Optional[Trace]: ...

def run(
    scenario: Scenario,
    controller: Controller = "proposed",
    *,
    trace: bool = True,
    trace_every: Optional[int] = None,
    force: bool = False,
) -> RunResult: ...
def run_batch(
    scenarios: Sequence[Scenario],
    controllers: Union[Controller, Sequence[Controller], None] = None,
    *,
    trace: bool = False,
    trace_every: Optional[int] = None,
    threads: Optional[int] = None,
    force: bool = False,
) -> List[RunResult]: ...
def compare(
    seed: int = 1,
    *,
    beta: Optional[float] = None,
    eps: Optional[float] = None,
    robot: Optional[Robot] = None,
    plant: Optional[Robot] = None,
    beyond_paper: bool = False,
    threads: Optional[int] = None,
) -> List[Dict[str, Any]]: ...

class MonteCarlo:
    """`hil-sim montecarlo`: random paper scenarios per controller."""

    def __init__(
        self,
        runs: int,
        *,
        case: int = 2,
        seed: int = 1,
        vary_mass: bool = False,
        duration_s: Optional[float] = None,
        sensing: str = "ideal",
        paper_setting: bool = False,
        robot: Optional[Robot] = None,
        plant: Optional[Robot] = None,
    ) -> None: ...
    @property
    def runs(self) -> int: ...
    def scenario(self, i: int) -> Scenario: ...
    def run(self, *, threads: Optional[int] = None) -> Dict[str, Any]: ...
    def records(
        self, start: int, stop: int, *, threads: Optional[int] = None
    ) -> List[Dict[str, Any]]: ...
    @staticmethod
    def stats(records: Sequence[Dict[str, Any]]) -> List[Dict[str, Any]]: ...
    def describe(self) -> str: ...

class TuneSet:
    """The tuner's scenario set and cost (`hil-sim tune`, book/src/how-to/tuning.md)."""

    def __init__(
        self,
        robot: Robot,
        *,
        sensing: Sequence[str] = ("mocap", "imu"),
        seed: int = 1,
        train: int = 10,
        validate: int = 16,
        figure8: int = 4,
        square: int = 0,
        torque_scale_min: float = 1.0,
        duration_s: float = 35.0,
        disturbance_max: float = 0.15,
        preset_mean: str = "geometric",
        chatter_weight: float = 2e-5,
    ) -> None: ...
    @staticmethod
    def dims(controller: Controller) -> List[Tuple[str, float, float]]: ...
    def start(self, controller: Controller) -> List[float]: ...
    def scenarios(self, part: str = "training") -> List[Scenario]: ...
    def cost(
        self,
        controller: Controller,
        x: Optional[npt.ArrayLike] = None,
        *,
        part: str = "training",
    ) -> Dict[str, Any]: ...
    def costs(
        self, controller: Controller, population: npt.ArrayLike, *, part: str = "training"
    ) -> List[float]: ...

def native_seconds(
    scenario: Scenario,
    controller: Controller = "proposed",
    reps: int = 10,
    trace: bool = False,
    checks: bool = True,
) -> List[float]:
    """Seconds of each of `reps` runs called from Rust (the benchmark's reference)."""
