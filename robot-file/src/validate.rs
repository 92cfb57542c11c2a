//! [`Robot::validate`]: every field against its physical range (the
//! parameter table, controller-core `param_table`: the ranges the device
//! and the ROS bridge check, D144), then the fields against each other,
//! then the gains through controller-core's own validation. Ranges and
//! their reasons: book/src/how-to/robot-file.md, book/src/reference/parameters.md.

use crate::derive::CONTROL_PERIOD_S;
use crate::error::{Reason, RobotError};
use crate::sections::{GainSet, Robot, SwitchingGain, FORMAT};
use controller_core::runtime::param_table::{self as table, Param, RobotBounds};
use controller_core::ControllerKind;

/// Timer clocks of the supported boards' PWM timers \[Hz\] (STM32F411 at
/// 96 MHz, STM32F405 at 168 MHz): a PWM frequency must give 100..=65,535
/// duty levels on each.
pub const SUPPORTED_TIMER_CLOCKS_HZ: [u32; 2] = [96_000_000, 168_000_000];

/// Largest relative difference of the two wheel radii (10 %).
pub const MAX_WHEEL_RADIUS_MISMATCH: f32 = 0.1;

/// Every leaf field of a robot file with every gain section present (SMC
/// with a fixed switching gain, ASMC and proposed adaptive), by TOML path,
/// in validation order. A test checks it against the serialized form, so a
/// new field cannot be left out of the field-by-field tests.
pub const FIELDS: &[&str] = &[
    "name",
    "format",
    "body.mass_kg",
    "body.inertia_kgm2",
    "body.wheel_inertia_kgm2",
    "body.com_offset_m",
    "body.wheel_radius_m[0]",
    "body.wheel_radius_m[1]",
    "body.track_m",
    "motors.torque_constant_nm_per_a",
    "motors.resistance_ohm",
    "motors.gear_ratio",
    "motors.gear_efficiency",
    "motors.supply_voltage_v",
    "motors.viscous_friction_nms_per_rad[0]",
    "motors.viscous_friction_nms_per_rad[1]",
    "motors.coulomb_friction_nm[0]",
    "motors.coulomb_friction_nm[1]",
    "encoders.counts_per_wheel_rev",
    "encoders.inverted[0]",
    "encoders.inverted[1]",
    "encoders.speed_window_ticks",
    "bridge.mode",
    "bridge.pwm_frequency_hz",
    "bridge.idle",
    "bridge.max_duty_fraction",
    "bridge.motor_inverted[0]",
    "bridge.motor_inverted[1]",
    "imu.yaw_axis",
    "limits.torque_nm",
    "limits.max_speed_mps",
    "limits.max_yaw_rate_radps",
    "limits.max_accel_mps2",
    "limits.link_timeout_ms",
    "control.controller",
    "control.clean_start",
    "control.governor",
    "control.initial_x_m",
    "control.initial_y_m",
    "control.initial_heading_rad",
    "estimator.gyro_noise_density",
    "estimator.gyro_bias_walk",
    "estimator.speed_noise_mps_per_sqrt_hz",
    "estimator.slip_fraction",
    "estimator.wheel_yaw_noise",
    // gains.<kind>.*: GAIN_FIELDS under each kind (`field_paths`).
];

macro_rules! gain_path {
    ($kind:expr, $p:literal) => {
        match $kind {
            ControllerKind::Proposed => concat!("gains.proposed.", $p),
            ControllerKind::Smc => concat!("gains.smc.", $p),
            ControllerKind::Asmc => concat!("gains.asmc.", $p),
        }
    };
}

/// The gain fields of one section, relative to `gains.<kind>.`.
pub const GAIN_FIELDS: &[&str] = &[
    "kinematic.k_x",
    "kinematic.k_y",
    "kinematic.k_th",
    "kinematic.large_error_m",
    "kinematic.printed_2ey_term",
    "observer.l_v",
    "observer.l_omega",
    "observer.max_estimate[0]",
    "observer.max_estimate[1]",
    "eso.lambda[0]",
    "eso.lambda[1]",
    "eso.lambda[2]",
    "eso.zeta",
    "eso.alpha",
    "eso.max_disturbance[0]",
    "eso.max_disturbance[1]",
    "sliding.k_s",
    "sliding.switching.fixed.k",
    "sliding.switching.adaptive.gamma",
    "sliding.switching.adaptive.dead_zone",
    "sliding.switching.adaptive.leakage",
    "sliding.switching.adaptive.rho0",
    "sliding.switching.adaptive.rho_min",
    "sliding.switching.adaptive.rho_max",
];

/// Largest gain accepted (any unit): beyond it a 1 kHz discrete loop is
/// far past stability; tuning stays well inside.
pub use controller_core::runtime::param_table::MAX_GAIN;

/// Checks field `field` (parameter `p`, or an element of it) against its
/// range in the parameter table for the robot `b`.
fn check(p: &Param, field: &'static str, x: f32, b: &RobotBounds) -> Result<(), RobotError> {
    if !x.is_finite() {
        return Err(RobotError::new(field, Reason::NotFinite));
    }
    p.check_as(field, x, b)
        .map_err(|e| RobotError::new(field, Reason::Range(e)))
}

/// `Ok` when `ok`, else [`Reason::Exceeds`]: `field` is `value` (in
/// `unit`), beyond `limit` computed from `with`; `why` says the rule and
/// what to do.
fn bounded(
    ok: bool,
    field: &'static str,
    (value, limit, unit): (f32, f32, &'static str),
    with: &'static str,
    why: &'static str,
) -> Result<(), RobotError> {
    if ok {
        Ok(())
    } else {
        Err(RobotError::new(
            field,
            Reason::Exceeds {
                value,
                limit,
                unit,
                with,
                why,
            },
        ))
    }
}

fn consistent(
    ok: bool,
    field: &'static str,
    with: &'static str,
    why: &'static str,
) -> Result<(), RobotError> {
    if ok {
        Ok(())
    } else {
        Err(RobotError::new(field, Reason::Inconsistent { with, why }))
    }
}

impl Robot {
    /// Checks every field against its physical range, the fields against
    /// each other and the gains of each controller (controller-core's own
    /// validation of the configuration built from them). The error names
    /// the first field refused, by its TOML path, and why.
    pub fn validate(&self) -> Result<(), RobotError> {
        self.validate_ranges()?;
        self.validate_consistency()?;
        self.validate_control()?;
        let b = self.bounds();
        for kind in ControllerKind::ALL {
            if let Some(g) = self.gains.of(kind) {
                validate_gains(kind, g, &b)?;
            }
            self.controller_config(kind)
                .validate()
                .map_err(|e| RobotError::new(gain_section(kind), Reason::Controller(e)))?;
        }
        Ok(())
    }

    /// The numbers of the parameter table's robot-dependent bounds for
    /// this robot (its stall torque, top speed and yaw rate at the mean
    /// wheel radius, the control rate), by the formulas the device uses
    /// (wmr-device `RobotLimits::bounds`): a file the device would refuse
    /// at boot is refused here (issue 31 item 3).
    pub fn bounds(&self) -> RobotBounds {
        RobotBounds::of(
            self.stall_torque_nm(),
            self.no_load_wheel_speed_radps() * self.mean_wheel_radius_m(),
            0.5 * self.body.track_m,
            CONTROL_PERIOD_S,
        )
    }

    /// `[control]` and `[estimator]`: the start pose and the sensors'
    /// noises through the parameter table
    /// (`control.initial_*`: within 1 km of the origin, the heading within
    /// ±π).
    fn validate_control(&self) -> Result<(), RobotError> {
        let c = &self.control;
        let ab = RobotBounds::ABSOLUTE;
        check(
            &table::CONTROL_INITIAL_X_M,
            "control.initial_x_m",
            c.initial_x_m,
            &ab,
        )?;
        check(
            &table::CONTROL_INITIAL_Y_M,
            "control.initial_y_m",
            c.initial_y_m,
            &ab,
        )?;
        check(
            &table::CONTROL_INITIAL_HEADING_RAD,
            "control.initial_heading_rad",
            c.initial_heading_rad,
            &ab,
        )?;
        let e = &self.estimator;
        let fields: [(&Param, &'static str, f32); 5] = [
            (
                &table::ESTIMATOR_GYRO_NOISE_DENSITY,
                "estimator.gyro_noise_density",
                e.gyro_noise_density,
            ),
            (
                &table::ESTIMATOR_GYRO_BIAS_WALK,
                "estimator.gyro_bias_walk",
                e.gyro_bias_walk,
            ),
            (
                &table::ESTIMATOR_SPEED_NOISE,
                "estimator.speed_noise_mps_per_sqrt_hz",
                e.speed_noise_mps_per_sqrt_hz,
            ),
            (
                &table::ESTIMATOR_SLIP_FRACTION,
                "estimator.slip_fraction",
                e.slip_fraction,
            ),
            (
                &table::ESTIMATOR_WHEEL_YAW_NOISE,
                "estimator.wheel_yaw_noise",
                e.wheel_yaw_noise,
            ),
        ];
        for (p, field, x) in fields {
            check(p, field, x, &ab)?;
        }
        Ok(())
    }

    fn validate_ranges(&self) -> Result<(), RobotError> {
        let n = self.name.len() as f32;
        if n < 1.0 {
            return Err(RobotError::new(
                "name",
                Reason::OutOfRange {
                    value: n,
                    min: 1.0,
                    max: crate::NAME_MAX_LEN as f32,
                    unit: "bytes",
                },
            ));
        }
        if self.format != FORMAT {
            return Err(RobotError::new(
                "format",
                Reason::UnsupportedFormat { found: self.format },
            ));
        }
        // Ranges that depend on no robot first (in file order), then
        // [limits] against the robot they bound.
        let ab = RobotBounds::ABSOLUTE;
        let b = &self.body;
        let m = &self.motors;
        let e = &self.encoders;
        let br = &self.bridge;
        let fields: [(&Param, &'static str, f32); 20] = [
            (&table::BODY_MASS_KG, "body.mass_kg", b.mass_kg),
            (
                &table::BODY_INERTIA_KGM2,
                "body.inertia_kgm2",
                b.inertia_kgm2,
            ),
            (
                &table::BODY_WHEEL_INERTIA_KGM2,
                "body.wheel_inertia_kgm2",
                b.wheel_inertia_kgm2,
            ),
            (
                &table::BODY_COM_OFFSET_M,
                "body.com_offset_m",
                b.com_offset_m,
            ),
            (
                &table::BODY_WHEEL_RADIUS_M,
                "body.wheel_radius_m[0]",
                b.wheel_radius_m[0],
            ),
            (
                &table::BODY_WHEEL_RADIUS_M,
                "body.wheel_radius_m[1]",
                b.wheel_radius_m[1],
            ),
            (&table::BODY_TRACK_M, "body.track_m", b.track_m),
            (
                &table::MOTORS_TORQUE_CONSTANT,
                "motors.torque_constant_nm_per_a",
                m.torque_constant_nm_per_a,
            ),
            (
                &table::MOTORS_RESISTANCE_OHM,
                "motors.resistance_ohm",
                m.resistance_ohm,
            ),
            (&table::MOTORS_GEAR_RATIO, "motors.gear_ratio", m.gear_ratio),
            (
                &table::MOTORS_GEAR_EFFICIENCY,
                "motors.gear_efficiency",
                m.gear_efficiency,
            ),
            (
                &table::MOTORS_SUPPLY_VOLTAGE_V,
                "motors.supply_voltage_v",
                m.supply_voltage_v,
            ),
            (
                &table::MOTORS_VISCOUS_FRICTION,
                "motors.viscous_friction_nms_per_rad[0]",
                m.viscous_friction_nms_per_rad[0],
            ),
            (
                &table::MOTORS_VISCOUS_FRICTION,
                "motors.viscous_friction_nms_per_rad[1]",
                m.viscous_friction_nms_per_rad[1],
            ),
            (
                &table::MOTORS_COULOMB_FRICTION_NM,
                "motors.coulomb_friction_nm[0]",
                m.coulomb_friction_nm[0],
            ),
            (
                &table::MOTORS_COULOMB_FRICTION_NM,
                "motors.coulomb_friction_nm[1]",
                m.coulomb_friction_nm[1],
            ),
            (
                &table::ENCODERS_COUNTS_PER_WHEEL_REV,
                "encoders.counts_per_wheel_rev",
                e.counts_per_wheel_rev,
            ),
            (
                &table::ENCODERS_SPEED_WINDOW_TICKS,
                "encoders.speed_window_ticks",
                e.speed_window_ticks as f32,
            ),
            (
                &table::BRIDGE_PWM_FREQUENCY_HZ,
                "bridge.pwm_frequency_hz",
                br.pwm_frequency_hz as f32,
            ),
            (
                &table::BRIDGE_MAX_DUTY_FRACTION,
                "bridge.max_duty_fraction",
                br.max_duty_fraction,
            ),
        ];
        for (p, field, x) in fields {
            check(p, field, x, &ab)?;
        }
        // [limits]: the device's parameter ranges for this robot (the
        // body and motors above are valid, so its bounds are numbers).
        let rb = self.bounds();
        let l = &self.limits;
        for (p, x) in [
            (&table::LIMITS_TORQUE_NM, l.torque_nm),
            (&table::LIMITS_MAX_SPEED_MPS, l.max_speed_mps),
            (&table::LIMITS_MAX_YAW_RATE_RADPS, l.max_yaw_rate_radps),
            (&table::LIMITS_MAX_ACCEL_MPS2, l.max_accel_mps2),
            (&table::LIMITS_LINK_TIMEOUT_MS, l.link_timeout_ms as f32),
        ] {
            check(p, p.name, x, &rb)?;
        }
        Ok(())
    }

    fn validate_consistency(&self) -> Result<(), RobotError> {
        let b = &self.body;
        let [r0, r1] = b.wheel_radius_m;
        let r_mean = 0.5 * (r0 + r1);
        let r_max = r0.max(r1);
        let m = b.mass_kg;
        bounded(
            (r0 - r1).abs() <= MAX_WHEEL_RADIUS_MISMATCH * r_mean,
            "body.wheel_radius_m[1]",
            ((r0 - r1).abs(), MAX_WHEEL_RADIUS_MISMATCH * r_mean, "m"),
            "10 % of the mean of body.wheel_radius_m",
            "the wheel radii differ by more than that: measure both wheels again (a typo in one \
             is the usual cause)",
        )?;
        bounded(
            b.com_offset_m < 0.5 * b.track_m,
            "body.com_offset_m",
            (b.com_offset_m, 0.5 * b.track_m, "m"),
            "body.track_m / 2",
            "the centre of mass is half a track or more ahead of the axle (the plant model needs \
             d < track/2): measure d again, from the axle's midpoint",
        )?;
        // All of the mass within sqrt(track² + r²) of G bounds the yaw
        // inertia from above; a robot with all of its mass within 3 % of
        // the track of G (1/1000 of m·track²) is not a robot.
        bounded(
            b.inertia_kgm2 <= m * (b.track_m * b.track_m + r_max * r_max),
            "body.inertia_kgm2",
            (
                b.inertia_kgm2,
                m * (b.track_m * b.track_m + r_max * r_max),
                "kg·m²",
            ),
            "body.mass_kg·(track² + r²)",
            "more than the whole mass at the wheels' reach: check the unit (kg·m²) or estimate \
             it as m·(length² + width²)/12",
        )?;
        bounded(
            b.inertia_kgm2 >= 1e-3 * m * b.track_m * b.track_m,
            "body.inertia_kgm2",
            (b.inertia_kgm2, 1e-3 * m * b.track_m * b.track_m, "kg·m²"),
            "body.mass_kg·track²/1000 (a lower bound)",
            "below it the mass would sit within 3 % of the track of G: check the unit (kg·m²) \
             or estimate it as m·(length² + width²)/12",
        )?;
        bounded(
            b.wheel_inertia_kgm2 <= m * r_max * r_max,
            "body.wheel_inertia_kgm2",
            (b.wheel_inertia_kgm2, m * r_max * r_max, "kg·m²"),
            "body.mass_kg·r²",
            "a wheel heavier than the robot as a ring at its rim: check the unit (kg·m²; a wheel \
             of mass m_w is about m_w·r²/2)",
        )?;
        let stall = self.stall_torque_nm();
        let w0 = self.no_load_wheel_speed_radps();
        let mo = &self.motors;
        for (i, f) in [
            "motors.viscous_friction_nms_per_rad[0]",
            "motors.viscous_friction_nms_per_rad[1]",
        ]
        .into_iter()
        .enumerate()
        {
            bounded(
                mo.viscous_friction_nms_per_rad[i] * w0 <= 0.5 * stall,
                f,
                (
                    mo.viscous_friction_nms_per_rad[i],
                    0.5 * stall / w0,
                    "N·m·s/rad",
                ),
                "half the stall torque η·N·k·V/R over the no-load speed V/(k·N)",
                "at the no-load speed it would take more than half the stall torque: measure it \
                 again (`wmr identify`), or check the motor's constants",
            )?;
        }
        for (i, f) in [
            "motors.coulomb_friction_nm[0]",
            "motors.coulomb_friction_nm[1]",
        ]
        .into_iter()
        .enumerate()
        {
            bounded(
                mo.coulomb_friction_nm[i] <= 0.5 * stall,
                f,
                (mo.coulomb_friction_nm[i], 0.5 * stall, "N·m"),
                "half the stall torque η·N·k·V/R",
                "more than half of what the motor gives at stall: measure it again (`wmr \
                 commission`), or check the motor's constants (gear ratio, k, V, R)",
            )?;
        }
        // limits.torque_nm ≤ the stall torque: its range (validate_ranges).
        let l = &self.limits;
        for (i, f) in [
            "motors.coulomb_friction_nm[0]",
            "motors.coulomb_friction_nm[1]",
        ]
        .into_iter()
        .enumerate()
        {
            let c = mo.coulomb_friction_nm[i];
            if c >= l.torque_nm {
                return Err(RobotError::new(
                    f,
                    Reason::Exceeds {
                        value: c,
                        limit: l.torque_nm,
                        unit: "N·m",
                        with: "limits.torque_nm",
                        why:
                            "no torque within the limit would move the wheel; measure the friction \
                              again (wmr commission) or raise limits.torque_nm if the driver allows",
                    },
                ));
            }
        }
        let top = self.friction_limited_speed_mps();
        if l.max_speed_mps > top {
            return Err(RobotError::new(
                "limits.max_speed_mps",
                Reason::Exceeds {
                    value: l.max_speed_mps,
                    limit: top,
                    unit: "m/s",
                    with: "the speed the motors hold against their friction at bridge.max_duty_fraction",
                    why: "the robot cannot reach it; lower limits.max_speed_mps to the bound or less",
                },
            ));
        }
        bounded(
            l.max_speed_mps <= self.no_load_speed_mps(),
            "limits.max_speed_mps",
            (l.max_speed_mps, self.no_load_speed_mps(), "m/s"),
            "the no-load speed r·V/(k·N) of motors and body.wheel_radius_m",
            "faster than the motors turn without load: lower limits.max_speed_mps to the bound \
             or less",
        )?;
        bounded(
            l.max_yaw_rate_radps <= 2.0 * self.no_load_speed_mps() / b.track_m,
            "limits.max_yaw_rate_radps",
            (
                l.max_yaw_rate_radps,
                2.0 * self.no_load_speed_mps() / b.track_m,
                "rad/s",
            ),
            "2·r·V/(k·N)/track, the wheels in opposite directions at no-load speed",
            "faster than the robot can turn: lower limits.max_yaw_rate_radps to the bound or less",
        )?;
        bounded(
            l.max_accel_mps2 <= 2.0 * l.torque_nm / (r_max * m),
            "limits.max_accel_mps2",
            (l.max_accel_mps2, 2.0 * l.torque_nm / (r_max * m), "m/s²"),
            "2·limits.torque_nm/(r·m), both wheels at the torque limit",
            "more than the wheels can give: lower limits.max_accel_mps2 to the bound or less \
             (or raise limits.torque_nm if the motors allow)",
        )?;
        let cpt = self.counts_per_tick(l.max_speed_mps / r0.min(r1), CONTROL_PERIOD_S);
        bounded(
            cpt <= i16::MAX as f32,
            "encoders.counts_per_wheel_rev",
            (cpt, i16::MAX as f32, "counts per 1 ms tick"),
            "half the 16-bit counter, at limits.max_speed_mps",
            "the counter would wrap between two ticks: check counts_per_wheel_rev (counts per \
             wheel turn, after the gearbox) or lower limits.max_speed_mps",
        )?;
        // The direction check's derived thresholds (derive.rs, D112): a
        // block of at most DIRECTION_MAX_BLOCK_S must resolve the runaway's
        // equilibrium margin, ½·W_ii × the torque limit, above the rate
        // estimate's quantisation.
        let (_, accel) = self.direction_block(CONTROL_PERIOD_S);
        let w = controller_core::model::ReducedModel::new(&self.robot_params())
            .map(|m| m.wheel_accel_map())
            .map_err(|e| RobotError::new("body", Reason::Controller(e)))?;
        bounded(
            accel <= 0.5 * w[0][0].min(w[1][1]) * l.torque_nm,
            "encoders.counts_per_wheel_rev",
            (accel, 0.5 * w[0][0].min(w[1][1]) * l.torque_nm, "rad/s²"),
            "half the wheel acceleration limits.torque_nm gives (body, encoders.speed_window_ticks)",
            "too coarse for the direction check: 3 counts per speed window over its longest block \
             resolve no finer than this; use a finer encoder, a longer speed_window_ticks or a \
             higher limits.torque_nm",
        )?;
        let bp = self.bridge.params();
        for clock in SUPPORTED_TIMER_CLOCKS_HZ {
            consistent(
                bp.duty_full_scale(clock).is_some(),
                "bridge.pwm_frequency_hz",
                "the boards' timer clocks (96 and 168 MHz)",
                "the duty resolution is not within 100..=65,535 levels",
            )?;
        }
        Ok(())
    }
}

fn gain_section(kind: ControllerKind) -> &'static str {
    match kind {
        ControllerKind::Proposed => "gains.proposed",
        ControllerKind::Smc => "gains.smc",
        ControllerKind::Asmc => "gains.asmc",
    }
}

fn validate_gains(kind: ControllerKind, g: &GainSet, b: &RobotBounds) -> Result<(), RobotError> {
    use table::*;
    let k = &g.kinematic;
    let o = &g.observer;
    let e = &g.eso;
    let s = &g.sliding;
    let fields: [(&Param, &'static str, f32); 16] = [
        (&GAINS_K_X, gain_path!(kind, "kinematic.k_x"), k.k_x),
        (&GAINS_K_Y, gain_path!(kind, "kinematic.k_y"), k.k_y),
        (&GAINS_K_TH, gain_path!(kind, "kinematic.k_th"), k.k_th),
        (
            &GAINS_LARGE_ERROR_M,
            gain_path!(kind, "kinematic.large_error_m"),
            k.large_error_m,
        ),
        (&GAINS_OBSERVER_L_V, gain_path!(kind, "observer.l_v"), o.l_v),
        (
            &GAINS_OBSERVER_L_OMEGA,
            gain_path!(kind, "observer.l_omega"),
            o.l_omega,
        ),
        (
            &GAINS_OBSERVER_MAX_ESTIMATE_V,
            gain_path!(kind, "observer.max_estimate[0]"),
            o.max_estimate[0],
        ),
        (
            &GAINS_OBSERVER_MAX_ESTIMATE_OMEGA,
            gain_path!(kind, "observer.max_estimate[1]"),
            o.max_estimate[1],
        ),
        (
            &GAINS_ESO_LAMBDA,
            gain_path!(kind, "eso.lambda[0]"),
            e.lambda[0],
        ),
        (
            &GAINS_ESO_LAMBDA,
            gain_path!(kind, "eso.lambda[1]"),
            e.lambda[1],
        ),
        (
            &GAINS_ESO_LAMBDA,
            gain_path!(kind, "eso.lambda[2]"),
            e.lambda[2],
        ),
        (&GAINS_ESO_ZETA, gain_path!(kind, "eso.zeta"), e.zeta),
        (&GAINS_ESO_ALPHA, gain_path!(kind, "eso.alpha"), e.alpha),
        (
            &GAINS_ESO_MAX_DISTURBANCE_V,
            gain_path!(kind, "eso.max_disturbance[0]"),
            e.max_disturbance[0],
        ),
        (
            &GAINS_ESO_MAX_DISTURBANCE_OMEGA,
            gain_path!(kind, "eso.max_disturbance[1]"),
            e.max_disturbance[1],
        ),
        (&GAINS_K_S, gain_path!(kind, "sliding.k_s"), s.k_s),
    ];
    for (p, field, x) in fields {
        check(p, field, x, b)?;
    }
    match s.switching {
        SwitchingGain::Fixed { k } => check(
            &GAINS_SWITCHING_FIXED_K,
            gain_path!(kind, "sliding.switching.fixed.k"),
            k,
            b,
        )?,
        SwitchingGain::Adaptive {
            gamma,
            dead_zone,
            leakage,
            rho0,
            rho_min,
            rho_max,
        } => {
            check(
                &GAINS_ADAPTIVE_GAMMA,
                gain_path!(kind, "sliding.switching.adaptive.gamma"),
                gamma,
                b,
            )?;
            check(
                &GAINS_ADAPTIVE_DEAD_ZONE,
                gain_path!(kind, "sliding.switching.adaptive.dead_zone"),
                dead_zone,
                b,
            )?;
            check(
                &GAINS_ADAPTIVE_LEAKAGE,
                gain_path!(kind, "sliding.switching.adaptive.leakage"),
                leakage,
                b,
            )?;
            check(
                &GAINS_ADAPTIVE_RHO0,
                gain_path!(kind, "sliding.switching.adaptive.rho0"),
                rho0,
                b,
            )?;
            check(
                &GAINS_ADAPTIVE_RHO_MIN,
                gain_path!(kind, "sliding.switching.adaptive.rho_min"),
                rho_min,
                b,
            )?;
            check(
                &GAINS_ADAPTIVE_RHO_MAX,
                gain_path!(kind, "sliding.switching.adaptive.rho_max"),
                rho_max,
                b,
            )?;
            consistent(
                rho_min <= rho0 && rho0 <= rho_max,
                gain_path!(kind, "sliding.switching.adaptive.rho0"),
                gain_path!(kind, "sliding.switching.adaptive.rho_min"),
                "need rho_min <= rho0 <= rho_max",
            )?;
        }
    }
    Ok(())
}
