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
/// Eqs. (22)-(24): adaptation rate γ and the bound ρ_max.
const ADAPTIVE: [Dim; 2] = [
    dim("sliding.switching.adaptive.gamma", 0.005, 5.0),
    dim("sliding.switching.adaptive.rho_max", 0.5, 30.0),
];
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
        }
    }
    v
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

/// The gains of `c` as a point of the unit box (each clamped to its range).
pub fn encode(c: &ControllerConfig) -> Vec<f64> {
    let g = gains_of(c);
    dims(c.kind)
        .iter()
        .zip(g)
        .map(|(d, x)| to_u(d, f64::from(x)))
        .collect()
}

/// The tuned gains of `c` in [`dims`] order.
pub fn gains_of(c: &ControllerConfig) -> Vec<f32> {
    let mut v = vec![
        c.kinematic.k_x,
        c.kinematic.k_y,
        c.kinematic.k_th,
        c.sliding.k_s,
    ];
    match c.sliding.switching {
        Switching::Fixed(k) => v.push(k),
        Switching::Adaptive(a) => v.extend([a.gamma, a.rho_max]),
    }
    if c.kind == ControllerKind::Proposed {
        v.extend(c.eso.lambda);
        v.extend([c.fault_observer.l_v, c.fault_observer.l_omega]);
    }
    v
}

/// `base` with the tuned gains set from `u` (clamped into the unit box;
/// ρ0 lowered to ρ_max when above it, so ρ_min ≤ ρ0 ≤ ρ_max holds).
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
            a.rho0 = a.rho0.min(a.rho_max);
            a.rho_min = a.rho_min.min(a.rho0);
            Switching::Adaptive(a)
        }
    };
    if c.kind == ControllerKind::Proposed {
        c.eso.lambda = [g[6], g[7], g[8]];
        c.fault_observer.l_v = g[9];
        c.fault_observer.l_omega = g[10];
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
                for (a, b) in back.iter().zip(&x) {
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
