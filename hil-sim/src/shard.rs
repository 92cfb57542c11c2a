//! Sharded Monte-Carlo sweeps: `montecarlo --shard I/N` runs a deterministic
//! slice of the run indices and writes its raw [`SimRecord`]s to a shard
//! file; `merge` reads any set of shard files, checks that they belong to
//! the same sweep and cover every run index exactly once, and computes the
//! statistics with the same function as an unsharded run
//! ([`stats_from_records`]). Run `i` uses the seed [`run_seed`]`(seed, i)`
//! in every split, so merged shards equal one run bit for bit.
//!
//! Shard file (JSON Lines): line 1 is a [`ShardHeader`], then one
//! [`SimRecord`] per line. Usage: book/src/how-to/sweeps.md.

use crate::montecarlo::{
    run_seed, stats_from_records, ControllerStats, McConfig, Outcome, SimRecord, MAX_RUNS, METRICS,
};
use crate::scenario::Scenario;
use controller_core::ControllerKind;
use serde::{Deserialize, Serialize};
use std::io::Write as _;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// Value of the header's `format` field.
pub const SHARD_FORMAT: &str = "hil-sim montecarlo shard";

/// Version of the shard file layout; `merge` refuses any other.
pub const SHARD_FORMAT_VERSION: u32 = 1;

/// At most this many duplicate or missing items are named in an error.
const MAX_LISTED: usize = 12;

/// Shard `index` of `count` (0-based: `0/4` … `3/4`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    /// 0-based index, `< count`.
    pub index: u64,
    /// Number of shards, >= 1.
    pub count: u64,
}

impl Shard {
    /// The whole sweep as one shard.
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };

    /// Shard `index` of `count`; error unless `index < count`.
    pub fn new(index: u64, count: u64) -> Result<Self, String> {
        if count == 0 || index >= count {
            return Err(format!(
                "shard {index}/{count}: need 0 <= I < N (shards are 0-based: 0/{n} … {m}/{n})",
                n = count.max(1),
                m = count.max(1) - 1
            ));
        }
        Ok(Self { index, count })
    }

    /// Parses `I/N` (the `--shard` argument).
    pub fn parse(s: &str) -> Result<Self, String> {
        let bad = || format!("expected I/N with 0 <= I < N (0-based, e.g. 0/4), got '{s}'");
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let i = i.trim().parse::<u64>().map_err(|_| bad())?;
        let n = n.trim().parse::<u64>().map_err(|_| bad())?;
        Self::new(i, n)
    }

    /// The run indices of this shard out of `0..total`: a contiguous block,
    /// `[⌊index·total/count⌋, ⌊(index+1)·total/count⌋)`. The blocks of
    /// `0/N … N−1/N` are disjoint and cover `0..total`; their sizes differ
    /// by at most one (empty when `count > total`).
    pub fn runs(&self, total: u64) -> Range<u64> {
        let at = |k: u64| (u128::from(k) * u128::from(total) / u128::from(self.count)) as u64;
        at(self.index)..at(self.index + 1)
    }
}

/// First line of a shard file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShardHeader {
    /// Always [`SHARD_FORMAT`].
    pub format: String,
    /// [`SHARD_FORMAT_VERSION`] of the writer.
    pub version: u32,
    /// Version of the hil-sim crate that wrote the file.
    pub hil_sim_version: String,
    /// The sweep (the `montecarlo` flags).
    pub sweep: McConfig,
    /// Every knob of run 0's scenario as this build sets it: shards from
    /// builds with different scenario defaults do not merge.
    pub run0_scenario: Scenario,
    /// Which shard.
    pub shard: Shard,
    /// Its run indices `[start, end)`.
    pub runs: [u64; 2],
    /// Wall-clock time of the shard \[s\] (information only).
    pub elapsed_s: f64,
    /// Worker threads of the shard (information only).
    pub threads: usize,
}

impl ShardHeader {
    /// Header of shard `shard` of the sweep `sweep`.
    pub fn new(sweep: &McConfig, shard: Shard, elapsed_s: f64, threads: usize) -> Self {
        let r = shard.runs(sweep.runs as u64);
        Self {
            format: SHARD_FORMAT.into(),
            version: SHARD_FORMAT_VERSION,
            hil_sim_version: env!("CARGO_PKG_VERSION").into(),
            sweep: sweep.clone(),
            run0_scenario: sweep.scenario(0),
            shard,
            runs: [r.start, r.end],
            elapsed_s,
            threads,
        }
    }

    /// The fields that must agree between shards of one sweep, as JSON, in
    /// the order a difference is reported: the sweep settings first (a
    /// different run 0 follows from them), then the build.
    fn identity(&self) -> [(&'static str, serde_json::Value); 3] {
        [
            ("sweep", serde_json::json!(self.sweep)),
            ("hil_sim_version", serde_json::json!(self.hil_sim_version)),
            ("run0_scenario", serde_json::json!(self.run0_scenario)),
        ]
    }

    /// Why `other` is not a shard of the same sweep as `self` (None if it is):
    /// the differing fields of the first part that differs.
    fn incompatibility(&self, other: &Self) -> Option<String> {
        self.identity()
            .iter()
            .zip(other.identity().iter())
            .find_map(|((name, a), (_, b))| {
                let mut diff = Vec::new();
                json_diff(name, a, b, &mut diff);
                (!diff.is_empty()).then(|| list(&diff))
            })
    }
}

/// Default shard file name, e.g. `mc-case2-seed1-runs200-shard3of8.jsonl`.
pub fn default_shard_path(sweep: &McConfig, shard: Shard) -> PathBuf {
    let sensing = match sweep.sensing {
        crate::scenario::Sensing::Ideal => String::new(),
        s => format!("-{}", s.name()),
    };
    PathBuf::from(format!(
        "mc-case{}{sensing}-seed{}-runs{}-shard{}of{}.jsonl",
        sweep.case, sweep.seed, sweep.runs, shard.index, shard.count
    ))
}

/// Writes a shard file: the header, then one record per line. Written to
/// `FILE.partial` and renamed, so an interrupted job leaves no file that
/// looks finished. A non-finite metric is an error (serde_json would write
/// it as `null`, which does not read back).
pub fn write_shard(path: &Path, header: &ShardHeader, records: &[SimRecord]) -> Result<(), String> {
    for r in records {
        check_finite(r)?;
    }
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".partial");
    let tmp = PathBuf::from(tmp);
    let err = |e: std::io::Error| format!("cannot write {}: {e}", tmp.display());
    let f = std::fs::File::create(&tmp).map_err(err)?;
    let mut w = std::io::BufWriter::new(f);
    let line = |v: serde_json::Result<String>| v.map_err(|e| e.to_string());
    writeln!(w, "{}", line(serde_json::to_string(header))?).map_err(err)?;
    for r in records {
        writeln!(w, "{}", line(serde_json::to_string(r))?).map_err(err)?;
    }
    w.into_inner()
        .map_err(|e| err(e.into_error()))?
        .sync_all()
        .map_err(err)?;
    std::fs::rename(&tmp, path)
        .map_err(|e| format!("cannot rename {} to {}: {e}", tmp.display(), path.display()))
}

/// Error if a metric of `r` is NaN or infinite.
fn check_finite(r: &SimRecord) -> Result<(), String> {
    if let Outcome::Metrics(m) = &r.outcome {
        for (name, f) in METRICS {
            if f(m).is_some_and(|x| !x.is_finite()) {
                return Err(format!(
                    "run {} ({}): {name} is not finite and cannot be stored",
                    r.run,
                    r.controller.name()
                ));
            }
        }
    }
    Ok(())
}

/// Reads one shard file: its header and records. Errors name the file and
/// line: not a shard file, another format version, a malformed line, a run
/// outside the header's range or with a seed that is not the sweep's.
pub fn read_shard(path: &Path) -> Result<(ShardHeader, Vec<SimRecord>), String> {
    let name = path.display();
    let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read {name}: {e}"))?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let (_, first) = lines
        .next()
        .ok_or_else(|| format!("{name}: empty file, not a {SHARD_FORMAT} file"))?;
    let v: serde_json::Value = serde_json::from_str(first)
        .map_err(|_| format!("{name}: not a {SHARD_FORMAT} file (line 1 is not JSON)"))?;
    if v.get("format").and_then(|f| f.as_str()) != Some(SHARD_FORMAT) {
        return Err(format!(
            "{name}: not a {SHARD_FORMAT} file (line 1 has no format \"{SHARD_FORMAT}\")"
        ));
    }
    match v.get("version").and_then(|x| x.as_u64()) {
        Some(x) if x == u64::from(SHARD_FORMAT_VERSION) => {}
        other => {
            return Err(format!(
            "{name}: shard format version {}, this hil-sim reads version {SHARD_FORMAT_VERSION} \
                 (re-run the shard with this build)",
            other.map_or("missing".into(), |x| x.to_string())
        ))
        }
    }
    let header: ShardHeader =
        serde_json::from_value(v).map_err(|e| format!("{name} line 1: bad header: {e}"))?;
    let sweep = &header.sweep;
    let expected = header.shard.runs(sweep.runs as u64);
    if !(1..=MAX_RUNS).contains(&(sweep.runs as u64))
        || Shard::new(header.shard.index, header.shard.count).is_err()
        || header.runs != [expected.start, expected.end]
    {
        return Err(format!(
            "{name} line 1: inconsistent header (runs {}, shard {}/{}, block {:?})",
            sweep.runs, header.shard.index, header.shard.count, header.runs
        ));
    }
    sweep
        .validate()
        .map_err(|e| format!("{name} line 1: {e}"))?;
    let range = header.runs[0]..header.runs[1];
    let mut records = Vec::new();
    for (k, l) in lines {
        let r: SimRecord =
            serde_json::from_str(l).map_err(|e| format!("{name} line {}: {e}", k + 1))?;
        if !range.contains(&r.run) {
            return Err(format!(
                "{name} line {}: run {} is outside the shard's runs [{}, {})",
                k + 1,
                r.run,
                range.start,
                range.end
            ));
        }
        let want = run_seed(header.sweep.seed, r.run);
        if r.seed != want {
            return Err(format!(
                "{name} line {}: run {} has seed {}, the sweep's run {} has seed {want} \
                 (written by an incompatible hil-sim?)",
                k + 1,
                r.run,
                r.seed,
                r.run
            ));
        }
        records.push(r);
    }
    Ok((header, records))
}

/// The merged sweep.
#[derive(Clone, Debug, Serialize)]
pub struct Merged {
    /// The sweep's settings.
    pub sweep: McConfig,
    /// Statistics per controller (as an unsharded run computes them).
    pub stats: Vec<ControllerStats>,
    /// Simulations merged (runs × 3).
    pub simulations: usize,
    /// The shard files.
    pub shard_files: Vec<String>,
    /// Sum of the shards' own wall-clock times \[s\].
    pub shards_elapsed_s: f64,
}

/// `"a, b, c"` of the first [`MAX_LISTED`] items, `"… and N more"` after.
fn list<T: std::fmt::Display>(items: &[T]) -> String {
    let mut s = items
        .iter()
        .take(MAX_LISTED)
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(", ");
    if items.len() > MAX_LISTED {
        s += &format!(" and {} more", items.len() - MAX_LISTED);
    }
    s
}

/// Sorted indices as ranges: `[0, 1, 2, 5]` → `["0-2", "5"]`.
fn ranges(idx: &[u64]) -> Vec<String> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < idx.len() {
        let mut j = i;
        while j + 1 < idx.len() && idx[j + 1] == idx[j] + 1 {
            j += 1;
        }
        out.push(if i == j {
            idx[i].to_string()
        } else {
            format!("{}-{}", idx[i], idx[j])
        });
        i = j + 1;
    }
    out
}

/// Paths where two JSON values differ, with both values (`sweep.seed: 1 vs 2`).
fn json_diff(path: &str, a: &serde_json::Value, b: &serde_json::Value, out: &mut Vec<String>) {
    use serde_json::Value::Object;
    match (a, b) {
        (Object(x), Object(y)) => {
            let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
            keys.sort();
            keys.dedup();
            let null = serde_json::Value::Null;
            for k in keys {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                json_diff(
                    &p,
                    x.get(k).unwrap_or(&null),
                    y.get(k).unwrap_or(&null),
                    out,
                );
            }
        }
        _ if a != b => out.push(format!("{path}: {a} vs {b}")),
        _ => {}
    }
}

/// Merges shard files into the statistics of one unsharded run. Errors:
/// no files, an unreadable or foreign file, shards of different sweeps or
/// builds (naming the fields that differ), run indices present twice or
/// missing (naming them).
pub fn merge_shards(paths: &[PathBuf]) -> Result<Merged, String> {
    if paths.is_empty() {
        return Err("merge: no shard files given".into());
    }
    let shards = paths
        .iter()
        .map(|p| read_shard(p))
        .collect::<Result<Vec<_>, _>>()?;
    let (h0, _) = &shards[0];
    for ((h, _), p) in shards.iter().zip(paths).skip(1) {
        if let Some(why) = h0.incompatibility(h) {
            return Err(format!(
                "{} and {} are shards of different sweeps and cannot be merged: {why}",
                paths[0].display(),
                p.display(),
            ));
        }
    }
    let sweep = h0.sweep.clone();
    let runs = sweep.runs as u64;
    let nk = ControllerKind::ALL.len();
    let slot = |r: &SimRecord| {
        let k = ControllerKind::ALL
            .iter()
            .position(|&k| k == r.controller)
            .expect("every kind is in ALL");
        r.run as usize * nk + k
    };
    // Which file holds each (run, controller); a second holder is a duplicate.
    let mut holder: Vec<Option<usize>> = vec![None; runs as usize * nk];
    let mut duplicates: Vec<(usize, usize, u64)> = Vec::new();
    for (f, (_, recs)) in shards.iter().enumerate() {
        for r in recs {
            let s = slot(r);
            match holder[s] {
                None => holder[s] = Some(f),
                Some(g) => duplicates.push((g, f, r.run)),
            }
        }
    }
    if !duplicates.is_empty() {
        duplicates.sort_unstable();
        duplicates.dedup();
        let mut groups: Vec<String> = Vec::new();
        for pair in duplicates.chunk_by(|a, b| (a.0, a.1) == (b.0, b.1)) {
            let (g, f, _) = pair[0];
            let idx: Vec<u64> = pair.iter().map(|d| d.2).collect();
            groups.push(format!(
                "{} in {}{}",
                list(&ranges(&idx)),
                paths[g].display(),
                if g == f {
                    " twice".to_string()
                } else {
                    format!(" and {}", paths[f].display())
                }
            ));
        }
        return Err(format!(
            "duplicate run indices (overlapping shards, or one file given twice): {}",
            groups.join("; ")
        ));
    }
    let missing: Vec<u64> = (0..runs)
        .filter(|&i| (0..nk).any(|k| holder[i as usize * nk + k].is_none()))
        .collect();
    if !missing.is_empty() {
        return Err(format!(
            "missing run indices {} of 0-{} ({} runs): add the shard files that hold them",
            list(&ranges(&missing)),
            runs - 1,
            missing.len()
        ));
    }
    let records: Vec<SimRecord> = shards.iter().flat_map(|(_, r)| r.iter().cloned()).collect();
    Ok(Merged {
        sweep,
        stats: stats_from_records(&records),
        simulations: records.len(),
        shard_files: paths.iter().map(|p| p.display().to_string()).collect(),
        shards_elapsed_s: shards.iter().map(|(h, _)| h.elapsed_s).sum(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_partition_the_runs() {
        for total in [0u64, 1, 2, 7, 100, 1_000_000] {
            for count in [1u64, 2, 3, 8, 13] {
                let mut next = 0;
                let mut sizes = Vec::new();
                for index in 0..count {
                    let r = Shard::new(index, count).unwrap().runs(total);
                    assert_eq!(r.start, next, "total {total}, shard {index}/{count}");
                    next = r.end;
                    sizes.push(r.end - r.start);
                }
                assert_eq!(next, total);
                let (lo, hi) = (sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
                assert!(hi - lo <= 1, "{sizes:?}");
            }
        }
    }

    #[test]
    fn shard_argument_errors() {
        assert_eq!(Shard::parse("2/4").unwrap(), Shard { index: 2, count: 4 });
        for bad in ["4/4", "0/0", "1", "a/3", "-1/3", "1/3/4", ""] {
            let e = Shard::parse(bad).unwrap_err();
            assert!(e.contains("0 <= I < N"), "{bad}: {e}");
        }
    }

    /// Any finite f64 (random bit patterns, all exponents, subnormals) reads
    /// back from a shard file with the same bits; a non-finite metric is an
    /// error when writing, not a `null` that would fail at merge time.
    #[test]
    fn shard_files_round_trip_every_bit() {
        use crate::metrics::Metrics;
        use crate::rng::Rng;
        let sweep = McConfig {
            runs: 500,
            case: 2,
            seed: 3,
            vary_mass: false,
            duration_s: None,
            sensing: Default::default(),
            paper_setting: false,
            robot: None,
            plant: None,
        };
        let mut rng = Rng::new(9);
        let mut any = || loop {
            let x = f64::from_bits(rng.next_u64());
            if x.is_finite() {
                return x;
            }
        };
        let records: Vec<SimRecord> = (0..500u64)
            .flat_map(|i| ControllerKind::ALL.map(|k| (i, k)))
            .map(|(i, k)| SimRecord {
                run: i,
                seed: run_seed(3, i),
                controller: k,
                outcome: if i == 7 {
                    Outcome::Error("diverged, \"quoted\"\nnewline".into())
                } else {
                    Outcome::Metrics(Metrics {
                        rms_pos_err_m: any(),
                        rms_pos_err_window_m: any(),
                        max_pos_err_window_m: any(),
                        rms_pos_err_after5_m: any(),
                        final_pos_err_m: any(),
                        settling_time_s: (i % 2 == 0).then(&mut any),
                        torque_rms_nm: any(),
                        max_abs_torque_nm: f64::MIN_POSITIVE / 3.0,
                        chatter: any(),
                        saturated_fraction: any(),
                        fault_est_rmse: Some(any()),
                        time_lag_final_s: None,
                        min_time_scale: None,
                        degraded_fraction: None,
                        health_transitions: None,
                        safe_stop: None,
                        rms_est_err_window_m: None,
                    })
                },
            })
            .collect();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.jsonl");
        let header = ShardHeader::new(&sweep, Shard::WHOLE, 1.0, 2);
        write_shard(&path, &header, &records).unwrap();
        let (h, back) = read_shard(&path).unwrap();
        assert_eq!(h, header);
        assert_eq!(back.len(), records.len());
        for (a, b) in records.iter().zip(&back) {
            assert_eq!((a.run, a.seed, a.controller), (b.run, b.seed, b.controller));
            match (&a.outcome, &b.outcome) {
                (Outcome::Metrics(x), Outcome::Metrics(y)) => {
                    for (name, f) in METRICS {
                        assert_eq!(f(x).map(f64::to_bits), f(y).map(f64::to_bits), "{name}");
                    }
                }
                (x, y) => assert_eq!(x, y),
            }
        }
        let mut nan = records[0].clone();
        if let Outcome::Metrics(m) = &mut nan.outcome {
            m.chatter = f64::NAN;
        }
        let e = write_shard(&path, &header, &[nan]).unwrap_err();
        assert!(e.contains("chatter is not finite"), "{e}");
    }

    #[test]
    fn ranges_compress_consecutive_indices() {
        assert_eq!(ranges(&[0, 1, 2, 5, 7, 8]), ["0-2", "5", "7-8"]);
        assert!(ranges(&[]).is_empty());
    }
}
