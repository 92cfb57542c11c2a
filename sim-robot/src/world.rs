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
use crate::plant::{Drive, Perturbation, Plant, PlantParams, PlantState, TorqueScaled};
use crate::sensors::{
    GyroModel, PoseSourceModel, PoseSourceStats, SensorModelError, SimGyro, SimPoseSource, SimRng,
};
use controller_core::estimator::{GyroSample, PoseMeasurement};
use controller_core::runtime::{
    EncoderParams, Gyro, MotorModel, MotorParams, PoseSource, WheelEncoders,
};
use controller_core::Pose;

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
/// optionally a gyro and an external pose source.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HardwareSensing {
    /// The quadrature encoders (resolution, mounting).
    pub encoder: EncoderParams,
    /// The motors behind the H-bridge.
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

/// Injected faults beyond the paper's actuator fault ε (which is a
/// perturbation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Faults {
    /// Fraction of the commanded torque each wheel `[right, left]`
    /// delivers inside the perturbation window (a weak wheel; \[1, 1\] =
    /// healthy).
    pub wheel_torque_scale: [f64; 2],
    /// A dead encoder (hardware sensing only).
    pub dead_encoder: Option<DeadEncoder>,
}

impl Faults {
    /// No fault.
    pub const NONE: Self = Self {
        wheel_torque_scale: [1.0, 1.0],
        dead_encoder: None,
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
        inverted: [bool; 2],
    },
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
        let seed = cfg.seed;
        let (instruments, encoder, gyro, pose_source) = match cfg.instruments {
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
                let state = State::Hardware {
                    motor,
                    inverted: hw.motor_inverted,
                };
                (state, hw.encoder, gyro, pose)
            }
        };
        let p0 = cfg.initial_pose;
        let substep_s = cfg.period_s / cfg.substeps as f64;
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
        })
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
                self.encoders.set_angles(angles);
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
            (Actuation::Bridge(b), State::Hardware { motor, inverted }) => {
                WorldDrive::Motor(MotorDrive {
                    model: *motor,
                    bridge: *b,
                    inverted: *inverted,
                })
            }
            (Actuation::Bridge(_), State::Ideal { .. }) => WorldDrive::Torque([0.0; 2]),
        }
    }

    /// The plant over `dt_s` from the last reading's time, `actuation`
    /// held (zero-order hold), in the configured RK4 sub-steps, each wheel
    /// delivering its share of the torque (a weak wheel inside the
    /// perturbation window, judged at the step's start).
    pub fn advance(&mut self, actuation: Actuation, dt_s: f64) -> Result<(), Diverged> {
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
}
