//! The three controllers of section 4 behind one type.
//!
//! | kind | kinematic loop | dynamic loop |
//! |---|---|---|
//! | [`ControllerKind::Smc`] | eq. (14), F̂ = 0 | eq. (24) with fixed gain K, no ESO |
//! | [`ControllerKind::Asmc`] | eq. (14), F̂ = 0 | eq. (24) with adaptive ρ̂, no ESO |
//! | [`ControllerKind::Proposed`] | eq. (14) + fault observer (13) | eq. (24), adaptive ρ̂, fal-ESO (18) |
//!
//! One [`Controller::step`] per control period. The step is the sequence of
//! public stages of [`ControlLaw`] (input check, kinematic loop, dynamic loop,
//! [`saturate`], state advance, diagnostics), each taking the parameters as
//! `&self` and the [`ControllerState`] it reads or advances as an argument, so
//! a benchmark or a test can run and time the very code the step runs.
//!
//! Inputs are validated first: a NaN, infinite or implausible measurement or
//! reference yields zero torque and [`Diagnostics::fault`]; the controller's
//! state is left untouched, so it recovers on the next valid sample (the
//! firmware's supervisor decides when to latch a safe stop).

use crate::asmc::{AdaptiveGain, SlidingParams, SlidingState, Switching};
use crate::error::{ConfigError, InputFault};
use crate::eso::{EsoParams, EsoState};
use crate::fault_observer::{FaultObserverGains, FaultObserverState};
use crate::friction::FrictionModel;
use crate::kinematic::KinematicGains;
use crate::math::{all_finite, clamp_abs};
use crate::math::{all_non_negative, all_positive};
use crate::model::ReducedModel;
use crate::params::RobotParams;
use crate::tracking::{error_rate, tracking_error, TrackingError};
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

impl InputLimits {
    /// The defaults (also [`Default::default`]); a constant so that
    /// configurations built from it are data, not code.
    pub const DEFAULT: Self = Self {
        max_position_m: 1000.0,
        max_speed_mps: 10.0,
        max_yaw_rate_radps: 30.0,
    };
}

impl Default for InputLimits {
    fn default() -> Self {
        Self::DEFAULT
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
    /// The wheels' friction, compensated in the dynamic loop of every kind
    /// (eqs. 7f, 24f; [`FrictionModel::NONE`]: the paper's model).
    pub friction: FrictionModel,
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
    pub const fn paper(kind: ControllerKind) -> Self {
        let (k_s, switching) = match kind {
            ControllerKind::Smc => (5.0, Switching::Fixed(DEFAULT_SMC_GAIN)),
            ControllerKind::Asmc => (5.0, Switching::Adaptive(AdaptiveGain::DEFAULT)),
            ControllerKind::Proposed => (50.0, Switching::Adaptive(AdaptiveGain::DEFAULT)),
        };
        Self {
            kind,
            robot: RobotParams::paper(),
            kinematic: KinematicGains {
                k_y: DEFAULT_K_Y,
                ..KinematicGains::paper()
            },
            fault_observer: FaultObserverGains::DEFAULT,
            eso: EsoParams::DEFAULT,
            sliding: SlidingParams { k_s, switching },
            torque_limit_nm: DEFAULT_TORQUE_LIMIT_NM,
            friction: FrictionModel::NONE,
            period_s: 1e-3,
            input_limits: InputLimits::DEFAULT,
        }
    }

    /// Validates every part.
    pub fn validate(self) -> Result<Self, ConfigError> {
        self.robot.validate()?;
        self.kinematic.validate()?;
        self.fault_observer.validate()?;
        self.eso.validate()?;
        self.sliding.validate()?;
        if !all_positive(&[self.torque_limit_nm]) {
            return Err(ConfigError::NonPositiveTorqueLimit);
        }
        self.friction.validate(self.torque_limit_nm)?;
        // 0 < period <= 0.1 s.
        if !(all_positive(&[self.period_s]) && all_non_negative(&[0.1 - self.period_s])) {
            return Err(ConfigError::InvalidPeriod);
        }
        let l = self.input_limits;
        if !all_positive(&[l.max_position_m, l.max_speed_mps, l.max_yaw_rate_radps]) {
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

/// State of all loops: what [`Controller::reset`] clears and the
/// [`ControlLaw`] stages advance. The parameters live apart, in [`ControlLaw`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ControllerState {
    /// Fault observer, eq. (13) (advanced by `Proposed` only).
    pub fault_observer: FaultObserverState,
    /// fal-ESO, eq. (18) (advanced by `Proposed` only).
    pub eso: EsoState,
    /// ∫e_η and ρ̂ of the sliding loop, eqs. (20)-(24).
    pub sliding: SlidingState,
}

impl ControllerState {
    /// True when every integrator and estimate is finite.
    #[inline]
    pub fn is_finite(&self) -> bool {
        let (f, e, s) = (&self.fault_observer, &self.eso, &self.sliding);
        all_finite([
            f.f_hat[0],
            f.f_hat[1],
            e.e1[0],
            e.e1[1],
            e.x2[0],
            e.x2[1],
            e.x3[0],
            e.x3[1],
            s.integral[0],
            s.integral[1],
            s.rho_hat[0],
            s.rho_hat[1],
        ])
    }
}

/// What the kinematic stage ([`ControlLaw::kinematic`]) hands to the dynamic one.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct KinematicOutput {
    /// Tracking error (eq. 8) with its sin e_θ and cos e_θ.
    pub error: TrackingError,
    /// Fault estimate F̂ = \[Δv̂, Δω̂\] (eq. 13; zero without fault observer).
    pub f_hat: [f32; 2],
    /// η_c = \[v_c, ω_c\] (eq. 14).
    pub eta_c: [f32; 2],
    /// dη_c/dt (eq. 14 differentiated through eq. 11).
    pub eta_c_dot: [f32; 2],
}

/// What the dynamic stage ([`ControlLaw::dynamic`]) computes: the torque
/// request and the quantities the state advance needs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DynamicOutput {
    /// Velocity error e_η = η_c − η \[m/s, rad/s\].
    pub e_eta: [f32; 2],
    /// Sliding variable s (eq. 20).
    pub s: [f32; 2],
    /// Disturbance estimate D̂ = x̂3 the law used (zero without ESO).
    pub d_hat: [f32; 2],
    /// Mη at the measured η (eq. 7), less N·τ̂_f with friction (eq. 7f):
    /// the model's acceleration besides N·τ, which the ESO adds to the
    /// applied torque's (so it estimates what the friction model misses).
    pub m_eta: [f32; 2],
    /// Torque of eq. (24f) (eq. 24 plus τ̂_f) before saturation \[N·m\],
    /// `[right, left]`.
    pub torque_request_nm: [f32; 2],
}

/// Result of [`saturate`]: the torque to apply and whether it was limited.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SaturatedTorque {
    /// Wheel torques `[right, left]` \[N·m\], within the limit (zero for a
    /// non-finite request).
    pub torque_nm: [f32; 2],
    /// True when the request exceeded the limit or was not finite.
    pub saturated: bool,
}

/// Per-wheel torque limit that scales both wheels by the same factor, so the
/// ratio of v to ω (the steering) is kept (D14). `limit_nm` must be positive.
///
/// An infinite or all-NaN request gives zero torque and counts as saturated.
/// `f32::max` ignores a NaN, so a request with one NaN wheel whose other
/// wheel is within the limit passes through unchanged: [`Controller::step`]
/// catches that afterwards (non-finite torque: zero output and a reset,
/// [`InputFault::InternalStateReset`]).
#[inline]
pub fn saturate(request_nm: [f32; 2], limit_nm: f32) -> SaturatedTorque {
    // f32::max without the libcall (the M4F has no VMAXNM: `max` calls
    // fmaxf, ~20 instructions); the same value, a NaN ignored as by `max`.
    let (a, b) = (request_nm[0].abs(), request_nm[1].abs());
    let peak = if b > a || a.is_nan() { b } else { a };
    // NaN peak counts as saturated (handled below).
    let saturated = peak.is_nan() || peak > limit_nm;
    let torque_nm = if saturated && peak.is_finite() {
        // limit/peak·request can exceed the limit by an ulp: clamp as well.
        let k = limit_nm / peak;
        [
            clamp_abs(request_nm[0] * k, limit_nm),
            clamp_abs(request_nm[1] * k, limit_nm),
        ]
    } else if saturated {
        [0.0; 2]
    } else {
        request_nm
    };
    SaturatedTorque {
        torque_nm,
        saturated,
    }
}

/// The validated parameters of one controller, and the stages that
/// [`Controller::step`] runs in this order (each parameter-only `&self`, with
/// the state passed in):
///
/// 1. [`Self::check_input`]: plausibility of the measurement and reference;
/// 2. [`Self::kinematic`]: tracking error (eq. 8), fault observer (eq. 13),
///    η_c and η̇_c (eq. 14);
/// 3. [`Self::dynamic`]: sliding surface and torque request (eqs. 20, 24);
/// 4. [`saturate`] with [`ControllerConfig::torque_limit_nm`] (D14);
/// 5. [`Self::advance`]: ∫e_η and ρ̂ with anti-windup, fal-ESO (eqs. 18-19),
///    given the torque actually applied;
/// 6. [`Self::diagnostics`] and [`ControllerState::is_finite`].
///
/// Calling them yourself on a [`ControllerState`] from
/// [`Self::initial_state`] gives bit for bit what [`Controller::step`]
/// gives (the Cortex-M4F benchmark times them this way).
#[derive(Clone, Debug)]
pub struct ControlLaw {
    cfg: ControllerConfig,
    model: ReducedModel,
    /// ζ^(α−1) of the ESO's fal, computed once.
    fal_slope: f32,
    /// Any friction to compensate (false: the stage costs nothing).
    friction_on: bool,
    /// 1/r of the model \[1/m\], for the reference's wheel rates.
    inv_wheel_radius_per_m: f32,
}

impl ControlLaw {
    /// Validates `cfg` and derives the model and constants.
    pub fn new(cfg: ControllerConfig) -> Result<Self, ConfigError> {
        let cfg = cfg.validate()?;
        let model = ReducedModel::new(&cfg.robot)?;
        Ok(Self {
            cfg,
            model,
            fal_slope: cfg.eso.fal_slope(),
            friction_on: cfg.friction.is_some(),
            inv_wheel_radius_per_m: 1.0 / cfg.robot.wheel_radius_m,
        })
    }

    /// The validated configuration.
    pub fn config(&self) -> &ControllerConfig {
        &self.cfg
    }

    /// The reduced model derived from the configuration.
    pub fn model(&self) -> &ReducedModel {
        &self.model
    }

    /// The state at start and after a reset: integrators and estimates zero,
    /// ρ̂ at its initial value (or K for the SMC).
    pub fn initial_state(&self) -> ControllerState {
        let rho = self.cfg.sliding.rho_initial();
        ControllerState {
            sliding: SlidingState {
                integral: [0.0; 2],
                rho_hat: [rho; 2],
            },
            ..ControllerState::default()
        }
    }

    /// Stage 1: rejects non-finite or implausible input.
    ///
    /// The common case (all plausible) costs one compare per bounded value
    /// (|x| <= limit is false for NaN and ±∞ too) and one [`all_finite`]
    /// for the unbounded ones; only a rejected input goes through the
    /// checks one by one to name the fault, in the documented order
    /// (non-finite pose, velocity, reference; implausible position,
    /// velocity). Same result as checking each in that order (tested).
    #[inline]
    pub fn check_input(&self, input: &StepInput) -> Result<(), InputFault> {
        let l = &self.cfg.input_limits;
        let (p, r, e) = (&input.pose, &input.reference, &input.eta);
        let within = |x: f32, limit: f32| x.abs() <= limit;
        let pos = l.max_position_m;
        if within(p.x_m, pos)
            && within(p.y_m, pos)
            && within(r.pose.x_m, pos)
            && within(r.pose.y_m, pos)
            && within(e.v_mps, l.max_speed_mps)
            && within(e.omega_radps, l.max_yaw_rate_radps)
            && all_finite([
                p.theta_rad,
                r.pose.theta_rad,
                r.v_mps,
                r.omega_radps,
                r.v_dot_mps2,
                r.omega_dot_radps2,
            ])
        {
            return Ok(());
        }
        self.name_input_fault(input)
    }

    /// The fault of an input that [`Self::check_input`] rejected, checked
    /// one by one in the documented order.
    #[cold]
    #[inline(never)]
    fn name_input_fault(&self, input: &StepInput) -> Result<(), InputFault> {
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

    /// Stage 2, the kinematic loop: tracking error (eq. 8), the fault
    /// observer (eq. 13, `Proposed` only: it advances `observer`), η_c
    /// (eq. 14) and its analytic derivative through eq. (11).
    #[inline]
    pub fn kinematic(
        &self,
        observer: &mut FaultObserverState,
        input: &StepInput,
    ) -> KinematicOutput {
        let cfg = &self.cfg;
        let r = &input.reference;
        let eta = input.eta.as_array();
        // Eq. (8).
        let te = tracking_error(&input.pose, &r.pose);
        // Eq. (13).
        let f_hat = if cfg.kind == ControllerKind::Proposed {
            cfg.fault_observer
                .update(observer, &te, eta, r.v_mps, r.omega_radps, cfg.period_s)
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
        KinematicOutput {
            error: te,
            f_hat,
            eta_c,
            eta_c_dot,
        }
    }

    /// Stage 3, the dynamic loop: sliding surface (eq. 20) and the torque
    /// request of eq. (24) with D̂ = x̂3 (`Proposed` only), from the measured
    /// η and the kinematic stage, plus the friction at the wheel rates of
    /// the dynamic loop's reference η_c (eq. 24f). Reads the state, changes
    /// nothing.
    #[inline]
    pub fn dynamic(
        &self,
        state: &ControllerState,
        eta: Vel2,
        kin: &KinematicOutput,
    ) -> DynamicOutput {
        let eta = eta.as_array();
        let eta_c = kin.eta_c;
        let e_eta = [eta_c[0] - eta[0], eta_c[1] - eta[1]];
        let sl = &self.cfg.sliding;
        let s = sl.surface(&state.sliding, e_eta);
        let d_hat = if self.cfg.kind == ControllerKind::Proposed {
            state.eso.x3
        } else {
            [0.0; 2]
        };
        let m_eta = self.model.m_eta(eta);
        let accel = sl.accel_request(&state.sliding, kin.eta_c_dot, m_eta, d_hat, e_eta, s);
        let mut torque = self.model.n_inv_mul(accel);
        let mut m_eta = m_eta;
        // Eq. (24f): + τ̂_f at the wheel rates η_c asks for; eq. (7f) for the ESO.
        if self.friction_on {
            let rates = crate::params::wheel_rates(
                self.inv_wheel_radius_per_m,
                self.cfg.robot.half_track_m,
                eta_c,
            );
            let f = self.cfg.friction.torque_nm(rates);
            torque = [torque[0] + f[0], torque[1] + f[1]];
            let n_f = self.model.n_tau(f);
            m_eta = [m_eta[0] - n_f[0], m_eta[1] - n_f[1]];
        }
        DynamicOutput {
            e_eta,
            s,
            d_hat,
            m_eta,
            torque_request_nm: torque,
        }
    }

    /// Stage 5, the state advance over one period, given the torque actually
    /// applied: ∫e_η and ρ̂ are frozen while `applied.saturated`
    /// (anti-windup), and the fal-ESO (eqs. 18-19, `Proposed` only) sees
    /// `applied.torque_nm` with the friction model's acceleration (eq. 7f,
    /// in `dynamic.m_eta`: it estimates what the friction model misses).
    #[inline]
    pub fn advance(
        &self,
        state: &mut ControllerState,
        eta: Vel2,
        dynamic: &DynamicOutput,
        applied: &SaturatedTorque,
    ) {
        let cfg = &self.cfg;
        let dt = cfg.period_s;
        cfg.sliding.advance(
            &mut state.sliding,
            dynamic.e_eta,
            dynamic.s,
            applied.saturated,
            dt,
        );
        if cfg.kind == ControllerKind::Proposed {
            let m_eta = dynamic.m_eta;
            let n_tau = self.model.n_tau(applied.torque_nm);
            let known = [m_eta[0] + n_tau[0], m_eta[1] + n_tau[1]];
            cfg.eso
                .update_with_slope(&mut state.eso, eta.as_array(), known, dt, self.fal_slope);
        }
    }

    /// Stage 6: the step's [`Diagnostics`] (ρ̂ from `state` after
    /// [`Self::advance`]; V_K of eq. 15 computed here).
    #[inline]
    pub fn diagnostics(
        &self,
        state: &ControllerState,
        kin: &KinematicOutput,
        dynamic: &DynamicOutput,
        applied: &SaturatedTorque,
    ) -> Diagnostics {
        Diagnostics {
            error: kin.error.e,
            lyapunov_kinematic: self.cfg.kinematic.lyapunov(&kin.error),
            eta_c: kin.eta_c,
            eta_c_dot: kin.eta_c_dot,
            s: dynamic.s,
            rho_hat: state.sliding.rho_hat,
            d_hat: dynamic.d_hat,
            f_hat: kin.f_hat,
            torque_request_nm: dynamic.torque_request_nm,
            saturated: applied.saturated,
            fault: None,
        }
    }
}

/// One of the paper's controllers with its state.
#[derive(Clone, Debug)]
pub struct Controller {
    law: ControlLaw,
    state: ControllerState,
    rejected_steps: u32,
}

impl Controller {
    /// Builds a controller; rejects invalid configurations.
    pub fn new(cfg: ControllerConfig) -> Result<Self, ConfigError> {
        let law = ControlLaw::new(cfg)?;
        Ok(Self {
            state: law.initial_state(),
            law,
            rejected_steps: 0,
        })
    }

    /// The validated configuration.
    pub fn config(&self) -> &ControllerConfig {
        self.law.config()
    }

    /// The reduced model derived from the configuration.
    pub fn model(&self) -> &ReducedModel {
        self.law.model()
    }

    /// The parameters and stages [`Self::step`] runs.
    pub fn law(&self) -> &ControlLaw {
        &self.law
    }

    /// The loops' current state.
    pub fn state(&self) -> &ControllerState {
        &self.state
    }

    /// Number of steps rejected for bad input since construction or reset.
    pub fn rejected_steps(&self) -> u32 {
        self.rejected_steps
    }

    /// Clears every integrator and estimate.
    pub fn reset(&mut self) {
        self.state = self.law.initial_state();
        self.rejected_steps = 0;
    }

    fn safe_output(&mut self, fault: InputFault) -> StepOutput {
        self.rejected_steps = self.rejected_steps.saturating_add(1);
        StepOutput {
            torque_nm: [0.0; 2],
            diag: Diagnostics {
                fault: Some(fault),
                rho_hat: self.state.sliding.rho_hat,
                d_hat: self.state.eso.x3,
                f_hat: self.state.fault_observer.f_hat,
                ..Diagnostics::default()
            },
        }
    }

    /// One control period: measured pose and η in, wheel torques out. The
    /// stages of [`ControlLaw`] in order; a non-finite result resets the state.
    pub fn step(&mut self, input: &StepInput) -> StepOutput {
        let law = &self.law;
        if let Err(f) = law.check_input(input) {
            return self.safe_output(f);
        }
        let state = &mut self.state;
        let kin = law.kinematic(&mut state.fault_observer, input);
        let dynamic = law.dynamic(state, input.eta, &kin);
        let applied = saturate(dynamic.torque_request_nm, law.cfg.torque_limit_nm);
        law.advance(state, input.eta, &dynamic, &applied);
        let diag = law.diagnostics(state, &kin, &dynamic, &applied);
        let torque = applied.torque_nm;
        if !(all_finite(torque) && state.is_finite()) {
            self.reset();
            return self.safe_output(InputFault::InternalStateReset);
        }
        StepOutput {
            torque_nm: torque,
            diag,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Some request/limit pairs make limit/peak·peak round above the limit;
    /// the saturated torque must still be within it.
    #[test]
    fn saturate_never_exceeds_the_limit_by_an_ulp() {
        let (peak, limit) = (151.993f32, 10.0f32);
        assert!(peak * (limit / peak) > limit, "not an ulp case");
        let out = saturate([peak, -20.0], limit);
        assert!(out.saturated);
        assert_eq!(out.torque_nm[0], limit);
        assert!(out.torque_nm[1].abs() <= limit);
    }

    #[test]
    fn saturate_infinite_or_nan_request_gives_zero() {
        for bad in [
            [f32::NAN; 2],
            [f32::INFINITY, 1.0],
            [-1.0, f32::NEG_INFINITY],
        ] {
            let out = saturate(bad, 10.0);
            assert!(out.saturated);
            assert_eq!(out.torque_nm, [0.0; 2]);
        }
    }

    /// Values around the default limits (1000 m, 10 m/s, 30 rad/s), at them,
    /// and non-finite ones.
    fn edgy() -> impl Strategy<Value = f32> {
        prop_oneof![
            4 => -50.0f32..50.0,
            1 => -2000.0f32..2000.0,
            1 => prop::sample::select(vec![
                1000.0f32, -1000.0, 10.0, -10.0, 30.0, -30.0, 1000.0001, 10.000001,
                f32::MAX, f32::INFINITY, f32::NEG_INFINITY, f32::NAN,
            ]),
        ]
    }

    proptest! {
        /// The fused stage 1 gives the same verdict and the same fault as
        /// the checks one by one.
        #[test]
        fn check_input_equals_checks_one_by_one(v in prop::collection::vec(edgy(), 13)) {
            let law = ControlLaw::new(ControllerConfig::paper(ControllerKind::Proposed)).unwrap();
            let input = StepInput {
                reference: RefSample {
                    pose: Pose::new(v[0], v[1], v[2]),
                    v_mps: v[3],
                    omega_radps: v[4],
                    v_dot_mps2: v[5],
                    omega_dot_radps2: v[6],
                },
                pose: Pose::new(v[7], v[8], v[9]),
                eta: Vel2::new(v[10], v[11]),
            };
            // The fast checks give the verdict of the one-by-one checks
            // (`name_input_fault`, which names the fault on the cold path).
            prop_assert_eq!(law.check_input(&input), law.name_input_fault(&input));
        }

        /// Within the limit the request passes unchanged; beyond it the larger
        /// wheel gets the limit and the ratio between the wheels is kept (D14).
        #[test]
        fn saturate_limits_and_keeps_the_ratio(
            r0 in -1e4f32..1e4,
            r1 in -1e4f32..1e4,
            limit in 0.01f32..100.0,
        ) {
            let out = saturate([r0, r1], limit);
            let peak = r0.abs().max(r1.abs());
            prop_assert!(out.torque_nm.iter().all(|t| t.abs() <= limit));
            if peak <= limit {
                prop_assert!(!out.saturated);
                prop_assert_eq!(out.torque_nm, [r0, r1]);
            } else {
                prop_assert!(out.saturated);
                let t_peak = out.torque_nm[0].abs().max(out.torque_nm[1].abs());
                prop_assert!((t_peak - limit).abs() <= 2.0 * f32::EPSILON * limit);
                // Same ratio: t0·r1 = t1·r0 up to rounding.
                let cross = (out.torque_nm[0] * r1 - out.torque_nm[1] * r0).abs();
                prop_assert!(cross <= 4.0 * f32::EPSILON * limit * peak);
            }
        }
    }

    /// The stages run by hand on a separate state, in the documented order,
    /// give bit for bit the output and the state of `Controller::step`, for
    /// every kind, through saturated and unsaturated steps.
    #[test]
    fn stages_in_order_equal_step() {
        for kind in ControllerKind::ALL {
            let mut ctrl = Controller::new(ControllerConfig::paper(kind)).unwrap();
            let law = ctrl.law().clone();
            let mut state = law.initial_state();
            assert_eq!(&state, ctrl.state());
            let mut saturated_steps = 0;
            for k in 0..3000 {
                let t = k as f32 * 1e-3;
                // A robot near a circle of radius 2 m, knocked backwards for
                // 50 ms (which saturates the torque of every kind).
                let (s, c) = crate::math::sin_cos(0.5 * t);
                let heading = 0.5 * t + core::f32::consts::FRAC_PI_2;
                let kick = if (1000..1050).contains(&k) { 6.0 } else { 0.0 };
                let input = StepInput {
                    reference: RefSample {
                        pose: Pose::new(2.0 * c, 2.0 * s, heading),
                        v_mps: 1.0,
                        omega_radps: 0.5,
                        v_dot_mps2: 0.0,
                        omega_dot_radps2: 0.0,
                    },
                    pose: Pose::new(2.0 * c + 0.02, 2.0 * s - 0.01, heading + 0.02),
                    eta: Vel2::new(1.0 + 0.05 * s - kick, 0.5 + 0.05 * c),
                };
                let out = ctrl.step(&input);
                law.check_input(&input).unwrap();
                let kin = law.kinematic(&mut state.fault_observer, &input);
                let dynamic = law.dynamic(&state, input.eta, &kin);
                let applied = saturate(dynamic.torque_request_nm, law.config().torque_limit_nm);
                law.advance(&mut state, input.eta, &dynamic, &applied);
                let diag = law.diagnostics(&state, &kin, &dynamic, &applied);
                assert!(state.is_finite());
                let bits = |a: [f32; 2]| a.map(f32::to_bits);
                assert_eq!(
                    bits(out.torque_nm),
                    bits(applied.torque_nm),
                    "{kind:?} step {k}"
                );
                assert_eq!(out.diag, diag, "{kind:?} step {k}");
                assert_eq!(ctrl.state(), &state, "{kind:?} step {k}");
                saturated_steps += applied.saturated as u32;
            }
            assert!(
                saturated_steps > 0 && saturated_steps < 3000,
                "{kind:?}: {saturated_steps} saturated steps"
            );
        }
    }
}
