//! The z-gyro (`imu` feature): an InvenSense MPU-6050 on I2C1, read by its
//! own embassy task, published to the control task through a cell.
//!
//! The control tick never touches the bus: [`imu_task`] probes the chip
//! (WHO_AM_I), resets and configures it (a register-level driver of about
//! 60 lines over embassy's async I2C with DMA: the `mpu6050-dmp` crate
//! costs 6.3 KB more flash, see firmware/README.md "IMU") and then reads
//! the three gyro axes every millisecond, converts the yaw axis to rad/s
//! ([`yaw_rate_radps`])
//! and stores the newest [`GyroSample`] in [`LATEST`]. The board's
//! [`ImuGyro`] hands that sample to the estimator once per tick: `None`
//! until the first sample (the estimator then runs on the wheels' yaw rate,
//! exactly like `NoGyro`), and the sample's stamp lets the estimator reject
//! it as stale (`EstimatorConfig::gyro_stale_us`) when the task stops
//! delivering.
//!
//! Failures never block start-up or stop the robot:
//! * at boot, a chip that does not answer, answers with an unknown
//!   WHO_AM_I, or rejects its configuration is logged (`gyro: ...`) and the
//!   task ends: the firmware runs on odometry;
//! * at run time, [`READ_FAILURES_LOST`] failed reads in a row are logged
//!   as a lost gyro; the samples stop (stale after 20 ms: wheel yaw rate),
//!   and the task re-probes and reconfigures the chip every
//!   [`RETRY_MS`] (a chip that lost power comes back asleep with its reset
//!   configuration, so after a loss it is reconfigured before it is read
//!   again; a power glitch shorter than those 20 reads goes unnoticed).
//!
//! The pure part (raw counts to rad/s, axis and sign mapping, the WHO_AM_I
//! decision) is `const fn`, and the `const` assertions at the end of this
//! file check it at compile time in every build with the `imu` feature (the
//! firmware crate has no host tests).

use core::cell::Cell;

use controller_core::estimator::GyroSample;
use controller_core::runtime::Gyro;
use defmt::{error, info, unwrap, warn};
use embassy_executor::Spawner;
use embassy_stm32::i2c::{self, I2c};
use embassy_stm32::mode::Async;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_time::{with_timeout, Duration, Instant, Ticker, Timer};

use crate::board::{ImuPeripherals, IMU_I2C_ADDRESS, IMU_I2C_HZ};
use crate::config::{IMU_DLPF, IMU_RANGE, IMU_YAW};

/// The newest sample, written by [`imu_task`], read by [`ImuGyro`]. A
/// critical-section cell: a few instructions with interrupts masked, never
/// a wait, so the control tick cannot block on it.
static LATEST: Mutex<CriticalSectionRawMutex, Cell<Option<GyroSample>>> =
    Mutex::new(Cell::new(None));

/// The board's gyro with the `imu` feature: the newest sample of the IMU
/// task, `None` until there is one (and forever when the IMU did not
/// answer at boot: the `NoGyro` behaviour).
#[derive(Clone, Copy, Debug, Default)]
pub struct ImuGyro;

impl Gyro for ImuGyro {
    fn sample(&mut self) -> Option<GyroSample> {
        LATEST.lock(Cell::get)
    }
}

/// Gyro sampling period \[µs\]: the chip's output rate with its low-pass
/// filter on (1 kHz internal rate, SMPLRT_DIV = 0), the control rate.
pub const SAMPLE_PERIOD_US: u64 = 1_000;
/// Longest wait for one bus transaction \[ms\] (a gyro read takes about
/// 0.25 ms at 400 kHz: 9 bytes of 9 bits plus start/stop); a stuck bus
/// counts as a failed read.
pub const BUS_TIMEOUT_MS: u64 = 5;
/// Failed reads in a row after which the gyro counts as lost (logged; at
/// one read per ms this is also about the estimator's 20 ms staleness).
pub const READ_FAILURES_LOST: u32 = 20;
/// Pause between reconfiguration attempts after a run-time loss \[ms\].
pub const RETRY_MS: u64 = 1_000;

/// WHO_AM_I (register 117).
const REG_WHO_AM_I: u8 = 0x75;

/// A sensor axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
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
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub struct YawMapping {
    /// The sensor axis parallel to the robot's vertical axis.
    pub axis: Axis,
    /// `true` when that axis points down (chip upside down): the reading
    /// is negated.
    pub inverted: bool,
}

/// Gyro full-scale ranges (GYRO_CONFIG FS_SEL) and their sensitivities
/// (MPU-6000/6050 product specification rev 3.4, table 6.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
#[allow(dead_code)] // the choices for `config::IMU_RANGE`
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
/// this driver uses (PWR_MGMT_1, SMPLRT_DIV, CONFIG, GYRO_CONFIG and
/// GYRO_XOUT_H..GYRO_ZOUT_L at the same addresses and meanings).
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
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
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
#[non_exhaustive]
pub enum ImuFault {
    /// Nobody acknowledged the address: not fitted, not powered, wrong
    /// address (AD0 high: 0x69) or SDA/SCL swapped.
    NoAck,
    /// The transaction did not finish within [`BUS_TIMEOUT_MS`] (a line
    /// held low, no pull-ups).
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

fn fault(e: i2c::Error) -> ImuFault {
    match e {
        i2c::Error::Nack => ImuFault::NoAck,
        i2c::Error::Timeout => ImuFault::Timeout,
        _ => ImuFault::Bus,
    }
}

type Bus = I2c<'static, Async, i2c::Master>;

/// MPU-6050 registers (register map rev 4.2).
const REG_SMPLRT_DIV: u8 = 0x19;
const REG_GYRO_XOUT_H: u8 = 0x43;
const REG_PWR_MGMT_1: u8 = 0x6B;
/// PWR_MGMT_1: DEVICE_RESET.
const PWR_RESET: u8 = 0x80;
/// PWR_MGMT_1: awake (SLEEP = 0), clock = PLL with the X gyro reference
/// (CLKSEL = 1, recommended over the internal 8 MHz oscillator).
const PWR_AWAKE_PLL_X: u8 = 0x01;
/// Wait after DEVICE_RESET \[ms\] (the register map gives no figure; the
/// reference driver and the `mpu6050-dmp` crate wait 100-200 ms).
const RESET_WAIT_MS: u64 = 100;

/// The configuration writes after the reset and wake-up, in order:
/// SMPLRT_DIV = 0 (1 kHz with the DLPF on), CONFIG = DLPF_CFG (FSYNC off),
/// GYRO_CONFIG = FS_SEL (self-test off). 0x19-0x1B are consecutive and
/// written in one burst; read back in one burst too.
const CONFIG_BURST: [u8; 4] = [REG_SMPLRT_DIV, 0, IMU_DLPF, IMU_RANGE.fs_sel() << 3];

/// One write-read with the bus timeout.
async fn read(bus: &mut Bus, reg: u8, buf: &mut [u8]) -> Result<(), ImuFault> {
    match with_timeout(
        Duration::from_millis(BUS_TIMEOUT_MS),
        bus.write_read(IMU_I2C_ADDRESS, &[reg], buf),
    )
    .await
    {
        Ok(r) => r.map_err(fault),
        Err(_) => Err(ImuFault::Timeout),
    }
}

/// One write with the bus timeout (`bytes[0]` is the first register).
async fn write(bus: &mut Bus, bytes: &[u8]) -> Result<(), ImuFault> {
    match with_timeout(
        Duration::from_millis(BUS_TIMEOUT_MS),
        bus.write(IMU_I2C_ADDRESS, bytes),
    )
    .await
    {
        Ok(r) => r.map_err(fault),
        Err(_) => Err(ImuFault::Timeout),
    }
}

/// Opens I2C1 and spawns the IMU task.
pub fn start(spawner: &Spawner, p: ImuPeripherals) {
    let mut cfg = i2c::Config::default();
    cfg.frequency = embassy_stm32::time::Hertz(IMU_I2C_HZ);
    // Internal pull-ups as a fallback only (30-50 kΩ: too weak for 400 kHz
    // on their own; GY-521 modules carry 2.2-4.7 kΩ): with them an absent
    // module reads as a NACK rather than as noise.
    cfg.scl_pullup = true;
    cfg.sda_pullup = true;
    cfg.timeout = Duration::from_millis(BUS_TIMEOUT_MS);
    let bus = I2c::new(
        p.i2c,
        p.scl,
        p.sda,
        p.tx_dma,
        p.rx_dma,
        crate::board::ImuIrqs,
        cfg,
    );
    spawner.spawn(unwrap!(imu_task(bus).ok()));
}

/// Probes the chip (WHO_AM_I), resets, wakes and configures it, and reads
/// the configuration back.
async fn bring_up(bus: &mut Bus) -> Result<ImuChip, ImuFault> {
    let mut who = [0u8];
    read(bus, REG_WHO_AM_I, &mut who).await?;
    let chip = identify(who[0])?;
    write(bus, &[REG_PWR_MGMT_1, PWR_RESET]).await?;
    Timer::after_millis(RESET_WAIT_MS).await;
    write(bus, &[REG_PWR_MGMT_1, PWR_AWAKE_PLL_X]).await?;
    write(bus, &CONFIG_BURST).await?;
    let mut back = [0u8; 3];
    read(bus, REG_SMPLRT_DIV, &mut back).await?;
    if back[0] != 0 || !check_config(back[1], back[2], IMU_DLPF, IMU_RANGE) {
        return Err(ImuFault::ConfigMismatch(back[1], back[2]));
    }
    Ok(chip)
}

/// Reads the gyro every [`SAMPLE_PERIOD_US`] and publishes the yaw rate
/// until [`READ_FAILURES_LOST`] reads in a row fail; returns the last
/// failure.
async fn stream(bus: &mut Bus) -> ImuFault {
    let mut ticker = Ticker::every(Duration::from_micros(SAMPLE_PERIOD_US));
    let mut failures = 0u32;
    loop {
        ticker.next().await;
        // Stamped when the read starts: the registers hold the newest
        // filtered sample (at most 1 ms old, plus the filter's delay).
        let stamp_us = Instant::now().as_micros() as u32;
        let mut b = [0u8; 6];
        match read(bus, REG_GYRO_XOUT_H, &mut b).await {
            Ok(()) => {
                // Big-endian x, y, z.
                let raw = [
                    i16::from_be_bytes([b[0], b[1]]),
                    i16::from_be_bytes([b[2], b[3]]),
                    i16::from_be_bytes([b[4], b[5]]),
                ];
                let rate_radps = yaw_rate_radps(raw, IMU_YAW, IMU_RANGE);
                LATEST.lock(|c| {
                    c.set(Some(GyroSample {
                        rate_radps,
                        stamp_us,
                    }))
                });
                if failures > 0 {
                    warn!(
                        "gyro: {=u32} failed reads in a row, reading again",
                        failures
                    );
                }
                failures = 0;
            }
            Err(e) => {
                failures += 1;
                if failures >= READ_FAILURES_LOST {
                    return e;
                }
            }
        }
    }
}

/// The IMU task: bring-up, then samples; on a boot failure it logs why and
/// ends (odometry), on a run-time loss it logs it and reconfigures.
#[embassy_executor::task]
async fn imu_task(mut bus: Bus) {
    let mut booted = false;
    loop {
        match bring_up(&mut bus).await {
            Ok(chip) => {
                info!(
                    "gyro: {=str} at I2C1 0x{=u8:x}: +-{=u16} deg/s, DLPF_CFG {=u8}, {=u64} us sampling; yaw = {}",
                    chip.name(),
                    IMU_I2C_ADDRESS,
                    IMU_RANGE.full_scale_dps(),
                    IMU_DLPF,
                    SAMPLE_PERIOD_US,
                    IMU_YAW
                );
                booted = true;
                let e = stream(&mut bus).await;
                error!(
                    "gyro lost ({} after {=u32} failed reads): heading from the wheels; reconfiguring every {=u64} ms",
                    e, READ_FAILURES_LOST, RETRY_MS
                );
            }
            Err(e) if !booted => {
                error!(
                    "gyro: no IMU ({}) at I2C1 0x{=u8:x}: running on odometry (wheel yaw rate)",
                    e, IMU_I2C_ADDRESS
                );
                return;
            }
            Err(_) => {}
        }
        Timer::after_millis(RETRY_MS).await;
    }
}

// Compile-time checks of the pure part (evaluated in every build with the
// `imu` feature; a failing one is a build error).
const fn close(a: f32, b: f32, tol: f32) -> bool {
    let d = a - b;
    d <= tol && d >= -tol
}
/// ±500 °/s: 32 767 counts = 32 767 / 65.5 °/s = 500.26 °/s = 8.7312 rad/s
/// (independent arithmetic: 500.26 × 0.0174533).
const _: () = assert!(close(GyroRange::Dps500.limit_radps(), 8.7313, 1e-3));
const _: () = assert!(close(
    yaw_rate_radps(
        [0, 0, 32_767],
        YawMapping {
            axis: Axis::Z,
            inverted: false
        },
        GyroRange::Dps500
    ),
    8.7310,
    1e-3
));
/// 65.5 counts on the chosen axis = 1 °/s = 0.017453 rad/s; the other axes
/// are ignored; an inverted axis flips the sign.
const _: () = assert!(close(
    yaw_rate_radps(
        [1000, -1000, 0],
        YawMapping {
            axis: Axis::Z,
            inverted: false
        },
        GyroRange::Dps500
    ),
    0.0,
    0.0
));
const _: () = assert!(close(
    yaw_rate_radps(
        [0, 131, 0],
        YawMapping {
            axis: Axis::Y,
            inverted: true
        },
        GyroRange::Dps1000
    ),
    -131.0 / 32.8 * 0.017_453_292,
    1e-6
));
const _: () = assert!(close(
    yaw_rate_radps(
        [-16_400, 0, 0],
        YawMapping {
            axis: Axis::X,
            inverted: false
        },
        GyroRange::Dps2000
    ),
    -1000.0 * 0.017_453_292,
    1e-3
));
/// The probe decision.
const _: () = assert!(matches!(identify(0x68), Ok(ImuChip::Mpu6050)));
const _: () = assert!(matches!(identify(0x70), Ok(ImuChip::Mpu6500)));
const _: () = assert!(matches!(identify(0xFF), Err(ImuFault::NoChip(0xFF))));
const _: () = assert!(matches!(identify(0x00), Err(ImuFault::NoChip(0))));
const _: () = assert!(matches!(identify(0x98), Err(ImuFault::UnknownChip(0x98))));
/// The read-back check: FS_SEL = 1 is 0x08 in GYRO_CONFIG; self-test bits
/// (7:5) set fail; the FSYNC bits of CONFIG (5:3) are not ours.
const _: () = assert!(check_config(0x02, 0x08, 2, GyroRange::Dps500));
const _: () = assert!(check_config(0x0A, 0x08, 2, GyroRange::Dps500));
const _: () = assert!(!check_config(0x02, 0x18, 2, GyroRange::Dps500));
const _: () = assert!(!check_config(0x02, 0x88, 2, GyroRange::Dps500));
const _: () = assert!(!check_config(0x03, 0x08, 2, GyroRange::Dps500));
/// DLPF_CFG 1-6: the gyro's internal rate is 1 kHz (0 and 7 give 8 kHz,
/// which SMPLRT_DIV = 0 would not match).
const _: () = assert!(IMU_DLPF >= 1 && IMU_DLPF <= 6);
/// The configured range covers the estimator's saturation threshold.
const _: () = assert!(crate::config::ESTIMATOR.gyro_saturation_radps < IMU_RANGE.limit_radps());
