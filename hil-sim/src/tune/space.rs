//! The tuned gains of each controller and their bounds (D90).
//!
//! Every tuned gain is positive and spans one or more decades, so the
//! optimiser works in normalised coordinates: u ∈ \[0, 1\] per gain,
//! g = lo·(hi/lo)^u (log scale). A point outside the unit box is clamped
//! into it before it is decoded, so every configuration that reaches a
//! simulation satisfies the bounds; the cost adds the squared distance to
//! the box ([`box_penalty`]) so the optimiser is pushed back inside.
//!
//! The bounds keep the laws valid: positivity (what
//! `ControllerConfig::validate` requires) at the low end, and at the high
//! end a rate times the 1 ms control period small enough for the discrete
//! loop (k_s·T ≤ 0.1, l·T ≤ 0.05, λ1·ζ^(α−1)·T ≤ 0.5 with the fal slope of
//! the default ζ = 0.1, α = 0.01). Gains not listed (ζ, α, the clamps, the
//! adaptation's dead zone, leakage and ρ_min, the large-error bound) keep
//! the robot file's values.

use controller_core::asmc::Switching;
use controller_core::{ControllerConfig, ControllerKind};

/// One tuned gain: its name (the robot file's key under `[gains.<kind>]`)
/// and its range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dim {
    /// Robot-file key (e.g. `kinematic.k_x`).
    pub name: &'static str,
    /// Smallest value.
    pub lo: f64,
    /// Largest value.
    pub hi: f64,
}

const fn dim(name: &'static str, lo: f64, hi: f64) -> Dim {
    Dim { name, lo, hi }
}

/// Eq. (14): k_x \[1/s\], k_y \[rad/m²\], k_th \[1/s\].
const KINEMATIC: [Dim; 3] = [
    dim("kinematic.k_x", 0.2, 10.0),
    dim("kinematic.k_y", 1.0, 400.0),
    dim("kinematic.k_th", 0.5, 30.0),
];
/// Eq. (20): k_s \[1/s\], k_s·T ≤ 0.1.
const K_S: Dim = dim("sliding.k_s", 0.5, 100.0);
/// Plain SMC's fixed switching gain K.
const K_FIXED: Dim = dim("sliding.switching.fixed.k", 0.05, 20.0);
/// Eqs. (22)-(24): adaptation rate γ, the bound ρ_max and ρ0 (the
/// initial ρ̂ and the leakage's target) as a fraction of ρ_max. At
/// ρ0 = ρ_max, ρ̂ stays at ρ_max whatever s does (adaptation is clipped
/// at ρ_max, leakage pulls back to it): the law is plain SMC with
/// K = ρ_max, so the ASMC's and the proposed controller's boxes hold the
/// SMC's exactly ([`embed_smc`], issue 34).
const ADAPTIVE: [Dim; 3] = [
    dim("sliding.switching.adaptive.gamma", 0.005, 5.0),
    dim("sliding.switching.adaptive.rho_max", 0.5, 30.0),
    dim(RHO0_FRACTION, 1e-3, 1.0),
];
/// Name of ρ0 as a fraction of ρ_max.
pub const RHO0_FRACTION: &str = "sliding.switching.adaptive.rho0 (fraction of rho_max)";
/// Eq. (18): λ1, λ2, λ3.
const ESO: [Dim; 3] = [
    dim("eso.lambda[0]", 2.0, 50.0),
    dim("eso.lambda[1]", 2.0, 100.0),
    dim("eso.lambda[2]", 2.0, 150.0),
];
/// Eq. (13): l_v, l_ω \[1/s\], l·T ≤ 0.05.
const OBSERVER: [Dim; 2] = [
    dim("observer.l_v", 0.5, 50.0),
    dim("observer.l_omega", 0.5, 50.0),
];
/// The authority of the ESO and of the fault observer (D166, D212): the
/// scale of their clamps (`eso.max_disturbance`, `observer.max_estimate`)
/// against the robot file's, log-scaled from [`AUTHORITY_MIN`] to 1, and
/// exactly 0 at the low end of the box (the coordinate 0, where every
/// point outside the box is clamped to): the clamps are then 0, D̂ and F̂
/// are 0 and the proposed controller is ASMC term for term, so its box
/// holds the ASMC's (issue 34: the baselines are special cases).
const AUTHORITY: [Dim; 2] = [
    dim(ESO_AUTHORITY, AUTHORITY_MIN, 1.0),
    dim(OBSERVER_AUTHORITY, AUTHORITY_MIN, 1.0),
];
/// Name of the ESO's authority (the scale of `eso.max_disturbance`).
pub const ESO_AUTHORITY: &str = "eso.max_disturbance (scale)";
/// Name of the fault observer's authority (the scale of
/// `observer.max_estimate`).
pub const OBSERVER_AUTHORITY: &str = "observer.max_estimate (scale)";
/// Smallest authority scale above off: the paper's clamps (20, 40 m/s²;
/// 1.5, 2 m/s) become 0.2, 0.4 m/s² and 0.015, 0.02 m/s, estimates that
/// still act, so a search at the off end sees the cost change as soon as
/// it steps inside the box (with D166's 1e-7 floor, needed while a clamp
/// could not be 0, 70 % of the range was a flat plateau).
pub const AUTHORITY_MIN: f64 = 1e-2;

/// The tuned gains of `kind`, in the order of the optimiser's vector.
pub fn dims(kind: ControllerKind) -> Vec<Dim> {
    let mut v = KINEMATIC.to_vec();
    v.push(K_S);
    match kind {
        ControllerKind::Smc => v.push(K_FIXED),
        ControllerKind::Asmc => v.extend(ADAPTIVE),
        ControllerKind::Proposed => {
            v.extend(ADAPTIVE);
            v.extend(ESO);
            v.extend(OBSERVER);
            v.extend(AUTHORITY);
        }
    }
    v
}

/// Index of the first gain after the kinematic law and k_s (the switching
/// gain: SMC's K, or ASMC's and the proposed controller's γ).
const SWITCHING: usize = 4;

/// True when an authority coordinate `u` switches its estimate off: the
/// box's low end and below (a NaN decodes as the box's middle, as every
/// gain does).
pub fn authority_off(u: f64) -> bool {
    u <= 0.0
}

/// True for a gain given relative to another one or to the robot file's
/// (the authorities, ρ0's fraction): its top is the reference itself,
/// not a limit worth flagging.
pub fn is_relative(d: &Dim) -> bool {
    d.name.ends_with(')')
}

/// The ASMC point `asmc` (unit box of [`dims`]`(Asmc)`) embedded in the
/// proposed controller's box: the same kinematic and sliding gains, the
/// ESO's and the fault observer's gains of `proposed` (a point of the
/// proposed controller's box), and both authorities at their low end (the
/// estimates off, D166).
pub fn embed_asmc(asmc: &[f64], proposed: &[f64]) -> Vec<f64> {
    let n = dims(ControllerKind::Proposed).len();
    assert_eq!(asmc.len(), dims(ControllerKind::Asmc).len(), "ASMC point");
    assert_eq!(proposed.len(), n, "proposed point");
    let mut x = proposed.to_vec();
    x[..asmc.len()].copy_from_slice(asmc);
    x[n - 2] = 0.0;
    x[n - 1] = 0.0;
    x
}

/// The SMC point `smc` embedded in the box of `into` (a point of the
/// ASMC's or of the proposed controller's box): the same kinematic gains
/// and k_s, ρ_max = K and ρ0 = ρ_max, so ρ̂ ≡ K (the law is SMC's, up to
/// K's f32 rounding through the two ranges); γ at its low end; in the
/// proposed controller's box, its other gains from `into` and both
/// authorities at their low end (the estimates off).
pub fn embed_smc(smc: &[f64], into: &[f64]) -> Vec<f64> {
    assert_eq!(smc.len(), dims(ControllerKind::Smc).len(), "SMC point");
    let n = into.len();
    let proposed = n == dims(ControllerKind::Proposed).len();
    assert!(
        proposed || n == dims(ControllerKind::Asmc).len(),
        "an ASMC or proposed point"
    );
    let mut x = into.to_vec();
    x[..SWITCHING].copy_from_slice(&smc[..SWITCHING]);
    let k = f64::from(from_u(&K_FIXED, smc[SWITCHING]));
    x[SWITCHING] = 0.0;
    x[SWITCHING + 1] = to_u(&ADAPTIVE[1], k);
    x[SWITCHING + 2] = 1.0;
    if proposed {
        x[n - 2] = 0.0;
        x[n - 1] = 0.0;
    }
    x
}

fn to_u(d: &Dim, g: f64) -> f64 {
    ((g.ln() - d.lo.ln()) / (d.hi.ln() - d.lo.ln())).clamp(0.0, 1.0)
}

fn from_u(d: &Dim, u: f64) -> f32 {
    let u = if u.is_finite() {
        u.clamp(0.0, 1.0)
    } else {
        0.5
    };
    (d.lo.ln() + u * (d.hi.ln() - d.lo.ln())).exp() as f32
}

/// The gains of `c` as a point of the unit box (each clamped to its range;
/// the authorities are relative to `c`'s own clamps: 1; ρ0 as its
/// fraction of ρ_max).
pub fn encode(c: &ControllerConfig) -> Vec<f64> {
    let g = gains_of(c);
    dims(c.kind)
        .iter()
        .zip(g)
        .map(|(d, x)| to_u(d, f64::from(x)))
        .collect()
}

/// The gain of `d` at the unit-box coordinate `u` (clamped into the box).
pub fn value(d: &Dim, u: f64) -> f64 {
    f64::from(from_u(d, u))
}

/// The tuned gains of `c` in [`dims`] order (the authorities: 1, `c`'s
/// own clamps).
pub fn gains_of(c: &ControllerConfig) -> Vec<f32> {
    let mut v = vec![
        c.kinematic.k_x,
        c.kinematic.k_y,
        c.kinematic.k_th,
        c.sliding.k_s,
    ];
    match c.sliding.switching {
        Switching::Fixed(k) => v.push(k),
        Switching::Adaptive(a) => v.extend([a.gamma, a.rho_max, a.rho0 / a.rho_max]),
    }
    if c.kind == ControllerKind::Proposed {
        v.extend(c.eso.lambda);
        v.extend([c.fault_observer.l_v, c.fault_observer.l_omega]);
        v.extend([1.0, 1.0]);
    }
    v
}

/// `base` with the tuned gains set from `u` (clamped into the unit box;
/// ρ0 = fraction·ρ_max, never above ρ_max, and ρ_min lowered to ρ0 when
/// above it, so ρ_min ≤ ρ0 ≤ ρ_max holds).
/// `u.len()` must be `dims(base.kind).len()`.
pub fn decode(base: &ControllerConfig, u: &[f64]) -> ControllerConfig {
    let d = dims(base.kind);
    assert_eq!(u.len(), d.len(), "gain vector of the wrong length");
    let g: Vec<f32> = d.iter().zip(u).map(|(d, &u)| from_u(d, u)).collect();
    let mut c = *base;
    c.kinematic.k_x = g[0];
    c.kinematic.k_y = g[1];
    c.kinematic.k_th = g[2];
    c.sliding.k_s = g[3];
    c.sliding.switching = match c.sliding.switching {
        Switching::Fixed(_) => Switching::Fixed(g[4]),
        Switching::Adaptive(mut a) => {
            a.gamma = g[4];
            a.rho_max = g[5];
            a.rho0 = (g[5] * g[6]).min(a.rho_max);
            a.rho_min = a.rho_min.min(a.rho0);
            Switching::Adaptive(a)
        }
    };
    if c.kind == ControllerKind::Proposed {
        c.eso.lambda = [g[7], g[8], g[9]];
        c.fault_observer.l_v = g[10];
        c.fault_observer.l_omega = g[11];
        // The box's low end is off (module doc of AUTHORITY).
        let off = |i: usize| authority_off(u[i]);
        let scaled = |m: [f32; 2], i: usize| m.map(|x| if off(i) { 0.0 } else { x * g[i] });
        c.eso.max_disturbance = scaled(c.eso.max_disturbance, 12);
        c.fault_observer.max_estimate = scaled(c.fault_observer.max_estimate, 13);
    }
    c
}

/// Squared distance of `x` to the unit box (0 inside).
pub fn box_penalty(x: &[f64]) -> f64 {
    x.iter()
        .map(|&v| {
            let c = v.clamp(0.0, 1.0);
            (v - c) * (v - c)
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_are_valid_gains_and_round_trip() {
        for kind in ControllerKind::ALL {
            let base = ControllerConfig::paper(kind);
            for u in [0.0, 0.37, 1.0] {
                let x = vec![u; dims(kind).len()];
                let c = decode(&base, &x);
                c.validate()
                    .expect("every point of the box is a valid configuration");
                let back = encode(&c);
                let d = dims(kind);
                for ((a, b), d) in back.iter().zip(&x).zip(&d) {
                    // An authority is relative to the configuration's own
                    // clamps: encoded, it is always 1 (the box's top).
                    let b = if d.name.ends_with("(scale)") { 1.0 } else { *b };
                    assert!((a - b).abs() < 1e-5, "{kind:?}: {a} vs {b}");
                }
            }
            // Outside the box: clamped, still valid.
            let far = vec![7.0; dims(kind).len()];
            decode(&base, &far).validate().unwrap();
            assert!(box_penalty(&far) > 0.0);
            assert_eq!(box_penalty(&[0.5; 3]), 0.0);
        }
    }

    #[test]
    fn discrete_rate_bounds_hold_at_1_ms() {
        let t = 1e-3;
        assert!(K_S.hi * t <= 0.1);
        for d in OBSERVER {
            assert!(d.hi * t <= 0.05);
        }
        let e = controller_core::eso::EsoParams::DEFAULT;
        assert!(ESO[0].hi * f64::from(e.fal_slope()) * t <= 0.5);
    }

    #[test]
    fn the_asmc_point_embedded_is_asmc_with_the_estimates_bounded_near_zero() {
        let (a, p) = (
            ControllerConfig::paper(ControllerKind::Asmc),
            ControllerConfig::paper(ControllerKind::Proposed),
        );
        let xa = vec![0.3, 0.6, 0.2, 0.7, 0.4, 0.55, 0.5];
        let e = decode(&p, &embed_asmc(&xa, &encode(&p)));
        let da = decode(&a, &xa);
        assert_eq!(e.kinematic, da.kinematic);
        assert_eq!(e.sliding.k_s, da.sliding.k_s);
        assert_eq!(e.sliding.switching, da.sliding.switching);
        // D̂ and F̂ are clamped to a few 1e-6: the compensation is off.
        for m in e
            .eso
            .max_disturbance
            .into_iter()
            .chain(e.fault_observer.max_estimate)
        {
            assert_eq!(m, 0.0, "the estimates are off");
        }
        e.validate().unwrap();
        // The SMC point: K becomes ρ_max and ρ0 = ρ_max, γ slowest.
        let xs = vec![0.3, 0.6, 0.2, 0.7, to_u(&K_FIXED, 3.0)];
        let es = decode(&p, &embed_smc(&xs, &encode(&p)));
        let Switching::Adaptive(ad) = es.sliding.switching else {
            panic!("adaptive")
        };
        assert!((ad.rho_max - 3.0).abs() < 1e-4 && ad.rho0 == ad.rho_max);
        assert_eq!(ad.gamma as f64, ADAPTIVE[0].lo as f32 as f64);
        es.validate().unwrap();
    }

    /// SMC is a special case of ASMC and of the proposed controller
    /// (issue 34): the tuned SMC point embedded in their boxes runs the
    /// same closed loop as SMC itself, under the paper's Case 2 (slip,
    /// fault, disturbance, saturation) behind the firmware runtime. An
    /// independent reason: ρ̂ clipped at ρ_max and leaking to ρ0 = ρ_max
    /// never leaves K, so eq. (24) is term for term SMC's.
    #[test]
    fn smc_embedded_in_the_adaptive_boxes_runs_as_smc() {
        use crate::scenario::{Scenario, Sensing};
        let mut s = Scenario::paper_case(2, 3, None, None).with_sensing(Sensing::Imu);
        s.duration_s = 20.0;
        s.plant.torque_limit_nm = Some(2.0);
        let xs = vec![0.55, 0.4, 0.6, 0.5, to_u(&K_FIXED, 4.0)];
        let smc = decode(&s.controller_config(ControllerKind::Smc), &xs);
        let run = |c: ControllerConfig| crate::sim::run_with(&s, c, 0).unwrap().metrics;
        let m0 = run(smc);
        assert!(m0.saturated_fraction > 0.0, "the case saturates");
        for kind in [ControllerKind::Asmc, ControllerKind::Proposed] {
            let base = s.controller_config(kind);
            let c = decode(&base, &embed_smc(&xs, &encode(&base)));
            let m = run(c);
            let rel = (m.rms_pos_err_window_m / m0.rms_pos_err_window_m - 1.0).abs();
            // K's f32 rounding through the two ranges only.
            assert!(
                rel < 1e-4,
                "{kind:?}: window RMS {} vs SMC {} ({rel:.2e})",
                m.rms_pos_err_window_m,
                m0.rms_pos_err_window_m
            );
            assert!((m.saturated_fraction - m0.saturated_fraction).abs() < 1e-3);
        }
        // ASMC in the proposed controller's box: the same f32 gains, D̂
        // and F̂ clamped to 0, so the very same run.
        let xa = vec![0.5, 0.45, 0.55, 0.5, 0.6, 0.5, 0.3];
        let asmc = run(decode(&s.controller_config(ControllerKind::Asmc), &xa));
        let base = s.controller_config(ControllerKind::Proposed);
        let prop = run(decode(&base, &embed_asmc(&xa, &encode(&base))));
        assert_eq!(asmc.rms_pos_err_window_m, prop.rms_pos_err_window_m);
        assert_eq!(asmc.saturated_fraction, prop.saturated_fraction);
    }

    #[test]
    fn paper_gains_lie_inside_the_box() {
        for kind in ControllerKind::ALL {
            let c = ControllerConfig::paper(kind);
            for (d, g) in dims(kind).iter().zip(gains_of(&c)) {
                let g = f64::from(g);
                assert!(d.lo <= g && g <= d.hi, "{kind:?} {}: {g}", d.name);
            }
        }
    }
}
