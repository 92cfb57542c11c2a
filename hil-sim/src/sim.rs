//! Closed-loop runner: controller-core's `Controller` against the [`Plant`].
//!
//! Per control period k (t = k·Δt): measure (pose of G with optional noise;
//! η from the wheel-angle change over the last period, optionally quantised
//! to encoder counts), sample the reference, one `Controller::step`, quantise
//! the torque to the PWM resolution, then integrate the plant over the period
//! with the torque held (zero-order hold) in `substeps` RK4 steps.

use crate::metrics::{Metrics, MetricsAcc};
use crate::plant::{Plant, PlantParams, PlantState};
use crate::rng::Rng;
use crate::scenario::Scenario;
use controller_core::trajectory::Trajectory;
use controller_core::{
    Controller, ControllerConfig, ControllerKind, Diagnostics, Pose, StepInput, Vel2,
};
use serde::Serialize;

/// One logged sample (decimated) for plots and CSV.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct TraceSample {
    /// Time \[s\].
    pub t_s: f64,
    /// Reference x_s, y_s, θ_s.
    pub ref_pose: [f64; 3],
    /// True pose of G.
    pub pose: [f64; 3],
    /// Position error \[m\].
    pub pos_err_m: f64,
    /// World-frame error \[x_s − x, y_s − y\] \[m\].
    pub err_xy_m: [f64; 2],
    /// Controller's tracking error \[e_x, e_y, e_θ\].
    pub e: [f64; 3],
    /// Measured η \[v, ω\].
    pub eta: [f64; 2],
    /// η_c \[v_c, ω_c\].
    pub eta_c: [f64; 2],
    /// Applied torque \[right, left\] \[N·m\].
    pub torque_nm: [f64; 2],
    /// Sliding variable s.
    pub s: [f64; 2],
    /// ρ̂ (K for SMC).
    pub rho_hat: [f64; 2],
    /// D̂ = x̂3.
    pub d_hat: [f64; 2],
    /// F̂ = \[Δv̂, Δω̂\].
    pub f_hat: [f64; 2],
    /// Injected fault F = ε·η.
    pub f_true: [f64; 2],
    /// Saturation flag.
    pub saturated: bool,
}

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
    cfg
}

/// What the controller side commands for one control period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Actuation {
    /// Wheel torques `[right, left]` \[N·m\] held over the period.
    Torque([f64; 2]),
    /// A motor model driven at fixed duty: torque depends on the wheel rate,
    /// re-evaluated at every RK4 sub-step (see [`crate::hil`]).
    Motor(crate::hil::MotorActuation),
}

impl Actuation {
    /// Wheel torques at the given wheel rates \[rad/s\] `[right, left]`.
    pub fn torque_nm(&self, wheel_rates_radps: [f64; 2]) -> [f64; 2] {
        match self {
            Self::Torque(t) => *t,
            Self::Motor(m) => m.torque_nm(wheel_rates_radps),
        }
    }
}

/// What the simulated sensors give the controller side at one step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sensed {
    /// Pose of G with measurement noise.
    pub pose: Pose,
    /// True wheel angles φ `[right, left]` \[rad\] (for encoders).
    pub wheel_angle_rad: [f64; 2],
}

/// The controller side of the loop: the bare `Controller` ([`DirectSide`]) or
/// the firmware's runtime with simulated encoders and PWM ([`crate::hil::RuntimeSide`]).
pub trait ControlSide {
    /// The controller kind (for the fault-estimate metric).
    fn kind(&self) -> ControllerKind;
    /// One control period at step `k`, time `t_s`: returns the actuation, the
    /// η the controller used, and its diagnostics.
    fn step(&mut self, k: usize, t_s: f64, sensed: &Sensed) -> (Actuation, [f64; 2], Diagnostics);
    /// Steps the controller rejected or the runtime stopped on.
    fn rejected_steps(&self) -> u32;
}

impl<C: ControlSide> ControlSide for &mut C {
    fn kind(&self) -> ControllerKind {
        (**self).kind()
    }
    fn step(&mut self, k: usize, t_s: f64, sensed: &Sensed) -> (Actuation, [f64; 2], Diagnostics) {
        (**self).step(k, t_s, sensed)
    }
    fn rejected_steps(&self) -> u32 {
        (**self).rejected_steps()
    }
}

/// The bare controller: η from the wheel-angle change over the last period
/// (optionally quantised to encoder counts), torque optionally quantised to
/// PWM levels and clipped to the drive's limit.
pub struct DirectSide<'a> {
    scn: &'a Scenario,
    ctrl: Controller,
    reference: controller_core::trajectory::Reference,
    wheel_radius_m: f64,
    half_track_m: f64,
    phi_prev: Option<[f64; 2]>,
}

impl<'a> DirectSide<'a> {
    /// Builds the controller for `scn`.
    pub fn new(scn: &'a Scenario, cfg: ControllerConfig) -> Result<Self, String> {
        Ok(Self {
            scn,
            ctrl: Controller::new(cfg).map_err(|e| format!("controller config: {e}"))?,
            reference: scn.trajectory.reference(),
            wheel_radius_m: cfg.robot.wheel_radius_m as f64,
            half_track_m: cfg.robot.half_track_m as f64,
            phi_prev: None,
        })
    }

    fn count(&self, phi: f64) -> f64 {
        let cpr = self.scn.encoder_cpr as f64;
        if cpr > 0.0 {
            let q = 2.0 * std::f64::consts::PI / cpr;
            (phi / q).floor() * q
        } else {
            phi
        }
    }
}

impl ControlSide for DirectSide<'_> {
    fn kind(&self) -> ControllerKind {
        self.ctrl.config().kind
    }

    fn step(&mut self, _k: usize, t: f64, sensed: &Sensed) -> (Actuation, [f64; 2], Diagnostics) {
        let dt = self.scn.control_period_s;
        let phi = sensed.wheel_angle_rad.map(|p| self.count(p));
        let w = match self.phi_prev {
            Some(prev) => [(phi[0] - prev[0]) / dt, (phi[1] - prev[1]) / dt],
            None => [0.0, 0.0],
        };
        self.phi_prev = Some(phi);
        let (r, h) = (self.wheel_radius_m, self.half_track_m);
        let eta = [0.5 * r * (w[0] + w[1]), 0.5 * r * (w[0] - w[1]) / h];
        let out = self.ctrl.step(&StepInput {
            reference: self.reference.sample(t as f32),
            pose: sensed.pose,
            eta: Vel2::new(eta[0] as f32, eta[1] as f32),
        });
        let limit = self.scn.torque_limit_nm;
        let tau = out.torque_nm.map(|x| {
            let mut x = x as f64;
            if self.scn.pwm_levels > 0 {
                let q = limit / self.scn.pwm_levels as f64;
                x = (x / q).round() * q;
            }
            x.clamp(-limit, limit)
        });
        (Actuation::Torque(tau), eta, out.diag)
    }

    fn rejected_steps(&self) -> u32 {
        self.ctrl.rejected_steps()
    }
}

/// Runs `scn` with the given controller configuration; logs every
/// `trace_every`-th step (0 = no trace).
pub fn run_with(
    scn: &Scenario,
    cfg: ControllerConfig,
    trace_every: usize,
) -> Result<SimOutput, String> {
    scn.validate()?;
    let side = DirectSide::new(scn, cfg)?;
    run_loop(scn, &cfg.robot, side, trace_every)
}

/// The closed loop: simulated sensors, `side`, the plant; metrics at every
/// step, a trace every `trace_every` steps (0 = none).
pub fn run_loop(
    scn: &Scenario,
    robot: &controller_core::RobotParams,
    mut side: impl ControlSide,
    trace_every: usize,
) -> Result<SimOutput, String> {
    scn.validate()?;
    let plant = Plant {
        params: PlantParams::from_robot(robot, scn.mass_scale, scn.inertia_scale),
    };
    let reference = scn.trajectory.reference();
    let dt = scn.control_period_s;
    let n = (scn.duration_s / dt).round() as usize;
    let h = dt / scn.substeps as f64;
    let mut rng = Rng::new(
        scn.seed
            .wrapping_mul(0x2545_F491_4F6C_DD1D)
            .wrapping_add(17),
    );
    let mut st = PlantState {
        q: [
            scn.initial_pose[0],
            scn.initial_pose[1],
            scn.initial_pose[2],
            0.0,
            0.0,
        ],
        nu: [0.0, 0.0],
    };
    let kind = side.kind();
    let mut acc = MetricsAcc::new(kind == ControllerKind::Proposed);
    let mut trace = Vec::with_capacity(n.checked_div(trace_every).map_or(0, |q| q + 1));
    // The loop asks for the perturbation at the same instant several times
    // per step (sensing, metrics, the ZOH sub-step starts, RK4's end and the
    // next start): remember the last one (exact time match, so bit-identical).
    let last_perturb = std::cell::Cell::new((f64::NAN, crate::plant::Perturbation::default()));
    let perturb = |t: f64| {
        let (lt, lp) = last_perturb.get();
        if lt.to_bits() == t.to_bits() {
            return lp;
        }
        let p = scn.perturbation(t);
        last_perturb.set((t, p));
        p
    };
    let noisy = scn.pose_noise_m != 0.0 || scn.heading_noise_rad != 0.0;
    let (r, hh) = (plant.params.wheel_radius_m, plant.params.half_track_m);
    let wheel_rates = |st: &PlantState, t: f64| {
        let eta = plant.eta(st, &perturb(t));
        [(eta[0] + hh * eta[1]) / r, (eta[0] - hh * eta[1]) / r]
    };

    for k in 0..n {
        let t = k as f64 * dt;
        // Without noise, skip the draws (x + 0·n = x: same result, no log/cos).
        let noise = if noisy {
            [
                scn.pose_noise_m * rng.normal(),
                scn.pose_noise_m * rng.normal(),
                scn.heading_noise_rad * rng.normal(),
            ]
        } else {
            [0.0; 3]
        };
        let sensed = Sensed {
            pose: Pose::new(
                (st.q[0] + noise[0]) as f32,
                (st.q[1] + noise[1]) as f32,
                (st.q[2] + noise[2]) as f32,
            ),
            wheel_angle_rad: [st.q[3], st.q[4]],
        };
        let rs = reference.sample(t as f32);
        let (act, eta_meas, d) = side.step(k, t, &sensed);
        let tau = act.torque_nm(wheel_rates(&st, t));

        let p_now = perturb(t);
        let eta_true = plant.eta(&st, &p_now);
        let f_true = [p_now.fault_eps * eta_true[0], p_now.fault_eps * eta_true[1]];
        let ex = rs.pose.x_m as f64 - st.q[0];
        let ey = rs.pose.y_m as f64 - st.q[1];
        let pos_err = ex.hypot(ey);
        let fe = (d.f_hat[0] as f64 - f_true[0]).hypot(d.f_hat[1] as f64 - f_true[1]);
        acc.push(
            t,
            pos_err,
            scn.in_window(t),
            t < scn.window_s[0] || scn.window_s[0] >= scn.window_s[1],
            tau,
            d.saturated,
            fe,
        );
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
                eta: eta_meas,
                eta_c: f2(d.eta_c),
                torque_nm: tau,
                s: f2(d.s),
                rho_hat: f2(d.rho_hat),
                d_hat: f2(d.d_hat),
                f_hat: f2(d.f_hat),
                f_true,
                saturated: d.saturated,
            });
        }
        // Plant over [t, t + dt]: actuation held (zero-order hold).
        for j in 0..scn.substeps {
            let tj = t + j as f64 * h;
            let tau_j = act.torque_nm(wheel_rates(&st, tj));
            st = plant.rk4_step(&st, tj, h, tau_j, &perturb);
        }
        if !(st.q.iter().chain(&st.nu).all(|x| x.is_finite())) {
            return Err(format!("plant state diverged at t = {t:.3} s"));
        }
    }
    Ok(SimOutput {
        kind,
        trace,
        metrics: acc.finish(scn.duration_s, dt),
        rejected_steps: side.rejected_steps(),
    })
}

/// Runs `scn` with `kind` at the paper's gains; trace every 10 ms.
pub fn run(scn: &Scenario, kind: ControllerKind) -> Result<SimOutput, String> {
    let every = ((0.01 / scn.control_period_s).round() as usize).max(1);
    run_with(scn, controller_config(scn, kind), every)
}
