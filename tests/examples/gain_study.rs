//! Evidence for the decisions in book/src/explanation/paper-departures.md: k_y (D8), heading
//! reading (D3), torque limit (D14), SMC gain (D13).
//! `cargo run --release -p closed-loop-tests --example gain_study`
use controller_core::ControllerKind;
use hil_sim::scenario::TrajectoryKind;
use hil_sim::sim::{controller_config, run_with};
use hil_sim::Scenario;

fn row(
    label: &str,
    scn: &Scenario,
    kind: ControllerKind,
    tweak: impl Fn(&mut controller_core::ControllerConfig),
) {
    let mut cfg = controller_config(scn, kind);
    tweak(&mut cfg);
    match run_with(scn, cfg, 0) {
        Ok(o) => {
            let m = o.metrics;
            println!(
                "{label:38} {:9} rms {:8.4} after5 {:8.4} win {:8.4} maxwin {:8.4} sat {:.3} trms {:.2}",
                kind.name(), m.rms_pos_err_m, m.rms_pos_err_after5_m, m.rms_pos_err_window_m, m.max_pos_err_window_m, m.saturated_fraction, m.torque_rms_nm
            );
        }
        Err(e) => println!("{label:38} {:9} FAILED: {e}", kind.name()),
    }
}

fn main() {
    let c2 = Scenario::paper_case(2, 1, None, None);
    println!(
        "Case 2 seed 1: beta = {:.4} rad/s, eps = {:.4}",
        c2.perturbations.beta, c2.perturbations.eps
    );
    println!("== k_y (Case 2, seed 1) ==");
    for k_y in [250.0, 100.0, 50.0, 25.0, 10.0] {
        let scn = {
            let mut s = Scenario::paper_case(2, 1, None, None);
            s.controller.k_y = Some(k_y);
            s
        };
        for kind in ControllerKind::ALL {
            row(&format!("k_y = {k_y}"), &scn, kind, |_| {});
        }
    }
    println!("== k_y at a 5 N·m torque limit (Case 2, seed 1) ==");
    for k_y in [50.0, 25.0, 10.0] {
        let scn = {
            let mut s = Scenario::paper_case(2, 1, None, None);
            s.controller.k_y = Some(k_y);
            s.plant.torque_limit_nm = Some(5.0);
            s
        };
        row(
            &format!("k_y = {k_y}, 5 N·m"),
            &scn,
            ControllerKind::Proposed,
            |_| {},
        );
    }
    println!("== heading reading (Case 2, seed 1) ==");
    for tr in [
        TrajectoryKind::Paper,
        TrajectoryKind::PaperTangent,
        TrajectoryKind::PaperPrinted,
    ] {
        for k_y in [25.0, 250.0] {
            let scn = {
                let mut s = Scenario {
                    trajectory: tr,
                    ..Scenario::paper_case(2, 1, None, None)
                };
                s.controller.k_y = Some(k_y);
                s
            };
            for kind in ControllerKind::ALL {
                row(&format!("{tr:?} k_y={k_y}"), &scn, kind, |_| {});
            }
        }
    }
    println!("== torque limit (Case 2, seed 1) ==");
    for lim in [2.0, 5.0, 10.0, 20.0, 1000.0] {
        let scn = {
            let mut s = Scenario::paper_case(2, 1, None, None);
            s.plant.torque_limit_nm = Some(lim);
            s
        };
        for kind in ControllerKind::ALL {
            row(&format!("limit {lim} N·m"), &scn, kind, |_| {});
        }
    }
    println!("== SMC fixed gain K (Case 1 and 2, seed 1) ==");
    for case in [1u8, 2] {
        for k in [0.1f32, 0.5, 1.0, 2.0, 5.0] {
            let scn = Scenario::paper_case(case, 1, None, None);
            row(
                &format!("case {case} K = {k}"),
                &scn,
                ControllerKind::Smc,
                |c| c.sliding.switching = controller_core::asmc::Switching::Fixed(k),
            );
        }
    }
}
