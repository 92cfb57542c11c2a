//! The fit against an independent simulation of the model it assumes,
//! with everything the closed-loop tests cannot have yet (sim-robot has no
//! friction and one radius for both wheels): unequal wheel radii, per-wheel
//! viscous and Coulomb friction, a track and a centre-of-mass offset away
//! from the prior, quantised encoders with the runtime's 4-tick rate
//! window, PWM-quantised duties on a mirrored left motor, and noisy
//! external poses at 100 Hz. The generator below is written from the
//! equations of book/src/how-to/identification.md, not from the fit's code.

use robot_identify::{identify, FitOptions, IdRow, Prior};

struct Truth {
    m: f64,
    i: f64,
    d: f64,
    r: [f64; 2],
    h: f64,
    iw: f64,
    coulomb: [f64; 2],
    viscous: [f64; 2],
}

/// xorshift64* in (−0.5, 0.5).
fn noise(s: &mut u64) -> f64 {
    *s ^= *s >> 12;
    *s ^= *s << 25;
    *s ^= *s >> 27;
    (s.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64 - 0.5
}

/// 60 s at 1 kHz: voltages a sum of sinusoids per wheel plus a weak
/// speed feedback (keeps the robot near its start), held over each period.
fn simulate(t: &Truth, prior: &Prior, seed: u64, counts_per_rev: f64) -> Vec<IdRow> {
    let a = prior.torque_per_volt();
    let b = a * prior.emf_per_wheel_rate();
    let (vs, full) = (
        prior.motor.supply_voltage_v as f64,
        prior.motor.duty_full_scale as f64,
    );
    let inv_r2 = 1.0 / (t.r[0] * t.r[0]) + 1.0 / (t.r[1] * t.r[1]);
    let mv = t.m + t.iw * inv_r2;
    let mw = t.i + 3.0 * t.m * t.d * t.d + t.iw * t.h * t.h * inv_r2;
    let md = t.m * t.d;
    let cpr = counts_per_rev / std::f64::consts::TAU;
    let window = prior.speed_window_ticks as usize;
    // Voltage amplitude per component: a twelfth of the supply, or enough
    // for three times the Coulomb friction's torque when that is more.
    let amp = (vs / 12.0)
        .max(3.0 * t.coulomb[0].max(t.coulomb[1]) / a)
        .min(vs / 4.0);
    let dt = 1e-3;
    // State: x, y, θ of G, v, ω, φ_R, φ_L.
    let mut st = [0.0f64; 7];
    let mut hist: Vec<[f64; 2]> = Vec::new();
    let mut rows = Vec::new();
    let mut rng = seed;
    let deriv = |s: &[f64; 7], volts: [f64; 2]| -> [f64; 7] {
        let (th, v, w) = (s[2], s[3], s[4]);
        let rate = [(v + t.h * w) / t.r[0], (v - t.h * w) / t.r[1]];
        let tau: [f64; 2] = std::array::from_fn(|i| {
            a * volts[i] - (b + t.viscous[i]) * rate[i] - t.coulomb[i] * (rate[i] / 0.01).tanh()
        });
        let fv = tau[0] / t.r[0] + tau[1] / t.r[1];
        let fw = t.h * (tau[0] / t.r[0] - tau[1] / t.r[1]);
        let (sn, c) = th.sin_cos();
        [
            v * c - t.d * w * sn,
            v * sn + t.d * w * c,
            w,
            (fv + 2.0 * md * w * w) / mv,
            (fw - 2.0 * md * v * w) / mw,
            rate[0],
            rate[1],
        ]
    };
    for k in 0..60_000 {
        let time = k as f64 * dt;
        let env = (time / 3.0).min(1.0) * ((60.0 - time) / 3.0).clamp(0.0, 1.0);
        let wave = |f: [f64; 3], ph: f64| {
            f.iter()
                .enumerate()
                .map(|(j, w)| (w * time + ph + j as f64).sin())
                .sum::<f64>()
        };
        // Sum of sinusoids, minus a weak pull back toward the start.
        let pull = amp * (st[0] * st[2].cos() + st[1] * st[2].sin()) / t.r[0] * 0.1;
        let volts = [
            env * (amp * wave([1.3, 3.7, 6.1], 0.0) - pull),
            env * (amp * wave([1.1, 2.9, 5.3], 1.7) - pull),
        ];
        // Encoders (quantised, floor), the 4-tick rate window.
        let counts = [(st[5] * cpr).floor(), (st[6] * cpr).floor()];
        hist.push(counts);
        let w = window.min(hist.len() - 1).max(1);
        let rate: [f64; 2] = if hist.len() > 1 {
            std::array::from_fn(|i| {
                (counts[i] - hist[hist.len() - 1 - w][i]) / cpr / (w as f64 * dt)
            })
        } else {
            [0.0; 2]
        };
        // PWM-quantised duty; the left motor mirrored (its pin duty negated).
        let duty = [
            (volts[0] / vs * full).round(),
            -(volts[1] / vs * full).round(),
        ];
        let applied = [duty[0] * vs / full, -duty[1] * vs / full];
        let ext = k % 10 == 0;
        rows.push(IdRow {
            t_s: time,
            wheel_rate_radps: rate,
            duty,
            torque_nm: [a * applied[0] - b * rate[0], a * applied[1] - b * rate[1]],
            pose: [
                st[0] + 0.002 * noise(&mut rng),
                st[1] + 0.002 * noise(&mut rng),
                st[2] + 0.002 * noise(&mut rng),
            ],
            external_pose: ext,
            saturated: false,
        });
        // RK4 over the period with the duty held.
        let add = |s: &[f64; 7], d: &[f64; 7], h: f64| -> [f64; 7] {
            std::array::from_fn(|i| s[i] + h * d[i])
        };
        let k1 = deriv(&st, applied);
        let k2 = deriv(&add(&st, &k1, 0.5 * dt), applied);
        let k3 = deriv(&add(&st, &k2, 0.5 * dt), applied);
        let k4 = deriv(&add(&st, &k3, dt), applied);
        st =
            std::array::from_fn(|i| st[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]));
    }
    rows
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// Every parameter within the acceptance margins: mass 5 %, inertia 10 %,
/// radii 0.5 %, track 1 %, friction and EMF constant 20 %.
#[test]
fn recovers_friction_unequal_radii_and_track_from_the_model() {
    let prior = Prior::paper();
    for (seed, t) in [
        (
            1u64,
            Truth {
                m: 12.0,
                i: 1.8,
                d: 0.03,
                r: [0.1003, 0.0995],
                h: 0.21,
                iw: 0.001,
                coulomb: [0.15, 0.10],
                viscous: [0.02, 0.03],
            },
        ),
        (
            2,
            Truth {
                m: 20.0,
                i: 3.5,
                d: 0.06,
                r: [0.0990, 0.1008],
                h: 0.19,
                iw: 0.001,
                coulomb: [0.30, 0.25],
                viscous: [0.05, 0.04],
            },
        ),
    ] {
        let rows = simulate(&t, &prior, seed, 24_000.0);
        let id = identify(&rows, &prior, &FitOptions::default()).unwrap();
        let text = robot_identify::report::text(&id, &prior);
        let d = id.dynamics.as_ref().unwrap();
        println!("seed {seed}:\n{text}");
        assert!(rel(d.mass_kg.value, t.m) < 0.05, "{text}");
        assert!(rel(d.inertia_kgm2.value, t.i) < 0.10, "{text}");
        for w in 0..2 {
            assert!(rel(id.wheel_radius_m[w].value, t.r[w]) < 0.005, "{text}");
            assert!(rel(d.coulomb_nm[w].value, t.coulomb[w]) < 0.2, "{text}");
            assert!(
                rel(d.viscous_nms_per_rad[w].value, t.viscous[w]) < 0.2,
                "{text}"
            );
            let kappa = prior.emf_per_wheel_rate() + t.viscous[w] / prior.torque_per_volt();
            assert!(
                rel(d.emf_vs_per_rad.unwrap()[w].value, kappa) < 0.2,
                "{text}"
            );
        }
        assert!(rel(id.half_track_m.value, t.h) < 0.01, "{text}");
        assert!(!id.track_from_prior);
    }
}

/// The example robots of robots/ as priors, each simulated with its body
/// 10 % heavier, 15 % less inertia, the wheels 0.3 % apart and its own
/// friction (its encoders' resolution and rate window, its motor and
/// supply): the fit meets every margin, and its robot file output is a
/// valid robot file carrying the identified values.
#[test]
fn example_robots_are_identified_and_written_back() {
    for (name, seed) in [("tb6612-2kg", 11u64), ("bts7960-10kg", 12), ("paper", 13)] {
        let path = format!("{}/../robots/{name}.toml", env!("CARGO_MANIFEST_DIR"));
        let file =
            robot_file::Robot::from_toml_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let prior = Prior::from_robot(&file, 96_000_000).unwrap();
        let b = &file.body;
        let m = &file.motors;
        let r0 = b.wheel_radius_m[0] as f64;
        let t = Truth {
            m: 1.1 * b.mass_kg as f64,
            i: 0.85 * b.inertia_kgm2 as f64,
            d: b.com_offset_m as f64,
            r: [r0 * 1.0015, r0 * 0.9985],
            h: 0.5 * b.track_m as f64,
            iw: b.wheel_inertia_kgm2 as f64,
            // The paper file has none: give it some.
            coulomb: m
                .coulomb_friction_nm
                .map(|c| if c > 0.0 { c as f64 } else { 0.2 }),
            viscous: m
                .viscous_friction_nms_per_rad
                .map(|c| if c > 0.0 { c as f64 } else { 0.02 }),
        };
        let rows = simulate(&t, &prior, seed, file.encoders.counts_per_wheel_rev as f64);
        let id = identify(&rows, &prior, &FitOptions::default()).unwrap();
        let text = robot_identify::report::text(&id, &prior);
        println!("{name}:\n{text}");
        let d = id.dynamics.as_ref().unwrap();
        assert!(rel(d.mass_kg.value, t.m) < 0.05, "{name}\n{text}");
        assert!(rel(d.inertia_kgm2.value, t.i) < 0.10, "{name}\n{text}");
        assert!(rel(id.half_track_m.value, t.h) < 0.01, "{name}\n{text}");
        for w in 0..2 {
            assert!(
                rel(id.wheel_radius_m[w].value, t.r[w]) < 0.005,
                "{name}\n{text}"
            );
            assert!(
                rel(d.coulomb_nm[w].value, t.coulomb[w]) < 0.2,
                "{name}\n{text}"
            );
            // Within 20 %, or reported as not identified. Where it is
            // reported so, the viscous friction is a small fraction of the
            // motor's own back-EMF damping a·N·k, with which it shares the
            // regressor φ̇: the 2 kg robot's 0.0005 N·m·s/rad is 4 % of it,
            // the 10 kg robot's 0.02 about 1 % (book/src/how-to/identification.md has
            // the numbers; the latter's interval misses the truth).
            let e = d.viscous_nms_per_rad[w];
            let flagged = id
                .notes
                .iter()
                .any(|n| n.contains(["viscous friction right", "viscous friction left"][w]));
            assert!(
                rel(e.value, t.viscous[w]) < 0.2 || flagged,
                "{name}: viscous {e:?} vs {}\n{text}",
                t.viscous[w]
            );
            if flagged {
                println!(
                    "{name}: viscous friction {w}: {e:.5} for {:.5}: reported as not identified",
                    t.viscous[w]
                );
            }
        }
        let (out, _) = robot_identify::report::robot_file(&id, &prior, &file).unwrap();
        let back = robot_file::Robot::from_toml_str(&out).unwrap();
        assert!((back.body.mass_kg as f64 - d.mass_kg.value).abs() < 1e-4 * t.m);
        assert_eq!(back.bridge, file.bridge);
        assert!(rel(back.motors.coulomb_friction_nm[0] as f64, t.coulomb[0]) < 0.2);
    }
}
