//! The fit: kinematic calibration, then the dynamic parameters of the
//! reduced model (D1) with per-wheel friction and the motor, by linear
//! least squares (`book/src/how-to/identification.md` has the equations; D82).
//!
//! 1. **Alignment.** Each signal is put on the rows' time grid with its own
//!    delay: the runtime's wheel rate is the mean over its last W ticks
//!    (centred W·T/2 before the row), the duty written at a tick acts over
//!    the next period (centred T/2 after it), the pose is of the tick.
//! 2. **Kinematics**, integrated over horizons H (default 0.5 s): the
//!    fused heading's increment Δθ = α_R·∫φ̇_R − α_L·∫φ̇_L + b·H (α = r/2h;
//!    b absorbs a gyro bias the estimator left) gives α_R and α_L. With
//!    external poses, the position increments Δx = h·Σ_i α_i·∫φ̇_i cosθ +
//!    d·Δcosθ (and Δy with sinθ; G is d ahead of the axle) give the
//!    length scale h, and r_i = 2h·α_i. Without them the position is the
//!    robot's own odometry: only r/h is observable and the track is kept from the prior
//!    (said in the report). Integrating instead of differentiating the
//!    pose keeps the estimator's transients (bounded position errors) from
//!    being amplified.
//! 3. **Dynamics**, per wheel i (σ_R = +1, σ_L = −1), from (6) with
//!    B1⁻¹ and the wheels' torques τ_i = a·V_i − (b + c_v,i)·φ̇_i − c_c,i·sign φ̇_i
//!    (a = η_g·N·k/R \[N·m/V\], b = η_g·N²k²/R: the motor's V = R·τ/(η_g N k) + kNφ̇):
//!    (r_i/2)·\[M_v·v̇ + σ_i·M_ω·ω̇/h\] + r_i·md·(σ_i·vω/h − ω²) + τ_fric,i = τ_i,
//!    M_v = m + I_w(1/r_R² + 1/r_L²), M_ω = I + 3md² + I_w·h²(1/r_R² + 1/r_L²).
//!    With duties (the *voltage form*) divide by a: the unknowns are
//!    M_v/a, M_ω/a, md/a, κ_i = (b + c_v,i)/a \[V·s/rad\], γ_i = c_c,i/a \[V\]
//!    against y = V_i. Every term of the motion scales with one factor: a
//!    robot with all masses, frictions and a multiplied by λ moves the same,
//!    so one of them must come from outside: the prior motor's a (default;
//!    then the mass is identified) — and b and c_v,i share one regressor
//!    (φ̇_i): their sum is identified, κ_i = N·k + c_v,i/a (= N·k, the
//!    motor's EMF constant, without viscous friction). With commanded
//!    torques only (a trace CSV, the *torque form*), the prior motor model
//!    is trusted and M_v, M_ω, md, c_v,i, c_c,i are fitted against τ_i.
//!
//! Every column of both regressions passes the same Savitzky-Golay filter
//! (derivatives by its derivative weights), so the filter's small pass-band
//! loss is the same on both sides and cancels.

use crate::filter::SavitzkyGolay;
use crate::log::IdRow;
use crate::lsq::{solve, LsqError, LsqFit, Z95};
use controller_core::runtime::MotorParams;
use controller_core::RobotParams;
use nalgebra::{DMatrix, DVector};

/// What the fit takes from outside the log: the robot as it was configured
/// when the log was recorded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Prior {
    /// The robot's parameters (I_w is kept; the rest are starting values
    /// and, where the log cannot tell, the values reported).
    pub robot: RobotParams,
    /// The motor model (supply voltage and duty scale turn duties into
    /// volts; its a = η_g·N·k/R fixes the scale of the voltage form).
    pub motor: MotorParams,
    /// Control period T \[s\].
    pub control_period_s: f64,
    /// Ticks W of the runtime's wheel-rate window.
    pub speed_window_ticks: u32,
    /// The runtime's per-wheel radius scale r_i/r̄ (D60): its wheel rates
    /// are the true ones times this; the fit divides it out.
    pub radius_scale: [f64; 2],
}

impl Prior {
    /// The paper's robot with the example motor, 1 kHz, the example encoder window.
    pub fn paper() -> Self {
        Self {
            robot: RobotParams::paper(),
            motor: MotorParams::EXAMPLE,
            control_period_s: 1e-3,
            speed_window_ticks: controller_core::runtime::EncoderParams::EXAMPLE.speed_window_ticks
                as u32,
            radius_scale: [1.0; 2],
        }
    }

    /// The prior of a robot file, its PWM timer clocked at
    /// `timer_clock_hz` (the duty's full scale: clock / PWM frequency).
    pub fn from_robot(robot: &robot_file::Robot, timer_clock_hz: u32) -> Result<Self, String> {
        robot.validate().map_err(|e| format!("robot file: {e}"))?;
        let full = robot
            .bridge
            .params()
            .duty_full_scale(timer_clock_hz)
            .ok_or_else(|| {
                format!(
                    "robot file: bridge.pwm_frequency_hz {} gives no duty resolution at a {timer_clock_hz} Hz timer",
                    robot.bridge.pwm_frequency_hz
                )
            })?;
        let enc = robot.encoder_params();
        Ok(Self {
            robot: robot.robot_params(),
            motor: robot.motor_params(full),
            control_period_s: robot_file::CONTROL_PERIOD_S as f64,
            speed_window_ticks: enc.speed_window_ticks as u32,
            radius_scale: [enc.radius_scale[0] as f64, enc.radius_scale[1] as f64],
        })
    }

    /// a = η_g·N·k/R: wheel torque per volt at stall \[N·m/V\].
    pub fn torque_per_volt(&self) -> f64 {
        let m = &self.motor;
        (m.gear_efficiency * m.gear_ratio * m.torque_constant_nm_per_a) as f64
            / m.winding_resistance_ohm as f64
    }

    /// N·k: back-EMF per wheel rate \[V·s/rad\].
    pub fn emf_per_wheel_rate(&self) -> f64 {
        (self.motor.gear_ratio * self.motor.torque_constant_nm_per_a) as f64
    }
}

/// Options of the fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitOptions {
    /// Savitzky-Golay window \[s\] (rounded to an odd number of rows).
    pub filter_window_s: f64,
    /// Savitzky-Golay polynomial degree.
    pub filter_degree: usize,
    /// Horizon H of the integrated kinematic fit \[s\].
    pub kinematic_horizon_s: f64,
    /// Half-width of the smooth sign used for Coulomb friction \[rad/s\]
    /// (sign φ̇ beyond it, linear inside: wheel-rate noise near rest).
    pub sign_band_radps: f64,
    /// A parameter whose 95 % interval is wider than this fraction of its
    /// value is reported as poorly identified.
    pub max_relative_ci: f64,
    /// The robot's weighed mass \[kg\] (a kitchen scale), taken as known:
    /// it fixes the voltage form's scale, which the log cannot see, so the
    /// motor's torque per volt a = η_g·N·k/R is identified instead of
    /// taken from the prior (issue 34, D171).
    pub mass_kg: Option<f64>,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            filter_window_s: 0.15,
            filter_degree: 3,
            kinematic_horizon_s: 0.5,
            sign_band_radps: 0.05,
            max_relative_ci: 0.2,
            mass_kg: None,
        }
    }
}

/// An estimate and the half-width of its 95 % confidence interval.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Estimate {
    /// Value.
    pub value: f64,
    /// Half-width of the 95 % interval (∞: not identified).
    pub ci95: f64,
}

impl Estimate {
    fn new(value: f64, std_err: f64) -> Self {
        Self {
            value,
            ci95: Z95 * std_err,
        }
    }

    /// ci95/|value| (∞ for 0).
    pub fn relative_ci(&self) -> f64 {
        self.ci95 / self.value.abs()
    }

    /// The interval contains 0: the log cannot tell the value from zero.
    pub fn consistent_with_zero(&self) -> bool {
        self.value.abs() <= self.ci95
    }
}

impl std::fmt::Display for Estimate {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let p = f.precision().unwrap_or(4);
        write!(f, "{:.p$} ± {:.p$}", self.value, self.ci95)
    }
}

/// Which dynamic regression.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Form {
    /// Against the applied voltages (duties): motor identified, scale from the prior's a.
    Voltage,
    /// Against the commanded torques: the prior motor model trusted.
    Torque,
}

/// The dynamic parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct Dynamics {
    /// Which regression.
    pub form: Form,
    /// m \[kg\].
    pub mass_kg: Estimate,
    /// I \[kg·m²\].
    pub inertia_kgm2: Estimate,
    /// d \[m\].
    pub com_offset_m: Estimate,
    /// M1's diagonal \[kg, kg·m²\].
    pub m1: [Estimate; 2],
    /// Coulomb friction per wheel `[right, left]` \[N·m\].
    pub coulomb_nm: [Estimate; 2],
    /// Viscous friction per wheel \[N·m·s/rad\] (voltage form: beyond the
    /// prior motor's own back-EMF damping a·N·k).
    pub viscous_nms_per_rad: [Estimate; 2],
    /// Voltage form: κ_i = N·k + c_v,i/a per wheel \[V·s/rad\] (the EMF
    /// constant plus viscous friction per torque-per-volt).
    pub emf_vs_per_rad: Option<[Estimate; 2]>,
    /// Sign of each wheel's duty against its torque (−1: mirrored motor).
    pub duty_sign: [f64; 2],
    /// Voltage form: the motor's torque per volt a = η_g·N·k/R \[N·m/V\]
    /// that scales the fit: identified from the weighed mass, else the
    /// prior's (interval ∞: not identified). Torque form: 1.
    pub torque_per_volt: Estimate,
    /// The weighed mass \[kg\] when one was given (voltage form), whether or
    /// not the run let it fix the scale ([`Self::mass_given`]).
    pub weighed_mass_kg: Option<f64>,
    /// Instants left out of the fit for a torque-limited tick within a
    /// filter window of them (each would give two rows).
    pub saturated_rows: usize,
    /// The fitted translational term M_v/a (voltage form; M_v in the
    /// torque form): the weighed mass fixes the scale through it, so only
    /// when the run determined it ([`Dynamics::translation_determined`]).
    pub scale_term: Estimate,
    /// |M_v/a|·RMS(its regressor) over the residual RMS: how much of the
    /// duty the translational term explains against what nothing does.
    /// Below 1 the term is not determined whatever its interval (a spin
    /// on the spot gave M_v/a 1695 ± 226 for a true 14.9: its regressor,
    /// v̇ ≈ 0, picks up model error), and neither the scale nor the mass
    /// is taken from it (D218).
    pub scale_snr: f64,
    /// The least-squares fit (parameters in the order of [`Self::names`]).
    pub lsq: LsqFit,
    /// The fitted quantities, in the regressor's column order.
    pub names: [&'static str; 7],
    /// Unit of the residual (V or N·m).
    pub residual_unit: &'static str,
}

/// Everything the fit found.
#[derive(Clone, Debug, PartialEq)]
pub struct Identification {
    /// Rows of the log.
    pub rows: usize,
    /// Rows in the regressions (after the filter's edges and gaps).
    pub fitted_rows: usize,
    /// Log rate \[Hz\].
    pub rate_hz: f64,
    /// Time covered \[s\].
    pub duration_s: f64,
    /// Rows with an external pose fused.
    pub external_pose_rows: usize,
    /// Wheel radii `[right, left]` \[m\].
    pub wheel_radius_m: [Estimate; 2],
    /// Half track h \[m\].
    pub half_track_m: Estimate,
    /// The track was kept from the prior (no external poses: not observable).
    pub track_from_prior: bool,
    /// Constant yaw-rate offset between the heading and the wheels \[rad/s\].
    pub yaw_offset_radps: Estimate,
    /// Residual RMS of the heading fit over each horizon \[rad\].
    pub yaw_residual_rad: f64,
    /// Residual RMS of the displacement fit over each horizon \[m\] (with external poses).
    pub displacement_residual_m: Option<f64>,
    /// Dynamic parameters (voltage form when the log has duties, else torque form).
    pub dynamics: Option<Dynamics>,
    /// The torque form as a cross-check, when the primary is the voltage form.
    pub torque_check: Option<Dynamics>,
    /// Why parameters are not identified, and other findings.
    pub notes: Vec<String>,
}

impl Dynamics {
    /// The run determined the translational term M_v/a: its interval
    /// excludes 0 and it explains at least as much as the residual
    /// ([`Self::scale_snr`] ≥ 1). Only then does a weighed mass fix the
    /// scale, and only then is a mass identified without one.
    pub fn translation_determined(&self) -> bool {
        determined(&self.scale_term, self.scale_snr)
    }

    /// The scale came from the weighed mass ([`FitOptions::mass_kg`]): one
    /// was given and the run determined the term it scales.
    pub fn mass_given(&self) -> bool {
        self.weighed_mass_kg.is_some() && self.translation_determined()
    }
}

/// See [`Dynamics::translation_determined`].
fn determined(term: &Estimate, snr: f64) -> bool {
    !term.consistent_with_zero() && term.ci95.is_finite() && snr >= 1.0
}

/// Why a log cannot be fitted.
#[derive(Clone, Debug, PartialEq)]
pub enum FitError {
    /// Fewer usable rows than the filter window or the parameters need.
    TooShort(String),
    /// A row is not finite or time does not increase.
    BadLog(String),
    /// A regression failed.
    Lsq(&'static str, LsqError),
    /// The weighed mass is outside the robot file's `body.mass_kg` range
    /// (the parameter table's: a mass no robot this firmware drives has).
    BadMass(controller_core::runtime::param_table::RangeError),
    /// The weighed mass was given but the run does not determine the
    /// translational term it scales (its fitted M_v/a not positive).
    NoScale(f64),
}

impl std::fmt::Display for FitError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::TooShort(s) | Self::BadLog(s) => f.write_str(s),
            Self::Lsq(what, e) => write!(f, "{what}: {e}"),
            Self::BadMass(e) => write!(
                f,
                "--mass-kg: {} (the robot's mass on a scale, in kg, with its battery and everything it carries)",
                e.reason()
            ),
            Self::NoScale(v) => write!(
                f,
                "--mass-kg: the run's translational term M_v/a = {v:.4} is not positive: the run did not \
                 accelerate the robot along its heading (record a run with v̇ excited: `wmr identify run --v-amp`)"
            ),
        }
    }
}

/// One gap-free stretch of the log, every signal on the rows' times.
struct Segment {
    rates: [Vec<f64>; 2],
    volts: [Vec<f64>; 2],
    torque: [Vec<f64>; 2],
    pose: [Vec<f64>; 3],
    saturated: Vec<bool>,
}

/// Linear interpolation of samples (t_j + offset, y_j) at `t` (None outside).
fn interp(ts: &[f64], ys: &[f64], offset: f64, t: f64) -> Option<f64> {
    let x = t - offset;
    if ts.is_empty() || x < ts[0] || x > ts[ts.len() - 1] {
        return None;
    }
    let j = ts.partition_point(|&s| s <= x).clamp(1, ts.len() - 1);
    let (t0, t1) = (ts[j - 1], ts[j]);
    let w = if t1 > t0 { (x - t0) / (t1 - t0) } else { 0.0 };
    Some(ys[j - 1] + w * (ys[j] - ys[j - 1]))
}

fn unwrap(th: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(th.len());
    let mut off = 0.0;
    for (k, &a) in th.iter().enumerate() {
        if k > 0 {
            let d = a - th[k - 1];
            if d > std::f64::consts::PI {
                off -= std::f64::consts::TAU;
            } else if d < -std::f64::consts::PI {
                off += std::f64::consts::TAU;
            }
        }
        out.push(a + off);
    }
    out
}

fn median(mut x: Vec<f64>) -> f64 {
    x.sort_by(|a, b| a.total_cmp(b));
    x[x.len() / 2]
}

fn segments(rows: &[IdRow], prior: &Prior, dt: f64, duty_sign: [f64; 2]) -> Vec<Segment> {
    let t_ctl = prior.control_period_s;
    let rate_offset = -0.5 * prior.speed_window_ticks as f64 * t_ctl;
    let duty_offset = 0.5 * t_ctl;
    let volts_per_count = prior.motor.supply_voltage_v as f64 / prior.motor.duty_full_scale as f64;
    let mut out = Vec::new();
    let mut start = 0;
    for k in 1..=rows.len() {
        let gap = k == rows.len() || rows[k].t_s - rows[k - 1].t_s > 1.5 * dt;
        if !gap {
            continue;
        }
        let seg = &rows[start..k];
        start = k;
        let ts: Vec<f64> = seg.iter().map(|r| r.t_s).collect();
        let col = |f: &dyn Fn(&IdRow) -> f64| seg.iter().map(f).collect::<Vec<f64>>();
        // The runtime's rates carry its radius scale (D60): true wheel rates.
        let sc = prior.radius_scale;
        let rates = [
            col(&|r| r.wheel_rate_radps[0] / sc[0]),
            col(&|r| r.wheel_rate_radps[1] / sc[1]),
        ];
        let volts = [
            col(&|r| duty_sign[0] * r.duty[0] * volts_per_count),
            col(&|r| duty_sign[1] * r.duty[1] * volts_per_count),
        ];
        let torque = [col(&|r| r.torque_nm[0]), col(&|r| r.torque_nm[1])];
        let th = unwrap(&col(&|r| r.pose[2]));
        let pose = [col(&|r| r.pose[0]), col(&|r| r.pose[1]), th];
        let mut s = Segment {
            rates: Default::default(),
            volts: Default::default(),
            torque: Default::default(),
            pose: Default::default(),
            saturated: Vec::new(),
        };
        for (j, &t) in ts.iter().enumerate() {
            let r = [
                interp(&ts, &rates[0], rate_offset, t),
                interp(&ts, &rates[1], rate_offset, t),
            ];
            let v = [
                interp(&ts, &volts[0], duty_offset, t),
                interp(&ts, &volts[1], duty_offset, t),
            ];
            let q = [
                interp(&ts, &torque[0], duty_offset, t),
                interp(&ts, &torque[1], duty_offset, t),
            ];
            let (Some(r0), Some(r1), Some(v0), Some(v1), Some(q0), Some(q1)) =
                (r[0], r[1], v[0], v[1], q[0], q[1])
            else {
                continue;
            };
            s.rates[0].push(r0);
            s.rates[1].push(r1);
            s.volts[0].push(v0);
            s.volts[1].push(v1);
            s.torque[0].push(q0);
            s.torque[1].push(q1);
            for (a, p) in s.pose.iter_mut().zip(&pose) {
                a.push(p[j]);
            }
            s.saturated.push(seg[j].saturated);
        }
        out.push(s);
    }
    out
}

/// Fits `rows` (one run, in time order) with `prior` and `opts`.
pub fn identify(
    rows: &[IdRow],
    prior: &Prior,
    opts: &FitOptions,
) -> Result<Identification, FitError> {
    if let Some(m) = opts.mass_kg {
        // The file's own range (the one parameter table): a weighed mass the
        // robot file would refuse is refused here, with the same limits.
        use controller_core::runtime::param_table::{RobotBounds, BODY_MASS_KG};
        BODY_MASS_KG
            .check(m as f32, &RobotBounds::ABSOLUTE)
            .map_err(FitError::BadMass)?;
    }
    if rows.len() < 100 {
        return Err(FitError::TooShort(format!(
            "{} rows: an identification needs a run of at least 100 telemetry frames",
            rows.len()
        )));
    }
    for (k, r) in rows.iter().enumerate() {
        let finite = r.t_s.is_finite()
            && r.wheel_rate_radps.iter().all(|x| x.is_finite())
            && r.torque_nm.iter().all(|x| x.is_finite())
            && r.pose.iter().all(|x| x.is_finite());
        if !finite {
            return Err(FitError::BadLog(format!(
                "row {}: a value is not finite",
                k + 1
            )));
        }
        if k > 0 && r.t_s <= rows[k - 1].t_s {
            return Err(FitError::BadLog(format!(
                "row {}: time does not increase ({} after {})",
                k + 1,
                r.t_s,
                rows[k - 1].t_s
            )));
        }
    }
    let dt = median(rows.windows(2).map(|w| w[1].t_s - w[0].t_s).collect());
    let m = ((opts.filter_window_s / dt / 2.0).round() as usize).max(opts.filter_degree / 2 + 1);
    let sg = SavitzkyGolay::new(m, opts.filter_degree)
        .ok_or_else(|| FitError::BadLog("filter window too short".into()))?;
    let has_duty = rows.iter().all(|r| r.duty.iter().all(|x| x.is_finite()))
        && rows.iter().any(|r| r.duty != [0.0; 2]);
    // Each wheel's duty sign against its torque: a mirrored motor's pin
    // duty has the opposite sign of its wheel torque.
    let duty_sign: [f64; 2] = std::array::from_fn(|i| {
        let c: f64 = rows.iter().map(|r| r.duty[i] * r.torque_nm[i]).sum();
        if c < 0.0 {
            -1.0
        } else {
            1.0
        }
    });
    let segs = segments(rows, prior, dt, duty_sign);
    let mut notes = Vec::new();
    let external_pose_rows = rows.iter().filter(|r| r.external_pose).count();
    let duration_s = rows[rows.len() - 1].t_s - rows[0].t_s;
    // Poses at least once a second on average: the position is measured.
    let with_poses = external_pose_rows as f64 >= duration_s;

    // --- Kinematics, in integrated form over horizons of H: the pose's
    // increments against the wheel-rate integrals (no differentiation of
    // the pose, whose estimator transients are bounded position errors
    // that do not grow with H).
    let hz = ((opts.kinematic_horizon_s / dt).round() as usize).max(2);
    // Per horizon: Δθ, ∫φ̇_R, ∫φ̇_L, Δx, Δy, ∫φ̇_R cosθ, ∫φ̇_L cosθ,
    // ∫φ̇_R sinθ, ∫φ̇_L sinθ, Δcosθ, Δsinθ, H.
    let mut kin: Vec<[f64; 12]> = Vec::new();
    for s in &segs {
        let len = s.rates[0].len();
        let mut k0 = 0;
        while k0 + hz < len {
            let k1 = k0 + hz;
            let mut row = [0.0; 12];
            let th = &s.pose[2];
            row[0] = th[k1] - th[k0];
            for k in k0..k1 {
                // Trapezoid over [t_k, t_k+1].
                let (a, b) = (k, k + 1);
                let avg = |x: &Vec<f64>| 0.5 * (x[a] + x[b]) * dt;
                let (c, sn) = (0.5 * (th[a] + th[b])).sin_cos();
                let (r0, r1) = (avg(&s.rates[0]), avg(&s.rates[1]));
                row[1] += r0;
                row[2] += r1;
                row[5] += 0.5 * r0 * sn;
                row[6] += 0.5 * r1 * sn;
                row[7] += 0.5 * r0 * c;
                row[8] += 0.5 * r1 * c;
            }
            row[3] = s.pose[0][k1] - s.pose[0][k0];
            row[4] = s.pose[1][k1] - s.pose[1][k0];
            row[9] = th[k1].cos() - th[k0].cos();
            row[10] = th[k1].sin() - th[k0].sin();
            row[11] = hz as f64 * dt;
            kin.push(row);
            k0 = k1;
        }
    }
    let n = kin.len();
    if n < 10 {
        return Err(FitError::TooShort(format!(
            "{n} kinematic horizons of {:.2} s after the gaps: record a longer run",
            hz as f64 * dt
        )));
    }
    let h_prior = prior.robot.half_track_m as f64;
    // The heading gives α_R, α_L (each wheel's rate is excited on its own:
    // v and ω independently): Δθ = α_R ∫φ̇_R − α_L ∫φ̇_L + b·H, α = r/(2h).
    let phi = DMatrix::from_fn(n, 3, |i, j| match j {
        0 => kin[i][1],
        1 => -kin[i][2],
        _ => kin[i][11],
    });
    let y = DVector::from_fn(n, |i, _| kin[i][0]);
    let fw = solve(&phi, &y, 1).map_err(|e| FitError::Lsq("heading fit", e))?;
    let alpha = [fw.theta[0], fw.theta[1]];
    let rel_alpha = [fw.std_err[0] / alpha[0], fw.std_err[1] / alpha[1]];
    let yaw_offset = Estimate::new(fw.theta[2], fw.std_err[2]);
    let (wheel_radius_m, half_track_m, speed_res) = if with_poses {
        // The length scale from the positions: Δx = h·(α_R ∫φ̇_R cosθ +
        // α_L ∫φ̇_L cosθ) + d·Δcosθ (G is d ahead of the axle), Δy
        // likewise with sinθ; two rows per horizon, unknowns h and d.
        let phi = DMatrix::from_fn(2 * n, 2, |i, j| {
            let r = &kin[i / 2];
            match (j, i % 2 == 0) {
                (0, true) => 2.0 * (alpha[0] * r[5] + alpha[1] * r[6]),
                (0, false) => 2.0 * (alpha[0] * r[7] + alpha[1] * r[8]),
                (_, true) => r[9],
                (_, false) => r[10],
            }
        });
        let y = DVector::from_fn(2 * n, |i, _| kin[i / 2][if i % 2 == 0 { 3 } else { 4 }]);
        let fv = solve(&phi, &y, 2).map_err(|e| FitError::Lsq("displacement fit", e))?;
        let h = fv.theta[0];
        let rel_h = fv.std_err[0] / h;
        let r = |i: usize| {
            let v = 2.0 * h * alpha[i];
            Estimate::new(v, v * (rel_h * rel_h + rel_alpha[i] * rel_alpha[i]).sqrt())
        };
        (
            [r(0), r(1)],
            Estimate::new(h, rel_h * h),
            Some(fv.residual_rms),
        )
    } else {
        notes.push(format!(
            "wheel radii and track: no external poses in the log ({external_pose_rows} rows): \
             the heading gives r/h only (the position is the robot's own odometry); \
             the track is kept from the prior ({:.4} m) and the radii follow from it",
            2.0 * h_prior
        ));
        let r = |j: usize| Estimate::new(2.0 * h_prior * alpha[j], 2.0 * h_prior * fw.std_err[j]);
        ([r(0), r(1)], Estimate::new(h_prior, f64::INFINITY), None)
    };
    let yaw_res = fw.residual_rms;
    let lags = 2 * m;

    // --- Dynamics.
    let r = [wheel_radius_m[0].value, wheel_radius_m[1].value];
    let h = half_track_m.value;
    let dyn_fit = |form: Form| -> Result<Dynamics, FitError> {
        let mut phi_rows: Vec<[f64; 7]> = Vec::new();
        let mut saturated_rows = 0usize;
        let mut ys: Vec<f64> = Vec::new();
        for s in &segs {
            if s.rates[0].len() < 2 * m + 1 {
                continue;
            }
            let len = s.rates[0].len();
            let v: Vec<f64> = (0..len)
                .map(|k| 0.5 * (r[0] * s.rates[0][k] + r[1] * s.rates[1][k]))
                .collect();
            let w: Vec<f64> = (0..len)
                .map(|k| (r[0] * s.rates[0][k] - r[1] * s.rates[1][k]) / (2.0 * h))
                .collect();
            let ww: Vec<f64> = w.iter().map(|x| x * x).collect();
            let vw: Vec<f64> = v.iter().zip(&w).map(|(a, b)| a * b).collect();
            let band = opts.sign_band_radps;
            let sgn = |x: &Vec<f64>| -> Vec<f64> {
                x.iter().map(|&q| (q / band).clamp(-1.0, 1.0)).collect()
            };
            let (vd, wd) = (sg.derivative(&v, dt), sg.derivative(&w, dt));
            let (wws, vws) = (sg.smooth(&ww), sg.smooth(&vw));
            let rs = [sg.smooth(&s.rates[0]), sg.smooth(&s.rates[1])];
            let ss = [sg.smooth(&sgn(&s.rates[0])), sg.smooth(&sgn(&s.rates[1]))];
            let rhs = match form {
                Form::Voltage => [sg.smooth(&s.volts[0]), sg.smooth(&s.volts[1])],
                Form::Torque => [sg.smooth(&s.torque[0]), sg.smooth(&s.torque[1])],
            };
            for k in 0..vd.len() {
                // Rows within a filter window of a torque-limited tick are
                // left out of both forms: there the controller's torque
                // chatters against the limit, at frequencies where the
                // runtime's windowed wheel rate is no longer a delayed copy
                // of the true one (its 4-tick mean has a zero at 250 Hz),
                // and the back-EMF term κ·φ̇ is wrong. Measured on the
                // paper robot (seed 1): inertia −3.7 % with these rows,
                // +0.35 % without (D82).
                if s.saturated[k..=k + 2 * m].iter().any(|&b| b) {
                    saturated_rows += 1;
                    continue;
                }
                for i in 0..2 {
                    let sig = if i == 0 { 1.0 } else { -1.0 };
                    let mut row = [0.0; 7];
                    row[0] = 0.5 * r[i] * vd[k];
                    row[1] = sig * 0.5 * r[i] * wd[k] / h;
                    row[2] = r[i] * (sig * vws[k] / h - wws[k]);
                    row[3 + i] = rs[i][k];
                    row[5 + i] = ss[i][k];
                    phi_rows.push(row);
                    ys.push(rhs[i][k]);
                }
            }
        }
        let n = phi_rows.len();
        let phi = DMatrix::from_fn(n, 7, |i, j| phi_rows[i][j]);
        let y = DVector::from_column_slice(&ys);
        let name = match form {
            Form::Voltage => "dynamic fit (voltage form)",
            Form::Torque => "dynamic fit (torque form)",
        };
        // Two rows per instant: the correlation spans twice the window.
        let f = solve(&phi, &y, 2 * lags).map_err(|e| FitError::Lsq(name, e))?;
        // What the translational term explains of the right-hand side,
        // against what nothing explains (see `Dynamics::scale_snr`).
        let rms0 = (phi.column(0).iter().map(|x| x * x).sum::<f64>() / n.max(1) as f64).sqrt();
        let scale_snr = f.theta[0].abs() * rms0 / f.residual_rms;
        let iw = prior.robot.wheel_inertia_kgm2 as f64;
        let inv_r2 = 1.0 / (r[0] * r[0]) + 1.0 / (r[1] * r[1]);
        // The scale a: the prior motor's, or (voltage form, mass weighed)
        // the one that makes M_v = m + I_w·Σ1/r² of the weighed m. The
        // physical parameters are p = a·θ; with a = M_v/θ₀ their
        // covariance is J·C·Jᵀ, J = a·(1 − θ e₀ᵀ/θ₀) (p₀ = M_v exactly).
        let weighed = match (form, opts.mass_kg) {
            (Form::Voltage, Some(m)) => Some(m),
            _ => None,
        };
        // The weighed mass fixes the scale only when the run determined
        // M_v/a: an interval that contains 0 (a run that barely
        // accelerated the robot, most rows saturated against friction)
        // leaves a as the prior's, said in the notes (D218); a value
        // below 0 beyond its interval is a log no robot makes.
        let t0 = Estimate::new(f.theta[0], f.std_err[0]);
        let given = match weighed {
            Some(_) if !determined(&t0, scale_snr) => None,
            Some(_) if t0.value <= 0.0 => return Err(FitError::NoScale(t0.value)),
            Some(m) => Some(m + iw * inv_r2),
            None => None,
        };
        let (scale, jac) = match given {
            Some(mv) => {
                let t0 = f.theta[0];
                let a = mv / t0;
                let j = DMatrix::from_fn(7, 7, |i, k| {
                    (if i == k { a } else { 0.0 }) - if k == 0 { a * f.theta[i] / t0 } else { 0.0 }
                });
                (a, j)
            }
            None => {
                let a = match form {
                    Form::Voltage => prior.torque_per_volt(),
                    Form::Torque => 1.0,
                };
                (a, DMatrix::from_diagonal_element(7, 7, a))
            }
        };
        let cov = &jac * &f.cov * jac.transpose();
        let p: Vec<f64> = (0..7).map(|j| scale * f.theta[j]).collect();
        let est = |j: usize| Estimate::new(p[j], cov[(j, j)].max(0.0).sqrt());
        let torque_per_volt = match (form, given) {
            (Form::Torque, _) => Estimate::new(1.0, 0.0),
            (Form::Voltage, Some(mv)) => {
                let t0 = f.theta[0];
                Estimate::new(scale, mv * f.std_err[0] / (t0 * t0))
            }
            (Form::Voltage, None) => Estimate {
                value: scale,
                ci95: f64::INFINITY,
            },
        };
        let (mv, mw, md) = (p[0], p[1], p[2]);
        let mass = mv - iw * inv_r2;
        let d = md / mass;
        let inertia = mw - 3.0 * md * md / mass - iw * h * h * inv_r2;
        // Delta method over (M_v, M_ω, md).
        let c = |a: usize, b: usize| cov[(a, b)];
        let g_i = [3.0 * md * md / (mass * mass), 1.0, -6.0 * md / mass];
        let var_i: f64 = (0..3)
            .flat_map(|a| (0..3).map(move |b| (a, b)))
            .map(|(a, b)| g_i[a] * g_i[b] * c(a, b))
            .sum();
        let g_d = [-md / (mass * mass), 0.0, 1.0 / mass];
        let var_d: f64 = (0..3)
            .flat_map(|a| (0..3).map(move |b| (a, b)))
            .map(|(a, b)| g_d[a] * g_d[b] * c(a, b))
            .sum();
        let (viscous, emf) = match form {
            Form::Voltage => {
                let nk = prior.emf_per_wheel_rate();
                let a = scale;
                (
                    [0, 1].map(|i| Estimate::new(a * (f.theta[3 + i] - nk), a * f.std_err[3 + i])),
                    Some([0, 1].map(|i| Estimate::new(f.theta[3 + i], f.std_err[3 + i]))),
                )
            }
            Form::Torque => ([est(3), est(4)], None),
        };
        Ok(Dynamics {
            form,
            mass_kg: Estimate::new(mass, cov[(0, 0)].max(0.0).sqrt()),
            inertia_kgm2: Estimate::new(inertia, var_i.max(0.0).sqrt()),
            com_offset_m: Estimate::new(d, var_d.max(0.0).sqrt()),
            m1: [est(0), est(1)],
            coulomb_nm: [est(5), est(6)],
            viscous_nms_per_rad: viscous,
            emf_vs_per_rad: emf,
            duty_sign,
            torque_per_volt,
            weighed_mass_kg: weighed,
            saturated_rows,
            scale_term: t0,
            scale_snr,
            names: match form {
                Form::Voltage => [
                    "M_v/a", "M_w/a", "md/a", "kappa_R", "kappa_L", "gamma_R", "gamma_L",
                ],
                Form::Torque => ["M_v", "M_w", "md", "c_v,R", "c_v,L", "c_c,R", "c_c,L"],
            },
            residual_unit: match form {
                Form::Voltage => "V",
                Form::Torque => "N·m",
            },
            lsq: f,
        })
    };
    let torque = dyn_fit(Form::Torque);
    let (dynamics, torque_check) = if has_duty {
        (Some(dyn_fit(Form::Voltage)?), torque.ok())
    } else {
        notes.push(
            "no duties in the log: the torque form only (the prior motor model is trusted; \
             the motor is not identified)"
                .into(),
        );
        (Some(torque?), None)
    };
    let fitted_rows = dynamics.as_ref().map_or(0, |d| d.lsq.rows / 2);
    if let Some(d) = &dynamics {
        richness_notes(d, opts, &mut notes);
    }
    if has_duty {
        if let Some(d) = &dynamics {
            notes.push(scale_note(d, prior));
        }
        notes.push(format!(
            "motor: κ = N·k + c_v/a per wheel (the back-EMF constant and viscous friction share the regressor φ̇); \
             the prior's N·k = {:.4} V·s/rad; viscous friction is reported as a·(κ − N·k)",
            prior.emf_per_wheel_rate()
        ));
    }
    Ok(Identification {
        rows: rows.len(),
        fitted_rows,
        rate_hz: 1.0 / dt,
        duration_s,
        external_pose_rows,
        wheel_radius_m,
        half_track_m,
        track_from_prior: !with_poses,
        yaw_offset_radps: yaw_offset,
        yaw_residual_rad: yaw_res,
        displacement_residual_m: speed_res,
        dynamics,
        torque_check,
        notes,
    })
}

/// What the voltage form's scale is: from the weighed mass (the motor's
/// torque per volt identified), or the prior's, with what the log did
/// identify (ratios to a, and ratios free of it) and what it did not.
fn scale_note(d: &Dynamics, prior: &Prior) -> String {
    let a = d.torque_per_volt;
    let a0 = prior.torque_per_volt();
    if d.mass_given() {
        return format!(
            "scale: the weighed mass m = {:.4} kg (--mass-kg, taken as exact) fixes the scale the log cannot see: \
             the motor's torque per volt a = η_g·N·k/R is identified, {:.5} ± {:.5} N·m/V ({:+.1} % from the prior's {a0:.5}); \
             inertia and friction are in N·m from it (their intervals include a's)",
            d.mass_kg.value,
            a.value,
            a.ci95,
            100.0 * (a.value / a0 - 1.0)
        );
    }
    if let Some(m) = d.weighed_mass_kg {
        return format!(
            "scale NOT identified although the robot was weighed: the run's translational term M_v/a = {:.4} \
             (explaining {:.2} of the residual's RMS) is not determined, so the weighed m = {m:.4} kg cannot fix the motor's torque per volt \
             a = η_g·N·k/R: a is the prior's ({a0:.5} N·m/V), the weighed mass is written, and every value the run \
             did not determine keeps the prior's. The run barely accelerated the robot along its heading ({} of {} \
             rows fitted: rows at the torque limit are left out); a robot whose friction takes most of its torque \
             limit needs a slower excitation (`wmr identify run --v-amp`, `--w-amp` lower) or a higher \
             limits.torque_nm if its driver allows",
            d.scale_term,
            d.scale_snr,
            d.lsq.rows / 2,
            d.lsq.rows / 2 + d.saturated_rows,
        );
    }
    // Ratios the log determines whatever a is.
    let th = &d.lsq.theta;
    let se = &d.lsq.std_err;
    let ratio = |j: usize| Estimate::new(th[j], se[j]);
    let i_over_m = d.inertia_kgm2.value / d.mass_kg.value;
    let c_over_m = [0, 1].map(|i| d.coulomb_nm[i].value / d.mass_kg.value);
    format!(
        "scale NOT identified: duties and motion fix only ratios to the motor's torque per volt a = η_g·N·k/R. \
         Identified: M_v/a = {:.3} kg per N·m/V (M_v = m + I_w·Σ1/r²), M_ω/a = {:.4} kg·m² per N·m/V, \
         Coulomb friction/a = {:.4} V (right), {:.4} V (left); free of a: I/m = {:.6} m², \
         Coulomb friction/m = {:.5}, {:.5} N·m/kg. Not identified: a itself, taken from the prior ({a0:.5} N·m/V \
         from the file's η_g, N, k, R): the mass {:.4} kg, inertia {:.6} kg·m² and friction {:.4}/{:.4} N·m are that a \
         times the ratios, and an error of x % in a is x % in each of them. Weigh the robot and give --mass-kg: \
         then a is identified",
        ratio(0),
        ratio(1),
        ratio(5),
        ratio(6),
        i_over_m,
        c_over_m[0],
        c_over_m[1],
        d.mass_kg.value,
        d.inertia_kgm2.value,
        d.coulomb_nm[0].value,
        d.coulomb_nm[1].value,
    )
}

/// The richness check: condition number, parameters the run did not
/// determine, and the least-determined combination.
fn richness_notes(d: &Dynamics, opts: &FitOptions, notes: &mut Vec<String>) {
    let f = &d.lsq;
    if !d.translation_determined() {
        notes.push(format!(
            "the translational term {} = {} is not determined (it explains {:.2} of the residual's RMS; \
             at least 1 is needed): the run barely accelerated the robot along its heading ({} instants \
             fitted, {} left out at the torque limit), so the mass and d keep the prior's (D218)",
            d.names[0],
            d.scale_term,
            d.scale_snr,
            f.rows / 2,
            d.saturated_rows
        ));
    }
    if f.condition > 1e3 {
        let combo: Vec<String> = f
            .weakest
            .iter()
            .zip(d.names)
            .filter(|(w, _)| w.abs() > 0.3)
            .map(|(w, n)| format!("{w:+.2}·{n}"))
            .collect();
        notes.push(format!(
            "richness: condition number {:.3e} of the column-scaled regressor (> 1e3): the run does not \
             separate {} — excite v̇, ω̇, v, ω and sign(v) independently",
            f.condition,
            combo.join(" ")
        ));
    }
    // The fitted quantities, then the physical ones derived from them (a
    // small difference of two well-determined numbers, such as the viscous
    // friction a·(κ − N·k), can be undetermined while both are not).
    let derived = [
        ("mass", d.mass_kg),
        ("inertia", d.inertia_kgm2),
        ("CoM offset d", d.com_offset_m),
        ("Coulomb friction right", d.coulomb_nm[0]),
        ("Coulomb friction left", d.coulomb_nm[1]),
        ("viscous friction right", d.viscous_nms_per_rad[0]),
        ("viscous friction left", d.viscous_nms_per_rad[1]),
    ];
    let fitted = d
        .names
        .iter()
        .enumerate()
        .map(|(j, n)| (*n, Estimate::new(f.theta[j], f.std_err[j])));
    for (name, e) in fitted.chain(derived) {
        if e.consistent_with_zero() {
            notes.push(format!(
                "{name} = {e:.4}: not distinguishable from zero in this run (a term this small \
                 cannot be identified; it may be absent)"
            ));
        } else if e.relative_ci() > opts.max_relative_ci {
            notes.push(format!(
                "{name} = {e:.4}: poorly identified (95 % interval {:.0} % of the value)",
                100.0 * e.relative_ci()
            ));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows(n: usize) -> Vec<IdRow> {
        (0..n)
            .map(|k| IdRow {
                t_s: k as f64 * 1e-3,
                ..IdRow::default()
            })
            .collect()
    }

    /// Bad logs are refused with the row and the reason, never a panic.
    #[test]
    fn bad_logs_are_refused_clearly() {
        let (p, o) = (Prior::paper(), FitOptions::default());
        let e = identify(&rows(50), &p, &o).unwrap_err().to_string();
        assert!(e.contains("50 rows"), "{e}");
        let mut r = rows(500);
        r[7].pose[2] = f64::NAN;
        let e = identify(&r, &p, &o).unwrap_err().to_string();
        assert!(e.contains("row 8") && e.contains("not finite"), "{e}");
        let mut r = rows(500);
        r[9].t_s = r[8].t_s;
        let e = identify(&r, &p, &o).unwrap_err().to_string();
        assert!(
            e.contains("row 10") && e.contains("does not increase"),
            "{e}"
        );
        // At rest the whole run: nothing is excited.
        let e = identify(&rows(20_000), &p, &o).unwrap_err().to_string();
        assert!(e.contains("not excited") || e.contains("zero"), "{e}");
    }

    /// A weighed mass the robot file would refuse is refused with the file's
    /// own limits (the parameter table's `body.mass_kg`: 0.1-500 kg), the
    /// value and what to do; a plausible one passes the check.
    #[test]
    fn a_weighed_mass_outside_the_files_range_is_refused() {
        let p = Prior::paper();
        for (m, limit) in [(0.02, "0.1 kg"), (-1.0, "0.1 kg"), (2000.0, "500 kg")] {
            let o = FitOptions {
                mass_kg: Some(m),
                ..FitOptions::default()
            };
            let e = identify(&rows(500), &p, &o).unwrap_err();
            assert!(matches!(e, FitError::BadMass(_)), "{e:?}");
            let s = e.to_string();
            assert!(
                s.starts_with("--mass-kg: ") && s.contains(&format!("{m} kg")) && s.contains(limit),
                "{s}"
            );
            assert!(s.contains("set a value in [0.1, 500] kg"), "{s}");
        }
        let o = FitOptions {
            mass_kg: Some(f64::NAN),
            ..FitOptions::default()
        };
        let e = identify(&rows(500), &p, &o).unwrap_err().to_string();
        assert!(e.contains("not a finite number"), "{e}");
        // 0.85 kg (the light example robot) passes the mass check and fails
        // only for the log (all at rest).
        let o = FitOptions {
            mass_kg: Some(0.85),
            ..FitOptions::default()
        };
        let e = identify(&rows(20_000), &p, &o).unwrap_err();
        assert!(!matches!(e, FitError::BadMass(_)), "{e:?}");
    }
}
