//! Reference governor (time scaling): the reference's clock τ advances at
//! s·Δt per control period with the time scale s ∈ \[0, 1\], so the robot
//! follows the same path more slowly (and may stop on it) instead of leaving
//! it when the wheels saturate or the tracking error grows. Not in the paper
//! (book/src/explanation/decisions.md, D22).
//!
//! The controller tracks r(τ) with derivatives consistent with the scaled
//! clock (τ̇ = s):
//!
//! * pose: the curve's pose at τ;
//! * v = s·v_s(τ), ω = s·ω_s(τ);
//! * v̇ = ṡ·v_s(τ) + s²·v̇_s(τ), ω̇ = ṡ·ω_s(τ) + s²·ω̇_s(τ).
//!
//! The target scale is the smallest of three: one falling linearly from 1 to
//! 0 as the (filtered) saturation ratio peak|τ_request|/τ_limit rises from
//! `saturation_start` to `saturation_stop`; one falling from 1 to
//! `error_min_scale` as the squared position error rises from
//! `error_start_m`² to `error_stop_m`² (squares: no `sqrt` per tick; never to 0: a unicycle cannot remove a lateral error
//! while its reference stands still, so a zero floor could deadlock); and
//! the cap the health machine sets ([`crate::health`]). s approaches the
//! target at `gain_per_s`, its rate limited to `max_decrease_per_s` down and
//! `max_increase_per_s` up, and is never above 1 (never faster than nominal).
//!
//! τ is kept as whole periods plus a fraction of one (`ticks`, `frac`) so
//! that it does not drift in `f32` over a long run, and so that at s = 1
//! throughout τ = ticks·Δt exactly as the runtime's unscaled clock.
//!
//! Per tick: a handful of multiplies and compares, no `sqrt`, no
//! transcendental.

use crate::error::ConfigError;
use crate::math::{all_non_negative, all_positive};
use crate::trajectory::{RefSample, Trajectory};

/// Parameters of the time-scaling governor (validated by [`Governor::new`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GovernorParams {
    /// Filtered saturation ratio at which the reference starts slowing down.
    pub saturation_start: f32,
    /// Filtered saturation ratio at which the target scale reaches 0.
    pub saturation_stop: f32,
    /// Time constant of the saturation-ratio filter \[s\].
    pub saturation_filter_s: f32,
    /// Position error at which the reference starts slowing down \[m\].
    pub error_start_m: f32,
    /// Position error at which the error target reaches `error_min_scale` \[m\].
    pub error_stop_m: f32,
    /// Lowest scale the tracking error alone asks for (in (0, 1]).
    pub error_min_scale: f32,
    /// Rate at which s approaches its target \[1/s\].
    pub gain_per_s: f32,
    /// Largest decrease of s per second \[1/s\].
    pub max_decrease_per_s: f32,
    /// Largest increase of s per second \[1/s\] (smooth recovery).
    pub max_increase_per_s: f32,
}

impl GovernorParams {
    /// The defaults (also [`Default::default`]); a constant so that
    /// configurations built from it are data, not code.
    pub const DEFAULT: Self = Self {
        saturation_start: 0.9,
        saturation_stop: 1.5,
        saturation_filter_s: 0.02,
        error_start_m: 0.5,
        error_stop_m: 1.5,
        error_min_scale: 0.2,
        gain_per_s: 10.0,
        max_decrease_per_s: 1.0,
        max_increase_per_s: 0.5,
    };
}

impl Default for GovernorParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl GovernorParams {
    /// Checks every field.
    pub fn validate(self) -> Result<Self, ConfigError> {
        // Orderings as positive differences (see HealthParams::validate).
        let ok = all_positive(&[
            self.saturation_start,
            self.saturation_stop,
            self.saturation_stop - self.saturation_start,
            self.error_start_m,
            self.error_stop_m,
            self.error_stop_m - self.error_start_m,
            self.error_min_scale,
            self.gain_per_s,
            self.max_decrease_per_s,
            self.max_increase_per_s,
        ]) && all_non_negative(&[self.saturation_filter_s, 1.0 - self.error_min_scale]);
        if ok {
            Ok(self)
        } else {
            Err(ConfigError::InvalidGovernor)
        }
    }
}

/// What the governor reads each tick (from the controller step just run and
/// the health machine).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GovernorInput {
    /// peak |torque request| / torque limit of the step (>= 0; 0 when unknown).
    pub saturation_ratio: f32,
    /// Squared position error e_x² + e_y² \[m²\].
    pub position_error_sq_m2: f32,
    /// Upper bound on s from the health machine, in \[0, 1\].
    pub speed_cap: f32,
}

/// State of the governor: the scaled clock and the time scale.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GovernorState {
    /// Whole control periods of reference time.
    pub ticks: u32,
    /// Fraction of a period of reference time, in \[0, 1).
    pub frac: f32,
    /// Time scale s ∈ \[0, 1\].
    pub scale: f32,
    /// ds/dt over the last period \[1/s\].
    pub scale_rate_per_s: f32,
    /// Filtered saturation ratio.
    pub saturation_filtered: f32,
}

impl Default for GovernorState {
    fn default() -> Self {
        Self {
            ticks: 0,
            frac: 0.0,
            scale: 1.0,
            scale_rate_per_s: 0.0,
            saturation_filtered: 0.0,
        }
    }
}

/// The governor's validated parameters and derived constants; the state is
/// passed to each call.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Governor {
    params: GovernorParams,
    period_s: f32,
    /// 1/Δt.
    inv_period: f32,
    /// Filter coefficient Δt/(T + Δt).
    alpha: f32,
    inv_sat_span: f32,
    /// e_start², 1/(e_stop² − e_start²).
    err_start_sq_m2: f32,
    inv_err_span_m2: f32,
}

/// Saturation ratios above this are treated as this (a request of 100 times
/// the limit says no more than one of 4 times, and must not hold the filter).
const SATURATION_RATIO_CLAMP: f32 = 4.0;

/// Distance to the target scale below which s lands on it.
const SNAP: f32 = 1e-4;

impl Governor {
    /// Validates `params` and `period_s` (finite, in (0, 0.1] s).
    pub fn new(params: GovernorParams, period_s: f32) -> Result<Self, ConfigError> {
        let params = params.validate()?;
        if !(period_s.is_finite() && period_s > 0.0 && period_s <= 0.1) {
            return Err(ConfigError::InvalidPeriod);
        }
        Ok(Self {
            params,
            period_s,
            inv_period: 1.0 / period_s,
            alpha: period_s / (params.saturation_filter_s + period_s),
            inv_sat_span: 1.0 / (params.saturation_stop - params.saturation_start),
            err_start_sq_m2: params.error_start_m * params.error_start_m,
            inv_err_span_m2: 1.0
                / (params.error_stop_m * params.error_stop_m
                    - params.error_start_m * params.error_start_m),
        })
    }

    /// The validated parameters.
    pub fn params(&self) -> &GovernorParams {
        &self.params
    }

    /// Reference time τ \[s\] of `st`.
    #[inline]
    pub fn tau_s(&self, st: &GovernorState) -> f32 {
        (st.ticks as f32 + st.frac) * self.period_s
    }

    /// The reference at τ with the scaled clock's derivatives (module docs).
    #[inline]
    pub fn reference(&self, st: &GovernorState, traj: &impl Trajectory) -> RefSample {
        scale_sample(traj.sample(self.tau_s(st)), st.scale, st.scale_rate_per_s)
    }

    /// The target scale for `input` given the filtered saturation ratio.
    #[inline]
    pub fn target(&self, saturation_filtered: f32, input: &GovernorInput) -> f32 {
        let p = &self.params;
        let s_sat = 1.0 - (saturation_filtered - p.saturation_start) * self.inv_sat_span;
        let e2 = input.position_error_sq_m2;
        let s_err =
            1.0 - (1.0 - p.error_min_scale) * (e2 - self.err_start_sq_m2) * self.inv_err_span_m2;
        let s_err = if s_err < p.error_min_scale {
            p.error_min_scale
        } else {
            s_err
        };
        let mut t = input.speed_cap;
        if s_sat < t {
            t = s_sat;
        }
        if s_err < t {
            t = s_err;
        }
        // Also maps NaN to 0 (every comparison with NaN is false).
        if t >= 0.0 {
            if t > 1.0 {
                1.0
            } else {
                t
            }
        } else {
            0.0
        }
    }

    /// One period: filters the saturation ratio, moves s towards the target
    /// (rate-limited), then advances τ by s·Δt. A non-finite input stops the
    /// clock for this period (target 0).
    #[inline]
    pub fn advance(&self, st: &mut GovernorState, input: &GovernorInput) {
        let p = &self.params;
        let r = input.saturation_ratio;
        let r = if r >= 0.0 {
            if r > SATURATION_RATIO_CLAMP {
                SATURATION_RATIO_CLAMP
            } else {
                r
            }
        } else {
            // Negative or NaN: treat as fully saturated (unknown is not safe).
            SATURATION_RATIO_CLAMP
        };
        st.saturation_filtered += self.alpha * (r - st.saturation_filtered);
        let target = self.target(st.saturation_filtered, input);
        let mut rate = p.gain_per_s * (target - st.scale);
        if rate > p.max_increase_per_s {
            rate = p.max_increase_per_s;
        } else if rate < -p.max_decrease_per_s {
            rate = -p.max_decrease_per_s;
        }
        let old = st.scale;
        let mut s = old + rate * self.period_s;
        // Land on the target exactly (the first-order approach alone never
        // would): s reaches exactly 0 (clock stopped) and exactly 1 (nominal).
        let gap = target - s;
        if gap * gap < SNAP * SNAP {
            s = target;
        }
        // NaN or negative -> 0 (every comparison with NaN is false).
        s = if s > 1.0 {
            1.0
        } else if s >= 0.0 {
            s
        } else {
            0.0
        };
        st.scale = s;
        st.scale_rate_per_s = (s - old) * self.inv_period;
        // τ += s·Δt as a fraction of a period (s <= 1: at most one carry).
        st.frac += s;
        if st.frac >= 1.0 {
            st.frac -= 1.0;
            st.ticks = st.ticks.saturating_add(1);
        }
    }
}

/// The sample `r` of the unscaled reference at τ, re-timed for τ̇ = `scale`
/// with ds/dt = `scale_rate_per_s`: velocities times s, accelerations
/// ṡ·(velocity) + s²·(acceleration). At s = 1, ṡ = 0 it is `r` bit for bit.
#[inline]
pub fn scale_sample(r: RefSample, scale: f32, scale_rate_per_s: f32) -> RefSample {
    let s2 = scale * scale;
    RefSample {
        pose: r.pose,
        v_mps: scale * r.v_mps,
        omega_radps: scale * r.omega_radps,
        v_dot_mps2: scale_rate_per_s * r.v_mps + s2 * r.v_dot_mps2,
        omega_dot_radps2: scale_rate_per_s * r.omega_radps + s2 * r.omega_dot_radps2,
    }
}

/// e_x² + e_y² \[m²\] of a tracking error.
#[inline]
pub fn position_error_sq_m2(error: [f32; 3]) -> f32 {
    error[0] * error[0] + error[1] * error[1]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trajectory::{PaperCurve, PaperHeading};

    fn gov() -> Governor {
        Governor::new(GovernorParams::default(), 1e-3).unwrap()
    }

    const CALM: GovernorInput = GovernorInput {
        saturation_ratio: 0.5,
        position_error_sq_m2: 1e-4,
        speed_cap: 1.0,
    };

    #[test]
    fn rejects_invalid_parameters() {
        let bad = [
            GovernorParams {
                saturation_stop: 0.5,
                ..Default::default()
            },
            GovernorParams {
                error_min_scale: 0.0,
                ..Default::default()
            },
            GovernorParams {
                max_increase_per_s: f32::NAN,
                ..Default::default()
            },
            GovernorParams {
                saturation_filter_s: -1.0,
                ..Default::default()
            },
        ];
        for p in bad {
            assert_eq!(Governor::new(p, 1e-3), Err(ConfigError::InvalidGovernor));
        }
        assert_eq!(
            Governor::new(GovernorParams::default(), 0.0),
            Err(ConfigError::InvalidPeriod)
        );
    }

    /// With nothing to slow for, s stays 1 and τ = k·Δt exactly (the
    /// runtime's unscaled clock), and the sample equals the unscaled one.
    #[test]
    fn calm_input_keeps_nominal_clock_bit_for_bit() {
        let g = gov();
        let mut st = GovernorState::default();
        let traj = PaperCurve::paper(PaperHeading::SignedSmooth);
        for k in 0..40_000u32 {
            assert_eq!(g.tau_s(&st).to_bits(), (k as f32 * 1e-3).to_bits());
            if k % 997 == 0 {
                assert_eq!(g.reference(&st, &traj), traj.sample(k as f32 * 1e-3));
            }
            g.advance(&mut st, &CALM);
        }
        assert_eq!(st.scale, 1.0);
    }

    /// Scaled derivatives are those of r(τ(t)) with τ̇ = s(t): compare with
    /// a central finite difference along a run where s varies.
    #[test]
    fn scaled_derivatives_match_finite_difference() {
        let g = gov();
        let traj = PaperCurve::paper(PaperHeading::SignedSmooth);
        let mut st = GovernorState::default();
        let mut samples = [RefSample::default(); 3];
        let mut k = 0;
        // Saturation forces s down, then it recovers: take samples mid-ramp.
        for step in 0..3000 {
            let input = GovernorInput {
                saturation_ratio: if step < 1500 { 2.0 } else { 0.0 },
                ..CALM
            };
            if (700..703).contains(&step) || (2200..2203).contains(&step) {
                samples[k % 3] = g.reference(&st, &traj);
                k += 1;
                if k % 3 == 0 {
                    let (a, b, c) = (samples[0], samples[1], samples[2]);
                    let h = 1e-3;
                    // Velocity: finite difference of the path position
                    // projected on the heading.
                    let dx = (c.pose.x_m - a.pose.x_m) / (2.0 * h);
                    let dy = (c.pose.y_m - a.pose.y_m) / (2.0 * h);
                    let (sn, cs) = crate::math::sin_cos(b.pose.theta_rad);
                    let v_fd = dx * cs + dy * sn;
                    assert!((v_fd - b.v_mps).abs() < 2e-3, "v {v_fd} vs {}", b.v_mps);
                    let vd_fd = (c.v_mps - a.v_mps) / (2.0 * h);
                    assert!(
                        (vd_fd - b.v_dot_mps2).abs() < 2e-2 * (1.0 + b.v_dot_mps2.abs()),
                        "v̇ {vd_fd} vs {}",
                        b.v_dot_mps2
                    );
                    let wd_fd = (c.omega_radps - a.omega_radps) / (2.0 * h);
                    assert!(
                        (wd_fd - b.omega_dot_radps2).abs()
                            < 2e-2 * (1.0 + b.omega_dot_radps2.abs()),
                        "ω̇ {wd_fd} vs {}",
                        b.omega_dot_radps2
                    );
                }
            }
            g.advance(&mut st, &input);
        }
        assert_eq!(k, 6);
    }

    /// Persistent saturation stops the clock; the decrease and the recovery
    /// respect their rate limits; s never exceeds 1.
    #[test]
    fn saturation_stops_the_clock_and_recovery_is_rate_limited() {
        let g = gov();
        let p = *g.params();
        let mut st = GovernorState::default();
        let sat = GovernorInput {
            saturation_ratio: 3.0,
            ..CALM
        };
        let mut prev = st.scale;
        for _ in 0..3000 {
            g.advance(&mut st, &sat);
            assert!(prev - st.scale <= p.max_decrease_per_s * 1e-3 * 1.0001);
            prev = st.scale;
        }
        assert_eq!(st.scale, 0.0);
        let tau = g.tau_s(&st);
        g.advance(&mut st, &sat);
        assert_eq!(g.tau_s(&st), tau, "clock must stand still at s = 0");
        // Recovery from 0 to 1 takes at least 1/max_increase seconds.
        let mut n = 0;
        while st.scale < 1.0 {
            g.advance(&mut st, &CALM);
            assert!(st.scale - prev <= p.max_increase_per_s * 1e-3 * 1.0001);
            prev = st.scale;
            n += 1;
            assert!(n < 100_000);
        }
        assert!(n as f32 * 1e-3 >= 1.0 / p.max_increase_per_s * 0.999, "{n}");
    }

    /// A large tracking error alone slows to the floor, never to 0.
    #[test]
    fn tracking_error_slows_to_the_floor() {
        let g = gov();
        let mut st = GovernorState::default();
        let far = GovernorInput {
            position_error_sq_m2: 9.0,
            ..CALM
        };
        for _ in 0..5000 {
            g.advance(&mut st, &far);
        }
        assert!((st.scale - g.params().error_min_scale).abs() < 1e-4);
    }
}
