//! One 40 s paper Case 2 run of the proposed controller in the paper's
//! setting, no trace (what `hil-sim bench` times), `N` times (first
//! argument, default 1): a fixed workload for profilers (BENCHMARKS.md,
//! "Speed, issue 17": `perf record -g`, `valgrind --tool=callgrind`).
//! Prints the fastest run's wall-clock time.

use controller_core::ControllerKind;
use hil_sim::sim::{controller_config, run_with};
use hil_sim::Scenario;

fn main() {
    let n: usize = match std::env::args().nth(1).map(|s| s.parse()) {
        None => 1,
        Some(Ok(n)) if n > 0 => n,
        Some(_) => {
            eprintln!("usage: one_run [N >= 1]");
            std::process::exit(2);
        }
    };
    let scn = Scenario::paper_case(2, 1, None, None).as_printed();
    let cfg = controller_config(&scn, ControllerKind::Proposed);
    let mut best_ms = f64::INFINITY;
    for _ in 0..n {
        let t = std::time::Instant::now();
        match run_with(&scn, cfg, 0) {
            Ok(o) => {
                std::hint::black_box(o);
            }
            Err(e) => {
                eprintln!("one_run: {e}");
                std::process::exit(1);
            }
        }
        best_ms = best_ms.min(t.elapsed().as_secs_f64() * 1e3);
    }
    println!("fastest of {n}: {best_ms:.2} ms");
}
