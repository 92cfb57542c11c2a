//! Bounds on what a run may ask for: values that pass [`Scenario::validate`]
//! (finite, positive) but make no physical sense or would run for hours or
//! allocate terabytes (issue 21 item 7). Every bound is here, with its reason;
//! this is the only file outside the scenario's own that names its fields.
//! The CLI calls [`check_scenario`] once per subcommand, and the checks of its
//! own values ([`check_device_for_s`], [`check_csv`]).

use crate::scenario::Scenario;
use crate::sim::TraceSample;

/// Longest run [s] of robot time: a day (the paper's run is 40 s).
pub const MAX_DURATION_S: f64 = 86_400.0;
/// Shortest control period [s]: 100 kHz, ten times the fastest motor
/// current loops; the firmware runs at 1 kHz.
pub const MIN_CONTROL_PERIOD_S: f64 = 1e-5;
/// Most RK4 sub-steps per control period (the default is 4).
pub const MAX_SUBSTEPS: u32 = 10_000;
/// Most plant steps of one run (control steps x sub-steps): about 4 minutes
/// at the ~200 ns a plant step costs on the reference machine (BENCHMARKS.md).
pub const MAX_PLANT_STEPS: f64 = 1e9;
/// Largest per-wheel torque limit [N·m]: 10x the paper's 10 N·m, already
/// 2 kN at the paper's 5 cm wheel radius on a 10 kg robot.
pub const MAX_TORQUE_LIMIT_NM: f64 = 100.0;
/// Bits of an f32's significand after the leading one: the spacing of f32
/// values in [2^k, 2^(k+1)) is 2^(k − 23).
const F32_FRACTION_BITS: i32 = 23;

/// Largest disturbance amplitude, as a fraction of the robot's torque
/// limit: beyond half of it a controller cannot both reject it and track
/// (the paper's 1 N·m is 10 % of its 10 N·m; tune and sweep use
/// [`crate::sweep::DISTURBANCE_FRACTION`] of the robot's limit).
pub const MAX_DISTURBANCE_FRACTION: f64 = 0.5;

/// The scenario's reference and disturbance within what its robot can do
/// (issue 32: a 0.5 m/s robot was run on the paper's 2 m/s curve and the
/// run printed only a count of rejected steps). The reference is sampled
/// every control period over the run and each sample checked as the device
/// checks a trajectory it is given (wmr-device `RobotLimits::check_sample`:
/// the robot's top speed, yaw rate and acceleration from its motors and
/// torque limit); the disturbance against [`MAX_DISTURBANCE_FRACTION`] of
/// the torque limit. The first excess, with its numbers and what to do.
pub fn check_within_robot(s: &Scenario) -> Result<(), String> {
    use controller_core::trajectory::Trajectory;
    let name = &s.name;
    let rt = s.derive(controller_core::ControllerKind::Proposed).runtime;
    let lim = wmr_device::limits::RobotLimits::of(&rt);
    let reference = s.trajectory.reference();
    let dt = s.control_period_s.max(1e-3);
    let n = (s.duration_s / dt).ceil() as u64;
    // The worst sample (largest excess over its limit), not the first:
    // the message gives the trajectory's peak.
    let mut worst: Option<(f32, f64, wmr_device::limits::LimitExceeded)> = None;
    for i in 0..=n {
        let t_s = (i as f64 * dt).min(s.duration_s);
        let r = reference.sample(t_s as f32);
        if let Err(e) = lim.check_sample(&r, false) {
            let excess = e.value.abs() / e.limit;
            if worst
                .as_ref()
                .is_none_or(|w| excess > w.0 || excess.is_nan())
            {
                worst = Some((excess, t_s, e));
            }
        }
    }
    if let Some((_, t_s, e)) = worst {
        let (what, unit) = e.quantity.describe();
        return Err(format!(
            "scenario '{name}': the {:?} trajectory needs a {what} of {:.2} {unit} (at t = {t_s:.2} s); robot '{}' reaches at most {:.2} {unit} (its motors at the supply voltage and its torque limit {} N·m). Choose a trajectory within the robot (--trajectory circle or line: 0.5 m/s), or run it on a robot that can",
            s.trajectory,
            e.value.abs(),
            s.robot.name,
            e.limit,
            num(f64::from(rt.controller.torque_limit_nm)),
        ));
    }
    let limit = s.torque_limit_nm();
    let d = s.perturbations.disturbance_nm;
    if d > MAX_DISTURBANCE_FRACTION * limit {
        return Err(format!(
            "scenario '{name}': the disturbance amplitude {} N·m is {:.1}x robot '{}''s torque limit {} N·m (at most {MAX_DISTURBANCE_FRACTION} of it): give --disturbance {} (the {}% tune and sweep use) or less",
            num(d),
            d / limit,
            s.robot.name,
            num(limit),
            num(crate::sweep::DISTURBANCE_FRACTION * limit),
            crate::sweep::DISTURBANCE_FRACTION * 100.0,
        ));
    }
    Ok(())
}

/// Largest |x|, |y| of the initial pose [m] for a robot whose encoder
/// resolves `count_m` metres of wheel travel per count: the runtime and the
/// controllers hold the pose in f32 (controller-core), and where the f32
/// spacing exceeds one count of travel, single counts are rounded out of
/// the odometry and the position error is quantised coarser than the
/// robot can measure. The bound is the largest power of two 2^(k+1) with
/// spacing 2^(k − 23) ≤ `count_m` below it: 256 m for the example encoder
/// on the paper's wheel (24,000 counts per revolution of a 0.1 m wheel,
/// 26 µm per count); a coarser encoder allows more.
pub fn max_initial_position_m(count_m: f64) -> f64 {
    let k = count_m.log2().floor() as i32 + F32_FRACTION_BITS;
    2f64.powi(k + 1)
}
/// Largest |θ| of the initial pose [rad] (about 16 turns).
pub const MAX_INITIAL_HEADING_RAD: f64 = 100.0;
/// Largest CSV a run writes without `--force` [bytes] (estimated).
pub const MAX_CSV_BYTES: f64 = 1e9;
/// Largest trace a run keeps in memory even with `--force` [bytes]: the
/// trace is held whole before it is written.
pub const MAX_TRACE_MEMORY_BYTES: f64 = 8e9;
/// At most this many characters per CSV value (an f64's shortest round-trip
/// form is at most 24 characters) plus its separator.
const MAX_CSV_VALUE_BYTES: f64 = 25.0;

/// The scenario's physical and computational bounds (beyond
/// [`Scenario::validate`]); the error names the field, the value and the bound.
pub fn check_scenario(s: &Scenario) -> Result<(), String> {
    let name = &s.name;
    if !(0.0..=MAX_DURATION_S).contains(&s.duration_s) {
        return Err(format!(
            "scenario '{name}': duration_s = {} s is beyond the {MAX_DURATION_S} s (one day) limit",
            num(s.duration_s)
        ));
    }
    if !(MIN_CONTROL_PERIOD_S..=f64::MAX).contains(&s.control_period_s) {
        return Err(format!(
            "scenario '{name}': control_period_s = {} s is below the {} s (100 kHz) limit",
            num(s.control_period_s),
            num(MIN_CONTROL_PERIOD_S)
        ));
    }
    if s.substeps > MAX_SUBSTEPS {
        return Err(format!(
            "scenario '{name}': substeps = {} is beyond the {MAX_SUBSTEPS} limit",
            s.substeps
        ));
    }
    let steps = plant_steps(s);
    if !(0.0..=MAX_PLANT_STEPS).contains(&steps) {
        return Err(format!(
            "scenario '{name}': duration_s / control_period_s x substeps = {steps:.3e} plant steps, beyond the {MAX_PLANT_STEPS:.0e} limit (minutes of computing per 1e9)"
        ));
    }
    if !(0.0..=MAX_TORQUE_LIMIT_NM).contains(&s.torque_limit_nm()) {
        return Err(format!(
            "scenario '{name}': torque_limit_nm = {} N·m is beyond the {MAX_TORQUE_LIMIT_NM} N·m limit",
            num(s.torque_limit_nm())
        ));
    }
    let [x, y, th] = s.initial_pose;
    let radius_m = f64::from(
        s.controller_config(controller_core::ControllerKind::Proposed)
            .robot
            .wheel_radius_m,
    );
    let count_m = std::f64::consts::TAU * radius_m / f64::from(s.encoder().counts_per_wheel_rev);
    let max_m = max_initial_position_m(count_m);
    let within = |v: f64| (0.0..max_m).contains(&v.abs());
    if !(within(x) && within(y)) {
        return Err(format!(
            "scenario '{name}': initial_pose position ({}, {}) m is beyond ±{max_m} m, where the runtime's f32 pose no longer resolves one encoder count ({:.1} µm)",
            num(x),
            num(y),
            count_m * 1e6
        ));
    }
    if !(0.0..=MAX_INITIAL_HEADING_RAD).contains(&th.abs()) {
        return Err(format!(
            "scenario '{name}': initial_pose heading {} rad is beyond ±{MAX_INITIAL_HEADING_RAD} rad",
            num(th)
        ));
    }
    Ok(())
}

/// A value as a person reads it: plain in [1e-3, 1e6), else with an exponent.
fn num(v: f64) -> String {
    // Six significant digits: an f32 value widened to f64 (0.12 N·m read
    // as 0.11999999731779099) prints as the user wrote it.
    let v = format!("{v:.5e}").parse::<f64>().unwrap_or(v);
    if v == 0.0 || !v.is_finite() || (1e-3..1e6).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// Plant steps of a run: control steps x RK4 sub-steps.
pub fn plant_steps(s: &Scenario) -> f64 {
    s.duration_s / s.control_period_s * f64::from(s.substeps)
}

/// `device --for-s`: robot time [s] in (0, one day].
pub fn check_device_for_s(for_s: f64) -> Result<(), String> {
    if for_s.is_finite() && for_s > 0.0 && for_s <= MAX_DURATION_S {
        Ok(())
    } else {
        Err(format!(
            "--for-s must be in (0, {MAX_DURATION_S}] s of robot time (got {})",
            num(for_s)
        ))
    }
}

/// The size of `run --csv` before the run: rows, at most this many bytes of
/// CSV, this many bytes of trace in memory.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CsvEstimate {
    /// Rows the trace will hold.
    pub rows: f64,
    /// Upper bound of the file size [bytes].
    pub csv_bytes: f64,
    /// The trace in memory [bytes].
    pub memory_bytes: f64,
}

/// Estimates `run --csv` for one row every `every` control steps; refuses
/// above [`MAX_CSV_BYTES`] unless `force`, and above
/// [`MAX_TRACE_MEMORY_BYTES`] in any case.
pub fn check_csv(s: &Scenario, every: usize, force: bool) -> Result<CsvEstimate, String> {
    let rows = (s.duration_s / s.control_period_s / every.max(1) as f64).ceil() + 1.0;
    let columns = crate::report::CSV_HEADER.split(',').count() as f64;
    let e = CsvEstimate {
        rows,
        csv_bytes: rows * columns * MAX_CSV_VALUE_BYTES,
        memory_bytes: rows * std::mem::size_of::<TraceSample>() as f64,
    };
    if e.memory_bytes > MAX_TRACE_MEMORY_BYTES {
        return Err(format!(
            "--csv: {:.3e} rows would hold {:.1} GB of trace in memory, beyond the {:.0} GB limit even with --force: shorten --duration or raise --csv-every",
            e.rows,
            e.memory_bytes / 1e9,
            MAX_TRACE_MEMORY_BYTES / 1e9
        ));
    }
    if e.csv_bytes > MAX_CSV_BYTES && !force {
        return Err(format!(
            "--csv: {:.3e} rows, up to {:.1} GB, beyond the {:.0} GB limit: raise --csv-every, shorten --duration, or pass --force",
            e.rows,
            e.csv_bytes / 1e9,
            MAX_CSV_BYTES / 1e9
        ));
    }
    Ok(e)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paper() -> Scenario {
        Scenario::paper_case(2, 1, None, None)
    }

    /// The position bound against f32 itself: below the bound one count of
    /// travel added to the position changes it; at the bound's f32 spacing
    /// doubled it would be rounded away.
    #[test]
    fn initial_position_bound_resolves_one_count() {
        let count_m = std::f64::consts::TAU * 0.1 / 24_000.0;
        let max_m = max_initial_position_m(count_m);
        assert_eq!(max_m, 256.0);
        let below = (max_m as f32).next_down();
        assert_ne!(
            below + count_m as f32,
            below,
            "one count lost below the bound"
        );
        // Past the bound (spacing 2^-15 m = 30.5 µm > 26 µm) a count is rounded to
        // the next f32 value or lost: never resolved exactly.
        let above = 2.0 * max_m as f32;
        let moved = f64::from((above + count_m as f32) - above);
        assert!((moved - count_m).abs() > 0.1 * count_m, "moved {moved}");
        let mut s = paper();
        s.initial_pose = [255.0, -255.0, 0.0];
        check_scenario(&s).unwrap();
        s.initial_pose = [256.0, 0.0, 0.0];
        assert!(
            check_scenario(&s).unwrap_err().contains("26.2 µm"),
            "{}",
            check_scenario(&s).unwrap_err()
        );
        s.sensing.preset = crate::scenario::Sensing::Odometry;
        s.sensing.encoder_cpr = 1024;
        check_scenario(&s).unwrap();
    }

    /// The values of issue 21 item 7 are refused, each with its field named;
    /// the paper's scenario passes.
    #[test]
    fn absurd_values_are_refused_by_name() {
        check_scenario(&paper()).unwrap();
        type Case = (fn(&mut Scenario), &'static str);
        let cases: [Case; 7] = [
            (|s| s.duration_s = 1e9, "duration_s"),
            (|s| s.control_period_s = 1e-9, "control_period_s"),
            (|s| s.substeps = 4_000_000_000, "substeps"),
            (|s| s.plant.torque_limit_nm = Some(1e30), "torque_limit_nm"),
            (|s| s.initial_pose = [1e308, 0.0, 0.0], "initial_pose"),
            (|s| s.initial_pose = [0.0, -256.0, 0.0], "initial_pose"),
            (
                |s| {
                    s.duration_s = 80_000.0;
                    s.control_period_s = 2e-5;
                }, // 4e9 control steps
                "plant steps",
            ),
        ];
        for (set, field) in cases {
            let mut s = paper();
            set(&mut s);
            let e = check_scenario(&s).unwrap_err();
            assert!(e.contains(field), "{field}: {e}");
        }
        for bad in [f64::NAN, -5.0, 0.0, 1e12] {
            assert!(check_device_for_s(bad).unwrap_err().contains("--for-s"));
        }
        check_device_for_s(20.0).unwrap();
    }

    /// The CSV estimate bounds the file a real run writes, and refuses the
    /// 1e9 s run of issue 21 item 7 (25.6 TB of trace) even with --force.
    #[test]
    fn csv_estimate_bounds_the_real_file() {
        let s = Scenario {
            duration_s: 1.0,
            ..paper()
        };
        let every = 10;
        let est = check_csv(&s, every, false).unwrap();
        let cfg = crate::sim::controller_config(&s, controller_core::ControllerKind::Smc);
        let out = crate::sim::run_with(&s, cfg, every).unwrap();
        let mut buf = Vec::new();
        crate::report::write_trace_csv(&mut buf, &out.trace).unwrap();
        assert!(
            out.trace.len() as f64 <= est.rows,
            "{} rows",
            out.trace.len()
        );
        assert!(buf.len() as f64 <= est.csv_bytes, "{} bytes", buf.len());
        let huge = Scenario {
            duration_s: 1e9,
            ..paper()
        };
        assert!(check_csv(&huge, 10, true).unwrap_err().contains("memory"));
        let big = Scenario {
            duration_s: 40_000.0,
            ..paper()
        };
        assert!(check_csv(&big, 10, false).unwrap_err().contains("--force"));
        check_csv(&big, 10, true).unwrap();
    }
}
