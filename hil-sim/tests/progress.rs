//! Long runs are never silent (issue 21 item 7): with stderr not a terminal
//! (a log file, a batch job), `montecarlo` prints progress lines on stderr
//! at the period of `HIL_SIM_PROGRESS_EVERY_S` (10 s by default), and so
//! does a long `run`.

use std::process::Command;

fn stderr_of(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_hil-sim"))
        .args(args)
        .env(hil_sim::progress::LINE_PERIOD_ENV, "0.05")
        .output()
        .expect("hil-sim");
    assert!(out.status.success(), "{out:?}");
    String::from_utf8(out.stderr).unwrap()
}

#[test]
fn montecarlo_and_run_print_progress_lines_when_stderr_is_a_pipe() {
    let e = stderr_of(&["montecarlo", "--runs", "12", "--duration", "8"]);
    let lines: Vec<&str> = e
        .lines()
        .filter(|l| l.starts_with("progress: ") && l.contains("/36 simulations"))
        .collect();
    assert!(!lines.is_empty(), "no progress lines: {e:?}");
    let e = stderr_of(&["run", "--duration", "20", "--sensing", "mocap"]);
    assert!(
        e.lines()
            .any(|l| l.starts_with("progress: run: simulating 20 s")),
        "{e:?}"
    );
}
