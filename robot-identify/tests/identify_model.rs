//! The fit against an independent simulation of the model it assumes,
//! with everything the closed-loop tests cannot have yet (sim-robot has no
//! friction and one radius for both wheels): unequal wheel radii, per-wheel
//! viscous and Coulomb friction, a track and a centre-of-mass offset away
//! from the prior, quantised encoders with the runtime's 4-tick rate
//! window, PWM-quantised duties on a mirrored left motor, and noisy
//! external poses at 100 Hz. The generator below is written from the
//! equations of docs/identification.md, not from the fit's code.

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
fn simulate(t: &Truth, prior: &Prior, seed: u64) -> Vec<IdRow> {
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
    let cpr = 24_000.0 / std::f64::consts::TAU;
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
        let pull = 2.0 * (st[0] * st[2].cos() + st[1] * st[2].sin());
        let volts = [
            env * (2.0 * wave([1.3, 3.7, 6.1], 0.0) - pull),
            env * (2.0 * wave([1.1, 2.9, 5.3], 1.7) - pull),
        ];
        // Encoders (quantised, floor), the 4-tick rate window.
        let counts = [(st[5] * cpr).floor(), (st[6] * cpr).floor()];
        hist.push(counts);
        let w = 4.min(hist.len() - 1).max(1);
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
        let rows = simulate(&t, &prior, seed);
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
