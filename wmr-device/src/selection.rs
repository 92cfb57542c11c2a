//! Reference selection: what the robot drives ([`Mode`]) and the reference
//! sample of each tick: the built-in shape, the uploaded waypoints, the
//! velocity command's virtual vehicle, or the braking profile of a
//! controlled stop.

use crate::limits::RobotLimits;
use crate::params::LinkConfig;
use crate::reference::{PlacedReference, VirtualVehicle, WaypointBuffer};
use controller_core::trajectory::{RefSample, Trajectory};
use wmr_protocol::{ModeMsg, StopCode};

/// What the robot drives when armed (compared with `matches!`: a derived
/// `PartialEq` would compare the references' floats, and cost flash).
#[derive(Clone, Copy, Debug)]
pub(crate) enum Mode {
    None,
    Builtin(PlacedReference),
    Trajectory,
    Velocity,
}

/// The velocity command.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct VelocityCmd {
    pub target: [f32; 2],
    /// Robot time the command expires \[µs\]; `None` when expired.
    pub expires_us: Option<u32>,
}

/// A controlled stop in progress: a braking ramp from the measured motion
/// to rest, then the reference held at rest until the robot is at rest.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Braking {
    vehicle: VirtualVehicle,
    rates: [f32; 2],
    /// Ticks of the braking ramp left (the reference at rest after them).
    ramp_ticks_left: u32,
    /// Ticks left until the stop's bound: the motors are cut then
    /// whatever the robot does.
    ticks_left: u32,
    /// Consecutive ticks with both wheels at rest.
    rest_ticks: u32,
    pub cause: StopCode,
}

/// The robot's measured motion after the last tick: what a controlled stop
/// brakes from and waits for.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Measured {
    /// The pose given to the controller (the estimator's fused pose of G).
    pub pose: controller_core::Pose,
    /// η = \[v, ω\] from the wheel rates \[m/s, rad/s\].
    pub eta: [f32; 2],
    /// Each wheel's ground speed r·φ̇ `[right, left]` \[m/s\].
    pub wheel_mps: [f32; 2],
}

/// How a controlled stop runs: the ramp's rates and its bounds.
#[derive(Clone, Copy, Debug)]
pub(crate) struct StopPolicy {
    /// Control period \[s\].
    pub period_s: f32,
    /// The stop's bound \[ticks\] (`RobotLimits::stop_bound_ticks`).
    pub cap_ticks: u32,
    /// Ticks both wheels must stay at rest.
    pub rest_hold_ticks: u32,
    /// A wheel at or below this ground speed is at rest \[m/s\].
    pub rest_speed_mps: f32,
    /// The robot's limits: every tick's reference is checked against them.
    pub limits: RobotLimits,
}

/// The reference of one tick.
pub(crate) enum Selected {
    /// Drive this sample.
    Drive(RefSample),
    /// The controlled stop is over: disarm with this cause, and hold this
    /// sample (at rest where the braking reference stopped).
    Finished(StopCode, RefSample),
}

/// The loaded mode, its references and the controlled stop.
pub(crate) struct Selector {
    pub mode: Mode,
    pub waypoints: WaypointBuffer,
    pub velocity: VelocityCmd,
    /// The velocity command's virtual vehicle.
    pub vehicle: VirtualVehicle,
    pub braking: Option<Braking>,
    /// The reference of the last tick.
    pub last_ref: RefSample,
    /// The measured motion after the last tick.
    pub measured: Measured,
}

impl Selector {
    pub fn new() -> Self {
        Self {
            mode: Mode::None,
            waypoints: WaypointBuffer::default(),
            velocity: VelocityCmd::default(),
            vehicle: VirtualVehicle::default(),
            braking: None,
            last_ref: RefSample::default(),
            measured: Measured::default(),
        }
    }

    /// The loaded mode.
    pub fn mode_msg(&self) -> ModeMsg {
        match self.mode {
            Mode::None => ModeMsg::None,
            Mode::Builtin(_) => ModeMsg::Builtin,
            Mode::Trajectory => ModeMsg::Trajectory,
            Mode::Velocity => ModeMsg::Velocity,
        }
    }

    /// The loaded mode can be armed.
    pub fn ready(&self) -> bool {
        match self.mode {
            Mode::None => false,
            Mode::Builtin(_) | Mode::Velocity => true,
            Mode::Trajectory => self.waypoints.armable(),
        }
    }

    /// The braking cause, while a controlled stop runs.
    pub fn braking_cause(&self) -> Option<StopCode> {
        self.braking.map(|b| b.cause)
    }

    /// The robot stopped (latched or controlled): no braking, no command.
    pub fn on_stop(&mut self) {
        self.braking = None;
        self.velocity = VelocityCmd::default();
    }

    /// The robot was disarmed: as [`Self::on_stop`], and an upload that
    /// can no longer start from t = 0 is unloaded.
    pub fn on_disarm(&mut self) {
        self.on_stop();
        if matches!(self.mode, Mode::Trajectory) && !self.waypoints.ready() {
            self.mode = Mode::None;
        }
    }

    /// Starts a controlled stop from the measured motion (when `running`
    /// and none runs yet): a reference starting at the robot's pose with
    /// its measured v and ω, both falling linearly to zero together (the
    /// path's curvature is kept) at the braking deceleration, then held at
    /// rest until both wheels have been at rest for the policy's hold time;
    /// the whole stop ends within `policy.cap_ticks` − 1 ticks (the ramp
    /// is made faster when the braking settings would take longer: D41's
    /// hard cap), then the robot disarms.
    pub fn start_braking(
        &mut self,
        running: bool,
        link: &LinkConfig,
        policy: &StopPolicy,
        cause: StopCode,
    ) {
        if self.braking.is_some() || !running {
            return;
        }
        let m = self.measured;
        // A non-finite measurement (a runtime fault) brakes from the last
        // reference instead.
        let (pose, v, w) = if m.eta.iter().all(|x| x.is_finite()) && m.pose.is_finite() {
            (m.pose, m.eta[0], m.eta[1])
        } else {
            let r = self.last_ref;
            (r.pose, r.v_mps, r.omega_radps)
        };
        // Within the limits (a wheel measured beyond its no-load speed:
        // pushed, or an encoder glitch), so the braking reference is too.
        let lim = &policy.limits;
        let v = v.clamp(-lim.top_speed_mps, lim.top_speed_mps);
        let w = w.clamp(-lim.top_yaw_rate_radps, lim.top_yaw_rate_radps);
        let period_s = policy.period_s;
        let cap = policy.cap_ticks.saturating_sub(1).max(1);
        let t_v = v.abs() / link.brake_decel_mps2;
        let t_w = w.abs() / link.ang_accel_radps2;
        let ramp = ((t_v.max(t_w) / period_s) as u32)
            .saturating_add(1)
            .min(cap);
        let t = ramp as f32 * period_s;
        self.braking = Some(Braking {
            vehicle: VirtualVehicle::from_sample(RefSample {
                pose,
                v_mps: v,
                omega_radps: w,
                v_dot_mps2: -v / t,
                omega_dot_radps2: -w / t,
            }),
            rates: [-v / t, -w / t],
            ramp_ticks_left: ramp,
            ticks_left: cap,
            rest_ticks: 0,
            cause,
        });
    }

    /// This tick's reference (`running`: the runtime runs; `t_ref_s`: its
    /// reference time; `now_us`: the robot clock).
    pub fn select(
        &mut self,
        running: bool,
        t_ref_s: f32,
        now_us: u32,
        link: &LinkConfig,
        policy: &StopPolicy,
    ) -> Selected {
        let dt = policy.period_s;
        if let Some(b) = &mut self.braking {
            let rest = RefSample {
                v_mps: 0.0,
                omega_radps: 0.0,
                v_dot_mps2: 0.0,
                omega_dot_radps2: 0.0,
                ..b.vehicle.sample
            };
            if b.ticks_left == 0 {
                // The stop's bound: the motors are cut now.
                return Selected::Finished(b.cause, rest);
            }
            b.ticks_left -= 1;
            if b.ramp_ticks_left > 0 {
                let out = b.vehicle.sample;
                b.vehicle.advance(dt, b.rates[0], b.rates[1]);
                b.ramp_ticks_left -= 1;
                return Selected::Drive(out);
            }
            // The reference is at rest: hold it until the robot is.
            let at_rest = self
                .measured
                .wheel_mps
                .iter()
                .all(|w| w.abs() <= policy.rest_speed_mps);
            b.rest_ticks = if at_rest { b.rest_ticks + 1 } else { 0 };
            if b.rest_ticks >= policy.rest_hold_ticks {
                return Selected::Finished(b.cause, rest);
            }
            return Selected::Drive(rest);
        }
        if !running {
            return Selected::Drive(self.last_ref);
        }
        let sample = match self.mode {
            Mode::None => self.last_ref,
            Mode::Builtin(p) => p.sample(t_ref_s),
            Mode::Trajectory => match self.waypoints.sample(t_ref_s) {
                Some(r) => r,
                None => {
                    // Past the last buffered waypoint: the trajectory's
                    // end when every declared waypoint arrived; else a run
                    // that ran out of streamed waypoints (a path longer than
                    // the buffer armed without its stream, a stream that
                    // fell behind): not an end a host may report as
                    // success (issue 37, D195).
                    let cause = if self.waypoints.complete() {
                        StopCode::TrajectoryEnd
                    } else {
                        StopCode::Other
                    };
                    self.start_braking(running, link, policy, cause);
                    return self.select(running, t_ref_s, now_us, link, policy);
                }
            },
            Mode::Velocity => {
                let expired = match self.velocity.expires_us {
                    Some(e) => (now_us.wrapping_sub(e) as i32) >= 0,
                    None => true,
                };
                // No live command (expired, or armed without one): stop.
                if expired {
                    self.velocity = VelocityCmd::default();
                    self.start_braking(running, link, policy, StopCode::VelocityTimeout);
                    return self.select(running, t_ref_s, now_us, link, policy);
                }
                let s = self.vehicle.sample;
                let a = VirtualVehicle::ramp_rate(
                    s.v_mps,
                    self.velocity.target[0],
                    link.accel_mps2,
                    dt,
                );
                let al = VirtualVehicle::ramp_rate(
                    s.omega_radps,
                    self.velocity.target[1],
                    link.ang_accel_radps2,
                    dt,
                );
                let mut out = s;
                out.v_dot_mps2 = a;
                out.omega_dot_radps2 = al;
                self.vehicle.advance(dt, a, al);
                out
            }
        };
        // Every tick's reference within the robot's limits (issue 31 item
        // 1): the uploads are checked segment by segment and the built-in
        // shapes analytically, so this is the backstop between a
        // segment's samples; a reference beyond a limit is never driven,
        // a controlled stop starts instead (cause `Other`).
        if policy.limits.check_sample(&sample, false).is_err() {
            self.start_braking(running, link, policy, StopCode::Other);
            return self.select(running, t_ref_s, now_us, link, policy);
        }
        Selected::Drive(sample)
    }
}
