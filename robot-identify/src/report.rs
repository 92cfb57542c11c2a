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
    if d.mass_given() {
        let _ = writeln!(
            out,
            "  {:<22} {:>12.5} {:<12} {:<10}    given (--mass-kg)   (prior {:.5})",
            "mass m", d.mass_kg.value, "", "kg", p.mass_kg
        );
    } else {
        line(out, "mass m", "kg", &d.mass_kg, Some(p.mass_kg as f64));
    }
    if d.form == crate::fit::Form::Voltage && d.mass_given() {
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

/// Lowers each motion limit of `r` that its (identified) motors cannot
/// give to what they can, rounded down to 3 significant digits, and says
/// so: a gearbox 20 % weaker than the datasheet holds less speed against
/// its friction (the N20 robot's 0.6 m/s above its identified 0.598), and
/// a robot file the validator refuses is of no use to its user (D218).
/// The limits that bound others (`limits.torque_nm`) are never raised or
/// lowered here.
pub fn lower_limits_to_bounds(r: &mut robot_file::Robot) -> Vec<String> {
    let mut said = Vec::new();
    for _ in 0..4 {
        let Err(e) = r.validate() else { break };
        let robot_file::Reason::Exceeds {
            value,
            limit,
            unit,
            with,
            ..
        } = e.reason
        else {
            break;
        };
        let l = &mut r.limits;
        let slot = match e.field {
            "limits.max_speed_mps" => &mut l.max_speed_mps,
            "limits.max_yaw_rate_radps" => &mut l.max_yaw_rate_radps,
            "limits.max_accel_mps2" => &mut l.max_accel_mps2,
            _ => break,
        };
        if !(limit.is_finite() && limit > 0.0) {
            break;
        }
        let scale = 10f32.powi(2 - limit.log10().floor() as i32);
        let new = (limit * scale).floor() / scale;
        *slot = new;
        said.push(format!(
            "{} lowered from {value} to {new} {unit}: the identified robot's bound is {limit:.4} {unit} ({with})",
            e.field
        ));
    }
    said
}

/// Puts back the prior's (`base`'s) value of an identified field the
/// robot file refuses, and says so: the first refusal of `r.validate()`
/// when it names a field the fit writes (a Coulomb friction identified
/// above half the stall torque from a run whose rows mostly saturated
/// against it). Nothing when `r` is valid or the refusal is another
/// field's (D218).
pub fn keep_refused_at_prior(r: &mut robot_file::Robot, base: &robot_file::Robot) -> Vec<String> {
    let Err(e) = r.validate() else {
        return Vec::new();
    };
    let (b, m, bb, bm) = (&mut r.body, &mut r.motors, &base.body, &base.motors);
    let (slot, prior) = match e.field {
        "body.mass_kg" => (&mut b.mass_kg, bb.mass_kg),
        "body.inertia_kgm2" => (&mut b.inertia_kgm2, bb.inertia_kgm2),
        "body.com_offset_m" => (&mut b.com_offset_m, bb.com_offset_m),
        "body.track_m" => (&mut b.track_m, bb.track_m),
        "body.wheel_radius_m[0]" => (&mut b.wheel_radius_m[0], bb.wheel_radius_m[0]),
        "body.wheel_radius_m[1]" => (&mut b.wheel_radius_m[1], bb.wheel_radius_m[1]),
        "motors.coulomb_friction_nm[0]" => {
            (&mut m.coulomb_friction_nm[0], bm.coulomb_friction_nm[0])
        }
        "motors.coulomb_friction_nm[1]" => {
            (&mut m.coulomb_friction_nm[1], bm.coulomb_friction_nm[1])
        }
        "motors.viscous_friction_nms_per_rad[0]" => (
            &mut m.viscous_friction_nms_per_rad[0],
            bm.viscous_friction_nms_per_rad[0],
        ),
        "motors.viscous_friction_nms_per_rad[1]" => (
            &mut m.viscous_friction_nms_per_rad[1],
            bm.viscous_friction_nms_per_rad[1],
        ),
        "motors.gear_efficiency" => (&mut m.gear_efficiency, bm.gear_efficiency),
        "motors.resistance_ohm" => (&mut m.resistance_ohm, bm.resistance_ohm),
        _ => return Vec::new(),
    };
    if *slot == prior {
        return Vec::new();
    }
    let was = *slot;
    *slot = prior;
    vec![format!(
        "{} identified as {was} is refused by the robot file ({e}): the prior's {prior} is written",
        e.field
    )]
}

/// The friction written for an estimate `e` of a friction whose prior
/// value is `prior`: the estimate when the run identified it (at least 0);
/// one the run cannot tell from zero is 0 when its interval excludes the
/// prior's value (the run says it is smaller), and the prior's when the
/// interval holds both (the run says nothing: an excitation that
/// saturated against friction wrote 0 for a gearbox that eats 75 % of the
/// torque limit, D218).
pub fn written_friction(e: &Estimate, prior: f32) -> f32 {
    if e.ci95.is_finite() && !e.consistent_with_zero() {
        e.value.max(0.0) as f32
    } else if (e.value - prior as f64).abs() <= e.ci95 {
        prior
    } else {
        0.0
    }
}

/// The identified robot as a robot file: `base` (the prior's file) with
/// the body's mass, inertia, centre-of-mass offset, both wheel radii and
/// the track, and each wheel's friction, replaced where the run identified
/// them (a friction whose interval contains zero but not the prior's value
/// is written as 0, one whose interval holds both keeps the prior's, one
/// identified below zero is 0); with a weighed mass, the mass and the identified torque per volt
/// a = η_g·N·k/R (as `motors.gear_efficiency`, or `motors.resistance_ohm`
/// when that efficiency would leave 0.1..=1); everything else (the other
/// motor constants, encoders, bridge, limits, gains) kept. The header comment is the report (every value with its
/// interval). An identified value the file refuses keeps the prior's, a
/// motion limit the identified motors cannot give is lowered to their
/// bound ([`keep_refused_at_prior`], [`lower_limits_to_bounds`]): each
/// said in the header and returned with the text. Fails when the result
/// is still not a valid robot file (the error names the field).
pub fn robot_file(
    id: &Identification,
    prior: &Prior,
    base: &robot_file::Robot,
) -> Result<(String, Vec<String>), String> {
    let mut r = base.clone();
    let ok = |e: &Estimate| e.ci95.is_finite() && !e.consistent_with_zero();
    if let Some(d) = &id.dynamics {
        if d.mass_given() {
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
        } else if let Some(m) = d.weighed_mass_kg {
            // Weighed, but the run could not fix the scale with it (D218):
            // the mass is the scale's, a the prior's.
            r.body.mass_kg = m as f32;
        } else if ok(&d.mass_kg) && d.translation_determined() {
            r.body.mass_kg = d.mass_kg.value as f32;
        }
        if ok(&d.inertia_kgm2) {
            r.body.inertia_kgm2 = d.inertia_kgm2.value as f32;
        }
        if ok(&d.com_offset_m) && d.com_offset_m.value >= 0.0 && d.translation_determined() {
            r.body.com_offset_m = d.com_offset_m.value as f32;
        }
        let f = written_friction;
        let m = &mut r.motors;
        for i in 0..2 {
            m.coulomb_friction_nm[i] = f(&d.coulomb_nm[i], m.coulomb_friction_nm[i]);
            m.viscous_friction_nms_per_rad[i] =
                f(&d.viscous_nms_per_rad[i], m.viscous_friction_nms_per_rad[i]);
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
    let mut lowered = Vec::new();
    for _ in 0..8 {
        let mut said = lower_limits_to_bounds(&mut r);
        said.extend(keep_refused_at_prior(&mut r, base));
        if said.is_empty() {
            break;
        }
        lowered.extend(said);
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
    for l in &lowered {
        let _ = writeln!(out, "# {l}");
    }
    out.push_str(&r.to_toml_string());
    Ok((out, lowered))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn e(value: f64, ci95: f64) -> Estimate {
        Estimate { value, ci95 }
    }

    /// Identified: written (a negative one as 0); not told from zero: 0
    /// when the interval excludes the prior, the prior when it holds it;
    /// not identified at all (∞): the prior.
    #[test]
    fn a_friction_changes_only_where_the_run_says_so() {
        assert_eq!(written_friction(&e(0.05, 0.01), 0.03), 0.05);
        assert_eq!(written_friction(&e(-0.05, 0.01), 0.03), 0.0);
        assert_eq!(written_friction(&e(0.002, 0.004), 0.03), 0.0);
        assert_eq!(written_friction(&e(0.31, 1.63), 0.069), 0.069);
        assert_eq!(written_friction(&e(0.0, f64::INFINITY), 0.069), 0.069);
        assert_eq!(written_friction(&e(0.0, 0.0), 0.0), 0.0);
    }

    /// An identified friction the file refuses (above half the stall
    /// torque) goes back to the prior's, said; a valid file is untouched.
    #[test]
    fn a_refused_identified_value_goes_back_to_the_prior() {
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
        let text = std::fs::read_to_string(format!("{root}/robots/n20-0p85kg.toml")).unwrap();
        let base = robot_file::Robot::from_toml_str(&text).unwrap();
        let mut r = base.clone();
        assert!(keep_refused_at_prior(&mut r, &base).is_empty());
        r.motors.coulomb_friction_nm[1] = 0.9 * r.limits.torque_nm + 1.0;
        let said = keep_refused_at_prior(&mut r, &base);
        assert_eq!(r, base);
        assert!(
            said[0].starts_with("motors.coulomb_friction_nm[1] identified as"),
            "{said:?}"
        );
    }

    /// A file whose speed limit its motors cannot hold against their
    /// friction (the validator's bound) gets the bound, rounded down to 3
    /// digits, and validates; a valid file is left as it is.
    #[test]
    fn a_limit_beyond_the_identified_motors_is_lowered_to_their_bound() {
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
        let text = std::fs::read_to_string(format!("{root}/robots/n20-0p85kg.toml")).unwrap();
        let mut r = robot_file::Robot::from_toml_str(&text).unwrap();
        assert!(lower_limits_to_bounds(&mut r.clone()).is_empty());
        r.motors.gear_efficiency *= 0.7;
        let before = r.limits.max_speed_mps;
        assert!(r.validate().is_err());
        let said = lower_limits_to_bounds(&mut r);
        r.validate().unwrap();
        let top = r.friction_limited_speed_mps();
        assert!(
            r.limits.max_speed_mps <= top && r.limits.max_speed_mps > 0.99 * top,
            "{said:?}"
        );
        assert!(r.limits.max_speed_mps < before);
        assert!(
            said[0].starts_with("limits.max_speed_mps lowered from 0.6 to"),
            "{said:?}"
        );
    }
}
