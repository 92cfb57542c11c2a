//! `hil-sim run --live`: the simulation streamed to Foxglove as it runs,
//! paced at real time (D157): row k is published when the wall clock
//! reaches the run's start plus its simulated time, stamped with that same
//! time (the MCAP log of the run, `--mcap`, holds the same messages at the
//! same stamps).

use crate::sim::{SimOutput, TraceSample};
use ros_mcap::live::LiveView;
use std::cell::RefCell;
use std::rc::Rc;
use std::time::{Duration, Instant};

/// A live view waiting for its run.
pub struct LiveRun {
    view: LiveView,
}

impl LiveRun {
    /// Starts the server on `at`'s address, prints it to stderr (`live
    /// view: ws://HOST:PORT`), and with `wait` waits until a client has
    /// subscribed to every topic.
    pub fn start(
        at: &ros_mcap::live::LiveArgs,
        geometry: ros_mcap::Geometry,
        wait: bool,
    ) -> Result<Self, String> {
        let view = at
            .start(geometry, "hil-sim run")
            .map_err(|e| e.to_string())?;
        eprintln!("live view: {}", at.url(view.port()));
        if wait {
            eprintln!("live view: waiting for a client to subscribe to every topic");
            while !view.subscribed_to_all() {
                std::thread::sleep(Duration::from_millis(20));
            }
        }
        Ok(Self { view })
    }

    /// Runs `sim`, publishing each trace row as the loop makes it, at
    /// Unix time `start_ns` + its t, paced at real time; the view back (it
    /// serves until dropped: the caller writes its log first, so a client
    /// that reads until the server closes finds the log complete).
    pub fn run(
        self,
        start_ns: u64,
        sim: impl FnOnce() -> Result<SimOutput, String>,
    ) -> Result<(SimOutput, LiveView), String> {
        let view = Rc::new(RefCell::new(self.view));
        let error: Rc<RefCell<Option<String>>> = Rc::default();
        let t0 = Instant::now();
        let (v, e) = (view.clone(), error.clone());
        let hook = move |row: &TraceSample| {
            let due = t0 + Duration::from_secs_f64(row.t_s.max(0.0));
            if let Some(wait) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(wait);
            }
            if let Err(err) = v.borrow_mut().publish(&ros_mcap::sim_frame(row, start_ns)) {
                e.borrow_mut().get_or_insert(err.to_string());
            }
        };
        let res = crate::closed_loop::with_trace_hook(hook, sim)?;
        if let Some(e) = error.borrow_mut().take() {
            return Err(format!("live view: {e}"));
        }
        let view = Rc::try_unwrap(view)
            .map_err(|_| "live view: still in use after the run".to_string())?
            .into_inner();
        Ok((res, view))
    }
}
