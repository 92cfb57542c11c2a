//! The InvenSense MPU-6050 on the board's I2C bus (`imu` images): the
//! registers the firmware's driver uses, from the register map rev 4.2
//! (reset values §3: 0x00 except PWR_MGMT_1 = 0x40 and WHO_AM_I = 0x68),
//! the I2C slave protocol of the product specification rev 3.4 §9.3 (the
//! register pointer written first, bursts auto-increment), the start-up time
//! for register access (table 6.1: 100 ms maximum, NACKed before it),
//! DEVICE_RESET, SLEEP (the output registers hold their last values), the
//! sample rate (1 kHz with DLPF_CFG 1-6, 8 kHz with 0 or 7, divided by
//! 1 + SMPLRT_DIV) and the gyro sensitivity per FS_SEL (131, 65.5, 32.8,
//! 16.4 LSB/(°/s)). The yaw axis (`imu.yaw_axis` of the robot file) reads
//! the simulated robot's yaw rate plus white noise of the specification's
//! 0.005 °/s/√Hz over the filter's bandwidth, the other axes noise only;
//! the filter's delay and the zero-rate offset are not modelled. An access
//! to a register not listed here fails the run. Injectable faults:
//! [`Faults`].

use std::fmt::Write as _;

/// The 7-bit address with AD0 low.
pub const ADDRESS: u8 = 0x68;
/// Start-up time for register read/write after power-up \[ps\] (product
/// specification rev 3.4, table 6.1: 100 ms maximum).
pub const START_UP_PS: u128 = 100_000_000_000;

/// Registers the model knows (register map rev 4.2) and their reset values.
const REGISTERS: &[(u8, &str, u8)] = &[
    (0x19, "SMPLRT_DIV", 0x00),
    (0x1A, "CONFIG", 0x00),
    (0x1B, "GYRO_CONFIG", 0x00),
    (0x1C, "ACCEL_CONFIG", 0x00),
    (0x3B, "ACCEL_XOUT_H", 0x00),
    (0x3C, "ACCEL_XOUT_L", 0x00),
    (0x3D, "ACCEL_YOUT_H", 0x00),
    (0x3E, "ACCEL_YOUT_L", 0x00),
    (0x3F, "ACCEL_ZOUT_H", 0x00),
    (0x40, "ACCEL_ZOUT_L", 0x00),
    (0x41, "TEMP_OUT_H", 0x00),
    (0x42, "TEMP_OUT_L", 0x00),
    (0x43, "GYRO_XOUT_H", 0x00),
    (0x44, "GYRO_XOUT_L", 0x00),
    (0x45, "GYRO_YOUT_H", 0x00),
    (0x46, "GYRO_YOUT_L", 0x00),
    (0x47, "GYRO_ZOUT_H", 0x00),
    (0x48, "GYRO_ZOUT_L", 0x00),
    (0x6B, "PWR_MGMT_1", 0x40),
    (0x6C, "PWR_MGMT_2", 0x00),
    (0x75, "WHO_AM_I", 0x68),
];

const PWR_MGMT_1: u8 = 0x6B;
const GYRO_XOUT_H: u8 = 0x43;
/// PWR_MGMT_1 bits.
const DEVICE_RESET: u8 = 0x80;
const SLEEP: u8 = 0x40;

/// Gyro rate noise density (product specification rev 3.4, table 6.1)
/// \[°/s/√Hz\].
pub const NOISE_DENSITY_DPS_PER_SQRT_HZ: f64 = 0.005;

/// The faults `--imu-*` inject (times in ps of emulated time).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Faults {
    /// From this time the next `n` address phases are not acknowledged.
    pub nack: Option<(u128, u32)>,
    /// From this time, at the next STOP, the chip holds SDA low until it
    /// has seen this many SCL clocks (a slave left mid-byte).
    pub stuck_sda: Option<(u128, u8)>,
    /// At this time the chip restarts (a brown-out): every register at its
    /// reset value, so it wakes asleep; the output registers keep their
    /// last values.
    pub asleep: Option<u128>,
    /// From this time for this long the output registers stop updating.
    pub frozen: Option<(u128, u128)>,
    /// From this time for this long the yaw axis reads +32 767 counts (full
    /// scale: a saturated or corrupted reading), or, with a rate \[rad/s\],
    /// that rate (a plausible but wrong reading: the control that shows
    /// the estimator uses the gyro).
    pub implausible: Option<(u128, u128)>,
    /// The rate the yaw axis reads during `implausible` (None: full scale).
    pub implausible_radps: Option<f64>,
    /// From this time for this long the chip is gone (no acknowledge);
    /// then it is powered again: its reset state, answering after its
    /// start-up time.
    pub absent: Option<(u128, u128)>,
}

/// Counters of the chip's traffic.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MpuStats {
    /// Address phases acknowledged.
    pub acks: u64,
    /// Address phases not acknowledged (its address).
    pub nacks: u64,
    /// Bursts read from GYRO_XOUT_H.
    pub gyro_reads: u64,
    /// DEVICE_RESET writes.
    pub resets: u64,
    /// SCL clocks seen while holding SDA.
    pub recovery_clocks: u64,
}

/// Where the chip is in an I2C transaction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    /// Not addressed (or another device's transaction).
    Idle,
    /// Addressed for a write: the next byte is the register pointer.
    WritePointer,
    /// Writing data at the pointer.
    WriteData,
    /// Addressed for a read: sending from the pointer.
    Read,
}

/// The chip.
#[derive(Clone, Debug)]
pub struct Mpu6050 {
    regs: [u8; 128],
    ptr: u8,
    phase: Phase,
    /// When the chip last powered up \[ps\].
    powered_ps: u128,
    /// The output sample in the registers (its index), if any.
    sample: Option<u64>,
    /// The yaw axis (0 x, 1 y, 2 z) and its sign (+1: the robot's
    /// counter-clockwise yaw reads positive).
    yaw_axis: (usize, f64),
    /// Faults to inject.
    pub faults: Faults,
    nacks_left: u32,
    nack_armed: bool,
    stuck_armed: bool,
    asleep_done: bool,
    absent_state: u8,
    /// SCL clocks to go before SDA is released (0: not holding).
    hold_clocks: u8,
    /// Counters.
    pub stats: MpuStats,
    /// Things worth an event line (drained by the board).
    pub events: Vec<String>,
}

impl Mpu6050 {
    /// A chip powered up at time 0, mounted with its `yaw_axis` (0-2) along
    /// the robot's vertical, `inverted` when pointing down.
    pub fn new(yaw_axis: usize, inverted: bool) -> Self {
        let mut regs = [0u8; 128];
        for &(a, _, v) in REGISTERS {
            regs[a as usize] = v;
        }
        Self {
            regs,
            ptr: 0,
            phase: Phase::Idle,
            powered_ps: 0,
            sample: None,
            yaw_axis: (yaw_axis.min(2), if inverted { -1.0 } else { 1.0 }),
            faults: Faults::default(),
            nacks_left: 0,
            nack_armed: false,
            stuck_armed: false,
            asleep_done: false,
            absent_state: 0,
            hold_clocks: 0,
            stats: MpuStats::default(),
            events: Vec::new(),
        }
    }

    fn name(reg: u8) -> Option<&'static str> {
        REGISTERS.iter().find(|r| r.0 == reg).map(|r| r.1)
    }

    fn check(reg: u8, what: &str) -> Result<(), String> {
        if Self::name(reg).is_some() {
            Ok(())
        } else {
            Err(format!(
                "MPU-6050 {what} of register 0x{reg:02X}: not modelled (register map rev 4.2)"
            ))
        }
    }

    /// The chip to its reset state (power-on or DEVICE_RESET).
    fn reset_registers(&mut self, keep_outputs: bool) {
        let out: Vec<u8> = self.regs[0x3B..=0x48].to_vec();
        for &(a, _, v) in REGISTERS {
            self.regs[a as usize] = v;
        }
        if keep_outputs {
            self.regs[0x3B..=0x48].copy_from_slice(&out);
        } else {
            self.sample = None;
        }
    }

    /// A register's value (tests, reports).
    pub fn reg(&self, reg: u8) -> u8 {
        self.regs[reg as usize & 0x7F]
    }

    /// The scheduled faults that change the chip by themselves, up to `now`.
    fn apply_faults(&mut self, now: u128) {
        if let Some(t) = self.faults.asleep {
            if !self.asleep_done && now >= t {
                self.asleep_done = true;
                self.reset_registers(true);
                self.events.push(format!(
                    "MPU-6050: restarted (brown-out, --imu-asleep): PWR_MGMT_1 = 0x{:02X} (asleep), configuration at reset, outputs held",
                    self.reg(PWR_MGMT_1)
                ));
            }
        }
        if let Some((t, d)) = self.faults.absent {
            if self.absent_state == 0 && now >= t {
                self.absent_state = 1;
                self.phase = Phase::Idle;
                self.events
                    .push("MPU-6050: gone (--imu-absent): no acknowledge".into());
            }
            if self.absent_state == 1 && now >= t + d {
                self.absent_state = 2;
                self.powered_ps = t + d;
                self.reset_registers(false);
                self.events.push(format!(
                    "MPU-6050: back since {:.6} s (--imu-absent), powered up in its reset state (asleep), answering after its start-up time",
                    (t + d) as f64 * 1e-12
                ));
            }
        }
        if let Some((t, _)) = self.faults.nack {
            if !self.nack_armed && now >= t {
                self.nack_armed = true;
                self.nacks_left = self.faults.nack.map_or(0, |f| f.1);
            }
        }
    }

    /// SDA is held low by the chip.
    pub fn holds_sda(&self) -> bool {
        self.hold_clocks > 0
    }

    /// A rising SCL edge the master clocks as a GPIO (bus recovery).
    pub fn scl_clock(&mut self) {
        if self.hold_clocks > 0 {
            self.stats.recovery_clocks += 1;
            self.hold_clocks -= 1;
            if self.hold_clocks == 0 {
                self.events
                    .push("MPU-6050: SDA released (the byte it was sending clocked out)".into());
            }
        }
    }

    /// A START or repeated START on the bus.
    pub fn start(&mut self, now: u128) {
        self.apply_faults(now);
        self.phase = Phase::Idle;
    }

    /// A STOP on the bus.
    pub fn stop(&mut self, now: u128) {
        self.apply_faults(now);
        self.phase = Phase::Idle;
        if let Some((t, clocks)) = self.faults.stuck_sda {
            if !self.stuck_armed && now >= t {
                self.stuck_armed = true;
                self.hold_clocks = clocks.clamp(1, 9);
                self.events.push(format!(
                    "MPU-6050: holding SDA low (--imu-stuck-sda) until {} SCL clocks",
                    self.hold_clocks
                ));
            }
        }
    }

    /// The address phase: `addr7` with R/W̄ `read`; true when acknowledged.
    pub fn address(&mut self, addr7: u8, read: bool, now: u128, yaw_radps: f64) -> bool {
        self.apply_faults(now);
        if addr7 != ADDRESS {
            self.phase = Phase::Idle;
            return false;
        }
        let started = now >= self.powered_ps + START_UP_PS;
        let gone = self.absent_state == 1;
        let mut ack = started && !gone && self.hold_clocks == 0;
        if ack && self.nack_armed && self.nacks_left > 0 {
            self.nacks_left -= 1;
            ack = false;
            if self.nacks_left == 0 {
                self.events
                    .push("MPU-6050: acknowledges again (--imu-nack done)".into());
            }
        }
        if !ack {
            self.stats.nacks += 1;
            self.phase = Phase::Idle;
            return false;
        }
        self.stats.acks += 1;
        if read {
            self.phase = Phase::Read;
            if self.ptr == GYRO_XOUT_H {
                self.stats.gyro_reads += 1;
            }
            self.update_outputs(now, yaw_radps);
        } else {
            self.phase = Phase::WritePointer;
        }
        true
    }

    /// A byte the master writes; `Ok(true)` when acknowledged.
    pub fn write_byte(&mut self, b: u8, now: u128) -> Result<bool, String> {
        match self.phase {
            Phase::Idle | Phase::Read => Ok(false),
            Phase::WritePointer => {
                self.ptr = b & 0x7F;
                self.phase = Phase::WriteData;
                Ok(true)
            }
            Phase::WriteData => {
                let reg = self.ptr;
                Self::check(reg, "write")?;
                match reg {
                    PWR_MGMT_1 if b & DEVICE_RESET != 0 => {
                        self.stats.resets += 1;
                        self.reset_registers(false);
                        self.events
                            .push("MPU-6050: reset by PWR_MGMT_1 bit 7 (device reset)".into());
                    }
                    PWR_MGMT_1 => {
                        let was_asleep = self.regs[PWR_MGMT_1 as usize] & SLEEP != 0;
                        self.regs[PWR_MGMT_1 as usize] = b;
                        if was_asleep && b & SLEEP == 0 {
                            // Samples count from the wake-up.
                            self.sample = None;
                            let _ = now;
                        }
                    }
                    0x3B..=0x48 | 0x75 => {} // read-only
                    _ => self.regs[reg as usize] = b,
                }
                self.ptr = (self.ptr + 1) & 0x7F;
                Ok(true)
            }
        }
    }

    /// The next byte the chip sends.
    pub fn read_byte(&mut self) -> Result<u8, String> {
        if self.phase != Phase::Read {
            return Ok(0xFF); // nobody drives SDA: the pull-up
        }
        let reg = self.ptr;
        Self::check(reg, "read")?;
        self.ptr = (self.ptr + 1) & 0x7F;
        Ok(self.regs[reg as usize])
    }

    /// The output sample period \[ps\] as configured.
    pub fn sample_period_ps(&self) -> u128 {
        let dlpf = self.regs[0x1A] & 7;
        let internal_hz: u128 = if dlpf == 0 || dlpf == 7 { 8_000 } else { 1_000 };
        1_000_000_000_000 * (1 + self.regs[0x19] as u128) / internal_hz
    }

    /// Sensitivity \[LSB per °/s\] of FS_SEL (GYRO_CONFIG bits 4:3).
    pub fn lsb_per_dps(&self) -> f64 {
        [131.0, 65.5, 32.8, 16.4][((self.regs[0x1B] >> 3) & 3) as usize]
    }

    /// The DLPF's gyro bandwidth \[Hz\] (register map rev 4.2, register 26).
    fn bandwidth_hz(&self) -> f64 {
        [256.0, 188.0, 98.0, 42.0, 20.0, 10.0, 5.0, 256.0][(self.regs[0x1A] & 7) as usize]
    }

    fn in_window(w: Option<(u128, u128)>, now: u128) -> bool {
        w.is_some_and(|(t, d)| now >= t && now < t + d)
    }

    /// Latches the newest output sample into GYRO_*OUT (awake only; a
    /// sleeping or frozen chip keeps its registers).
    fn update_outputs(&mut self, now: u128, yaw_radps: f64) {
        let p = self.regs[PWR_MGMT_1 as usize];
        if p & (SLEEP | DEVICE_RESET) != 0 || Self::in_window(self.faults.frozen, now) {
            return;
        }
        let k = ((now - self.powered_ps.min(now)) / self.sample_period_ps()) as u64;
        if self.sample == Some(k) {
            return;
        }
        self.sample = Some(k);
        let lsb = self.lsb_per_dps();
        let sigma = NOISE_DENSITY_DPS_PER_SQRT_HZ * self.bandwidth_hz().sqrt() * lsb;
        let mut out = [0i16; 3];
        for (axis, o) in out.iter_mut().enumerate() {
            let mut v = sigma * gaussian(k, axis as u64);
            if axis == self.yaw_axis.0 {
                v += self.yaw_axis.1 * yaw_radps.to_degrees() * lsb;
            }
            *o = v.round().clamp(-32768.0, 32767.0) as i16;
        }
        if Self::in_window(self.faults.implausible, now) {
            out[self.yaw_axis.0] = match self.faults.implausible_radps {
                None => i16::MAX,
                Some(r) => (self.yaw_axis.1 * r.to_degrees() * lsb)
                    .round()
                    .clamp(-32768.0, 32767.0) as i16,
            };
        }
        for (i, v) in out.iter().enumerate() {
            let b = v.to_be_bytes();
            self.regs[0x43 + 2 * i] = b[0];
            self.regs[0x44 + 2 * i] = b[1];
        }
        // Accelerometer at rest, flat (+1 g on z at ±2 g: 16 384 LSB/g);
        // 25 °C (TEMP = (T − 36.53) × 340).
        let accel: [i16; 3] = [0, 0, 16_384];
        for (i, v) in accel.iter().enumerate() {
            let b = v.to_be_bytes();
            self.regs[0x3B + 2 * i] = b[0];
            self.regs[0x3C + 2 * i] = b[1];
        }
        let t = ((25.0 - 36.53) * 340.0f64).round() as i16;
        self.regs[0x41] = t.to_be_bytes()[0];
        self.regs[0x42] = t.to_be_bytes()[1];
    }

    /// A one-line description (for the summary).
    pub fn report(&self) -> String {
        let mut s = String::new();
        let _ = write!(
            s,
            "PWR_MGMT_1 0x{:02X}, CONFIG 0x{:02X}, GYRO_CONFIG 0x{:02X}, SMPLRT_DIV {}",
            self.reg(PWR_MGMT_1),
            self.reg(0x1A),
            self.reg(0x1B),
            self.reg(0x19)
        );
        s
    }
}

/// A standard normal deviate for sample `k`, axis `axis` (deterministic:
/// the same sample reads the same, as the chip's registers hold it).
fn gaussian(k: u64, axis: u64) -> f64 {
    let mut z = k
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(axis.wrapping_mul(0xD1B5_4A32_D192_ED03))
        .wrapping_add(0x2545_F491_4F6C_DD1D);
    let mut next = || {
        // splitmix64
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut x = z;
        x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        x ^ (x >> 31)
    };
    let u1 = ((next() >> 11) as f64 + 1.0) / (1u64 << 53) as f64;
    let u2 = (next() >> 11) as f64 / (1u64 << 53) as f64;
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

#[cfg(test)]
mod tests {
    use super::*;

    const AWAKE: u128 = START_UP_PS;

    fn write(m: &mut Mpu6050, bytes: &[u8], now: u128) {
        m.start(now);
        assert!(m.address(ADDRESS, false, now, 0.0));
        for &b in bytes {
            assert!(m.write_byte(b, now).unwrap());
        }
        m.stop(now);
    }

    fn read(m: &mut Mpu6050, reg: u8, n: usize, now: u128, yaw: f64) -> Vec<u8> {
        m.start(now);
        assert!(m.address(ADDRESS, false, now, yaw));
        assert!(m.write_byte(reg, now).unwrap());
        m.start(now);
        assert!(m.address(ADDRESS, true, now, yaw));
        let v = (0..n).map(|_| m.read_byte().unwrap()).collect();
        m.stop(now);
        v
    }

    /// Register map rev 4.2 §3/§4: every register resets to 0x00 except
    /// PWR_MGMT_1 (0x40: asleep) and WHO_AM_I (0x68); the chip does not
    /// answer before its 100 ms start-up time (product spec table 6.1).
    #[test]
    fn reset_values_and_start_up() {
        let mut m = Mpu6050::new(2, false);
        assert!(
            !m.address(ADDRESS, false, AWAKE - 1, 0.0),
            "NACK during start-up"
        );
        assert_eq!(read(&mut m, 0x75, 1, AWAKE, 0.0), [0x68]);
        assert_eq!(read(&mut m, 0x6B, 1, AWAKE, 0.0), [0x40]);
        assert_eq!(read(&mut m, 0x19, 3, AWAKE, 0.0), [0, 0, 0]);
        assert!(!m.address(0x69, false, AWAKE, 0.0), "AD0 low: 0x68 only");
        // Asleep: the outputs stay at their reset value 0.
        assert_eq!(read(&mut m, 0x43, 6, AWAKE, 1.0), [0; 6]);
        // An unknown register fails loudly.
        m.start(AWAKE);
        m.address(ADDRESS, false, AWAKE, 0.0);
        m.write_byte(0x37, AWAKE).unwrap();
        assert!(m.write_byte(0x00, AWAKE).unwrap_err().contains("0x37"));
    }

    /// The firmware's bring-up (reset, wake on the PLL, the configuration
    /// burst) reads back as written; the yaw axis then reads the rate at
    /// 65.5 LSB/(°/s) (±500 °/s), within the noise.
    #[test]
    fn configured_chip_reads_the_yaw_rate() {
        let mut m = Mpu6050::new(2, false);
        write(&mut m, &[0x6B, 0x80], AWAKE);
        assert_eq!(m.reg(0x6B), 0x40, "DEVICE_RESET clears itself, asleep");
        write(&mut m, &[0x6B, 0x01], AWAKE);
        write(&mut m, &[0x19, 0, 2, 1 << 3], AWAKE);
        assert_eq!(read(&mut m, 0x19, 3, AWAKE, 0.0), [0, 2, 8]);
        assert_eq!(m.sample_period_ps(), 1_000_000_000, "1 kHz with DLPF 2");
        let yaw = 1.0; // rad/s = 57.3 °/s = 3753 LSB
        let mut sum = 0.0;
        let n = 200;
        for i in 0..n {
            let b = read(&mut m, 0x43, 6, AWAKE + (i + 1) * 1_000_000_000, yaw);
            let z = i16::from_be_bytes([b[4], b[5]]) as f64;
            let x = i16::from_be_bytes([b[0], b[1]]) as f64;
            assert!(x.abs() < 20.0, "x: noise only, {x}");
            sum += z;
        }
        let mean = sum / n as f64;
        let want = 1.0f64.to_degrees() * 65.5;
        assert!((mean - want).abs() < 1.0, "mean {mean} vs {want}");
        // Inverted mounting: negative.
        let mut m = Mpu6050::new(2, true);
        write(&mut m, &[0x6B, 0x01], AWAKE);
        write(&mut m, &[0x1B, 1 << 3], AWAKE);
        let b = read(&mut m, 0x47, 2, AWAKE + 5_000_000_000, yaw);
        assert!(i16::from_be_bytes([b[0], b[1]]) < -3_000);
    }

    /// Stuck SDA: the chip holds the line until the injected number of SCL
    /// clocks; it NACKs meanwhile (it cannot see its address).
    #[test]
    fn stuck_sda_released_by_clocks() {
        let mut m = Mpu6050::new(2, false);
        m.faults.stuck_sda = Some((0, 7));
        m.stop(AWAKE);
        assert!(m.holds_sda());
        for _ in 0..6 {
            m.scl_clock();
        }
        assert!(m.holds_sda());
        m.scl_clock();
        assert!(!m.holds_sda());
    }
}
