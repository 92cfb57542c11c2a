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
use controller_core::{Controller, ControllerConfig, ControllerKind, Pose, StepInput, Vel2};
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

/// Runs `scn` with the given controller configuration; logs every
/// `trace_every`-th step (0 = no trace).
pub fn run_with(
    scn: &Scenario,
    cfg: ControllerConfig,
    trace_every: usize,
) -> Result<SimOutput, String> {
    scn.validate()?;
    let mut ctrl = Controller::new(cfg).map_err(|e| format!("controller config: {e}"))?;
    let plant = Plant {
        params: PlantParams::from_robot(&cfg.robot, scn.mass_scale, scn.inertia_scale),
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
    let cpr = scn.encoder_cpr as f64;
    let count = |phi: f64| {
        if cpr > 0.0 {
            (phi * cpr / (2.0 * std::f64::consts::PI)).floor() * 2.0 * std::f64::consts::PI / cpr
        } else {
            phi
        }
    };
    let mut phi_prev = [count(st.q[3]), count(st.q[4])];
    let mut acc = MetricsAcc::new(cfg.kind == ControllerKind::Proposed);
    let mut trace = Vec::with_capacity(n.checked_div(trace_every).map_or(0, |q| q + 1));
    let perturb = |t: f64| scn.perturbation(t);
    let r = plant.params.wheel_radius_m;
    let hh = plant.params.half_track_m;
    let limit = scn.torque_limit_nm;

    for k in 0..n {
        let t = k as f64 * dt;
        // Sensors.
        let pose = Pose::new(
            (st.q[0] + scn.pose_noise_m * rng.normal()) as f32,
            (st.q[1] + scn.pose_noise_m * rng.normal()) as f32,
            (st.q[2] + scn.heading_noise_rad * rng.normal()) as f32,
        );
        let phi = [count(st.q[3]), count(st.q[4])];
        let eta_meas = if k == 0 {
            plant.eta(&st, &perturb(t))
        } else {
            let w = [(phi[0] - phi_prev[0]) / dt, (phi[1] - phi_prev[1]) / dt];
            [0.5 * r * (w[0] + w[1]), 0.5 * r * (w[0] - w[1]) / hh]
        };
        phi_prev = phi;
        let rs = reference.sample(t as f32);
        let out = ctrl.step(&StepInput {
            reference: rs,
            pose,
            eta: Vel2::new(eta_meas[0] as f32, eta_meas[1] as f32),
        });
        // Actuators: PWM quantisation and the hard limit of the drive.
        let mut tau = [out.torque_nm[0] as f64, out.torque_nm[1] as f64];
        for x in &mut tau {
            if scn.pwm_levels > 0 {
                let q = limit / scn.pwm_levels as f64;
                *x = (*x / q).round() * q;
            }
            *x = x.clamp(-limit, limit);
        }

        let p_now = perturb(t);
        let eta_true = plant.eta(&st, &p_now);
        let f_true = [p_now.fault_eps * eta_true[0], p_now.fault_eps * eta_true[1]];
        let ex = rs.pose.x_m as f64 - st.q[0];
        let ey = rs.pose.y_m as f64 - st.q[1];
        let pos_err = ex.hypot(ey);
        let d = out.diag;
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
        // Plant over [t, t + dt] with the torque held.
        for j in 0..scn.substeps {
            st = plant.rk4_step(&st, t + j as f64 * h, h, tau, &perturb);
        }
        if !(st.q.iter().chain(&st.nu).all(|x| x.is_finite())) {
            return Err(format!("plant state diverged at t = {t:.3} s"));
        }
    }
    Ok(SimOutput {
        kind: cfg.kind,
        trace,
        metrics: acc.finish(scn.duration_s, dt),
        rejected_steps: ctrl.rejected_steps(),
    })
}

/// Runs `scn` with `kind` at the paper's gains; trace every 10 ms.
pub fn run(scn: &Scenario, kind: ControllerKind) -> Result<SimOutput, String> {
    let every = ((0.01 / scn.control_period_s).round() as usize).max(1);
    run_with(scn, controller_config(scn, kind), every)
}
