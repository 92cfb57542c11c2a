//! The sections of the robot file. Every field is documented with its unit;
//! the ranges are in [`crate::validate`] and book/src/how-to/robot-file.md.

use controller_core::asmc::{AdaptiveGain, SlidingParams, Switching};
use controller_core::eso::EsoParams;
use controller_core::fault_observer::FaultObserverGains;
use controller_core::kinematic::KinematicGains;
use controller_core::runtime::{
    BridgeMode, BridgeParams, EncoderParams, IdleMode, MotorParams, MIRRORED_LEFT,
};
use controller_core::{ControllerConfig, ControllerKind, RobotParams};
use serde::{Deserialize, Serialize};

/// Schema version this build reads and writes (`format = 1`).
pub const FORMAT: u32 = 1;
/// Longest robot name \[bytes of UTF-8\].
pub const NAME_MAX_LEN: usize = 32;
/// The robot's name (at most [`NAME_MAX_LEN`] bytes, no allocation).
pub type Name = heapless::String<NAME_MAX_LEN>;

/// A robot: everything robot-dependent the runtime, the simulator, the
/// emulated board and the firmware need.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Robot {
    /// Free-form name, 1 to 32 bytes.
    #[cfg_attr(
        feature = "std",
        schemars(with = "std::string::String", length(min = 1, max = 32))
    )]
    pub name: Name,
    /// Schema version; this build reads [`FORMAT`].
    pub format: u32,
    /// Mechanics.
    pub body: Body,
    /// Gear motors (per wheel, identical type).
    pub motors: Motors,
    /// Wheel encoders.
    pub encoders: Encoders,
    /// H-bridge wiring.
    pub bridge: Bridge,
    /// Gyro mounting.
    pub imu: Imu,
    /// Operating limits.
    pub limits: Limits,
    /// Controller gains per controller (absent = the paper's).
    #[serde(default)]
    pub gains: Gains,
    /// What runs: the controller, the clean start, the governor, the start
    /// pose (absent = the defaults of [`Control::default`]).
    #[serde(default)]
    pub control: Control,
    /// The sensors' noise the pose estimator assumes (absent = the
    /// estimator example's, a MEMS gyro and hobby encoders).
    #[serde(default)]
    pub estimator: Estimator,
}

/// `[estimator]`: what differs between robots in the pose estimator's
/// tuning: the noise of its sensors (controller-core `EstimatorConfig`;
/// the gates, counts and smoothing are the estimator's own). Every field is
/// optional, default the example's (D145). Continuous-time densities: over
/// a tick of dt the variance added is density²·dt.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(default, deny_unknown_fields)]
pub struct Estimator {
    /// Gyro angle random walk \[rad/s/√Hz\] (the data sheet's rate noise
    /// density: MPU-6050 0.005 °/s/√Hz = 8.7e-5).
    pub gyro_noise_density: f32,
    /// Gyro bias random walk \[rad/s/√s\].
    pub gyro_bias_walk: f32,
    /// White noise on the wheel-derived speed \[m/s/√Hz\].
    pub speed_noise_mps_per_sqrt_hz: f32,
    /// Relative wheel-odometry error from slip and faults (a fraction of
    /// the speed and wheel yaw rate, as a density per √s).
    pub slip_fraction: f32,
    /// White noise on the wheel yaw rate used without a gyro \[rad/s/√Hz\].
    pub wheel_yaw_noise: f32,
}

impl Default for Estimator {
    fn default() -> Self {
        let e = controller_core::estimator::EstimatorConfig::EXAMPLE;
        Self {
            gyro_noise_density: e.gyro_noise_density,
            gyro_bias_walk: e.gyro_bias_walk,
            speed_noise_mps_per_sqrt_hz: e.speed_noise_mps_per_sqrt_hz,
            slip_fraction: e.slip_fraction,
            wheel_yaw_noise: e.wheel_yaw_noise,
        }
    }
}

impl Estimator {
    /// `base` with these noises.
    pub fn apply(&self, base: &mut controller_core::estimator::EstimatorConfig) {
        base.gyro_noise_density = self.gyro_noise_density;
        base.gyro_bias_walk = self.gyro_bias_walk;
        base.speed_noise_mps_per_sqrt_hz = self.speed_noise_mps_per_sqrt_hz;
        base.slip_fraction = self.slip_fraction;
        base.wheel_yaw_noise = self.wheel_yaw_noise;
    }
}

#[derive(Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(remote = "ControllerKind", rename_all = "kebab-case")]
#[cfg_attr(feature = "std", schemars(rename = "ControllerKind"))]
enum ControllerKindDef {
    /// SMC without observer (baseline).
    Smc,
    /// ASMC without observer (baseline).
    Asmc,
    /// The paper's controller: fault observer + fal-ESO + ASMC.
    Proposed,
}

/// `[control]`: what the robot runs, beyond its mechanics: which of the
/// paper's controllers, the clean start of D23, the reference governor and
/// health machine, and the pose odometry starts from. Every field is
/// optional; the defaults are what the firmware ran before the section
/// existed (D139).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(default, deny_unknown_fields)]
pub struct Control {
    /// The controller: `"proposed"` (default), `"smc"` or `"asmc"`.
    #[serde(with = "ControllerKindDef")]
    pub controller: ControllerKind,
    /// Large-error bound of the kinematic law (D23) where the gains leave
    /// it unbounded as printed: the robot starts cleanly far from the
    /// reference. `false`: eq. (14) as printed.
    pub clean_start: bool,
    /// Reference governor and health machine on (`controller_core::pacer`).
    pub governor: bool,
    /// Where odometry starts, x \[m\].
    pub initial_x_m: f32,
    /// Where odometry starts, y \[m\].
    pub initial_y_m: f32,
    /// Where odometry starts, heading \[rad\] (counter-clockwise from +x).
    pub initial_heading_rad: f32,
}

impl Default for Control {
    fn default() -> Self {
        Self {
            controller: ControllerKind::Proposed,
            clean_start: true,
            governor: true,
            initial_x_m: 0.0,
            initial_y_m: 0.0,
            initial_heading_rad: 0.0,
        }
    }
}

impl Control {
    /// The start pose.
    pub fn initial_pose(&self) -> controller_core::Pose {
        controller_core::Pose::new(self.initial_x_m, self.initial_y_m, self.initial_heading_rad)
    }
}

/// `[body]`: mass, inertia and geometry.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Body {
    /// Total mass \[kg\].
    pub mass_kg: f32,
    /// Body yaw inertia about the vertical axis through G \[kg·m²\].
    pub inertia_kgm2: f32,
    /// Inertia of one wheel about its axle, with the reflected rotor \[kg·m²\].
    pub wheel_inertia_kgm2: f32,
    /// Distance of the centre of mass G ahead of the axle midpoint \[m\].
    pub com_offset_m: f32,
    /// Wheel radius `[right, left]` \[m\].
    pub wheel_radius_m: [f32; 2],
    /// Distance between the wheels' contact points \[m\].
    pub track_m: f32,
}

/// `[motors]`: one gear-motor type for both wheels, friction per wheel.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Motors {
    /// Torque constant k at the motor shaft \[N·m/A\] (= back-EMF constant \[V·s/rad\]).
    pub torque_constant_nm_per_a: f32,
    /// Winding resistance R \[Ω\].
    pub resistance_ohm: f32,
    /// Gear ratio N (motor turns per wheel turn).
    pub gear_ratio: f32,
    /// Gearbox efficiency η (fraction, 0..1].
    pub gear_efficiency: f32,
    /// Bridge supply voltage V \[V\].
    pub supply_voltage_v: f32,
    /// Viscous friction at the wheel `[right, left]` \[N·m·s/rad\].
    pub viscous_friction_nms_per_rad: [f32; 2],
    /// Coulomb friction at the wheel `[right, left]` \[N·m\].
    pub coulomb_friction_nm: [f32; 2],
}

/// `[encoders]`: quadrature encoders, counted ×4.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Encoders {
    /// Counts per wheel revolution after ×4 decoding and the gearbox \[counts\].
    pub counts_per_wheel_rev: f32,
    /// Counter runs backwards when the wheel drives forward `[right, left]`.
    pub inverted: [bool; 2],
    /// Speed estimate window \[control ticks\].
    pub speed_window_ticks: u8,
}

#[derive(Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(remote = "BridgeMode", rename_all = "kebab-case")]
#[cfg_attr(feature = "std", schemars(rename = "BridgeMode"))]
enum BridgeModeDef {
    /// One PWM and one DIR input per motor.
    PwmDir,
    /// Two PWM inputs per motor (IN1/IN2).
    TwoPwm,
    /// One PWM and two direction inputs per motor (TB6612/L298N).
    PwmIn1In2,
}

#[derive(Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(remote = "IdleMode", rename_all = "kebab-case")]
#[cfg_attr(feature = "std", schemars(rename = "IdleMode"))]
enum IdleModeDef {
    /// Armature shorted at zero duty.
    Brake,
    /// Bridge off at zero duty (freewheel).
    Coast,
}

/// `[bridge]`: H-bridge wiring (maps to
/// [`controller_core::runtime::BridgeParams`]) and the PWM duty limit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Bridge {
    /// Input scheme: `"pwm-dir"`, `"two-pwm"` or `"pwm-in1-in2"`.
    #[serde(with = "BridgeModeDef")]
    pub mode: BridgeMode,
    /// PWM frequency \[Hz\].
    pub pwm_frequency_hz: u32,
    /// Zero-duty behaviour while enabled: `"brake"` or `"coast"`.
    #[serde(with = "IdleModeDef")]
    pub idle: IdleMode,
    /// Largest duty the runtime commands (fraction of full scale).
    pub max_duty_fraction: f32,
    /// Swap the motor's direction output `[right, left]`.
    pub motor_inverted: [bool; 2],
}

impl Bridge {
    /// The bridge parameters of controller-core.
    pub fn params(&self) -> BridgeParams {
        BridgeParams {
            mode: self.mode,
            pwm_frequency_hz: self.pwm_frequency_hz,
            idle: self.idle,
        }
    }
}

/// Which gyro axis, with which sign, is the robot's yaw rate
/// (counter-clockwise positive seen from above).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
pub enum YawAxis {
    /// +z (chip flat, face up).
    #[serde(rename = "+z")]
    PlusZ,
    /// −z (chip flat, face down).
    #[serde(rename = "-z")]
    MinusZ,
    /// +x.
    #[serde(rename = "+x")]
    PlusX,
    /// −x.
    #[serde(rename = "-x")]
    MinusX,
    /// +y.
    #[serde(rename = "+y")]
    PlusY,
    /// −y.
    #[serde(rename = "-y")]
    MinusY,
}

impl YawAxis {
    /// Axis index (0 = x, 1 = y, 2 = z) and sign (±1).
    pub const fn axis_and_sign(self) -> (usize, f32) {
        match self {
            Self::PlusX => (0, 1.0),
            Self::MinusX => (0, -1.0),
            Self::PlusY => (1, 1.0),
            Self::MinusY => (1, -1.0),
            Self::PlusZ => (2, 1.0),
            Self::MinusZ => (2, -1.0),
        }
    }

    /// The yaw rate \[rad/s\] from a gyro's `[x, y, z]` rates \[rad/s\].
    pub fn yaw_rate_radps(self, gyro_radps: [f32; 3]) -> f32 {
        let (i, s) = self.axis_and_sign();
        s * gyro_radps[i]
    }
}

/// `[imu]`: gyro mounting.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Imu {
    /// Gyro axis and sign of the yaw rate: `"+z"`, `"-z"`, `"+x"`, `"-x"`, `"+y"`, `"-y"`.
    pub yaw_axis: YawAxis,
}

/// `[limits]`: what the robot may do.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Limits {
    /// Per-wheel torque limit the controller saturates at \[N·m\].
    pub torque_nm: f32,
    /// Largest commanded forward speed \[m/s\].
    pub max_speed_mps: f32,
    /// Largest commanded yaw rate \[rad/s\].
    pub max_yaw_rate_radps: f32,
    /// Largest commanded acceleration \[m/s²\].
    pub max_accel_mps2: f32,
    /// Controlled stop after this long without a valid frame under host control \[ms\].
    pub link_timeout_ms: u32,
}

impl Limits {
    /// The paper robot's limits: controller-core's torque limit (D14) and the
    /// link defaults of wmr-device (`LinkConfig::DEFAULT`: 1 m/s, 3 rad/s,
    /// 1 m/s², 500 ms; a wmr-device test checks they agree).
    pub fn paper() -> Self {
        Self {
            torque_nm: controller_core::controller::DEFAULT_TORQUE_LIMIT_NM,
            max_speed_mps: 1.0,
            max_yaw_rate_radps: 3.0,
            max_accel_mps2: 1.0,
            link_timeout_ms: 500,
        }
    }
}

/// `[gains.<kind>.kinematic]`: eq. (14)
/// ([`controller_core::kinematic::KinematicGains`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Kinematic {
    /// k_x \[1/s\].
    pub k_x: f32,
    /// k_y \[rad/m²\].
    pub k_y: f32,
    /// k_th \[1/s\].
    pub k_th: f32,
    /// Length L of the large-error bound of the lateral term \[m\] (0 = off, D23).
    pub large_error_m: f32,
    /// Include the printed 2·e_y·Δω̂ term (D7).
    pub printed_2ey_term: bool,
}

/// `[gains.<kind>.observer]`: the fault observer, eq. (13)
/// ([`controller_core::fault_observer::FaultObserverGains`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Observer {
    /// l_v \[1/s\].
    pub l_v: f32,
    /// l_ω \[1/s\].
    pub l_omega: f32,
    /// Bound on |F̂| `[m/s, rad/s]`.
    pub max_estimate: [f32; 2],
}

/// `[gains.<kind>.eso]`: the fal-ESO, eq. (18)
/// ([`controller_core::eso::EsoParams`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Eso {
    /// λ1, λ2, λ3.
    pub lambda: [f32; 3],
    /// ζ, half-width of fal's linear zone.
    pub zeta: f32,
    /// α in (0, 1).
    pub alpha: f32,
    /// Bound on |x̂3| `[m/s², rad/s²]`.
    pub max_disturbance: [f32; 2],
}

/// The switching gain of the sliding loop.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum SwitchingGain {
    /// Fixed gain K (plain SMC).
    Fixed {
        /// K.
        k: f32,
    },
    /// Adaptive ρ̂, eqs. (22)-(24) ([`controller_core::asmc::AdaptiveGain`]).
    Adaptive {
        /// γ, adaptation rate.
        gamma: f32,
        /// Dead zone on |s|.
        dead_zone: f32,
        /// Leakage rate σ \[1/s\].
        leakage: f32,
        /// Initial value and leakage target ρ0.
        rho0: f32,
        /// Lower bound ρ_min.
        rho_min: f32,
        /// Upper bound ρ_max.
        rho_max: f32,
    },
}

/// `[gains.<kind>.sliding]`: eqs. (20)-(24)
/// ([`controller_core::asmc::SlidingParams`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Sliding {
    /// k_s \[1/s\].
    pub k_s: f32,
    /// Switching gain.
    pub switching: SwitchingGain,
}

/// `[gains.<kind>]`: every tunable gain of one controller.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct GainSet {
    /// Kinematic law.
    pub kinematic: Kinematic,
    /// Fault observer (used by the proposed controller only).
    pub observer: Observer,
    /// fal-ESO (used by the proposed controller only).
    pub eso: Eso,
    /// Sliding loop.
    pub sliding: Sliding,
}

impl GainSet {
    /// The gains of a controller configuration.
    pub fn of(c: &ControllerConfig) -> Self {
        let k = c.kinematic;
        let f = c.fault_observer;
        let e = c.eso;
        let switching = match c.sliding.switching {
            Switching::Fixed(k) => SwitchingGain::Fixed { k },
            Switching::Adaptive(a) => SwitchingGain::Adaptive {
                gamma: a.gamma,
                dead_zone: a.dead_zone,
                leakage: a.leakage,
                rho0: a.rho0,
                rho_min: a.rho_min,
                rho_max: a.rho_max,
            },
        };
        Self {
            kinematic: Kinematic {
                k_x: k.k_x,
                k_y: k.k_y,
                k_th: k.k_th,
                large_error_m: k.large_error_m,
                printed_2ey_term: k.printed_2ey_term,
            },
            observer: Observer {
                l_v: f.l_v,
                l_omega: f.l_omega,
                max_estimate: f.max_estimate,
            },
            eso: Eso {
                lambda: e.lambda,
                zeta: e.zeta,
                alpha: e.alpha,
                max_disturbance: e.max_disturbance,
            },
            sliding: Sliding {
                k_s: c.sliding.k_s,
                switching,
            },
        }
    }

    /// The paper's gains for `kind` (`ControllerConfig::paper(kind)`).
    pub fn paper(kind: ControllerKind) -> Self {
        Self::of(&ControllerConfig::paper(kind))
    }

    /// Writes these gains into `c`.
    pub fn apply(&self, c: &mut ControllerConfig) {
        let k = self.kinematic;
        c.kinematic = KinematicGains {
            k_x: k.k_x,
            k_y: k.k_y,
            k_th: k.k_th,
            printed_2ey_term: k.printed_2ey_term,
            large_error_m: k.large_error_m,
        };
        c.fault_observer = FaultObserverGains {
            l_v: self.observer.l_v,
            l_omega: self.observer.l_omega,
            max_estimate: self.observer.max_estimate,
        };
        c.eso = EsoParams {
            lambda: self.eso.lambda,
            zeta: self.eso.zeta,
            alpha: self.eso.alpha,
            max_disturbance: self.eso.max_disturbance,
        };
        c.sliding = SlidingParams {
            k_s: self.sliding.k_s,
            switching: match self.sliding.switching {
                SwitchingGain::Fixed { k } => Switching::Fixed(k),
                SwitchingGain::Adaptive {
                    gamma,
                    dead_zone,
                    leakage,
                    rho0,
                    rho_min,
                    rho_max,
                } => Switching::Adaptive(AdaptiveGain {
                    gamma,
                    dead_zone,
                    leakage,
                    rho0,
                    rho_min,
                    rho_max,
                }),
            },
        };
    }
}

/// `[gains]`: one optional section per controller; an absent one means the
/// paper's Table 2 gains (`ControllerConfig::paper(kind)`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "std", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Gains {
    /// The proposed controller.
    #[serde(default)]
    pub proposed: Option<GainSet>,
    /// SMC without observer.
    #[serde(default)]
    pub smc: Option<GainSet>,
    /// ASMC without observer.
    #[serde(default)]
    pub asmc: Option<GainSet>,
}

impl Gains {
    /// No section: every controller runs the paper's gains.
    pub fn is_empty(&self) -> bool {
        self.proposed.is_none() && self.smc.is_none() && self.asmc.is_none()
    }

    /// The section for `kind` (`None` = the paper's gains).
    pub fn of(&self, kind: ControllerKind) -> Option<&GainSet> {
        match kind {
            ControllerKind::Proposed => self.proposed.as_ref(),
            ControllerKind::Smc => self.smc.as_ref(),
            ControllerKind::Asmc => self.asmc.as_ref(),
        }
    }

    /// The section for `kind`, to write.
    pub fn of_mut(&mut self, kind: ControllerKind) -> &mut Option<GainSet> {
        match kind {
            ControllerKind::Proposed => &mut self.proposed,
            ControllerKind::Smc => &mut self.smc,
            ControllerKind::Asmc => &mut self.asmc,
        }
    }

    /// The gains `kind` runs with: its section, or the paper's.
    pub fn resolved(&self, kind: ControllerKind) -> GainSet {
        self.of(kind)
            .copied()
            .unwrap_or_else(|| GainSet::paper(kind))
    }
}

impl Robot {
    /// The paper's robot (Table 1) with controller-core's example motor,
    /// encoder, bridge and the link defaults, built from those constants.
    pub fn paper() -> Self {
        let p = RobotParams::paper();
        let m = MotorParams::EXAMPLE;
        let e = EncoderParams::EXAMPLE;
        let b = BridgeParams::EXAMPLE;
        let mut name = Name::new();
        // "paper" is 5 bytes < NAME_MAX_LEN.
        let _ = name.push_str("paper");
        Self {
            name,
            format: FORMAT,
            body: Body {
                mass_kg: p.mass_kg,
                inertia_kgm2: p.inertia_kgm2,
                wheel_inertia_kgm2: p.wheel_inertia_kgm2,
                com_offset_m: p.com_offset_m,
                wheel_radius_m: [p.wheel_radius_m; 2],
                track_m: 2.0 * p.half_track_m,
            },
            motors: Motors {
                torque_constant_nm_per_a: m.torque_constant_nm_per_a,
                resistance_ohm: m.winding_resistance_ohm,
                gear_ratio: m.gear_ratio,
                gear_efficiency: m.gear_efficiency,
                supply_voltage_v: m.supply_voltage_v,
                // The paper's model has no friction.
                viscous_friction_nms_per_rad: [0.0; 2],
                coulomb_friction_nm: [0.0; 2],
            },
            encoders: Encoders {
                counts_per_wheel_rev: e.counts_per_wheel_rev,
                inverted: e.inverted,
                speed_window_ticks: e.speed_window_ticks,
            },
            bridge: Bridge {
                mode: b.mode,
                pwm_frequency_hz: b.pwm_frequency_hz,
                idle: b.idle,
                max_duty_fraction: m.max_duty_fraction,
                motor_inverted: MIRRORED_LEFT,
            },
            imu: Imu {
                yaw_axis: YawAxis::PlusZ,
            },
            limits: Limits::paper(),
            gains: Gains::default(),
            control: Control::default(),
            estimator: Estimator::default(),
        }
    }
}
