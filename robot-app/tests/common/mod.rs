//! The host-test rig: robot-app's real tasks on embassy's std executor
//! (its own thread), embassy-time's mock clock advanced by the test thread,
//! the simulated board (`sim_board::SimBoard`: a `sim_robot::World`, the
//! plant behind simulated encoders and H-bridge, the board `hil-sim device`
//! runs) with the test's probes, and a minimal host speaking
//! wmr-protocol through the link pipes.
//!
//! The mock clock is global: the tests of one binary run one at a time
//! ([`Rig::start`] takes a lock and resets the clock).
#![allow(dead_code)]

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration as StdDuration, Instant as StdInstant};

use controller_core::runtime::{ArmingButton, LoopTimer, RuntimeConfig};
use controller_core::ControllerKind;
use embassy_executor::{Executor, Spawner};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;
use embassy_time::{Duration, Instant, MockDriver};
use robot_app::{AppConfig, AppEvent, ControlTask, LinkPipes, StatusSummary};
use sim_board::{Harness, SimBoard};
use sim_robot::{World, WorldConfig};
use wmr_device::{Device, DeviceConfig};
use wmr_protocol::{Decoded, FrameDecoder, Reply, Request, RunStateMsg, MAX_FRAME};

/// Pose history of the devices under test.
pub const H: usize = 16;
/// The loop period \[µs\] (RuntimeConfig::example: 1 kHz).
pub const PERIOD_US: u64 = 1000;
/// Button debounce \[ticks\] (as the firmware's).
pub const DEBOUNCE_TICKS: u16 = 20;

/// What the board saw, for the test thread.
#[derive(Default, Debug)]
pub struct Obs {
    /// Mock time at each tick's peripheral access \[µs\].
    pub tick_times_us: Vec<u64>,
    /// Watchdog started (and at which tick count).
    pub watchdog_started_at: Option<usize>,
    /// Feeds so far.
    pub feeds: u32,
    /// Motor driver enabled now.
    pub motors_enabled: bool,
    /// Events, in order, as text.
    pub events: Vec<String>,
    /// Ticks run when the first safe stop was announced.
    pub stop_at_tick: Option<usize>,
    /// The last status event.
    pub last_status: Option<StatusSummary>,
    /// Run states announced, in order, with the mock time \[µs\].
    pub states: Vec<(u64, RunStateMsg)>,
}

/// Knobs the test thread turns while the tasks run.
pub struct Knobs {
    pub button: AtomicBool,
    /// Each tick's peripheral access advances the mock clock by this much
    /// \[µs\] (a slow tick).
    pub tick_cost_us: AtomicU32,
    /// The hog task blocks the executor thread while this is set.
    pub hog_hold: AtomicBool,
    pub hog_active: AtomicBool,
    pub hog_go: Signal<CriticalSectionRawMutex, ()>,
}

pub struct Shared {
    pub obs: Mutex<Obs>,
    pub knobs: Knobs,
}

/// The mock board: the simulated board (`sim_board::SimBoard`: the world
/// behind raw encoders and an H-bridge; no gyro, no external pose source,
/// nothing perturbing) on embassy's mock clock, with the test's harness.
pub type MockBoard = SimBoard<Probe>;

/// The board's harness: the mock clock (each tick's peripheral access
/// brings the world up to it), the button, the watchdog and the log, all
/// observed by the test thread.
pub struct Probe {
    shared: &'static Shared,
}

impl Probe {
    fn obs(&self) -> MutexGuard<'_, Obs> {
        self.shared.obs.lock().unwrap()
    }
}

fn mock_board(shared: &'static Shared, cfg: &RuntimeConfig) -> MockBoard {
    let period_s = PERIOD_US as f64 * 1e-6;
    let world = World::new(&WorldConfig {
        period_s,
        ..WorldConfig::of_runtime(cfg)
    })
    .expect("world");
    SimBoard::new(world, period_s, Probe { shared })
}

impl Harness for Probe {
    const LOGS_STATUS: bool = true;

    fn tick_clock_us(&mut self) -> Option<u64> {
        let now = Instant::now().as_micros();
        self.obs().tick_times_us.push(now);
        let cost = self.shared.knobs.tick_cost_us.load(Ordering::SeqCst);
        if cost > 0 {
            MockDriver::get().advance(Duration::from_micros(cost as u64));
        }
        Some(now)
    }

    fn plant_diverged(&mut self, diverged: sim_robot::world::Diverged) {
        panic!("{diverged}");
    }

    fn button_pressed(&mut self, world: &World) -> bool {
        // The bridge state as of the previous tick, published here.
        self.obs().motors_enabled = world.bridge().enabled;
        self.shared.knobs.button.load(Ordering::SeqCst)
    }

    fn start_watchdog(&mut self) {
        let mut o = self.obs();
        let n = o.tick_times_us.len();
        o.watchdog_started_at = Some(n);
    }

    fn feed_watchdog(&mut self) {
        self.obs().feeds += 1;
    }

    fn event(&mut self, event: &AppEvent<'_>) {
        let mut o = self.obs();
        match event {
            AppEvent::State(s) => o.states.push((Instant::now().as_micros(), *s)),
            AppEvent::Status(s) => o.last_status = Some(*s),
            AppEvent::SafeStop(_) if o.stop_at_tick.is_none() => {
                o.stop_at_tick = Some(o.tick_times_us.len())
            }
            _ => {}
        }
        let text = format!("{event:?}");
        o.events.push(text);
    }
}

#[embassy_executor::task(pool_size = 16)]
async fn control(
    board: &'static mut MockBoard,
    dev: &'static mut Device<H>,
    pipes: &'static LinkPipes,
    task: ControlTask,
) {
    robot_app::control_task(board, dev, pipes, task).await
}

/// Blocks the executor thread (no `.await`) while `hog_hold` is set: a task
/// that never yields, or a driver that hangs.
#[embassy_executor::task(pool_size = 16)]
async fn hog(shared: &'static Shared) {
    loop {
        shared.knobs.hog_go.wait().await;
        shared.knobs.hog_active.store(true, Ordering::SeqCst);
        while shared.knobs.hog_hold.load(Ordering::SeqCst) {
            std::thread::sleep(StdDuration::from_micros(200));
        }
        shared.knobs.hog_active.store(false, Ordering::SeqCst);
    }
}

static SERIAL: Mutex<()> = Mutex::new(());

/// One running application.
pub struct Rig {
    _serial: MutexGuard<'static, ()>,
    pub shared: &'static Shared,
    pub pipes: &'static LinkPipes,
    decoder: FrameDecoder<MAX_FRAME>,
    seq: u16,
    /// Replies read so far and not yet taken.
    pub replies: Vec<Reply>,
}

/// The device configuration of the tests: firmware-like (hold at boot, the
/// button drives a 0.5 m circle at 0.2 m/s from the start pose).
/// Both from the paper's robot file (`robot_file::Robot::paper()`), as the
/// firmware builds them from its compiled-in robot.
pub fn runtime_config() -> RuntimeConfig {
    let kind = ControllerKind::Proposed;
    let robot = robot_file::Robot::paper();
    let board =
        robot_file::BoardFacts::of_timer(&robot, 96_000_000).expect("the paper robot is valid");
    robot
        .derive(&board, RuntimeConfig::example(kind).reference)
        .runtime
}

pub fn device_config() -> DeviceConfig {
    DeviceConfig::of_robot(
        &robot_file::Robot::paper(),
        "mock",
        wmr_protocol::CAP_TRAJECTORY | wmr_protocol::CAP_VELOCITY,
        Some(robot_app::DEFAULT_BUTTON_REFERENCE),
    )
}

fn leak<T>(x: T) -> &'static mut T {
    Box::leak(Box::new(x))
}

impl Rig {
    /// Resets the mock clock to 0, starts an executor thread with the
    /// control task (and the hog task, idle), and waits until
    /// the control task has started.
    pub fn start() -> Self {
        Self::start_with(runtime_config(), AppConfig::DEFAULT)
    }

    pub fn start_with(cfg: RuntimeConfig, app: AppConfig) -> Self {
        let serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
        MockDriver::get().reset();
        let shared: &'static Shared = leak(Shared {
            obs: Mutex::new(Obs::default()),
            knobs: Knobs {
                button: AtomicBool::new(false),
                tick_cost_us: AtomicU32::new(0),
                hog_hold: AtomicBool::new(false),
                hog_active: AtomicBool::new(false),
                hog_go: Signal::new(),
            },
        });
        let pipes: &'static LinkPipes = leak(LinkPipes::new());
        let dev = leak(
            Device::<H>::with_estimator(
                device_config(),
                cfg,
                controller_core::estimator::EstimatorConfig::EXAMPLE,
            )
            .expect("device"),
        );
        let task = ControlTask::new(
            LoopTimer::from_config(&cfg).expect("timer"),
            ArmingButton::new(DEBOUNCE_TICKS).expect("button"),
            app,
        )
        .expect("task");
        let board = leak(mock_board(shared, &cfg));
        std::thread::spawn(move || {
            let ex: &'static mut Executor = leak(Executor::new());
            ex.run(move |sp: Spawner| {
                sp.spawn(control(board, dev, pipes, task).expect("pool"));
                sp.spawn(hog(shared).expect("pool"));
            })
        });
        let rig = Self {
            _serial: serial,
            shared,
            pipes,
            decoder: FrameDecoder::new(),
            seq: 0,
            replies: Vec::new(),
        };
        rig.wait_until("the control task starts", |o| {
            o.events.iter().any(|e| e == "Started")
        });
        rig
    }

    pub fn obs(&self) -> MutexGuard<'_, Obs> {
        self.shared.obs.lock().unwrap()
    }

    pub fn knobs(&self) -> &Knobs {
        &self.shared.knobs
    }

    /// Mock time now \[µs\].
    pub fn now_us(&self) -> u64 {
        Instant::now().as_micros()
    }

    /// Ticks due by now: the ticker fires at 1, 2, 3, ... ms.
    pub fn due_ticks(&self) -> usize {
        (self.now_us() / PERIOD_US) as usize
    }

    pub fn ticks(&self) -> usize {
        self.obs().tick_times_us.len()
    }

    /// Waits (real time, at most 20 s) until `pred` holds.
    pub fn wait_until(&self, what: &str, pred: impl Fn(&Obs) -> bool) {
        let t0 = StdInstant::now();
        loop {
            if pred(&self.obs()) {
                return;
            }
            assert!(
                t0.elapsed() < StdDuration::from_secs(20),
                "timed out waiting until {what}; ticks {}, last events {:?}",
                self.ticks(),
                self.obs().events.iter().rev().take(5).collect::<Vec<_>>()
            );
            std::thread::sleep(StdDuration::from_micros(100));
        }
    }

    /// Advances the mock clock by `ms` periods, one at a time, waiting
    /// after each until the control task has run every tick due.
    pub fn run_ms(&mut self, ms: u32) {
        for _ in 0..ms {
            MockDriver::get().advance(Duration::from_micros(PERIOD_US));
            let due = self.due_ticks();
            // A tick has completed when it fed the watchdog (its last act).
            self.wait_until("the due ticks ran", |o| o.feeds as usize >= due);
        }
    }

    /// Sends a lone frame delimiter: the protocol's resynchronisation after
    /// garbage (it ends any partial frame the device is holding).
    pub fn resync(&mut self) {
        assert_eq!(self.pipes.port_received(&[0]), 1);
    }

    /// Sends a request (as the port task would hand received bytes over).
    pub fn send(&mut self, req: &Request) -> u16 {
        self.seq = self.seq.wrapping_add(1);
        let mut buf = [0u8; MAX_FRAME];
        let frame = wmr_protocol::encode(req, self.seq, &mut buf).expect("encode");
        let kept = self.pipes.port_received(frame);
        assert_eq!(kept, frame.len(), "receive pipe full");
        self.seq
    }

    /// Reads what the robot sent (as the port task would) and decodes it.
    pub fn read_replies(&mut self) {
        let mut buf = [0u8; 256];
        loop {
            let n = self.pipes.port_try_tx(&mut buf);
            if n == 0 {
                break;
            }
            let replies = &mut self.replies;
            self.decoder.feed_all::<Reply>(&buf[..n], |d| {
                if let Decoded::Frame { msg, .. } = d {
                    replies.push(msg);
                }
            });
        }
    }

    /// Sends `req`, runs until its answer arrives (at most 50 ms), returns it.
    pub fn request(&mut self, req: &Request) -> Reply {
        let seq = self.send(req);
        for _ in 0..50 {
            self.run_ms(1);
            self.read_replies();
            if let Some(i) = self.replies.iter().position(|r| r.seq() == Some(seq)) {
                return self.replies.remove(i);
            }
        }
        panic!("no answer to {req:?}");
    }

    /// The device's status over the link.
    pub fn status(&mut self) -> wmr_protocol::StatusMsg {
        match self.request(&Request::GetStatus) {
            Reply::Status { status, .. } => status,
            r => panic!("expected a status, got {r:?}"),
        }
    }

    /// Holds the button for `ticks` ticks, then releases it for one tick.
    pub fn press_button(&mut self, ticks: u32) {
        self.knobs().button.store(true, Ordering::SeqCst);
        self.run_ms(ticks);
        self.knobs().button.store(false, Ordering::SeqCst);
        self.run_ms(1);
    }

    /// The last run state announced (hold at boot).
    pub fn state(&self) -> RunStateMsg {
        self.obs()
            .states
            .last()
            .map(|&(_, s)| s)
            .unwrap_or(RunStateMsg::Hold)
    }
}
