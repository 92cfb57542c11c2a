//! The paper's robot, in f64.
//!
//! State: q = \[x, y, θ, φ_R, φ_L\] (x, y of the centre of mass G) and the
//! body velocity ν = η − σ of eq. (6) (η = \[v, ω\] is what the wheels impose
//! and the encoders see; σ is the slip of eq. 3).
//!
//! * Dynamics (6): M1·ν̇ + N1(θ̇)·ν + P1 + Sᵀτ_d = B1·τ, with the plant's own
//!   (possibly scaled) mass and inertia. M1, N1 as derived in controller-core's
//!   `model` module; P1 = SᵀM0·U̇_D + SᵀC0·U_D in closed form:
//!   P1 = \[−m·θ̇·δ + I_w(ϖ̇_R + ϖ̇_L)/r, 2md·δ̇ + I_w·h(ϖ̇_R − ϖ̇_L)/r\]
//!   (C0·U_D = 0 because U_D has no θ component). Checked against the 5x5
//!   products in the tests.
//! * Kinematics (3) with the actuator fault (10): the wheels turn per η
//!   (φ̇_R = (v + hω)/r, φ̇_L = (v − hω)/r) while the body moves at
//!   η_b = (1 − ε)·η − σ, i.e. q̇_{x,y,θ} = S(θ)·η_b + U_D.
//!
//! Integration: classical RK4. The wheel torques come from a [`Drive`]
//! evaluated at each stage's wheel rates (a torque source holds them; a DC
//! motor at fixed duty feels its back-EMF continuously). At most one sin/cos
//! of θ per step, none when the step starts where the last one ended: the
//! stages' headings (and the end's) differ from the step's start by a small
//! angle δ, and sin/cos(θ + δ) follow from the angle-sum identities with
//! series for sin δ and cos δ (exact to rounding for |δ| ≤ [`SMALL_ANGLE_RAD`];
//! larger δ falls back to sin/cos).

use crate::math::sin_cos;
use controller_core::params::{eta_from_wheel_rates, m1_diagonal, wheel_rates};
use controller_core::RobotParams;
use core::cell::Cell;

/// Friction at one wheel (bearing, gearbox and rolling losses seen at the
/// wheel shaft), opposing the wheel's rotation: τ_f = b·φ̇ + c·sgn_w(φ̇), with
/// sgn_w(x) = x/√(x² + w²) a smooth sign (D69).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WheelFriction {
    /// Viscous coefficient b \[N·m·s/rad\] (>= 0).
    pub viscous_nms_per_rad: f64,
    /// Coulomb (dry) friction torque c \[N·m\] (>= 0): the breakaway torque.
    pub coulomb_nm: f64,
}

impl WheelFriction {
    /// No friction (the paper's plant).
    pub const NONE: Self = Self {
        viscous_nms_per_rad: 0.0,
        coulomb_nm: 0.0,
    };
}

/// The actuator's own dynamics between the command and the wheel torque
/// (used by [`World`](crate::World); the [`Plant`] itself integrates the
/// torque it is given).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ActuatorDynamics {
    /// Pure delay between a command and its effect at the wheels \[s\]
    /// (>= 0; the bus, the PWM update, the driver's dead time).
    pub delay_s: f64,
    /// Motor electrical time constant L/R \[s\] (>= 0; 0 = the current,
    /// and so the torque, follows the command instantly): the torque lags
    /// the one the command asks for as a first-order system.
    pub electrical_time_constant_s: f64,
}

impl ActuatorDynamics {
    /// No delay, no lag (the paper's plant).
    pub const NONE: Self = Self {
        delay_s: 0.0,
        electrical_time_constant_s: 0.0,
    };
}

/// Plant physical parameters: what the simulated robot *has*, which may
/// differ from what the controller's model believes in every field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantParams {
    /// m \[kg\].
    pub mass_kg: f64,
    /// I \[kg·m²\].
    pub inertia_kgm2: f64,
    /// I_w \[kg·m²\].
    pub wheel_inertia_kgm2: f64,
    /// Wheel radii `[r_R, r_L]` \[m\] (equal on the paper's robot; Eq. (3)
    /// with unequal radii: D68).
    pub wheel_radius_m: [f64; 2],
    /// h \[m\] (half the track width).
    pub half_track_m: f64,
    /// d \[m\].
    pub com_offset_m: f64,
    /// Friction at each wheel `[right, left]`.
    pub friction: [WheelFriction; 2],
    /// Actuation delay and motor electrical lag.
    pub actuator: ActuatorDynamics,
}

/// A physically impossible plant parameter, named.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum PlantParamsError {
    /// Mass, inertia, radii and half track must be finite and > 0 (wheel
    /// inertia >= 0), the offset finite and smaller than the half track.
    Geometry(&'static str),
    /// Friction coefficients must be finite and >= 0.
    Friction(&'static str),
    /// Delay and electrical time constant must be finite, >= 0 and at most
    /// 1 s.
    Actuator(&'static str),
}

impl core::fmt::Display for PlantParamsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Geometry(n) => write!(f, "plant: {n} is not physical"),
            Self::Friction(n) => write!(f, "plant: friction {n} must be finite and >= 0"),
            Self::Actuator(n) => write!(f, "plant: {n} must be finite, >= 0 and <= 1 s"),
        }
    }
}

#[cfg(any(test, feature = "robot-file"))]
impl PlantParams {
    /// The plant of the robot file `robot` (what it *has*: its per-wheel
    /// radii, track, masses, friction per wheel), no actuator dynamics:
    /// the one mapping from a robot file to the simulated body, used by
    /// [`crate::WorldConfig::of_robot`] and stm32-emu. Not validated
    /// (`Robot::validate`; [`Plant::new`] checks the numbers again).
    pub fn of_robot(robot: &robot_file::Robot) -> Self {
        let b = &robot.body;
        let m = &robot.motors;
        Self {
            mass_kg: b.mass_kg as f64,
            inertia_kgm2: b.inertia_kgm2 as f64,
            wheel_inertia_kgm2: b.wheel_inertia_kgm2 as f64,
            wheel_radius_m: [b.wheel_radius_m[0] as f64, b.wheel_radius_m[1] as f64],
            half_track_m: 0.5 * b.track_m as f64,
            com_offset_m: b.com_offset_m as f64,
            friction: core::array::from_fn(|i| WheelFriction {
                viscous_nms_per_rad: m.viscous_friction_nms_per_rad[i] as f64,
                coulomb_nm: m.coulomb_friction_nm[i] as f64,
            }),
            actuator: ActuatorDynamics::NONE,
        }
    }
}

impl PlantParams {
    /// The robot of `p` with mass and body inertia scaled (model mismatch),
    /// otherwise exactly as the model (equal radii, no friction, no delay).
    pub fn from_robot(p: &RobotParams, mass_scale: f64, inertia_scale: f64) -> Self {
        Self {
            mass_kg: p.mass_kg as f64 * mass_scale,
            inertia_kgm2: p.inertia_kgm2 as f64 * inertia_scale,
            wheel_inertia_kgm2: p.wheel_inertia_kgm2 as f64,
            wheel_radius_m: [p.wheel_radius_m as f64; 2],
            half_track_m: p.half_track_m as f64,
            com_offset_m: p.com_offset_m as f64,
            friction: [WheelFriction::NONE; 2],
            actuator: ActuatorDynamics::NONE,
        }
    }

    /// Every field physical (see [`PlantParamsError`]).
    pub fn validate(&self) -> Result<(), PlantParamsError> {
        let pos = |x: f64| x.is_finite() && x > 0.0;
        let nonneg = |x: f64| x.is_finite() && x >= 0.0;
        let geo = PlantParamsError::Geometry;
        if !pos(self.mass_kg) {
            return Err(geo("mass_kg"));
        }
        if !pos(self.inertia_kgm2) {
            return Err(geo("inertia_kgm2"));
        }
        if !nonneg(self.wheel_inertia_kgm2) {
            return Err(geo("wheel_inertia_kgm2"));
        }
        if !self.wheel_radius_m.iter().all(|&r| pos(r)) {
            return Err(geo("wheel_radius_m"));
        }
        if !pos(self.half_track_m) {
            return Err(geo("half_track_m"));
        }
        if !(self.com_offset_m.is_finite() && self.com_offset_m.abs() < self.half_track_m) {
            return Err(geo("com_offset_m"));
        }
        for f in &self.friction {
            if !nonneg(f.viscous_nms_per_rad) {
                return Err(PlantParamsError::Friction("viscous_nms_per_rad"));
            }
            if !nonneg(f.coulomb_nm) {
                return Err(PlantParamsError::Friction("coulomb_nm"));
            }
        }
        let a = self.actuator;
        if !(nonneg(a.delay_s) && a.delay_s <= 1.0) {
            return Err(PlantParamsError::Actuator("delay_s"));
        }
        if !(nonneg(a.electrical_time_constant_s) && a.electrical_time_constant_s <= 1.0) {
            return Err(PlantParamsError::Actuator("electrical_time_constant_s"));
        }
        Ok(())
    }

    /// Diagonal of M1 with equal wheel radii (controller-core's
    /// [`m1_diagonal`], in f64, at the right wheel's radius); unequal radii
    /// also give an off-diagonal term: [`Self::m1`].
    pub fn m1_diag(&self) -> [f64; 2] {
        let (m, i, iw, r, h, d) = self.unpack();
        m1_diagonal(m, i, iw, r, h, d)
    }

    /// M1 = SᵀM0S as \[M11, M12, M22\] (symmetric) with per-wheel radii:
    /// the body part of [`m1_diagonal`] plus I_w·Σ s_i s_iᵀ, s_R = \[1/r_R,
    /// h/r_R\], s_L = \[1/r_L, −h/r_L\] (D68).
    pub fn m1(&self) -> [f64; 3] {
        let [rr, rl] = self.wheel_radius_m;
        if rr == rl {
            let [a, c] = self.m1_diag();
            return [a, 0.0, c];
        }
        let (m, i, iw, _, h, d) = self.unpack();
        let body = m1_diagonal(m, i, 0.0, 1.0, h, d);
        let (qr, ql) = (1.0 / (rr * rr), 1.0 / (rl * rl));
        [
            body[0] + iw * (qr + ql),
            iw * h * (qr - ql),
            body[1] + iw * h * h * (qr + ql),
        ]
    }

    fn unpack(&self) -> (f64, f64, f64, f64, f64, f64) {
        (
            self.mass_kg,
            self.inertia_kgm2,
            self.wheel_inertia_kgm2,
            self.wheel_radius_m[0],
            self.half_track_m,
            self.com_offset_m,
        )
    }
}

/// Perturbations acting at one instant (from the scenario).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Perturbation {
    /// Lateral skid velocity δ_sl \[m/s\] and its time derivative.
    pub skid_mps: f64,
    /// dδ_sl/dt \[m/s²\].
    pub skid_rate_mps2: f64,
    /// Wheel slip rates ϖ = \[ϖ_R, ϖ_L\] \[rad/s\].
    pub wheel_slip_radps: [f64; 2],
    /// dϖ/dt \[rad/s²\].
    pub wheel_slip_rate_radps2: [f64; 2],
    /// External disturbance τ_d = \[f_x, f_y, τ_θ, τ_R, τ_L\] (N, N, N·m, N·m, N·m).
    pub tau_d: [f64; 5],
    /// Actuator fault ε (body moves at (1 − ε)η), 0 = healthy.
    pub fault_eps: f64,
}

/// Plant state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlantState {
    /// q = \[x, y, θ, φ_R, φ_L\].
    pub q: [f64; 5],
    /// ν = η − σ \[m/s, rad/s\].
    pub nu: [f64; 2],
}

/// Where the wheel torques come from, evaluated at every integration
/// stage from the wheel rates φ̇ = \[φ̇_R, φ̇_L\] \[rad/s\].
pub trait Drive {
    /// Wheel torques `[right, left]` \[N·m\] at these wheel rates.
    fn torque_nm(&self, wheel_rates_radps: [f64; 2]) -> [f64; 2];
}

/// Torques held over the step (an ideal torque source, zero-order hold).
impl Drive for [f64; 2] {
    fn torque_nm(&self, _wheel_rates_radps: [f64; 2]) -> [f64; 2] {
        *self
    }
}

/// A drive whose wheels deliver only `scale` of the inner drive's torque
/// (an actuator losing torque: a weak motor, a slipping gearbox), beyond
/// the paper. `scale = [1, 1]` gives the inner torques exactly.
#[derive(Clone, Copy, Debug)]
pub struct TorqueScaled<'a, D: Drive> {
    /// The commanded drive.
    pub drive: &'a D,
    /// Fraction of torque each wheel `[right, left]` delivers.
    pub scale: [f64; 2],
}

impl<D: Drive> Drive for TorqueScaled<'_, D> {
    fn torque_nm(&self, wheel_rates_radps: [f64; 2]) -> [f64; 2] {
        let t = self.drive.torque_nm(wheel_rates_radps);
        [t[0] * self.scale[0], t[1] * self.scale[1]]
    }
}

/// |δ| \[rad\] up to which sin/cos(θ + δ) are formed from sin/cos θ and
/// series in δ to δ⁷: the first omitted terms, δ⁸/8! and δ⁹/9!, stay below
/// 10⁻¹⁷ (under a tenth of an f64 ulp of 1). Beyond it: sin/cos.
pub const SMALL_ANGLE_RAD: f64 = 0.02;

/// sin/cos of θ0 + δ from (sin θ0, cos θ0): angle sums with Taylor series
/// of sin δ, cos δ for small |δ|, sin/cos otherwise.
#[inline]
fn sin_cos_offset(theta0: f64, sc0: (f64, f64), delta: f64) -> (f64, f64) {
    if delta.abs() > SMALL_ANGLE_RAD {
        return sin_cos(theta0 + delta);
    }
    // Horner with the reciprocals as constants (six divisions in a chain
    // cost more than the rest of a stage; the products differ from the
    // quotients by an ulp of terms below 10⁻⁴: D57).
    let d2 = delta * delta;
    let sd =
        delta * (1.0 - d2 * (1.0 / 6.0) * (1.0 - d2 * (1.0 / 20.0) * (1.0 - d2 * (1.0 / 42.0))));
    let cd = 1.0 - d2 * 0.5 * (1.0 - d2 * (1.0 / 12.0) * (1.0 - d2 * (1.0 / 30.0)));
    let (s0, c0) = sc0;
    (s0 * cd + c0 * sd, c0 * cd - s0 * sd)
}

/// The simulated robot.
#[derive(Clone, Debug)]
pub struct Plant {
    params: PlantParams,
    /// Constants of (3) and (6) computed once.
    k: Constants,
    /// θ at the end of the last step (its bits) and its (sin, cos), formed
    /// from that step's start: the next step starting there needs no sin/cos.
    theta_end: Cell<(u64, (f64, f64))>,
}

/// Products and reciprocals of the parameters used at every evaluation.
#[derive(Clone, Copy, Debug)]
struct Constants {
    /// 1/r_R (1/r with equal radii).
    inv_r: f64,
    /// 1/r_L.
    inv_rl: f64,
    /// r_R = r_L: the paper's formulas in their original operation order.
    equal_r: bool,
    h: f64,
    d: f64,
    m: f64,
    /// 2·m·d (N1 and P1).
    two_md: f64,
    /// I_w/r_R (P1).
    iw_over_r: f64,
    /// I_w/r_L (P1).
    iw_over_rl: f64,
    /// 1/M1 diagonal (equal radii).
    inv_m1: [f64; 2],
    /// M1⁻¹ as \[(1,1), (1,2), (2,2)\] (unequal radii).
    inv_m1_full: [f64; 3],
    /// Any friction at all.
    has_friction: bool,
    friction: [WheelFriction; 2],
    /// Per wheel: ∂φ̇_i/∂τ_i = s_iᵀM1⁻¹s_i \[rad/s² per N·m\] (1/effective
    /// inertia at the wheel), which scales the friction's smoothing (D69).
    inv_j: [f64; 2],
}

/// The parts of (3) and (6) that depend only on the perturbations at one
/// instant (shared by the RK4 stages at that instant).
#[derive(Clone, Copy, Debug)]
struct Forcing {
    /// σ of eq. (3).
    sigma: [f64; 2],
    /// 1 − ε of eq. (10).
    healthy: f64,
    /// δ_sl.
    skid_mps: f64,
    /// P1 without its θ̇ term: \[I_w(ϖ̇_R + ϖ̇_L)/r, 2md·δ̇ + I_w·h(ϖ̇_R − ϖ̇_L)/r\].
    p1_rest: [f64; 2],
    /// τ_d's world-frame force \[f_x, f_y\] (rotated by θ in Sᵀτ_d).
    force_xy: [f64; 2],
    /// Sᵀτ_d without the force: \[(τ_R + τ_L)/r, τ_θ + h(τ_R − τ_L)/r\].
    tau_body: [f64; 2],
}

impl Plant {
    /// The plant with these parameters (assumed physical:
    /// [`PlantParams::validate`]; [`World`](crate::World) checks them).
    pub fn new(params: PlantParams) -> Self {
        let (m, _, iw, r, h, d) = params.unpack();
        let rl = params.wheel_radius_m[1];
        let m1 = params.m1_diag();
        let [a, b, c] = params.m1();
        let det = a * c - b * b;
        let inv_m1_full = [c / det, -b / det, a / det];
        // s_iᵀ M1⁻¹ s_i with s_R = [1/r_R, h/r_R], s_L = [1/r_L, −h/r_L].
        let quad = |s: [f64; 2]| {
            let [ia, ib, ic] = inv_m1_full;
            s[0] * (ia * s[0] + ib * s[1]) + s[1] * (ib * s[0] + ic * s[1])
        };
        let friction = params.friction;
        Self {
            params,
            theta_end: Cell::new((f64::NAN.to_bits(), (0.0, 1.0))),
            k: Constants {
                inv_r: 1.0 / r,
                inv_rl: 1.0 / rl,
                equal_r: r == rl,
                h,
                d,
                m,
                two_md: 2.0 * m * d,
                iw_over_r: iw / r,
                iw_over_rl: iw / rl,
                inv_m1: [1.0 / m1[0], 1.0 / m1[1]],
                inv_m1_full,
                has_friction: friction
                    .iter()
                    .any(|f| f.viscous_nms_per_rad != 0.0 || f.coulomb_nm != 0.0),
                friction,
                inv_j: [quad([1.0 / r, h / r]), quad([1.0 / rl, -h / rl])],
            },
        }
    }

    /// Physical parameters.
    #[inline]
    pub fn params(&self) -> &PlantParams {
        &self.params
    }

    /// σ = \[σ_v, σ_ω\] of eq. (3) for wheel slip ϖ (with the sign fixed: D15):
    /// the η that wheel rates ϖ would give (controller-core's
    /// [`eta_from_wheel_rates`], in f64; per-wheel radii: D68).
    #[inline]
    pub fn sigma(&self, slip: [f64; 2]) -> [f64; 2] {
        let h = self.params.half_track_m;
        if self.k.equal_r {
            return eta_from_wheel_rates(self.params.wheel_radius_m[0], h, slip);
        }
        let [rr, rl] = self.params.wheel_radius_m;
        let (ur, ul) = (rr * slip[0], rl * slip[1]);
        [0.5 * (ur + ul), 0.5 * (ur - ul) / h]
    }

    /// η = ν + σ: the wheel-imposed velocities the encoders see.
    #[inline]
    pub fn eta(&self, st: &PlantState, p: &Perturbation) -> [f64; 2] {
        let s = self.sigma(p.wheel_slip_radps);
        [st.nu[0] + s[0], st.nu[1] + s[1]]
    }

    /// Wheel rates φ̇ = \[(v + hω)/r_R, (v − hω)/r_L\] \[rad/s\] (eq. 3, rows 4-5).
    #[inline]
    pub fn wheel_rates_radps(&self, st: &PlantState, p: &Perturbation) -> [f64; 2] {
        self.rates(self.eta(st, p))
    }

    #[inline(always)]
    fn rates(&self, eta: [f64; 2]) -> [f64; 2] {
        let k = &self.k;
        if k.equal_r {
            wheel_rates(k.inv_r, k.h, eta)
        } else {
            let hw = k.h * eta[1];
            [(eta[0] + hw) * k.inv_r, (eta[0] - hw) * k.inv_rl]
        }
    }

    /// B1-like map of wheel torques to \[Σ τ_i/r_i, h(τ_R/r_R − τ_L/r_L)\].
    #[inline(always)]
    fn wheel_forces(&self, t: [f64; 2]) -> [f64; 2] {
        let k = &self.k;
        if k.equal_r {
            [(t[0] + t[1]) * k.inv_r, k.h * (t[0] - t[1]) * k.inv_r]
        } else {
            let (fr, fl) = (t[0] * k.inv_r, t[1] * k.inv_rl);
            [fr + fl, k.h * (fr - fl)]
        }
    }

    #[inline]
    fn forcing(&self, p: &Perturbation) -> Forcing {
        let k = &self.k;
        let sr = p.wheel_slip_rate_radps2;
        let t = p.tau_d;
        let (p1_rest, tau_body) = if k.equal_r {
            (
                [
                    k.iw_over_r * (sr[0] + sr[1]),
                    k.two_md * p.skid_rate_mps2 + k.iw_over_r * k.h * (sr[0] - sr[1]),
                ],
                [
                    (t[3] + t[4]) * k.inv_r,
                    t[2] + k.h * (t[3] - t[4]) * k.inv_r,
                ],
            )
        } else {
            let (wr, wl) = (k.iw_over_r * sr[0], k.iw_over_rl * sr[1]);
            let w = self.wheel_forces([t[3], t[4]]);
            (
                [wr + wl, k.two_md * p.skid_rate_mps2 + k.h * (wr - wl)],
                [w[0], t[2] + w[1]],
            )
        };
        Forcing {
            sigma: self.sigma(p.wheel_slip_radps),
            healthy: 1.0 - p.fault_eps,
            skid_mps: p.skid_mps,
            p1_rest,
            force_xy: [t[0], t[1]],
            tau_body,
        }
    }

    /// q̇ (eq. 3 with the fault of eq. 10).
    #[inline]
    pub fn q_dot(&self, st: &PlantState, p: &Perturbation) -> [f64; 5] {
        self.q_dot_f(st, &self.forcing(p), sin_cos(st.q[2]))
    }

    /// q̇ of eq. (3) with the fault (10): the wheels turn per η = ν + σ, the
    /// body moves at (1 − ε)η − σ plus the skid.
    #[inline(always)]
    fn q_dot_f(&self, st: &PlantState, f: &Forcing, (s, c): (f64, f64)) -> [f64; 5] {
        let k = &self.k;
        let eta = [st.nu[0] + f.sigma[0], st.nu[1] + f.sigma[1]];
        let vb = f.healthy * eta[0] - f.sigma[0];
        let wb = f.healthy * eta[1] - f.sigma[1];
        let dl = f.skid_mps;
        let [rate_r, rate_l] = self.rates(eta);
        [
            vb * c - k.d * wb * s - s * dl,
            vb * s + k.d * wb * c + c * dl,
            wb,
            rate_r,
            rate_l,
        ]
    }

    /// ν̇ from eq. (6) for net wheel torques `[right, left]` (after
    /// friction).
    #[inline]
    pub fn nu_dot(&self, st: &PlantState, p: &Perturbation, torque_nm: [f64; 2]) -> [f64; 2] {
        let sc = sin_cos(st.q[2]);
        let f = self.forcing(p);
        let theta_dot = self.q_dot_f(st, &f, sc)[2];
        self.nu_dot_f(st, &f, torque_nm, theta_dot, sc)
    }

    /// The friction torques `[right, left]` \[N·m\] opposing these wheel
    /// rates, the Coulomb part's sign smoothed over `smooth_radps` (D69).
    #[inline]
    pub fn friction_nm(&self, wheel_rates_radps: [f64; 2], smooth_radps: [f64; 2]) -> [f64; 2] {
        core::array::from_fn(|i| {
            let f = self.k.friction[i];
            let x = wheel_rates_radps[i];
            let mut t = f.viscous_nms_per_rad * x;
            if f.coulomb_nm > 0.0 {
                let w = smooth_radps[i];
                t += f.coulomb_nm * x / libm::sqrt(x * x + w * w);
            }
            t
        })
    }

    /// The Coulomb smoothing speeds for an integration step `h_s`: w_i =
    /// c_i·h·(∂φ̇_i/∂τ_i), so that the smoothed friction's stiffness times
    /// the step is 1 (RK4 stays stable and monotone; D69).
    #[inline]
    pub fn friction_smoothing_radps(&self, h_s: f64) -> [f64; 2] {
        if !self.k.has_friction {
            return [0.0; 2];
        }
        core::array::from_fn(|i| self.k.friction[i].coulomb_nm * h_s * self.k.inv_j[i])
    }

    /// ν̇ of eq. (6): M1·ν̇ = B1·τ − N1(θ̇)·ν − P1 − Sᵀτ_d.
    #[inline(always)]
    fn nu_dot_f(
        &self,
        st: &PlantState,
        f: &Forcing,
        torque_nm: [f64; 2],
        theta_dot: f64,
        (s, c): (f64, f64),
    ) -> [f64; 2] {
        let k = &self.k;
        let n1c = k.two_md * theta_dot;
        let n1nu = [-n1c * st.nu[1], n1c * st.nu[0]];
        let p1 = [-k.m * theta_dot * f.skid_mps + f.p1_rest[0], f.p1_rest[1]];
        let [fx, fy] = f.force_xy;
        let std = [
            c * fx + s * fy + f.tau_body[0],
            k.d * (c * fy - s * fx) + f.tau_body[1],
        ];
        let b1tau = self.wheel_forces(torque_nm);
        let rhs = [
            b1tau[0] - n1nu[0] - p1[0] - std[0],
            b1tau[1] - n1nu[1] - p1[1] - std[1],
        ];
        if k.equal_r {
            [rhs[0] * k.inv_m1[0], rhs[1] * k.inv_m1[1]]
        } else {
            let [ia, ib, ic] = k.inv_m1_full;
            [ia * rhs[0] + ib * rhs[1], ib * rhs[0] + ic * rhs[1]]
        }
    }

    /// (q̇, ν̇) at (sin θ, cos θ) = `sc`, the drive's torque taken at the
    /// state's wheel rates (q̇ rows 4-5), less the wheels' friction.
    #[inline(always)]
    fn deriv(
        &self,
        st: &PlantState,
        f: &Forcing,
        drive: &impl Drive,
        sc: (f64, f64),
        smooth: [f64; 2],
    ) -> PlantState {
        let q = self.q_dot_f(st, f, sc);
        let tau = drive.torque_nm([q[3], q[4]]);
        self.deriv_with(st, f, q, tau, sc, smooth)
    }

    #[inline(always)]
    fn deriv_with(
        &self,
        st: &PlantState,
        f: &Forcing,
        q: [f64; 5],
        mut tau: [f64; 2],
        sc: (f64, f64),
        smooth: [f64; 2],
    ) -> PlantState {
        if self.k.has_friction {
            let fr = self.friction_nm([q[3], q[4]], smooth);
            tau = [tau[0] - fr[0], tau[1] - fr[1]];
        }
        let nu = self.nu_dot_f(st, f, tau, q[2], sc);
        PlantState { q, nu }
    }

    #[inline]
    fn start_sin_cos(&self, th0: f64) -> (f64, f64) {
        match self.theta_end.get() {
            (bits, sc) if bits == th0.to_bits() => sc,
            _ => sin_cos(th0),
        }
    }

    /// One classical RK4 step of length `h_s` from `t_s`; `perturb(t)` gives
    /// the perturbations at time t (asked at t, t + h/2 and t + h: a
    /// [`PerturbationGrid`](crate::PerturbationGrid) of step h/2 serves them
    /// cheaply), `drive` the wheel torques at each stage (less the wheels'
    /// friction).
    #[inline]
    pub fn rk4_step(
        &self,
        st: &PlantState,
        t_s: f64,
        h_s: f64,
        drive: &impl Drive,
        perturb: &mut impl FnMut(f64) -> Perturbation,
    ) -> PlantState {
        let th0 = st.q[2];
        let sc0 = self.start_sin_cos(th0);
        let w = self.friction_smoothing_radps(h_s);
        let p0 = self.forcing(&perturb(t_s));
        let pm = self.forcing(&perturb(t_s + 0.5 * h_s));
        let p1 = self.forcing(&perturb(t_s + h_s));
        let k1 = self.deriv(st, &p0, drive, sc0, w);
        let s2 = add(st, &k1, 0.5 * h_s);
        let k2 = self.deriv(&s2, &pm, drive, sin_cos_offset(th0, sc0, s2.q[2] - th0), w);
        let s3 = add(st, &k2, 0.5 * h_s);
        let k3 = self.deriv(&s3, &pm, drive, sin_cos_offset(th0, sc0, s3.q[2] - th0), w);
        let s4 = add(st, &k3, h_s);
        let k4 = self.deriv(&s4, &p1, drive, sin_cos_offset(th0, sc0, s4.q[2] - th0), w);
        let o = combine(st, h_s, [&k1, &k2, &k3, &k4]);
        let sc_end = sin_cos_offset(th0, sc0, o.q[2] - th0);
        self.theta_end.set((o.q[2].to_bits(), sc_end));
        o
    }

    /// One RK4 step of the plant with a first-order lag of time constant
    /// `tau_e_s` between the drive and the wheels (the motor's current,
    /// L/R): the state is augmented with the wheel torques `torque_nm`,
    /// dτ/dt = (drive(φ̇) − τ)/τ_e, the plant driven by τ. Returns the new
    /// state and torques. Stable for h ≤ 2.7·τ_e; [`World`](crate::World)
    /// asks for h ≤ 2·τ_e.
    #[allow(clippy::too_many_arguments)]
    pub fn rk4_step_lagged(
        &self,
        st: &PlantState,
        torque_nm: [f64; 2],
        tau_e_s: f64,
        t_s: f64,
        h_s: f64,
        drive: &impl Drive,
        perturb: &mut impl FnMut(f64) -> Perturbation,
    ) -> (PlantState, [f64; 2]) {
        let th0 = st.q[2];
        let sc0 = self.start_sin_cos(th0);
        let w = self.friction_smoothing_radps(h_s);
        let inv_te = 1.0 / tau_e_s;
        let p0 = self.forcing(&perturb(t_s));
        let pm = self.forcing(&perturb(t_s + 0.5 * h_s));
        let p1 = self.forcing(&perturb(t_s + h_s));
        let d = |s: &PlantState, tau: [f64; 2], f: &Forcing, sc| {
            let q = self.q_dot_f(s, f, sc);
            let want = drive.torque_nm([q[3], q[4]]);
            let dt = [(want[0] - tau[0]) * inv_te, (want[1] - tau[1]) * inv_te];
            (self.deriv_with(s, f, q, tau, sc, w), dt)
        };
        let addt = |a: [f64; 2], k: [f64; 2], f: f64| [a[0] + f * k[0], a[1] + f * k[1]];
        let (k1, l1) = d(st, torque_nm, &p0, sc0);
        let s2 = add(st, &k1, 0.5 * h_s);
        let t2 = addt(torque_nm, l1, 0.5 * h_s);
        let (k2, l2) = d(&s2, t2, &pm, sin_cos_offset(th0, sc0, s2.q[2] - th0));
        let s3 = add(st, &k2, 0.5 * h_s);
        let t3 = addt(torque_nm, l2, 0.5 * h_s);
        let (k3, l3) = d(&s3, t3, &pm, sin_cos_offset(th0, sc0, s3.q[2] - th0));
        let s4 = add(st, &k3, h_s);
        let t4 = addt(torque_nm, l3, h_s);
        let (k4, l4) = d(&s4, t4, &p1, sin_cos_offset(th0, sc0, s4.q[2] - th0));
        let o = combine(st, h_s, [&k1, &k2, &k3, &k4]);
        let tau = core::array::from_fn(|i| {
            torque_nm[i] + h_s / 6.0 * (l1[i] + 2.0 * l2[i] + 2.0 * l3[i] + l4[i])
        });
        let sc_end = sin_cos_offset(th0, sc0, o.q[2] - th0);
        self.theta_end.set((o.q[2].to_bits(), sc_end));
        (o, tau)
    }

    /// True when every state component is finite. (One sum: a NaN or an
    /// infinity in any component makes it non-finite; finite components
    /// only overflow it beyond 10³⁰⁷, a diverged state anyway.)
    #[inline]
    pub fn state_is_finite(st: &PlantState) -> bool {
        let [a, b, c, d, e] = st.q;
        let [f, g] = st.nu;
        (a + b + c + d + e + f + g).is_finite()
    }
}

/// a + f·k.
#[inline]
fn add(a: &PlantState, k: &PlantState, f: f64) -> PlantState {
    let mut o = *a;
    for i in 0..5 {
        o.q[i] += f * k.q[i];
    }
    for i in 0..2 {
        o.nu[i] += f * k.nu[i];
    }
    o
}

/// RK4's weighted sum of the stages.
#[inline]
fn combine(st: &PlantState, h_s: f64, [k1, k2, k3, k4]: [&PlantState; 4]) -> PlantState {
    let mut o = *st;
    for i in 0..5 {
        o.q[i] += h_s / 6.0 * (k1.q[i] + 2.0 * k2.q[i] + 2.0 * k3.q[i] + k4.q[i]);
    }
    for i in 0..2 {
        o.nu[i] += h_s / 6.0 * (k1.nu[i] + 2.0 * k2.nu[i] + 2.0 * k3.nu[i] + k4.nu[i]);
    }
    o
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::RobotParams;

    fn paper_plant() -> Plant {
        Plant::new(PlantParams::from_robot(&RobotParams::paper(), 1.0, 1.0))
    }

    fn perturbed(t: f64) -> Perturbation {
        Perturbation {
            skid_mps: 0.1 + 0.04 * t.sin(),
            skid_rate_mps2: 0.04 * t.cos(),
            wheel_slip_radps: [0.15 * t.sin(), 0.15 * t.cos()],
            wheel_slip_rate_radps2: [0.15 * t.cos(), -0.15 * t.sin()],
            tau_d: [0.0, 0.0, 0.2 * t.sin(), 0.5, -0.3],
            fault_eps: 0.0,
        }
    }

    fn run(
        plant: &Plant,
        h: f64,
        t_end: f64,
        tau: [f64; 2],
        pert: &mut impl FnMut(f64) -> Perturbation,
    ) -> PlantState {
        let mut st = PlantState {
            q: [2.5, 0.0, 0.3, 0.0, 0.0],
            nu: [0.2, 0.1],
        };
        let n = (t_end / h).round() as usize;
        for k in 0..n {
            st = plant.rk4_step(&st, k as f64 * h, h, &tau, &mut *pert);
        }
        st
    }

    /// The angle-sum shortcut equals sin/cos(θ + δ) to rounding, on both
    /// sides of the series threshold.
    #[test]
    fn small_angle_sin_cos_matches_direct() {
        for i in 0..2000 {
            let th = -7.0 + 0.007 * i as f64;
            let delta = -0.03 + 0.00003 * i as f64;
            let (s, c) = sin_cos_offset(th, sin_cos(th), delta);
            let (s_ref, c_ref) = (th + delta).sin_cos();
            let err = (s - s_ref).abs().max((c - c_ref).abs());
            // θ + δ itself rounds by up to half an ulp of 8 (8.9e-16).
            assert!(err < 1.5e-15, "{th} {delta}: {err:e}");
        }
    }

    /// Fourth order: halving the step divides the error by ~16.
    #[test]
    fn rk4_converges_at_fourth_order() {
        let plant = paper_plant();
        let tau = [0.8, 0.3];
        let a = run(&plant, 0.04, 4.0, tau, &mut perturbed);
        let b = run(&plant, 0.02, 4.0, tau, &mut perturbed);
        let c = run(&plant, 0.01, 4.0, tau, &mut perturbed);
        let diff = |u: &PlantState, v: &PlantState| {
            (0..3).map(|i| (u.q[i] - v.q[i]).abs()).fold(0.0, f64::max)
        };
        let ratio = diff(&a, &b) / diff(&b, &c);
        assert!(ratio > 12.0 && ratio < 20.0, "ratio {ratio}");
    }

    /// No slip, no disturbance, equal torques τ on both wheels from rest:
    /// ω stays 0 and v̇ = 2τ/(r·M1₁₁), so the distance is a·t²/2 along θ0.
    #[test]
    fn constant_torque_straight_line_matches_analytic() {
        let plant = paper_plant();
        let tau = 0.5;
        let mut st = PlantState {
            q: [1.0, -1.0, 0.4, 0.0, 0.0],
            nu: [0.0, 0.0],
        };
        let h = 1e-3;
        let t_end = 3.0;
        for k in 0..3000 {
            st = plant.rk4_step(&st, k as f64 * h, h, &[tau, tau], &mut |_| {
                Perturbation::default()
            });
        }
        let a = 2.0 * tau / (plant.params().wheel_radius_m[0] * plant.params().m1_diag()[0]);
        let dist = 0.5 * a * t_end * t_end;
        assert!((st.nu[0] - a * t_end).abs() < 1e-9);
        assert!(st.nu[1].abs() < 1e-12);
        assert!((st.q[0] - (1.0 + dist * 0.4f64.cos())).abs() < 1e-9);
        assert!((st.q[1] - (-1.0 + dist * 0.4f64.sin())).abs() < 1e-9);
        // Wheel angles: φ = distance / r.
        assert!((st.q[3] - dist / plant.params().wheel_radius_m[0]).abs() < 1e-8);
    }

    /// Opposite torques from rest: ω̇ = 2hτ/(r·M1₂₂) = α constant (N1 ν has no
    /// ω component while v = ... small), and the offset d couples a centripetal
    /// v̇ = 2md·ω²/M1₁₁, so v(t) = 2md·α²t³/(3·M1₁₁) to leading order.
    #[test]
    fn opposite_torques_spin_with_analytic_rates() {
        let plant = paper_plant();
        let tau = 0.2;
        let mut st = PlantState::default();
        let h = 1e-3;
        for k in 0..1000 {
            st = plant.rk4_step(&st, k as f64 * h, h, &[tau, -tau], &mut |_| {
                Perturbation::default()
            });
        }
        let p = *plant.params();
        let m1 = p.m1_diag();
        let alpha = 2.0 * p.half_track_m * tau / (p.wheel_radius_m[0] * m1[1]);
        let v_expect = 2.0 * p.mass_kg * p.com_offset_m * alpha * alpha / (3.0 * m1[0]);
        // ω̇ gets −2md·ω·v/M1₂₂, a relative correction of order 1e-4 here.
        assert!(
            (st.nu[1] - alpha).abs() < 1e-3 * alpha,
            "{} vs {alpha}",
            st.nu[1]
        );
        assert!(
            (st.nu[0] - v_expect).abs() < 1e-2 * v_expect,
            "{} vs {v_expect}",
            st.nu[0]
        );
    }

    /// Integrates `steps` ms of a perturbed run and checks the perturbed
    /// constraint (2), A(q)·q̇ = Δ_S, at every step, per wheel:
    /// −s·ẋ + c·ẏ − d·θ̇ = δ_skid and c·ẋ + s·ẏ ± h·θ̇ − r_i·φ̇_i = −r_i·ϖ_i
    /// (A's printed typos corrected).
    fn assert_perturbed_constraint(plant: &Plant, steps: u32) {
        let p = *plant.params();
        let ([rr, rl], h, d) = (p.wheel_radius_m, p.half_track_m, p.com_offset_m);
        let mut st = PlantState {
            q: [0.0, 0.0, 0.5, 0.0, 0.0],
            nu: [0.3, 0.2],
        };
        let dt = 1e-3;
        for k in 0..steps {
            let t = k as f64 * dt;
            let pert = perturbed(t);
            let qd = plant.q_dot(&st, &pert);
            let (s, c) = st.q[2].sin_cos();
            let aq = [
                -s * qd[0] + c * qd[1] - d * qd[2],
                c * qd[0] + s * qd[1] + h * qd[2] - rr * qd[3],
                c * qd[0] + s * qd[1] - h * qd[2] - rl * qd[4],
            ];
            let ds = [
                pert.skid_mps,
                -rr * pert.wheel_slip_radps[0],
                -rl * pert.wheel_slip_radps[1],
            ];
            for i in 0..3 {
                assert!((aq[i] - ds[i]).abs() < 1e-12, "row {i} at t {t}");
            }
            st = plant.rk4_step(&st, t, dt, &[0.3, 0.1], &mut perturbed);
        }
    }

    /// The perturbed constraint (2) holds along a run with slip, skid and
    /// disturbance (no fault) on the paper's robot.
    #[test]
    fn perturbed_constraint_holds_along_run() {
        assert_perturbed_constraint(&paper_plant(), 5000);
    }

    /// P1 closed form equals SᵀM0·U̇_D + SᵀC0·U_D from the 5x5 matrices.
    #[test]
    fn p1_closed_form_matches_matrices() {
        let plant = paper_plant();
        let p = *plant.params();
        let (m, i, iw, r, h, d) = p.unpack();
        let st = PlantState {
            q: [0.0, 0.0, 0.9, 0.0, 0.0],
            nu: [0.4, -0.6],
        };
        let pert = Perturbation {
            tau_d: [0.0; 5],
            ..perturbed(1.3)
        };
        let th = st.q[2];
        let thd = plant.q_dot(&st, &pert)[2];
        let (s, c) = th.sin_cos();
        let dl = pert.skid_mps;
        let dld = pert.skid_rate_mps2;
        let ud_dot = [
            -c * thd * dl - s * dld,
            -s * thd * dl + c * dld,
            0.0,
            pert.wheel_slip_rate_radps2[0],
            pert.wheel_slip_rate_radps2[1],
        ];
        let ud = [
            -s * dl,
            c * dl,
            0.0,
            pert.wheel_slip_radps[0],
            pert.wheel_slip_radps[1],
        ];
        let mut m0 = [[0.0; 5]; 5];
        m0[0][0] = m;
        m0[1][1] = m;
        m0[0][2] = -m * d * s;
        m0[2][0] = m0[0][2];
        m0[1][2] = m * d * c;
        m0[2][1] = m0[1][2];
        m0[2][2] = i;
        m0[3][3] = iw;
        m0[4][4] = iw;
        let mut c0 = [[0.0; 5]; 5];
        c0[0][2] = -m * d * thd * c;
        c0[1][2] = -m * d * thd * s;
        let sm = [
            [c, -d * s],
            [s, d * c],
            [0.0, 1.0],
            [1.0 / r, h / r],
            [1.0 / r, -h / r],
        ];
        let mut p1 = [0.0; 2];
        for j in 0..2 {
            for a in 0..5 {
                let row: f64 = (0..5)
                    .map(|b| m0[a][b] * ud_dot[b] + c0[a][b] * ud[b])
                    .sum();
                p1[j] += sm[a][j] * row;
            }
        }
        // ν̇ with zero torque and no τ_d is −(N1ν + P1)/M1: recover P1 from it.
        let nud = plant.nu_dot(&st, &pert, [0.0, 0.0]);
        let m1 = p.m1_diag();
        let n1c = 2.0 * m * d * thd;
        let p1_impl = [
            -nud[0] * m1[0] + n1c * st.nu[1],
            -nud[1] * m1[1] - n1c * st.nu[0],
        ];
        for j in 0..2 {
            assert!(
                (p1[j] - p1_impl[j]).abs() < 1e-12,
                "P1[{j}] {} vs {}",
                p1[j],
                p1_impl[j]
            );
        }
    }
    fn params_lr(rr: f64, rl: f64) -> PlantParams {
        PlantParams {
            wheel_radius_m: [rr, rl],
            ..PlantParams::from_robot(&RobotParams::paper(), 1.0, 1.0)
        }
    }

    /// M1 with unequal radii equals SᵀM0S of the 5x5 inertia matrix (at
    /// any heading: the body part's θ dependence cancels).
    #[test]
    fn m1_unequal_radii_matches_matrices() {
        let p = params_lr(0.103, 0.097);
        let (m, i, iw, h, d) = (
            p.mass_kg,
            p.inertia_kgm2,
            p.wheel_inertia_kgm2,
            p.half_track_m,
            p.com_offset_m,
        );
        let [rr, rl] = p.wheel_radius_m;
        for th in [0.0, 0.7, -2.1] {
            let (s, c) = f64::sin_cos(th);
            let mut m0 = [[0.0; 5]; 5];
            m0[0][0] = m;
            m0[1][1] = m;
            m0[0][2] = -m * d * s;
            m0[2][0] = m0[0][2];
            m0[1][2] = m * d * c;
            m0[2][1] = m0[1][2];
            m0[2][2] = i;
            m0[3][3] = iw;
            m0[4][4] = iw;
            let sm = [
                [c, -d * s],
                [s, d * c],
                [0.0, 1.0],
                [1.0 / rr, h / rr],
                [1.0 / rl, -h / rl],
            ];
            let mut m1 = [[0.0; 2]; 2];
            for a in 0..2 {
                for b in 0..2 {
                    for x in 0..5 {
                        for y in 0..5 {
                            m1[a][b] += sm[x][a] * m0[x][y] * sm[y][b];
                        }
                    }
                }
            }
            let got = p.m1();
            let want = [m1[0][0], m1[0][1], m1[1][1]];
            for k in 0..3 {
                assert!(
                    (got[k] - want[k]).abs() < 1e-12 * want[0],
                    "{k}: {got:?} {want:?}"
                );
            }
        }
    }

    /// Unequal radii, coasting straight without torque or friction: ν stays
    /// [v, 0] (N1ν = 0 at θ̇ = 0), each wheel turns by L/r_i, and odometry
    /// with the model's single radius r reads a heading change
    /// r·(φ_R − φ_L)/(2h) = r·L·(1/r_R − 1/r_L)/(2h): the analytic drift.
    #[test]
    fn wheel_radius_mismatch_gives_analytic_odometry_drift() {
        let (r, e) = (0.1, 0.01);
        let plant = Plant::new(params_lr(r * (1.0 + e), r));
        let h = plant.params().half_track_m;
        let v = 0.5;
        let mut st = PlantState {
            q: [0.0, 0.0, 0.3, 0.0, 0.0],
            nu: [v, 0.0],
        };
        let dt = 1e-3;
        for k in 0..10_000 {
            st = plant.rk4_step(&st, k as f64 * dt, dt, &[0.0, 0.0], &mut |_| {
                Perturbation::default()
            });
        }
        let dist = v * 10.0;
        assert!((st.nu[0] - v).abs() < 1e-12 && st.nu[1].abs() < 1e-12);
        assert!((st.q[2] - 0.3).abs() < 1e-12, "the body goes straight");
        assert!((st.q[3] - dist / (r * (1.0 + e))).abs() < 1e-9);
        assert!((st.q[4] - dist / r).abs() < 1e-9);
        let odo_heading = r * (st.q[3] - st.q[4]) / (2.0 * h);
        let analytic = r * dist * (1.0 / (r * (1.0 + e)) - 1.0 / r) / (2.0 * h);
        assert!(
            (odo_heading - analytic).abs() < 1e-9,
            "{odo_heading} {analytic}"
        );
        // About −0.124 rad over 5 m for a 1 % larger right wheel.
        assert!(analytic < -0.1);
    }

    /// Equal torques with a larger right wheel: the right wheel pushes with
    /// less force (τ/r_R < τ/r_L), so the robot turns right (ω < 0).
    #[test]
    fn larger_right_wheel_turns_right_under_equal_torques() {
        let plant = Plant::new(params_lr(0.105, 0.1));
        let mut st = PlantState::default();
        for k in 0..500 {
            st = plant.rk4_step(&st, k as f64 * 1e-3, 1e-3, &[0.5, 0.5], &mut |_| {
                Perturbation::default()
            });
        }
        assert!(st.nu[0] > 0.0 && st.nu[1] < 0.0, "{:?}", st.nu);
    }

    /// The perturbed constraint (2) with per-wheel radii:
    /// c·ẋ + s·ẏ ± h·θ̇ − r_i·φ̇_i = −r_i·ϖ_i, along a perturbed run.
    #[test]
    fn perturbed_constraint_holds_with_unequal_radii() {
        assert_perturbed_constraint(&Plant::new(params_lr(0.102, 0.099)), 2000);
    }

    fn with_friction(viscous: f64, coulomb: f64) -> Plant {
        Plant::new(PlantParams {
            friction: [WheelFriction {
                viscous_nms_per_rad: viscous,
                coulomb_nm: coulomb,
            }; 2],
            ..PlantParams::from_robot(&RobotParams::paper(), 1.0, 1.0)
        })
    }

    fn straight(plant: &Plant, tau: f64, h: f64, t_end: f64) -> PlantState {
        let mut st = PlantState::default();
        for k in 0..(t_end / h).round() as usize {
            st = plant.rk4_step(&st, k as f64 * h, h, &[tau, tau], &mut |_| {
                Perturbation::default()
            });
        }
        st
    }

    /// Coulomb friction c: a torque below the breakaway leaves the wheels
    /// still but for the smooth sign's creep, while the same torque without friction turns
    /// them by radians; above it the robot accelerates at the analytic
    /// 2(τ − c)/(r·M1₁₁) (the smooth sign is ±1 away from zero speed).
    #[test]
    fn coulomb_friction_holds_below_breakaway() {
        let c = 1.0;
        let h = 2.5e-4;
        let held = straight(&with_friction(0.0, c), 0.5 * c, h, 1.0);
        let free = straight(&with_friction(0.0, 0.0), 0.5 * c, h, 1.0);
        // The smooth sign lets the wheel creep at the rate where
        // c·x/√(x² + w²) = τ: x = w·u/√(1 − u²), u = τ/c (D69), here about
        // 1 mrad/s; the transient lasts a few steps.
        let plant = with_friction(0.0, c);
        let w = plant.friction_smoothing_radps(h)[0];
        let creep = w * 0.5 / (1.0f64 - 0.25).sqrt();
        assert!(creep < 2e-3, "creep {creep} rad/s");
        assert!(
            (held.q[3] - creep).abs() < 0.02 * creep,
            "held wheel turned {} rad, creep {creep}",
            held.q[3]
        );
        assert!(free.q[3] > 100.0 * held.q[3], "free wheel {}", free.q[3]);
        let (a1, a2) = (
            straight(&plant, 2.0 * c, h, 1.0),
            straight(&plant, 2.0 * c, h, 2.0),
        );
        let p = *plant.params();
        let a = 2.0 * (2.0 * c - c) / (p.wheel_radius_m[0] * p.m1_diag()[0]);
        let measured = a2.nu[0] - a1.nu[0];
        assert!((measured - a).abs() < 1e-6 * a, "{measured} vs {a}");
    }

    /// Viscous friction b: under a constant torque the wheels reach the
    /// terminal rate φ̇ = τ/b (torque balance at the wheel).
    #[test]
    fn viscous_friction_terminal_rate() {
        let (b, tau) = (2.0, 0.5);
        let plant = with_friction(b, 0.0);
        let st = straight(&plant, tau, 1e-3, 60.0);
        let rate = st.nu[0] / plant.params().wheel_radius_m[0];
        assert!((rate - tau / b).abs() < 1e-6, "{rate} vs {}", tau / b);
    }

    /// The paper's plant has no friction and equal radii: the new fields'
    /// defaults, which keep every run bit-identical (the equal-radius path
    /// is the original arithmetic).
    #[test]
    fn defaults_are_the_model() {
        let p = PlantParams::from_robot(&RobotParams::paper(), 1.0, 1.0);
        assert_eq!(p.friction, [WheelFriction::NONE; 2]);
        assert_eq!(p.actuator, ActuatorDynamics::NONE);
        assert_eq!(p.wheel_radius_m[0], p.wheel_radius_m[1]);
        assert_eq!(p.validate(), Ok(()));
        let bad = |f: &dyn Fn(&mut PlantParams)| {
            let mut q = p;
            f(&mut q);
            q.validate().err()
        };
        assert_eq!(
            bad(&|q| q.wheel_radius_m[1] = f64::NAN),
            Some(PlantParamsError::Geometry("wheel_radius_m"))
        );
        assert_eq!(
            bad(&|q| q.friction[0].coulomb_nm = -1.0),
            Some(PlantParamsError::Friction("coulomb_nm"))
        );
        assert_eq!(
            bad(&|q| q.actuator.delay_s = 2.0),
            Some(PlantParamsError::Actuator("delay_s"))
        );
    }
}
