"""wmrsim equals the hil-sim CLI number for number on the same inputs:
`run --json` and its `--csv` trace, `montecarlo --json`, `compare --json`
and the costs `tune --json` reports (floats compared exactly: the CLI's
JSON and CSV print the shortest text that reads back to the same f64)."""

import csv
import json
import math

import numpy as np
import pytest

import wmrsim


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], np.array([[float(c) for c in r] for r in rows[1:]])


@pytest.mark.parametrize("controller, case, seed", [("proposed", 2, 3), ("smc", 1, 11), ("asmc", 2, 1)])
def test_run_equals_cli(hil_sim, tmp_path, controller, case, seed):
    out = hil_sim(
        "run", "--controller", controller, "--case", str(case), "--seed", str(seed),
        "--duration", "5", "--json", "--csv", str(tmp_path / "t.csv"),
    )
    cli = json.loads(out)
    scn = wmrsim.Scenario.paper_case(case, seed).replace({"duration_s": 5.0})
    res = wmrsim.run(scn, controller)
    assert res.report == cli
    header, rows = read_csv(tmp_path / "t.csv")
    assert tuple(header) == res.trace.columns
    assert rows.shape == res.trace.array.shape
    assert np.array_equal(rows, res.trace.array, equal_nan=True)


def test_run_with_files_equals_cli(hil_sim, root):
    scn_file = root / "scenarios" / "example.toml"
    robot = root / "robots" / "paper.tuned.toml"
    out = hil_sim("run", "--scenario", str(scn_file), "--robot", str(robot),
                  "--duration", "4", "--json", "--controller", "asmc")
    scn = wmrsim.Scenario.from_file(scn_file, robot=wmrsim.Robot.from_file(robot))
    res = wmrsim.run(scn.replace({"duration_s": 4.0}), "asmc", trace=False)
    assert res.report == json.loads(out)


def test_runtime_sensing_run_equals_cli(hil_sim):
    out = hil_sim("run", "--sensing", "mocap", "--duration", "4", "--seed", "2", "--json")
    scn = wmrsim.Scenario.paper_case(2, 2).replace({"duration_s": 4.0, "sensing": {"preset": "mocap"}})
    assert wmrsim.run(scn, trace=False).report == json.loads(out)


def test_montecarlo_equals_cli(hil_sim):
    out = hil_sim("montecarlo", "--runs", "5", "--duration", "3", "--seed", "9",
                  "--vary-mass", "--json", "--quiet")
    cli = json.loads(out)
    mc = wmrsim.MonteCarlo(5, duration_s=3.0, seed=9, vary_mass=True)
    py = mc.run()
    assert py["stats"] == cli["stats"]
    assert py["simulations"] == cli["simulations"] == 15
    assert wmrsim.MonteCarlo.stats(mc.records(0, 5)) == cli["stats"]


def test_compare_equals_cli(hil_sim, tmp_path):
    out = hil_sim("compare", "--seed", "2", "--json", "--no-plots", "--out", str(tmp_path))
    cli = json.loads(out)
    assert wmrsim.compare(seed=2) == cli
    gov = json.loads((tmp_path / "metrics_governor.json").read_text())
    assert wmrsim.compare(seed=2, beyond_paper=True) == gov


def test_tune_costs_equal_cli(hil_sim, root, tmp_path):
    out = hil_sim(
        "tune", "--robot", str(root / "robots" / "paper.toml"), "--sensing", "mocap,ideal",
        "--train", "2", "--validate", "1", "--duration", "15", "--optimizer", "nelder-mead",
        "--evaluations", "7", "--controllers", "asmc", "--seed", "5", "--json", "--quiet",
        "--write", str(tmp_path / "tuned.toml"),
    )
    cli = json.loads(out)
    (name, start, best), = cli["controllers"]
    assert name == "asmc"
    ts = wmrsim.TuneSet(wmrsim.Robot.paper(), sensing=["mocap", "ideal"], seed=5, train=2,
                        validate=1, duration_s=15.0)

    def same(py, cli_eval):
        assert {k: py[k] for k in cli_eval} == cli_eval

    same(ts.cost("asmc"), start["training"])
    same(ts.cost("asmc", part="validation"), start["validation"])
    x = np.array(best["x"])
    same(ts.cost("asmc", x), best["tuned"]["training"])
    same(ts.cost("asmc", x, part="validation"), best["tuned"]["validation"])


def test_shard_file_records_equal_a_block(hil_sim, tmp_path):
    # `montecarlo --shard 1/2` of 5 runs is runs 2..5: the file's lines after
    # the header are MonteCarlo.records(2, 5), so shards merge in Python too.
    path = tmp_path / "s.jsonl"
    hil_sim("montecarlo", "--runs", "5", "--duration", "3", "--seed", "4", "--quiet",
            "--shard", "1/2", "--out", str(path))
    lines = path.read_text().splitlines()
    header = json.loads(lines[0])
    assert header["runs"] == [2, 5]
    recs = [json.loads(line) for line in lines[1:]]
    mc = wmrsim.MonteCarlo(5, duration_s=3.0, seed=4)
    key = lambda r: (r["run"], r["controller"])  # noqa: E731
    assert sorted(recs, key=key) == sorted(mc.records(2, 5), key=key)
