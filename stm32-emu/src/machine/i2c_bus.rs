//! The IMU's bus: I2C1 and DMA1 (the driver's streams 0 and 6, channel 1)
//! moving bytes between SRAM and I2C1.DR, the MPU-6050 behind them, the
//! SCL/SDA lines shared with GPIOB (PB8/PB9: a slave holding SDA reads low
//! on the pin; SCL clocked as a GPIO reaches the slave).

use super::*;
use crate::mpu6050::Mpu6050;
use crate::periph::i2c::Bus;

/// I2C1.DR's address (the DMA streams' PAR).
pub const I2C1_DR: u32 = 0x4000_5410;
/// DMA1 channel of I2C1_RX (stream 0) and I2C1_TX (stream 6) (RM0383 table 27).
const I2C1_DMA_CHANNEL: u32 = 1;
/// SCL and SDA on GPIOB.
const SCL_PIN: u32 = 8;
const SDA_PIN: u32 = 9;

/// The MPU-6050 as the I2C master's bus, with the robot's yaw rate now.
struct MpuBus<'a> {
    mpu: &'a mut Mpu6050,
    yaw_radps: f64,
}

impl Bus for MpuBus<'_> {
    fn sda_held(&self) -> bool {
        self.mpu.holds_sda()
    }
    fn start(&mut self, t: u128) {
        self.mpu.start(t);
    }
    fn stop(&mut self, t: u128) {
        self.mpu.stop(t);
    }
    fn address(&mut self, addr7: u8, read: bool, t: u128) -> bool {
        self.mpu.address(addr7, read, t, self.yaw_radps)
    }
    fn write_byte(&mut self, b: u8, t: u128) -> Result<bool, String> {
        self.mpu.write_byte(b, t)
    }
    fn read_byte(&mut self) -> Result<u8, String> {
        self.mpu.read_byte()
    }
}

impl Board {
    /// A DMA item I2C1 can move now (its request and an enabled stream).
    fn i2c_dma_item(&self) -> Result<Option<crate::periph::dma::Item>, String> {
        if self.i2c1.tx_request() {
            if let Some(it) = self.dma1.request(6, I2C1_DMA_CHANNEL, I2C1_DR)? {
                return Ok(Some(it));
            }
        }
        if self.i2c1.rx_request() {
            if let Some(it) = self.dma1.request(0, I2C1_DMA_CHANNEL, I2C1_DR)? {
                return Ok(Some(it));
            }
        }
        Ok(None)
    }

    /// The next time the IMU's bus changes by itself \[ps\].
    pub(super) fn i2c_next_event_ps(&self) -> Option<u128> {
        let now = self.now_ps();
        if matches!(self.i2c_dma_item(), Ok(Some(_))) {
            return Some(now);
        }
        self.i2c1.next_event_ps(now)
    }

    /// CR1.START: the lines must be I2C1's (AF4, open drain), the kernel
    /// clock as CR2.FREQ says (RM0383 §18.6.2).
    pub(super) fn i2c_start_check(&self) -> Result<(), String> {
        let b = &self.gpio[1];
        for (pin, name) in [(SCL_PIN, "SCL PB8"), (SDA_PIN, "SDA PB9")] {
            if b.mode(pin) != gpio::Mode::Alternate(4) || !b.open_drain(pin) {
                return Err(format!(
                    "I2C1 START with {name} in mode {:?}, open drain {}: not I2C1's AF4 open-drain pin",
                    b.mode(pin),
                    b.open_drain(pin)
                ));
            }
        }
        let pclk1_mhz = self.rcc.clocks()?.pclk1_hz / 1_000_000;
        if self.i2c1.freq_mhz() as u64 != pclk1_mhz {
            return Err(format!(
                "I2C1 START with CR2.FREQ = {} MHz but PCLK1 = {pclk1_mhz} MHz (RM0383 §18.6.2)",
                self.i2c1.freq_mhz()
            ));
        }
        Ok(())
    }

    /// A GPIOB write: SCL clocked as a GPIO (bus recovery) reaches the
    /// slave (a rising edge of the line); SDA reads what the slave leaves
    /// of it.
    pub(super) fn gpio_b_written(&mut self, scl_before: bool) {
        if !scl_before && self.scl_line() {
            self.mpu.scl_clock();
        }
        self.sda_line();
        self.drain_mpu_events();
    }

    /// The SCL line's level: PB8's ODR as a GPIO output (open drain), else
    /// high (the pull-ups; the I2C peripheral's own clocking is its bus
    /// model's, and it never clocks while a slave holds SDA).
    pub(super) fn scl_line(&self) -> bool {
        let b = &self.gpio[1];
        b.mode(SCL_PIN) != gpio::Mode::Output || b.odr_bit(SCL_PIN)
    }

    /// PB9 reads low while the slave holds SDA.
    pub(super) fn sda_line(&mut self) {
        let held = self.mpu.holds_sda();
        self.gpio[1].pull_low(SDA_PIN, held);
    }

    fn drain_mpu_events(&mut self) {
        for e in std::mem::take(&mut self.mpu.events) {
            self.event(e);
        }
    }
}

impl Machine<'_> {
    /// The IMU's bus to now: DMA items and bus steps until nothing is due.
    pub(super) fn sync_i2c(&mut self) -> Result<(), String> {
        let ue = |e: uc_error| format!("DMA1: {e:?}");
        for _ in 0..10_000 {
            let d = self.uc.get_data_mut();
            let now = d.now_ps();
            match d.i2c_dma_item()? {
                Some(it) if it.dir == crate::periph::dma::Dir::MemToPeriph => {
                    let mut b = [0u8];
                    self.uc
                        .mem_read(it.mem_addr as u64, &mut b)
                        .map_err(|e| format!("{} reading 0x{:08X}", ue(e), it.mem_addr))?;
                    let d = self.uc.get_data_mut();
                    d.i2c1.dma_write(b[0], now);
                    d.dma1.item_done(it.stream);
                    continue;
                }
                Some(it) => {
                    let b = d.i2c1.dma_read(now);
                    d.dma1.item_done(it.stream);
                    self.uc
                        .mem_write(it.mem_addr as u64, &[b])
                        .map_err(|e| format!("{} writing 0x{:08X}", ue(e), it.mem_addr))?;
                    continue;
                }
                None => {}
            }
            if d.i2c1.next_event_ps(now).is_none_or(|t| t > now) {
                d.sda_line();
                d.drain_mpu_events();
                return Ok(());
            }
            d.sync_robot()?;
            let yaw_radps = d.robot.yaw_rate_radps();
            let left = d.dma1.streams[0].ndtr;
            let mut bus = MpuBus {
                mpu: &mut d.mpu,
                yaw_radps,
            };
            let stepped = d.i2c1.step(now, &mut bus, left)?;
            d.sda_line();
            d.drain_mpu_events();
            if !stepped {
                return Ok(());
            }
        }
        Err("I2C1: more than 10,000 bus steps at one instant".into())
    }
}
