//! Random robots for property tests (issue 34): light robots whose gearbox
//! friction is 30-60 % of the torque limit, drawn from a seed, each a valid
//! robot file. One generator for every test that draws them
//! (tests/tests/friction.rs, hil-sim/tests/bringup_never_worse.rs).

use crate::scenario::Robot;

/// A tiny seeded generator (SplitMix64): uniform in [lo, hi).
pub fn draw(state: &mut u64, lo: f64, hi: f64) -> f64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    let u = ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64;
    lo + (hi - lo) * u
}

/// A light robot drawn at random around `base` (robots/n20-0p85kg.toml in
/// the tests; its bridge, encoders and gains are kept): wheel
/// radius, track, supply, gear ratio, a no-load speed of 1.2-2 m/s and a
/// stall torque of 0.15-0.6 N·m (the motor constant and resistance from
/// them), the torque limit 35-60 % of the stall torque, Coulomb friction 30-60 % of
/// the limit, a mass that the limit less the friction accelerates at twice
/// `limits.max_accel_mps2` or more, and the inertia of a plate of that mass.
/// Every draw is a valid robot file (validated).
pub fn light_robot(base: &Robot, state: &mut u64) -> (Robot, f64) {
    let mut r = base.clone();
    let radius_m = draw(state, 0.02, 0.05);
    let track_m = draw(state, 0.1, 0.25);
    let m = &mut r.motors;
    m.supply_voltage_v = draw(state, 5.0, 12.0) as f32;
    m.gear_ratio = draw(state, 30.0, 150.0) as f32;
    m.gear_efficiency = draw(state, 0.5, 0.8) as f32;
    let no_load_mps = draw(state, 1.2, 2.0);
    // k·N from the no-load speed r·V/(k·N), R from the stall torque η·k·N·V/R.
    let k_n = m.supply_voltage_v as f64 * radius_m / no_load_mps;
    m.torque_constant_nm_per_a = (k_n / m.gear_ratio as f64) as f32;
    let stall_nm = draw(state, 0.15, 0.6);
    m.resistance_ohm =
        (m.gear_efficiency as f64 * k_n * m.supply_voltage_v as f64 / stall_nm) as f32;
    let limit_nm = draw(state, 0.35, 0.6) * stall_nm;
    let friction_fraction = draw(state, 0.3, 0.6);
    let c = friction_fraction * limit_nm;
    m.coulomb_friction_nm = [c as f32; 2];
    m.viscous_friction_nms_per_rad = [(0.01 * c * radius_m) as f32; 2];
    r.limits.torque_nm = limit_nm as f32;
    r.limits.max_speed_mps = 0.6;
    r.limits.max_yaw_rate_radps = 4.0;
    r.limits.max_accel_mps2 = 1.0;
    let b = &mut r.body;
    b.wheel_radius_m = [radius_m as f32; 2];
    b.track_m = track_m as f32;
    b.mass_kg = (draw(state, 0.25, 0.5) * 2.0 * (limit_nm - c) / radius_m) as f32;
    let (a, w) = (1.1 * track_m, 0.9 * track_m);
    b.inertia_kgm2 = b.mass_kg * ((a * a + w * w) / 12.0) as f32;
    b.wheel_inertia_kgm2 = 0.2 * b.mass_kg * (radius_m * radius_m) as f32;
    b.com_offset_m = 0.0;
    let name = format!(
        "random-{:.0}g-{:.0}pct",
        1000.0 * b.mass_kg,
        100.0 * friction_fraction
    );
    r.name = name.as_str().try_into().expect("a short name");
    if let Err(e) = r.validate() {
        panic!(
            "the generator drew an invalid robot {}: {e}\n{r:#?}",
            r.name
        );
    }
    (r, friction_fraction)
}
