//! Physical bounds that every consumer of a robot checks with the same
//! numbers (issue 31 item 3): the robot file's validation (robot-file), the
//! device's limits and parameter ranges (wmr-device `limits`, D41), and so
//! the store's commit and the board's boot. A robot the file accepts is a
//! robot the device accepts. Each parameter's range is declared once in
//! [`super::param_table`] from these.

/// Largest speed any command or reference may ask \[m/s\].
pub const MAX_SPEED_MPS: f32 = 10.0;
/// Largest yaw rate any command or reference may ask \[rad/s\].
pub const MAX_YAW_RATE_RADPS: f32 = 30.0;
/// Largest acceleration of velocity commands and deceleration of a
/// controlled stop \[m/s²\] (2 g: beyond any wheel's grip).
pub const MAX_ACCEL_MPS2: f32 = 20.0;
/// Least acceleration of velocity commands \[m/s²\].
pub const MIN_ACCEL_MPS2: f32 = 0.01;
/// Least speed and yaw-rate limit of velocity commands \[m/s, rad/s\].
pub const MIN_COMMAND_LIMIT: f32 = 0.01;
/// Least torque limit and stall torque \[N·m\].
pub const MIN_TORQUE_NM: f32 = 0.01;
/// Least deceleration of a controlled stop \[m/s²\]: the gentlest stop
/// the device makes (a walking-pace robot at 1 m/s stops within 4 s).
pub const MIN_BRAKE_DECEL_MPS2: f32 = 0.25;
/// Least angular acceleration of velocity commands and of the braking
/// profile \[rad/s²\].
pub const MIN_ANG_ACCEL_RADPS2: f32 = 1.0;
/// Largest angular acceleration \[rad/s²\].
pub const MAX_ANG_ACCEL_RADPS2: f32 = 50.0;
/// Least controller gain (k_x, k_y, k_θ, k_s in their units): a smaller one
/// corrects nothing within a run.
pub const MIN_GAIN: f32 = 1e-3;

/// The fastest closed-loop rate a gain may ask at control period
/// `period_s`: half the control rate 1/(2·period) \[1/s\]; k_x, k_θ and
/// k_s are at most this.
pub fn max_gain_rate_per_s(period_s: f32) -> f32 {
    0.5 / period_s
}

/// The largest k_y \[rad/m²\] at control period `period_s` for a robot whose
/// top speed is `top_speed_mps`: the lateral mode of eq. (14) linearised
/// about the reference, ë_y + k_θ·ė_y + k_y·v²·e_y = 0, has the rate
/// v·√k_y, at most [`max_gain_rate_per_s`] at top speed.
pub fn max_ky(period_s: f32, top_speed_mps: f32) -> f32 {
    let r = max_gain_rate_per_s(period_s) / top_speed_mps;
    r * r
}

/// The top speed the device uses for its limits: the no-load ground speed
/// `wheel_radius_m`·V/(k·N) at `no_load_wheel_radps`, at most
/// [`MAX_SPEED_MPS`] \[m/s\].
pub fn top_speed_mps(wheel_radius_m: f32, no_load_wheel_radps: f32) -> f32 {
    (no_load_wheel_radps * wheel_radius_m).min(MAX_SPEED_MPS)
}
