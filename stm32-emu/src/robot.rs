//! The simulated robot behind the pins: sim-robot's plant (the project's
//! one plant, RK4), its DC-motor drive and its 16-bit encoders, advanced in
//! emulated time on a fixed grid of [`STEP_PS`], with the H-bridge inputs
//! (PWM duty from TIM1's outputs, DIR and ENABLE pin levels) held over each
//! step. By default the robot is the firmware's compiled-in one
//! (firmware/src/config.rs): the paper's body (Table 1), controller-core's
//! example motors and 24 000-count encoders, the left motor and encoder
//! mirrored; [`Robot::of_file`] makes it a robot file's (`--robot FILE`).
//! It does not reset when the chip does.

pub use controller_core::runtime::BridgeMode;
use controller_core::runtime::{
    DutyCommand, EncoderParams, MotorDriver, MotorModel, MotorParams, WheelEncoders,
};
use controller_core::RobotParams;
use sim_robot::{
    Drive, MotorDrive, Perturbation, Plant, PlantParams, PlantState, SimDriver, SimEncoders,
};

/// sim-robot's motor drive with a per-wheel coast: an open bridge gives no
/// torque (the motor model's duty 0 is a brake: zero volts on the winding).
struct CoastingDrive {
    drive: MotorDrive,
    coast: [bool; 2],
}

impl Drive for CoastingDrive {
    fn torque_nm(&self, wheel_rates_radps: [f64; 2]) -> [f64; 2] {
        let t = self.drive.torque_nm(wheel_rates_radps);
        [0, 1].map(|i| if self.coast[i] { 0.0 } else { t[i] })
    }
}

/// Plant integration step \[ps\]: 100 µs (ten RK4 steps per 1 ms control
/// period; a bridge change takes effect at the next grid point).
pub const STEP_PS: u128 = 100_000_000;

/// Duty resolution the armature voltage is handed to sim-robot's motor
/// model with (a fraction of the supply in 1/10 000).
pub const ARMATURE_FULL_SCALE: u16 = 10_000;

/// What the H-bridges apply, per wheel `[right, left]`, computed from the
/// pins by the bridge model of the board's [`BridgeMode`]
/// (`Board::bridge`), and the pin levels the safety checks read.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BridgeInputs {
    /// Mean armature voltage over the PWM period as a fraction of the
    /// supply (+ forward, drive/brake: the time driving forward minus the
    /// time driving in reverse, braking counts 0), or `None` when the
    /// bridge is off (coasting: every switch open) for the whole period.
    pub armature: [Option<f64>; 2],
    /// PWM high counts and period on PA8/PA9 (for the event log).
    pub pwm: [(u32, u32); 2],
    /// Every motor line that is high (or PWM) at some time: bit n = PBn
    /// for PB0, PB1, PB12-PB15, bits 8/9 = PA8/PA9.
    pub high_lines: u16,
    /// ENABLE (PB14) level.
    pub enable: bool,
}

impl BridgeInputs {
    /// True when no wheel is driven: every bridge coasting or at zero volts.
    pub fn motors_off(&self) -> bool {
        self.armature.iter().all(|a| a.is_none_or(|u| u == 0.0))
    }

    /// True when every motor line of every bridge mode is low (ENABLE,
    /// DIR / IN lines, PWM).
    pub fn all_low(&self) -> bool {
        self.high_lines == 0
    }
}

/// The robot.
pub struct Robot {
    plant: Plant,
    state: PlantState,
    encoders: SimEncoders,
    motor: MotorParams,
    inverted: [bool; 2],
    t_ps: u128,
    still: Perturbation,
    /// Plant steps taken.
    pub steps: u64,
}

impl Robot {
    /// The firmware's robot at rest at the origin.
    pub fn new() -> Self {
        let enc = EncoderParams::EXAMPLE;
        Self {
            plant: Plant::new(PlantParams::from_robot(&RobotParams::paper(), 1.0, 1.0)),
            state: PlantState {
                q: [0.0; 5],
                nu: [0.0; 2],
            },
            encoders: SimEncoders::new(&enc),
            motor: MotorParams::EXAMPLE,
            inverted: controller_core::runtime::MIRRORED_LEFT,
            t_ps: 0,
            still: Perturbation::default(),
            steps: 0,
        }
    }

    /// The robot of a robot file (book/src/how-to/robot-file.md) at rest at the origin:
    /// sim-robot's plant with the file's body, per-wheel radii and
    /// friction, its motors, encoders (counting the true wheel angle) and
    /// motor directions, as `sim_robot::WorldConfig::of_robot` builds
    /// hil-sim's plant from the same file.
    pub fn of_file(robot: &robot_file::Robot) -> Result<Self, String> {
        robot.validate().map_err(|e| format!("robot file: {e}"))?;
        let plant = PlantParams::of_robot(robot);
        let enc = EncoderParams {
            radius_scale: [1.0; 2],
            ..robot.encoder_params()
        };
        Ok(Self {
            plant: Plant::new(plant),
            encoders: SimEncoders::new(&enc),
            motor: robot.motor_params(ARMATURE_FULL_SCALE),
            inverted: robot.bridge.motor_inverted,
            ..Self::new()
        })
    }

    /// Advances to `now_ps` with `bridge` held; an error when the state
    /// diverges.
    pub fn advance(&mut self, now_ps: u128, bridge: &BridgeInputs) -> Result<(), String> {
        if self.t_ps + STEP_PS > now_ps {
            return Ok(());
        }
        let model = MotorModel::new(MotorParams {
            duty_full_scale: ARMATURE_FULL_SCALE,
            ..self.motor
        })
        .map_err(|e| format!("motor model: {e:?}"))?;
        let mut driver = SimDriver::default();
        driver.set(bridge.armature.map(|a| {
            let u = a.unwrap_or(0.0).clamp(-1.0, 1.0);
            DutyCommand {
                duty: (u.abs() * ARMATURE_FULL_SCALE as f64).round() as u16,
                reverse: u < 0.0,
            }
        }));
        let drive = CoastingDrive {
            drive: MotorDrive {
                model,
                bridge: driver,
                inverted: self.inverted,
            },
            coast: bridge.armature.map(|a| a.is_none()),
        };
        let dt = STEP_PS as f64 * 1e-12;
        while self.t_ps + STEP_PS <= now_ps {
            let t_s = self.t_ps as f64 * 1e-12;
            let still = self.still;
            self.state = self
                .plant
                .rk4_step(&self.state, t_s, dt, &drive, &mut |_| still);
            if !Plant::state_is_finite(&self.state) {
                return Err(format!("plant diverged at t = {t_s:.4} s"));
            }
            self.t_ps += STEP_PS;
            self.steps += 1;
        }
        self.encoders.set_angles([self.state.q[3], self.state.q[4]]);
        Ok(())
    }

    /// Raw 16-bit encoder positions `[right, left]` (left mirrored).
    pub fn encoder_counts(&mut self) -> [u16; 2] {
        self.encoders.counts()
    }

    /// True pose of G `[x m, y m, θ rad]`.
    pub fn pose(&self) -> [f64; 3] {
        [self.state.q[0], self.state.q[1], self.state.q[2]]
    }

    /// Yaw rate θ̇ \[rad/s\] (counter-clockwise positive): η's ω.
    pub fn yaw_rate_radps(&self) -> f64 {
        self.plant.eta(&self.state, &self.still)[1]
    }

    /// Wheel speeds `[right, left]` \[rad/s\].
    pub fn wheel_rates(&self) -> [f64; 2] {
        self.plant.wheel_rates_radps(&self.state, &self.still)
    }
}

impl Default for Robot {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Full forward duty on both bridges: both wheels turn forward, the
    /// right encoder counts up and the mirrored left one down; disabled
    /// the robot stays put (no torque).
    #[test]
    fn bridge_drives_wheels_and_encoders() {
        let mut r = Robot::new();
        let off = BridgeInputs::default();
        r.advance(10 * STEP_PS, &off).unwrap();
        assert_eq!(r.encoder_counts(), [0, 0]);
        let on = BridgeInputs {
            // Half the supply, the mirrored left motor reversed (the
            // runtime flips its direction).
            armature: [Some(0.5), Some(-0.5)],
            pwm: [(4200, 8400); 2],
            high_lines: 0x7300,
            enable: true,
        };
        r.advance(5_000 * STEP_PS, &on).unwrap();
        let [cr, cl] = r.encoder_counts();
        assert!((cr as i16) > 100, "right counts up: {cr}");
        assert!((cl as i16) < -100, "left counts down: {cl}");
        assert!(r.pose()[0] > 0.01, "moved forward: {:?}", r.pose());
    }
}
