//! The closed loop, the bottom layer of the simulator: a [`ControlSide`]
//! against the scenario's simulated world ([`sim_robot::World`], built in
//! [`world`]).
//!
//! Per control period k (t = k·Δt): the world's reading at t (the truth and,
//! with ideal sensing, the exact measurements; the encoders, gyro and pose
//! source latch theirs), one step of the controller side (which samples the
//! reference once and returns it for the metrics), then the world over the
//! period with the actuation held (zero-order hold of torque or of PWM
//! duty) in `substeps` RK4 steps. The controller sides live one layer up
//! ([`crate::sides`]); which one a scenario runs is chosen above them
//! ([`crate::sim`], [`crate::hil`]).

pub mod control_side;
pub mod world;

pub use control_side::{ControlOutput, ControlSide};

use crate::metrics::{Metrics, MetricsAcc};
use crate::scenario::Scenario;
use controller_core::estimator::EstimatorStatus;
use controller_core::runtime::StopReason;
use controller_core::ControllerKind;
use sim_robot::sensors::PoseSourceStats;
use sim_robot::World;

/// Period of the logged trace \[s\] (every control step goes into the metrics).
pub const TRACE_PERIOD_S: f64 = 0.01;

/// Control steps per trace sample for `scn` (at least 1).
pub fn trace_every(scn: &Scenario) -> usize {
    ((TRACE_PERIOD_S / scn.control_period_s).round() as usize).max(1)
}

pub use track_log::TraceSample;

/// Result of one run.
#[derive(Clone, Debug)]
pub struct SimOutput {
    /// Controller kind.
    pub kind: ControllerKind,
    /// Decimated trace.
    pub trace: Vec<TraceSample>,
    /// Metrics over every control step.
    pub metrics: Metrics,
    /// Steps the controller rejected (bad input).
    pub rejected_steps: u32,
    /// The first stop the firmware runtime latched: (step, reason); None
    /// without one (and always with ideal sensing, which has no runtime).
    pub stop: Option<(usize, StopReason)>,
    /// Firmware sensing: the estimator's status and the pose source's
    /// counters at the end (None with ideal sensing).
    pub sensing: Option<SensingReport>,
}

/// What the sensing did over a run: the estimator's final status and the
/// pose source's counters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensingReport {
    /// The estimator's status at the end of the run.
    pub estimator: EstimatorStatus,
    /// The simulated pose source's counters (None without one).
    pub pose_source: Option<PoseSourceStats>,
}

/// A trace row's consumer.
type TraceHook = Box<dyn FnMut(&TraceSample)>;

thread_local! {
    /// Called with each trace row as the loop makes it (`hil-sim run
    /// --live`): set by [`with_trace_hook`] for one run on this thread.
    static TRACE_HOOK: std::cell::RefCell<Option<TraceHook>> =
        const { std::cell::RefCell::new(None) };
}

/// Runs `f` with `hook` called on every trace row the closed loop of this
/// thread makes while `f` runs, in time order, as it makes it (before the
/// world advances past it): a simulation streamed as it runs.
pub fn with_trace_hook<R>(hook: impl FnMut(&TraceSample) + 'static, f: impl FnOnce() -> R) -> R {
    TRACE_HOOK.with(|h| *h.borrow_mut() = Some(Box::new(hook)));
    let r = f();
    TRACE_HOOK.with(|h| *h.borrow_mut() = None);
    r
}

/// The closed loop: `world`, `side`, the world over each period; metrics
/// at every step, a trace every `trace_every` steps (0 = none).
pub fn run_loop(
    scn: &Scenario,
    world: &mut World,
    side: impl ControlSide,
    trace_every: usize,
) -> Result<SimOutput, String> {
    run_loop_ending(scn, world, side, trace_every, false)
}

/// [`run_loop`]; with `end_at_stop` the run ends at the step the control
/// side latched its first stop (a tuning evaluation scores a stopped run
/// by the stop alone: the rest of it would be simulated for nothing; the
/// metrics then cover the steps run).
pub fn run_loop_ending(
    scn: &Scenario,
    world: &mut World,
    mut side: impl ControlSide,
    trace_every: usize,
    end_at_stop: bool,
) -> Result<SimOutput, String> {
    scn.validate()?;
    let perturbations = scn.perturbations();
    let dt = scn.control_period_s;
    let n = (scn.duration_s / dt).round() as usize;
    let kind = side.kind();
    let mut acc = MetricsAcc::new(kind == ControllerKind::Proposed);
    let mut trace = Vec::with_capacity(n.checked_div(trace_every).map_or(0, |q| q + 1));
    let (mut last_tau_s, mut last_scale) = (0.0f64, 1.0f64);

    for k in 0..n {
        let t = k as f64 * dt;
        let reading = world.sense(t);
        let p_now = reading.perturbation;
        // The governed clock the step used (before its own update).
        let (rs_tau_s, scale_before) = (last_tau_s, last_scale);
        let ControlOutput {
            actuation,
            eta_measured,
            diag: d,
            reference: rs,
            pace,
            pose_used,
        } = side.step(k, &reading, world);
        let tau = world.torque_nm(&actuation, reading.wheel_rate_radps);

        let st = *world.state();
        let eta_true = world.plant().eta(&st, &p_now);
        let f_true = [p_now.fault_eps * eta_true[0], p_now.fault_eps * eta_true[1]];
        let ex = rs.pose.x_m as f64 - st.q[0];
        let ey = rs.pose.y_m as f64 - st.q[1];
        let norm = |a: f64, b: f64| (a * a + b * b).sqrt(); // no overflow at these sizes
        let pos_err = norm(ex, ey);
        let fe = norm(d.f_hat[0] as f64 - f_true[0], d.f_hat[1] as f64 - f_true[1]);
        acc.push(
            t,
            pos_err,
            perturbations.in_window(t),
            t < scn.perturbations.window_s[0]
                || scn.perturbations.window_s[0] >= scn.perturbations.window_s[1],
            tau,
            d.saturated,
            fe,
        );
        acc.push_estimate(
            perturbations.in_window(t),
            norm(
                pose_used.x_m as f64 - st.q[0],
                pose_used.y_m as f64 - st.q[1],
            ),
        );
        if scn.governor_on() {
            acc.push_pace(
                t - rs_tau_s,
                pace.scale as f64,
                pace.mode as u8,
                pace.transitions,
            );
        }
        if trace_every > 0 && k % trace_every == 0 {
            let f2 = |a: [f32; 2]| [a[0] as f64, a[1] as f64];
            trace.push(TraceSample {
                t_s: t,
                ref_pose: [
                    rs.pose.x_m as f64,
                    rs.pose.y_m as f64,
                    rs.pose.theta_rad as f64,
                ],
                pose: [st.q[0], st.q[1], st.q[2]],
                pos_err_m: pos_err,
                err_xy_m: [ex, ey],
                e: [d.error[0] as f64, d.error[1] as f64, d.error[2] as f64],
                eta: eta_measured,
                eta_c: f2(d.eta_c),
                torque_nm: tau,
                s: f2(d.s),
                rho_hat: f2(d.rho_hat),
                d_hat: f2(d.d_hat),
                f_hat: f2(d.f_hat),
                f_true,
                saturated: d.saturated,
                time_scale: if scn.governor_on() { scale_before } else { 1.0 },
                tau_s: if scn.governor_on() { rs_tau_s } else { t },
                health: pace.mode.level(),
                health_reason: pace.reason as u8,
            });
            if let Some(row) = trace.last() {
                TRACE_HOOK.with(|h| {
                    if let Some(hook) = h.borrow_mut().as_mut() {
                        hook(row)
                    }
                });
            }
        }
        last_tau_s = pace.tau_s as f64;
        last_scale = pace.scale as f64;
        if end_at_stop && side.stop().is_some() {
            break;
        }
        // The world over [t, t + dt], actuation held (zero-order hold).
        world.advance(actuation, dt).map_err(|e| e.to_string())?;
    }
    Ok(SimOutput {
        kind,
        trace,
        metrics: acc.finish(scn.duration_s, dt),
        rejected_steps: side.rejected_steps(),
        stop: side.stop(),
        sensing: None,
    })
}
