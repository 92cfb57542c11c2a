//! The reference governor ([`crate::governor`]) and the health machine
//! ([`crate::health`]) together, as the runtime and the simulator run them
//! around one [`Controller::step`](crate::Controller::step):
//!
//! 1. [`Pacer::reference`]: the reference at the governed time τ (or, when
//!    pacing is off, at the nominal time, exactly as without a pacer);
//! 2. the controller step;
//! 3. [`Pacer::update`] with the step's [`Diagnostics`]: the health machine,
//!    then the governor (capped by the health mode), then τ += s·Δt.
//!
//! The same for all three controllers: SMC and ASMC simply have F̂ = D̂ = 0.

use crate::asmc::Switching;
use crate::controller::{ControllerConfig, Diagnostics};
use crate::error::ConfigError;
use crate::governor::{
    position_error_sq_m2, Governor, GovernorInput, GovernorParams, GovernorState,
};
use crate::health::{
    EstimatorHealth, HealthInput, HealthMode, HealthMonitor, HealthParams, HealthReason,
    HealthState, HealthTransition,
};
use crate::model::ReducedModel;
use crate::trajectory::{RefSample, Trajectory};
use crate::types::Vel2;

/// Whether and how the reference is paced.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PacingConfig {
    /// Governor and health machine on. Off: the reference runs at the nominal
    /// time (the paper's setting), health stays nominal.
    pub enabled: bool,
    /// Governor parameters.
    pub governor: GovernorParams,
    /// Health machine parameters.
    pub health: HealthParams,
}

impl PacingConfig {
    /// On, default parameters (the default in the runtime and the simulator).
    pub const fn on() -> Self {
        Self {
            enabled: true,
            governor: GovernorParams::DEFAULT,
            health: HealthParams::DEFAULT,
        }
    }

    /// Off (the paper's setting).
    pub fn off() -> Self {
        Self {
            enabled: false,
            ..Self::on()
        }
    }
}

impl Default for PacingConfig {
    fn default() -> Self {
        Self::on()
    }
}

/// State of the pacer.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PacerState {
    /// Governor clock and scale.
    pub governor: GovernorState,
    /// Health machine.
    pub health: HealthState,
}

/// What the pacer reports per tick (telemetry, traces).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PaceReport {
    /// Reference time τ the next step will use \[s\].
    pub tau_s: f32,
    /// Time scale s after this tick.
    pub scale: f32,
    /// Health mode after this tick.
    pub mode: HealthMode,
    /// Reason published with the mode.
    pub reason: HealthReason,
    /// Mode changes so far.
    pub transitions: u32,
    /// Set on the tick the mode changed.
    pub transition: Option<HealthTransition>,
    /// The fitted fault ratio ε̂.
    pub fault_ratio: f32,
}

/// Governor and health machine with the controller constants they need.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Pacer {
    enabled: bool,
    governor: Governor,
    health: HealthMonitor,
    model: ReducedModel,
    inv_torque_limit: f32,
    inv_rho_max: f32,
    period_s: f32,
}

impl Pacer {
    /// Validates `cfg` for the controller `controller` (period, torque limit,
    /// model, adaptive bound).
    pub fn new(cfg: PacingConfig, controller: &ControllerConfig) -> Result<Self, ConfigError> {
        let controller = controller.validate()?;
        let inv_rho_max = match controller.sliding.switching {
            Switching::Adaptive(a) if a.rho_max > 0.0 => 1.0 / a.rho_max,
            _ => 0.0,
        };
        Ok(Self {
            enabled: cfg.enabled,
            governor: Governor::new(cfg.governor, controller.period_s)?,
            health: HealthMonitor::new(cfg.health, controller.period_s)?,
            model: ReducedModel::new(&controller.robot)?,
            inv_torque_limit: 1.0 / controller.torque_limit_nm,
            inv_rho_max,
            period_s: controller.period_s,
        })
    }

    /// True when pacing is on.
    pub fn enabled(&self) -> bool {
        self.enabled
    }

    /// The governor.
    pub fn governor(&self) -> &Governor {
        &self.governor
    }

    /// The health machine.
    pub fn health(&self) -> &HealthMonitor {
        &self.health
    }

    /// State at start (s = 1, τ = 0, nominal).
    pub fn initial_state(&self) -> PacerState {
        PacerState::default()
    }

    /// The reference for this tick: at the governed τ when on, at
    /// `nominal_t_s` (unchanged) when off.
    #[inline]
    pub fn reference(
        &self,
        st: &PacerState,
        traj: &impl Trajectory,
        nominal_t_s: f32,
    ) -> RefSample {
        if self.enabled {
            self.governor.reference(&st.governor, traj)
        } else {
            traj.sample(nominal_t_s)
        }
    }

    /// The health machine's input from a step's diagnostics.
    #[inline]
    pub fn health_input(
        &self,
        diag: &Diagnostics,
        eta: Vel2,
        estimator: EstimatorHealth,
    ) -> HealthInput {
        let tau_d = self.model.n_inv_mul(diag.d_hat);
        let abs_max = |a: [f32; 2]| {
            let (x, y) = (a[0].abs(), a[1].abs());
            if x > y {
                x
            } else {
                y
            }
        };
        HealthInput {
            fault_v_mps: diag.f_hat[0],
            v_mps: eta.v_mps,
            disturbance_ratio: abs_max(tau_d) * self.inv_torque_limit,
            adaptation_ratio: abs_max(diag.rho_hat) * self.inv_rho_max,
            saturated: diag.saturated,
            position_error_sq_m2: position_error_sq_m2(diag.error),
            estimator,
            controller_fault: diag.fault.is_some(),
        }
    }

    /// After the step: health, then governor, then the clock. When off, only
    /// the nominal clock advances (s = 1, Nominal).
    #[inline]
    pub fn update(
        &self,
        st: &mut PacerState,
        diag: &Diagnostics,
        eta: Vel2,
        estimator: EstimatorHealth,
    ) -> PaceReport {
        if !self.enabled {
            let g = &mut st.governor;
            g.ticks = g.ticks.saturating_add(1);
            return self.report(st, None);
        }
        let h = self.health_input(diag, eta, estimator);
        let transition = self.health.update(&mut st.health, &h);
        let peak = {
            let r = diag.torque_request_nm;
            let (x, y) = (r[0].abs(), r[1].abs());
            if x > y {
                x
            } else {
                y
            }
        };
        let g = GovernorInput {
            saturation_ratio: peak * self.inv_torque_limit,
            position_error_sq_m2: h.position_error_sq_m2,
            speed_cap: self.health.speed_cap(st.health.mode),
        };
        self.governor.advance(&mut st.governor, &g);
        self.report(st, transition)
    }

    /// The report of `st` without a transition (for ticks that do not step).
    pub fn status(&self, st: &PacerState) -> PaceReport {
        self.report(st, None)
    }

    fn report(&self, st: &PacerState, transition: Option<HealthTransition>) -> PaceReport {
        PaceReport {
            tau_s: self.governor.tau_s(&st.governor),
            scale: st.governor.scale,
            mode: st.health.mode,
            reason: st.health.reason,
            transitions: st.health.transitions,
            transition,
            fault_ratio: st.health.eps_hat,
        }
    }

    /// Control period \[s\].
    pub fn period_s(&self) -> f32 {
        self.period_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::ControllerKind;
    use proptest::prelude::*;

    fn any_diag() -> impl Strategy<Value = (Diagnostics, f32)> {
        let f = prop_oneof![
            -1e6f32..1e6,
            Just(f32::NAN),
            Just(f32::INFINITY),
            Just(f32::NEG_INFINITY),
            Just(0.0)
        ];
        (
            proptest::array::uniform3(f.clone()),
            proptest::array::uniform2(f.clone()),
            proptest::array::uniform2(f.clone()),
            proptest::array::uniform2(f.clone()),
            proptest::array::uniform2(f.clone()),
            any::<bool>(),
            any::<bool>(),
            f,
        )
            .prop_map(|(error, f_hat, d_hat, rho_hat, req, sat, fault, v)| {
                (
                    Diagnostics {
                        error,
                        f_hat,
                        d_hat,
                        rho_hat,
                        torque_request_nm: req,
                        saturated: sat,
                        fault: fault.then_some(crate::InputFault::NonFinitePose),
                        ..Diagnostics::default()
                    },
                    v,
                )
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Whatever the diagnostics (NaN, ±inf, huge), the time scale stays
        /// finite, in [0, 1], τ never decreases and never runs ahead of the
        /// nominal clock, and every reference sample stays finite.
        #[test]
        fn scale_finite_nonnegative_never_above_nominal(
            steps in proptest::collection::vec(any_diag(), 1..400),
            kind in prop_oneof![Just(ControllerKind::Smc), Just(ControllerKind::Asmc), Just(ControllerKind::Proposed)],
        ) {
            let cfg = ControllerConfig::paper(kind);
            let pacer = Pacer::new(PacingConfig::on(), &cfg).unwrap();
            let mut st = pacer.initial_state();
            let traj = crate::trajectory::PaperCurve::paper(crate::trajectory::PaperHeading::SignedSmooth);
            let mut tau_prev = 0.0f32;
            for (k, (diag, v)) in steps.iter().enumerate() {
                let r = pacer.reference(&st, &traj, 0.0);
                prop_assert!(r.is_finite());
                let rep = pacer.update(&mut st, diag, Vel2::new(*v, 0.0), EstimatorHealth::Ok);
                prop_assert!(rep.scale.is_finite() && rep.scale >= 0.0 && rep.scale <= 1.0);
                prop_assert!(st.governor.scale_rate_per_s.is_finite());
                prop_assert!(rep.tau_s.is_finite() && rep.tau_s >= tau_prev);
                prop_assert!(rep.tau_s <= (k + 1) as f32 * cfg.period_s * (1.0 + 1e-6));
                prop_assert!(pacer.health().speed_cap(rep.mode) <= 1.0);
                tau_prev = rep.tau_s;
            }
        }
    }

    /// Off: the reference is the nominal sample and health stays nominal,
    /// whatever the diagnostics.
    #[test]
    fn off_is_the_nominal_reference() {
        let cfg = ControllerConfig::paper(ControllerKind::Proposed);
        let pacer = Pacer::new(PacingConfig::off(), &cfg).unwrap();
        let mut st = pacer.initial_state();
        let traj = crate::trajectory::PaperCurve::paper(crate::trajectory::PaperHeading::Tangent);
        let diag = Diagnostics {
            saturated: true,
            torque_request_nm: [100.0, 0.0],
            error: [3.0, 0.0, 0.0],
            ..Diagnostics::default()
        };
        for k in 0..2000 {
            let t = k as f32 * 1e-3;
            assert_eq!(pacer.reference(&st, &traj, t), traj.sample(t));
            let rep = pacer.update(&mut st, &diag, Vel2::new(1.0, 0.0), EstimatorHealth::Ok);
            assert_eq!(rep.scale, 1.0);
            assert_eq!(rep.mode, HealthMode::Nominal);
        }
    }
}
