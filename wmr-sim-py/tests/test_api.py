"""The API of wmrsim: loading, runs, batches, traces, Monte-Carlo and the
tuner's cost; bad input raises an exception naming the field, never
crashes the interpreter."""

import math
import pickle

import numpy as np
import pytest

import wmrsim
from wmrsim import InvalidInputError, SimulationError

SHORT = {"duration_s": 3.0}


def short_case(case=2, seed=1):
    return wmrsim.Scenario.paper_case(case, seed).replace(SHORT)


# ---- loading and validation ----


def test_robot_files_load_and_read_back(root):
    for path in sorted((root / "robots").glob("*.toml")):
        r = wmrsim.Robot.from_file(path)
        assert wmrsim.Robot.from_toml(r.to_toml()) == r
        assert wmrsim.Robot.from_dict(r.to_dict()) == r
    assert wmrsim.Robot.paper() == wmrsim.Robot.from_file(root / "robots" / "paper.toml")


def test_unknown_robot_field_names_it(root):
    text = (root / "robots" / "paper.toml").read_text()
    bad = text.replace("[body]", "[body]\nwheel_radius_mm = 3", 1)
    with pytest.raises(InvalidInputError) as e:
        wmrsim.Robot.from_toml(bad)
    assert "wheel_radius_mm" in str(e.value)


def test_bad_robot_value_names_the_field(root):
    d = wmrsim.Robot.paper().to_dict()
    d["body"]["mass_kg"] = float("nan")
    with pytest.raises(InvalidInputError) as e:
        wmrsim.Robot.from_dict(d)
    assert e.value.field is not None and "mass_kg" in e.value.field
    assert "mass_kg" in str(e.value)
    d["body"]["mass_kg"] = -4.0
    with pytest.raises(ValueError, match="mass_kg"):
        wmrsim.Robot.from_dict(d)


def test_missing_files_raise_file_not_found(tmp_path):
    with pytest.raises(FileNotFoundError):
        wmrsim.Robot.from_file(tmp_path / "nope.toml")
    with pytest.raises(FileNotFoundError):
        wmrsim.Scenario.from_file(tmp_path / "nope.toml")


def test_scenario_files_load(root):
    for path in sorted((root / "scenarios").glob("*.toml")):
        s = wmrsim.Scenario.from_file(path)
        assert wmrsim.Scenario.from_toml(s.to_toml()) == s
        assert wmrsim.Scenario.from_dict(s.to_dict()) == s


@pytest.mark.parametrize(
    "changes, word",
    [
        ({"duration_s": float("nan")}, "duration_s"),
        ({"duration_s": -1.0}, "duration_s"),
        ({"control_period_s": float("inf")}, "control_period_s"),
        ({"initial_pose": [0.0, 1.0]}, "initial_pose"),
        ({"no_such_key": 1}, "no_such_key"),
        ({"plant": {"mass_scale": float("nan")}}, "mass_scale"),
        ({"trajectory": "spiral"}, "spiral"),
        ({"seed": "one"}, "seed"),
        ({"initial_pose": np.array([0.0, np.nan, 0.0])}, "initial_pose"),
    ],
)
def test_bad_scenario_values_raise(changes, word):
    with pytest.raises(InvalidInputError) as e:
        short_case().replace(changes)
    assert word in str(e.value)


def test_unknown_scenario_key_from_dict():
    with pytest.raises(InvalidInputError, match="durration_s"):
        wmrsim.Scenario.from_dict({"version": 2, "durration_s": 5})


def test_bad_arguments_raise():
    with pytest.raises(InvalidInputError, match="case"):
        wmrsim.Scenario.paper_case(3)
    with pytest.raises(InvalidInputError, match="beta"):
        wmrsim.Scenario.paper_case(2, beta=float("nan"))
    with pytest.raises(InvalidInputError, match="controller"):
        wmrsim.run(short_case(), "pid")
    with pytest.raises(InvalidInputError, match="threads"):
        wmrsim.run_batch([short_case()], threads=0)
    with pytest.raises(InvalidInputError, match="controllers"):
        wmrsim.run_batch([short_case(), short_case()], ["smc"])
    with pytest.raises(InvalidInputError, match="trace_every"):
        wmrsim.run(short_case(), trace_every=0)
    with pytest.raises(InvalidInputError, match="sensing"):
        wmrsim.MonteCarlo(2, sensing="sonar")
    with pytest.raises(InvalidInputError, match="runs"):
        wmrsim.MonteCarlo(0)
    with pytest.raises(TypeError):
        wmrsim.run("not a scenario")


def test_replace_keeps_the_rest():
    a = wmrsim.Scenario.paper_case(2, 7)
    b = a.replace({"plant": {"mass_scale": 1.1}})
    assert b.to_dict()["plant"]["mass_scale"] == 1.1
    da, db = a.to_dict(), b.to_dict()
    db["plant"]["mass_scale"] = da["plant"]["mass_scale"]
    assert da == db
    assert b.robot == a.robot


# ---- runs ----


def test_run_metrics_keys_and_trace():
    res = wmrsim.run(short_case())
    m = res.metrics
    for key in ("rms_pos_err_m", "rms_pos_err_window_m", "final_pos_err_m", "saturated_fraction"):
        assert isinstance(m[key], float)
    rep = res.report
    assert rep["controller"] == "proposed"
    assert rep["rejected_steps"] == 0
    assert rep["runtime_stop"] is None
    assert {k: rep[k] for k in m} == m
    tr = res.trace
    # 3 s at one row per 10 ms, the first at t = 0.
    assert tr.array.shape == (len(tr), len(tr.columns)) and len(tr.columns) == 34
    assert 300 <= len(tr) <= 301
    assert np.allclose(np.diff(tr["t_s"]), 0.01)
    # pos_err_m is the distance between the reference and the pose.
    d = np.hypot(tr["ref_x_m"] - tr["x_m"], tr["ref_y_m"] - tr["y_m"])
    assert np.allclose(d, tr["pos_err_m"], atol=1e-12)
    rec = tr.to_records()
    assert np.array_equal(rec["x_m"], tr["x_m"])
    with pytest.raises(KeyError, match="x_m"):
        tr["x"]


def test_trace_dataframe():
    pd = pytest.importorskip("pandas")
    df = wmrsim.run(short_case()).trace.to_pandas()
    assert isinstance(df, pd.DataFrame)
    assert list(df.columns)[:3] == ["t_s", "ref_x_m", "ref_y_m"]


def test_no_trace_when_not_asked():
    assert wmrsim.run(short_case(), trace=False).trace is None


def test_runs_are_deterministic_for_a_seed_and_differ_across_seeds():
    # 12 s: into the perturbation window (10-35 s), where beta and eps act.
    def scn(seed):
        return wmrsim.Scenario.paper_case(2, seed).replace({"duration_s": 12.0})

    a = wmrsim.run(scn(5), "asmc").metrics
    b = wmrsim.run(scn(5), "asmc").metrics
    c = wmrsim.run(scn(6), "asmc").metrics
    assert a == b
    assert a != c


def test_batch_equals_single_runs_in_order():
    scns = [short_case(seed=s) for s in (1, 2, 3)]
    names = ["smc", "asmc", "proposed"]
    batch = wmrsim.run_batch(scns, names, threads=2, trace=True)
    for s, n, r in zip(scns, names, batch):
        one = wmrsim.run(s, n)
        assert r.controller == n
        assert r.metrics == one.metrics
        assert np.array_equal(r.trace.array, one.trace.array, equal_nan=True)
    one_thread = wmrsim.run_batch(scns, names, threads=1)
    assert [r.metrics for r in one_thread] == [r.metrics for r in batch]


def test_pickled_objects_give_the_same_runs(root):
    scn = wmrsim.Scenario.from_file(root / "scenarios" / "example.toml").replace(
        SHORT, plant=wmrsim.Robot.from_file(root / "robots" / "paper.tuned.toml")
    )
    back = pickle.loads(pickle.dumps(scn))
    assert back == scn
    assert wmrsim.run(back, trace=False).metrics == wmrsim.run(scn, trace=False).metrics
    r = wmrsim.Robot.from_file(root / "robots" / "tb6612-2kg.toml")
    assert pickle.loads(pickle.dumps(r)) == r
    mc = wmrsim.MonteCarlo(3, duration_s=2.0, seed=4, robot=wmrsim.Robot.paper())
    assert pickle.loads(pickle.dumps(mc)).records(0, 3) == mc.records(0, 3)


# ---- Monte-Carlo ----


def test_montecarlo_blocks_give_the_whole_sweeps_statistics():
    mc = wmrsim.MonteCarlo(6, duration_s=12.0, seed=3)  # into the window: runs differ
    whole = mc.run(threads=2)
    assert whole["simulations"] == 18
    recs = mc.records(4, 6) + mc.records(0, 1) + mc.records(1, 4, threads=1)
    assert wmrsim.MonteCarlo.stats(recs) == whole["stats"]
    assert [s["controller"] for s in whole["stats"]] == ["smc", "asmc", "proposed"]
    rms = whole["stats"][2]["metrics"]["rms_pos_err_m"]
    assert rms["n"] == 6 and rms["mean"] < rms["max"] and rms["p95"] <= rms["max"]
    with pytest.raises(InvalidInputError, match="0..6"):
        mc.records(2, 7)
    with pytest.raises(InvalidInputError, match="records"):
        wmrsim.MonteCarlo.stats([{"run": "x"}])


# ---- the tuner's cost ----


@pytest.fixture(scope="module")
def tune_set():
    return wmrsim.TuneSet(
        wmrsim.Robot.paper(), sensing=["mocap"], train=2, validate=1, figure8=0, duration_s=15.0
    )


def test_tune_cost_of_the_start_and_of_points(tune_set):
    dims = wmrsim.TuneSet.dims("asmc")
    assert [d[0] for d in dims][:4] == ["kinematic.k_x", "kinematic.k_y", "kinematic.k_th", "sliding.k_s"]
    x0 = tune_set.start("asmc")
    assert len(x0) == len(dims) and all(0.0 <= u <= 1.0 for u in x0)
    e = tune_set.cost("asmc")
    assert e["runs"] == 2 and e["box_penalty"] == 0.0 and e["objective"] == e["cost"]
    pop = np.array([x0, [0.5] * len(dims), [1.2] + [0.5] * (len(dims) - 1)])
    costs = tune_set.costs("asmc", pop)
    assert costs == [tune_set.cost("asmc", row)["objective"] for row in pop]
    # Outside the box: the clamped point's cost plus the squared distance.
    inside = tune_set.cost("asmc", [1.0] + [0.5] * (len(dims) - 1))
    assert costs[2] == pytest.approx(inside["cost"] + 0.2**2, rel=0, abs=1e-12)
    val = tune_set.cost("asmc", x0, part="validation")
    assert val["runs"] == 1


@pytest.mark.parametrize(
    "x, word",
    [
        ([0.5, 0.5], "x has 2 values"),
        ([0.5, math.nan, 0.5, 0.5, 0.5, 0.5], "kinematic.k_y"),
        (np.zeros((2, 6)), ""),
    ],
)
def test_tune_cost_refuses_bad_points(tune_set, x, word):
    with pytest.raises((InvalidInputError, TypeError, ValueError)) as e:
        tune_set.cost("asmc", x)
    assert word in str(e.value)


def test_tune_costs_refuses_bad_populations(tune_set):
    with pytest.raises((TypeError, ValueError)):
        tune_set.costs("smc", np.zeros(5))
    with pytest.raises(InvalidInputError, match=r"population\[1\]"):
        tune_set.costs("smc", np.array([[0.5] * 5, [0.5, 0.5, np.inf, 0.5, 0.5]]))
    with pytest.raises(InvalidInputError, match="part"):
        tune_set.cost("smc", part="test")
    with pytest.raises(InvalidInputError, match="chatter"):
        wmrsim.TuneSet(wmrsim.Robot.paper(), chatter_weight=1.0)


def test_simulation_error_is_a_runtime_error():
    assert issubclass(SimulationError, RuntimeError)
    assert issubclass(InvalidInputError, ValueError)


def test_help_is_useful():
    for obj in (wmrsim, wmrsim.run, wmrsim.run_batch, wmrsim.compare, wmrsim.Scenario,
                wmrsim.Scenario.replace, wmrsim.MonteCarlo, wmrsim.MonteCarlo.records,
                wmrsim.TuneSet, wmrsim.TuneSet.cost, wmrsim.Trace):
        assert obj.__doc__ and len(obj.__doc__) > 40, obj
