//! # sim-board
//!
//! The simulated board: robot-app's [`Board`] over sim-robot's [`World`].
//! The world's simulated peripherals (quadrature counters, H-bridge, MEMS
//! gyro, pose source) are the board's encoders, motors, gyro and pose
//! source, so robot-app's own control task — the firmware's — runs on the
//! simulated robot unchanged: the simulator replaces only the sources and
//! the sinks (copper-rs's principle). What a board does beyond its
//! peripherals (a clock, a button, a watchdog, a log) is a [`Harness`]'s.
//!
//! Two ways to run it:
//!
//! * [`SimBoard::step`]: robot-app's loop one period at a time, on the
//!   caller's clock (the world's sensors at the tick's time, robot-app's
//!   [`ControlTask::tick`], the world over the period with the bridge held,
//!   the robot record's write and a reboot between two ticks as the
//!   control task does them). `hil-sim device` serves this behind a pty.
//! * robot-app's async control task on an executor: a [`Harness`] with a
//!   clock ([`Harness::tick_clock_us`]) brings the world up to the tick's
//!   time when the tick reads the peripherals (robot-app's host tests, on
//!   embassy's mock clock).
//!
//! The emulated Cortex-M4 board (`firmware-emu/`) drives the same
//! [`World`] but not this board: there the peripherals are registers the
//! world's readings are latched into by a plant task half a period after
//! each tick, so that the tick's measured instruction count is the
//! firmware's alone (book/src/explanation/decisions.md D140).
//!
//! `no_std`, no allocation.
#![no_std]
#![deny(missing_docs)]
#![forbid(unsafe_code)]

use robot_app::store::RecordWriter;
use robot_app::{AppEvent, Board, BoardIo, ControlTask, LinkPipes};
use sim_robot::world::{Actuation, Diverged, Reading, WorldGyro, WorldPoseSource};
use sim_robot::{SimDriver, SimEncoders, World};
use wmr_device::Device;

/// What a simulated board does beyond the world's peripherals. Every
/// method has a default: no clock of its own, no button, a watchdog and a
/// log that do nothing ([`NoHarness`]).
pub trait Harness {
    /// Whether the board logs [`AppEvent::Status`] and
    /// [`AppEvent::Telemetry`] ([`Board::LOGS_STATUS`]).
    const LOGS_STATUS: bool = false;

    /// Called when a tick reads the peripherals: the board's clock now
    /// \[µs\] when the world follows it (the world is brought up to it in
    /// whole periods first), None when the caller advances the world
    /// ([`SimBoard::step`]).
    fn tick_clock_us(&mut self) -> Option<u64> {
        None
    }

    /// The plant diverged while a tick brought it up to
    /// [`Self::tick_clock_us`] (it stays where it was from then on).
    fn plant_diverged(&mut self, diverged: Diverged) {
        let _ = diverged;
    }

    /// The operator button (raw level); `world` as of the tick.
    fn button_pressed(&mut self, world: &World) -> bool {
        let _ = world;
        false
    }

    /// [`Board::start_watchdog`].
    fn start_watchdog(&mut self) {}

    /// [`Board::feed_watchdog`].
    fn feed_watchdog(&mut self) {}

    /// [`Board::reboot`] (an acknowledged `Reboot` drained).
    fn reboot(&mut self) {}

    /// [`Board::cycles`] (0: no cycle counter).
    fn cycles(&mut self) -> u32 {
        0
    }

    /// [`Board::event`].
    fn event(&mut self, event: &AppEvent<'_>) {
        let _ = event;
    }
}

/// A board with nothing beyond the world.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoHarness;

impl Harness for NoHarness {}

/// The simulated board: `world` behind robot-app's [`Board`], its plant
/// stepped in whole control periods with the H-bridge held (zero-order
/// hold, as a PWM timer holds the duty between two ticks).
pub struct SimBoard<H: Harness = NoHarness> {
    world: World,
    period_s: f64,
    period_us: u64,
    /// Periods the plant has been advanced: its time is `plant_ticks`
    /// periods.
    plant_ticks: u64,
    diverged: Option<Diverged>,
    harness: H,
}

/// What happened between a [`SimBoard::step`]'s tick and the next.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Step {
    /// The robot record was written to the store (`Some(stored and read
    /// back equal)`).
    pub robot_written: Option<bool>,
    /// An acknowledged `Reboot` is due ([`ControlTask::reboot_due`]): the
    /// caller restarts the device (the harness's [`Harness::reboot`] has
    /// been told).
    pub reboot: bool,
}

impl<H: Harness> SimBoard<H> {
    /// The board over `world` (its plant at time 0), ticked every
    /// `period_s` (the control period; robot µs ticks of its rounding).
    pub fn new(world: World, period_s: f64, harness: H) -> Self {
        Self {
            world,
            period_s,
            period_us: libm_round_us(period_s),
            plant_ticks: 0,
            diverged: None,
            harness,
        }
    }

    /// The world.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The world, mutable (faults a test injects).
    pub fn world_mut(&mut self) -> &mut World {
        &mut self.world
    }

    /// The harness.
    pub fn harness(&self) -> &H {
        &self.harness
    }

    /// The harness, mutable.
    pub fn harness_mut(&mut self) -> &mut H {
        &mut self.harness
    }

    /// The control period \[s\] (one plant step).
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// Periods the plant has been advanced.
    pub fn plant_ticks(&self) -> u64 {
        self.plant_ticks
    }

    /// Robot time of the plant \[µs\] (a wrapping firmware clock's).
    pub fn now_us(&self) -> u32 {
        (self.plant_ticks * self.period_us) as u32
    }

    /// The plant's first divergence, if it diverged while a tick brought
    /// it up to the harness's clock (it stays where it was from then on).
    pub fn diverged(&self) -> Option<Diverged> {
        self.diverged
    }

    /// The sensors at the plant's time (the encoders latch, the gyro and
    /// the pose source sample when due).
    pub fn sense(&mut self) -> Reading {
        self.world.sense(self.plant_ticks as f64 * self.period_s)
    }

    /// The plant over one period with the H-bridge as the last tick left it.
    pub fn advance_period(&mut self) -> Result<(), Diverged> {
        let bridge = self.world.bridge();
        self.world
            .advance(Actuation::Bridge(bridge), self.period_s)?;
        self.plant_ticks += 1;
        Ok(())
    }

    /// The plant in whole periods up to `now_us`, then the sensors.
    pub fn advance_to_us(&mut self, now_us: u64) -> Result<(), Diverged> {
        if let Some(d) = self.diverged {
            return Err(d);
        }
        while (self.plant_ticks + 1) * self.period_us <= now_us {
            if let Err(d) = self.advance_period() {
                self.diverged = Some(d);
                return Err(d);
            }
        }
        self.sense();
        Ok(())
    }

    /// One control period of robot-app's loop at the plant's time, as its
    /// control task runs it on a board: the sensors at the tick's time,
    /// [`ControlTask::tick`] (host bytes in from `pipes`, the device's
    /// tick, bytes out, the watchdog, the button, the events), the world
    /// over the period with the bridge held, then between two ticks the
    /// robot record's write ([`ControlTask::store_robot`]; the simulated
    /// flash takes no robot time) and the reboot check
    /// ([`ControlTask::reboot_due`]).
    pub fn step<const N: usize, S: RecordWriter>(
        &mut self,
        task: &mut ControlTask,
        dev: &mut Device<N>,
        pipes: &LinkPipes,
        store: &mut S,
    ) -> Result<Step, Diverged> {
        self.sense();
        let now_us = self.now_us();
        task.tick(now_us, self, dev, pipes);
        self.advance_period()?;
        let mut step = Step::default();
        if dev.pending_robot_write().is_some() {
            let written = embassy_futures::block_on(task.store_robot(self, dev, store));
            if let Some(ok) = written {
                self.harness
                    .event(&AppEvent::RobotWritten { ok, duration_us: 0 });
            }
            step.robot_written = written;
        }
        if task.reboot_due(dev, pipes) {
            self.harness.reboot();
            step.reboot = true;
        }
        Ok(step)
    }
}

/// `period_s` in whole µs (no_std: no `f64::round`).
fn libm_round_us(period_s: f64) -> u64 {
    let us = period_s * 1e6;
    if us.is_finite() && us > 0.0 {
        (us + 0.5) as u64
    } else {
        0
    }
}

impl<H: Harness> Board for SimBoard<H> {
    type Encoders = SimEncoders;
    type Motors = SimDriver;
    type Gyro = WorldGyro;
    type PoseSource = WorldPoseSource;

    const LOGS_STATUS: bool = H::LOGS_STATUS;

    fn io(&mut self) -> BoardIo<'_, SimEncoders, SimDriver, WorldGyro, WorldPoseSource> {
        if let Some(now_us) = self.harness.tick_clock_us() {
            // A diverged plant stays put (its sensors too).
            if let Err(d) = self.advance_to_us(now_us) {
                self.harness.plant_diverged(d);
            }
        }
        let io = self.world.io();
        BoardIo {
            encoders: io.encoders,
            motors: io.motors,
            gyro: io.gyro,
            pose_source: io.pose_source,
        }
    }

    fn motors(&mut self) -> &mut SimDriver {
        self.world.io().motors
    }

    fn button_pressed(&mut self) -> bool {
        self.harness.button_pressed(&self.world)
    }

    fn start_watchdog(&mut self) {
        self.harness.start_watchdog();
    }

    fn feed_watchdog(&mut self) {
        self.harness.feed_watchdog();
    }

    fn reboot(&mut self) {
        self.harness.reboot();
    }

    fn cycles(&mut self) -> u32 {
        self.harness.cycles()
    }

    fn event(&mut self, event: &AppEvent<'_>) {
        self.harness.event(event);
    }
}
