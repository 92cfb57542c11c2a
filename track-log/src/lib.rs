//! # track-log
//!
//! The one tracking-log format of the project: [`TraceSample`] rows, their
//! CSV ([`csv`]: `hil-sim run --csv` and `wmr record` write the same
//! columns) and the run [`metrics`] computed from every control step of a
//! simulation or from the rows of any log (`hil-sim report FILE.csv`,
//! `wmr record`'s summary).
#![deny(missing_docs)]

pub mod csv;
pub mod metrics;
pub mod report;

pub use metrics::{Metrics, MetricsAcc};
pub use report::{log_report, HealthShare, LogReport};
use serde::Serialize;

/// One logged sample (decimated) for plots and CSV.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct TraceSample {
    /// Time \[s\].
    pub t_s: f64,
    /// Reference x_s, y_s, θ_s.
    pub ref_pose: [f64; 3],
    /// True pose of G.
    pub pose: [f64; 3],
    /// Position error \[m\].
    pub pos_err_m: f64,
    /// World-frame error \[x_s − x, y_s − y\] \[m\].
    pub err_xy_m: [f64; 2],
    /// Controller's tracking error \[e_x, e_y, e_θ\].
    pub e: [f64; 3],
    /// Measured η \[v, ω\].
    pub eta: [f64; 2],
    /// η_c \[v_c, ω_c\].
    pub eta_c: [f64; 2],
    /// Applied torque \[right, left\] \[N·m\].
    pub torque_nm: [f64; 2],
    /// Sliding variable s.
    pub s: [f64; 2],
    /// ρ̂ (K for SMC).
    pub rho_hat: [f64; 2],
    /// D̂ = x̂3.
    pub d_hat: [f64; 2],
    /// F̂ = \[Δv̂, Δω̂\].
    pub f_hat: [f64; 2],
    /// Injected fault F = ε·η.
    pub f_true: [f64; 2],
    /// Saturation flag.
    pub saturated: bool,
    /// Governor time scale s (1 = nominal speed; 1 throughout with pacing off).
    pub time_scale: f64,
    /// Reference time τ \[s\] the step tracked (t with pacing off).
    pub tau_s: f64,
    /// Health mode: 0 nominal, 1 degraded, 2 safe stop.
    pub health: u8,
    /// Reason published with the health mode (`HealthReason` as its index:
    /// 0 none, 1 saturation, 2 tracking error, 3 actuator fault,
    /// 4 disturbance, 5 adaptation limit, 6 estimator, 7 lost path,
    /// 8 controller fault).
    pub health_reason: u8,
}

/// Metrics of a logged trace, row by row through [`MetricsAcc`] (the same
/// accumulator a simulation feeds at every control step): the rows' own
/// spacing is the step. `window_s` is the perturbation window (`[0, 0]`:
/// none, e.g. a robot log); `track_fault` enables the fault-estimate
/// metric (needs `f_true`). `None` for fewer than two rows.
pub fn metrics_from_trace(
    trace: &[TraceSample],
    window_s: [f64; 2],
    track_fault: bool,
) -> Option<Metrics> {
    let n = trace.len();
    if n < 2 {
        return None;
    }
    let dt = (trace[n - 1].t_s - trace[0].t_s) / (n - 1) as f64;
    if !(dt.is_finite() && dt > 0.0) {
        return None;
    }
    let mut acc = MetricsAcc::new(track_fault);
    let no_window = window_s[0] >= window_s[1];
    for s in trace {
        let t = s.t_s;
        let fe = ((s.f_hat[0] - s.f_true[0]).powi(2) + (s.f_hat[1] - s.f_true[1]).powi(2)).sqrt();
        acc.push(
            t,
            s.pos_err_m,
            !no_window && t >= window_s[0] && t < window_s[1],
            no_window || t < window_s[0],
            s.torque_nm,
            s.saturated,
            fe,
        );
    }
    Some(acc.finish(n as f64 * dt, dt))
}

/// Names of the health reasons by index ([`TraceSample::health_reason`],
/// `HealthReason` in controller-core).
pub const HEALTH_REASONS: [&str; 9] = [
    "none",
    "saturation",
    "tracking error",
    "actuator fault",
    "disturbance",
    "adaptation limit",
    "estimator",
    "lost path",
    "controller fault",
];
