//! The z-gyro's logic above the registers (the STM32 firmware's `imu`
//! feature, an InvenSense MPU-6050 or a register-compatible chip on I2C):
//! raw counts to rad/s, the mounting, the probe decision, the read-back
//! checks, the plausibility monitor that rejects a frozen or implausible
//! gyro, the retry schedule after a failed probe, and the cell through
//! which the IMU task hands samples to the control tick.
//!
//! The firmware's `imu.rs` is the bus driver only (register addresses and
//! I2C transfers); everything here is host-tested (`tests/imu.rs`).

use core::cell::Cell;

use controller_core::estimator::GyroSample;
use controller_core::runtime::Gyro;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;

/// A sensor axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Axis {
    /// Sensor x.
    X = 0,
    /// Sensor y.
    Y = 1,
    /// Sensor z (perpendicular to the chip).
    Z = 2,
}

/// Which sensor axis measures the robot's yaw (about the robot's z axis,
/// up; positive counter-clockwise seen from above, the controller's θ
/// convention), and whether it reads backwards.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct YawMapping {
    /// The sensor axis parallel to the robot's vertical axis.
    pub axis: Axis,
    /// `true` when that axis points down (chip upside down): the reading
    /// is negated.
    pub inverted: bool,
}

/// Gyro full-scale ranges (GYRO_CONFIG FS_SEL) and their sensitivities
/// (MPU-6000/6050 product specification rev 3.4, table 6.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GyroRange {
    /// ±250 °/s, 131 LSB/(°/s).
    Dps250,
    /// ±500 °/s, 65.5 LSB/(°/s).
    Dps500,
    /// ±1000 °/s, 32.8 LSB/(°/s).
    Dps1000,
    /// ±2000 °/s, 16.4 LSB/(°/s).
    Dps2000,
}

impl GyroRange {
    /// Nominal full scale \[°/s\].
    pub const fn full_scale_dps(self) -> u16 {
        match self {
            Self::Dps250 => 250,
            Self::Dps500 => 500,
            Self::Dps1000 => 1000,
            Self::Dps2000 => 2000,
        }
    }

    /// Sensitivity \[LSB per °/s\].
    pub const fn lsb_per_dps(self) -> f32 {
        match self {
            Self::Dps250 => 131.0,
            Self::Dps500 => 65.5,
            Self::Dps1000 => 32.8,
            Self::Dps2000 => 16.4,
        }
    }

    /// One count in rad/s: (π/180) / sensitivity.
    pub const fn radps_per_lsb(self) -> f32 {
        core::f32::consts::PI / 180.0 / self.lsb_per_dps()
    }

    /// The largest |rate| the chip can report \[rad/s\]: 32 768 counts
    /// (the i16 limit) × [`radps_per_lsb`](Self::radps_per_lsb). A reading
    /// at the limit is clipped, not measured.
    pub const fn limit_radps(self) -> f32 {
        32_768.0 * self.radps_per_lsb()
    }

    /// FS_SEL (GYRO_CONFIG bits 4:3).
    pub const fn fs_sel(self) -> u8 {
        match self {
            Self::Dps250 => 0,
            Self::Dps500 => 1,
            Self::Dps1000 => 2,
            Self::Dps2000 => 3,
        }
    }
}

/// The robot's yaw rate \[rad/s\] from the raw gyro counts `[x, y, z]`:
/// `±raw[axis] × (π/180) / sensitivity`, negated for an inverted axis.
/// At ±500 °/s (65.5 LSB/(°/s)) one count is 2.665e-4 rad/s and
/// 32 767 counts are 8.731 rad/s.
pub const fn yaw_rate_radps(raw: [i16; 3], yaw: YawMapping, range: GyroRange) -> f32 {
    let rate = raw[yaw.axis as usize] as f32 * range.radps_per_lsb();
    if yaw.inverted {
        -rate
    } else {
        rate
    }
}

/// Chips that answer at the MPU-6050's address with the register layout
/// the firmware's driver uses (PWR_MGMT_1, SMPLRT_DIV, CONFIG, GYRO_CONFIG
/// and GYRO_XOUT_H..GYRO_ZOUT_L at the same addresses and meanings).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ImuChip {
    /// InvenSense MPU-6050 (WHO_AM_I 0x68), the GY-521 module.
    Mpu6050,
    /// InvenSense MPU-6500 (WHO_AM_I 0x70), fitted on many "GY-521"
    /// clones and on MPU-6500 modules.
    Mpu6500,
    /// InvenSense MPU-9250 (WHO_AM_I 0x71): an MPU-6500 with a
    /// magnetometer (not used).
    Mpu9250,
}

impl ImuChip {
    /// Name for the log.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Mpu6050 => "MPU-6050",
            Self::Mpu6500 => "MPU-6500",
            Self::Mpu9250 => "MPU-9250",
        }
    }
}

/// Why the gyro is not used (logged).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ImuFault {
    /// Nobody acknowledged the address: not fitted, not powered, wrong
    /// address (AD0 high: 0x69) or SDA/SCL swapped.
    NoAck,
    /// The transaction did not finish within the bus timeout (a line held
    /// low, no pull-ups).
    Timeout,
    /// Bus error, lost arbitration or overrun (noise, a second master,
    /// missing pull-ups).
    Bus,
    /// WHO_AM_I read 0x00 or 0xFF: lines stuck or floating.
    NoChip(u8),
    /// WHO_AM_I names a chip this driver does not know.
    UnknownChip(u8),
    /// The configuration read back differs from what was written
    /// (CONFIG, GYRO_CONFIG as read).
    ConfigMismatch(u8, u8),
    /// PWR_MGMT_1 read back asleep, in reset or on another clock (the
    /// value read): a sleeping chip holds its last output registers, which
    /// would read as a valid rate.
    NotAwake(u8),
    /// The readings stopped changing ([`GyroMonitor`]): a frozen chip
    /// (asleep after a brown-out, a dead sensor) or a bus that returns
    /// the same bytes.
    Frozen,
}

impl ImuFault {
    /// Whether the bus itself may be wedged (a slave holding SDA low after
    /// a cut transfer): the driver then clocks it free and re-creates the
    /// I2C peripheral before the next attempt.
    pub const fn needs_bus_recovery(self) -> bool {
        matches!(self, Self::Timeout | Self::Bus)
    }
}

/// The probe decision from the WHO_AM_I register (0x75).
pub const fn identify(who_am_i: u8) -> Result<ImuChip, ImuFault> {
    match who_am_i {
        0x68 => Ok(ImuChip::Mpu6050),
        0x70 => Ok(ImuChip::Mpu6500),
        0x71 => Ok(ImuChip::Mpu9250),
        0x00 | 0xFF => Err(ImuFault::NoChip(who_am_i)),
        other => Err(ImuFault::UnknownChip(other)),
    }
}

/// Checks the CONFIG (0x1A) and GYRO_CONFIG (0x1B) registers read back
/// after configuration: DLPF_CFG (CONFIG bits 2:0) and FS_SEL
/// (GYRO_CONFIG bits 4:3) as configured, the gyro self-test bits clear.
pub const fn check_config(config: u8, gyro_config: u8, dlpf: u8, range: GyroRange) -> bool {
    config & 0x07 == dlpf & 0x07 && gyro_config & 0xF8 == range.fs_sel() << 3
}

/// PWR_MGMT_1 as the driver writes it: awake (SLEEP = 0, CYCLE = 0),
/// temperature sensor on, clock = PLL with the X gyro reference (CLKSEL = 1).
pub const PWR_MGMT_1_AWAKE_PLL_X: u8 = 0x01;

/// Checks PWR_MGMT_1 (0x6B) read back: DEVICE_RESET (bit 7), SLEEP
/// (bit 6) and CYCLE (bit 5) clear, CLKSEL (bits 2:0) = 1, the value
/// written. A chip that browned out and came back in its reset state reads
/// 0x40 (asleep): rejected.
pub const fn check_awake(pwr_mgmt_1: u8) -> Result<(), ImuFault> {
    if pwr_mgmt_1 & 0xE7 == PWR_MGMT_1_AWAKE_PLL_X {
        Ok(())
    } else {
        Err(ImuFault::NotAwake(pwr_mgmt_1))
    }
}

/// The plausibility checks of a gyro reading.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MonitorConfig {
    /// Identical raw readings (all three axes, bit for bit) in a row after
    /// which the gyro counts as frozen. A live MEMS gyro's noise (MPU-6050:
    /// 0.005 °/s/√Hz, 0.05 °/s RMS at the 98 Hz filter: about 3 counts RMS
    /// at ±500 °/s) makes two equal 3-axis readings rare and
    /// `frozen_after` of them in a row practically impossible.
    pub frozen_after: u16,
    /// Largest physically possible |rate| on any axis \[rad/s\]: above it
    /// a reading is implausible (a corrupted transfer) and discarded. A
    /// wheeled robot's roll and pitch rates are far smaller than its yaw
    /// rate; the yaw rate of a spin in place at full motor speed bounds
    /// all three.
    pub max_rate_radps: f32,
}

/// A rejected [`MonitorConfig`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum MonitorConfigError {
    /// `frozen_after` below 2: one reading cannot repeat.
    FrozenAfterTooSmall,
    /// `max_rate_radps` not a positive finite rate.
    MaxRateInvalid,
}

/// What [`GyroMonitor::check`] concluded about one reading.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Verdict {
    /// A plausible reading: publish its yaw rate \[rad/s\].
    Valid(f32),
    /// Implausible (an axis beyond [`MonitorConfig::max_rate_radps`]):
    /// discard it (one bad transfer; the estimator keeps the last valid
    /// sample while it is fresh).
    Implausible,
    /// The readings stopped changing: the gyro is invalid from now on
    /// (withdraw the published sample so the estimator uses the wheels),
    /// until a reading differs.
    Frozen,
}

/// Counters of the plausibility monitor, since boot.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MonitorCounts {
    /// Readings rejected as implausible.
    pub implausible: u32,
    /// Times the gyro froze (episodes, not readings).
    pub frozen_episodes: u32,
}

/// Rejects a frozen or implausible gyro before its readings reach the
/// estimator: `frozen_after` bit-identical 3-axis readings in a row freeze
/// it (invalid until a reading differs), an axis beyond the physical rate
/// bound discards that reading.
#[derive(Clone, Copy, Debug)]
pub struct GyroMonitor {
    cfg: MonitorConfig,
    yaw: YawMapping,
    range: GyroRange,
    last: Option<[i16; 3]>,
    repeats: u16,
    frozen: bool,
    counts: MonitorCounts,
}

impl GyroMonitor {
    /// A monitor for a gyro mounted as `yaw` with full scale `range`.
    pub fn new(
        cfg: MonitorConfig,
        yaw: YawMapping,
        range: GyroRange,
    ) -> Result<Self, MonitorConfigError> {
        if cfg.frozen_after < 2 {
            return Err(MonitorConfigError::FrozenAfterTooSmall);
        }
        if !(cfg.max_rate_radps.is_finite() && cfg.max_rate_radps > 0.0) {
            return Err(MonitorConfigError::MaxRateInvalid);
        }
        Ok(Self {
            cfg,
            yaw,
            range,
            last: None,
            repeats: 0,
            frozen: false,
            counts: MonitorCounts::default(),
        })
    }

    /// Checks one raw reading `[x, y, z]`.
    pub fn check(&mut self, raw: [i16; 3]) -> Verdict {
        if self.last == Some(raw) {
            self.repeats = self.repeats.saturating_add(1);
        } else {
            self.repeats = 1;
            self.last = Some(raw);
            self.frozen = false;
        }
        if self.repeats >= self.cfg.frozen_after {
            if !self.frozen {
                self.frozen = true;
                self.counts.frozen_episodes = self.counts.frozen_episodes.saturating_add(1);
            }
            return Verdict::Frozen;
        }
        let limit = self.cfg.max_rate_radps;
        let per_lsb = self.range.radps_per_lsb();
        // |raw| × scale per axis; i16::MIN's magnitude fits in f32.
        if raw.iter().any(|&r| (r as f32 * per_lsb).abs() > limit) {
            self.counts.implausible = self.counts.implausible.saturating_add(1);
            return Verdict::Implausible;
        }
        Verdict::Valid(yaw_rate_radps(raw, self.yaw, self.range))
    }

    /// Forgets the reading history (after the chip was reconfigured: the
    /// first readings may repeat the last ones before the reset).
    pub fn restart(&mut self) {
        self.last = None;
        self.repeats = 0;
        self.frozen = false;
    }

    /// Whether the gyro is frozen now.
    pub fn is_frozen(&self) -> bool {
        self.frozen
    }

    /// Counters since boot.
    pub fn counts(&self) -> MonitorCounts {
        self.counts
    }
}

/// The wait before each bring-up attempt of the IMU: a power-up delay
/// before the first one (the chip's start-up, and a module powered from
/// the same rail as the MCU), then a doubling backoff up to a cap, forever:
/// a gyro plugged in, powered or freed later is found, and a gyro that is
/// absent costs one probe per `max_ms`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Backoff {
    first_ms: u32,
    max_ms: u32,
    next_ms: u32,
}

impl Backoff {
    /// Starts at `first_ms`, doubles per failed attempt, at most `max_ms`
    /// (both at least 1 ms, `first_ms <= max_ms`; out-of-order values are
    /// swapped, zero becomes 1 ms).
    pub const fn new(first_ms: u32, max_ms: u32) -> Self {
        let (a, b) = if first_ms <= max_ms {
            (first_ms, max_ms)
        } else {
            (max_ms, first_ms)
        };
        let a = if a == 0 { 1 } else { a };
        let b = if b == 0 { 1 } else { b };
        Self {
            first_ms: a,
            max_ms: b,
            next_ms: a,
        }
    }

    /// The wait before the next attempt \[ms\]; doubles the one after.
    pub fn next_wait_ms(&mut self) -> u32 {
        let w = self.next_ms;
        self.next_ms = self.next_ms.saturating_mul(2).min(self.max_ms);
        w
    }

    /// An attempt succeeded: the next failure starts from the first wait.
    pub fn reset(&mut self) {
        self.next_ms = self.first_ms;
    }
}

/// The newest gyro sample, written by the IMU task and read by the control
/// tick through [`GyroCell::reader`]. A critical-section cell: a few
/// instructions with interrupts masked, never a wait, so the control tick
/// cannot block on it. Put it in a `static`.
pub struct GyroCell {
    latest: Mutex<CriticalSectionRawMutex, Cell<Option<GyroSample>>>,
}

impl Default for GyroCell {
    fn default() -> Self {
        Self::new()
    }
}

impl GyroCell {
    /// Empty: the reader returns `None` (the estimator uses the wheels).
    pub const fn new() -> Self {
        Self {
            latest: Mutex::new(Cell::new(None)),
        }
    }

    /// The IMU task: a new valid sample.
    pub fn publish(&self, sample: GyroSample) {
        self.latest.lock(|c| c.set(Some(sample)));
    }

    /// The IMU task: the gyro is invalid now (frozen, not awake, lost):
    /// the reader returns `None` from the next tick on, so the estimator
    /// predicts with the wheels' yaw rate at once instead of after the
    /// staleness limit.
    pub fn invalidate(&self) {
        self.latest.lock(|c| c.set(None));
    }

    /// The newest sample, if any.
    pub fn latest(&self) -> Option<GyroSample> {
        self.latest.lock(Cell::get)
    }

    /// The board's [`Gyro`] on this cell.
    pub const fn reader(&'static self) -> CellGyro {
        CellGyro(self)
    }
}

/// The board's gyro: the newest sample in a [`GyroCell`].
#[derive(Clone, Copy)]
pub struct CellGyro(&'static GyroCell);

impl Gyro for CellGyro {
    fn sample(&mut self) -> Option<GyroSample> {
        self.0.latest()
    }
}

/// The two I2C lines driven as open-drain GPIOs, for [`recover_bus`].
pub trait RecoveryPins {
    /// Releases (`true`: pulled up) or pulls low (`false`) SCL.
    fn set_scl(&mut self, high: bool);
    /// Releases (`true`) or pulls low (`false`) SDA.
    fn set_sda(&mut self, high: bool);
    /// The SDA line's level (another device may hold it low).
    fn sda_is_high(&mut self) -> bool;
    /// Waits half an SCL period (5 µs: 100 kHz, within every device's
    /// standard-mode timing).
    fn half_period(&mut self);
}

/// SCL pulses [`recover_bus`] gives at most: a slave cut off in the middle
/// of a byte it transmits holds SDA low for at most 8 data bits and the
/// acknowledge; nine clocks always take it to the end of the byte, where
/// it sees no acknowledge and releases the bus (NXP UM10204 rev 7,
/// §3.1.16 "Bus clear").
pub const RECOVERY_PULSES: u8 = 9;

/// What [`recover_bus`] achieved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Recovery {
    /// SDA is free: after `pulses` SCL pulses (0: it was not held), then a
    /// STOP condition.
    Freed {
        /// SCL pulses given.
        pulses: u8,
    },
    /// SDA still low after [`RECOVERY_PULSES`] pulses: a short to ground,
    /// a dead or unpowered device clamping the line.
    StillHeld,
}

/// Frees an I2C bus that a slave holds (SDA stuck low after a transfer cut
/// off by a reset or a timeout): with the I2C peripheral off and both lines
/// as open-drain GPIOs, clocks SCL until SDA is released (at most
/// [`RECOVERY_PULSES`]), then generates a STOP (SDA rising while SCL is
/// high) so every device is back at the idle state. Leaves both lines
/// released.
pub fn recover_bus(p: &mut impl RecoveryPins) -> Recovery {
    p.set_sda(true);
    p.set_scl(true);
    p.half_period();
    let mut pulses = 0;
    while !p.sda_is_high() && pulses < RECOVERY_PULSES {
        p.set_scl(false);
        p.half_period();
        p.set_scl(true);
        p.half_period();
        pulses += 1;
    }
    let freed = p.sda_is_high();
    // STOP: SDA low while SCL is low, SCL high, then SDA high.
    p.set_scl(false);
    p.half_period();
    p.set_sda(false);
    p.half_period();
    p.set_scl(true);
    p.half_period();
    p.set_sda(true);
    p.half_period();
    if freed {
        Recovery::Freed { pulses }
    } else {
        Recovery::StillHeld
    }
}
