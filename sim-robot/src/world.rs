//! The one simulated world: the plant and its state, the section-4
//! perturbations, the injected faults and the instruments between the
//! plant and whatever controls it, advanced and read in one place.
//!
//! Every closed loop of the project (hil-sim's runs and its simulated robot
//! behind the host link, the closed-loop tests, robot-app's test board, the
//! Cortex-M4F benchmark, the emulated board) closes through a [`World`]:
//!
//! 1. [`World::sense`] at the period's start time t: the true state, and the
//!    instruments' readings: exact measurements with ideal sensing
//!    ([`Instruments::Ideal`]); otherwise the 16-bit encoder counters, the
//!    gyro and the external pose source ([`Instruments::Hardware`]), read
//!    through the runtime's hardware traits ([`World::io`]).
//! 2. the controller side runs (the bare controller, or the firmware runtime
//!    writing the world's H-bridge);
//! 3. [`World::advance`] over the period with the actuation held: wheel
//!    torques (an ideal torque source) or the H-bridge's duty into the
//!    DC-motor model (torque at each integration stage's wheel rates), each
//!    wheel delivering `wheel_torque_scale` of it inside the perturbation
//!    window.
//!
//! Ideal sensing is a configuration of the world, not a second simulator:
//! the true pose of G (plus optional Gaussian noise) and the wheel rates
//! from the exact wheel-angle change over the last period, torques applied
//! exactly.

use crate::hardware::{MotorDrive, SimDriver, SimEncoders};
use crate::perturbation::{PerturbationGrid, PerturbationProfile};
use crate::plant::{
    Drive, Perturbation, Plant, PlantParams, PlantParamsError, PlantState, TorqueScaled,
};
use crate::sensors::{
    GyroModel, PoseSourceModel, PoseSourceStats, SensorModelError, SimGyro, SimPoseSource, SimRng,
};
use controller_core::estimator::{GyroSample, PoseMeasurement};
use controller_core::runtime::{
    EncoderParams, Gyro, MotorModel, MotorParams, PoseSource, WheelEncoders,
};
use controller_core::Pose;

/// Control periods of command history the actuation delay may need
/// (delay <= (MAX_DELAY_PERIODS − 1) periods).
pub const MAX_DELAY_PERIODS: usize = 32;

/// Salt of the gyro's noise seed (`seed ^ GYRO_SEED_SALT`).
pub const GYRO_SEED_SALT: u64 = 0x6779_726F;
/// Salt of the external pose source's noise seed (`seed ^ POSE_SEED_SALT`).
pub const POSE_SEED_SALT: u64 = 0x706F_7365;

/// The seed of ideal sensing's measurement noise for a world seed (kept
/// apart from the sensors' seeds).
pub fn ideal_noise_seed(seed: u64) -> u64 {
    seed.wrapping_mul(0x2545_F491_4F6C_DD1D).wrapping_add(17)
}

/// Ideal sensing: exact measurements and an ideal torque source.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdealSensing {
    /// Std. dev. of the noise on each measured position coordinate \[m\].
    pub position_noise_m: f64,
    /// Std. dev. of the noise on the measured heading \[rad\].
    pub heading_noise_rad: f64,
    /// The period over which the wheel-angle change is taken as a rate
    /// \[s\] (the controller's own period, as it sees it).
    pub rate_period_s: f64,
}

/// The simulated hardware: encoders, the H-bridge into the DC motors, and
/// optionally a gyro and an external pose source. Every value is the
/// *plant's*, what the robot has, which may differ from what the runtime
/// believes (its `RuntimeConfig`): a plant motor of another torque constant,
/// encoders of another resolution ([`WorldConfig::of_runtime`] makes them
/// equal).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HardwareSensing {
    /// The plant's quadrature encoders (resolution, mounting).
    pub encoder: EncoderParams,
    /// The plant's motors behind the H-bridge (torque constant, resistance,
    /// gear, efficiency, supply), run forward by the runtime's
    /// [`MotorModel`] formulas.
    pub motor: MotorParams,
    /// Per wheel: the motor is mounted mirrored.
    pub motor_inverted: [bool; 2],
    /// The z-gyro, if any.
    pub gyro: Option<GyroModel>,
    /// The external pose source (motion capture, UWB...), if any.
    pub pose_source: Option<PoseSourceModel>,
}

/// What sits between the plant and the controller side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Instruments {
    /// Exact measurements, an ideal torque source (the paper's setting).
    Ideal(IdealSensing),
    /// Encoders, H-bridge, gyro and pose source in raw units.
    Hardware(HardwareSensing),
}

/// A dead encoder: from `from_s` on, wheel `wheel` (0 = right, 1 = left)
/// stops counting (a broken wire).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeadEncoder {
    /// 0 = right, 1 = left.
    pub wheel: usize,
    /// Time the encoder dies \[s\].
    pub from_s: f64,
}

/// Wiring mistakes between the board and the robot (hardware sensing only),
/// on top of the configured mountings: what commissioning must catch.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Wiring {
    /// Per wheel `[right, left]`: the encoder's A/B lines swapped (it
    /// counts opposite to its configured direction).
    pub encoder_inverted: [bool; 2],
    /// Per wheel: the motor's leads swapped (it turns opposite to its
    /// configured direction).
    pub motor_inverted: [bool; 2],
    /// The bridge's right channel drives the left wheel's motor and the
    /// left channel the right one.
    pub motors_swapped: bool,
    /// The right encoder counter reads the left wheel's encoder and the
    /// left counter the right one's.
    pub encoders_swapped: bool,
}

impl Wiring {
    /// Wired as configured.
    pub const CORRECT: Self = Self {
        encoder_inverted: [false; 2],
        motor_inverted: [false; 2],
        motors_swapped: false,
        encoders_swapped: false,
    };
}

/// Injected faults beyond the paper's actuator fault ε (which is a
/// perturbation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Faults {
    /// Fraction of the commanded torque each wheel `[right, left]`
    /// delivers inside the perturbation window (a weak wheel; \[1, 1\] =
    /// healthy).
    pub wheel_torque_scale: [f64; 2],
    /// A dead encoder (hardware sensing only; `wheel` names the counter).
    pub dead_encoder: Option<DeadEncoder>,
    /// Wiring mistakes (hardware sensing only).
    pub wiring: Wiring,
}

impl Faults {
    /// No fault.
    pub const NONE: Self = Self {
        wheel_torque_scale: [1.0, 1.0],
        dead_encoder: None,
        wiring: Wiring::CORRECT,
    };
}

impl Default for Faults {
    fn default() -> Self {
        Self::NONE
    }
}

/// Everything a [`World`] is made of.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldConfig {
    /// The plant's physical parameters.
    pub plant: PlantParams,
    /// The section-4 perturbations.
    pub perturbations: PerturbationProfile,
    /// Initial pose of G \[x m, y m, θ rad\] (at rest, wheel angles 0).
    pub initial_pose: [f64; 3],
    /// The control period the world is advanced by \[s\] (sets the
    /// perturbation grid; [`World::advance`] takes any step).
    pub period_s: f64,
    /// RK4 sub-steps per [`World::advance`].
    pub substeps: u32,
    /// Seed of every random draw (sensor noise); the sensors' seeds are
    /// derived from it ([`GYRO_SEED_SALT`], [`POSE_SEED_SALT`],
    /// [`ideal_noise_seed`]).
    pub seed: u64,
    /// What the controller side measures and drives.
    pub instruments: Instruments,
    /// Injected faults.
    pub faults: Faults,
}

impl WorldConfig {
    /// The robot a runtime configuration describes, exactly as described
    /// (the plant's mass and inertia nominal), at rest at its initial pose,
    /// stepped at its control period with one RK4 sub-step, unperturbed,
    /// behind its encoders, motors and H-bridge, with no gyro, no pose
    /// source and no fault: the starting point of a closed-loop test
    /// (override fields with `..`).
    pub fn of_runtime(rt: &controller_core::runtime::RuntimeConfig) -> Self {
        let p = rt.initial_pose;
        Self {
            plant: PlantParams::from_robot(&rt.controller.robot, 1.0, 1.0),
            perturbations: PerturbationProfile::NONE,
            initial_pose: [p.x_m as f64, p.y_m as f64, p.theta_rad as f64],
            period_s: rt.controller.period_s as f64,
            substeps: 1,
            seed: 0,
            instruments: Instruments::Hardware(HardwareSensing {
                encoder: rt.encoder,
                motor: rt.motor,
                motor_inverted: rt.motor_inverted,
                gyro: None,
                pose_source: None,
            }),
            faults: Faults::NONE,
        }
    }
}

#[cfg(any(test, feature = "robot-file"))]
impl WorldConfig {
    /// The robot of the robot file `plant` as the plant (what it *has*: its
    /// per-wheel radii, track, masses, friction per wheel, motors, encoder
    /// resolution and directions, motor directions), controlled by a runtime
    /// configured as `model_runtime` (what the controller *believes*: it sets
    /// only the initial pose, the control period and the duty full scale of
    /// the PWM timer, a board property). One RK4 sub-step, unperturbed, no
    /// gyro, no pose source, no fault, no actuation delay or electrical lag
    /// (set `plant.actuator`, `substeps`, ... with `..`). With the file the
    /// runtime was derived from, the plant is the model but for the per-wheel
    /// radii (the model takes their mean, D60). Errors: the file's own
    /// validation ([`WorldError::Robot`]).
    pub fn of_robot(
        plant: &robot_file::Robot,
        model_runtime: &controller_core::runtime::RuntimeConfig,
    ) -> Result<Self, WorldError> {
        plant.validate().map_err(WorldError::Robot)?;
        let e = plant.encoder_params();
        Ok(Self {
            plant: PlantParams::of_robot(plant),
            instruments: Instruments::Hardware(HardwareSensing {
                // The simulated counters count the true wheel angle
                // (radius_scale is the runtime's business).
                encoder: EncoderParams {
                    radius_scale: [1.0; 2],
                    ..e
                },
                motor: plant.motor_params(model_runtime.motor.duty_full_scale),
                motor_inverted: plant.bridge.motor_inverted,
                gyro: None,
                pose_source: None,
            }),
            ..Self::of_runtime(model_runtime)
        })
    }
}

/// A world configuration rejected at construction.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum WorldError {
    /// The period must be finite and > 0, with at least one sub-step.
    InvalidStep,
    /// The initial pose must be finite.
    InvalidInitialPose,
    /// Each wheel torque scale must be in \[0, 1\].
    InvalidTorqueScale,
    /// A dead encoder needs hardware sensing, a wheel 0 or 1 and a finite time.
    InvalidDeadEncoder,
    /// Ideal sensing's noise must be finite and >= 0, its period > 0.
    InvalidIdealSensing,
    /// The motor parameters are not physical.
    InvalidMotor,
    /// A plant parameter is not physical.
    Plant(PlantParamsError),
    /// The actuation delay needs more than [`MAX_DELAY_PERIODS`] control
    /// periods of history.
    DelayTooLong,
    /// The RK4 sub-step must be at most twice the motor's electrical time
    /// constant (raise `substeps`).
    StiffActuator,
    /// Wiring faults need hardware sensing.
    InvalidWiring,
    /// The plant's robot file is invalid.
    #[cfg(any(test, feature = "robot-file"))]
    Robot(robot_file::RobotError),
    /// A sensor model was rejected.
    Sensor(SensorModelError),
}

impl core::fmt::Display for WorldError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::InvalidStep => f.write_str("world: period must be > 0 with >= 1 sub-step"),
            Self::InvalidInitialPose => f.write_str("world: initial pose must be finite"),
            Self::InvalidTorqueScale => f.write_str("world: wheel_torque_scale must be in [0, 1]"),
            Self::InvalidDeadEncoder => f.write_str(
                "world: a dead encoder needs hardware sensing, wheel 0 or 1, a finite time",
            ),
            Self::InvalidIdealSensing => {
                f.write_str("world: ideal sensing noise must be >= 0 and its period > 0")
            }
            Self::InvalidMotor => f.write_str("world: motor parameters are not physical"),
            Self::Plant(e) => write!(f, "world: {e}"),
            Self::DelayTooLong => write!(
                f,
                "world: actuation delay exceeds {MAX_DELAY_PERIODS} control periods"
            ),
            Self::StiffActuator => f.write_str(
                "world: the RK4 sub-step exceeds twice the electrical time constant: raise substeps",
            ),
            Self::InvalidWiring => f.write_str("world: wiring faults need hardware sensing"),
            #[cfg(any(test, feature = "robot-file"))]
            Self::Robot(e) => write!(f, "world: plant robot file: {e}"),
            Self::Sensor(e) => write!(f, "world: {e}"),
        }
    }
}

/// The plant state stopped being finite (the loop diverged).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Diverged {
    /// Start of the step that diverged \[s\].
    pub t_s: f64,
}

impl core::fmt::Display for Diverged {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "plant state diverged at t = {:.3} s", self.t_s)
    }
}

/// How the wheels are driven over the next step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Actuation {
    /// Wheel torques `[right, left]` \[N·m\] held over the step (an ideal
    /// torque source).
    Torque([f64; 2]),
    /// The H-bridge's duty and direction per wheel (and its enable line)
    /// held over the step; the motors' torque follows the wheel speed
    /// (back-EMF). Hardware sensing only (an ideal world has no motors:
    /// no torque).
    Bridge(SimDriver),
}

/// Exact measurements of ideal sensing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdealReading {
    /// The pose of G with the configured noise.
    pub pose: Pose,
    /// Wheel rates `[right, left]` from the exact wheel-angle change over
    /// the last period \[rad/s\] (0 at the first reading).
    pub wheel_rate_radps: [f32; 2],
}

/// What [`World::sense`] returns: the truth at the reading's time and, with
/// ideal sensing, the exact measurements. (Hardware readings are read
/// through [`World::io`], as a board reads its registers.)
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reading {
    /// Time of the reading \[s\].
    pub t_s: f64,
    /// True pose of G \[x m, y m, θ rad\].
    pub true_pose: [f64; 3],
    /// True wheel angles φ `[right, left]` \[rad\].
    pub wheel_angle_rad: [f64; 2],
    /// True wheel rates φ̇ `[right, left]` \[rad/s\].
    pub wheel_rate_radps: [f64; 2],
    /// The perturbations acting now.
    pub perturbation: Perturbation,
    /// Exact measurements (ideal sensing only).
    pub ideal: Option<IdealReading>,
}

/// The world's gyro as the runtime's [`Gyro`] (no sample without one).
#[derive(Clone, Debug)]
pub struct WorldGyro(Option<SimGyro>);

impl Gyro for WorldGyro {
    fn sample(&mut self) -> Option<GyroSample> {
        self.0.as_mut().and_then(|g| g.sample())
    }
}

/// The world's external pose source as the runtime's [`PoseSource`]
/// (nothing without one).
#[derive(Clone, Debug)]
pub struct WorldPoseSource(Option<SimPoseSource>);

impl PoseSource for WorldPoseSource {
    fn measurement(&mut self) -> Option<PoseMeasurement> {
        self.0.as_mut().and_then(|p| p.measurement())
    }
}

/// The world's hardware as a board hands it to the runtime.
pub struct WorldIo<'a> {
    /// The quadrature counters.
    pub encoders: &'a mut SimEncoders,
    /// The H-bridge.
    pub motors: &'a mut SimDriver,
    /// The gyro (none: no samples).
    pub gyro: &'a mut WorldGyro,
    /// The external pose source (none: no measurements).
    pub pose_source: &'a mut WorldPoseSource,
}

/// Per-instrument state.
#[derive(Clone, Debug)]
enum State {
    Ideal {
        cfg: IdealSensing,
        rng: SimRng,
        wheel_angle_prev_rad: Option<[f64; 2]>,
    },
    Hardware {
        motor: MotorModel,
        /// Per wheel: the motor turns opposite to its wheel (mounting XOR
        /// a wiring fault).
        inverted: [bool; 2],
        /// The bridge's channels drive the other wheel's motor.
        swapped: bool,
    },
}

/// The commands on their way to the wheels: each actuation with the time
/// it was given; the first entry is the one acting now (D70).
#[derive(Clone, Debug)]
struct DelayLine {
    delay_s: f64,
    t_s: [f64; MAX_DELAY_PERIODS + 2],
    act: [Actuation; MAX_DELAY_PERIODS + 2],
    head: usize,
    len: usize,
}

/// Two instants closer than this are the same switching time \[s\] (the
/// delay's switch and a sub-step boundary a rounding apart).
const SAME_INSTANT_S: f64 = 1e-9;

impl DelayLine {
    const CAP: usize = MAX_DELAY_PERIODS + 2;

    fn new(delay_s: f64) -> Self {
        let mut d = Self {
            delay_s,
            t_s: [f64::NEG_INFINITY; MAX_DELAY_PERIODS + 2],
            act: [Actuation::Torque([0.0; 2]); MAX_DELAY_PERIODS + 2],
            head: 0,
            len: 1,
        };
        d.act[0] = Actuation::Torque([0.0; 2]);
        d
    }

    fn push(&mut self, t_s: f64, act: Actuation) {
        if self.len == Self::CAP {
            // Only reached when stepped far below the configured period.
            self.head = (self.head + 1) % Self::CAP;
            self.len -= 1;
        }
        let i = (self.head + self.len) % Self::CAP;
        self.t_s[i] = t_s;
        self.act[i] = act;
        self.len += 1;
    }

    /// The actuation acting at `t_s` (older ones dropped).
    fn at(&mut self, t_s: f64) -> Actuation {
        while self.len >= 2 {
            let next = (self.head + 1) % Self::CAP;
            if self.t_s[next] + self.delay_s <= t_s + SAME_INSTANT_S {
                self.head = next;
                self.len -= 1;
            } else {
                break;
            }
        }
        self.act[self.head]
    }

    /// When the next pending actuation reaches the wheels.
    fn next_switch_s(&self) -> Option<f64> {
        (self.len >= 2).then(|| self.t_s[(self.head + 1) % Self::CAP] + self.delay_s)
    }
}

/// The simulated world (see the module documentation).
#[derive(Clone, Debug)]
pub struct World {
    plant: Plant,
    state: PlantState,
    perturbations: PerturbationProfile,
    grid: PerturbationGrid,
    substeps: u32,
    faults: Faults,
    /// Time of the last reading (the start of the next step) \[s\].
    t_s: f64,
    instruments: State,
    encoders: SimEncoders,
    bridge: SimDriver,
    gyro: WorldGyro,
    pose_source: WorldPoseSource,
    /// The encoder counters read the other wheel.
    encoders_swapped: bool,
    /// Commands in flight (actuation delay or electrical lag configured).
    delay: Option<DelayLine>,
    /// The lagged wheel torques \[N·m\] and L/R \[s\] (electrical lag
    /// configured).
    lag: Option<([f64; 2], f64)>,
}

impl World {
    /// The world of `cfg`, the robot at rest at its initial pose at t = 0.
    pub fn new(cfg: &WorldConfig) -> Result<Self, WorldError> {
        let pos = |x: f64| x.is_finite() && x > 0.0;
        let nonneg = |x: f64| x.is_finite() && x >= 0.0;
        if !(pos(cfg.period_s) && cfg.substeps >= 1) {
            return Err(WorldError::InvalidStep);
        }
        if !cfg.initial_pose.iter().all(|x| x.is_finite()) {
            return Err(WorldError::InvalidInitialPose);
        }
        if !cfg
            .faults
            .wheel_torque_scale
            .iter()
            .all(|&k| nonneg(k) && k <= 1.0)
        {
            return Err(WorldError::InvalidTorqueScale);
        }
        cfg.plant.validate().map_err(WorldError::Plant)?;
        let substep_s = cfg.period_s / cfg.substeps as f64;
        let act = cfg.plant.actuator;
        if act.delay_s > (MAX_DELAY_PERIODS - 1) as f64 * cfg.period_s {
            return Err(WorldError::DelayTooLong);
        }
        let te = act.electrical_time_constant_s;
        if te > 0.0 && substep_s > 2.0 * te {
            return Err(WorldError::StiffActuator);
        }
        let wiring = cfg.faults.wiring;
        let seed = cfg.seed;
        let (instruments, mut encoder, gyro, pose_source) = match cfg.instruments {
            Instruments::Ideal(ideal) => {
                if !(nonneg(ideal.position_noise_m)
                    && nonneg(ideal.heading_noise_rad)
                    && pos(ideal.rate_period_s))
                {
                    return Err(WorldError::InvalidIdealSensing);
                }
                if cfg.faults.dead_encoder.is_some() {
                    return Err(WorldError::InvalidDeadEncoder);
                }
                if wiring != Wiring::CORRECT {
                    return Err(WorldError::InvalidWiring);
                }
                let state = State::Ideal {
                    cfg: ideal,
                    rng: SimRng::new(ideal_noise_seed(seed)),
                    wheel_angle_prev_rad: None,
                };
                (state, EncoderParams::EXAMPLE, None, None)
            }
            Instruments::Hardware(hw) => {
                if cfg
                    .faults
                    .dead_encoder
                    .is_some_and(|d| d.wheel > 1 || !d.from_s.is_finite())
                {
                    return Err(WorldError::InvalidDeadEncoder);
                }
                let motor = MotorModel::new(hw.motor).map_err(|_| WorldError::InvalidMotor)?;
                let gyro = match hw.gyro {
                    Some(m) => {
                        Some(SimGyro::new(m, seed ^ GYRO_SEED_SALT).map_err(WorldError::Sensor)?)
                    }
                    None => None,
                };
                let pose = match hw.pose_source {
                    Some(m) => Some(
                        SimPoseSource::new(m, seed ^ POSE_SEED_SALT).map_err(WorldError::Sensor)?,
                    ),
                    None => None,
                };
                let m = hw.motor_inverted;
                let w = wiring.motor_inverted;
                let state = State::Hardware {
                    motor,
                    inverted: [m[0] ^ w[0], m[1] ^ w[1]],
                    swapped: wiring.motors_swapped,
                };
                (state, hw.encoder, gyro, pose)
            }
        };
        // The counter of channel i reads wheel w(i)'s encoder, mounted (and
        // mis-wired) as that wheel's.
        let wheel_inv = [
            encoder.inverted[0] ^ wiring.encoder_inverted[0],
            encoder.inverted[1] ^ wiring.encoder_inverted[1],
        ];
        encoder.inverted = if wiring.encoders_swapped {
            [wheel_inv[1], wheel_inv[0]]
        } else {
            wheel_inv
        };
        let p0 = cfg.initial_pose;
        let dynamic = act.delay_s > 0.0 || te > 0.0;
        Ok(Self {
            plant: Plant::new(cfg.plant),
            state: PlantState {
                q: [p0[0], p0[1], p0[2], 0.0, 0.0],
                nu: [0.0, 0.0],
            },
            perturbations: cfg.perturbations,
            // RK4 asks at t, t + h/2 and t + h of each sub-step h: a grid of h/2.
            grid: PerturbationGrid::new(cfg.perturbations, 0.5 * substep_s),
            substeps: cfg.substeps,
            faults: cfg.faults,
            t_s: 0.0,
            instruments,
            encoders: SimEncoders::new(&encoder),
            bridge: SimDriver::default(),
            gyro: WorldGyro(gyro),
            pose_source: WorldPoseSource(pose_source),
            encoders_swapped: wiring.encoders_swapped,
            delay: dynamic.then(|| DelayLine::new(act.delay_s)),
            lag: (te > 0.0).then_some(([0.0; 2], te)),
        })
    }

    /// The wheel torques the lagging motor currents deliver now \[N·m\]
    /// (None without an electrical time constant; before friction).
    pub fn lagged_torque_nm(&self) -> Option<[f64; 2]> {
        self.lag.map(|(t, _)| t)
    }

    /// The plant.
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The plant's state now.
    pub fn state(&self) -> &PlantState {
        &self.state
    }

    /// The true pose of G \[x m, y m, θ rad\].
    pub fn true_pose(&self) -> [f64; 3] {
        [self.state.q[0], self.state.q[1], self.state.q[2]]
    }

    /// The perturbations of this world.
    pub fn perturbations(&self) -> &PerturbationProfile {
        &self.perturbations
    }

    /// Time of the last reading, or of the state after the last step \[s\].
    pub fn t_s(&self) -> f64 {
        self.t_s
    }

    /// The instruments at time `t_s` (the state's time: the previous
    /// reading's time plus the steps advanced since): the truth, the exact
    /// measurements of ideal sensing; the encoders latch the wheel angles
    /// (a dead one stays stuck), the gyro and the pose source take their
    /// samples if due.
    pub fn sense(&mut self, t_s: f64) -> Reading {
        self.t_s = t_s;
        let st = self.state;
        let p = self.grid.at(t_s);
        let angles = [st.q[3], st.q[4]];
        let true_pose = [st.q[0], st.q[1], st.q[2]];
        let ideal = match &mut self.instruments {
            State::Ideal {
                cfg,
                rng,
                wheel_angle_prev_rad,
            } => {
                // Without noise, no draws (x + 0·n = x: same result).
                let noise = if cfg.position_noise_m != 0.0 || cfg.heading_noise_rad != 0.0 {
                    [
                        cfg.position_noise_m * rng.normal_open(),
                        cfg.position_noise_m * rng.normal_open(),
                        cfg.heading_noise_rad * rng.normal_open(),
                    ]
                } else {
                    [0.0; 3]
                };
                let rate = match wheel_angle_prev_rad.replace(angles) {
                    Some(prev) => [
                        ((angles[0] - prev[0]) / cfg.rate_period_s) as f32,
                        ((angles[1] - prev[1]) / cfg.rate_period_s) as f32,
                    ],
                    None => [0.0; 2],
                };
                Some(IdealReading {
                    pose: Pose::new(
                        (true_pose[0] + noise[0]) as f32,
                        (true_pose[1] + noise[1]) as f32,
                        (true_pose[2] + noise[2]) as f32,
                    ),
                    wheel_rate_radps: rate,
                })
            }
            State::Hardware { .. } => {
                self.encoders.set_angles(if self.encoders_swapped {
                    [angles[1], angles[0]]
                } else {
                    angles
                });
                if let Some(d) = self.faults.dead_encoder {
                    if t_s >= d.from_s {
                        self.encoders.kill(d.wheel);
                    }
                }
                // Only a gyro needs θ̇.
                if let Some(g) = &mut self.gyro.0 {
                    g.update(t_s, self.plant.q_dot(&st, &p)[2]);
                }
                if let Some(s) = &mut self.pose_source.0 {
                    s.update(t_s, true_pose);
                }
                None
            }
        };
        Reading {
            t_s,
            true_pose,
            wheel_angle_rad: angles,
            wheel_rate_radps: self.plant.wheel_rates_radps(&st, &p),
            perturbation: p,
            ideal,
        }
    }

    /// The hardware as the runtime reads and writes it.
    pub fn io(&mut self) -> WorldIo<'_> {
        WorldIo {
            encoders: &mut self.encoders,
            motors: &mut self.bridge,
            gyro: &mut self.gyro,
            pose_source: &mut self.pose_source,
        }
    }

    /// The H-bridge as last written through [`World::io`].
    pub fn bridge(&self) -> SimDriver {
        self.bridge
    }

    /// The encoder counts now (what the runtime reads).
    pub fn encoder_counts(&mut self) -> [u16; 2] {
        self.encoders.counts()
    }

    /// The gyro's latest sample (None without a gyro or before its first).
    pub fn gyro_sample(&mut self) -> Option<GyroSample> {
        self.gyro.sample()
    }

    /// The next external pose that has arrived by the last reading's time.
    pub fn pose_measurement(&mut self) -> Option<PoseMeasurement> {
        self.pose_source.measurement()
    }

    /// The pose source's counters (None without one).
    pub fn pose_stats(&self) -> Option<PoseSourceStats> {
        self.pose_source.0.as_ref().map(|p| p.stats)
    }

    /// The commanded wheel torques of `actuation` at these wheel rates
    /// \[N·m\] (before a weak wheel's loss).
    pub fn torque_nm(&self, actuation: &Actuation, wheel_rates_radps: [f64; 2]) -> [f64; 2] {
        self.drive(actuation).torque_nm(wheel_rates_radps)
    }

    fn drive(&self, actuation: &Actuation) -> WorldDrive {
        match (actuation, &self.instruments) {
            (Actuation::Torque(t), _) => WorldDrive::Torque(*t),
            (
                Actuation::Bridge(b),
                State::Hardware {
                    motor,
                    inverted,
                    swapped,
                },
            ) => {
                let mut bridge = *b;
                if *swapped {
                    bridge.duty = [b.duty[1], b.duty[0]];
                }
                WorldDrive::Motor(MotorDrive {
                    model: *motor,
                    bridge,
                    inverted: *inverted,
                })
            }
            (Actuation::Bridge(_), State::Ideal { .. }) => WorldDrive::Torque([0.0; 2]),
        }
    }

    /// The plant over `dt_s` from the last reading's time, `actuation`
    /// held (zero-order hold), in the configured RK4 sub-steps, each wheel
    /// delivering its share of the torque (a weak wheel inside the
    /// perturbation window, judged at the step's start). With an actuation
    /// delay d, the wheels feel the actuation given d earlier (nothing
    /// before the first command reaches them), switching exactly at the
    /// delayed instants (a sub-step is split there: D70); with an
    /// electrical time constant the torque lags it (first order).
    pub fn advance(&mut self, actuation: Actuation, dt_s: f64) -> Result<(), Diverged> {
        if self.delay.is_some() {
            return self.advance_dynamic(actuation, dt_s);
        }
        let t = self.t_s;
        let drive = self.drive(&actuation);
        let scaled = TorqueScaled {
            drive: &drive,
            scale: if self.perturbations.in_window(t) {
                self.faults.wheel_torque_scale
            } else {
                [1.0, 1.0]
            },
        };
        let h = dt_s / self.substeps as f64;
        let grid = &mut self.grid;
        for j in 0..self.substeps {
            let t_j = t + j as f64 * h;
            self.state = self
                .plant
                .rk4_step(&self.state, t_j, h, &scaled, &mut |t| grid.at(t));
        }
        self.t_s = t + dt_s;
        if Plant::state_is_finite(&self.state) {
            Ok(())
        } else {
            Err(Diverged { t_s: t })
        }
    }
}

impl World {
    fn advance_dynamic(&mut self, actuation: Actuation, dt_s: f64) -> Result<(), Diverged> {
        let t = self.t_s;
        let scale = if self.perturbations.in_window(t) {
            self.faults.wheel_torque_scale
        } else {
            [1.0, 1.0]
        };
        let mut line = self.delay.take().unwrap_or_else(|| DelayLine::new(0.0));
        line.push(t, actuation);
        let h = dt_s / self.substeps as f64;
        for j in 0..self.substeps {
            let mut a = t + j as f64 * h;
            let end = if j + 1 == self.substeps {
                t + dt_s
            } else {
                t + (j + 1) as f64 * h
            };
            loop {
                let act = line.at(a);
                let piece_end = match line.next_switch_s() {
                    Some(s) if s < end - SAME_INSTANT_S => s,
                    _ => end,
                };
                self.piece(&act, scale, a, piece_end - a);
                a = piece_end;
                if piece_end == end {
                    break;
                }
            }
        }
        self.delay = Some(line);
        self.t_s = t + dt_s;
        if Plant::state_is_finite(&self.state) {
            Ok(())
        } else {
            Err(Diverged { t_s: t })
        }
    }

    /// One RK4 step of length `len_s` from `t_s` with `act` held.
    fn piece(&mut self, act: &Actuation, scale: [f64; 2], t_s: f64, len_s: f64) {
        let drive = self.drive(act);
        let scaled = TorqueScaled {
            drive: &drive,
            scale,
        };
        let grid = &mut self.grid;
        match &mut self.lag {
            Some((tau, te)) => {
                let (st, t_new) = self.plant.rk4_step_lagged(
                    &self.state,
                    *tau,
                    *te,
                    t_s,
                    len_s,
                    &scaled,
                    &mut |t| grid.at(t),
                );
                self.state = st;
                *tau = t_new;
            }
            None => {
                self.state = self
                    .plant
                    .rk4_step(&self.state, t_s, len_s, &scaled, &mut |t| grid.at(t));
            }
        }
    }
}

/// The drive the world integrates with.
enum WorldDrive {
    Torque([f64; 2]),
    Motor(MotorDrive),
}

impl Drive for WorldDrive {
    fn torque_nm(&self, wheel_rates_radps: [f64; 2]) -> [f64; 2] {
        match self {
            Self::Torque(t) => *t,
            Self::Motor(m) => m.torque_nm(wheel_rates_radps),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::Drive;
    use controller_core::runtime::{DutyCommand, MotorDriver, MIRRORED_LEFT};
    use controller_core::RobotParams;

    fn still() -> PerturbationProfile {
        PerturbationProfile {
            window_s: [0.0, 0.0],
            beta_radps: 0.0,
            fault_eps: 0.0,
            skid_scale: 0.0,
            disturbance_nm: 0.0,
            fault_eps_end: None,
        }
    }

    fn ideal() -> Instruments {
        Instruments::Ideal(IdealSensing {
            position_noise_m: 0.0,
            heading_noise_rad: 0.0,
            rate_period_s: 1e-3,
        })
    }

    fn hardware() -> Instruments {
        Instruments::Hardware(HardwareSensing {
            encoder: EncoderParams::EXAMPLE,
            motor: MotorParams::EXAMPLE,
            motor_inverted: MIRRORED_LEFT,
            gyro: None,
            pose_source: None,
        })
    }

    fn cfg(instruments: Instruments) -> WorldConfig {
        WorldConfig {
            plant: PlantParams::from_robot(&RobotParams::paper(), 1.0, 1.0),
            perturbations: still(),
            initial_pose: [1.0, 2.0, 0.3],
            period_s: 1e-3,
            substeps: 2,
            seed: 1,
            instruments,
            faults: Faults::NONE,
        }
    }

    /// Advancing the world is the plant's RK4 over the sub-steps (two
    /// ways of computing the same trajectory agree bit for bit).
    #[test]
    fn advance_is_the_plants_rk4() {
        let mut w = World::new(&cfg(ideal())).unwrap();
        let plant = Plant::new(cfg(ideal()).plant);
        let mut st = *w.state();
        for k in 0..200 {
            let t = k as f64 * 1e-3;
            w.sense(t);
            w.advance(Actuation::Torque([0.3, 0.1]), 1e-3).unwrap();
            for j in 0..2 {
                let tj = t + j as f64 * 5e-4;
                st = plant.rk4_step(&st, tj, 5e-4, &[0.3, 0.1], &mut |_| Perturbation::default());
            }
        }
        assert_eq!(*w.state(), st);
    }

    /// A wheel that delivers no torque inside the window: a robot at rest
    /// with nothing else acting stays exactly where it is (no force);
    /// outside the window it moves.
    #[test]
    fn weak_wheels_act_inside_the_window_only() {
        let mut c = cfg(ideal());
        c.perturbations.window_s = [0.0, 0.1];
        c.faults.wheel_torque_scale = [0.0, 0.0];
        let mut w = World::new(&c).unwrap();
        let p0 = w.true_pose();
        for k in 0..100 {
            w.sense(k as f64 * 1e-3);
            w.advance(Actuation::Torque([0.5, 0.5]), 1e-3).unwrap();
        }
        assert_eq!(w.true_pose(), p0);
        for k in 100..200 {
            w.sense(k as f64 * 1e-3);
            w.advance(Actuation::Torque([0.5, 0.5]), 1e-3).unwrap();
        }
        assert!(w.state().nu[0] > 0.0);
    }

    /// Ideal sensing: the exact pose, and the wheel rates from the angle
    /// change over the period (0 at the first reading), which under a
    /// constant torque lie between the true rates at the period's ends.
    #[test]
    fn ideal_readings_are_exact() {
        let mut w = World::new(&cfg(ideal())).unwrap();
        let r0 = w.sense(0.0);
        let m0 = r0.ideal.unwrap();
        assert_eq!(m0.wheel_rate_radps, [0.0; 2]);
        assert_eq!(m0.pose, Pose::new(1.0, 2.0, 0.3));
        w.advance(Actuation::Torque([0.4, 0.2]), 1e-3).unwrap();
        let r1 = w.sense(1e-3);
        let m1 = r1.ideal.unwrap();
        for i in 0..2 {
            let (lo, hi) = (r0.wheel_rate_radps[i], r1.wheel_rate_radps[i]);
            let r = m1.wheel_rate_radps[i] as f64;
            assert!(lo < r && r < hi, "wheel {i}: {lo} < {r} < {hi}");
        }
        // The bridge drives nothing in an ideal world (it has no motors).
        let mut b = SimDriver::default();
        b.set(
            [DutyCommand {
                duty: 1000,
                reverse: false,
            }; 2],
        );
        assert_eq!(w.torque_nm(&Actuation::Bridge(b), [0.0; 2]), [0.0; 2]);
    }

    /// Hardware: the bridge's duty into the motor model (left mirrored),
    /// and a dead encoder stuck from its time on.
    #[test]
    fn hardware_bridge_and_dead_encoder() {
        let mut c = cfg(hardware());
        c.faults.dead_encoder = Some(DeadEncoder {
            wheel: 1,
            from_s: 0.05,
        });
        let mut w = World::new(&c).unwrap();
        let cmd = [
            DutyCommand {
                duty: 2000,
                reverse: false,
            },
            DutyCommand {
                duty: 2000,
                reverse: true,
            },
        ];
        let mut stuck = None;
        for k in 0..200 {
            let t = k as f64 * 1e-3;
            w.sense(t);
            w.io().motors.set(cmd);
            let counts = w.encoder_counts();
            if t >= 0.05 {
                assert_eq!(*stuck.get_or_insert(counts[1]), counts[1]);
            }
            w.advance(Actuation::Bridge(w.bridge()), 1e-3).unwrap();
        }
        // Both wheels turn forward (the mirrored motor reversed).
        assert!(w.state().q[3] > 0.0 && w.state().q[4] > 0.0);
        let model = MotorModel::new(MotorParams::EXAMPLE).unwrap();
        let want = model.torque_for_duty(cmd[0], 0.0) as f64;
        let t = w.torque_nm(&Actuation::Bridge(w.bridge()), [0.0; 2]);
        assert_eq!(t, [want, want]);
        let drive = WorldDrive::Torque([1.0, 2.0]);
        assert_eq!(drive.torque_nm([5.0, 5.0]), [1.0, 2.0]);
    }

    #[test]
    fn invalid_worlds_rejected() {
        let bad = |f: &dyn Fn(&mut WorldConfig)| {
            let mut c = cfg(hardware());
            f(&mut c);
            World::new(&c).err()
        };
        assert_eq!(bad(&|c| c.period_s = 0.0), Some(WorldError::InvalidStep));
        assert_eq!(bad(&|c| c.substeps = 0), Some(WorldError::InvalidStep));
        assert_eq!(
            bad(&|c| c.initial_pose[0] = f64::NAN),
            Some(WorldError::InvalidInitialPose)
        );
        assert_eq!(
            bad(&|c| c.faults.wheel_torque_scale = [1.5, 1.0]),
            Some(WorldError::InvalidTorqueScale)
        );
        assert_eq!(
            bad(&|c| c.faults.dead_encoder = Some(DeadEncoder {
                wheel: 2,
                from_s: 0.0
            })),
            Some(WorldError::InvalidDeadEncoder)
        );
        let mut c = cfg(ideal());
        c.faults.dead_encoder = Some(DeadEncoder {
            wheel: 0,
            from_s: 0.0,
        });
        assert_eq!(World::new(&c).err(), Some(WorldError::InvalidDeadEncoder));
        let mut c = cfg(ideal());
        c.instruments = Instruments::Ideal(IdealSensing {
            position_noise_m: -1.0,
            heading_noise_rad: 0.0,
            rate_period_s: 1e-3,
        });
        assert_eq!(World::new(&c).err(), Some(WorldError::InvalidIdealSensing));
    }

    /// A diverging plant is reported with the step's start time.
    #[test]
    fn divergence_is_an_error() {
        let mut w = World::new(&cfg(ideal())).unwrap();
        w.sense(0.5);
        let e = w
            .advance(Actuation::Torque([f64::INFINITY, 0.0]), 1e-3)
            .unwrap_err();
        assert_eq!(e, Diverged { t_s: 0.5 });
    }
    fn with_actuator(delay_s: f64, tau_e_s: f64, substeps: u32) -> WorldConfig {
        let mut c = cfg(ideal());
        c.initial_pose = [0.0, 0.0, 0.0];
        c.substeps = substeps;
        c.plant.actuator = crate::plant::ActuatorDynamics {
            delay_s,
            electrical_time_constant_s: tau_e_s,
        };
        c
    }

    /// Equal torques τ from rest: x(t) = a·(t − d)²/2 for t > d, 0 before,
    /// a = 2τ/(r·M1₁₁): a delay d (here 1.3 periods, so the switch falls
    /// inside a sub-step) shifts the step response by exactly d.
    #[test]
    fn delay_shifts_the_step_response() {
        let d = 1.3e-3;
        let mut w = World::new(&with_actuator(d, 0.0, 4)).unwrap();
        let p = *w.plant().params();
        let tau = 0.5;
        let a = 2.0 * tau / (p.wheel_radius_m[0] * p.m1_diag()[0]);
        for k in 0..50 {
            let t = k as f64 * 1e-3;
            w.sense(t);
            let x = w.true_pose()[0];
            let want = if t > d {
                0.5 * a * (t - d) * (t - d)
            } else {
                0.0
            };
            assert!((x - want).abs() < 1e-12, "t {t}: {x} vs {want}");
            w.advance(Actuation::Torque([tau, tau]), 1e-3).unwrap();
        }
    }

    /// Electrical time constant τ_e: after a torque step the delivered
    /// torque is τ·(1 − e^(−t/τ_e)) and the speed a·(t − τ_e(1 − e^(−t/τ_e))).
    #[test]
    fn electrical_lag_is_first_order() {
        let te = 2e-3;
        let mut w = World::new(&with_actuator(0.0, te, 4)).unwrap();
        let p = *w.plant().params();
        let tau = 0.5;
        let a = 2.0 * tau / (p.wheel_radius_m[0] * p.m1_diag()[0]);
        for k in 0..20 {
            w.sense(k as f64 * 1e-3);
            w.advance(Actuation::Torque([tau, tau]), 1e-3).unwrap();
            let t = (k + 1) as f64 * 1e-3;
            let e = (-t / te).exp();
            let got = w.lagged_torque_nm().unwrap()[0];
            assert!((got - tau * (1.0 - e)).abs() < 1e-5 * tau, "t {t}: {got}");
            let v = a * (t - te * (1.0 - e));
            assert!((w.state().nu[0] - v).abs() < 1e-5 * a * t, "t {t}");
        }
        // A sub-step longer than 2·τ_e is refused.
        assert_eq!(
            World::new(&with_actuator(0.0, 1e-4, 1)).err(),
            Some(WorldError::StiffActuator)
        );
        assert_eq!(
            World::new(&with_actuator(0.05, 0.0, 1)).err(),
            Some(WorldError::DelayTooLong)
        );
    }

    fn duty(d: i32) -> DutyCommand {
        DutyCommand {
            duty: d.unsigned_abs() as u16,
            reverse: d < 0,
        }
    }

    /// The wheels' angles after `ms` periods of `cmd` on a hardware world
    /// with this wiring (starting at rest).
    fn drive_wired(wiring: Wiring, cmd: [i32; 2], ms: usize) -> (World, [u16; 2]) {
        let mut c = cfg(hardware());
        c.faults.wiring = wiring;
        let mut w = World::new(&c).unwrap();
        let c0 = w.encoder_counts();
        for k in 0..ms {
            w.sense(k as f64 * 1e-3);
            w.io().motors.set([duty(cmd[0]), duty(cmd[1])]);
            w.advance(Actuation::Bridge(w.bridge()), 1e-3).unwrap();
        }
        w.sense(ms as f64 * 1e-3);
        (w, c0)
    }

    /// Swapped motors: a command on the right channel alone drives the
    /// left motor: the run equals the correctly wired one with that command
    /// on the left channel (the same signal into the same motor), and the
    /// robot turns right instead of left.
    #[test]
    fn swapped_motors_turn_the_other_wheel() {
        let swapped = Wiring {
            motors_swapped: true,
            ..Wiring::CORRECT
        };
        let (sw, _) = drive_wired(swapped, [-1500, 0], 100);
        let (left, _) = drive_wired(Wiring::CORRECT, [0, -1500], 100);
        let (right, _) = drive_wired(Wiring::CORRECT, [-1500, 0], 100);
        assert_eq!(sw.state(), left.state());
        // The left wheel (mirrored motor, reverse duty) drives forward.
        assert!(sw.state().q[4] > sw.state().q[3] && sw.state().nu[1] < 0.0);
        assert!(right.state().nu[1] > 0.0 || right.state().nu[0] < 0.0);
    }

    /// A motor with its leads swapped turns backwards on a forward command.
    #[test]
    fn inverted_motor_turns_backwards() {
        let w = Wiring {
            motor_inverted: [true, false],
            ..Wiring::CORRECT
        };
        let (world, _) = drive_wired(w, [1500, 0], 100);
        assert!(world.state().q[3] < 0.0);
    }

    /// Encoder faults: an inverted encoder counts the other way; swapped
    /// encoders report each wheel's angle on the other counter (with that
    /// wheel's mounting), counts = floor(φ·cpr/2π) per the mounting.
    #[test]
    fn encoder_wiring_faults_as_counted() {
        let cpr = EncoderParams::EXAMPLE.counts_per_wheel_rev as f64;
        let mount = EncoderParams::EXAMPLE.inverted;
        let count = |phi: f64, inv: bool| {
            let c = (phi * cpr / core::f64::consts::TAU).floor() as i64;
            (if inv { -c } else { c }) as u16
        };
        let cmd = [1500, -600];
        for wiring in [
            Wiring::CORRECT,
            Wiring {
                encoder_inverted: [true, false],
                ..Wiring::CORRECT
            },
            Wiring {
                encoders_swapped: true,
                ..Wiring::CORRECT
            },
            Wiring {
                encoders_swapped: true,
                encoder_inverted: [false, true],
                ..Wiring::CORRECT
            },
        ] {
            let (mut w, _) = drive_wired(wiring, cmd, 50);
            let q = w.state().q;
            let phi = [q[3], q[4]];
            let inv = |wheel: usize| mount[wheel] ^ wiring.encoder_inverted[wheel];
            let want = if wiring.encoders_swapped {
                [count(phi[1], inv(1)), count(phi[0], inv(0))]
            } else {
                [count(phi[0], inv(0)), count(phi[1], inv(1))]
            };
            assert_eq!(w.encoder_counts(), want, "{wiring:?}");
        }
        // Ideal sensing has no wires.
        let mut c = cfg(ideal());
        c.faults.wiring.motors_swapped = true;
        assert_eq!(World::new(&c).err(), Some(WorldError::InvalidWiring));
    }

    /// The plant's encoders may have another resolution than the
    /// runtime's: counts scale with it.
    #[test]
    fn plant_encoder_resolution() {
        let mut c = cfg(hardware());
        if let Instruments::Hardware(hw) = &mut c.instruments {
            hw.encoder.counts_per_wheel_rev = 1320.0;
            hw.encoder.inverted = [false; 2];
        }
        let mut w = World::new(&c).unwrap();
        for k in 0..100 {
            w.sense(k as f64 * 1e-3);
            w.advance(Actuation::Torque([2.0, 2.0]), 1e-3).unwrap();
        }
        w.sense(0.1);
        let phi = w.state().q[3];
        let want = (phi * 1320.0 / core::f64::consts::TAU).floor() as i64 as u16;
        assert_eq!(w.encoder_counts()[0], want);
    }
    /// A robot file as the plant: the paper's file behind the runtime
    /// derived from it is exactly `of_runtime`'s world (two constructions
    /// of the same robot); a plant file that differs reaches the plant, its
    /// motors and encoders; an invalid file is refused naming the field.
    #[cfg(any(test, feature = "robot-file"))]
    #[test]
    fn world_of_a_robot_file() {
        use controller_core::runtime::RuntimeConfig;
        use controller_core::ControllerKind;
        use robot_file::Robot;
        let kind = ControllerKind::Proposed;
        let mut model = Robot::paper();
        model.control.controller = kind;
        (model.control.initial_x_m, model.control.initial_y_m) = (0.5, -0.2);
        model.control.initial_heading_rad = 0.1;
        let board = robot_file::BoardFacts::of_timer(&model, 96_000_000).unwrap();
        let rt = model
            .derive(&board, RuntimeConfig::example(kind).reference)
            .runtime;
        let same = WorldConfig::of_robot(&model, &rt).unwrap();
        assert_eq!(same, WorldConfig::of_runtime(&rt));
        let mut plant = model.clone();
        plant.body.wheel_radius_m = [0.102, 0.1];
        plant.body.track_m = 0.42;
        plant.motors.torque_constant_nm_per_a = 0.06;
        plant.motors.coulomb_friction_nm = [0.3, 0.2];
        plant.encoders.counts_per_wheel_rev = 1320.0;
        plant.encoders.inverted = [true, true];
        let c = WorldConfig::of_robot(&plant, &rt).unwrap();
        assert_eq!(c.plant.wheel_radius_m, [0.102f32 as f64, 0.1f32 as f64]);
        assert_eq!(c.plant.half_track_m, 0.5 * 0.42f32 as f64);
        assert_eq!(c.plant.friction[0].coulomb_nm, 0.3f32 as f64);
        assert_eq!(c.period_s, rt.controller.period_s as f64);
        let Instruments::Hardware(hw) = c.instruments else {
            panic!("hardware expected");
        };
        assert_eq!(hw.motor.torque_constant_nm_per_a, 0.06);
        assert_eq!(hw.motor.duty_full_scale, rt.motor.duty_full_scale);
        assert_eq!(hw.encoder.counts_per_wheel_rev, 1320.0);
        assert_eq!(hw.encoder.inverted, [true, true]);
        assert!(World::new(&c).is_ok());
        let mut bad = plant.clone();
        bad.body.mass_kg = f32::NAN;
        match WorldConfig::of_robot(&bad, &rt) {
            Err(WorldError::Robot(e)) => assert_eq!(e.field, "body.mass_kg"),
            other => panic!("{other:?}"),
        }
    }
}
