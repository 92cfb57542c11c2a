//! Run metrics. Every metric's definition is here and in book/src/explanation/results.md.
//!
//! Position error = Euclidean distance between the true position of G and the
//! reference point, sampled at every control step.

use serde::{Deserialize, Serialize};

/// Error threshold for [`Metrics::settling_time_s`] \[m\].
pub const SETTLE_THRESHOLD_M: f64 = 0.1;

/// Metrics of one run (`--json` prints this object).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// RMS position error over the whole run \[m\].
    pub rms_pos_err_m: f64,
    /// RMS position error over the perturbation window \[m\].
    pub rms_pos_err_window_m: f64,
    /// Max position error over the perturbation window \[m\].
    pub max_pos_err_window_m: f64,
    /// RMS position error for t >= 5 s (after the initial transient) \[m\].
    pub rms_pos_err_after5_m: f64,
    /// Position error at the last step \[m\].
    pub final_pos_err_m: f64,
    /// First time after which the position error stays below 0.1 m until the
    /// window starts (until the end if the window is empty) \[s\]; null if never.
    pub settling_time_s: Option<f64>,
    /// RMS wheel torque over both wheels and the run \[N·m\].
    pub torque_rms_nm: f64,
    /// Max |torque| over both wheels \[N·m\].
    pub max_abs_torque_nm: f64,
    /// Chattering: total variation Σ|τ_k − τ_{k−1}| over both wheels, per second \[N·m/s\].
    pub chatter: f64,
    /// Fraction of control steps whose request exceeded the torque limit.
    pub saturated_fraction: f64,
    /// RMS of |F̂ − F| over the window, F = ε·η the injected fault
    /// (proposed controller only, else null) \[m/s and rad/s combined\].
    pub fault_est_rmse: Option<f64>,
    /// Reference governor (null with it off): how far the governed
    /// reference time τ is behind t at the end, t − τ \[s\].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_lag_final_s: Option<f64>,
    /// Smallest governor time scale s over the run (null with it off).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_time_scale: Option<f64>,
    /// Share of control steps in a degraded health mode (null with it off).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub degraded_fraction: Option<f64>,
    /// Health mode changes over the run (null with it off).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub health_transitions: Option<u32>,
    /// True when the health machine latched a safe stop (null with it off).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub safe_stop: Option<bool>,
    /// RMS over the perturbation window of the sensing error: the distance
    /// between the position of G the controller was given (the estimator's
    /// fused pose; the true one with ideal sensing) and the true position
    /// \[m\]. No controller tracks the truth better than its estimate of it:
    /// by the triangle inequality (Minkowski's, for the RMS)
    /// `rms_pos_err_window_m ≥ rms_est_err_window_m − rms(|e_xy|)` over the
    /// window. Null where the truth is unknown (a robot's log).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rms_est_err_window_m: Option<f64>,
}

/// Streaming accumulator for [`Metrics`].
#[derive(Clone, Debug, Default)]
pub struct MetricsAcc {
    n: u64,
    sq: f64,
    n_win: u64,
    sq_win: f64,
    max_win: f64,
    n_after5: u64,
    sq_after5: f64,
    last_err: f64,
    last_bad_before_window: Option<f64>,
    ever_before_window: bool,
    tau_sq: f64,
    tau_max: f64,
    tv: f64,
    prev_tau: Option<[f64; 2]>,
    n_sat: u64,
    fault_sq: f64,
    n_fault: u64,
    track_fault: bool,
    paced: bool,
    est_sq_win: f64,
    n_est_win: u64,
    lag_final: f64,
    min_scale: f64,
    n_degraded: u64,
    transitions: u32,
    safe_stop: bool,
}

impl MetricsAcc {
    /// New accumulator; `track_fault` enables `fault_est_rmse`.
    pub fn new(track_fault: bool) -> Self {
        Self {
            track_fault,
            ..Self::default()
        }
    }

    /// Adds one control step.
    #[allow(clippy::too_many_arguments)]
    pub fn push(
        &mut self,
        t: f64,
        pos_err: f64,
        in_window: bool,
        before_window: bool,
        tau: [f64; 2],
        saturated: bool,
        fault_err: f64,
    ) {
        self.n += 1;
        self.sq += pos_err * pos_err;
        if in_window {
            self.n_win += 1;
            self.sq_win += pos_err * pos_err;
            self.max_win = self.max_win.max(pos_err);
            if self.track_fault {
                self.n_fault += 1;
                self.fault_sq += fault_err * fault_err;
            }
        }
        if t >= 5.0 {
            self.n_after5 += 1;
            self.sq_after5 += pos_err * pos_err;
        }
        if before_window {
            self.ever_before_window = true;
            if pos_err >= SETTLE_THRESHOLD_M {
                self.last_bad_before_window = Some(t);
            }
        }
        self.last_err = pos_err;
        self.tau_sq += tau[0] * tau[0] + tau[1] * tau[1];
        self.tau_max = self.tau_max.max(tau[0].abs()).max(tau[1].abs());
        if let Some(p) = self.prev_tau {
            self.tv += (tau[0] - p[0]).abs() + (tau[1] - p[1]).abs();
        }
        self.prev_tau = Some(tau);
        if saturated {
            self.n_sat += 1;
        }
    }

    /// Adds the governor and health state of one control step (called
    /// only with the governor on): lag t − τ, time scale, mode, transitions.
    /// `health` is the mode's index: 0 nominal, 1 degraded, 2 safe stop
    /// (as in [`TraceSample::health`](crate::TraceSample::health)).
    pub fn push_pace(&mut self, lag_s: f64, scale: f64, health: u8, transitions: u32) {
        if !self.paced {
            self.paced = true;
            self.min_scale = scale;
        }
        self.lag_final = lag_s;
        self.min_scale = self.min_scale.min(scale);
        self.n_degraded += (health != 0) as u64;
        self.safe_stop |= health == 2;
        self.transitions = transitions;
    }

    /// One step's sensing error (the distance between the position the
    /// controller was given and the true one \[m\]); counted in the window
    /// only ([`Metrics::rms_est_err_window_m`]).
    pub fn push_estimate(&mut self, in_window: bool, est_err_m: f64) {
        if in_window {
            self.n_est_win += 1;
            self.est_sq_win += est_err_m * est_err_m;
        }
    }

    /// Final metrics for a run of `duration_s` with control period `dt_s`.
    pub fn finish(&self, duration_s: f64, dt_s: f64) -> Metrics {
        let rms = |sq: f64, n: u64| if n > 0 { (sq / n as f64).sqrt() } else { 0.0 };
        let settling = if !self.ever_before_window {
            None
        } else {
            match self.last_bad_before_window {
                None => Some(0.0),
                Some(t) if self.last_err < SETTLE_THRESHOLD_M || self.n_win > 0 => Some(t + dt_s),
                Some(_) => None,
            }
        };
        Metrics {
            rms_pos_err_m: rms(self.sq, self.n),
            rms_pos_err_window_m: rms(self.sq_win, self.n_win),
            max_pos_err_window_m: self.max_win,
            rms_pos_err_after5_m: rms(self.sq_after5, self.n_after5),
            final_pos_err_m: self.last_err,
            settling_time_s: settling,
            torque_rms_nm: rms(self.tau_sq, 2 * self.n),
            max_abs_torque_nm: self.tau_max,
            chatter: self.tv / duration_s,
            saturated_fraction: if self.n > 0 {
                self.n_sat as f64 / self.n as f64
            } else {
                0.0
            },
            fault_est_rmse: self.track_fault.then(|| rms(self.fault_sq, self.n_fault)),
            time_lag_final_s: self.paced.then_some(self.lag_final),
            min_time_scale: self.paced.then_some(self.min_scale),
            degraded_fraction: self
                .paced
                .then(|| self.n_degraded as f64 / self.n.max(1) as f64),
            health_transitions: self.paced.then_some(self.transitions),
            safe_stop: self.paced.then_some(self.safe_stop),
            rms_est_err_window_m: (self.n_est_win > 0)
                .then(|| rms(self.est_sq_win, self.n_est_win)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn definitions_on_a_synthetic_signal() {
        // Error 1 m for t < 2, then 0.05 m; window [4, 6); torque ±1 alternating.
        let dt = 0.01;
        let mut acc = MetricsAcc::new(false);
        for k in 0..1000 {
            let t = k as f64 * dt;
            let err = if t < 2.0 { 1.0 } else { 0.05 };
            let tau = if k % 2 == 0 { [1.0, -1.0] } else { [-1.0, 1.0] };
            acc.push(t, err, (4.0..6.0).contains(&t), t < 4.0, tau, k < 100, 0.0);
        }
        let m = acc.finish(10.0, dt);
        assert!((m.rms_pos_err_window_m - 0.05).abs() < 1e-12);
        assert!((m.max_pos_err_window_m - 0.05).abs() < 1e-12);
        assert!((m.rms_pos_err_m - (0.2 + 0.8 * 0.0025f64).sqrt()).abs() < 1e-9);
        assert!((m.settling_time_s.unwrap() - 2.0).abs() < 1e-9);
        assert!((m.torque_rms_nm - 1.0).abs() < 1e-12);
        // 999 transitions × 2 wheels × |Δτ| = 2, over 10 s.
        assert!((m.chatter - 999.0 * 4.0 / 10.0).abs() < 1e-9);
        assert!((m.saturated_fraction - 0.1).abs() < 1e-12);
        assert_eq!(m.fault_est_rmse, None);
    }
}
