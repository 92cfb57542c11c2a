//! Closed-loop runner: a [`ControlSide`] against the simulated world
//! ([`sim_robot::World`]).
//!
//! Per control period k (t = k·Δt): the world's reading at t (the truth and,
//! with ideal sensing, the exact measurements; the encoders, gyro and pose
//! source latch theirs), one step of the controller side (which samples the
//! reference once and returns it for the metrics), then the world over the
//! period with the actuation held (zero-order hold of torque or of PWM
//! duty) in `substeps` RK4 steps. The scenario's [`Sensing`] chooses the
//! controller side: the bare `Controller` with ideal measurements
//! ([`IdealSide`]) or the firmware runtime ([`crate::hil::RuntimeSide`]).

use crate::control_side::{ControlOutput, ControlSide};
use crate::metrics::{Metrics, MetricsAcc};
use crate::scenario::{Scenario, Sensing};
use controller_core::health::{EstimatorHealth, HealthMode};
use controller_core::pacer::{PacerState, PacingConfig};
use controller_core::trajectory::{Reference, Trajectory};
use controller_core::{Controller, ControllerConfig, ControllerKind, StepInput};
use sim_robot::world::{Actuation, Reading};
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
    /// Firmware sensing: the estimator's status and the pose source's
    /// counters at the end (None with ideal sensing).
    pub sensing: Option<crate::hil::SensingReport>,
}

/// Controller configuration for a scenario: Table 2 gains plus the scenario's
/// torque limit, period and optional k_y override.
pub fn controller_config(scn: &Scenario, kind: ControllerKind) -> ControllerConfig {
    let mut cfg = ControllerConfig::paper(kind);
    cfg.torque_limit_nm = scn.torque_limit_nm as f32;
    cfg.period_s = scn.control_period_s as f32;
    if let Some(k_y) = scn.k_y {
        cfg.kinematic.k_y = k_y as f32;
    }
    if scn.clean_start {
        cfg.kinematic.large_error_m = controller_core::kinematic::DEFAULT_LARGE_ERROR_M;
    }
    cfg
}

/// The bare controller with ideal measurements ([`Sensing::Ideal`], the
/// paper's setting): the world's exact measurements (the pose of G, the
/// wheel rates from the exact wheel-angle change over the last period; see
/// [`sim_robot::world::IdealSensing`]) into η through eq. (3)
/// ([`controller_core::RobotParams::eta_from_wheel_rates`]), torque applied
/// exactly.
///
/// With pacing on, the reference governor and the health machine
/// ([`controller_core::pacer`]) choose the reference time τ and the
/// controller tracks `reference` at τ; a safe stop outputs zero torque
/// from then on.
pub struct IdealSide {
    ctrl: Controller,
    pacer: controller_core::pacer::Pacer,
    pace: PacerState,
    reference: Reference,
    /// Steps without an ideal reading (a world with hardware sensing).
    missing_readings: u32,
}

impl IdealSide {
    /// The controller of `cfg`, paced by `pacing` along `reference`.
    pub fn new(
        cfg: ControllerConfig,
        pacing: PacingConfig,
        reference: Reference,
    ) -> Result<Self, String> {
        let pacer = controller_core::pacer::Pacer::new(pacing, &cfg)
            .map_err(|e| format!("pacing config: {e}"))?;
        Ok(Self {
            ctrl: Controller::new(cfg).map_err(|e| format!("controller config: {e}"))?,
            pace: pacer.initial_state(),
            pacer,
            reference,
            missing_readings: 0,
        })
    }
}

impl ControlSide for IdealSide {
    fn kind(&self) -> ControllerKind {
        self.ctrl.config().kind
    }

    fn step(&mut self, _step: usize, reading: &Reading, _world: &mut World) -> ControlOutput {
        let ideal = reading.ideal.unwrap_or_else(|| {
            // Not an ideal world: nothing to measure with; the torque below
            // is zeroed and the step counted as rejected.
            self.missing_readings += 1;
            sim_robot::world::IdealReading {
                pose: controller_core::Pose::default(),
                wheel_rate_radps: [0.0; 2],
            }
        });
        let eta = self
            .ctrl
            .config()
            .robot
            .eta_from_wheel_rates(ideal.wheel_rate_radps);
        let reference = if self.pacer.enabled() {
            self.pacer.reference(&self.pace, &self.reference, 0.0)
        } else {
            self.reference.sample(reading.t_s as f32)
        };
        let out = self.ctrl.step(&StepInput {
            reference,
            pose: ideal.pose,
            eta,
        });
        let pace = self
            .pacer
            .update(&mut self.pace, &out.diag, eta, EstimatorHealth::Ok);
        let torque = if pace.mode == HealthMode::SafeStop || reading.ideal.is_none() {
            [0.0; 2]
        } else {
            out.torque_nm.map(f64::from)
        };
        ControlOutput {
            actuation: Actuation::Torque(torque),
            eta_measured: [eta.v_mps as f64, eta.omega_radps as f64],
            diag: out.diag,
            reference,
            pace,
        }
    }

    fn rejected_steps(&self) -> u32 {
        self.ctrl.rejected_steps() + self.missing_readings
    }
}

/// Runs `scn` with the given controller configuration, on the controller
/// side its [`Sensing`] names; logs every `trace_every`-th step (0 = no trace).
pub fn run_with(
    scn: &Scenario,
    cfg: ControllerConfig,
    trace_every: usize,
) -> Result<SimOutput, String> {
    scn.validate()?;
    match scn.sensing {
        Sensing::Ideal => {
            let side = IdealSide::new(cfg, scn.pacing(), scn.trajectory.reference())?;
            let mut world = crate::world::ideal_world(scn, &cfg)?;
            run_loop(scn, &mut world, side, trace_every)
        }
        Sensing::Odometry | Sensing::Imu | Sensing::Mocap | Sensing::Uwb => {
            let opts = crate::hil::HilOptions::default();
            crate::hil::run_runtime(scn, cfg, opts, trace_every).map(|o| o.sim)
        }
    }
}

/// The closed loop: `world`, `side`, the world over each period; metrics
/// at every step, a trace every `trace_every` steps (0 = none).
pub fn run_loop(
    scn: &Scenario,
    world: &mut World,
    mut side: impl ControlSide,
    trace_every: usize,
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
            t < scn.window_s[0] || scn.window_s[0] >= scn.window_s[1],
            tau,
            d.saturated,
            fe,
        );
        if scn.governor {
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
                time_scale: if scn.governor { scale_before } else { 1.0 },
                tau_s: if scn.governor { rs_tau_s } else { t },
                health: pace.mode.level(),
                health_reason: pace.reason as u8,
            });
        }
        last_tau_s = pace.tau_s as f64;
        last_scale = pace.scale as f64;
        // The world over [t, t + dt], actuation held (zero-order hold).
        world.advance(actuation, dt).map_err(|e| e.to_string())?;
    }
    Ok(SimOutput {
        kind,
        trace,
        metrics: acc.finish(scn.duration_s, dt),
        rejected_steps: side.rejected_steps(),
        sensing: None,
    })
}

/// Runs `scn` with `kind` at the paper's gains; trace every [`TRACE_PERIOD_S`].
pub fn run(scn: &Scenario, kind: ControllerKind) -> Result<SimOutput, String> {
    run_with(scn, controller_config(scn, kind), trace_every(scn))
}
