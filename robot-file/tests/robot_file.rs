//! The robot file: examples, round trips, every field's error, the binary
//! form's corruption and fuzz checks.

use controller_core::runtime::{
    BridgeParams, ControlLoop, EncoderParams, MotorParams, RuntimeConfig, SafetyLimits,
    MIRRORED_LEFT,
};
use controller_core::{ControllerConfig, ControllerKind, RobotParams};
use robot_file::{
    BoardFacts, DecodeError, GainSet, Reason, Robot, RobotFileError, FIELDS, GAIN_FIELDS,
    MAX_ENCODED_LEN,
};
use std::collections::BTreeSet;

fn robots_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots")
}

fn read(name: &str) -> String {
    std::fs::read_to_string(robots_dir().join(name)).unwrap()
}

/// The paper robot with every gain section written out (SMC fixed, the
/// others adaptive): every field of the schema present.
fn full() -> Robot {
    let mut r = Robot::paper();
    r.gains.proposed = Some(GainSet::paper(ControllerKind::Proposed));
    r.gains.smc = Some(GainSet::paper(ControllerKind::Smc));
    r.gains.asmc = Some(GainSet::paper(ControllerKind::Asmc));
    // Not the defaults, so that the written file has every `[control]` key.
    r.control.controller = ControllerKind::Asmc;
    r.control.initial_x_m = 0.25;
    r.estimator.gyro_noise_density = 8.7e-5;
    r
}

/// Every field path: FIELDS then GAIN_FIELDS under each kind that has it.
fn all_fields() -> Vec<String> {
    let mut v: Vec<String> = FIELDS.iter().map(|s| s.to_string()).collect();
    for kind in ["proposed", "smc", "asmc"] {
        for g in GAIN_FIELDS {
            let fixed = g.contains("switching.fixed");
            let adaptive = g.contains("switching.adaptive");
            if (kind == "smc" && adaptive) || (kind != "smc" && fixed) {
                continue;
            }
            v.push(format!("gains.{kind}.{g}"));
        }
    }
    v
}

fn leaves(prefix: &str, v: &toml::Value, out: &mut BTreeSet<String>) {
    match v {
        toml::Value::Table(t) => {
            for (k, v) in t {
                let p = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                leaves(&p, v, out);
            }
        }
        toml::Value::Array(a) => {
            for (i, v) in a.iter().enumerate() {
                leaves(&format!("{prefix}[{i}]"), v, out);
            }
        }
        _ => {
            out.insert(prefix.to_string());
        }
    }
}

/// The value at `path` in a TOML document.
fn at<'a>(v: &'a mut toml::Value, path: &str) -> &'a mut toml::Value {
    let mut cur = v;
    for part in path.split('.') {
        let (key, idx) = match part.split_once('[') {
            Some((k, i)) => (k, Some(i.trim_end_matches(']').parse::<usize>().unwrap())),
            None => (part, None),
        };
        cur = cur.as_table_mut().unwrap().get_mut(key).unwrap();
        if let Some(i) = idx {
            cur = &mut cur.as_array_mut().unwrap()[i];
        }
    }
    cur
}

fn doc(r: &Robot) -> toml::Value {
    toml::Value::try_from(r).unwrap()
}

fn parse(v: &toml::Value) -> Result<Robot, RobotFileError> {
    Robot::from_toml_str(&toml::to_string(v).unwrap())
}

#[test]
fn paper_toml_is_robot_paper() {
    let r = Robot::from_toml_str(&read("paper.toml")).unwrap();
    assert_eq!(r, Robot::paper());
}

#[test]
fn paper_robot_is_built_from_controller_core() {
    let r = Robot::paper();
    r.validate().unwrap();
    assert_eq!(r.robot_params(), RobotParams::paper());
    assert_eq!(r.encoder_params(), EncoderParams::EXAMPLE);
    assert_eq!(
        r.motor_params(MotorParams::EXAMPLE.duty_full_scale),
        MotorParams::EXAMPLE
    );
    assert_eq!(r.bridge.params(), BridgeParams::EXAMPLE);
    assert_eq!(r.bridge.motor_inverted, MIRRORED_LEFT);
    for kind in ControllerKind::ALL {
        assert_eq!(r.controller_config(kind), ControllerConfig::paper(kind));
    }
}

#[test]
fn paper_runtime_config_is_the_example() {
    // RuntimeConfig::example is the configuration every test and the paper
    // comparison ran with; the paper robot must give it, except the
    // safety limits, which are now derived (checked apart below).
    let mut r = Robot::paper();
    // The example runs eq. (14) as printed.
    r.control.clean_start = false;
    for kind in ControllerKind::ALL {
        let ex = RuntimeConfig::example(kind);
        r.control.controller = kind;
        r.control.initial_x_m = ex.initial_pose.x_m;
        r.control.initial_y_m = ex.initial_pose.y_m;
        r.control.initial_heading_rad = ex.initial_pose.theta_rad;
        // 96 MHz / 20 kHz = 4,800 = MotorParams::EXAMPLE's full scale.
        let c = r
            .derive(&BoardFacts::of_timer(&r, 96_000_000).unwrap(), ex.reference)
            .runtime;
        assert_eq!(
            RuntimeConfig {
                safety: ex.safety,
                ..c
            },
            ex
        );
    }
}

#[test]
fn derived_safety_limits_follow_their_formulas() {
    let r = Robot::paper();
    let s = r.safety_limits(1e-3);
    // No-load 40 rad/s; 2.5 × 40 rad/s × 1 ms × 24,000/(2π) = 381.97 → 382.
    assert_eq!(s.max_counts_per_tick, 382);
    // A fifth of the 10 N·m torque limit: SafetyLimits::EXAMPLE's 2 N·m.
    assert_eq!(s.stall_torque_nm, SafetyLimits::EXAMPLE.stall_torque_nm);
    assert_eq!(s.stall_ticks, 250);
    assert_eq!(s.overrun_limit_us, 500);
    s.validate().unwrap();
    // Jump limit above the counts per tick at the no-load speed: a real
    // wheel never trips it.
    assert!(s.max_counts_per_tick as f32 > r.counts_per_tick(40.0, 1e-3));
}

#[test]
fn examples_parse_and_round_trip() {
    for f in [
        "paper.toml",
        "tb6612-2kg.toml",
        "bts7960-10kg.toml",
        "n20-0p85kg.toml",
    ] {
        let text = read(f);
        let r = Robot::from_toml_str(&text).unwrap_or_else(|e| panic!("{f}: {e}"));
        let back = Robot::from_toml_str(&r.to_toml_string()).unwrap();
        assert_eq!(back, r, "{f}");
        let mut buf = [0u8; MAX_ENCODED_LEN];
        let n = r.encode(&mut buf).unwrap();
        assert_eq!(Robot::decode(&buf[..n]).unwrap(), r, "{f}");
        let board = BoardFacts::of_timer(&r, 96_000_000).unwrap_or_else(|e| panic!("{f}: {e}"));
        for kind in ControllerKind::ALL {
            let mut r = r.clone();
            r.control.controller = kind;
            let c = r.derive(&board, RuntimeConfig::example(kind).reference);
            ControlLoop::<{ controller_core::estimator::HISTORY_LEN }>::with_estimator(
                c.runtime,
                c.estimator,
            )
            .unwrap_or_else(|e| panic!("{f} {kind:?}: {e}"));
        }
    }
}

#[test]
fn full_robot_round_trips_both_forms() {
    let r = full();
    r.validate().unwrap();
    assert_eq!(Robot::from_toml_str(&r.to_toml_string()).unwrap(), r);
    let mut buf = [0u8; MAX_ENCODED_LEN];
    let n = r.encode(&mut buf).unwrap();
    assert_eq!(Robot::decode(&buf[..n]).unwrap(), r);
}

#[test]
fn field_list_is_every_leaf_of_the_file() {
    let mut got = BTreeSet::new();
    leaves("", &doc(&full()), &mut got);
    let want: BTreeSet<String> = all_fields().into_iter().collect();
    assert_eq!(got, want);
}

#[test]
fn schema_lists_every_section_field() {
    // The schema's properties of each section are the keys of the file.
    let schema: serde_json::Value = serde_json::from_str(&robot_file::json_schema()).unwrap();
    let props = schema["properties"].as_object().unwrap();
    let top: BTreeSet<_> = props.keys().cloned().collect();
    let d = doc(&full());
    let file_top: BTreeSet<_> = d.as_table().unwrap().keys().cloned().collect();
    assert_eq!(top, file_top);
}

#[test]
fn committed_schema_is_current() {
    let path = robots_dir().join("robot.schema.json");
    let now = robot_file::json_schema();
    if std::env::var_os("ROBOT_FILE_WRITE_SCHEMA").is_some() {
        std::fs::write(&path, &now).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == now,
        "robots/robot.schema.json is stale: regenerate with \
         `ROBOT_FILE_WRITE_SCHEMA=1 cargo test -p robot-file --test robot_file committed_schema`"
    );
}

fn bad_value(path: &str, v: &toml::Value) -> Option<toml::Value> {
    Some(match v {
        toml::Value::Float(_) => toml::Value::Float(1e30),
        toml::Value::Integer(_) => match path {
            "encoders.speed_window_ticks" => toml::Value::Integer(200),
            _ => toml::Value::Integer(4_000_000_000),
        },
        toml::Value::String(_) => match path {
            "name" => toml::Value::String(String::new()),
            _ => toml::Value::String("sideways".into()),
        },
        toml::Value::Boolean(_) => return None,
        _ => unreachable!("{path}"),
    })
}

#[test]
fn every_field_out_of_range_names_it() {
    for path in all_fields() {
        let mut d = doc(&full());
        let slot = at(&mut d, &path);
        let Some(bad) = bad_value(&path, slot) else {
            continue;
        };
        *slot = bad;
        let e = parse(&d).expect_err(&path);
        assert_eq!(e.field(), Some(path.as_str()), "{path}: {e}");
        // Also in the message a user reads.
        assert!(e.to_string().contains(&path), "{path}: {e}");
    }
}

#[test]
fn every_float_field_nan_names_it() {
    for path in all_fields() {
        let mut d = doc(&full());
        let slot = at(&mut d, &path);
        if !slot.is_float() {
            continue;
        }
        *slot = toml::Value::Float(f64::NAN);
        let e = parse(&d).expect_err(&path);
        assert_eq!(e.field(), Some(path.as_str()), "{path}: {e}");
        let Err(RobotFileError::Invalid { error, .. }) = parse(&d) else {
            panic!("{path}")
        };
        assert_eq!(error.reason, Reason::NotFinite, "{path}");
    }
}

#[test]
fn every_field_missing_names_it() {
    for path in all_fields() {
        // An array element cannot be missing; the whole array can.
        let path = path.split('[').next().unwrap().to_string();
        // `[control]` and `[estimator]` are optional field by field (their
        // defaults: below).
        if path.starts_with("control.") || path.starts_with("estimator.") {
            continue;
        }
        let mut d = doc(&full());
        let (parent, key) = match path.rsplit_once('.') {
            Some((p, k)) => (Some(p), k),
            None => (None, path.as_str()),
        };
        let t = match parent {
            Some(p) => at(&mut d, p),
            None => &mut d,
        };
        t.as_table_mut().unwrap().remove(key);
        let e = parse(&d).expect_err(&path);
        let text = e.to_string();
        assert!(text.contains(key), "{path}: {text}");
        assert_eq!(e.field(), Some(path.as_str()), "{path}: {e}");
    }
}

#[test]
fn control_fields_default_one_by_one() {
    // Each `[control]` field left out takes `Control::default()`'s value,
    // the others kept: what the firmware ran before the section (D139).
    let mut full = full();
    full.control = robot_file::Control {
        controller: ControllerKind::Smc,
        clean_start: false,
        governor: false,
        initial_x_m: 1.5,
        initial_y_m: -2.0,
        initial_heading_rad: 0.5,
    };
    let def = robot_file::Control::default();
    for key in FIELDS.iter().filter_map(|f| f.strip_prefix("control.")) {
        let mut d = doc(&full);
        at(&mut d, "control").as_table_mut().unwrap().remove(key);
        let r = parse(&d).unwrap_or_else(|e| panic!("{key}: {e}"));
        let mut want = full.control;
        match key {
            "controller" => want.controller = def.controller,
            "clean_start" => want.clean_start = def.clean_start,
            "governor" => want.governor = def.governor,
            "initial_x_m" => want.initial_x_m = def.initial_x_m,
            "initial_y_m" => want.initial_y_m = def.initial_y_m,
            "initial_heading_rad" => want.initial_heading_rad = def.initial_heading_rad,
            _ => panic!("a [control] field this test does not know: {key}"),
        }
        assert_eq!(r.control, want, "{key}");
    }
    // The derivation runs what the section says.
    let board = BoardFacts::of_timer(&full, 96_000_000).unwrap();
    let d = full.derive(
        &board,
        RuntimeConfig::example(ControllerKind::Smc).reference,
    );
    assert_eq!(d.runtime.controller.kind, ControllerKind::Smc);
    assert_eq!(d.runtime.initial_pose.x_m, 1.5);
    assert_eq!(
        d.runtime.pacing,
        controller_core::pacer::PacingConfig::off()
    );
    assert_eq!(
        d.runtime.controller.kinematic.large_error_m,
        ControllerConfig::paper(ControllerKind::Smc)
            .kinematic
            .large_error_m
    );
}

#[test]
fn estimator_fields_default_one_by_one_and_reach_the_estimator() {
    let e = controller_core::estimator::EstimatorConfig::EXAMPLE;
    let mut r = full();
    r.estimator = robot_file::Estimator {
        gyro_noise_density: 1e-4,
        gyro_bias_walk: 2e-5,
        speed_noise_mps_per_sqrt_hz: 0.01,
        slip_fraction: 0.05,
        wheel_yaw_noise: 0.2,
    };
    for key in FIELDS.iter().filter_map(|f| f.strip_prefix("estimator.")) {
        let mut d = doc(&r);
        at(&mut d, "estimator").as_table_mut().unwrap().remove(key);
        let back = parse(&d).unwrap_or_else(|err| panic!("{key}: {err}"));
        let (got, want) = match key {
            "gyro_noise_density" => (back.estimator.gyro_noise_density, e.gyro_noise_density),
            "gyro_bias_walk" => (back.estimator.gyro_bias_walk, e.gyro_bias_walk),
            "speed_noise_mps_per_sqrt_hz" => (
                back.estimator.speed_noise_mps_per_sqrt_hz,
                e.speed_noise_mps_per_sqrt_hz,
            ),
            "slip_fraction" => (back.estimator.slip_fraction, e.slip_fraction),
            "wheel_yaw_noise" => (back.estimator.wheel_yaw_noise, e.wheel_yaw_noise),
            _ => panic!("an [estimator] field this test does not know: {key}"),
        };
        assert_eq!(got, want, "{key}");
    }
    // The derivation gives the estimator the file's noises, the board's
    // gyro saturation and the example's gates and counts.
    let mut board = BoardFacts::of_timer(&r, 96_000_000).unwrap();
    board.gyro_saturation_radps = Some(8.5);
    let d = r.derive(
        &board,
        RuntimeConfig::example(ControllerKind::Proposed).reference,
    );
    assert_eq!(d.estimator.gyro_noise_density, 1e-4);
    assert_eq!(d.estimator.wheel_yaw_noise, 0.2);
    assert_eq!(d.estimator.gyro_saturation_radps, 8.5);
    assert_eq!(d.estimator.chi2_gate_2dof, e.chi2_gate_2dof);
    d.estimator.validate().unwrap();
    // A noise outside the table's range is refused naming the field.
    r.estimator.slip_fraction = -0.1;
    let err = r.validate().unwrap_err();
    assert_eq!(err.field, "estimator.slip_fraction");
}

#[test]
fn unknown_key_in_every_table_names_it() {
    let mut tables = BTreeSet::new();
    for path in all_fields() {
        let mut p = path.as_str();
        while let Some((t, _)) = p.rsplit_once('.') {
            tables.insert(t.to_string());
            p = t;
        }
    }
    tables.insert(String::new());
    for t in tables {
        // Variant tables of an enum take no extra key either.
        let mut d = doc(&full());
        let tbl = if t.is_empty() { &mut d } else { at(&mut d, &t) };
        tbl.as_table_mut()
            .unwrap()
            .insert("wheel_colour".into(), toml::Value::Integer(3));
        let e = parse(&d).expect_err(&t);
        if t.ends_with("switching") {
            assert_eq!(e.field(), Some(t.as_str()), "{t}: {e}");
            assert!(e.to_string().contains("exactly one key"), "{t}: {e}");
            continue;
        }
        assert!(e.to_string().contains("wheel_colour"), "{t}: {e}");
        let want = if t.is_empty() {
            "wheel_colour".to_string()
        } else {
            format!("{t}.wheel_colour")
        };
        if !t.contains("switching") {
            assert_eq!(e.field(), Some(want.as_str()), "{t}: {e}");
        }
    }
}

#[test]
fn wrong_type_names_field_and_line() {
    let text = read("paper.toml").replace("mass_kg = 15.0", "mass_kg = \"heavy\"");
    let e = Robot::from_toml_str(&text).unwrap_err();
    let line = text.lines().position(|l| l.starts_with("mass_kg")).unwrap() + 1;
    match &e {
        RobotFileError::Toml { field, line: l, .. } => {
            assert_eq!(field.as_deref(), Some("body.mass_kg"));
            assert_eq!(*l, Some(line));
        }
        other => panic!("{other}"),
    }
}

#[test]
fn invalid_value_names_its_line() {
    let text = read("paper.toml").replace("track_m = 0.4", "track_m = 40.0");
    let line = text.lines().position(|l| l.starts_with("track_m")).unwrap() + 1;
    match Robot::from_toml_str(&text).unwrap_err() {
        RobotFileError::Invalid { error, line: l } => {
            assert_eq!(error.field, "body.track_m");
            assert_eq!(l, Some(line));
        }
        other => panic!("{other}"),
    }
}

#[test]
fn another_format_is_refused_clearly() {
    let text = read("paper.toml").replace("format = 1", "format = 2");
    let e = Robot::from_toml_str(&text).unwrap_err();
    assert_eq!(e, RobotFileError::UnsupportedFormat { found: 2 });
    assert!(e.to_string().contains("format 2"));
}

/// Physical-range checks that a plain "finite and positive" check misses.
#[test]
fn implausible_robots_are_refused_with_the_field() {
    type Edit = Box<dyn Fn(&mut Robot)>;
    let cases: Vec<(&str, Edit)> = vec![
        ("body.mass_kg", Box::new(|r| r.body.mass_kg = 0.02)),
        ("body.mass_kg", Box::new(|r| r.body.mass_kg = 2000.0)),
        (
            "body.wheel_radius_m[0]",
            Box::new(|r| r.body.wheel_radius_m[0] = 0.001),
        ),
        (
            "motors.gear_efficiency",
            Box::new(|r| r.motors.gear_efficiency = 1.05),
        ),
        // 24.48 N·m stall torque at the wheel.
        ("limits.torque_nm", Box::new(|r| r.limits.torque_nm = 25.0)),
        // 4 m/s no-load speed.
        (
            "limits.max_speed_mps",
            Box::new(|r| r.limits.max_speed_mps = 4.1),
        ),
        (
            "body.wheel_radius_m[1]",
            Box::new(|r| r.body.wheel_radius_m[1] = 0.111),
        ),
        (
            "body.com_offset_m",
            Box::new(|r| r.body.com_offset_m = 0.41),
        ),
        // m·(track² + r²) = 15·0.17 = 2.55 kg·m².
        ("body.inertia_kgm2", Box::new(|r| r.body.inertia_kgm2 = 2.6)),
        (
            "encoders.counts_per_wheel_rev",
            // 1 m/s on r = 0.1 m is 10 rad/s; 32,767 counts per ms at 10
            // rad/s is 2.06e7 counts/rev: above the range anyway; with
            // a 5 m/s limit... use a small wheel instead.
            Box::new(|r| {
                r.body.wheel_radius_m = [0.01, 0.01];
                r.body.wheel_inertia_kgm2 = 1e-4;
                r.body.inertia_kgm2 = 0.5;
                r.motors.gear_ratio = 1.0;
                r.limits.torque_nm = 1.0;
                r.limits.max_accel_mps2 = 1.0;
                r.limits.max_speed_mps = 4.0;
                r.limits.max_yaw_rate_radps = 1.0;
                r.encoders.counts_per_wheel_rev = 600_000.0;
            }),
        ),
        // 96 MHz / 1 kHz = 96,000 levels: does not fit the 16-bit timer.
        (
            "bridge.pwm_frequency_hz",
            Box::new(|r| r.bridge.pwm_frequency_hz = 1_000),
        ),
        (
            "gains.proposed.sliding.switching.adaptive.rho0",
            Box::new(|r| {
                let mut g = GainSet::paper(ControllerKind::Proposed);
                g.sliding.switching = robot_file::SwitchingGain::Adaptive {
                    gamma: 0.1,
                    dead_zone: 0.01,
                    leakage: 0.01,
                    rho0: 6.0,
                    rho_min: 0.0,
                    rho_max: 5.0,
                };
                r.gains.proposed = Some(g);
            }),
        ),
    ];
    for (field, f) in cases {
        let mut r = Robot::paper();
        f(&mut r);
        let e = r.validate().expect_err(field);
        assert_eq!(e.field, field, "{e}");
    }
}

#[test]
fn binary_lengths_fit_max_encoded_len() {
    let mut buf = [0u8; 2 * MAX_ENCODED_LEN];
    let n = Robot::paper().encode(&mut buf).unwrap();
    assert!(n <= MAX_ENCODED_LEN);
    // Worst case: every gain section, the longest name, every varint at its
    // widest.
    let mut r = full();
    r.name = robot_file::Name::try_from("ÿ".repeat(16).as_str()).unwrap();
    r.format = u32::MAX;
    r.bridge.pwm_frequency_hz = u32::MAX;
    r.limits.link_timeout_ms = u32::MAX;
    let n = r.encode(&mut buf).unwrap();
    assert!(n <= MAX_ENCODED_LEN, "{n}");
    // Too small a buffer is an error, not a panic.
    for len in 0..n {
        assert!(Robot::paper().encode(&mut buf[..len.min(20)]).is_err() || len >= 20);
    }
}

#[test]
fn every_corrupted_byte_is_refused() {
    let mut buf = [0u8; MAX_ENCODED_LEN];
    let n = full().encode(&mut buf).unwrap();
    for i in 0..n {
        for flip in [0x01u8, 0x80, 0xff] {
            let mut b = buf;
            b[i] ^= flip;
            assert!(
                Robot::decode(&b[..n]).is_err(),
                "byte {i} ^ {flip:#x} accepted"
            );
        }
    }
    // Truncated anywhere or extended.
    for len in 0..n {
        assert!(Robot::decode(&buf[..len]).is_err());
    }
    assert_eq!(Robot::decode(&buf[..n + 1]), Err(DecodeError::BadLength));
}

#[test]
fn a_valid_record_of_an_invalid_robot_is_refused() {
    let mut r = Robot::paper();
    r.body.mass_kg = f32::NAN;
    let mut buf = [0u8; MAX_ENCODED_LEN];
    let n = r.encode(&mut buf).unwrap();
    match Robot::decode(&buf[..n]) {
        Err(DecodeError::Invalid(e)) => assert_eq!(e.field, "body.mass_kg"),
        other => panic!("{other:?}"),
    }
}

/// xorshift64*: a seeded generator for the fuzz loop.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
}

#[test]
fn decoding_arbitrary_bytes_never_panics() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let mut valid = [0u8; MAX_ENCODED_LEN];
    let n = full().encode(&mut valid).unwrap();
    for round in 0..20_000 {
        let mut b = [0u8; MAX_ENCODED_LEN + 16];
        let len = (rng.next() as usize) % b.len();
        if round % 2 == 0 {
            for x in b[..len].iter_mut() {
                *x = rng.next() as u8;
            }
        } else {
            // A real record with a few random bytes: reaches the payload.
            b[..n].copy_from_slice(&valid[..n]);
            for _ in 0..1 + rng.next() % 4 {
                let i = (rng.next() as usize) % n;
                b[i] = rng.next() as u8;
            }
        }
        let _ = Robot::decode(&b[..len.max(if round % 2 == 0 { 0 } else { n }).min(b.len())]);
    }
}

#[test]
fn payload_that_passes_the_crc_but_is_not_a_robot_is_malformed() {
    // A header + CRC around garbage: the CRC is right, postcard refuses it.
    let payload = [0xffu8; 40];
    let mut b = Vec::new();
    b.extend_from_slice(&robot_file::MAGIC);
    b.extend_from_slice(&robot_file::BINARY_VERSION.to_le_bytes());
    b.extend_from_slice(&(payload.len() as u16).to_le_bytes());
    b.extend_from_slice(&payload);
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(&b);
    b.extend_from_slice(&crc.to_le_bytes());
    assert_eq!(Robot::decode(&b), Err(DecodeError::Malformed));
}

#[test]
fn unequal_wheels_reach_the_runtime_as_arc_per_count() {
    let mut r = Robot::paper();
    r.body.wheel_radius_m = [0.105, 0.095];
    r.validate().unwrap();
    let model = r.robot_params();
    assert!((model.wheel_radius_m - 0.1).abs() < 1e-7);
    let e = r.encoder_params();
    let cpr = r.encoders.counts_per_wheel_rev;
    for i in 0..2 {
        // The model's radius times the runtime's angle per count is the
        // wheel's own arc per count, 2π·r_i/cpr.
        let arc = model.wheel_radius_m * e.rad_per_count()[i];
        let want = 2.0 * std::f32::consts::PI * r.body.wheel_radius_m[i] / cpr;
        assert!((arc - want).abs() < 1e-9, "{i}: {arc} {want}");
    }
    e.validate().unwrap();
}

#[test]
fn build_script_embeds_a_good_file_and_names_the_field_of_a_bad_one() {
    let dir = std::env::temp_dir().join(format!("robot-file-embed-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let good = robots_dir().join("tb6612-2kg.toml");
    let r = robot_file::build_script::embed(&good, &dir).unwrap();
    let bytes =
        std::fs::read(dir.join(robot_file::build_script::EMBEDDED_ROBOT_FILE_NAME)).unwrap();
    assert_eq!(Robot::decode(&bytes).unwrap(), r);
    let bad = dir.join("bad.toml");
    std::fs::write(
        &bad,
        read("tb6612-2kg.toml").replace("torque_nm = 0.25", "torque_nm = 2.5"),
    )
    .unwrap();
    let e = robot_file::build_script::embed(&bad, &dir).unwrap_err();
    assert!(
        e.contains("limits.torque_nm") && e.contains("bad.toml"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The derived direction thresholds (D110, D112) pass the runtime's
/// physical-range validation (`ControlLoop::new` runs
/// `SafetyLimits::validate_direction`) for every example robot file and for
/// 400 pseudo-random variants of them (body, motors, encoders and torque
/// limit each scaled by 0.3-3, the right wheel's radius by another 0.95-1.05): every variant the robot file accepts gives
/// a runtime that accepts its thresholds; a variant whose encoder is too
/// coarse for the check is refused naming `encoders.counts_per_wheel_rev`.
#[test]
fn derived_direction_thresholds_are_always_valid() {
    let mut files = Vec::new();
    for f in std::fs::read_dir(robots_dir()).unwrap() {
        let p = f.unwrap().path();
        if p.extension().is_some_and(|e| e == "toml") {
            files.push(Robot::from_toml_str(&std::fs::read_to_string(&p).unwrap()).unwrap());
        }
    }
    assert!(files.len() >= 6, "{}", files.len());
    let ex = RuntimeConfig::example(ControllerKind::Proposed);
    let check = |r: &Robot| {
        let c = r
            .derive(&BoardFacts::of_timer(r, 96_000_000).unwrap(), ex.reference)
            .runtime;
        if let Err(e) = ControlLoop::new(c) {
            panic!("{}: {e} ({:?})", r.name, c.safety);
        }
        c.safety
    };
    for r in &files {
        let s = check(r);
        println!(
            "{}: {} N·m, {} rad/s², {} ticks × {}",
            r.name,
            s.direction_torque_nm,
            s.direction_accel_radps2,
            s.direction_block_ticks,
            s.direction_blocks
        );
    }
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        // 0.3..3, log-uniform.
        0.3f32 * 10f32.powf((seed >> 40) as f32 / (1u64 << 24) as f32)
    };
    let (mut accepted, mut coarse) = (0, 0);
    for k in 0..400 {
        let mut r = files[k % files.len()].clone();
        r.body.mass_kg *= next();
        r.body.inertia_kgm2 *= next();
        r.body.wheel_inertia_kgm2 *= next();
        let s = next();
        // Unequal wheels too (the right one 0.95-1.05 × the left): the
        // runtime's rate quantum is the coarser wheel's.
        let d = 0.95 + 0.1 * (next() - 0.3) / 2.7;
        r.body.wheel_radius_m = [
            r.body.wheel_radius_m[0] * s * d,
            r.body.wheel_radius_m[1] * s,
        ];
        r.motors.torque_constant_nm_per_a *= next();
        r.motors.gear_ratio *= next();
        r.encoders.counts_per_wheel_rev *= next();
        r.encoders.speed_window_ticks = ((r.encoders.speed_window_ticks as f32 * next()) as u8)
            .clamp(1, controller_core::runtime::MAX_SPEED_WINDOW as u8);
        r.limits.torque_nm *= next();
        match r.validate() {
            Ok(()) => {
                check(&r);
                accepted += 1;
            }
            Err(e) if e.field == "encoders.counts_per_wheel_rev" => coarse += 1,
            Err(_) => {}
        }
    }
    println!("{accepted} variants accepted, {coarse} refused as too coarse");
    assert!(accepted >= 40, "{accepted}");
}

/// Issue 31 item 4: a fixed-size array with extra elements of any type
/// (149 of 400 such files were accepted: serde reads its N elements and
/// the rest passed) is refused naming the field, its length and the one
/// it takes; so is one too short. Every fixed-size array of the file,
/// gain sections included.
#[test]
fn fixed_size_arrays_take_exactly_their_length() {
    let text = read("paper.toml").replace(
        "wheel_radius_m = [0.1, 0.1]",
        "wheel_radius_m = [0.1, 0.1, \"junk\", {a = 1}]",
    );
    assert!(text.contains("junk"), "the example changed: {text}");
    let e = Robot::from_toml_str(&text).unwrap_err();
    assert_eq!(e.field(), Some("body.wheel_radius_m"), "{e}");
    assert!(
        e.to_string().contains("has 4 elements; it takes exactly 2"),
        "{e}"
    );
    let with_gains = || {
        let mut r = Robot::paper();
        r.gains.proposed = Some(GainSet::paper(ControllerKind::Proposed));
        r.gains.smc = Some(GainSet::paper(ControllerKind::Smc));
        r.gains.asmc = Some(GainSet::paper(ControllerKind::Asmc));
        doc(&r)
    };
    let mut v = with_gains();
    for (path, n) in [
        ("body.wheel_radius_m", 2),
        ("encoders.inverted", 2),
        ("bridge.motor_inverted", 2),
        ("gains.proposed.eso.lambda", 3),
        ("gains.smc.observer.max_estimate", 2),
    ] {
        let mut w = v.clone();
        let parts: Vec<&str> = path.split('.').collect();
        let leaf = parts
            .iter()
            .fold(&mut w, |t, k| &mut t.as_table_mut().unwrap()[*k]);
        let arr = leaf.as_array_mut().unwrap();
        assert_eq!(arr.len(), n, "{path}");
        arr.push(arr[0].clone());
        let e = parse(&w).unwrap_err();
        assert_eq!(e.field(), Some(path), "{e}");
        arr_shorten(&mut v, path);
        let e = parse(&v).unwrap_err();
        assert_eq!(e.field(), Some(path), "too short: {e}");
        v = with_gains();
    }
}

fn arr_shorten(v: &mut toml::Value, path: &str) {
    let leaf = path
        .split('.')
        .fold(v, |t, k| &mut t.as_table_mut().unwrap()[k]);
    leaf.as_array_mut().unwrap().pop();
}

/// Issue 31 item 6: a carriage return or form feed inside a comment is a
/// TOML error on the comment's line; the error names the table there, not
/// the comment's text as a field.
#[test]
fn a_control_character_in_a_comment_names_no_field_of_its_text() {
    for cc in ['\r', '\u{c}'] {
        let text = read("paper.toml").replacen(
            "[body]\n",
            &format!("[body]\n# a note{cc}mass_kg = 99\n"),
            1,
        );
        let e = Robot::from_toml_str(&text).unwrap_err();
        let field = e.field().unwrap_or("");
        assert!(
            !field.contains("note") && !field.contains('#'),
            "{cc:?}: {e}"
        );
        assert!(
            matches!(e, RobotFileError::Toml { line: Some(_), .. }),
            "{cc:?}: {e}"
        );
    }
}

/// A Coulomb friction at or above the torque limit, and a top speed the
/// motors cannot hold against their friction, are refused with the value,
/// the bound and what to do. The bound is the motor law's: at duty d the
/// torque τ_s·(d − ω/ω₀) equals c + b·ω at ω = (τ_s·d − c)/(τ_s/ω₀ + b);
/// checked here against that formula written out for n20-0p85kg.toml.
#[test]
fn friction_beyond_the_limit_and_an_unreachable_top_speed_are_refused() {
    let base = Robot::from_toml_str(&read("n20-0p85kg.toml")).unwrap();
    let mut r = base.clone();
    r.motors.coulomb_friction_nm = [0.12, 0.06];
    let e = r.validate().unwrap_err();
    assert_eq!(e.field, "motors.coulomb_friction_nm[0]", "{e}");
    let text = e.to_string();
    assert!(
        text.contains("0.12 N·m") && text.contains("limits.torque_nm"),
        "{text}"
    );

    // The bound by hand: 7.4 V, k = 0.00191, N = 120, η = 0.6, R = 4 Ω,
    // d = 0.95, c = 0.06, b = 0.0002, r = 0.03.
    let (v, k, n, eta, res) = (7.4f64, 0.00191f64, 120.0f64, 0.6f64, 4.0f64);
    let stall = eta * n * k * v / res;
    let w0 = v / (k * n);
    let w = (stall * 0.95 - 0.06) / (stall / w0 + 0.0002);
    let top = 0.03 * w;
    assert!((base.friction_limited_speed_mps() as f64 - top).abs() < 1e-4 * top);
    assert!(base.limits.max_speed_mps as f64 <= top);
    let mut r = base.clone();
    r.limits.max_speed_mps = (top * 1.02) as f32;
    let e = r.validate().unwrap_err();
    assert_eq!(e.field, "limits.max_speed_mps", "{e}");
    let text = e.to_string();
    assert!(
        text.contains(&format!("{top:.4} m/s")) && text.contains("lower"),
        "{text}"
    );
}

/// Issue 37: every refusal of a value against a bound computed from the
/// file says the value, the computed bound with its unit, and what to do.
/// The bounds here are computed by hand from the n20 file's own numbers.
#[test]
fn refusals_say_the_value_the_computed_limit_and_what_to_do() {
    let base = read("n20-0p85kg.toml");
    let refuse = |from: &str, to: &str| {
        assert!(base.contains(from), "{from}");
        robot_file::Robot::from_toml_str(&base.replacen(from, to, 1))
            .unwrap_err()
            .to_string()
    };
    // Coulomb friction above half the stall torque, η·N·k·V/R / 2 =
    // 0.6·120·0.00191·7.4/4/2 = 0.12722 N·m.
    let e = refuse(
        "coulomb_friction_nm = [0.06, 0.06]",
        "coulomb_friction_nm = [0.2, 0.06]",
    );
    assert!(
        e.contains("motors.coulomb_friction_nm[0]: 0.2 N·m")
            && e.contains("0.1272 N·m")
            && e.contains("measure it again"),
        "{e}"
    );
    // The torque limit above the stall torque 0.25441 N·m (the parameter
    // table's range, its end computed for this robot).
    let e = refuse("torque_nm = 0.12", "torque_nm = 1.0");
    assert!(
        e.contains("limits.torque_nm") && e.contains("1 N·m") && e.contains("0.2544"),
        "{e}"
    );
    // d beyond half the track, 0.07 m.
    let e = refuse("com_offset_m = 0.01", "com_offset_m = 0.09");
    assert!(
        e.contains("body.com_offset_m: 0.09 m")
            && e.contains("0.0700 m")
            && e.contains("measure d again"),
        "{e}"
    );
    // The wheel inertia above m·r² = 0.85·0.03² = 0.000765 kg·m².
    let e = refuse("wheel_inertia_kgm2 = ", "wheel_inertia_kgm2 = 0.01 # ");
    assert!(
        e.contains("body.wheel_inertia_kgm2: 0.01 kg·m²") && e.contains("0.0008 kg·m²"),
        "{e}"
    );
}

/// The health machine's position-error thresholds are the robot's (issue
/// 34, D206): the paper robot (1 m/s) keeps controller-core's defaults, a
/// robot of half that speed limit gets half the distances, and the derived
/// configuration carries them.
#[test]
fn health_thresholds_scale_with_the_speed_limit() {
    use controller_core::health::HealthParams;
    use robot_file::{health_for_speed, HEALTH_DEFAULT_SPEED_MPS};
    let d = HealthParams::DEFAULT;
    assert_eq!(health_for_speed(d, HEALTH_DEFAULT_SPEED_MPS), d);
    let slow = health_for_speed(d, 0.5 * HEALTH_DEFAULT_SPEED_MPS)
        .validate()
        .unwrap();
    assert_eq!(
        [slow.error_degraded_m, slow.acquired_m, slow.lost_path_m],
        [
            0.5 * d.error_degraded_m,
            0.5 * d.acquired_m,
            0.5 * d.lost_path_m
        ]
    );
    assert_eq!(slow.saturation_degraded, d.saturation_degraded);
    let mut r = Robot::paper();
    r.limits.max_speed_mps = 0.6;
    let board = robot_file::BoardFacts::of_timer(&r, 96_000_000).unwrap();
    let derived = r.derive(
        &board,
        controller_core::runtime::RuntimeConfig::example(controller_core::ControllerKind::Proposed)
            .reference,
    );
    assert_eq!(derived.runtime.pacing.health, health_for_speed(d, 0.6));
}
