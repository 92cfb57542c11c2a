//! The three controllers of section 4 behind one type.
//!
//! | kind | kinematic loop | dynamic loop |
//! |---|---|---|
//! | [`ControllerKind::Smc`] | eq. (14), F̂ = 0 | eq. (24) with fixed gain K, no ESO |
//! | [`ControllerKind::Asmc`] | eq. (14), F̂ = 0 | eq. (24) with adaptive ρ̂, no ESO |
//! | [`ControllerKind::Proposed`] | eq. (14) + fault observer (13) | eq. (24), adaptive ρ̂, fal-ESO (18) |
//!
//! One [`Controller::step`] per control period. Inputs are validated first:
//! a NaN, infinite or implausible measurement or reference yields zero torque
//! and [`Diagnostics::fault`]; the controller's state is left untouched, so it
//! recovers on the next valid sample (the firmware's supervisor decides when
//! to latch a safe stop).

use crate::asmc::{AdaptiveGain, SlidingParams, SlidingState, Switching};
use crate::error::{ConfigError, InputFault};
use crate::eso::{EsoParams, EsoState};
use crate::fault_observer::{FaultObserverGains, FaultObserverState};
use crate::kinematic::KinematicGains;
use crate::math::clamp_abs;
use crate::model::ReducedModel;
use crate::params::RobotParams;
use crate::tracking::{error_rate, tracking_error};
use crate::trajectory::RefSample;
use crate::types::{Pose, Vel2};

/// Which of the paper's three controllers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ControllerKind {
    /// "SMC without observer".
    Smc,
    /// "ASMC without observer".
    Asmc,
    /// The proposed controller: fault observer + fal-ESO + ASMC.
    Proposed,
}

impl ControllerKind {
    /// All three, in the paper's order.
    pub const ALL: [ControllerKind; 3] = [Self::Smc, Self::Asmc, Self::Proposed];

    /// Short lowercase name (`smc`, `asmc`, `proposed`).
    pub const fn name(self) -> &'static str {
        match self {
            Self::Smc => "smc",
            Self::Asmc => "asmc",
            Self::Proposed => "proposed",
        }
    }
}

/// Plausibility limits on measurements; beyond them a step is rejected.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct InputLimits {
    /// Max |x|, |y| of the measured and reference pose \[m\].
    pub max_position_m: f32,
    /// Max |v| \[m/s\].
    pub max_speed_mps: f32,
    /// Max |ω| \[rad/s\].
    pub max_yaw_rate_radps: f32,
}

impl Default for InputLimits {
    fn default() -> Self {
        Self {
            max_position_m: 1000.0,
            max_speed_mps: 10.0,
            max_yaw_rate_radps: 30.0,
        }
    }
}

/// Everything a [`Controller`] needs, validated by [`Controller::new`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ControllerConfig {
    /// Which controller.
    pub kind: ControllerKind,
    /// The controller's model of the robot.
    pub robot: RobotParams,
    /// Kinematic law gains, eq. (14).
    pub kinematic: KinematicGains,
    /// Fault observer gains, eq. (13) (used by `Proposed` only).
    pub fault_observer: FaultObserverGains,
    /// ESO parameters, eq. (18) (used by `Proposed` only).
    pub eso: EsoParams,
    /// Sliding loop, eqs. (20)-(24).
    pub sliding: SlidingParams,
    /// Per-wheel torque limit \[N·m\].
    pub torque_limit_nm: f32,
    /// Control period \[s\].
    pub period_s: f32,
    /// Input plausibility limits.
    pub input_limits: InputLimits,
}

/// Default lateral gain k_y: the printed 250 is unstable while the reference
/// reverses faster than k_th/(d·k_y) = 0.4 m/s (D8).
pub const DEFAULT_K_Y: f32 = 25.0;
/// Fixed switching gain K of the plain SMC baseline (Table 2 gives none: D13).
pub const DEFAULT_SMC_GAIN: f32 = 1.0;
/// Default per-wheel torque limit \[N·m\] (the paper has none: D14).
pub const DEFAULT_TORQUE_LIMIT_NM: f32 = 10.0;

impl ControllerConfig {
    /// Table 2 gains for `kind` at a 1 kHz period, with the project's
    /// documented choices where the paper is silent or unusable.
    pub fn paper(kind: ControllerKind) -> Self {
        let (k_s, switching) = match kind {
            ControllerKind::Smc => (5.0, Switching::Fixed(DEFAULT_SMC_GAIN)),
            ControllerKind::Asmc => (5.0, Switching::Adaptive(AdaptiveGain::default())),
            ControllerKind::Proposed => (50.0, Switching::Adaptive(AdaptiveGain::default())),
        };
        Self {
            kind,
            robot: RobotParams::paper(),
            kinematic: KinematicGains {
                k_y: DEFAULT_K_Y,
                ..KinematicGains::paper()
            },
            fault_observer: FaultObserverGains::default(),
            eso: EsoParams::default(),
            sliding: SlidingParams { k_s, switching },
            torque_limit_nm: DEFAULT_TORQUE_LIMIT_NM,
            period_s: 1e-3,
            input_limits: InputLimits::default(),
        }
    }

    /// Validates every part.
    pub fn validate(self) -> Result<Self, ConfigError> {
        self.robot.validate()?;
        self.kinematic.validate()?;
        self.fault_observer.validate()?;
        self.eso.validate()?;
        self.sliding.validate()?;
        if !(self.torque_limit_nm.is_finite() && self.torque_limit_nm > 0.0) {
            return Err(ConfigError::NonPositiveTorqueLimit);
        }
        if !(self.period_s.is_finite() && self.period_s > 0.0 && self.period_s <= 0.1) {
            return Err(ConfigError::InvalidPeriod);
        }
        let l = self.input_limits;
        let ok = |x: f32| x.is_finite() && x > 0.0;
        if !(ok(l.max_position_m) && ok(l.max_speed_mps) && ok(l.max_yaw_rate_radps)) {
            return Err(ConfigError::InvalidInputLimits);
        }
        Ok(self)
    }
}

/// One control step's input.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StepInput {
    /// Reference sample at this step's time.
    pub reference: RefSample,
    /// Measured pose of G (odometry or an external measurement).
    pub pose: Pose,
    /// Measured wheel-derived η = \[v, ω\] (from encoder rates).
    pub eta: Vel2,
}

/// What a user wants to log and plot from one step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Diagnostics {
    /// Tracking error \[e_x, e_y, e_θ\] (eq. 8).
    pub error: [f32; 3],
    /// V_K of eq. (15).
    pub lyapunov_kinematic: f32,
    /// η_c (eq. 14).
    pub eta_c: [f32; 2],
    /// dη_c/dt.
    pub eta_c_dot: [f32; 2],
    /// Sliding variable s (eq. 20).
    pub s: [f32; 2],
    /// Switching gain per channel (ρ̂, or K for SMC).
    pub rho_hat: [f32; 2],
    /// Disturbance estimate D̂ = x̂3 (zero without ESO).
    pub d_hat: [f32; 2],
    /// Fault estimate F̂ = \[Δv̂, Δω̂\] (zero without fault observer).
    pub f_hat: [f32; 2],
    /// Torque the law asked for, before saturation \[N·m\], `[right, left]`.
    pub torque_request_nm: [f32; 2],
    /// True when the request exceeded the torque limit this step.
    pub saturated: bool,
    /// Set when the input was rejected and zero torque was output.
    pub fault: Option<InputFault>,
}

/// One step's output.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StepOutput {
    /// Wheel torques `[right, left]` \[N·m\], always finite and within the limit.
    pub torque_nm: [f32; 2],
    /// Diagnostics.
    pub diag: Diagnostics,
}

/// Internal state of all loops.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct State {
    fault_obs: FaultObserverState,
    eso: EsoState,
    sliding: SlidingState,
}

/// One of the paper's controllers with its state.
#[derive(Clone, Debug)]
pub struct Controller {
    cfg: ControllerConfig,
    model: ReducedModel,
    /// ζ^(α−1) of the ESO's fal, computed once.
    fal_slope: f32,
    state: State,
    rejected_steps: u32,
}

impl Controller {
    /// Builds a controller; rejects invalid configurations.
    pub fn new(cfg: ControllerConfig) -> Result<Self, ConfigError> {
        let cfg = cfg.validate()?;
        let model = ReducedModel::new(&cfg.robot)?;
        let mut c = Self {
            cfg,
            model,
            fal_slope: cfg.eso.fal_slope(),
            state: State::default(),
            rejected_steps: 0,
        };
        c.reset();
        Ok(c)
    }

    /// The validated configuration.
    pub fn config(&self) -> &ControllerConfig {
        &self.cfg
    }

    /// The reduced model derived from the configuration.
    pub fn model(&self) -> &ReducedModel {
        &self.model
    }

    /// Number of steps rejected for bad input since construction or reset.
    pub fn rejected_steps(&self) -> u32 {
        self.rejected_steps
    }

    /// Clears every integrator and estimate.
    pub fn reset(&mut self) {
        let rho = self.cfg.sliding.rho_initial();
        self.state = State {
            sliding: SlidingState {
                integral: [0.0; 2],
                rho_hat: [rho; 2],
            },
            ..State::default()
        };
        self.rejected_steps = 0;
    }

    fn check_input(&self, input: &StepInput) -> Result<(), InputFault> {
        let l = &self.cfg.input_limits;
        if !input.pose.is_finite() {
            return Err(InputFault::NonFinitePose);
        }
        if !input.eta.is_finite() {
            return Err(InputFault::NonFiniteVelocity);
        }
        if !input.reference.is_finite() {
            return Err(InputFault::NonFiniteReference);
        }
        let far = |p: &Pose| p.x_m.abs() > l.max_position_m || p.y_m.abs() > l.max_position_m;
        if far(&input.pose) || far(&input.reference.pose) {
            return Err(InputFault::ImplausiblePosition);
        }
        if input.eta.v_mps.abs() > l.max_speed_mps
            || input.eta.omega_radps.abs() > l.max_yaw_rate_radps
        {
            return Err(InputFault::ImplausibleVelocity);
        }
        Ok(())
    }

    fn safe_output(&mut self, fault: InputFault) -> StepOutput {
        self.rejected_steps = self.rejected_steps.saturating_add(1);
        StepOutput {
            torque_nm: [0.0; 2],
            diag: Diagnostics {
                fault: Some(fault),
                rho_hat: self.state.sliding.rho_hat,
                d_hat: self.state.eso.x3,
                f_hat: self.state.fault_obs.f_hat,
                ..Diagnostics::default()
            },
        }
    }

    /// One control period: measured pose and η in, wheel torques out.
    pub fn step(&mut self, input: &StepInput) -> StepOutput {
        if let Err(f) = self.check_input(input) {
            return self.safe_output(f);
        }
        let cfg = &self.cfg;
        let dt = cfg.period_s;
        let r = &input.reference;
        let eta = input.eta.as_array();
        let proposed = cfg.kind == ControllerKind::Proposed;

        // Eq. (8).
        let te = tracking_error(&input.pose, &r.pose);
        let e = te.e;
        // Eq. (13).
        let f_hat = if proposed {
            cfg.fault_observer.update(
                &mut self.state.fault_obs,
                &te,
                eta,
                r.v_mps,
                r.omega_radps,
                dt,
            )
        } else {
            [0.0; 2]
        };
        // Eq. (14) and its analytic derivative through eq. (11).
        let kin = &cfg.kinematic;
        let eta_c = kin.eta_c(&te, r.v_mps, r.omega_radps, f_hat);
        let e_dot = error_rate(
            &te,
            eta,
            f_hat,
            r.v_mps,
            r.omega_radps,
            cfg.robot.com_offset_m,
        );
        let eta_c_dot = kin.eta_c_dot(&te, e_dot, r.v_mps, r.v_dot_mps2, r.omega_dot_radps2, f_hat);

        // Eqs. (20), (24).
        let e_eta = [eta_c[0] - eta[0], eta_c[1] - eta[1]];
        let sl = &cfg.sliding;
        let s = sl.surface(&self.state.sliding, e_eta);
        let d_hat = if proposed {
            self.state.eso.x3
        } else {
            [0.0; 2]
        };
        let m_eta = self.model.m_eta(eta);
        let accel = sl.accel_request(&self.state.sliding, eta_c_dot, m_eta, d_hat, e_eta, s);
        let request = self.model.n_inv_mul(accel);

        // Per-wheel limit, scaling both wheels by the same factor so the ratio
        // of v to ω (the steering) is kept (D14).
        let limit = cfg.torque_limit_nm;
        let peak = request[0].abs().max(request[1].abs());
        // NaN peak counts as saturated (handled below).
        let saturated = peak.is_nan() || peak > limit;
        let torque = if saturated && peak.is_finite() {
            // limit/peak·request can exceed the limit by an ulp: clamp as well.
            let k = limit / peak;
            [
                clamp_abs(request[0] * k, limit),
                clamp_abs(request[1] * k, limit),
            ]
        } else if saturated {
            [0.0; 2]
        } else {
            request
        };

        // Anti-windup: ∫e_η and ρ̂ frozen while saturated; the ESO sees the
        // applied torque.
        sl.advance(&mut self.state.sliding, e_eta, s, saturated, dt);
        if proposed {
            let n_tau = self.model.n_tau(torque);
            let known = [m_eta[0] + n_tau[0], m_eta[1] + n_tau[1]];
            cfg.eso
                .update_with_slope(&mut self.state.eso, eta, known, dt, self.fal_slope);
        }

        let diag = Diagnostics {
            error: e,
            lyapunov_kinematic: kin.lyapunov(&te),
            eta_c,
            eta_c_dot,
            s,
            rho_hat: self.state.sliding.rho_hat,
            d_hat,
            f_hat,
            torque_request_nm: request,
            saturated,
            fault: None,
        };
        if !(torque[0].is_finite() && torque[1].is_finite() && self.state_is_finite()) {
            self.reset();
            return self.safe_output(InputFault::InternalStateReset);
        }
        StepOutput {
            torque_nm: torque,
            diag,
        }
    }

    fn state_is_finite(&self) -> bool {
        let s = &self.state;
        s.fault_obs.f_hat.iter().all(|x| x.is_finite())
            && s.eso
                .e1
                .iter()
                .chain(&s.eso.x2)
                .chain(&s.eso.x3)
                .all(|x| x.is_finite())
            && s.sliding
                .integral
                .iter()
                .chain(&s.sliding.rho_hat)
                .all(|x| x.is_finite())
    }
}
