//! Health state machine: nominal, degraded (reference slowed through the
//! governor's speed cap, reason published) or safe stop (hard faults only).
//! Not in the paper (book/src/explanation/decisions.md, D24).
//!
//! Inputs, each low-pass filtered with `filter_s` (one multiply-add each):
//!
//! * the estimated fault ratio ε̂ = ⟨Δv̂·v⟩/⟨v² + v₀²⟩ (a running
//!   least-squares fit of F̂_v = ε·v, eq. 10; v₀ keeps it defined at rest);
//! * the disturbance estimate as a share of the torque limit,
//!   max|N⁻¹·D̂|/τ_limit (the torque the ESO's D̂ eats);
//! * the adaptive gain's share of its bound, max ρ̂/ρ_max;
//! * the share of steps at the torque limit;
//! * the squared position error (its filter is a mean square: the
//!   thresholds below apply to its root, an RMS error);
//! * the estimator's health ([`EstimatorHealth`]).
//!
//! Nominal → Degraded when any filtered input reaches its `*_degraded`
//! threshold; Degraded → Nominal when every input is below
//! `exit_fraction` × its threshold and the machine has been degraded for at
//! least `min_dwell_s` (hysteresis and dwell: no chatter). Safe stop (latched
//! until [`HealthMonitor::reset`]) only on hard faults held for
//! `hard_dwell_s`: ε̂ at `fault_ratio_hard` (the actuators deliver almost
//! nothing), a lost path (error above `lost_path_m` after the error was once
//! below `acquired_m`), a failed estimator, or a controller fault.

use crate::error::ConfigError;
use crate::math::{all_non_negative, all_positive};

/// Health mode, ordered by severity.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum HealthMode {
    /// Everything within thresholds: full speed.
    #[default]
    Nominal,
    /// Running at reduced speed (`degraded_speed_scale`).
    Degraded,
    /// Hard fault: reference stopped, motors to be disabled (latched).
    SafeStop,
}

impl HealthMode {
    /// Numeric level for traces and plots (0, 1, 2).
    pub const fn level(self) -> u8 {
        self as u8
    }
}

/// Why the machine is (or last went) out of nominal.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum HealthReason {
    /// Nominal since start.
    #[default]
    None,
    /// The torque is at its limit too often.
    Saturation,
    /// The position error is large.
    TrackingError,
    /// The estimated actuator fault ε̂ is large.
    ActuatorFault,
    /// The disturbance estimate eats much of the torque.
    Disturbance,
    /// The adaptive switching gain is near its bound.
    AdaptationLimit,
    /// The state estimator reports a problem.
    Estimator,
    /// The path was lost after it had been acquired (hard).
    LostPath,
    /// The controller rejected its input or reset (hard).
    ControllerFault,
}

/// Health of the pose estimator, for the health machine: what the runtime's
/// estimator reports each tick
/// ([`crate::estimator::PoseEstimator::health`]; its detailed counters are
/// [`crate::estimator::EstimatorStatus`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EstimatorHealth {
    /// Consistent innovations.
    #[default]
    Ok,
    /// Innovations large or measurements missing: degrade.
    Degraded,
    /// Estimator diverged: hard fault.
    Failed,
}

/// One tick's inputs (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HealthInput {
    /// Fault estimate Δv̂ \[m/s\].
    pub fault_v_mps: f32,
    /// Measured v \[m/s\].
    pub v_mps: f32,
    /// max|N⁻¹·D̂| / τ_limit.
    pub disturbance_ratio: f32,
    /// max ρ̂ / ρ_max (0 for a fixed gain).
    pub adaptation_ratio: f32,
    /// True when the torque was at its limit this step.
    pub saturated: bool,
    /// Squared position error e_x² + e_y² \[m²\].
    pub position_error_sq_m2: f32,
    /// Estimator status.
    pub estimator: EstimatorHealth,
    /// The controller rejected its input or reset this step.
    pub controller_fault: bool,
}

/// Thresholds, filter and timing of the machine (validated by
/// [`HealthMonitor::new`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HealthParams {
    /// Time constant of the input filters \[s\].
    pub filter_s: f32,
    /// v₀ of the ε̂ fit \[m/s\].
    pub fault_fit_speed_mps: f32,
    /// ε̂ that degrades (the paper's faults are ε < 0.25).
    pub fault_ratio_degraded: f32,
    /// ε̂ that is a hard fault.
    pub fault_ratio_hard: f32,
    /// Disturbance share of the torque limit that degrades.
    pub disturbance_degraded: f32,
    /// ρ̂/ρ_max that degrades; above 1 (the default,
    /// [`ADAPTATION_CHECK_OFF`]) the check is off: with the project's
    /// ρ_max = 5 the ω channel's ρ̂ sits at its bound through every Case 2
    /// run (measured, D24), so it says nothing about the robot's health.
    pub adaptation_degraded: f32,
    /// Share of saturated steps that degrades.
    pub saturation_degraded: f32,
    /// Position error that degrades \[m\].
    pub error_degraded_m: f32,
    /// Error below which the path counts as acquired \[m\].
    pub acquired_m: f32,
    /// Error beyond which an acquired path counts as lost (hard) \[m\].
    pub lost_path_m: f32,
    /// Exit thresholds as a fraction of the entry thresholds (hysteresis).
    pub exit_fraction: f32,
    /// Least time in Degraded before returning to Nominal \[s\].
    pub min_dwell_s: f32,
    /// How long a hard condition must hold before the safe stop \[s\].
    pub hard_dwell_s: f32,
    /// Speed cap (governor's time scale bound) while degraded, in (0, 1].
    pub degraded_speed_scale: f32,
}

/// [`HealthParams::adaptation_degraded`] that turns the ρ̂ check off.
pub const ADAPTATION_CHECK_OFF: f32 = 2.0;

impl HealthParams {
    /// The defaults (also [`Default::default`]); a constant so that
    /// configurations built from it are data, not code.
    pub const DEFAULT: Self = Self {
        filter_s: 0.5,
        fault_fit_speed_mps: 0.2,
        fault_ratio_degraded: 0.35,
        fault_ratio_hard: 0.9,
        disturbance_degraded: 0.5,
        adaptation_degraded: ADAPTATION_CHECK_OFF,
        saturation_degraded: 0.3,
        error_degraded_m: 0.3,
        acquired_m: 0.2,
        lost_path_m: 2.0,
        exit_fraction: 0.7,
        min_dwell_s: 1.0,
        hard_dwell_s: 0.5,
        degraded_speed_scale: 0.6,
    };
}

impl Default for HealthParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl HealthParams {
    /// Checks every field.
    pub fn validate(self) -> Result<Self, ConfigError> {
        // Orderings as positive differences: for finite a, b, a − b > 0
        // exactly when a > b (and a NaN or an infinity fails the check).
        let ok = all_positive(&[
            self.filter_s,
            self.fault_fit_speed_mps,
            self.fault_ratio_degraded,
            self.fault_ratio_hard,
            self.fault_ratio_hard - self.fault_ratio_degraded,
            self.disturbance_degraded,
            self.adaptation_degraded,
            self.saturation_degraded,
            self.error_degraded_m,
            self.acquired_m,
            self.lost_path_m,
            self.lost_path_m - self.acquired_m,
            self.exit_fraction,
            1.0 - self.exit_fraction,
            self.degraded_speed_scale,
        ]) && all_non_negative(&[
            self.min_dwell_s,
            self.hard_dwell_s,
            1.0 - self.degraded_speed_scale,
        ]);
        if ok {
            Ok(self)
        } else {
            Err(ConfigError::InvalidHealth)
        }
    }
}

/// A mode change, reported on the tick it happens.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HealthTransition {
    /// Mode before.
    pub from: HealthMode,
    /// Mode after.
    pub to: HealthMode,
    /// The reason published with the new mode.
    pub reason: HealthReason,
}

/// State of the machine: filters, mode, timers, counters.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HealthState {
    /// Current mode.
    pub mode: HealthMode,
    /// Reason published with the mode.
    pub reason: HealthReason,
    /// Mode changes since start or reset.
    pub transitions: u32,
    /// Ticks in the current mode.
    pub ticks_in_mode: u32,
    /// Ticks the current hard condition has held.
    pub hard_ticks: u32,
    /// The error has been below `acquired_m`.
    pub acquired: bool,
    /// The filters hold a value (set by the first update, which loads them
    /// with its inputs).
    pub primed: bool,
    /// Filtered ⟨Δv̂·v⟩.
    pub fault_cross: f32,
    /// Filtered ⟨v² + v₀²⟩.
    pub fault_norm: f32,
    /// Filtered disturbance share.
    pub disturbance: f32,
    /// Filtered adaptation share.
    pub adaptation: f32,
    /// Filtered saturated share.
    pub saturation: f32,
    /// Filtered squared position error (mean square) \[m²\].
    pub error_sq_m2: f32,
    /// ε̂ of the last update (see [`Self::fault_ratio`]).
    pub eps_hat: f32,
}

impl HealthState {
    /// The fitted fault ratio ε̂ (0 before any input).
    pub fn fault_ratio(&self) -> f32 {
        if self.fault_norm > 0.0 {
            self.fault_cross / self.fault_norm
        } else {
            0.0
        }
    }
}

/// The soft conditions' thresholds at one scale (computed once).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct SoftThresholds {
    saturation: f32,
    fault_ratio: f32,
    disturbance: f32,
    adaptation: f32,
    error_sq_m2: f32,
}

impl SoftThresholds {
    fn of(p: &HealthParams, scale: f32) -> Self {
        Self {
            saturation: scale * p.saturation_degraded,
            fault_ratio: scale * p.fault_ratio_degraded,
            disturbance: scale * p.disturbance_degraded,
            adaptation: scale * p.adaptation_degraded,
            error_sq_m2: scale * scale * p.error_degraded_m * p.error_degraded_m,
        }
    }
}

/// The validated parameters and derived constants of the machine; the state
/// is passed to each call.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HealthMonitor {
    params: HealthParams,
    /// The soft thresholds to enter Degraded, and × `exit_fraction` to leave it.
    enter_at: SoftThresholds,
    exit_at: SoftThresholds,
    alpha: f32,
    dwell_ticks: u32,
    hard_ticks: u32,
    acquired_sq_m2: f32,
    lost_path_sq_m2: f32,
    /// e_deg² \[m²\]: no longer read (the thresholds are in `enter_at` and
    /// `exit_at`), kept because removing it moved the worst typical tick on
    /// the M4F across a 40-instruction SysTick quantum (2,996 → 3,036
    /// measured): the budget sits at that edge (BENCHMARKS.md, D175/D176).
    #[allow(dead_code)]
    error_degraded_sq_m2: f32,
}

impl HealthMonitor {
    /// Validates `params` at the control period `period_s`.
    pub fn new(params: HealthParams, period_s: f32) -> Result<Self, ConfigError> {
        let params = params.validate()?;
        if !(period_s.is_finite() && period_s > 0.0 && period_s <= 0.1) {
            return Err(ConfigError::InvalidPeriod);
        }
        // Rounded up; as u32 saturates for absurd values.
        let ticks = |t: f32| (t / period_s + 0.999) as u32;
        Ok(Self {
            params,
            enter_at: SoftThresholds::of(&params, 1.0),
            exit_at: SoftThresholds::of(&params, params.exit_fraction),
            alpha: period_s / (params.filter_s + period_s),
            dwell_ticks: ticks(params.min_dwell_s),
            hard_ticks: ticks(params.hard_dwell_s).max(1),
            acquired_sq_m2: params.acquired_m * params.acquired_m,
            lost_path_sq_m2: params.lost_path_m * params.lost_path_m,
            error_degraded_sq_m2: params.error_degraded_m * params.error_degraded_m,
        })
    }

    /// The validated parameters.
    pub fn params(&self) -> &HealthParams {
        &self.params
    }

    /// Back to Nominal with cleared filters (counters kept).
    pub fn reset(&self, st: &mut HealthState) {
        *st = HealthState {
            transitions: st.transitions,
            ..HealthState::default()
        };
    }

    /// Speed cap for the governor in `mode`.
    #[inline]
    pub fn speed_cap(&self, mode: HealthMode) -> f32 {
        match mode {
            HealthMode::Nominal => 1.0,
            HealthMode::Degraded => self.params.degraded_speed_scale,
            HealthMode::SafeStop => 0.0,
        }
    }

    /// One period: filters the inputs and steps the machine. Returns the
    /// transition if the mode changed. Non-finite inputs are ignored by the
    /// filters (they keep their value).
    #[inline]
    pub fn update(&self, st: &mut HealthState, input: &HealthInput) -> Option<HealthTransition> {
        let p = &self.params;
        let a = if st.primed { self.alpha } else { 1.0 };
        st.primed = true;
        let filt = |y: &mut f32, x: f32| {
            let n = *y + a * (x - *y);
            if n.is_finite() {
                *y = n;
            }
        };
        let v = input.v_mps;
        let v0 = p.fault_fit_speed_mps;
        filt(&mut st.fault_cross, input.fault_v_mps * v);
        filt(&mut st.fault_norm, v * v + v0 * v0);
        filt(&mut st.disturbance, input.disturbance_ratio);
        filt(&mut st.adaptation, input.adaptation_ratio);
        filt(&mut st.saturation, input.saturated as u8 as f32);
        filt(&mut st.error_sq_m2, input.position_error_sq_m2);
        if st.error_sq_m2 < self.acquired_sq_m2 {
            st.acquired = true;
        }
        st.ticks_in_mode = st.ticks_in_mode.saturating_add(1);
        if st.mode == HealthMode::SafeStop {
            return None;
        }

        // Hard conditions, held for hard_dwell.
        let eps = st.fault_ratio();
        st.eps_hat = eps;
        let hard = if input.controller_fault {
            Some(HealthReason::ControllerFault)
        } else if input.estimator == EstimatorHealth::Failed {
            Some(HealthReason::Estimator)
        } else if eps >= p.fault_ratio_hard {
            Some(HealthReason::ActuatorFault)
        } else if st.acquired && st.error_sq_m2 > self.lost_path_sq_m2 {
            Some(HealthReason::LostPath)
        } else {
            None
        };
        match hard {
            Some(reason) => {
                st.hard_ticks = st.hard_ticks.saturating_add(1);
                if st.hard_ticks >= self.hard_ticks {
                    st.hard_ticks = 0;
                    return Some(Self::enter(st, HealthMode::SafeStop, reason));
                }
            }
            None => st.hard_ticks = 0,
        }

        // Soft conditions: the first at or above its threshold in `at`.
        let over = |at: &SoftThresholds| -> Option<HealthReason> {
            if st.saturation >= at.saturation {
                Some(HealthReason::Saturation)
            } else if eps >= at.fault_ratio {
                Some(HealthReason::ActuatorFault)
            } else if st.disturbance >= at.disturbance {
                Some(HealthReason::Disturbance)
            } else if st.adaptation >= at.adaptation {
                Some(HealthReason::AdaptationLimit)
            } else if input.estimator == EstimatorHealth::Degraded {
                Some(HealthReason::Estimator)
            } else if st.acquired && st.error_sq_m2 >= at.error_sq_m2 {
                Some(HealthReason::TrackingError)
            } else {
                None
            }
        };
        match st.mode {
            HealthMode::Nominal => {
                over(&self.enter_at).map(|reason| Self::enter(st, HealthMode::Degraded, reason))
            }
            HealthMode::Degraded => {
                if let Some(r) = over(&self.enter_at) {
                    st.reason = r;
                    None
                } else if over(&self.exit_at).is_none() && st.ticks_in_mode >= self.dwell_ticks {
                    let reason = st.reason;
                    Some(Self::enter(st, HealthMode::Nominal, reason))
                } else {
                    None
                }
            }
            HealthMode::SafeStop => None,
        }
    }

    fn enter(st: &mut HealthState, to: HealthMode, reason: HealthReason) -> HealthTransition {
        let from = st.mode;
        st.mode = to;
        st.reason = reason;
        st.ticks_in_mode = 0;
        st.transitions = st.transitions.saturating_add(1);
        HealthTransition { from, to, reason }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mon() -> HealthMonitor {
        HealthMonitor::new(HealthParams::default(), 1e-3).unwrap()
    }

    const CALM: HealthInput = HealthInput {
        fault_v_mps: 0.0,
        v_mps: 1.0,
        disturbance_ratio: 0.05,
        adaptation_ratio: 0.02,
        saturated: false,
        position_error_sq_m2: 1e-4,
        estimator: EstimatorHealth::Ok,
        controller_fault: false,
    };

    #[test]
    fn rejects_invalid_parameters() {
        for p in [
            HealthParams {
                exit_fraction: 1.0,
                ..Default::default()
            },
            HealthParams {
                fault_ratio_hard: 0.1,
                ..Default::default()
            },
            HealthParams {
                degraded_speed_scale: 0.0,
                ..Default::default()
            },
            HealthParams {
                min_dwell_s: f32::NAN,
                ..Default::default()
            },
        ] {
            assert_eq!(HealthMonitor::new(p, 1e-3), Err(ConfigError::InvalidHealth));
        }
    }

    /// ε̂ fits F̂_v = ε·v: with a constant ratio and v ≫ v₀ it converges to
    /// ε·v²/(v² + v₀²) (the analytic limit of the two filters).
    #[test]
    fn fault_ratio_fit_converges_to_least_squares_limit() {
        let m = mon();
        let mut st = HealthState::default();
        let (eps, v) = (0.2f32, 1.5f32);
        for _ in 0..5000 {
            m.update(
                &mut st,
                &HealthInput {
                    fault_v_mps: eps * v,
                    v_mps: v,
                    ..CALM
                },
            );
        }
        let expect = eps * v * v / (v * v + 0.04);
        assert!(
            (st.fault_ratio() - expect).abs() < 1e-4,
            "{}",
            st.fault_ratio()
        );
        assert_eq!(st.mode, HealthMode::Nominal);
    }

    /// A growing fault degrades once, with the reason; it returns to nominal
    /// only after the dwell and once below the exit threshold; an input
    /// oscillating around the entry threshold does not chatter.
    #[test]
    fn hysteresis_and_dwell_prevent_chatter() {
        let m = mon();
        let mut st = HealthState::default();
        let mut transitions = 0;
        // Oscillate around the entry threshold (0.35) for 10 s.
        for k in 0..10_000 {
            let eps = if (k / 700) % 2 == 0 { 0.40 } else { 0.30 };
            let input = HealthInput {
                fault_v_mps: eps,
                v_mps: 1.0,
                ..CALM
            };
            if let Some(t) = m.update(&mut st, &input) {
                transitions += 1;
                assert_eq!(t.reason, HealthReason::ActuatorFault);
            }
        }
        assert_eq!(transitions, 1, "chattered: {transitions}");
        assert_eq!(st.mode, HealthMode::Degraded);
        // Back to a small fault: nominal again, not before the dwell.
        let mut n = 0;
        while st.mode == HealthMode::Degraded {
            m.update(&mut st, &CALM);
            n += 1;
            assert!(n < 10_000);
        }
        assert!(st.transitions == 2);
        assert!(n >= 1, "{n}");
    }

    /// Saturation alone degrades but never stops; a controller fault held
    /// for the hard dwell stops and latches.
    #[test]
    fn only_hard_faults_stop() {
        let m = mon();
        let mut st = HealthState::default();
        for _ in 0..20_000 {
            m.update(
                &mut st,
                &HealthInput {
                    saturated: true,
                    position_error_sq_m2: 1.0,
                    ..CALM
                },
            );
        }
        assert_eq!(st.mode, HealthMode::Degraded);
        let mut stopped_at = None;
        for k in 0..1000 {
            let t = m.update(
                &mut st,
                &HealthInput {
                    controller_fault: true,
                    ..CALM
                },
            );
            if t.is_some_and(|t| t.to == HealthMode::SafeStop) {
                stopped_at = Some(k);
            }
        }
        assert_eq!(st.mode, HealthMode::SafeStop);
        assert_eq!(st.reason, HealthReason::ControllerFault);
        assert_eq!(stopped_at, Some(499), "hard dwell 0.5 s at 1 kHz");
        for _ in 0..5000 {
            assert!(m.update(&mut st, &CALM).is_none());
        }
        assert_eq!(st.mode, HealthMode::SafeStop, "latched");
        m.reset(&mut st);
        assert_eq!(st.mode, HealthMode::Nominal);
        assert_eq!(m.speed_cap(HealthMode::SafeStop), 0.0);
    }
}
