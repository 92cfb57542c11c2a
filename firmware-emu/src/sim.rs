//! The simulated robot in the guest: sim-robot's [`World`] (the project's
//! one simulated world, f64 through libm: the plant behind simulated
//! encoders, H-bridge and MEMS gyro) behind the board's peripherals.
//!
//! The board's peripherals ([`crate::board`]) are thin handles on [`HW`],
//! the registers the world's readings are latched into: the control tick
//! reads the encoder counters and the gyro and writes the bridge there,
//! exactly as it would read and write registers. The plant task owns the
//! world and advances it: half a period after each control tick (when
//! the tick has written its duties and the next has not read the sensors),
//! it integrates one control period with the bridge held (one RK4 step,
//! the DC-motor torque at each stage's wheel rates, as `hil-sim`'s runtime
//! path does with its default single sub-step) and sets the sensors to the
//! state at the next tick's time. So the control tick sees the same
//! sequence as in `hil-sim` (sensors at t_k, duty over [t_k, t_k+1]) and its
//! instruction count is the firmware's alone: the plant runs in its own
//! task, outside the timed tick.

use core::cell::RefCell;

use controller_core::estimator::GyroSample;
use controller_core::runtime::{DutyCommand, Gyro, MotorDriver, WheelEncoders};
use critical_section::Mutex;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;
use embassy_time::{Instant, Timer};
use sim_robot::sensors::PRESET_GYRO;
use sim_robot::world::{Actuation, Faults, HardwareSensing, Instruments};
use sim_robot::{PerturbationProfile, PlantParams, SimDriver, World, WorldConfig};

/// The simulated peripherals the board's handles reach: the world's
/// latest readings and the bridge as the tick wrote it.
pub struct SimHw {
    counts: [u16; 2],
    bridge: SimDriver,
    gyro: Option<GyroSample>,
    /// A fault handler (NMI, panic, hard fault) cut the motors: the bridge
    /// outputs nothing until the board resets.
    killed: bool,
}

/// The simulated hardware (None until [`init`]).
static HW: Mutex<RefCell<Option<SimHw>>> = Mutex::new(RefCell::new(None));

/// When the control loop started (its first period begins): the plant
/// task's phase.
pub static LOOP_START: Signal<CriticalSectionRawMutex, Instant> = Signal::new();

/// Seed of the world's noise (the gyro's: `sim_robot::world::GYRO_SEED_SALT` from it).
const SEED: u64 = 0;

/// The world, built (and checked) at boot, taken by the plant task.
static WORLD: Mutex<RefCell<Option<World>>> = Mutex::new(RefCell::new(None));

/// Sets up the simulated world for `cfg` (the robot at rest at its initial
/// pose; the runtime's encoders and motors, sim-robot's MEMS gyro) and the
/// peripherals (counters at 0, no gyro sample yet).
pub fn init(cfg: &controller_core::runtime::RuntimeConfig) -> Result<(), &'static str> {
    let p0 = cfg.initial_pose;
    let world = World::new(&WorldConfig {
        plant: PlantParams::from_robot(&cfg.controller.robot, 1.0, 1.0),
        perturbations: PerturbationProfile::NONE,
        initial_pose: [p0.x_m as f64, p0.y_m as f64, p0.theta_rad as f64],
        period_s: cfg.controller.period_s as f64,
        substeps: 1,
        seed: SEED,
        instruments: Instruments::Hardware(HardwareSensing {
            encoder: cfg.encoder,
            motor: cfg.motor,
            motor_inverted: cfg.motor_inverted,
            gyro: Some(PRESET_GYRO),
            pose_source: None,
        }),
        faults: Faults::NONE,
    })
    .map_err(|_| "simulated world (motor or gyro parameters)")?;
    let hw = SimHw {
        counts: [0; 2],
        bridge: SimDriver::default(),
        gyro: None,
        killed: false,
    };
    critical_section::with(|cs| {
        HW.borrow(cs).replace(Some(hw));
        WORLD.borrow(cs).replace(Some(world));
    });
    Ok(())
}

fn with_hw<R>(f: impl FnOnce(&mut SimHw) -> R) -> Option<R> {
    critical_section::with(|cs| HW.borrow(cs).borrow_mut().as_mut().map(f))
}

/// The gyro's full scale \[rad/s\] (the estimator's saturation threshold).
pub fn gyro_saturation_radps() -> f32 {
    PRESET_GYRO.saturation_radps as f32
}

/// Fault handlers: the motors stop at once and stay off until reset.
pub fn kill_motors() {
    with_hw(|hw| {
        hw.killed = true;
        hw.bridge.disable();
    });
}

/// The two quadrature counters (16-bit, wrapping, left mirrored).
pub struct EmuEncoders;

impl WheelEncoders for EmuEncoders {
    fn counts(&mut self) -> [u16; 2] {
        with_hw(|hw| hw.counts).unwrap_or([0; 2])
    }
}

/// The H-bridge: duty and direction per wheel, an enable line.
pub struct EmuMotors;

impl MotorDriver for EmuMotors {
    fn set(&mut self, cmd: [DutyCommand; 2]) {
        with_hw(|hw| {
            if !hw.killed {
                hw.bridge.set(cmd);
            }
        });
    }

    fn disable(&mut self) {
        with_hw(|hw| hw.bridge.disable());
    }
}

/// The z-axis gyro (sim-robot's MEMS preset, sampled at 1 kHz).
pub struct EmuGyro;

impl Gyro for EmuGyro {
    fn sample(&mut self) -> Option<GyroSample> {
        with_hw(|hw| hw.gyro).flatten()
    }
}

/// What the plant task reports (for the status line).
#[derive(Clone, Copy, Debug, Default)]
pub struct PlantReport {
    /// True pose of G \[x m, y m, θ rad\].
    pub pose: [f64; 3],
    /// Largest instruction count of one plant step so far.
    pub step_insn_max: u32,
}

static REPORT: Mutex<RefCell<PlantReport>> = Mutex::new(RefCell::new(PlantReport {
    pose: [0.0; 3],
    step_insn_max: 0,
}));

/// The plant's latest report.
pub fn report() -> PlantReport {
    critical_section::with(|cs| *REPORT.borrow(cs).borrow())
}

/// Advances the robot one control period per period, half a period after
/// each control tick, from the loop's start on. Returns only when the
/// simulation cannot go on (no world, no hardware, a diverged plant), with
/// the reason: the caller ends the run (a failed run, exit code 1).
/// Returning it rather than failing here keeps this module below the log
/// (`log` reads [`report`]; nothing here names `log`). The world was built
/// from the same configuration by [`init`].
pub async fn plant_task(
    _cfg: controller_core::runtime::RuntimeConfig,
    period_us: u32,
) -> &'static str {
    let t0 = LOOP_START.wait().await;
    let dt_s = period_us as f64 * 1e-6;
    let Some(mut world) = critical_section::with(|cs| WORLD.borrow(cs).take()) else {
        return "plant: no world (sim::init not run)";
    };
    let t0_us = t0.as_micros();
    let mut k: u64 = 1;
    loop {
        // Control tick k ran at t0 + k periods; the next is at k + 1.
        Timer::at(Instant::from_micros(
            t0_us + k * period_us as u64 + period_us as u64 / 2,
        ))
        .await;
        let c0 = crate::time::instructions();
        let Some(bridge) = with_hw(|hw| hw.bridge) else {
            return "plant: no hardware";
        };
        // Nothing perturbs this world: the step does not depend on its start time.
        if world.advance(Actuation::Bridge(bridge), dt_s).is_err() {
            return "plant: state diverged";
        }
        let t_next_s = (t0_us + (k + 1) * period_us as u64) as f64 * 1e-6;
        let reading = world.sense(t_next_s);
        let counts = world.encoder_counts();
        let gyro = world.gyro_sample();
        with_hw(|hw| {
            hw.counts = counts;
            hw.gyro = gyro;
        });
        let insn = crate::time::instructions().wrapping_sub(c0);
        critical_section::with(|cs| {
            let mut r = REPORT.borrow(cs).borrow_mut();
            r.pose = reading.true_pose;
            r.step_insn_max = r.step_insn_max.max(insn);
        });
        k += 1;
    }
}
