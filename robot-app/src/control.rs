//! The control task: one [`Device::tick`] per period on an embassy
//! [`Ticker`], the host link's bytes around it, the watchdog and the button.

use controller_core::runtime::{ArmingButton, CycleStats, LoopTimer};
use embassy_time::{Duration, Instant, Ticker};
use wmr_device::Device;
use wmr_protocol::RunStateMsg;

use crate::board::{AppEvent, Board, StatusSummary};
use crate::link::LinkPipes;
use crate::store::RecordWriter;

/// Longest wait for the acknowledgement of a `Reboot` to leave before
/// the board restarts anyway \[ticks\].
pub const REBOOT_DRAIN_TICKS: u32 = 50;

/// How often the control task reports to the board's log.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AppConfig {
    /// Ticks between two [`AppEvent::Status`] (0: never).
    pub status_every_ticks: u32,
    /// Ticks between two [`AppEvent::Telemetry`] (0: never; the host link
    /// carries the telemetry, `wmr record`).
    pub telemetry_every_ticks: u32,
}

impl AppConfig {
    /// A status every second at 1 kHz, no local telemetry.
    pub const DEFAULT: Self = Self {
        status_every_ticks: 1000,
        telemetry_every_ticks: 0,
    };
}

impl Default for AppConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// A rejected [`ControlTask`] configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum AppConfigError {
    /// The loop period does not fit embassy's timer (0 or over 1 s).
    InvalidPeriod,
}

/// The control task's own state: the loop's schedule, the button's
/// debounce, the execution-time statistics.
pub struct ControlTask {
    timer: LoopTimer,
    button: ArmingButton,
    cfg: AppConfig,
    state: RunStateMsg,
    /// Completed ticks (each fed the watchdog once).
    ticks: u32,
    cycles: CycleStats,
    link_max: u32,
    link_ticks: u32,
    /// Ticks left to drain the link before an acknowledged `Reboot`.
    reboot_in: Option<u32>,
}

impl ControlTask {
    /// The task for a loop timed by `timer` (its period is the ticker's),
    /// sampling `button` once per tick.
    pub fn new(
        timer: LoopTimer,
        button: ArmingButton,
        cfg: AppConfig,
    ) -> Result<Self, AppConfigError> {
        if timer.period_us() == 0 || timer.period_us() > 1_000_000 {
            return Err(AppConfigError::InvalidPeriod);
        }
        Ok(Self {
            timer,
            button,
            cfg,
            state: RunStateMsg::Hold,
            ticks: 0,
            cycles: CycleStats::new(),
            link_max: 0,
            link_ticks: 0,
            reboot_in: None,
        })
    }

    /// The loop's schedule statistics.
    pub fn timer(&self) -> &LoopTimer {
        &self.timer
    }

    /// Watchdog feeds so far (one per completed tick).
    pub fn watchdog_feeds(&self) -> u32 {
        self.ticks
    }

    /// Runs forever: starts the watchdog, then one [`tick`](Self::tick) per
    /// period. Late ticks (the executor was busy, a debugger halted the
    /// core) arrive back to back; the [`LoopTimer`] measures each against
    /// the schedule t₀ + n·period and gives the runtime the true elapsed
    /// time, and a sustained overrun latches a safe stop.
    pub async fn run<B: Board, const H: usize>(
        self,
        board: &mut B,
        dev: &mut Device<H>,
        pipes: &LinkPipes,
    ) -> ! {
        self.run_with_store(board, dev, pipes, &mut crate::store::NoStore)
            .await
    }

    /// [`Self::run`] with a robot store: after a tick that accepted a
    /// `RobotCommit` (the device in hold, motors off), the record is
    /// written here, between two ticks ([`Self::write_robot`]); after an
    /// acknowledged `Reboot` the board restarts once the link's send pipe
    /// has drained (at most [`REBOOT_DRAIN_TICKS`]).
    pub async fn run_with_store<B: Board, const H: usize, S: RecordWriter>(
        mut self,
        board: &mut B,
        dev: &mut Device<H>,
        pipes: &LinkPipes,
        store: &mut S,
    ) -> ! {
        let mut ticker = Ticker::every(Duration::from_micros(self.timer.period_us() as u64));
        board.start_watchdog();
        board.event(&AppEvent::Started);
        loop {
            ticker.next().await;
            let now_us = Instant::now().as_micros() as u32;
            self.tick(now_us, board, dev, pipes);
            if dev.pending_robot_write().is_some() {
                self.write_robot(board, dev, store).await;
                // The ticker would fire the missed ticks back to back.
                ticker.reset();
            }
            if self.reboot_due(dev, pipes) {
                board.reboot();
            }
        }
    }

    /// After a tick: whether the board restarts now. After an acknowledged
    /// `Reboot`, once the acknowledgement has left (the device's and the
    /// link's send buffers empty), or [`REBOOT_DRAIN_TICKS`] after the
    /// request at the latest; false without a request.
    pub fn reboot_due<const H: usize>(&mut self, dev: &Device<H>, pipes: &LinkPipes) -> bool {
        if !dev.reboot_requested() {
            return false;
        }
        let left = self.reboot_in.get_or_insert(REBOOT_DRAIN_TICKS);
        let due = (dev.tx_len() == 0 && pipes.tx_len() == 0) || *left == 0;
        *left = left.saturating_sub(1);
        due
    }

    /// Writes the device's pending robot record (the device is in hold,
    /// motors off): the board stretches its watchdog, the store writes and
    /// reads back, the watchdog returns to the loop's timeout, the device
    /// answers the commit, and the loop's schedule restarts at the next
    /// tick ([`LoopTimer::resync`]: the pause is not an overrun). The
    /// motors stay off throughout: nothing drives them between ticks, and
    /// arming is refused while the write is pending.
    pub async fn write_robot<B: Board, const H: usize, S: RecordWriter>(
        &mut self,
        board: &mut B,
        dev: &mut Device<H>,
        store: &mut S,
    ) {
        let t0 = Instant::now();
        if let Some(ok) = self.store_robot(board, dev, store).await {
            let duration_us = Instant::now().duration_since(t0).as_micros() as u32;
            board.event(&AppEvent::RobotWritten { ok, duration_us });
        }
    }

    /// [`Self::write_robot`] without timing it or the event (a board
    /// without embassy's clock: the simulated board, whose flash takes no
    /// robot time). Returns whether the record was stored and read back
    /// equal, None when nothing was pending.
    pub async fn store_robot<B: Board, const H: usize, S: RecordWriter>(
        &mut self,
        board: &mut B,
        dev: &mut Device<H>,
        store: &mut S,
    ) -> Option<bool> {
        let mut record = [0u8; wmr_protocol::ROBOT_BLOB_MAX];
        let n = match dev.pending_robot_write() {
            Some(r) => {
                record[..r.len()].copy_from_slice(r);
                r.len()
            }
            None => return None,
        };
        board.flash_write_begins();
        let ok = store.write(&record[..n]).await;
        board.flash_write_ends();
        dev.robot_write_done(ok);
        self.timer.resync();
        Some(ok)
    }

    /// One period's work at robot time `now_us` (a wrapping µs clock):
    /// schedule check, host bytes in, the device's tick, host bytes out,
    /// watchdog feed, the button, events. Never waits, never panics.
    pub fn tick<B: Board, const H: usize>(
        &mut self,
        now_us: u32,
        board: &mut B,
        dev: &mut Device<H>,
        pipes: &LinkPipes,
    ) {
        let timing = self.timer.tick(now_us);
        // The port's own losses into the status the host reads.
        let report = dev.board_report_mut();
        report.port_rx_dropped = pipes.rx_dropped_bytes();
        report.port_rx_errors = pipes.rx_port_errors();
        let c0 = board.cycles();
        let received = pipes.receive(dev);
        let io = board.io();
        let rep = dev.tick(
            now_us,
            io.encoders,
            io.motors,
            io.gyro,
            io.pose_source,
            timing,
        );
        let sent = pipes.transmit(dev);
        let cycles = board.cycles().wrapping_sub(c0);
        self.ticks = self.ticks.wrapping_add(1);
        if B::LOGS_STATUS {
            self.cycles.record(cycles);
            if received + sent > 0 {
                self.link_ticks += 1;
                self.link_max = self.link_max.max(cycles);
            }
        }

        // Operator button: arm / disarm / clear a latched stop, without a host.
        if self.button.press(board.button_pressed()) {
            dev.button_pressed(board.motors());
        }

        if let Some(reason) = rep.stopped {
            board.event(&AppEvent::SafeStop(reason));
        }
        if let Some(transition) = rep.pace.transition {
            board.event(&AppEvent::Health {
                transition,
                transitions: rep.pace.transitions,
            });
        }
        if dev.state() != self.state {
            self.state = dev.state();
            board.event(&AppEvent::State(self.state));
        }
        if B::LOGS_STATUS && every(self.ticks, self.cfg.telemetry_every_ticks) {
            board.event(&AppEvent::Telemetry(&rep));
        }
        if B::LOGS_STATUS && every(self.ticks, self.cfg.status_every_ticks) {
            let status = self.status(pipes);
            board.event(&AppEvent::Status(status));
        }
        // The tick completed: the loop is alive.
        board.feed_watchdog();
    }

    /// The status since the last one (starts a new execution-time window).
    fn status(&mut self, pipes: &LinkPipes) -> StatusSummary {
        let t = self.timer.stats();
        let c = self.cycles.take();
        let s = StatusSummary {
            ticks: self.ticks,
            late_ticks: t.late_ticks,
            overrun_episodes: t.overrun_episodes,
            max_lateness_us: t.max_lateness_us,
            tick_cycles_mean: c.mean(),
            tick_cycles_max: c.max(),
            tick_cycles_max_link: self.link_max,
            link_ticks: self.link_ticks,
            watchdog_feeds: self.ticks,
            rx_dropped_bytes: pipes.rx_dropped_bytes(),
        };
        self.link_max = 0;
        self.link_ticks = 0;
        s
    }
}

fn every(n: u32, period: u32) -> bool {
    period != 0 && n % period == 0
}

/// The control task (see [`ControlTask::run`]): wrap it in a one-line
/// `#[embassy_executor::task]` with the board's concrete types.
pub async fn control_task<B: Board, const H: usize>(
    board: &mut B,
    dev: &mut Device<H>,
    pipes: &LinkPipes,
    task: ControlTask,
) -> ! {
    task.run(board, dev, pipes).await
}
