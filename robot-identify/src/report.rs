//! The fit's report (values ± 95 % interval, residuals, richness) and the
//! identified robot as TOML with its uncertainty in comments.

use crate::fit::{Dynamics, Estimate, Identification, Prior};
use std::fmt::Write as _;

fn line(out: &mut String, name: &str, unit: &str, e: &Estimate, prior: Option<f64>) {
    let rel = if e.ci95.is_finite() {
        format!("{:>6.2} %", 100.0 * e.relative_ci())
    } else {
        "  fixed".into()
    };
    let prior = prior.map_or(String::new(), |p| format!("   (prior {p:.5})"));
    let _ = writeln!(
        out,
        "  {name:<22} {:>12.5} ± {:<10.5} {unit:<10} {rel}{prior}",
        e.value, e.ci95
    );
}

fn dynamics(out: &mut String, d: &Dynamics, prior: &Prior) {
    let p = &prior.robot;
    if d.mass_given {
        let _ = writeln!(
            out,
            "  {:<22} {:>12.5} {:<12} {:<10}    given (--mass-kg)   (prior {:.5})",
            "mass m", d.mass_kg.value, "", "kg", p.mass_kg
        );
    } else {
        line(out, "mass m", "kg", &d.mass_kg, Some(p.mass_kg as f64));
    }
    if d.form == crate::fit::Form::Voltage && d.mass_given {
        line(
            out,
            "torque/volt a=ηNk/R",
            "N·m/V",
            &d.torque_per_volt,
            Some(prior.torque_per_volt()),
        );
    } else if d.form == crate::fit::Form::Voltage {
        let _ = writeln!(
            out,
            "  {:<22} {:>12.5} {:<12} {:<10}    the prior's: NOT identified (give --mass-kg)",
            "torque/volt a=ηNk/R", d.torque_per_volt.value, "", "N·m/V"
        );
    }
    line(
        out,
        "inertia I",
        "kg·m²",
        &d.inertia_kgm2,
        Some(p.inertia_kgm2 as f64),
    );
    line(
        out,
        "CoM offset d",
        "m",
        &d.com_offset_m,
        Some(p.com_offset_m as f64),
    );
    line(out, "M1 translational", "kg", &d.m1[0], None);
    line(out, "M1 rotational", "kg·m²", &d.m1[1], None);
    for (i, w) in ["right", "left"].iter().enumerate() {
        line(
            out,
            &format!("Coulomb friction {w}"),
            "N·m",
            &d.coulomb_nm[i],
            None,
        );
        line(
            out,
            &format!("viscous friction {w}"),
            "N·m·s/rad",
            &d.viscous_nms_per_rad[i],
            None,
        );
    }
    if let Some(k) = &d.emf_vs_per_rad {
        for (i, w) in ["right", "left"].iter().enumerate() {
            line(
                out,
                &format!("EMF κ = Nk + c_v/a {w}"),
                "V·s/rad",
                &k[i],
                Some(prior.emf_per_wheel_rate()),
            );
        }
        let _ = writeln!(
            out,
            "  duty sign per wheel     {:?} (−1: mirrored motor)",
            d.duty_sign
        );
    }
    let _ = writeln!(
        out,
        "  residual RMS {:.4} {} over {} rows; condition number {:.3e}; residual correlation inflation {:.1}",
        d.lsq.residual_rms, d.residual_unit, d.lsq.rows, d.lsq.condition, d.lsq.inflation
    );
}

/// The report as text.
pub fn text(id: &Identification, prior: &Prior) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "identification: {} rows at {:.0} Hz over {:.1} s ({} fitted), {} with an external pose",
        id.rows, id.rate_hz, id.duration_s, id.fitted_rows, id.external_pose_rows
    );
    let _ = writeln!(out, "kinematics:");
    let p = &prior.robot;
    line(
        &mut out,
        "wheel radius right",
        "m",
        &id.wheel_radius_m[0],
        Some(p.wheel_radius_m as f64),
    );
    line(
        &mut out,
        "wheel radius left",
        "m",
        &id.wheel_radius_m[1],
        Some(p.wheel_radius_m as f64),
    );
    let track = Estimate {
        value: 2.0 * id.half_track_m.value,
        ci95: 2.0 * id.half_track_m.ci95,
    };
    line(
        &mut out,
        "track 2h",
        "m",
        &track,
        Some(2.0 * p.half_track_m as f64),
    );
    line(
        &mut out,
        "yaw-rate offset",
        "rad/s",
        &id.yaw_offset_radps,
        None,
    );
    let _ = writeln!(
        out,
        "  residual RMS {:.5} rad (heading per horizon){}",
        id.yaw_residual_rad,
        id.displacement_residual_m
            .map_or(String::new(), |s| format!(
                ", {s:.5} m (displacement per horizon)"
            ))
    );
    if let Some(d) = &id.dynamics {
        let _ = writeln!(out, "dynamics ({:?} form):", d.form);
        dynamics(&mut out, d, prior);
    }
    if let Some(d) = &id.torque_check {
        let _ = writeln!(
            out,
            "cross-check against the commanded torques (torque form, prior motor trusted):"
        );
        dynamics(&mut out, d, prior);
    }
    if !id.notes.is_empty() {
        let _ = writeln!(out, "notes:");
        for n in &id.notes {
            let _ = writeln!(out, "  - {n}");
        }
    }
    out
}

/// The identified robot as TOML (the `RobotParams` fields, the mean of the
/// two radii; each value's interval and the per-wheel and friction values
/// in comments). Parameters the log did not determine keep the prior's
/// value, marked so.
pub fn robot_toml(id: &Identification, prior: &Prior) -> String {
    let p = &prior.robot;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "# Identified by `wmr identify fit` ({} rows, {:.1} s).",
        id.rows, id.duration_s
    );
    let _ = writeln!(
        out,
        "# value ± half-width of the 95 % confidence interval; see book/src/how-to/identification.md"
    );
    let mut kv = |key: &str, e: Option<&Estimate>, prior_value: f64| match e {
        Some(e) if e.ci95.is_finite() && !e.consistent_with_zero() => {
            let _ = writeln!(out, "{key} = {:.6} # ± {:.6}", e.value, e.ci95);
        }
        _ => {
            let _ = writeln!(
                out,
                "{key} = {prior_value:.6} # prior: not identified by this run"
            );
        }
    };
    let r = Estimate {
        value: 0.5 * (id.wheel_radius_m[0].value + id.wheel_radius_m[1].value),
        ci95: 0.5 * (id.wheel_radius_m[0].ci95 + id.wheel_radius_m[1].ci95),
    };
    let d = id.dynamics.as_ref();
    kv("mass_kg", d.map(|d| &d.mass_kg), p.mass_kg as f64);
    kv(
        "inertia_kgm2",
        d.map(|d| &d.inertia_kgm2),
        p.inertia_kgm2 as f64,
    );
    kv("wheel_inertia_kgm2", None, p.wheel_inertia_kgm2 as f64);
    kv("wheel_radius_m", Some(&r), p.wheel_radius_m as f64);
    kv(
        "half_track_m",
        (!id.track_from_prior).then_some(&id.half_track_m),
        p.half_track_m as f64,
    );
    kv(
        "com_offset_m",
        d.map(|d| &d.com_offset_m),
        p.com_offset_m as f64,
    );
    let _ = writeln!(
        out,
        "# wheel radius right {:.6}, left {:.6}",
        id.wheel_radius_m[0], id.wheel_radius_m[1]
    );
    if let Some(d) = d {
        let _ = writeln!(
            out,
            "# Coulomb friction [N·m] right {:.4}, left {:.4}",
            d.coulomb_nm[0], d.coulomb_nm[1]
        );
        let _ = writeln!(
            out,
            "# viscous friction [N·m·s/rad] right {:.4}, left {:.4}",
            d.viscous_nms_per_rad[0], d.viscous_nms_per_rad[1]
        );
        if let Some(k) = &d.emf_vs_per_rad {
            let _ = writeln!(
                out,
                "# EMF kappa = N·k + c_v/a [V·s/rad] right {:.4}, left {:.4}",
                k[0], k[1]
            );
        }
    }
    out
}

/// The identified robot as a robot file: `base` (the prior's file) with
/// the body's mass, inertia, centre-of-mass offset, both wheel radii and
/// the track, and each wheel's friction, replaced where the run identified
/// them (a friction whose interval contains zero, or below zero, is written
/// as 0); with a weighed mass, the mass and the identified torque per volt
/// a = η_g·N·k/R (as `motors.gear_efficiency`, or `motors.resistance_ohm`
/// when that efficiency would leave 0.1..=1); everything else (the other
/// motor constants, encoders, bridge, limits, gains) kept. The header comment is the report (every value with its
/// interval). Fails when the result is not a valid robot file (the error
/// names the field).
pub fn robot_file(
    id: &Identification,
    prior: &Prior,
    base: &robot_file::Robot,
) -> Result<String, String> {
    let mut r = base.clone();
    let ok = |e: &Estimate| e.ci95.is_finite() && !e.consistent_with_zero();
    if let Some(d) = &id.dynamics {
        if d.mass_given {
            r.body.mass_kg = d.mass_kg.value as f32;
            // The identified a = η_g·N·k/R: in the gear efficiency (the
            // number a datasheet knows least; N, k and the back-EMF N·k
            // are kept), else, beyond its range, in the resistance.
            let a = d.torque_per_volt.value as f32;
            let m = &mut r.motors;
            let eta = a * m.resistance_ohm / (m.gear_ratio * m.torque_constant_nm_per_a);
            if (0.1..=1.0).contains(&eta) {
                m.gear_efficiency = eta;
            } else {
                m.resistance_ohm =
                    m.gear_efficiency * m.gear_ratio * m.torque_constant_nm_per_a / a;
            }
        } else if ok(&d.mass_kg) {
            r.body.mass_kg = d.mass_kg.value as f32;
        }
        if ok(&d.inertia_kgm2) {
            r.body.inertia_kgm2 = d.inertia_kgm2.value as f32;
        }
        if ok(&d.com_offset_m) && d.com_offset_m.value >= 0.0 {
            r.body.com_offset_m = d.com_offset_m.value as f32;
        }
        let f = |e: &Estimate| if ok(e) { e.value.max(0.0) as f32 } else { 0.0 };
        for i in 0..2 {
            r.motors.coulomb_friction_nm[i] = f(&d.coulomb_nm[i]);
            r.motors.viscous_friction_nms_per_rad[i] = f(&d.viscous_nms_per_rad[i]);
        }
    }
    for i in 0..2 {
        if ok(&id.wheel_radius_m[i]) {
            r.body.wheel_radius_m[i] = id.wheel_radius_m[i].value as f32;
        }
    }
    if !id.track_from_prior && ok(&id.half_track_m) {
        r.body.track_m = 2.0 * id.half_track_m.value as f32;
    }
    r.validate()
        .map_err(|e| format!("the identified robot is not a valid robot file: {e}"))?;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "# Identified by `wmr identify fit` from {} rows over {:.1} s (book/src/how-to/identification.md);",
        id.rows, id.duration_s
    );
    let _ = writeln!(
        out,
        "# the fit's report (values ± the half-width of their 95 % confidence interval):"
    );
    for l in text(id, prior).lines() {
        let _ = writeln!(out, "#   {l}");
    }
    out.push_str(&r.to_toml_string());
    Ok(out)
}
