//! The simulated robot behind the host link (`hil-sim device --pty`): the
//! firmware's application — robot-app's control task around the link
//! handler ([`wmr_device::Device`]) and the runtime inside it — on the
//! simulated board ([`sim_board::SimBoard`]: the scenario's
//! [`sim_robot::World`], the same as `hil-sim run`'s, behind the board's
//! peripherals), stepped one control period at a time, and served over a
//! pseudo-terminal so that `wmr` talks to it exactly as to a robot.
//!
//! Robot time is simulated time (one control period per tick); `--speed N`
//! paces the ticks N times faster than the wall clock, and the durations
//! the host gives (the link timeout, a velocity command's timeout) count
//! the host's time ([`SimRobot::set_speed`], D140).

pub use crate::closed_loop::world::Miswire;
use crate::scenario::{Scenario, Sensing};
use crate::sim::controller_config;
use controller_core::estimator::EstimatorConfig;
use controller_core::runtime::RuntimeConfig;
use controller_core::runtime::{ArmingButton, LoopTimer, TickReport};
use controller_core::ControllerKind;
use robot_app::link::PIPE_BYTES;
use robot_app::store::{load_record, FlashRecord};
use robot_app::{AppConfig, AppEvent, ControlTask, LinkPipes};
use robot_store::{validate_robot, RamFlash, RobotStore};
use sim_board::{Harness, SimBoard};
use sim_robot::World;
use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use wmr_device::{Device, DeviceConfig, LinkConfig};
use wmr_protocol::{
    RobotSource, CAP_EXTERNAL_POSE, CAP_ROBOT_STORE, CAP_SIMULATED, CAP_TRAJECTORY, CAP_VELOCITY,
    ROBOT_BLOB_MAX,
};

/// The simulated device's flash for the robot record: two pages of 8 KiB
/// (the STM32 store's two 128 KiB sectors scaled down: the record and
/// sequential-storage's map work the same; the sim need not erase seconds).
pub type SimFlash = RamFlash<{ 16 * 1024 }, { 8 * 1024 }>;

/// The timer clock the simulated device's PWM runs from \[Hz\] (the F411's).
pub const SIM_TIMER_CLOCK_HZ: u32 = 96_000_000;

/// The arm button's debounce \[ticks\] (the simulated board has no button;
/// the control task wants one).
const BUTTON_DEBOUNCE_TICKS: u16 = 20;

/// The simulated board's harness: no button, watchdog or log; it keeps
/// each tick's report (robot-app's [`AppEvent::Telemetry`], every tick).
#[derive(Default)]
struct Reports {
    last: Option<TickReport>,
}

impl Harness for Reports {
    const LOGS_STATUS: bool = true;

    fn event(&mut self, event: &AppEvent<'_>) {
        if let AppEvent::Telemetry(rep) = event {
            self.last = Some(**rep);
        }
    }
}

/// What the control task reports: every tick's report to the harness, no
/// status.
const APP_CONFIG: AppConfig = AppConfig {
    status_every_ticks: 0,
    telemetry_every_ticks: 1,
};

/// The firmware's application on the simulated board, one tick at a time.
pub struct SimRobot {
    device: Device,
    task: ControlTask,
    board: SimBoard<Reports>,
    /// The host link's byte pipes (the port's side: [`Self::port_received`],
    /// [`Self::port_take_tx`]).
    pipes: LinkPipes,
    /// The robot store over the simulated flash (kept across reboots).
    store: FlashRecord<SimFlash>,
    /// What a boot builds the device from.
    boot: BootConfig,
    /// Reboots so far.
    reboots: u32,
    /// Robot µs per host ms (`Device::set_host_clock`).
    robot_us_per_host_ms: u32,
}

/// The scenario's configuration: the compiled-in robot of the simulated
/// device, and what a robot from flash is combined with.
struct BootConfig {
    kind: ControllerKind,
    /// A flash robot runs its own `[control] controller` and starts its
    /// odometry at its own `initial_*`, as the firmware's boot does
    /// ([`SimRobot::follow_flash_robot`]); otherwise `kind` and the
    /// scenario's initial pose.
    follow_flash_robot: bool,
    dev_cfg: DeviceConfig,
    runtime: RuntimeConfig,
    estimator: EstimatorConfig,
    /// The compiled-in robot's record (`default_record`).
    default_record: Vec<u8>,
}

/// The control task of a device booted with `cfg` (its loop period).
fn control_task(cfg: &RuntimeConfig) -> Result<ControlTask, String> {
    let timer = LoopTimer::from_config(cfg).map_err(|e| format!("loop timer: {e}"))?;
    let button = ArmingButton::new(BUTTON_DEBOUNCE_TICKS).map_err(|e| format!("button: {e:?}"))?;
    ControlTask::new(timer, button, APP_CONFIG).map_err(|e| format!("control task: {e:?}"))
}

/// The compiled-in robot of the simulated device: the scenario's robot
/// (`--robot`, default the paper's), in robot-file's binary form.
fn default_record(robot: &robot_file::Robot) -> Result<Vec<u8>, String> {
    let mut buf = [0u8; ROBOT_BLOB_MAX];
    let n = robot
        .encode(&mut buf)
        .map_err(|e| format!("robot {}: binary form: {e:?}", robot.name))?;
    Ok(buf[..n].to_vec())
}

/// Builds the device the way a boot does: the record in flash (validated)
/// or the default; a flash robot's runtime configuration from the robot
/// file (with the scenario's reference and initial pose), the scenario's
/// otherwise. A flash robot the runtime refuses falls back to the default
/// and reports `DefaultCorrupt`.
fn boot_device(boot: &BootConfig, store: &mut FlashRecord<SimFlash>) -> Result<Device, String> {
    let mut record = [0u8; ROBOT_BLOB_MAX];
    let default = boot.default_record.clone();
    let (n, mut source, _) = embassy_futures::block_on(load_record(store, &default, &mut record));
    let from_flash = match source {
        RobotSource::Flash => robot_file::Robot::decode(&record[..n])
            .ok()
            .and_then(|mut r| {
                // As the firmware's boot: the one derivation on this board
                // (its PWM timer read back for the robot's frequency), with
                // the device's controller and the scenario's start pose.
                if !boot.follow_flash_robot {
                    let p = boot.runtime.initial_pose;
                    r.control.controller = boot.kind;
                    (r.control.initial_x_m, r.control.initial_y_m) = (p.x_m, p.y_m);
                    r.control.initial_heading_rad = p.theta_rad;
                }
                let facts = robot_file::BoardFacts {
                    pwm_full_scale: r.pwm_full_scale(SIM_TIMER_CLOCK_HZ).ok()?,
                    control_period_s: boot.runtime.controller.period_s,
                    gyro_saturation_radps: Some(boot.estimator.gyro_saturation_radps),
                };
                Some(r.derive(&facts, boot.runtime.reference))
            })
            .and_then(|d| Device::with_estimator(boot.dev_cfg, d.runtime, d.estimator).ok()),
        _ => None,
    };
    let (mut device, rec): (Device, &[u8]) = match from_flash {
        Some(d) => (d, &record[..n]),
        None => {
            if source == RobotSource::Flash {
                source = RobotSource::DefaultCorrupt;
            }
            let d = Device::with_estimator(boot.dev_cfg, boot.runtime, boot.estimator)
                .map_err(|e| format!("device: {e}"))?;
            (
                d,
                if source == RobotSource::Flash {
                    &record[..n]
                } else {
                    &default
                },
            )
        }
    };
    device.attach_robot_store(validate_robot, rec, source);
    Ok(device)
}

/// The link's limits from the robot file's `[limits]` (timeout, speed,
/// yaw rate, acceleration), the rest `LinkConfig::DEFAULT`'s; the paper
/// robot's are the defaults (robot-file's `Limits::paper`).
pub fn link_config(robot: &crate::scenario::Robot) -> LinkConfig {
    let l = &robot.limits;
    LinkConfig {
        link_timeout_ms: l.link_timeout_ms,
        accel_mps2: l.max_accel_mps2,
        max_speed_mps: l.max_speed_mps,
        max_yaw_rate_radps: l.max_yaw_rate_radps,
        ..LinkConfig::DEFAULT
    }
}

impl SimRobot {
    /// The robot of `scn` (at rest at `initial_pose`, in hold) with the
    /// runtime running `kind` at the scenario's gains and the simulated
    /// world of `hil-sim run` for the scenario (its perturbations, weak
    /// wheel and the sensors of its sensing preset; `ideal` is served as
    /// `mocap`: the runtime always reads encoders); external poses sent by
    /// the host go to the same estimator.
    pub fn new(scn: &Scenario, kind: ControllerKind) -> Result<Self, String> {
        Self::miswired(scn, kind, &Miswire::default(), |_| {})
    }

    /// [`Self::new`] with wiring mistakes in the plant (`wmr commission`'s
    /// test) and the runtime configuration changed by `runtime` (the robot
    /// file the robot runs: its inversion flags and resolution), the plant
    /// staying as the scenario builds it.
    pub fn miswired(
        scn: &Scenario,
        kind: ControllerKind,
        miswire: &Miswire,
        runtime: impl FnOnce(&mut controller_core::runtime::RuntimeConfig),
    ) -> Result<Self, String> {
        scn.validate()?;
        let mut served = scn.clone();
        if served.sensing.preset == Sensing::Ideal {
            served.sensing.preset = Sensing::Mocap;
        }
        let scn = &served;
        let controller = controller_config(scn, kind);
        let built = scn.runtime_config(controller, scn.safety_limits());
        // The plant is built as `built` says (its mountings, resolution);
        // the runtime may believe otherwise.
        let mut cfg = built;
        runtime(&mut cfg);
        // The runtime gives the estimator its geometry and initial pose.
        let estimator = scn.derive(kind).estimator;
        let dev_cfg = DeviceConfig {
            chip: "sim",
            capabilities: CAP_EXTERNAL_POSE
                | CAP_TRAJECTORY
                | CAP_VELOCITY
                | CAP_SIMULATED
                | CAP_ROBOT_STORE,
            link: link_config(&scn.robot),
            button_reference: None,
        };
        let boot = BootConfig {
            kind,
            follow_flash_robot: false,
            dev_cfg,
            runtime: cfg,
            estimator,
            default_record: default_record(&scn.robot)?,
        };
        let mut store = FlashRecord {
            store: RobotStore::new(SimFlash::new(), 0..16 * 1024)
                .map_err(|_| "robot store: flash range".to_string())?,
            validate: validate_robot,
        };
        let device = boot_device(&boot, &mut store)?;
        let task = control_task(device.control().config())?;
        let world: World =
            crate::closed_loop::world::hardware_world_miswired(scn, &built, None, miswire)?;
        Ok(Self {
            device,
            task,
            board: SimBoard::new(world, scn.control_period_s, Reports::default()),
            pipes: LinkPipes::new(),
            store,
            boot,
            reboots: 0,
            robot_us_per_host_ms: 1000,
        })
    }

    /// The host's clock runs `speed` times slower than the robot's
    /// (`--speed`): the durations the host gives count its own time
    /// (`wmr_device::Device::set_host_clock`), kept across reboots.
    pub fn set_speed(&mut self, speed: f64) {
        self.robot_us_per_host_ms = (speed * 1000.0).round().clamp(1.0, u32::MAX as f64) as u32;
        self.device.set_host_clock(self.robot_us_per_host_ms);
    }

    /// From now on, a robot file in the simulated flash runs as the
    /// firmware runs it: its own `[control] controller` and its odometry
    /// starting at its own `[control] initial_*` at every boot (`hil-sim
    /// device` without `--controller`). By default a flash robot takes the
    /// controller and initial pose this device was built with (tests that
    /// push a file and keep their scenario's frame).
    pub fn follow_flash_robot(&mut self) {
        self.boot.follow_flash_robot = true;
    }

    /// Restarts the simulated MCU: a new device and control task (hold,
    /// motors off, empty link pipes) built from the record in the
    /// simulated flash, which survives; the world (the robot's hardware)
    /// goes on. The control task asks for this once a `Reboot`'s
    /// acknowledgement has left.
    pub fn reboot(&mut self) -> Result<(), String> {
        // Like a power cycle: a fresh store over the same flash.
        let old = std::mem::replace(
            &mut self.store.store,
            RobotStore::new(SimFlash::new(), 0..16 * 1024).map_err(|_| "flash range")?,
        );
        self.store.store =
            RobotStore::new(old.into_flash(), 0..16 * 1024).map_err(|_| "flash range")?;
        self.device = boot_device(&self.boot, &mut self.store)?;
        self.device.set_host_clock(self.robot_us_per_host_ms);
        self.task = control_task(self.device.control().config())?;
        self.pipes = LinkPipes::new();
        self.reboots += 1;
        Ok(())
    }

    /// Reboots so far.
    pub fn reboots(&self) -> u32 {
        self.reboots
    }

    /// The link handler.
    pub fn device(&mut self) -> &mut Device {
        &mut self.device
    }

    /// The simulated world.
    pub fn world(&self) -> &World {
        self.board.world()
    }

    /// The true pose of G \[x m, y m, θ rad\].
    pub fn true_pose(&self) -> [f64; 3] {
        self.world().true_pose()
    }

    /// The true wheel angles φ = \[φ_R, φ_L\] \[rad\] (the plant's, which
    /// the encoders sample).
    pub fn true_wheel_angles_rad(&self) -> [f64; 2] {
        let q = &self.world().state().q;
        [q[3], q[4]]
    }

    /// Robot time of the next tick \[µs\] (wraps like a firmware clock).
    pub fn now_us(&self) -> u32 {
        self.board.now_us()
    }

    /// Ticks run.
    pub fn ticks(&self) -> u64 {
        self.board.plant_ticks()
    }

    /// The port's side: bytes from the host into the receive pipe; what
    /// does not fit is dropped and counted (the status's `port_rx_dropped`).
    /// Returns the bytes kept.
    pub fn port_received(&mut self, bytes: &[u8]) -> usize {
        self.pipes.port_received(bytes)
    }

    /// Room in the receive pipe \[bytes\] (a port that holds the host off
    /// reads no more).
    pub fn port_rx_room(&self) -> usize {
        PIPE_BYTES - self.pipes.rx_len()
    }

    /// The port's side: bytes for the host, up to `buf.len()`.
    pub fn port_take_tx(&mut self, buf: &mut [u8]) -> usize {
        self.pipes.port_try_tx(buf)
    }

    /// One control period of robot-app's loop on the simulated board
    /// ([`SimBoard::step`]: the world's sensors, the control task's tick —
    /// host bytes in, the device's tick, bytes out —, the world over the
    /// period with the H-bridge held, the robot record's write and a due
    /// reboot between two ticks); the tick's report.
    pub fn step(&mut self) -> Result<TickReport, String> {
        let step = self
            .board
            .step(
                &mut self.task,
                &mut self.device,
                &self.pipes,
                &mut self.store,
            )
            .map_err(|e| e.to_string())?;
        let rep = self
            .board
            .harness_mut()
            .last
            .take()
            .ok_or("the control task reported no tick")?;
        if step.reboot {
            self.reboot()?;
        }
        Ok(rep)
    }
}

/// Serves `robot` on `port` (the master side of a pseudo-terminal, or any
/// byte stream with non-blocking reads) until `stop` is set: per tick, the
/// bytes that fit into the receive buffer in, one tick, the queued bytes
/// out (dropped when the other side does not read, like a USB CDC with no
/// host). Ticks are paced at `speed` × real time; a host that falls
/// behind never slows the robot.
pub fn serve(
    robot: &mut SimRobot,
    port: &mut (impl Read + Write),
    speed: f64,
    stop: &AtomicBool,
) -> Result<(), String> {
    robot.set_speed(speed);
    let period = Duration::from_secs_f64(robot.board.period_s() / speed);
    let start = Instant::now();
    let mut next = start;
    let mut rx = [0u8; PIPE_BYTES];
    let mut tx = Vec::with_capacity(4096);
    while !stop.load(Ordering::Relaxed) {
        // Only what the receive pipe has room for: the pty holds the rest
        // (a USB port NAKs the host), nothing is dropped.
        let room = robot.port_rx_room().min(rx.len());
        if room > 0 {
            match port.read(&mut rx[..room]) {
                Ok(n) => {
                    robot.port_received(&rx[..n]);
                }
                Err(e) if transient(&e) => {}
                Err(e) => return Err(format!("pty read: {e}")),
            }
        }
        robot.step()?;
        if tx.is_empty() {
            let mut buf = [0u8; PIPE_BYTES];
            let n = robot.port_take_tx(&mut buf);
            tx.extend_from_slice(&buf[..n]);
        }
        if !tx.is_empty() {
            match port.write(&tx) {
                Ok(n) => {
                    tx.drain(..n);
                }
                Err(e) if transient(&e) => {}
                Err(e) => return Err(format!("pty write: {e}")),
            }
        }
        next += period;
        let now = Instant::now();
        if next > now {
            std::thread::sleep(next - now);
        } else if now - next > Duration::from_millis(100) {
            // Far behind (a loaded machine): do not try to catch up. The
            // robot's clock then runs slower than `speed` times the host's,
            // which only lengthens the host's durations in wall time
            // (`set_speed`): safe.
            next = now;
        }
    }
    Ok(())
}

fn transient(e: &std::io::Error) -> bool {
    use std::io::ErrorKind::*;
    matches!(e.kind(), TimedOut | WouldBlock | Interrupted)
}

/// The simulated robot served on a pseudo-terminal by a thread of this
/// process ([`serve`] on [`open_pty`]'s master side): what `hil-sim device
/// --pty` runs, as the end-to-end tests' rig (hil-sim's and wmr's). The
/// robot stops when this is dropped.
pub struct PtyRobot {
    /// The pty's path: the port to give the host.
    pub path: String,
    stop: Arc<AtomicBool>,
    handle: Option<JoinHandle<Result<SimRobot, String>>>,
    _slave: serialport::TTYPort,
}

impl PtyRobot {
    /// Serves `robot` at `speed` × real time on a new pty.
    pub fn start(mut robot: SimRobot, speed: f64) -> Result<Self, String> {
        let (mut master, slave, path) = open_pty()?;
        let stop = Arc::new(AtomicBool::new(false));
        let s = stop.clone();
        let handle =
            std::thread::spawn(move || serve(&mut robot, &mut master, speed, &s).map(|()| robot));
        Ok(Self {
            path,
            stop,
            handle: Some(handle),
            _slave: slave,
        })
    }

    /// Stops the robot: the robot, or the error that ended [`serve`].
    pub fn finish(mut self) -> Result<SimRobot, String> {
        self.stop.store(true, Ordering::Relaxed);
        match self.handle.take().map(JoinHandle::join) {
            Some(Ok(r)) => r,
            _ => Err("the robot's thread panicked".into()),
        }
    }

    /// One real-time robot at a time: tests hold this lock while theirs
    /// runs (several at once on 2 shared cores would starve the robots'
    /// clocks, which timing assertions measure).
    pub fn serial() -> MutexGuard<'static, ()> {
        static SERIAL: Mutex<()> = Mutex::new(());
        SERIAL.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl Drop for PtyRobot {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

/// A pseudo-terminal pair for the simulated robot: the master side for
/// [`serve`] (non-blocking reads and writes) and the slave side, kept
/// open so that hosts can come and go; returns (master, slave, slave path).
pub fn open_pty() -> Result<(serialport::TTYPort, serialport::TTYPort, String), String> {
    use serialport::SerialPort;
    let (mut master, slave) =
        serialport::TTYPort::pair().map_err(|e| format!("cannot open a pseudo-terminal: {e}"))?;
    master
        .set_timeout(Duration::ZERO)
        .map_err(|e| format!("pty: {e}"))?;
    let path = slave
        .name()
        .ok_or_else(|| "pty: the slave side has no path".to_string())?;
    Ok((master, slave, path))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::PerturbationPart;
    use crate::scenario::Robot;
    use wmr_protocol::{Request, RunStateMsg, MAX_FRAME};

    fn send(robot: &mut SimRobot, seq: u16, req: &Request) {
        let mut buf = [0u8; MAX_FRAME];
        let frame = wmr_protocol::encode(req, seq, &mut buf).unwrap();
        assert_eq!(robot.port_received(frame), frame.len());
    }

    /// Drives `scn`'s robot behind the link at 0.3 m/s for 1 s (velocity
    /// commands refreshed, armed over the link); returns the distance G
    /// travelled \[m\] and whether the bridge was ever driven while running.
    fn drive(scn: &Scenario) -> (f64, bool) {
        let mut robot = SimRobot::new(scn, ControllerKind::Proposed).unwrap();
        let p0 = robot.true_pose();
        let velocity = Request::Velocity {
            v_mps: 0.3,
            omega_radps: 0.0,
            timeout_ms: 500,
        };
        send(&mut robot, 1, &velocity);
        send(&mut robot, 2, &Request::Arm);
        let mut driven = false;
        for k in 0..1000u16 {
            if k % 100 == 99 {
                send(&mut robot, 3 + k, &velocity);
            }
            robot.step().unwrap();
            let mut out = [0u8; 4096];
            robot.port_take_tx(&mut out);
            let b = robot.world().bridge();
            driven |= robot.device().state() == RunStateMsg::Running
                && b.enabled
                && b.duty.iter().any(|d| d.duty > 0);
        }
        let p = robot.true_pose();
        ((p[0] - p0[0]).hypot(p[1] - p0[1]), driven)
    }

    /// The robot behind the link is the robot of `hil-sim run`: a scenario
    /// whose wheels deliver no torque inside its window (weak wheels,
    /// `wheel_torque_scale = [0, 0]`, nothing else acting) cannot move, however
    /// hard the runtime drives the bridge (no force on a robot at rest:
    /// ν̇ = 0). The same scenario with healthy wheels moves (the check is
    /// not blind). Before the world was shared, the link's robot ignored
    /// the weak wheels and drove off.
    #[test]
    fn robot_behind_the_link_has_the_scenarios_weak_wheels() {
        let mut still = Scenario::default().with_sensing(Sensing::Mocap);
        still.perturbations = PerturbationPart {
            window_s: [0.0, 100.0],
            wheel_torque_scale: [0.0, 0.0],
            ..PerturbationPart::none()
        };
        let (dead, driven) = drive(&still);
        assert!(driven, "the runtime never drove the bridge");
        assert!(dead < 1e-12, "a robot without wheel torque moved {dead} m");
        let mut healthy = still;
        healthy.perturbations.wheel_torque_scale = [1.0, 1.0];
        let (moved, _) = drive(&healthy);
        assert!(moved > 0.1, "healthy robot moved only {moved} m");
    }

    /// `device --robot FILE` serves that robot: the runtime's encoder, motor
    /// and controller model are the file's, the link's limits its
    /// `[limits]`; the paper robot's link limits are the defaults.
    #[test]
    fn device_serves_the_robot_of_its_file() {
        assert_eq!(link_config(&Robot::paper()), LinkConfig::DEFAULT);
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../robots/tb6612-2kg.toml"
        ))
        .unwrap();
        let robot = Robot::from_toml_str(&text).unwrap();
        let scn = Scenario::default().with_robots(Some(&robot), None);
        let mut sim = SimRobot::new(&scn, ControllerKind::Proposed).unwrap();
        let link = *sim.device().link_config();
        assert_eq!(
            (link.max_speed_mps, link.max_yaw_rate_radps),
            (robot.limits.max_speed_mps, robot.limits.max_yaw_rate_radps)
        );
        let cfg = *sim.device().control().config();
        assert_eq!(cfg.encoder.counts_per_wheel_rev, 1320.0);
        assert_eq!(cfg.controller.robot.wheel_radius_m, 0.035);
        assert_eq!(cfg.controller.torque_limit_nm, robot.limits.torque_nm);
        assert_eq!(
            cfg.motor.torque_constant_nm_per_a,
            robot.motors.torque_constant_nm_per_a
        );
    }
}
