//! Reference trajectories: the virtual vehicle's pose, v_s, ω_s and their
//! time derivatives (which the analytic η̇_c of the dynamic loop needs).

use crate::error::ConfigError;
use crate::math::{all_positive, atan2, sin_cos, sqrt};
#[cfg(feature = "square")]
use crate::math::{floor, wrap_angle};
use crate::types::Pose;

/// One sample of the reference (virtual vehicle) at time t.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RefSample {
    /// Reference pose (x_s, y_s, θ_s).
    pub pose: Pose,
    /// Reference linear velocity v_s \[m/s\] (signed: negative drives backwards).
    pub v_mps: f32,
    /// Reference angular velocity ω_s \[rad/s\].
    pub omega_radps: f32,
    /// dv_s/dt \[m/s²\].
    pub v_dot_mps2: f32,
    /// dω_s/dt \[rad/s²\].
    pub omega_dot_radps2: f32,
}

impl RefSample {
    /// True when every field is finite.
    pub fn is_finite(&self) -> bool {
        self.pose.is_finite()
            && self.v_mps.is_finite()
            && self.omega_radps.is_finite()
            && self.v_dot_mps2.is_finite()
            && self.omega_dot_radps2.is_finite()
    }
}

/// Anything that yields a reference sample at a time.
pub trait Trajectory {
    /// Reference at time `t_s` \[s\].
    fn sample(&self, t_s: f32) -> RefSample;
}

/// Reference from a planar curve's derivatives p, ṗ, p̈, p⃛ with the tangent
/// heading and v_s = |ṗ| >= 0. Undefined where ṗ = 0 (returns ω_s = 0 there).
pub fn tangent_sample(p: [f32; 2], d1: [f32; 2], d2: [f32; 2], d3: [f32; 2]) -> RefSample {
    let v2 = d1[0] * d1[0] + d1[1] * d1[1];
    let v = sqrt(v2);
    let (omega, v_dot, omega_dot) = if v2 > 1e-12 {
        let cross = d1[0] * d2[1] - d1[1] * d2[0];
        let dot = d1[0] * d2[0] + d1[1] * d2[1];
        let omega = cross / v2;
        // d/dt (cross / v²) = (ṗ×p⃛)/v² − 2ω(ṗ·p̈)/v²
        let cross3 = d1[0] * d3[1] - d1[1] * d3[0];
        (omega, dot / v, (cross3 - 2.0 * omega * dot) / v2)
    } else {
        (0.0, sqrt(d2[0] * d2[0] + d2[1] * d2[1]), 0.0)
    };
    RefSample {
        pose: Pose::new(p[0], p[1], atan2(d1[1], d1[0])),
        v_mps: v,
        omega_radps: omega,
        v_dot_mps2: v_dot,
        omega_dot_radps2: omega_dot,
    }
}

/// How the paper's curve gets a heading (NOTES: the printed θ_d = 0.2t does
/// not follow the curve). See `book/src/explanation/paper-departures.md`, D3.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PaperHeading {
    /// Default. Smooth heading through the cusps, signed v_s: the virtual
    /// vehicle faces +x throughout and drives backwards on alternate sweeps.
    #[default]
    SignedSmooth,
    /// Tangent heading with v_s >= 0: heading jumps by π at each cusp
    /// (t = 0, 5π, 10π s): a U-turn on the spot.
    Tangent,
    /// As printed: θ_s = w·t, ω_s = w, v_s = |ṗ| (heading unrelated to the path).
    Printed,
}

/// The paper's reference, x_d = a_x·cos(w t), y_d = a_y·cos(3 w t)
/// (paper: a_x = 4 m, a_y = 3 m, w = 0.2 rad/s).
///
/// Because the y frequency is three times the x frequency, y = a_y·T₃(x/a_x)
/// and the velocity factors as ṗ = −sin(wt)·W(t) with
/// W = w·\[a_x, 3a_y(1 + 2cos 2wt)\], which never vanishes (W_x = w·a_x > 0):
/// the heading atan2(W_y, W_x) is smooth and v_s = −sin(wt)·|W| is signed.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PaperCurve {
    /// x amplitude a_x \[m\].
    pub ax_m: f32,
    /// y amplitude a_y \[m\].
    pub ay_m: f32,
    /// Base angular frequency w \[rad/s\].
    pub w_radps: f32,
    /// Heading reading.
    pub heading: PaperHeading,
}

impl PaperCurve {
    /// The paper's curve with the given heading reading.
    pub const fn paper(heading: PaperHeading) -> Self {
        Self {
            ax_m: 4.0,
            ay_m: 3.0,
            w_radps: 0.2,
            heading,
        }
    }

    /// Validates the parameters.
    pub fn validate(self) -> Result<Self, ConfigError> {
        if all_positive(&[self.ax_m, self.ay_m, self.w_radps]) {
            Ok(self)
        } else {
            Err(ConfigError::InvalidTrajectory)
        }
    }

    fn signed_smooth(&self, t: f32) -> RefSample {
        let (ax, ay, w) = (self.ax_m, self.ay_m, self.w_radps);
        // One sin/cos: the double and triple angles from the identities
        // sin 2u = 2 sin u cos u, cos 2u = (cos u − sin u)(cos u + sin u),
        // cos 3u = cos u·(2 cos 2u − 1): as accurate as sin/cos of 2wt and
        // 3wt in f32, two sin/cos fewer per tick (D58).
        let (su, cu) = sin_cos(w * t);
        let s2 = 2.0 * su * cu;
        let c2 = (cu - su) * (cu + su);
        let c3 = cu * (2.0 * c2 - 1.0);
        // W = w·[ax, 3ay(1 + 2cos 2u)], Ẇ = [0, −12 ay w² sin 2u], Ẅ = [0, −24 ay w³ cos 2u]
        let wx = w * ax;
        let wy = 3.0 * ay * w * (1.0 + 2.0 * c2);
        let wy_d = -12.0 * ay * w * w * s2;
        let wy_dd = -24.0 * ay * w * w * w * c2;
        let n2 = wx * wx + wy * wy;
        let n = sqrt(n2);
        let n_d = wy * wy_d / n;
        let omega = wx * wy_d / n2;
        let omega_dot = wx * (wy_dd * n2 - wy_d * 2.0 * wy * wy_d) / (n2 * n2);
        RefSample {
            pose: Pose::new(ax * cu, ay * c3, atan2(wy, wx)),
            v_mps: -su * n,
            omega_radps: omega,
            v_dot_mps2: -w * cu * n - su * n_d,
            omega_dot_radps2: omega_dot,
        }
    }
}

impl Trajectory for PaperCurve {
    fn sample(&self, t_s: f32) -> RefSample {
        let smooth = self.signed_smooth(t_s);
        match self.heading {
            PaperHeading::SignedSmooth => smooth,
            PaperHeading::Tangent => {
                if smooth.v_mps < 0.0 {
                    let th = smooth.pose.theta_rad;
                    let flipped = if th > 0.0 {
                        th - core::f32::consts::PI
                    } else {
                        th + core::f32::consts::PI
                    };
                    RefSample {
                        pose: Pose::new(smooth.pose.x_m, smooth.pose.y_m, flipped),
                        v_mps: -smooth.v_mps,
                        v_dot_mps2: -smooth.v_dot_mps2,
                        ..smooth
                    }
                } else {
                    smooth
                }
            }
            PaperHeading::Printed => {
                let (ax, ay, w) = (self.ax_m, self.ay_m, self.w_radps);
                let (su, cu) = sin_cos(w * t_s);
                let (s3, c3) = sin_cos(3.0 * w * t_s);
                let d1 = [-ax * w * su, -3.0 * ay * w * s3];
                let d2 = [-ax * w * w * cu, -9.0 * ay * w * w * c3];
                let v = sqrt(d1[0] * d1[0] + d1[1] * d1[1]);
                let v_dot = if v > 1e-6 {
                    (d1[0] * d2[0] + d1[1] * d2[1]) / v
                } else {
                    0.0
                };
                RefSample {
                    pose: Pose::new(smooth.pose.x_m, smooth.pose.y_m, w * t_s),
                    v_mps: v,
                    omega_radps: w,
                    v_dot_mps2: v_dot,
                    omega_dot_radps2: 0.0,
                }
            }
        }
    }
}

/// Circle of radius R centred at the origin, driven counter-clockwise at
/// constant speed, starting at (R, 0) heading +y.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Circle {
    /// Radius \[m\].
    pub radius_m: f32,
    /// Speed \[m/s\].
    pub speed_mps: f32,
}

impl Trajectory for Circle {
    fn sample(&self, t_s: f32) -> RefSample {
        let w = self.speed_mps / self.radius_m;
        let (s, c) = sin_cos(w * t_s);
        let r = self.radius_m;
        tangent_sample(
            [r * c, r * s],
            [-r * w * s, r * w * c],
            [-r * w * w * c, -r * w * w * s],
            [r * w * w * w * s, -r * w * w * w * c],
        )
    }
}

/// Figure-eight (lemniscate of Gerono): x = A·sin(wt), y = (A/2)·sin(2wt).
/// Its speed never vanishes, so the tangent heading is smooth.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FigureEight {
    /// Half-width A \[m\].
    pub amplitude_m: f32,
    /// Angular frequency w \[rad/s\] (period 2π/w).
    pub w_radps: f32,
}

impl Trajectory for FigureEight {
    fn sample(&self, t_s: f32) -> RefSample {
        let (a, w) = (self.amplitude_m, self.w_radps);
        let (s1, c1) = sin_cos(w * t_s);
        let (s2, c2) = sin_cos(2.0 * w * t_s);
        let b = 0.5 * a;
        tangent_sample(
            [a * s1, b * s2],
            [a * w * c1, 2.0 * b * w * c2],
            [-a * w * w * s1, -4.0 * b * w * w * s2],
            [-a * w * w * w * c1, -8.0 * b * w * w * w * c2],
        )
    }
}

#[cfg(feature = "square")]
/// Peak of the minimum-jerk profile's slope, p'(1/2) = 30/16: a move of
/// length D in time T peaks at 1.875·D/T.
const MIN_JERK_PEAK: f32 = 1.875;

#[cfg(feature = "square")]
/// The minimum-jerk (quintic) rest-to-rest profile at τ ∈ \[0, 1\]:
/// (p, p', p'') with p = 10τ³ − 15τ⁴ + 6τ⁵ (zero slope and curvature at
/// both ends, so a chain of them has continuous speed and acceleration).
fn min_jerk(tau: f32) -> [f32; 3] {
    let t2 = tau * tau;
    let u = 1.0 - tau;
    [
        t2 * tau * (10.0 - 15.0 * tau + 6.0 * t2),
        30.0 * t2 * u * u,
        60.0 * tau * u * (1.0 - 2.0 * tau),
    ]
}

#[cfg(feature = "square")]
/// A square driven side by side with quarter turns on the spot (issue 34:
/// a validation path unlike the training one, where v and ω are never
/// both non-zero and each starts from rest). From the origin along +x,
/// counter-clockwise: each side of `side_m` a minimum-jerk move peaking at
/// `speed_mps`, then a quarter turn peaking at `yaw_rate_radps`; the four
/// sides repeat.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Square {
    /// Side length \[m\].
    pub side_m: f32,
    /// Peak speed on a side \[m/s\].
    pub speed_mps: f32,
    /// Peak yaw rate of a turn \[rad/s\].
    pub yaw_rate_radps: f32,
}

#[cfg(feature = "square")]
impl Square {
    /// Durations of a side and of a turn \[s\].
    pub fn durations_s(&self) -> [f32; 2] {
        [
            MIN_JERK_PEAK * self.side_m / self.speed_mps,
            MIN_JERK_PEAK * core::f32::consts::FRAC_PI_2 / self.yaw_rate_radps,
        ]
    }
}

#[cfg(feature = "square")]
impl Trajectory for Square {
    fn sample(&self, t_s: f32) -> RefSample {
        let [ts, tt] = self.durations_s();
        let t = if t_s > 0.0 { t_s } else { 0.0 };
        let k = floor(t / (ts + tt));
        let u = t - k * (ts + tt);
        // Side j of 4 starts at corner j with heading j·π/2.
        let j = k - 4.0 * floor(0.25 * k);
        let theta0 = j * core::f32::consts::FRAC_PI_2;
        let (sn, cs) = sin_cos(theta0);
        let l = self.side_m;
        // Corner j: (0,0), (L,0), (L,L), (0,L).
        let corner = |j: f32| -> (f32, f32) {
            let j = j - 4.0 * floor(0.25 * j);
            let x = if j > 0.5 && j < 2.5 { l } else { 0.0 };
            let y = if j > 1.5 { l } else { 0.0 };
            (x, y)
        };
        let (x0, y0) = corner(j);
        if u < ts {
            let [p, dp, ddp] = min_jerk(u / ts);
            let d = l * p;
            RefSample {
                pose: Pose::new(x0 + d * cs, y0 + d * sn, wrap_angle(theta0)),
                v_mps: l * dp / ts,
                omega_radps: 0.0,
                v_dot_mps2: l * ddp / (ts * ts),
                omega_dot_radps2: 0.0,
            }
        } else {
            let [p, dp, ddp] = min_jerk((u - ts) / tt);
            let q = core::f32::consts::FRAC_PI_2;
            let (x1, y1) = corner(j + 1.0);
            RefSample {
                pose: Pose::new(x1, y1, wrap_angle(theta0 + q * p)),
                v_mps: 0.0,
                omega_radps: q * dp / tt,
                v_dot_mps2: 0.0,
                omega_dot_radps2: q * ddp / (tt * tt),
            }
        }
    }
}

/// Straight line from a start point at constant speed and heading.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Line {
    /// Start point and heading.
    pub start: Pose,
    /// Speed \[m/s\].
    pub speed_mps: f32,
}

impl Trajectory for Line {
    fn sample(&self, t_s: f32) -> RefSample {
        let (s, c) = sin_cos(self.start.theta_rad);
        let d = self.speed_mps * t_s;
        RefSample {
            pose: Pose::new(
                self.start.x_m + d * c,
                self.start.y_m + d * s,
                self.start.theta_rad,
            ),
            v_mps: self.speed_mps,
            omega_radps: 0.0,
            v_dot_mps2: 0.0,
            omega_dot_radps2: 0.0,
        }
    }
}

/// Frequency ratios of the excitation's three v components (to its base
/// frequency): 1, √7, √19, pairwise incommensurate and incommensurate with
/// those of ω, so that no product of a v and an ω component has a constant
/// part (no drift of the travelled position) and the regressors of the
/// identification (v̇, ω̇, v, ω, sign v) stay linearly independent.
pub const EXCITATION_V_RATIOS: [f32; 3] = [1.0, 2.645_751_3, 4.358_899];
/// Frequency ratios of the excitation's three ω components: √3/2, √5, √13.
pub const EXCITATION_OMEGA_RATIOS: [f32; 3] = [0.866_025_4, 2.236_068, 3.605_551_3];
/// Phases of the three v and the three ω components \[rad\] (spread so the
/// peaks of the components do not line up at the end of the ramp-in).
const EXCITATION_PHASES: [[f32; 3]; 2] = [[0.0, 2.1, 4.2], [1.0, 3.1, 5.2]];

/// Identification excitation (beyond the paper; `book/src/how-to/identification.md`,
/// D80): v and ω each a sum of three sinusoids at incommensurate
/// frequencies ([`EXCITATION_V_RATIOS`], [`EXCITATION_OMEGA_RATIOS`] times
/// `w_radps`), each third of its amplitude, under a raised-cosine envelope
/// that starts and ends the run at rest. Bounded by construction:
/// |v| ≤ `v_amp_mps`, |ω| ≤ `omega_amp_radps`, and
/// |v̇| ≤ `v_amp_mps`·(w·Σratios/3 + π/(2·ramp)) (same for ω̇); the travelled
/// area is measured by [`Excitation::samples`] (bounded in practice: no
/// product of components has a constant part). v changes sign many times
/// (Coulomb friction's sign(v) is excited), ω both ways.
///
/// The pose has no closed form (x, y integrate v along the heading):
/// [`Excitation::samples`] integrates it step by step, so this is a
/// reference the host samples into timed waypoints (`wmr identify run`
/// uploads them; no protocol change) rather than a [`Reference`] variant.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Excitation {
    /// Peak linear velocity \[m/s\] (> 0).
    pub v_amp_mps: f32,
    /// Peak yaw rate \[rad/s\] (> 0).
    pub omega_amp_radps: f32,
    /// Base angular frequency w \[rad/s\] (> 0).
    pub w_radps: f32,
    /// Length of the run \[s\] (> 2·ramp).
    pub duration_s: f32,
    /// Raised-cosine ramp at the start and the end \[s\] (> 0).
    pub ramp_s: f32,
}

/// v, ω and their derivatives of an [`Excitation`] at one time.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ExcitationVelocity {
    /// v \[m/s\].
    pub v_mps: f32,
    /// ω \[rad/s\].
    pub omega_radps: f32,
    /// v̇ \[m/s²\].
    pub v_dot_mps2: f32,
    /// ω̇ \[rad/s²\].
    pub omega_dot_radps2: f32,
}

impl Excitation {
    /// A default excitation for a robot whose top speed and yaw rate are
    /// given: half of each as the peak, w = 1.5 rad/s (components at
    /// 0.24-1.04 Hz for v, 0.21-0.86 Hz for ω), 60 s with 3 s ramps.
    pub fn for_limits(top_speed_mps: f32, top_yaw_rate_radps: f32) -> Self {
        Self {
            v_amp_mps: 0.5 * top_speed_mps,
            omega_amp_radps: 0.5 * top_yaw_rate_radps,
            w_radps: 1.5,
            duration_s: 60.0,
            ramp_s: 3.0,
        }
    }

    /// Validates the parameters.
    pub fn validate(self) -> Result<Self, ConfigError> {
        let ok = all_positive(&[
            self.v_amp_mps,
            self.omega_amp_radps,
            self.w_radps,
            self.duration_s,
            self.ramp_s,
        ]) && self.duration_s > 2.0 * self.ramp_s;
        if ok {
            Ok(self)
        } else {
            Err(ConfigError::InvalidTrajectory)
        }
    }

    /// Raised-cosine envelope and its derivative at `t_s` (0 outside the run).
    fn envelope(&self, t_s: f32) -> (f32, f32) {
        let (t, r, d) = (t_s, self.ramp_s, self.duration_s);
        if t <= 0.0 || t >= d {
            return (0.0, 0.0);
        }
        let k = core::f32::consts::PI / r;
        let ramp = |u: f32, sign: f32| {
            let (s, c) = sin_cos(k * u);
            (0.5 * (1.0 - c), sign * 0.5 * k * s)
        };
        if t < r {
            ramp(t, 1.0)
        } else if t > d - r {
            ramp(d - t, -1.0)
        } else {
            (1.0, 0.0)
        }
    }

    /// v, ω, v̇, ω̇ at `t_s` (all 0 before 0 and after the end).
    pub fn velocity(&self, t_s: f32) -> ExcitationVelocity {
        let (e, e_dot) = self.envelope(t_s);
        let sum = |amp: f32, ratios: &[f32; 3], phases: &[f32; 3]| {
            let (mut x, mut x_dot) = (0.0f32, 0.0f32);
            for (q, ph) in ratios.iter().zip(phases) {
                let w = self.w_radps * q;
                let (s, c) = sin_cos(w * t_s + ph);
                x += s;
                x_dot += w * c;
            }
            let a = amp / 3.0;
            (a * x, a * x_dot)
        };
        let (v, v_d) = sum(self.v_amp_mps, &EXCITATION_V_RATIOS, &EXCITATION_PHASES[0]);
        let (w, w_d) = sum(
            self.omega_amp_radps,
            &EXCITATION_OMEGA_RATIOS,
            &EXCITATION_PHASES[1],
        );
        ExcitationVelocity {
            v_mps: e * v,
            omega_radps: e * w,
            v_dot_mps2: e_dot * v + e * v_d,
            omega_dot_radps2: e_dot * w + e * w_d,
        }
    }

    /// The reference every `dt_s` from `start` at t = 0 to the end, the
    /// pose integrated by Simpson's rule over each step (v, ω at its start,
    /// middle and end): a unicycle of the axle-free reference point, which
    /// is what the tracked point G follows (eq. 3 with d folded into the
    /// reference, as for every built-in shape).
    pub fn samples(&self, start: Pose, dt_s: f32) -> ExcitationSamples {
        ExcitationSamples {
            ex: *self,
            dt_s,
            k: 0,
            x: [start.x_m, start.y_m, start.theta_rad],
        }
    }
}

/// The iterator of [`Excitation::samples`]: (t \[s\], reference sample).
#[derive(Clone, Debug)]
pub struct ExcitationSamples {
    ex: Excitation,
    dt_s: f32,
    k: u32,
    x: [f32; 3],
}

impl Iterator for ExcitationSamples {
    type Item = (f32, RefSample);

    fn next(&mut self) -> Option<Self::Item> {
        let t = self.k as f32 * self.dt_s;
        let step_ok = self.dt_s.is_finite() && self.dt_s > 0.0;
        if !step_ok || t > self.ex.duration_s + 0.5 * self.dt_s {
            return None;
        }
        let vel = self.ex.velocity(t);
        let out = RefSample {
            pose: Pose::new(self.x[0], self.x[1], self.x[2]),
            v_mps: vel.v_mps,
            omega_radps: vel.omega_radps,
            v_dot_mps2: vel.v_dot_mps2,
            omega_dot_radps2: vel.omega_dot_radps2,
        };
        // Simpson over [t, t + dt]: θ first (from ω), then x, y from v
        // along the heading at the three nodes.
        let h = self.dt_s;
        let (a, m, b) = (vel, self.ex.velocity(t + 0.5 * h), self.ex.velocity(t + h));
        let th0 = self.x[2];
        let th_m = th0 + h * (5.0 * a.omega_radps + 8.0 * m.omega_radps - b.omega_radps) / 24.0;
        let th1 = th0 + h * (a.omega_radps + 4.0 * m.omega_radps + b.omega_radps) / 6.0;
        let (s0, c0) = sin_cos(th0);
        let (sm, cm) = sin_cos(th_m);
        let (s1, c1) = sin_cos(th1);
        self.x[0] += h * (a.v_mps * c0 + 4.0 * m.v_mps * cm + b.v_mps * c1) / 6.0;
        self.x[1] += h * (a.v_mps * s0 + 4.0 * m.v_mps * sm + b.v_mps * s1) / 6.0;
        self.x[2] = th1;
        self.k += 1;
        Some((t, out))
    }
}

/// Any of the built-in trajectories, for static dispatch in the firmware.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Reference {
    /// The paper's curve.
    Paper(PaperCurve),
    /// A circle.
    Circle(Circle),
    /// A figure-eight.
    FigureEight(FigureEight),
    /// A straight line.
    Line(Line),
    /// A square with turns on the spot (feature `square`: host only).
    #[cfg(feature = "square")]
    Square(Square),
}

impl Reference {
    /// Checks the parameters of the chosen trajectory.
    pub fn validate(self) -> Result<Self, ConfigError> {
        let valid = match &self {
            Self::Paper(p) => p.validate().is_ok(),
            Self::Circle(c) => all_positive(&[c.radius_m, c.speed_mps]),
            Self::FigureEight(f) => all_positive(&[f.amplitude_m, f.w_radps]),
            Self::Line(l) => l.start.is_finite() && l.speed_mps.is_finite(),
            #[cfg(feature = "square")]
            Self::Square(q) => all_positive(&[q.side_m, q.speed_mps, q.yaw_rate_radps]),
        };
        if valid {
            Ok(self)
        } else {
            Err(ConfigError::InvalidTrajectory)
        }
    }
}

impl Trajectory for Reference {
    fn sample(&self, t_s: f32) -> RefSample {
        match self {
            Self::Paper(p) => p.sample(t_s),
            Self::Circle(c) => c.sample(t_s),
            Self::FigureEight(f) => f.sample(t_s),
            Self::Line(l) => l.sample(t_s),
            #[cfg(feature = "square")]
            Self::Square(q) => q.sample(t_s),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::wrap_angle;

    /// Checks a trajectory against central finite differences: position moves
    /// along the heading at v_s (unless `printed`), θ̇ = ω_s, v̇_s, ω̇_s.
    fn check_fd<T: Trajectory>(
        traj: &T,
        t0: f32,
        t1: f32,
        unicycle: bool,
        skip: impl Fn(f32) -> bool,
    ) {
        let h = 1e-3f32;
        let mut t = t0;
        let mut checked = 0;
        while t < t1 {
            if !skip(t) {
                let a = traj.sample(t - h);
                let b = traj.sample(t + h);
                let m = traj.sample(t);
                let (s, c) = sin_cos(m.pose.theta_rad);
                if unicycle {
                    let vx = (b.pose.x_m - a.pose.x_m) / (2.0 * h);
                    let vy = (b.pose.y_m - a.pose.y_m) / (2.0 * h);
                    assert!(
                        (vx - m.v_mps * c).abs() < 5e-3,
                        "t={t} vx {vx} vs {}",
                        m.v_mps * c
                    );
                    assert!((vy - m.v_mps * s).abs() < 5e-3, "t={t} vy");
                }
                let th = wrap_angle(b.pose.theta_rad - a.pose.theta_rad) / (2.0 * h);
                assert!(
                    (th - m.omega_radps).abs() < 5e-3,
                    "t={t} ω {th} vs {}",
                    m.omega_radps
                );
                let vd = (b.v_mps - a.v_mps) / (2.0 * h);
                assert!(
                    (vd - m.v_dot_mps2).abs() < 2e-2,
                    "t={t} v̇ {vd} vs {}",
                    m.v_dot_mps2
                );
                let wd = (b.omega_radps - a.omega_radps) / (2.0 * h);
                assert!(
                    (wd - m.omega_dot_radps2).abs() < 2e-2,
                    "t={t} ω̇ {wd} vs {}",
                    m.omega_dot_radps2
                );
                checked += 1;
            }
            t += 0.0731;
        }
        assert!(checked > 100);
    }

    #[test]
    fn paper_signed_smooth_matches_finite_differences() {
        check_fd(
            &PaperCurve::paper(PaperHeading::SignedSmooth),
            0.0,
            40.0,
            true,
            |_| false,
        );
    }

    /// The paper curve's sample in f64 (the formulas of `signed_smooth` with
    /// f64 sin/cos of each multiple of the angle): the truth for the f32 code.
    fn signed_smooth_f64(p: &PaperCurve, t: f64) -> [f64; 7] {
        let (ax, ay, w) = (p.ax_m as f64, p.ay_m as f64, p.w_radps as f64);
        let (su, cu) = (w * t).sin_cos();
        let (s2, c2) = (2.0 * w * t).sin_cos();
        let c3 = (3.0 * w * t).cos();
        let wx = w * ax;
        let wy = 3.0 * ay * w * (1.0 + 2.0 * c2);
        let wy_d = -12.0 * ay * w * w * s2;
        let wy_dd = -24.0 * ay * w * w * w * c2;
        let n2 = wx * wx + wy * wy;
        let n = n2.sqrt();
        [
            ax * cu,
            ay * c3,
            wy.atan2(wx),
            -su * n,
            wx * wy_d / n2,
            -w * cu * n - su * wy * wy_d / n,
            wx * (wy_dd * n2 - wy_d * 2.0 * wy * wy_d) / (n2 * n2),
        ]
    }

    /// The previous f32 form (three sin/cos: of wt, 2wt and 3wt), kept here
    /// as the yardstick of D58.
    fn signed_smooth_three_trig(p: &PaperCurve, t: f32) -> [f32; 7] {
        let (ax, ay, w) = (p.ax_m, p.ay_m, p.w_radps);
        let (su, cu) = sin_cos(w * t);
        let (s2, c2) = sin_cos(2.0 * w * t);
        let (_, c3) = sin_cos(3.0 * w * t);
        let wx = w * ax;
        let wy = 3.0 * ay * w * (1.0 + 2.0 * c2);
        let wy_d = -12.0 * ay * w * w * s2;
        let wy_dd = -24.0 * ay * w * w * w * c2;
        let n2 = wx * wx + wy * wy;
        let n = sqrt(n2);
        [
            ax * cu,
            ay * c3,
            atan2(wy, wx),
            -su * n,
            wx * wy_d / n2,
            -w * cu * n - su * (wy * wy_d / n),
            wx * (wy_dd * n2 - wy_d * 2.0 * wy * wy_d) / (n2 * n2),
        ]
    }

    /// D58: one sin/cos and the double/triple-angle identities. Over the
    /// 40 s paper run at 1 kHz, each field's largest error against the f64
    /// evaluation is at most 1.2 times that of the previous three-sin/cos
    /// form (measured: x equal, y 0.6 times, the others 1.03-1.10 times;
    /// about 1e-6 in every field but ω̇_s, 1e-5 rad/s² for both forms: f32
    /// rounding, of the angles wt, 2wt, 3wt of up to 24 rad among others).
    #[test]
    fn paper_signed_smooth_single_sin_cos_matches_f64() {
        let p = PaperCurve::paper(PaperHeading::SignedSmooth);
        let (mut err_new, mut err_old) = ([0.0f64; 7], [0.0f64; 7]);
        for k in 0..40_000 {
            let t = (k as f64 * 1e-3) as f32;
            let truth = signed_smooth_f64(&p, t as f64);
            let s = p.sample(t);
            let new = [
                s.pose.x_m,
                s.pose.y_m,
                s.pose.theta_rad,
                s.v_mps,
                s.omega_radps,
                s.v_dot_mps2,
                s.omega_dot_radps2,
            ];
            let old = signed_smooth_three_trig(&p, t);
            for i in 0..7 {
                err_new[i] = err_new[i].max((new[i] as f64 - truth[i]).abs());
                err_old[i] = err_old[i].max((old[i] as f64 - truth[i]).abs());
            }
        }
        for i in 0..7 {
            assert!(
                err_new[i] <= 1.2 * err_old[i],
                "field {i}: {:e} vs {:e}",
                err_new[i],
                err_old[i]
            );
        }
    }

    #[test]
    fn paper_signed_smooth_is_the_paper_curve_and_heading_continuous() {
        let p = PaperCurve::paper(PaperHeading::SignedSmooth);
        let mut prev = p.sample(0.0).pose.theta_rad;
        for i in 0..4000 {
            let t = i as f32 * 0.01;
            let s = p.sample(t);
            assert!((s.pose.x_m - 4.0 * libm::cosf(0.2 * t)).abs() < 1e-5);
            assert!((s.pose.y_m - 3.0 * libm::cosf(0.6 * t)).abs() < 1e-5);
            // faces +x, no jump.
            assert!(s.pose.theta_rad.abs() < core::f32::consts::FRAC_PI_2);
            assert!((s.pose.theta_rad - prev).abs() < 0.05);
            prev = s.pose.theta_rad;
        }
        // Drives backwards on the first sweep (0, 5π) and forwards on the second.
        assert!(p.sample(5.0).v_mps < 0.0 && p.sample(20.0).v_mps > 0.0);
    }

    #[test]
    fn paper_tangent_matches_fd_away_from_cusps_and_flips_at_cusp() {
        let p = PaperCurve::paper(PaperHeading::Tangent);
        let cusp = |t: f32| {
            let k = libm::roundf(t / (5.0 * core::f32::consts::PI));
            (t - k * 5.0 * core::f32::consts::PI).abs() < 0.3
        };
        check_fd(&p, 0.0, 40.0, true, cusp);
        let c = 5.0 * core::f32::consts::PI;
        let before = p.sample(c - 0.05).pose.theta_rad;
        let after = p.sample(c + 0.05).pose.theta_rad;
        assert!((wrap_angle(after - before).abs() - core::f32::consts::PI).abs() < 0.1);
        assert!(p.sample(3.0).v_mps >= 0.0 && p.sample(20.0).v_mps >= 0.0);
    }

    #[test]
    fn paper_printed_heading_is_linear_in_time() {
        let p = PaperCurve::paper(PaperHeading::Printed);
        let cusp = |t: f32| {
            let k = libm::roundf(t / (5.0 * core::f32::consts::PI));
            (t - k * 5.0 * core::f32::consts::PI).abs() < 0.3
        };
        check_fd(&p, 0.0, 40.0, false, cusp);
        assert!((p.sample(10.0).pose.theta_rad - 2.0).abs() < 1e-6);
    }

    #[test]
    fn circle_figure_eight_line_match_finite_differences() {
        check_fd(
            &Circle {
                radius_m: 2.0,
                speed_mps: 0.5,
            },
            0.0,
            30.0,
            true,
            |_| false,
        );
        check_fd(
            &FigureEight {
                amplitude_m: 2.0,
                w_radps: 0.3,
            },
            0.0,
            30.0,
            true,
            |_| false,
        );
        let l = Line {
            start: Pose::new(1.0, -1.0, 0.7),
            speed_mps: 0.4,
        };
        check_fd(&l, 0.0, 30.0, true, |_| false);
        // Circle stays on its radius.
        let c = Circle {
            radius_m: 2.0,
            speed_mps: 0.5,
        }
        .sample(7.3)
        .pose;
        assert!(((c.x_m * c.x_m + c.y_m * c.y_m).sqrt() - 2.0).abs() < 1e-5);
    }

    /// The excitation's v̇, ω̇ are the derivatives of its v, ω (central
    /// differences), its bounds hold, it starts and ends at rest, v changes
    /// sign often, and the integrated pose moves along its heading at v
    /// (finite differences of the samples) within a bounded area.
    #[test]
    fn excitation_is_consistent_bounded_and_rich() {
        let ex = Excitation::for_limits(1.0, 2.0).validate().unwrap();
        let h = 1e-3f32;
        let mut sign_changes = 0;
        let mut prev_v = 0.0f32;
        for i in 1..5900 {
            let t = i as f32 * 0.01;
            let (a, m, b) = (ex.velocity(t - h), ex.velocity(t), ex.velocity(t + h));
            assert!(m.v_mps.abs() <= ex.v_amp_mps + 1e-6);
            assert!(m.omega_radps.abs() <= ex.omega_amp_radps + 1e-6);
            let vd = (b.v_mps - a.v_mps) / (2.0 * h);
            let wd = (b.omega_radps - a.omega_radps) / (2.0 * h);
            assert!(
                (vd - m.v_dot_mps2).abs() < 2e-2,
                "t={t}: v̇ {vd} vs {}",
                m.v_dot_mps2
            );
            assert!((wd - m.omega_dot_radps2).abs() < 4e-2, "t={t}: ω̇");
            if m.v_mps * prev_v < 0.0 {
                sign_changes += 1;
            }
            prev_v = m.v_mps;
        }
        assert!(sign_changes > 40, "{sign_changes} sign changes of v");
        assert_eq!(ex.velocity(0.0), ExcitationVelocity::default());
        assert_eq!(ex.velocity(ex.duration_s), ExcitationVelocity::default());
        let pts: std::vec::Vec<_> = ex.samples(Pose::new(1.0, 2.0, 0.5), 0.01).collect();
        assert_eq!(pts.len(), 6001);
        let mut max_r = 0.0f32;
        for w in pts.windows(3) {
            let (p0, p1, p2) = (w[0].1.pose, w[1].1.pose, w[2].1.pose);
            let (s, c) = sin_cos(p1.theta_rad);
            let vx = (p2.x_m - p0.x_m) / 0.02;
            let vy = (p2.y_m - p0.y_m) / 0.02;
            assert!((vx - w[1].1.v_mps * c).abs() < 5e-3);
            assert!((vy - w[1].1.v_mps * s).abs() < 5e-3);
            let th = (p2.theta_rad - p0.theta_rad) / 0.02;
            assert!((th - w[1].1.omega_radps).abs() < 5e-3);
            max_r = max_r.max(libm::hypotf(p1.x_m - 1.0, p1.y_m - 2.0));
        }
        // Half a metre per second peak, 60 s: the robot stays within a
        // couple of metres of its start.
        assert!(max_r < 2.5, "travelled {max_r} m from the start");
        let bad = Excitation { ramp_s: 40.0, ..ex };
        assert_eq!(bad.validate(), Err(ConfigError::InvalidTrajectory));
    }

    #[test]
    fn invalid_trajectories_rejected() {
        let bad = Reference::Circle(Circle {
            radius_m: 0.0,
            speed_mps: 1.0,
        });
        assert_eq!(bad.validate(), Err(ConfigError::InvalidTrajectory));
        let bad = PaperCurve {
            w_radps: f32::NAN,
            ..PaperCurve::paper(PaperHeading::Tangent)
        };
        assert_eq!(bad.validate(), Err(ConfigError::InvalidTrajectory));
    }

    #[cfg(feature = "square")]
    #[test]
    fn square_is_a_unicycle_path_through_its_corners() {
        // The square: unicycle-consistent everywhere (v and ω never both
        // non-zero), continuous through the joints of sides and turns.
        let q = Square {
            side_m: 2.0,
            speed_mps: 0.5,
            yaw_rate_radps: 1.0,
        };
        check_fd(&q, 0.0, 90.0, true, |_| false);
        let [ts, tt] = q.durations_s();
        // Corners at the ends of the sides, headings after the turns, the
        // loop closed after four sides; peaks at the given speed and rate.
        for (k, (x, y)) in [(2.0, 0.0), (2.0, 2.0), (0.0, 2.0), (0.0, 0.0)]
            .into_iter()
            .enumerate()
        {
            let end = (k as f32 + 1.0) * (ts + tt);
            let at = q.sample(end - tt - 1e-4).pose;
            assert!(
                (at.x_m - x).abs() < 1e-3 && (at.y_m - y).abs() < 1e-3,
                "{k}: {at:?}"
            );
            let after = q.sample(end).pose.theta_rad;
            let want = wrap_angle((k as f32 + 1.0) * core::f32::consts::FRAC_PI_2);
            assert!(wrap_angle(after - want).abs() < 1e-3, "{k}: {after}");
            let mid = q.sample(end - (ts + tt) + 0.5 * ts);
            assert!((mid.v_mps - 0.5).abs() < 1e-5 && mid.omega_radps == 0.0);
            let turn = q.sample(end - 0.5 * tt);
            assert!((turn.omega_radps - 1.0).abs() < 1e-5 && turn.v_mps == 0.0);
        }
    }
}
