//! Long runs are never silent (issue 21 item 7): with stderr not a terminal
//! (a log file, a batch job), `montecarlo` prints progress lines on stderr
//! at the period of `HIL_SIM_PROGRESS_EVERY_S` (10 s by default), and so
//! does a long `run`.
//!
//! These tests set the period to zero, which makes the lines count-driven
//! (one per simulation; one at the start of a `run`): what they assert
//! holds however fast or slow the machine is (issue 30). The timed lines
//! are tested against a clock the test drives, in `src/progress.rs`.

use std::collections::BTreeSet;
use std::process::Command;

fn stderr_of(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_hil-sim"))
        .args(args)
        .env(hil_sim::progress::LINE_PERIOD_ENV, "0")
        .output()
        .expect("hil-sim");
    assert!(out.status.success(), "{out:?}");
    String::from_utf8(out.stderr).unwrap()
}

#[test]
fn montecarlo_prints_a_progress_line_for_every_simulation_when_stderr_is_a_pipe() {
    let e = stderr_of(&["montecarlo", "--runs", "12", "--duration", "8"]);
    // Every count from 1 to 36 exactly once (the simulations run on
    // several threads, so the lines may come in any order).
    let counts: Vec<u64> = e
        .lines()
        .filter_map(|l| l.strip_prefix("progress: "))
        .filter_map(|l| l.split_once("/36 simulations"))
        .map(|(k, _)| k.parse().expect("a count"))
        .collect();
    let distinct: BTreeSet<u64> = counts.iter().copied().collect();
    assert_eq!(counts.len(), 36, "{e:?}");
    assert_eq!(distinct, (1..=36).collect(), "{e:?}");
}

#[test]
fn run_prints_a_progress_line_when_stderr_is_a_pipe() {
    let e = stderr_of(&["run", "--duration", "20", "--sensing", "mocap"]);
    let lines: Vec<&str> = e
        .lines()
        .filter(|l| l.starts_with("progress: run: simulating 20 s"))
        .collect();
    assert_eq!(lines.len(), 1, "{e:?}");
}

#[test]
fn quiet_montecarlo_prints_no_progress() {
    let e = stderr_of(&["montecarlo", "--runs", "2", "--duration", "2", "--quiet"]);
    assert!(!e.contains("progress: "), "{e:?}");
}
