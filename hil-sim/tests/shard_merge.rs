//! Sharded Monte-Carlo: shards merged equal one unsharded run, bit for bit,
//! and bad sets of shard files are refused with errors that name the problem.

use clap::Parser;
use hil_sim::cli::{execute, Cli};
use hil_sim::montecarlo::{run_montecarlo, ControllerStats, McConfig};
use hil_sim::shard::merge_shards;
use std::path::{Path, PathBuf};

/// Runs the CLI; stdout or the error message.
fn hil_sim(args: &[&str]) -> Result<String, String> {
    let cli = Cli::try_parse_from(std::iter::once("hil-sim").chain(args.iter().copied()))
        .map_err(|e| e.to_string())?;
    let mut buf = Vec::new();
    execute(&cli, &mut buf)?;
    Ok(String::from_utf8(buf).expect("utf-8"))
}

/// 9 runs of 12 s: the perturbation window (10-35 s) is entered, so every
/// metric (window RMS/max, fault estimate) has run-dependent values.
const RUNS: &str = "9";
const DURATION: &str = "12";

fn write_shard(dir: &Path, shard: &str, seed: &str) -> PathBuf {
    let f = dir.join(format!("seed{seed}-{}.jsonl", shard.replace('/', "of")));
    hil_sim(&[
        "montecarlo",
        "--runs",
        RUNS,
        "--duration",
        DURATION,
        "--seed",
        seed,
        "--vary-mass",
        "--quiet",
        "--shard",
        shard,
        "--out",
        f.to_str().unwrap(),
    ])
    .unwrap();
    f
}

/// Every summary field compared by its bits (0.0 vs -0.0 or a rounding
/// difference would fail).
fn assert_bitwise_equal(a: &[ControllerStats], b: &[ControllerStats]) {
    assert_eq!(a.len(), 3);
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(b) {
        assert_eq!(x.controller, y.controller);
        assert_eq!((x.runs, x.failed), (y.runs, y.failed));
        assert_eq!(x.errors, y.errors);
        for ((n1, s1), (n2, s2)) in x.metrics.iter().zip(&y.metrics) {
            assert_eq!(n1, n2);
            let bits = |s: &Option<hil_sim::montecarlo::Summary>| {
                s.map(|s| (s.mean.to_bits(), s.p95.to_bits(), s.max.to_bits(), s.n))
            };
            assert_eq!(bits(s1), bits(s2), "{} {n1}", x.controller);
        }
    }
}

#[test]
fn three_shards_merged_equal_the_unsharded_run() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = McConfig {
        runs: RUNS.parse().unwrap(),
        case: 2,
        seed: 5,
        vary_mass: true,
        duration_s: Some(DURATION.parse().unwrap()),
        sensing: Default::default(),
        paper_setting: false,
        robot: None,
        plant: None,
    };
    let whole = run_montecarlo(&cfg, &|| {});
    // Non-trivial sample: the runs differ and the window metrics are defined.
    let proposed = &whole.stats[2];
    assert_eq!((proposed.runs, proposed.failed), (9, 0));
    let win = proposed.metrics[1].1.unwrap();
    assert!(win.max > win.mean && win.mean > 0.0, "{win:?}");
    assert!(proposed.metrics[10].1.unwrap().mean > 0.0);

    // Shards given out of order: the order of the files must not matter.
    let files: Vec<PathBuf> = ["2/3", "0/3", "1/3"]
        .iter()
        .map(|s| write_shard(dir.path(), s, "5"))
        .collect();
    let merged = merge_shards(&files).unwrap();
    assert_eq!(merged.sweep, cfg);
    assert_eq!(merged.simulations, 27);
    assert_bitwise_equal(&whole.stats, &merged.stats);

    // The printed text: identical but for the last line (timing vs shard files).
    let unsharded = hil_sim(&[
        "montecarlo",
        "--runs",
        RUNS,
        "--duration",
        DURATION,
        "--seed",
        "5",
        "--vary-mass",
        "--quiet",
    ])
    .unwrap();
    let mut args = vec!["merge"];
    args.extend(files.iter().map(|f| f.to_str().unwrap()));
    let merged_text = hil_sim(&args).unwrap();
    let body = |t: &str| t.lines().count() - 1;
    assert_eq!(body(&unsharded), body(&merged_text));
    let head = |t: &str| t.lines().take(body(t)).collect::<Vec<_>>().join("\n");
    assert_eq!(head(&unsharded), head(&merged_text));
    assert!(
        merged_text.contains("merged from 3 shard files"),
        "{merged_text}"
    );

    // Another split of the same sweep gives the same statistics.
    let two: Vec<PathBuf> = ["0/2", "1/2"]
        .iter()
        .map(|s| write_shard(dir.path(), s, "5"))
        .collect();
    assert_bitwise_equal(&whole.stats, &merge_shards(&two).unwrap().stats);
}

#[test]
fn bad_shard_sets_are_refused_with_named_runs() {
    let dir = tempfile::tempdir().unwrap();
    let s0of3 = write_shard(dir.path(), "0/3", "5");
    let s2of3 = write_shard(dir.path(), "2/3", "5");
    let s0of2 = write_shard(dir.path(), "0/2", "5");
    let s1of2 = write_shard(dir.path(), "1/2", "5");

    // Overlap: 0/2 holds runs 0-3, 0/3 holds 0-2.
    let e = merge_shards(&[s0of2.clone(), s1of2.clone(), s0of3.clone()]).unwrap_err();
    assert!(
        e.contains("duplicate run indices") && e.contains("0-2"),
        "{e}"
    );
    let e = merge_shards(&[s0of2.clone(), s0of2.clone()]).unwrap_err();
    assert!(
        e.contains("duplicate run indices") && e.contains("0-3"),
        "{e}"
    );

    // Gap: 0/3 and 2/3 miss runs 3-5.
    let e = merge_shards(&[s0of3.clone(), s2of3.clone()]).unwrap_err();
    assert!(e.contains("missing run indices 3-5"), "{e}");

    // Another sweep (seed) does not mix.
    let other = write_shard(dir.path(), "1/3", "6");
    let e = merge_shards(&[s0of3.clone(), other, s2of3.clone()]).unwrap_err();
    assert!(
        e.contains("different sweeps") && e.contains("sweep.seed: 5 vs 6"),
        "{e}"
    );

    // Another format version, a foreign file, a corrupted record.
    let text = std::fs::read_to_string(&s0of3).unwrap();
    let v2 = dir.path().join("v2.jsonl");
    std::fs::write(&v2, text.replacen("\"version\":1,", "\"version\":2,", 1)).unwrap();
    let e = merge_shards(&[v2]).unwrap_err();
    assert!(e.contains("format version 2"), "{e}");
    let widened = dir.path().join("widened.jsonl");
    std::fs::write(
        &widened,
        text.replacen("\"runs\":[0,3]", "\"runs\":[0,4]", 1),
    )
    .unwrap();
    let e = merge_shards(&[widened]).unwrap_err();
    assert!(e.contains("inconsistent header"), "{e}");
    let csv = dir.path().join("x.csv");
    std::fs::write(&csv, "a,b\n1,2\n").unwrap();
    assert!(merge_shards(&[csv])
        .unwrap_err()
        .contains("not a hil-sim montecarlo shard"));
    let bad = dir.path().join("bad.jsonl");
    let mut lines: Vec<&str> = text.lines().collect();
    lines[2] = "{\"run\":1}";
    std::fs::write(&bad, lines.join("\n")).unwrap();
    let e = merge_shards(&[bad]).unwrap_err();
    assert!(e.contains("line 3"), "{e}");
}
