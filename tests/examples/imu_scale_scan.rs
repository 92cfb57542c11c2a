//! The gyro-vs-wheel speed scale (book/src/explanation/decisions.md D36) off and on: window
//! RMS of the three controllers (smc, asmc, proposed), the proposed's final
//! speed scale and gyro bias, per Case 2 scenario of tests/tests/sensing.rs,
//! and the worst ratio proposed / better baseline. A development aid.
//! `cargo run --release -p closed-loop-tests --example imu_scale_scan -- [imu|uwb|mocap]`
use controller_core::estimator::EstimatorConfig;
use controller_core::ControllerKind;
use hil_sim::hil::{run_hil, HilOptions};
use hil_sim::scenario::Sensing;
use hil_sim::Scenario;

fn main() {
    let base = EstimatorConfig::EXAMPLE;
    let args: Vec<String> = std::env::args().collect();
    let sensing = match args.get(1).map(|s| s.as_str()) {
        Some("uwb") => Sensing::Uwb,
        Some("mocap") => Sensing::Mocap,
        _ => Sensing::Imu,
    };
    let mut tunings: Vec<(String, EstimatorConfig)> = vec![
        (
            "off".into(),
            EstimatorConfig {
                gyro_speed_scale: false,
                ..base
            },
        ),
        ("on".into(), base),
    ];
    for (yn, mt) in [
        (0.07f32, 0.005f32),
        (0.1, 0.005),
        (0.2, 0.005),
        (0.15, 0.002),
        (0.15, 0.01),
    ] {
        tunings.push((
            format!("yn{yn}mt{mt}"),
            EstimatorConfig {
                gyro_scale_yaw_noise: yn,
                gyro_scale_min_turn_rad: mt,
                ..base
            },
        ));
    }
    let mut scns = vec![];
    for s in 1..=3u64 {
        scns.push({
            let mut s = Scenario::paper_case(2, s, Some(0.1), Some(0.2)).as_printed();
            s.sensing.preset = sensing;
            s
        });
        scns.push({
            let mut s = Scenario::paper_case(2, s, None, None).as_printed();
            s.sensing.preset = sensing;
            s
        });
    }
    for (name, est) in &tunings {
        let res: Vec<Vec<(f64, f32, f32)>> = std::thread::scope(|sc| {
            let hs: Vec<Vec<_>> = scns
                .iter()
                .map(|scn| {
                    ControllerKind::ALL
                        .iter()
                        .map(|&k| {
                            sc.spawn(move || {
                                let o = run_hil(
                                    scn,
                                    k,
                                    HilOptions {
                                        estimator: Some(*est),
                                        ..HilOptions::default()
                                    },
                                )
                                .unwrap();
                                (
                                    o.sim.metrics.rms_pos_err_window_m,
                                    o.sensing.estimator.speed_scale,
                                    o.sensing.estimator.gyro_bias_radps,
                                )
                            })
                        })
                        .collect()
                })
                .collect();
            hs.into_iter()
                .map(|v| v.into_iter().map(|h| h.join().unwrap()).collect())
                .collect()
        });
        let mut worst_ratio: f64 = 0.0;
        let mut line = String::new();
        for r in &res {
            let ratio = r[2].0 / r[0].0.min(r[1].0);
            worst_ratio = worst_ratio.max(ratio);
            line += &format!(
                " [{:.3} {:.3} {:.3} s{:.3} b{:.4}]",
                r[0].0, r[1].0, r[2].0, r[2].1, r[2].2
            );
        }
        println!(
            "{} {:10} worst prop/best {:.4}{}",
            sensing.name(),
            name,
            worst_ratio,
            line
        );
    }
}
