//! Progress of long runs on stderr: a bar on a terminal (indicatif), and
//! otherwise (a log file, a batch job) one line every
//! [`line_period`] with the count, the elapsed time and the time left, so a
//! sweep that runs for hours is never silent (issue 21 item 7).

use std::io::IsTerminal;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Period of the progress lines when stderr is not a terminal.
pub const LINE_PERIOD: Duration = Duration::from_secs(10);

/// Environment variable that replaces [`LINE_PERIOD`] [s] (tests, logs).
pub const LINE_PERIOD_ENV: &str = "HIL_SIM_PROGRESS_EVERY_S";

/// The period of progress lines: [`LINE_PERIOD_ENV`] when it holds a
/// positive number of seconds, else [`LINE_PERIOD`].
pub fn line_period() -> Duration {
    std::env::var(LINE_PERIOD_ENV)
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s > 0.0 && *s < 1e6)
        .map_or(LINE_PERIOD, Duration::from_secs_f64)
}

/// Progress of `total` items (simulations), or of one long computation
/// with `total == 0` (elapsed time only).
pub struct Progress {
    what: String,
    total: u64,
    bar: Option<indicatif::ProgressBar>,
    done: AtomicU64,
    t0: Instant,
    period: Duration,
    last_line: Mutex<Instant>,
    quiet: bool,
}

impl Progress {
    /// Progress of `total` items named `what` (e.g. "simulations"); nothing
    /// at all with `quiet`.
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
        let now = Instant::now();
        Self {
            what: what.into(),
            total,
            bar,
            done: AtomicU64::new(0),
            t0: now,
            period: line_period(),
            last_line: Mutex::new(now),
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
        let Ok(mut last) = self.last_line.try_lock() else {
            return;
        };
        if last.elapsed() < self.period {
            return;
        }
        *last = Instant::now();
        let el = self.t0.elapsed().as_secs_f64();
        if self.total == 0 {
            eprintln!("progress: {}, {el:.0} s elapsed", self.what);
        } else {
            let left = if done > 0 {
                format!(
                    ", about {:.0} s left",
                    el / done as f64 * (self.total - done.min(self.total)) as f64
                )
            } else {
                String::new()
            };
            eprintln!(
                "progress: {done}/{} {} ({:.1} %), {el:.0} s elapsed{left}",
                self.total,
                self.what,
                100.0 * done as f64 / self.total.max(1) as f64
            );
        }
    }

    /// Prints `line` on stderr above the bar (or as is without one);
    /// nothing when quiet.
    pub fn println(&self, line: &str) {
        if self.quiet {
            return;
        }
        match &self.bar {
            Some(b) => b.println(line),
            None => eprintln!("{line}"),
        }
    }

    /// Removes the bar (no effect on lines).
    pub fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }

    /// Runs `f` while a second thread prints lines (or spins the bar) until
    /// it returns: progress of one long computation.
    pub fn during<T: Send>(what: &str, quiet: bool, f: impl FnOnce() -> T + Send) -> T {
        let p = Progress::new(what, 0, quiet);
        let done = std::sync::atomic::AtomicBool::new(false);
        let out = std::thread::scope(|s| {
            s.spawn(|| {
                while !done.load(Ordering::Relaxed) {
                    std::thread::sleep(Duration::from_millis(50).min(p.period));
                    p.tick();
                }
            });
            let out = f();
            done.store(true, Ordering::Relaxed);
            out
        });
        p.finish();
        out
    }
}
