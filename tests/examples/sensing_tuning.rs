//! Scans estimator tunings over the sensing presets (Case 2, β = 0.1,
//! ε = 0.2): window RMS per controller. A development aid for D25/D26.
//! `cargo run --release -p closed-loop-tests --example sensing_tuning -- [seeds]`

use controller_core::estimator::EstimatorConfig;
use controller_core::ControllerKind;
use hil_sim::hil::{run_hil, HilOptions};
use hil_sim::scenario::Sensing;
use hil_sim::Scenario;

fn main() {
    let seeds: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    let base = EstimatorConfig::EXAMPLE;
    let mut tunings: Vec<(String, EstimatorConfig)> = vec![("example".into(), base)];
    for tau in [0.0f32, 0.1, 0.3] {
        tunings.push((
            format!("max_tau{tau}"),
            EstimatorConfig {
                output_smoothing_s: tau,
                ..base
            },
        ));
    }
    let only: Vec<Sensing> = match std::env::args().nth(2).as_deref() {
        Some("mocap") => vec![Sensing::Mocap],
        Some("uwb") => vec![Sensing::Uwb],
        _ => vec![Sensing::Mocap, Sensing::Uwb],
    };
    for sensing in only {
        for (name, est) in &tunings {
            let mut line = format!("{:6} {:24}", sensing.name(), name);
            for kind in ControllerKind::ALL {
                let rms: Vec<f64> = std::thread::scope(|s| {
                    let hs: Vec<_> = (1..=seeds)
                        .map(|seed| {
                            s.spawn(move || {
                                let scn = {
                                    let mut s = Scenario {
                                        seed,
                                        ..Scenario::paper_case(2, seed, Some(0.1), Some(0.2))
                                    };
                                    s.sensing.preset = sensing;
                                    s
                                };
                                let opts = HilOptions {
                                    estimator: Some(*est),
                                    ..HilOptions::default()
                                };
                                run_hil(&scn, kind, opts)
                                    .map(|o| o.sim.metrics.rms_pos_err_window_m)
                                    .unwrap_or(f64::NAN)
                            })
                        })
                        .collect();
                    hs.into_iter().map(|h| h.join().unwrap()).collect()
                });
                let worst = rms.iter().cloned().fold(0.0, f64::max);
                line += &format!("  {}: worst {:.4}", kind.name(), worst);
            }
            println!("{line}");
        }
    }
}
