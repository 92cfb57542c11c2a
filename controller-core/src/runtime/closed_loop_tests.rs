//! Closed loop through the whole runtime: quantized encoders, integer PWM
//! duty through the motor model's forward direction, the reduced dynamics
//! (eq. 7) as the plant. Checks sign conventions end to end (mirrored
//! encoder and motor) and that the chain tracks.

use super::*;
use crate::controller::ControllerKind;
use crate::model::ReducedModel;
use crate::trajectory::{Circle, Reference, Trajectory};
use crate::types::Vel2;

/// Plant state in f64: axle midpoint, heading, η, wheel angles.
struct Plant {
    model: ReducedModel,
    x: f64,
    y: f64,
    th: f64,
    eta: [f64; 2],
    phi: [f64; 2],
}

struct SimEncoders<'a> {
    phi: [f64; 2],
    cpr: f64,
    inverted: [bool; 2],
    _p: core::marker::PhantomData<&'a ()>,
}

impl WheelEncoders for SimEncoders<'_> {
    fn counts(&mut self) -> [u16; 2] {
        let mut out = [0u16; 2];
        for i in 0..2 {
            let c = (self.phi[i] * self.cpr / (2.0 * core::f64::consts::PI)).floor() as i64;
            let c = if self.inverted[i] { -c } else { c };
            out[i] = c as u16; // wrapping truncation, as a 16-bit counter
        }
        out
    }
}

#[derive(Default)]
struct SimDriver {
    enabled: bool,
    cmd: [DutyCommand; 2],
}

impl MotorDriver for SimDriver {
    fn set(&mut self, cmd: [DutyCommand; 2]) {
        self.enabled = true;
        self.cmd = cmd;
    }
    fn disable(&mut self) {
        self.enabled = false;
        self.cmd = [DutyCommand::ZERO; 2];
    }
}

impl Plant {
    fn g(&self) -> Pose {
        let d = self.model.params.com_offset_m as f64;
        Pose::new(
            (self.x + d * self.th.cos()) as f32,
            (self.y + d * self.th.sin()) as f32,
            self.th as f32,
        )
    }

    /// Advances one control period with the driver's outputs held.
    fn step(&mut self, drv: &SimDriver, motor: &MotorModel, inverted: [bool; 2], dt: f64) {
        let n_sub = 10;
        let h = dt / n_sub as f64;
        for _ in 0..n_sub {
            let rates = self
                .model
                .params
                .wheel_rates_radps(Vel2::new(self.eta[0] as f32, self.eta[1] as f32));
            let mut tau = [0.0f32; 2];
            if drv.enabled {
                for i in 0..2 {
                    let mut c = drv.cmd[i];
                    if inverted[i] && c.duty > 0 {
                        c.reverse = !c.reverse; // undo the mirrored wiring
                    }
                    tau[i] = motor.torque_for_duty(c, rates[i]);
                }
            }
            let e = [self.eta[0] as f32, self.eta[1] as f32];
            let m = self.model.m_eta(e);
            let n = self.model.n_tau(tau);
            let acc = [(m[0] + n[0]) as f64, (m[1] + n[1]) as f64];
            // Semi-implicit Euler: velocities first, then positions.
            self.eta[0] += h * acc[0];
            self.eta[1] += h * acc[1];
            let (v, w) = (self.eta[0], self.eta[1]);
            let thm = self.th + 0.5 * h * w;
            self.x += h * v * thm.cos();
            self.y += h * v * thm.sin();
            self.th += h * w;
            let r = self.model.params.wheel_radius_m as f64;
            let hh = self.model.params.half_track_m as f64;
            self.phi[0] += h * (v + hh * w) / r;
            self.phi[1] += h * (v - hh * w) / r;
        }
    }
}

/// Circle of radius 1.5 m at 0.5 m/s with the proposed controller, the
/// example motor (24 V) and encoders (24 000 counts/rev, left mirrored) and
/// a mirrored left motor: the chain must stay running, track within 2 cm
/// after the transient, and the odometry must agree with the true pose
/// (no slip in this plant) to within a few encoder counts' worth.
#[test]
fn quantized_closed_loop_tracks_a_circle() {
    let reference = Reference::Circle(Circle {
        radius_m: 1.5,
        speed_mps: 0.5,
    });
    let start = reference.sample(0.0).pose;
    let cfg = RuntimeConfig {
        reference,
        initial_pose: start,
        ..RuntimeConfig::example(ControllerKind::Proposed)
    };
    let mut cl = ControlLoop::new(cfg).unwrap();
    let model = *cl.controller().model();
    let motor = *cl.motor_model();
    let d = model.params.com_offset_m as f64;
    let th0 = start.theta_rad as f64;
    let mut plant = Plant {
        model,
        x: start.x_m as f64 - d * th0.cos(),
        y: start.y_m as f64 - d * th0.sin(),
        th: th0,
        eta: [0.0; 2],
        phi: [0.0; 2],
    };
    let mut drv = SimDriver::default();
    let dt = cfg.controller.period_s as f64;
    cl.arm().unwrap();
    let mut worst_late = 0.0f32;
    let steps = 20_000; // 20 s, over two laps
    for k in 0..steps {
        let mut enc = SimEncoders {
            phi: plant.phi,
            cpr: cfg.encoder.counts_per_wheel_rev as f64,
            inverted: cfg.encoder.inverted,
            _p: core::marker::PhantomData,
        };
        let rep = cl.tick(&mut enc, &mut drv, &mut WheelOdometryOnly, 1000);
        assert_eq!(rep.stopped, None, "tick {k}: {rep:?}");
        plant.step(&drv, &motor, cfg.motor_inverted, dt);
        if k > 5_000 {
            let g = plant.g();
            let r = reference.sample((k + 1) as f32 * dt as f32).pose;
            let err = libm::hypotf(g.x_m - r.x_m, g.y_m - r.y_m);
            worst_late = worst_late.max(err);
        }
    }
    assert!(
        worst_late < 0.02,
        "tracking error after 5 s: {worst_late} m"
    );
    let truth = plant.g();
    let odo = cl.odometry();
    let drift = libm::hypotf(truth.x_m - odo.x_m, truth.y_m - odo.y_m);
    assert!(drift < 5e-3, "odometry drift {drift} m");
    assert_eq!(cl.state(), RunState::Running);
}
