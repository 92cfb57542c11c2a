//! Progress of long runs on stderr: a bar on a terminal (indicatif), and
//! otherwise (a log file, a batch job) one line every
//! [`line_period`] with the count, the elapsed time and the time left, so a
//! sweep that runs for hours is never silent (issue 21 item 7).
//!
//! When the lines are due is decided against a [`Clock`]: the wall clock in
//! the tools, a clock the test drives in the tests (issue 30: no test may
//! depend on how fast the machine is). A period of zero
//! (`HIL_SIM_PROGRESS_EVERY_S=0`) makes the lines count-driven instead: one
//! per item, and one at the start of a computation without items, so a
//! script (or a test) sees them however fast the work finishes.

use std::io::IsTerminal;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// Period of the progress lines when stderr is not a terminal.
pub const LINE_PERIOD: Duration = Duration::from_secs(10);

/// Environment variable that replaces [`LINE_PERIOD`] [s] (tests, logs);
/// `0` prints a line for every item (and one at the start of a
/// computation without items).
pub const LINE_PERIOD_ENV: &str = "HIL_SIM_PROGRESS_EVERY_S";

/// The period of progress lines: [`LINE_PERIOD_ENV`] when it holds a
/// number of seconds in [0, 1e6), else [`LINE_PERIOD`].
pub fn line_period() -> Duration {
    std::env::var(LINE_PERIOD_ENV)
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s >= 0.0 && *s < 1e6)
        .map_or(LINE_PERIOD, Duration::from_secs_f64)
}

/// The time the progress lines are due against: time since an arbitrary
/// origin, never decreasing.
pub trait Clock: Send + Sync {
    /// Time since the clock's origin.
    fn now(&self) -> Duration;
}

/// The wall clock (monotonic), origin at its creation.
pub struct WallClock(Instant);

impl WallClock {
    /// A wall clock starting now.
    pub fn new() -> Self {
        Self(Instant::now())
    }
}

impl Default for WallClock {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for WallClock {
    fn now(&self) -> Duration {
        self.0.elapsed()
    }
}

/// Where the lines go: stderr in the tools, a buffer in the tests.
pub type LineSink = Box<dyn Fn(&str) + Send + Sync>;

/// Progress of `total` items (simulations), or of one long computation
/// with `total == 0` (elapsed time only).
pub struct Progress {
    what: String,
    total: u64,
    bar: Option<indicatif::ProgressBar>,
    done: AtomicU64,
    clock: Arc<dyn Clock>,
    t0: Duration,
    period: Duration,
    /// Clock time of the last line (or of the start).
    last_line: Mutex<Duration>,
    sink: LineSink,
    quiet: bool,
}

impl Progress {
    /// Progress of `total` items named `what` (e.g. "simulations"); nothing
    /// at all with `quiet`. A bar when stderr is a terminal, else lines on
    /// stderr every [`line_period`] of wall time.
    pub fn new(what: &str, total: u64, quiet: bool) -> Self {
        let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
            let pb = indicatif::ProgressBar::with_draw_target(
                (total > 0).then_some(total),
                indicatif::ProgressDrawTarget::stderr(),
            );
            let template = if total > 0 {
                format!("{{elapsed_precise}} [{{bar:40}}] {{pos}}/{{len}} {what}, eta {{eta}}")
            } else {
                format!("{{elapsed_precise}} {{spinner}} {what}")
            };
            if let Ok(style) = indicatif::ProgressStyle::with_template(&template) {
                pb.set_style(style.progress_chars("=> "));
            }
            if total == 0 {
                pb.enable_steady_tick(Duration::from_millis(200));
            }
            pb
        });
        let mut p = Self::with_clock(
            what,
            total,
            quiet,
            line_period(),
            Arc::new(WallClock::new()),
            Box::new(|l: &str| eprintln!("{l}")),
        );
        p.bar = bar;
        p
    }

    /// Progress printed as lines (never a bar) to `sink`, due every
    /// `period` of `clock`'s time (every item when `period` is zero).
    pub fn with_clock(
        what: &str,
        total: u64,
        quiet: bool,
        period: Duration,
        clock: Arc<dyn Clock>,
        sink: LineSink,
    ) -> Self {
        let t0 = clock.now();
        Self {
            what: what.into(),
            total,
            bar: None,
            done: AtomicU64::new(0),
            clock,
            t0,
            period,
            last_line: Mutex::new(t0),
            sink,
            quiet,
        }
    }

    /// One more item done (any thread).
    pub fn inc(&self) {
        let done = self.done.fetch_add(1, Ordering::Relaxed) + 1;
        match &self.bar {
            Some(b) => b.inc(1),
            None => self.maybe_line(done),
        }
    }

    /// Prints a line when one is due (no bar): call it from a waiting thread
    /// for a computation without items.
    pub fn tick(&self) {
        if self.bar.is_none() {
            self.maybe_line(self.done.load(Ordering::Relaxed));
        }
    }

    fn maybe_line(&self, done: u64) {
        if self.quiet {
            return;
        }
        // Count-driven lines (period zero) never skip one; timed lines
        // skip when another thread is printing the due one.
        let last = if self.period.is_zero() {
            self.last_line.lock().ok()
        } else {
            self.last_line.try_lock().ok()
        };
        let Some(mut last) = last else {
            return;
        };
        let now = self.clock.now();
        if now.saturating_sub(*last) < self.period {
            return;
        }
        *last = now;
        self.line(done, now);
    }

    fn line(&self, done: u64, now: Duration) {
        let el = now.saturating_sub(self.t0).as_secs_f64();
        let text = if self.total == 0 {
            format!("progress: {}, {el:.0} s elapsed", self.what)
        } else {
            let left = if done > 0 {
                format!(
                    ", about {:.0} s left",
                    el / done as f64 * (self.total - done.min(self.total)) as f64
                )
            } else {
                String::new()
            };
            format!(
                "progress: {done}/{} {} ({:.1} %), {el:.0} s elapsed{left}",
                self.total,
                self.what,
                100.0 * done as f64 / self.total.max(1) as f64
            )
        };
        (self.sink)(&text);
    }

    /// Prints `line` on stderr above the bar (or as is without one);
    /// nothing when quiet.
    pub fn println(&self, line: &str) {
        if self.quiet {
            return;
        }
        match &self.bar {
            Some(b) => b.println(line),
            None => (self.sink)(line),
        }
    }

    /// Removes the bar (no effect on lines).
    pub fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }

    /// Runs `f` while a second thread prints lines (or spins the bar) until
    /// it returns: progress of one long computation. The helper thread
    /// wakes for each due line and as soon as `f` returns (no polling), so
    /// a short computation takes no longer with progress than without.
    pub fn during<T: Send>(what: &str, quiet: bool, f: impl FnOnce() -> T + Send) -> T {
        Progress::new(what, 0, quiet).run_during(f)
    }

    /// [`Progress::during`] with this progress (its clock, period and sink).
    /// With a period of zero, one line at the start and none after.
    pub fn run_during<T: Send>(self, f: impl FnOnce() -> T + Send) -> T {
        let p = &self;
        if p.period.is_zero() {
            p.tick();
        }
        let done = (Mutex::new(false), Condvar::new());
        let out = std::thread::scope(|s| {
            s.spawn(|| {
                let (lock, cv) = &done;
                let Ok(mut finished) = lock.lock() else {
                    return;
                };
                while !*finished {
                    if p.period.is_zero() || p.bar.is_some() {
                        // Nothing timed to print: wait for the end alone.
                        finished = match cv.wait(finished) {
                            Ok(g) => g,
                            Err(_) => return,
                        };
                        continue;
                    }
                    finished = match cv.wait_timeout(finished, p.period) {
                        Ok((g, _)) => g,
                        Err(_) => return,
                    };
                    if !*finished {
                        p.tick();
                    }
                }
            });
            let out = f();
            let (lock, cv) = &done;
            if let Ok(mut finished) = lock.lock() {
                *finished = true;
            }
            cv.notify_all();
            out
        });
        p.finish();
        out
    }
}

#[cfg(test)]
mod tests {
    //! The lines against a clock the test drives: what is printed depends
    //! on the clock's time and the counts, never on the machine's speed.
    use super::*;

    /// A clock that moves only when the test sets it.
    #[derive(Default)]
    struct TestClock(AtomicU64);

    impl TestClock {
        fn set_ms(&self, ms: u64) {
            self.0.store(ms, Ordering::SeqCst);
        }
    }

    impl Clock for TestClock {
        fn now(&self) -> Duration {
            Duration::from_millis(self.0.load(Ordering::SeqCst))
        }
    }

    fn progress(total: u64, period_ms: u64) -> (Progress, Arc<TestClock>, Arc<Mutex<Vec<String>>>) {
        let clock = Arc::new(TestClock::default());
        let lines = Arc::new(Mutex::new(Vec::new()));
        let sink = lines.clone();
        let p = Progress::with_clock(
            "simulations",
            total,
            false,
            Duration::from_millis(period_ms),
            clock.clone(),
            Box::new(move |l: &str| sink.lock().unwrap().push(l.to_string())),
        );
        (p, clock, lines)
    }

    #[test]
    fn a_line_when_a_period_has_passed_and_none_before() {
        let (p, clock, lines) = progress(10, 10_000);
        clock.set_ms(9_999);
        p.inc();
        assert!(lines.lock().unwrap().is_empty(), "a line before the period");
        clock.set_ms(10_000);
        p.inc();
        clock.set_ms(15_000);
        p.inc();
        clock.set_ms(20_000);
        p.inc();
        let l = lines.lock().unwrap().clone();
        // 2 of 10 at 10 s: 5 s per item, 8 items left = 40 s left.
        assert_eq!(
            l,
            [
                "progress: 2/10 simulations (20.0 %), 10 s elapsed, about 40 s left",
                "progress: 4/10 simulations (40.0 %), 20 s elapsed, about 30 s left",
            ]
        );
    }

    #[test]
    fn a_zero_period_prints_a_line_for_every_item_whatever_the_clock() {
        let (p, _clock, lines) = progress(3, 0);
        for _ in 0..3 {
            p.inc();
        }
        let l = lines.lock().unwrap().clone();
        assert_eq!(l.len(), 3, "{l:?}");
        assert!(l[2].starts_with("progress: 3/3 simulations (100.0 %), 0 s elapsed"));
    }

    #[test]
    fn quiet_prints_nothing() {
        let clock = Arc::new(TestClock::default());
        let lines = Arc::new(Mutex::new(Vec::<String>::new()));
        let sink = lines.clone();
        let p = Progress::with_clock(
            "x",
            2,
            true,
            Duration::ZERO,
            clock,
            Box::new(move |l: &str| sink.lock().unwrap().push(l.to_string())),
        );
        p.inc();
        p.println("hello");
        assert!(lines.lock().unwrap().is_empty());
    }

    #[test]
    fn during_prints_each_due_line_and_returns_as_soon_as_the_work_ends() {
        // The work moves the test clock past three periods and waits (on
        // events, not on time) until the helper thread has printed each
        // line; then it returns, and run_during must return with it. The
        // helper waits on the wall clock for at most one period (here
        // 1 ms) before it looks at the test clock again.
        let clock = Arc::new(TestClock::default());
        let lines = Arc::new(Mutex::new(Vec::<String>::new()));
        let sink = lines.clone();
        let p = Progress::with_clock(
            "work",
            0,
            false,
            Duration::from_millis(1),
            clock.clone(),
            Box::new(move |l: &str| sink.lock().unwrap().push(l.to_string())),
        );
        let out = p.run_during(|| {
            for k in 1..=3u64 {
                clock.set_ms(k);
                while lines.lock().unwrap().len() < k as usize {
                    std::thread::yield_now();
                }
            }
            42
        });
        assert_eq!(out, 42);
        let l = lines.lock().unwrap().clone();
        assert_eq!(l.len(), 3, "{l:?}");
        assert!(
            l.iter().all(|x| x == "progress: work, 0 s elapsed"),
            "{l:?}"
        );
    }

    #[test]
    fn during_with_a_zero_period_prints_one_line_at_the_start() {
        let (p, _clock, lines) = progress(0, 0);
        let seen_at_start = p.run_during(|| lines.lock().unwrap().len());
        assert_eq!(seen_at_start, 1, "the line comes before the work");
        assert_eq!(lines.lock().unwrap().len(), 1);
    }
}
