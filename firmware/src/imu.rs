//! The z-gyro (`imu` feature): an InvenSense MPU-6050 on I2C1, read by its
//! own embassy task, published to the control task through a cell.
//!
//! This file is the bus driver: register addresses, I2C transfers, the
//! GPIO bus recovery. The logic above the registers (conversion, probe and
//! read-back decisions, the frozen/implausible monitor, the retry backoff,
//! the bus-clear sequence, the cell) is `robot_app::imu`, host-tested.
//!
//! The control tick never touches the bus: [`imu_task`] waits the chip's
//! power-up time, probes it (WHO_AM_I), resets and configures it, reads the
//! configuration and PWR_MGMT_1 back, and then reads the three gyro axes
//! every millisecond; each reading goes through `GyroMonitor` and only a
//! plausible one is stored in [`LATEST`], which the board's gyro hands to
//! the estimator once per tick.
//!
//! Failures never block start-up or stop the robot, and the task never
//! gives up:
//! * a failed bring-up (no answer, unknown chip, configuration or
//!   PWR_MGMT_1 not read back as written) is logged and retried with a
//!   doubling backoff from [`POWER_UP_MS`] to [`RETRY_MAX_MS`], forever;
//! * at run time the gyro is withdrawn at once (the cell is emptied: the
//!   estimator uses the wheels from the next tick) and the chip brought up
//!   again when [`READ_FAILURES_LOST`] reads in a row fail, one transfer
//!   times out, PWR_MGMT_1 (read every [`AWAKE_CHECK_EVERY`] samples) is
//!   not awake, or the monitor finds the readings frozen;
//! * after a timeout or a bus error the I2C peripheral is dropped, the bus
//!   is clocked free as GPIOs (`recover_bus`: up to nine SCL pulses, then
//!   a STOP) and the peripheral is created again (reset by its RCC bit):
//!   a transfer cancelled by the timeout leaves neither the slave nor the
//!   peripheral mid-byte; the bus is clocked free before the first
//!   attempt after boot too (a reset of the MCU mid-read leaves the chip,
//!   which is not reset with it, holding SDA).

use controller_core::estimator::GyroSample;
use defmt::{error, info, warn};
use embassy_executor::Spawner;
use embassy_stm32::gpio::{Level, OutputOpenDrain, Speed};
use embassy_stm32::i2c::{self, I2c};
use embassy_stm32::mode::Async;
use embassy_stm32::peripherals::{DMA1_CH0, DMA1_CH6, I2C1, PB8, PB9};
use embassy_stm32::Peri;
use embassy_time::{block_for, with_timeout, Duration, Instant, Ticker, Timer};
use robot_app::imu::{
    check_awake, check_config, identify, recover_bus, Backoff, CellGyro, GyroCell, GyroMonitor,
    ImuChip, ImuFault, Recovery, RecoveryPins, Verdict, PWR_MGMT_1_AWAKE_PLL_X,
};

use crate::config::{IMU_DLPF, IMU_I2C_ADDRESS, IMU_I2C_HZ, IMU_MONITOR, IMU_RANGE};
use robot_app::imu::YawMapping;

/// The newest sample, written by [`imu_task`], read by the board's gyro
/// ([`gyro`]).
static LATEST: GyroCell = GyroCell::new();

/// The board's gyro with the `imu` feature: the newest plausible sample of
/// the IMU task, `None` until there is one and while the gyro is invalid
/// (the `NoGyro` behaviour: the estimator uses the wheels).
pub type ImuGyro = CellGyro;

/// The board's gyro on the IMU task's cell.
pub const fn gyro() -> ImuGyro {
    LATEST.reader()
}

/// The IMU's bus: I2C1 on PB8 (SCL) / PB9 (SDA), AF4 on both chips, with
/// DMA1 stream 6 channel 1 (I2C1_TX) and stream 0 channel 1 (I2C1_RX)
/// (RM0383 table 27 / RM0390 table 28). None of these is used elsewhere:
/// PB6/PB7 (also I2C1) are TIM4's encoder inputs, hence the PB8/PB9 pair.
/// `board::init` hands them over.
pub struct ImuPeripherals {
    /// I2C1.
    pub i2c: Peri<'static, I2C1>,
    /// SCL.
    pub scl: Peri<'static, PB8>,
    /// SDA.
    pub sda: Peri<'static, PB9>,
    /// TX DMA (DMA1 stream 6).
    pub tx_dma: Peri<'static, DMA1_CH6>,
    /// RX DMA (DMA1 stream 0).
    pub rx_dma: Peri<'static, DMA1_CH0>,
}

embassy_stm32::bind_interrupts!(
    /// The IMU bus's interrupts (I2C1 events and errors, its two DMA streams).
    struct ImuIrqs {
        I2C1_EV => embassy_stm32::i2c::EventInterruptHandler<I2C1>;
        I2C1_ER => embassy_stm32::i2c::ErrorInterruptHandler<I2C1>;
        DMA1_STREAM6 => embassy_stm32::dma::InterruptHandler<DMA1_CH6>;
        DMA1_STREAM0 => embassy_stm32::dma::InterruptHandler<DMA1_CH0>;
    }
);

/// Gyro sampling period \[µs\]: the chip's output rate with its low-pass
/// filter on (1 kHz internal rate, SMPLRT_DIV = 0), the control rate.
pub const SAMPLE_PERIOD_US: u64 = 1_000;
/// Longest wait for one bus transaction \[ms\] (a gyro read takes about
/// 0.25 ms at 400 kHz: 9 bytes of 9 bits plus start/stop).
pub const BUS_TIMEOUT_MS: u64 = 5;
/// Failed reads in a row (NACKs, bus errors) after which the gyro counts
/// as lost and is brought up again.
pub const READ_FAILURES_LOST: u32 = 20;
/// Wait before the first bring-up \[ms\]: the MPU-6050's start-up time for
/// register access (product specification rev 3.4, table 6.1: 100 ms
/// maximum), for a module powered up with the MCU. Also the first wait of
/// the retry backoff.
pub const POWER_UP_MS: u32 = 100;
/// Longest wait between two bring-up attempts \[ms\] (the backoff doubles
/// from [`POWER_UP_MS`] to this).
pub const RETRY_MAX_MS: u32 = 5_000;
/// PWR_MGMT_1 is read back every this many samples (100 ms): a chip that
/// browned out and restarted asleep is found within that, even if its
/// output registers still change (they do not: the monitor finds those
/// frozen within 50 ms).
pub const AWAKE_CHECK_EVERY: u32 = 100;

/// MPU-6050 registers (register map rev 4.2).
const REG_SMPLRT_DIV: u8 = 0x19;
const REG_GYRO_XOUT_H: u8 = 0x43;
const REG_PWR_MGMT_1: u8 = 0x6B;
const REG_WHO_AM_I: u8 = 0x75;
/// PWR_MGMT_1: DEVICE_RESET.
const PWR_RESET: u8 = 0x80;
/// Wait after DEVICE_RESET \[ms\] (the register map gives no figure; the
/// reference driver and the `mpu6050-dmp` crate wait 100-200 ms).
const RESET_WAIT_MS: u64 = 100;

/// The configuration writes after the reset and wake-up, in order:
/// SMPLRT_DIV = 0 (1 kHz with the DLPF on), CONFIG = DLPF_CFG (FSYNC off),
/// GYRO_CONFIG = FS_SEL (self-test off). 0x19-0x1B are consecutive and
/// written in one burst; read back in one burst too.
const CONFIG_BURST: [u8; 4] = [REG_SMPLRT_DIV, 0, IMU_DLPF, IMU_RANGE.fs_sel() << 3];

fn fault(e: i2c::Error) -> ImuFault {
    match e {
        i2c::Error::Nack => ImuFault::NoAck,
        i2c::Error::Timeout => ImuFault::Timeout,
        _ => ImuFault::Bus,
    }
}

type Bus<'a> = I2c<'a, Async, i2c::Master>;

/// One write-read with the bus timeout.
async fn read(bus: &mut Bus<'_>, reg: u8, buf: &mut [u8]) -> Result<(), ImuFault> {
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
async fn write(bus: &mut Bus<'_>, bytes: &[u8]) -> Result<(), ImuFault> {
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

/// Spawns the IMU task on the bus's peripherals, reading the robot's yaw
/// as `yaw` says (`config::imu_yaw`, from the robot file).
pub fn start(spawner: &Spawner, p: ImuPeripherals, yaw: YawMapping) {
    match imu_task(p, yaw) {
        Ok(t) => spawner.spawn(t),
        Err(_) => error!("gyro: IMU task not started: heading from the wheels"),
    }
}

/// I2C1 at [`IMU_I2C_HZ`] with the bus timeout.
fn i2c_config() -> i2c::Config {
    let mut cfg = i2c::Config::default();
    cfg.frequency = embassy_stm32::time::Hertz(IMU_I2C_HZ);
    // Internal pull-ups as a fallback only (30-50 kΩ: too weak for 400 kHz
    // on their own; GY-521 modules carry 2.2-4.7 kΩ): with them an absent
    // module reads as a NACK rather than as noise.
    cfg.scl_pullup = true;
    cfg.sda_pullup = true;
    cfg.timeout = Duration::from_millis(BUS_TIMEOUT_MS);
    cfg
}

/// SCL and SDA as open-drain GPIOs (the I2C peripheral dropped).
struct GpioBus<'a> {
    scl: OutputOpenDrain<'a>,
    sda: OutputOpenDrain<'a>,
}

impl RecoveryPins for GpioBus<'_> {
    fn set_scl(&mut self, high: bool) {
        self.scl
            .set_level(if high { Level::High } else { Level::Low });
    }
    fn set_sda(&mut self, high: bool) {
        self.sda
            .set_level(if high { Level::High } else { Level::Low });
    }
    fn sda_is_high(&mut self) -> bool {
        self.sda.is_high()
    }
    fn half_period(&mut self) {
        // At most 9 pulses + a STOP: about 0.1 ms of busy wait in this
        // task, far below the control loop's 0.5 ms lateness limit.
        block_for(Duration::from_micros(5));
    }
}

/// Clocks the bus free with the I2C peripheral off (`robot_app::imu::recover_bus`).
fn bus_recovery(p: &mut ImuPeripherals) -> Recovery {
    let mut pins = GpioBus {
        scl: OutputOpenDrain::new(p.scl.reborrow(), Level::High, Speed::Low),
        sda: OutputOpenDrain::new(p.sda.reborrow(), Level::High, Speed::Low),
    };
    recover_bus(&mut pins)
}

/// Probes the chip (WHO_AM_I), resets, wakes and configures it, and reads
/// the configuration and the power state back.
async fn bring_up(bus: &mut Bus<'_>) -> Result<ImuChip, ImuFault> {
    let mut who = [0u8];
    read(bus, REG_WHO_AM_I, &mut who).await?;
    let chip = identify(who[0])?;
    write(bus, &[REG_PWR_MGMT_1, PWR_RESET]).await?;
    Timer::after_millis(RESET_WAIT_MS).await;
    write(bus, &[REG_PWR_MGMT_1, PWR_MGMT_1_AWAKE_PLL_X]).await?;
    write(bus, &CONFIG_BURST).await?;
    let mut back = [0u8; 3];
    read(bus, REG_SMPLRT_DIV, &mut back).await?;
    if back[0] != 0 || !check_config(back[1], back[2], IMU_DLPF, IMU_RANGE) {
        return Err(ImuFault::ConfigMismatch(back[1], back[2]));
    }
    check_awake(read_pwr_mgmt_1(bus).await?)?;
    Ok(chip)
}

async fn read_pwr_mgmt_1(bus: &mut Bus<'_>) -> Result<u8, ImuFault> {
    let mut pwr = [0u8];
    read(bus, REG_PWR_MGMT_1, &mut pwr).await?;
    Ok(pwr[0])
}

/// Reads the gyro every [`SAMPLE_PERIOD_US`] and publishes the plausible
/// readings until the gyro is lost; returns why.
async fn stream(bus: &mut Bus<'_>, monitor: &mut GyroMonitor) -> ImuFault {
    let mut ticker = Ticker::every(Duration::from_micros(SAMPLE_PERIOD_US));
    let mut failures = 0u32;
    let mut samples = 0u32;
    loop {
        ticker.next().await;
        // Stamped when the read starts: the registers hold the newest
        // filtered sample (at most 1 ms old, plus the filter's delay).
        let stamp_us = Instant::now().as_micros() as u32;
        let mut b = [0u8; 6];
        match read(bus, REG_GYRO_XOUT_H, &mut b).await {
            Ok(()) => {
                if failures > 0 {
                    warn!(
                        "gyro: {=u32} failed reads in a row, reading again",
                        failures
                    );
                }
                failures = 0;
                // Big-endian x, y, z.
                let raw = [
                    i16::from_be_bytes([b[0], b[1]]),
                    i16::from_be_bytes([b[2], b[3]]),
                    i16::from_be_bytes([b[4], b[5]]),
                ];
                match monitor.check(raw) {
                    Verdict::Valid(rate_radps) => LATEST.publish(GyroSample {
                        rate_radps,
                        stamp_us,
                    }),
                    Verdict::Implausible => {
                        let n = monitor.counts().implausible;
                        if n.is_power_of_two() {
                            warn!(
                                "gyro: implausible reading {=i16} {=i16} {=i16} discarded ({=u32} so far)",
                                raw[0], raw[1], raw[2], n
                            );
                        }
                    }
                    Verdict::Frozen => return ImuFault::Frozen,
                }
                samples = samples.wrapping_add(1);
                if samples % AWAKE_CHECK_EVERY == 0 {
                    match read_pwr_mgmt_1(bus).await.and_then(check_awake) {
                        Ok(()) => {}
                        // A failed read counts like a failed sample.
                        Err(e @ ImuFault::NotAwake(_)) => return e,
                        Err(ImuFault::Timeout) => return ImuFault::Timeout,
                        Err(_) => failures += 1,
                    }
                }
            }
            // A cancelled transfer: re-create the peripheral at once.
            Err(ImuFault::Timeout) => return ImuFault::Timeout,
            Err(e) => {
                failures += 1;
                if failures >= READ_FAILURES_LOST {
                    return e;
                }
            }
        }
    }
}

/// The IMU task: bring-up (after the power-up wait, retried with backoff
/// forever), samples, and after a loss the gyro withdrawn, the bus
/// recovered when it may be wedged, and a new bring-up.
#[embassy_executor::task]
async fn imu_task(mut p: ImuPeripherals, yaw: YawMapping) {
    let Ok(mut monitor) = GyroMonitor::new(IMU_MONITOR, yaw, IMU_RANGE) else {
        error!("gyro: invalid config::IMU_MONITOR: heading from the wheels");
        return;
    };
    let mut backoff = Backoff::new(POWER_UP_MS, RETRY_MAX_MS);
    // The bus is clocked free before the first attempt too: a reset of
    // the MCU (the IWDG, the button) can cut a gyro read mid-byte and leave
    // the chip holding SDA, and the chip is not reset with the MCU. Without
    // this the first probe timed out and the gyro came 205 ms later than
    // necessary (stm32-emu run.sh (o), a reset while SDA is held; D146).
    let mut recover = true;
    let mut ever_up = false;
    let mut losses = 0u32;
    let mut recoveries = 0u32;
    loop {
        let wait_ms = backoff.next_wait_ms();
        Timer::after_millis(wait_ms as u64).await;
        if recover {
            let at_boot = !ever_up && recoveries == 0;
            recoveries += 1;
            match bus_recovery(&mut p) {
                // The usual boot: nothing held the bus.
                Recovery::Freed { pulses: 0 } if at_boot => {}
                Recovery::Freed { pulses } => warn!(
                    "gyro: bus recovery {=u32}: SDA free after {=u8} SCL pulses, STOP sent",
                    recoveries, pulses
                ),
                Recovery::StillHeld => error!(
                    "gyro: bus recovery {=u32}: SDA still held low after 9 SCL pulses (short, or a dead device)",
                    recoveries
                ),
            }
        }
        // A new peripheral for every attempt (RCC reset on creation): a
        // cancelled transfer leaves none of its state behind.
        let mut bus = I2c::new(
            p.i2c.reborrow(),
            p.scl.reborrow(),
            p.sda.reborrow(),
            p.tx_dma.reborrow(),
            p.rx_dma.reborrow(),
            ImuIrqs,
            i2c_config(),
        );
        let e = match bring_up(&mut bus).await {
            Ok(chip) => {
                info!(
                    "gyro: {=str} at I2C1 0x{=u8:x}: +-{=u16} deg/s, DLPF_CFG {=u8}, {=u64} us sampling; yaw = {}",
                    chip.name(),
                    IMU_I2C_ADDRESS,
                    IMU_RANGE.full_scale_dps(),
                    IMU_DLPF,
                    SAMPLE_PERIOD_US,
                    yaw
                );
                ever_up = true;
                backoff.reset();
                monitor.restart();
                let e = stream(&mut bus, &mut monitor).await;
                LATEST.invalidate();
                losses += 1;
                let c = monitor.counts();
                error!(
                    "gyro lost ({}; loss {=u32}, frozen {=u32}, implausible {=u32}): heading from the wheels; bringing it up again",
                    e, losses, c.frozen_episodes, c.implausible
                );
                e
            }
            Err(e) => {
                if ever_up {
                    warn!("gyro: bring-up failed ({}), retrying", e);
                } else {
                    error!(
                        "gyro: no IMU ({}) at I2C1 0x{=u8:x}: running on odometry (wheel yaw rate); retrying",
                        e, IMU_I2C_ADDRESS
                    );
                }
                e
            }
        };
        drop(bus);
        recover = e.needs_bus_recovery();
    }
}

// The configuration's compile-time checks (the pure logic's tests are
// robot-app's host tests, robot-app/tests/imu.rs).
/// DLPF_CFG 1-6: the gyro's internal rate is 1 kHz (0 and 7 give 8 kHz,
/// which SMPLRT_DIV = 0 would not match).
const _: () = assert!(IMU_DLPF >= 1 && IMU_DLPF <= 6);
/// The configured range covers the estimator's saturation threshold.
const _: () = assert!(crate::config::GYRO_SATURATION_RADPS < IMU_RANGE.limit_radps());
