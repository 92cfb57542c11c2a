//! Small plain-data types shared by every module.

/// Planar pose of the tracked point G (the centre of mass, `d` ahead of the
/// axle midpoint), in the world frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Pose {
    /// x coordinate \[m\].
    pub x_m: f32,
    /// y coordinate \[m\].
    pub y_m: f32,
    /// Heading θ \[rad\].
    pub theta_rad: f32,
}

impl Pose {
    /// Pose from its three coordinates.
    pub const fn new(x_m: f32, y_m: f32, theta_rad: f32) -> Self {
        Self {
            x_m,
            y_m,
            theta_rad,
        }
    }

    /// True when every coordinate is finite.
    pub fn is_finite(&self) -> bool {
        self.x_m.is_finite() && self.y_m.is_finite() && self.theta_rad.is_finite()
    }
}

/// Body velocities η = \[v, ω\] of the paper (wheel-derived: the velocities the
/// wheels impose, which is what encoders measure).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Vel2 {
    /// Linear velocity v \[m/s\].
    pub v_mps: f32,
    /// Angular velocity ω \[rad/s\].
    pub omega_radps: f32,
}

impl Vel2 {
    /// Velocity pair from v and ω.
    pub const fn new(v_mps: f32, omega_radps: f32) -> Self {
        Self { v_mps, omega_radps }
    }

    /// As an array `[v, ω]`.
    pub const fn as_array(&self) -> [f32; 2] {
        [self.v_mps, self.omega_radps]
    }

    /// From an array `[v, ω]`.
    pub const fn from_array(a: [f32; 2]) -> Self {
        Self {
            v_mps: a[0],
            omega_radps: a[1],
        }
    }

    /// True when both components are finite.
    pub fn is_finite(&self) -> bool {
        self.v_mps.is_finite() && self.omega_radps.is_finite()
    }
}
