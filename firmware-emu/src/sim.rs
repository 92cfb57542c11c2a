//! The simulated robot in the guest: sim-robot's plant (the project's one
//! plant, f64 through libm) behind the board's encoders, H-bridge and gyro.
//!
//! The board's peripherals ([`crate::board`]) are thin handles on [`HW`]:
//! the control tick reads the encoder counters and the gyro and writes the
//! bridge there, exactly as it would read and write registers. The plant
//! task advances the robot: half a period after each control tick (when
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
use controller_core::runtime::{DutyCommand, Gyro, MotorDriver, MotorModel, WheelEncoders};
use critical_section::Mutex;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;
use embassy_time::{Instant, Timer};
use sim_robot::sensors::PRESET_GYRO;
use sim_robot::{
    MotorDrive, Perturbation, Plant, PlantParams, PlantState, SimDriver, SimEncoders, SimGyro,
};

use crate::config;

/// The simulated peripherals the board's handles reach.
pub struct SimHw {
    encoders: SimEncoders,
    bridge: SimDriver,
    gyro: SimGyro,
    /// A fault handler (NMI, panic, hard fault) cut the motors: the bridge
    /// outputs nothing until the board resets.
    killed: bool,
}

/// The simulated hardware (None until [`init`]).
static HW: Mutex<RefCell<Option<SimHw>>> = Mutex::new(RefCell::new(None));

/// When the control loop started (its first period begins): the plant
/// task's phase.
pub static LOOP_START: Signal<CriticalSectionRawMutex, Instant> = Signal::new();

/// Seed of the gyro's noise.
const GYRO_SEED: u64 = 0x6779_726F;

/// Sets up the simulated peripherals for `cfg` (the robot at rest).
pub fn init(cfg: &controller_core::runtime::RuntimeConfig) -> Result<(), &'static str> {
    let gyro = SimGyro::new(PRESET_GYRO, GYRO_SEED).map_err(|_| "gyro model")?;
    let hw = SimHw {
        encoders: SimEncoders::new(&cfg.encoder),
        bridge: SimDriver::default(),
        gyro,
        killed: false,
    };
    critical_section::with(|cs| HW.borrow(cs).replace(Some(hw)));
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
        with_hw(|hw| hw.encoders.counts()).unwrap_or([0; 2])
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
        with_hw(|hw| hw.gyro.sample()).flatten()
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
/// simulation cannot go on (invalid motor parameters, no hardware, a
/// diverged plant), with the reason: the caller ends the run (a failed
/// run, exit code 1). Returning it rather than failing here keeps this
/// module below the log (`log` reads [`report`]; nothing here names `log`).
pub async fn plant_task(
    cfg: controller_core::runtime::RuntimeConfig,
    period_us: u32,
) -> &'static str {
    let t0 = LOOP_START.wait().await;
    let plant = Plant::new(PlantParams::from_robot(&config::ROBOT, 1.0, 1.0));
    let p0 = cfg.initial_pose;
    let mut st = PlantState {
        q: [p0.x_m as f64, p0.y_m as f64, p0.theta_rad as f64, 0.0, 0.0],
        nu: [0.0; 2],
    };
    let model = match MotorModel::new(cfg.motor) {
        Ok(m) => m,
        Err(_) => return "plant: invalid motor parameters",
    };
    let dt_s = period_us as f64 * 1e-6;
    let still = Perturbation::default();
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
        let drive = MotorDrive {
            model,
            bridge,
            inverted: cfg.motor_inverted,
        };
        let t_s = (t0_us + k * period_us as u64) as f64 * 1e-6;
        st = plant.rk4_step(&st, t_s, dt_s, &drive, &mut |_| still);
        if !Plant::state_is_finite(&st) {
            return "plant: state diverged";
        }
        let yaw_rate = plant.q_dot(&st, &still)[2];
        with_hw(|hw| {
            hw.encoders.set_angles([st.q[3], st.q[4]]);
            hw.gyro.update(t_s + dt_s, yaw_rate);
        });
        let insn = crate::time::instructions().wrapping_sub(c0);
        critical_section::with(|cs| {
            let mut r = REPORT.borrow(cs).borrow_mut();
            r.pose = [st.q[0], st.q[1], st.q[2]];
            r.step_insn_max = r.step_insn_max.max(insn);
        });
        k += 1;
    }
}
