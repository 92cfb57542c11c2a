//! Hardware-in-the-loop on the host: the firmware's runtime
//! ([`controller_core::runtime::ControlLoop`]) closed through the simulated
//! robot's hardware ([`sim_robot::hardware`]): 16-bit quadrature counters at
//! the scenario's resolution (wrapping, mirrored mounting) and an H-bridge
//! taking integer duty at the scenario's PWM resolution into the runtime's own
//! DC-motor model, whose torque depends on the wheel speed (back-EMF).
//!
//! With the `imu`, `mocap` and `uwb` presets the runtime also gets the
//! simulated gyro and external pose source of [`sim_robot::sensors`]
//! ([`crate::sensing`] sets them up).
//!
//! Only sensors and actuators are simulated: encoder decoding, speed
//! estimation, the pose estimator, the controller, torque-to-duty mapping
//! and the safety supervisor are the code the firmware runs.

use crate::control_side::{Actuation, ControlOutput, ControlSide, Sensed};
use crate::scenario::{Scenario, Sensing};
use crate::sensing::SensorSetup;
use crate::sim::{run_loop, trace_every, SimOutput};
use controller_core::estimator::{EstimatorConfig, EstimatorStatus, GyroSample, PoseMeasurement};
use controller_core::runtime::{
    ControlLoop, Gyro, LoopTimer, PoseSource, SafetyLimits, StopReason,
};
use controller_core::{ControllerConfig, ControllerKind};
use sim_robot::sensors::PoseSourceStats;
use sim_robot::{MotorDrive, SimDriver, SimEncoders, SimGyro, SimPoseSource};

/// Options of a HIL run beyond the scenario: safety thresholds and fault
/// injection. Resolution, sensing and motors come from the [`Scenario`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HilOptions {
    /// Safety thresholds.
    pub safety: SafetyLimits,
    /// Fault injection: from this time \[s\] on, the encoder of wheel
    /// `.0` (0 = right, 1 = left) stops counting (broken wire).
    pub dead_encoder: Option<(usize, f64)>,
    /// Estimator tuning (None = [`sensing_estimator_config`]); its initial
    /// pose and centre-of-mass offset are taken from the scenario.
    pub estimator: Option<EstimatorConfig>,
}

impl Default for HilOptions {
    fn default() -> Self {
        Self {
            safety: SafetyLimits::EXAMPLE,
            dead_encoder: None,
            estimator: None,
        }
    }
}

/// The preset's gyro, if it has one.
/// The simulated gyro and external pose source of a scenario's sensing
/// preset (either may be absent), as the runtime's [`Gyro`] and
/// [`PoseSource`]: shared by the HIL runs and the simulated robot behind the
/// host link.
pub struct SimSensors {
    gyro: MaybeGyro,
    pose_source: MaybePose,
}

impl SimSensors {
    /// The sensors of `scn`'s sensing preset (seeded from the scenario) and
    /// the estimator tuning for them.
    pub fn of(scn: &Scenario) -> Result<(Self, EstimatorConfig), String> {
        let sensors = SensorSetup::of(scn)?;
        let gyro = match sensors.gyro {
            Some(m) => {
                Some(SimGyro::new(m, scn.seed ^ GYRO_SEED_SALT).map_err(|e| format!("gyro: {e}"))?)
            }
            None => None,
        };
        let pose_source = match sensors.pose {
            Some(m) => Some(
                SimPoseSource::new(m, scn.seed ^ POSE_SEED_SALT)
                    .map_err(|e| format!("pose source: {e}"))?,
            ),
            None => None,
        };
        let est = sensing_estimator_config(&sensors);
        Ok((
            Self {
                gyro: MaybeGyro(gyro),
                pose_source: MaybePose(pose_source),
            },
            est,
        ))
    }

    /// The true motion at time `t_s`: the gyro's yaw rate \[rad/s\] and the
    /// pose of G for the pose source.
    pub fn update(&mut self, t_s: f64, yaw_rate_radps: f64, true_pose: [f64; 3]) {
        if let Some(g) = &mut self.gyro.0 {
            g.update(t_s, yaw_rate_radps);
        }
        if let Some(p) = &mut self.pose_source.0 {
            p.update(t_s, true_pose);
        }
    }

    /// The runtime's gyro and pose source.
    pub fn parts(&mut self) -> (&mut impl Gyro, &mut impl PoseSource) {
        (&mut self.gyro, &mut self.pose_source)
    }

    /// The pose source's counters (None without one).
    pub fn pose_stats(&self) -> Option<PoseSourceStats> {
        self.pose_source.0.as_ref().map(|p| p.stats)
    }
}

struct MaybeGyro(Option<SimGyro>);

impl Gyro for MaybeGyro {
    fn sample(&mut self) -> Option<GyroSample> {
        self.0.as_mut().and_then(|g| g.sample())
    }
}

/// The preset's external pose source, if it has one.
struct MaybePose(Option<SimPoseSource>);

impl PoseSource for MaybePose {
    fn measurement(&mut self) -> Option<PoseMeasurement> {
        self.0.as_mut().and_then(|p| p.measurement())
    }
}

/// Seeds of the gyro and pose-source noise, derived from the scenario's.
const GYRO_SEED_SALT: u64 = 0x6779_726F;
const POSE_SEED_SALT: u64 = 0x706F_7365;

/// What the sensing did over a run: the estimator's final status and the
/// pose source's counters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensingReport {
    /// The estimator's status at the end of the run.
    pub estimator: EstimatorStatus,
    /// The simulated pose source's counters (None without one).
    pub pose_source: Option<PoseSourceStats>,
}

/// The estimator tuning for a set of simulated sensors, as a user would
/// set it from the data sheets: [`EstimatorConfig::EXAMPLE`] with the
/// gyro's full scale.
pub fn sensing_estimator_config(sensors: &SensorSetup) -> EstimatorConfig {
    let mut est = EstimatorConfig::EXAMPLE;
    if let Some(g) = sensors.gyro {
        est.gyro_saturation_radps = g.saturation_radps as f32;
    }
    est
}

/// The runtime as the controller side of [`run_loop`].
pub struct RuntimeSide {
    control: ControlLoop,
    /// Measures each tick against the schedule, as in the firmware; the
    /// simulated clock advances exactly one period per step.
    timer: LoopTimer,
    encoders: SimEncoders,
    bridge: SimDriver,
    sensors: SimSensors,
    opts: HilOptions,
    /// First safe stop latched, with the step it happened at.
    pub stop: Option<(usize, StopReason)>,
}

impl RuntimeSide {
    /// The runtime for `scn` (firmware sensing) with `controller`, armed.
    pub fn new(
        scn: &Scenario,
        controller: ControllerConfig,
        opts: HilOptions,
    ) -> Result<Self, String> {
        if scn.sensing == Sensing::Ideal {
            return Err("the firmware runtime needs a firmware sensing preset, not ideal".into());
        }
        let (sensors, sensing_est) = SimSensors::of(scn)?;
        let cfg = scn.runtime_config(controller, opts.safety);
        let est = opts.estimator.unwrap_or(sensing_est);
        let mut control =
            ControlLoop::with_estimator(cfg, est).map_err(|e| format!("runtime config: {e}"))?;
        let timer = LoopTimer::from_config(&cfg).map_err(|e| format!("loop timer: {e}"))?;
        control.arm().map_err(|e| format!("arm: {e:?}"))?;
        Ok(Self {
            control,
            timer,
            encoders: SimEncoders::new(&cfg.encoder),
            bridge: SimDriver::default(),
            sensors,
            opts,
            stop: None,
        })
    }
}

impl RuntimeSide {
    /// What the sensing did so far.
    pub fn sensing_report(&self) -> SensingReport {
        SensingReport {
            estimator: *self.control.estimator_status(),
            pose_source: self.sensors.pose_stats(),
        }
    }
}

impl ControlSide for RuntimeSide {
    fn kind(&self) -> ControllerKind {
        self.control.config().controller.kind
    }

    fn step(&mut self, sensed: &Sensed) -> ControlOutput {
        self.encoders.set_angles(sensed.wheel_angle_rad);
        if let Some((wheel, t_dead)) = self.opts.dead_encoder {
            if sensed.t_s >= t_dead {
                self.encoders.kill(wheel);
            }
        }
        self.sensors
            .update(sensed.t_s, sensed.yaw_rate_radps, sensed.true_pose);
        // A µs counter that wraps, like the firmware's (the sensors stamp
        // their samples in the same clock).
        let now_us = (sensed.step as u64 * self.timer.period_us() as u64) as u32;
        let timing = self.timer.tick(now_us);
        let (gyro, pose_source) = self.sensors.parts();
        let rep = self.control.tick(
            &mut self.encoders,
            &mut self.bridge,
            gyro,
            pose_source,
            timing,
        );
        if let (Some(reason), None) = (rep.stopped, self.stop) {
            self.stop = Some((sensed.step, reason));
        }
        let cfg = self.control.config();
        ControlOutput {
            actuation: Actuation::Motor(MotorDrive {
                model: *self.control.motor_model(),
                bridge: self.bridge,
                inverted: cfg.motor_inverted,
            }),
            eta_measured: [rep.eta.v_mps as f64, rep.eta.omega_radps as f64],
            diag: rep.diag,
            reference: rep.reference,
            pace: rep.pace,
        }
    }

    fn rejected_steps(&self) -> u32 {
        self.control.status().input_faults + self.control.status().stops
    }
}

/// Result of a HIL run.
#[derive(Clone, Debug)]
pub struct HilOutput {
    /// Trace and metrics, as for [`crate::run`].
    pub sim: SimOutput,
    /// The first safe stop the runtime latched, if any: (step, reason).
    pub stop: Option<(usize, StopReason)>,
    /// The estimator's status and the pose source's counters at the end.
    pub sensing: SensingReport,
}

/// Runs `scn` (a firmware sensing preset) with `controller` through the firmware
/// runtime; a trace every `trace_every` steps (0 = none).
pub fn run_runtime(
    scn: &Scenario,
    controller: ControllerConfig,
    opts: HilOptions,
    trace_every: usize,
) -> Result<HilOutput, String> {
    scn.validate()?;
    let mut side = RuntimeSide::new(scn, controller, opts)?;
    let mut sim = run_loop(scn, &controller.robot, &mut side, trace_every)?;
    sim.sensing = Some(side.sensing_report());
    Ok(HilOutput {
        sim,
        stop: side.stop,
        sensing: side.sensing_report(),
    })
}

/// Runs `scn` (a firmware sensing preset) with `kind` at the scenario's gains through
/// the firmware runtime; trace every [`crate::sim::TRACE_PERIOD_S`].
pub fn run_hil(
    scn: &Scenario,
    kind: ControllerKind,
    opts: HilOptions,
) -> Result<HilOutput, String> {
    let controller = crate::sim::controller_config(scn, kind);
    run_runtime(scn, controller, opts, trace_every(scn))
}
