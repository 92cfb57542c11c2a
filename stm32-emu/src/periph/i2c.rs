//! I2C1 in master mode (RM0383 §18 / RM0390 §24, the F4's I2C "v1"):
//! CR1, CR2, OAR1, OAR2, DR, SR1, SR2, CCR, TRISE, FLTR with their reset
//! values (TRISE 0x0002, the rest 0), and the master's events on the bus in
//! the order §18.3.3 gives them, each taking its bus time from CCR and
//! PCLK1 (F/S, DUTY: a fast-mode period of 3 × CCR or 25 × CCR clocks, a
//! standard one of 2 × CCR):
//! * START → the bus (SDA high) → SB, MSL, BUSY; START cleared by hardware.
//!   A bus whose SDA a slave holds low is busy: no START (BUSY stays set).
//! * DR write with SB → the address byte (9 clocks) → ADDR (TRA from R/W̄)
//!   on an acknowledge, AF (error) on none.
//! * SR2 read with ADDR → ADDR cleared; a transmitter has TxE, a receiver
//!   starts clocking bytes in.
//! * transmitter: DR → shift register (TxE again), 9 clocks, the slave's
//!   acknowledge (AF on none); with no next byte BTF.
//! * receiver: 9 clocks → RxNE (a byte in DR and one in the shift
//!   register: BTF, the clock stretched); the master acknowledges with ACK
//!   unless LAST is set and the DMA's next end of transfer is this byte
//!   (§18.3.7 "using DMA": LAST = 1 gives a NACK after the last byte).
//! * STOP → after the current byte (or at once) the stop condition: MSL,
//!   BUSY, TRA cleared; STOP cleared by hardware.
//! * repeated START after BTF (a write-read) as START.
//!
//! With DMAEN, TxE and RxNE are DMA requests (stream 6 / stream 0,
//! channel 1) instead of being left to the CPU. Events: ITEVTEN with SB,
//! ADDR, BTF (and TxE/RxNE with ITBUFEN) on the event line; ITERREN with
//! BERR, ARLO, AF, OVR on the error line. SR1's error flags clear on a
//! written 0 (rc_w0). Slave mode, 10-bit addressing, PEC, SMBus and the
//! analog/digital filters are not modelled (their bits are stored; slave
//! addressing is never enabled by the image).

use super::{merge, Access};

/// SR1 bits.
pub mod sr1 {
    /// Start bit (master).
    pub const SB: u32 = 1 << 0;
    /// Address sent (master).
    pub const ADDR: u32 = 1 << 1;
    /// Byte transfer finished.
    pub const BTF: u32 = 1 << 2;
    /// Receive data register not empty.
    pub const RXNE: u32 = 1 << 6;
    /// Transmit data register empty.
    pub const TXE: u32 = 1 << 7;
    /// Bus error.
    pub const BERR: u32 = 1 << 8;
    /// Arbitration lost.
    pub const ARLO: u32 = 1 << 9;
    /// Acknowledge failure.
    pub const AF: u32 = 1 << 10;
    /// Overrun/underrun.
    pub const OVR: u32 = 1 << 11;
    /// The error flags (cleared by writing 0).
    pub const ERRORS: u32 = 0xDF00;
}

/// CR1 bits.
pub mod cr1 {
    /// Peripheral enable.
    pub const PE: u32 = 1 << 0;
    /// Start generation.
    pub const START: u32 = 1 << 8;
    /// Stop generation.
    pub const STOP: u32 = 1 << 9;
    /// Acknowledge enable.
    pub const ACK: u32 = 1 << 10;
    /// Software reset.
    pub const SWRST: u32 = 1 << 15;
}

/// CR2 bits.
pub mod cr2 {
    /// Error interrupt enable.
    pub const ITERREN: u32 = 1 << 8;
    /// Event interrupt enable.
    pub const ITEVTEN: u32 = 1 << 9;
    /// Buffer interrupt enable.
    pub const ITBUFEN: u32 = 1 << 10;
    /// DMA requests enable.
    pub const DMAEN: u32 = 1 << 11;
    /// DMA last transfer.
    pub const LAST: u32 = 1 << 12;
}

/// What the I2C master needs from the devices on its bus.
pub trait Bus {
    /// SDA held low by a device.
    fn sda_held(&self) -> bool;
    /// A START (or repeated START) at `t`.
    fn start(&mut self, t: u128);
    /// A STOP at `t`.
    fn stop(&mut self, t: u128);
    /// The address byte's 7-bit address and R/W̄ at `t`; true on an ACK.
    fn address(&mut self, addr7: u8, read: bool, t: u128) -> bool;
    /// A byte written by the master at `t`; `Ok(true)` on an ACK.
    fn write_byte(&mut self, b: u8, t: u128) -> Result<bool, String>;
    /// The byte a slave sends.
    fn read_byte(&mut self) -> Result<u8, String>;
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Action {
    Start,
    Address(u8),
    Tx(u8),
    Rx,
    Stop,
}

/// Counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct I2cStats {
    /// START conditions generated (repeated ones included).
    pub starts: u64,
    /// STOP conditions generated.
    pub stops: u64,
    /// Address phases not acknowledged.
    pub address_nacks: u64,
    /// Bytes moved (either way, address bytes excluded).
    pub bytes: u64,
}

/// I2C1.
#[derive(Clone, Debug)]
pub struct I2c {
    cr1: u32,
    cr2: u32,
    oar1: u32,
    oar2: u32,
    ccr: u32,
    trise: u32,
    fltr: u32,
    sr1: u32,
    msl: bool,
    tra: bool,
    dr_tx: Option<u8>,
    dr_rx: Option<u8>,
    shift_rx: Option<u8>,
    action: Option<(u128, Action)>,
    start_pending: bool,
    stop_pending: bool,
    /// The master acknowledged the last byte it received.
    last_ack: bool,
    /// Time of the last completed action \[ps\].
    t_last: u128,
    /// A START is waiting for a bus a slave holds (BUSY).
    waiting_bus: bool,
    pclk1_hz: u64,
    /// Counters.
    pub stats: I2cStats,
}

impl I2c {
    /// I2C1 at its reset values on an APB1 of `pclk1_hz`.
    pub fn new(pclk1_hz: u64) -> Self {
        Self {
            cr1: 0,
            cr2: 0,
            oar1: 0,
            oar2: 0,
            ccr: 0,
            trise: 0x0002,
            fltr: 0,
            sr1: 0,
            msl: false,
            tra: false,
            dr_tx: None,
            dr_rx: None,
            shift_rx: None,
            action: None,
            start_pending: false,
            stop_pending: false,
            last_ack: false,
            t_last: 0,
            waiting_bus: false,
            pclk1_hz,
            stats: I2cStats::default(),
        }
    }

    /// The APB1 clock changed.
    pub fn set_clock(&mut self, pclk1_hz: u64) {
        self.pclk1_hz = pclk1_hz;
    }

    /// One SCL period \[ps\] from CCR and PCLK1.
    pub fn bit_ps(&self) -> u128 {
        let ccr = (self.ccr & 0xFFF).max(1) as u128;
        let clocks = if self.ccr & (1 << 15) != 0 {
            if self.ccr & (1 << 14) != 0 {
                25 * ccr
            } else {
                3 * ccr
            }
        } else {
            2 * ccr
        };
        (clocks * super::PS_PER_S).div_ceil(self.pclk1_hz as u128)
    }

    fn clear_transfer(&mut self) {
        self.sr1 = 0;
        self.msl = false;
        self.tra = false;
        self.dr_tx = None;
        self.dr_rx = None;
        self.shift_rx = None;
        self.action = None;
        self.start_pending = false;
        self.stop_pending = false;
        self.waiting_bus = false;
    }

    /// Whether CR1.START/STOP asked for something the bus model must run
    /// now (the harness then synchronises at once).
    pub fn wants_sync(&self) -> bool {
        self.start_pending || self.stop_pending || self.action.is_some()
    }

    /// CR2.FREQ \[MHz\].
    pub fn freq_mhz(&self) -> u32 {
        self.cr2 & 0x3F
    }

    /// Reads the register at `off`.
    pub fn read(&mut self, off: u32, now: u128) -> Access<u32> {
        Ok(match off {
            0x00 => self.cr1,
            0x04 => self.cr2,
            0x08 => self.oar1,
            0x0C => self.oar2,
            0x10 => self.read_dr(now) as u32,
            0x14 => self.sr1,
            0x18 => {
                let v = self.sr2();
                if self.sr1 & sr1::ADDR != 0 {
                    // EV6: ADDR cleared by reading SR1 then SR2.
                    self.sr1 &= !sr1::ADDR;
                    if self.tra {
                        self.sr1 |= sr1::TXE;
                    } else {
                        self.action = Some((now + 9 * self.bit_ps(), Action::Rx));
                    }
                }
                v
            }
            0x1C => self.ccr,
            0x20 => self.trise,
            0x24 => self.fltr,
            _ => return Err(format!("I2C1+0x{off:02X}")),
        })
    }

    fn sr2(&self) -> u32 {
        let busy = self.msl || self.waiting_bus;
        (self.msl as u32) | ((busy as u32) << 1) | ((self.tra as u32) << 2)
    }

    /// Writes the register at `off`.
    pub fn write(&mut self, off: u32, value: u32, mask: u32, now: u128) -> Access<()> {
        match off {
            0x00 => {
                let v = merge(self.cr1, value, mask) & 0xBFFB;
                if v & cr1::SWRST != 0 {
                    // Under reset: every register at its reset value.
                    let (p, stats) = (self.pclk1_hz, self.stats);
                    *self = Self::new(p);
                    self.stats = stats;
                    self.cr1 = cr1::SWRST;
                    return Ok(());
                }
                if v & cr1::PE == 0 {
                    self.clear_transfer();
                    self.cr1 = v & !(cr1::START | cr1::STOP);
                    return Ok(());
                }
                if v & cr1::START != 0 && self.cr1 & cr1::START == 0 {
                    self.start_pending = true;
                }
                if v & cr1::STOP != 0 && self.cr1 & cr1::STOP == 0 {
                    self.stop_pending = true;
                }
                self.cr1 = v;
            }
            0x04 => self.cr2 = merge(self.cr2, value, mask) & 0x1F3F,
            0x08 => self.oar1 = merge(self.oar1, value, mask) & 0x83FF,
            0x0C => self.oar2 = merge(self.oar2, value, mask) & 0xFF,
            0x10 => self.write_dr((value & mask) as u8, now),
            0x14 => {
                // rc_w0: a written 0 clears an error flag.
                self.sr1 &= !(!value & mask & sr1::ERRORS);
            }
            0x18 => return Err("I2C1.SR2 write (read-only)".into()),
            0x1C => {
                if self.cr1 & cr1::PE != 0 {
                    return Err("I2C1.CCR written with PE = 1 (RM0383 §18.6.8)".into());
                }
                self.ccr = merge(self.ccr, value, mask) & 0xCFFF
            }
            0x20 => {
                if self.cr1 & cr1::PE != 0 {
                    return Err("I2C1.TRISE written with PE = 1 (RM0383 §18.6.9)".into());
                }
                self.trise = merge(self.trise, value, mask) & 0x3F
            }
            0x24 => self.fltr = merge(self.fltr, value, mask) & 0x1F,
            _ => return Err(format!("I2C1+0x{off:02X}")),
        }
        Ok(())
    }

    fn write_dr(&mut self, b: u8, now: u128) {
        if self.sr1 & sr1::SB != 0 {
            // EV5: SB cleared by the address written to DR.
            self.sr1 &= !sr1::SB;
            self.action = Some((now + 9 * self.bit_ps(), Action::Address(b)));
            return;
        }
        if !(self.msl && self.tra) || self.sr1 & sr1::ADDR != 0 {
            return; // ignored: not transmitting
        }
        if self.action.is_none() {
            self.sr1 &= !sr1::BTF;
            self.sr1 |= sr1::TXE;
            self.action = Some((now + 9 * self.bit_ps(), Action::Tx(b)));
        } else {
            self.dr_tx = Some(b);
            self.sr1 &= !sr1::TXE;
        }
    }

    fn read_dr(&mut self, now: u128) -> u8 {
        let Some(v) = self.dr_rx.take() else {
            return 0;
        };
        self.sr1 &= !sr1::RXNE;
        if let Some(s) = self.shift_rx.take() {
            self.dr_rx = Some(s);
            self.sr1 |= sr1::RXNE;
            self.sr1 &= !sr1::BTF;
            if self.last_ack && !self.stop_pending && self.action.is_none() {
                self.action = Some((now + 9 * self.bit_ps(), Action::Rx));
            }
        }
        v
    }

    /// A TxE DMA request (DMAEN and TxE while transmitting).
    pub fn tx_request(&self) -> bool {
        self.cr2 & cr2::DMAEN != 0
            && self.sr1 & sr1::TXE != 0
            && self.msl
            && self.tra
            && self.dr_tx.is_none()
    }

    /// An RxNE DMA request.
    pub fn rx_request(&self) -> bool {
        self.cr2 & cr2::DMAEN != 0 && self.sr1 & sr1::RXNE != 0
    }

    /// The DMA writes DR.
    pub fn dma_write(&mut self, b: u8, now: u128) {
        self.write_dr(b, now);
    }

    /// The DMA reads DR.
    pub fn dma_read(&mut self, now: u128) -> u8 {
        self.read_dr(now)
    }

    /// When the bus action in progress ends \[ps\], or `now` when a START
    /// or STOP can begin at once.
    pub fn next_event_ps(&self, now: u128) -> Option<u128> {
        match self.action {
            Some((t, _)) => Some(t),
            None if self.stop_pending || (self.start_pending && !self.waiting_bus) => Some(now),
            None => None,
        }
    }

    /// Runs at most one bus step due by `now`: an action's completion, or
    /// the START/STOP that can begin. `rx_dma_left` is the RX stream's
    /// NDTR (for LAST). Returns whether something happened.
    pub fn step(&mut self, now: u128, bus: &mut dyn Bus, rx_dma_left: u32) -> Result<bool, String> {
        if self.cr1 & cr1::PE == 0 {
            return Ok(false);
        }
        if let Some((t, a)) = self.action {
            if t > now {
                return Ok(false);
            }
            self.action = None;
            self.t_last = t;
            self.complete(a, t, bus, rx_dma_left)?;
            return Ok(true);
        }
        let t = now.max(self.t_last);
        if self.stop_pending {
            if self.msl {
                self.action = Some((t + self.bit_ps(), Action::Stop));
            } else {
                self.stop_pending = false;
                self.cr1 &= !cr1::STOP;
            }
            return Ok(true);
        }
        if self.start_pending {
            if bus.sda_held() {
                self.waiting_bus = true;
                return Ok(false);
            }
            self.waiting_bus = false;
            self.start_pending = false;
            self.action = Some((t + self.bit_ps(), Action::Start));
            return Ok(true);
        }
        Ok(false)
    }

    fn complete(
        &mut self,
        a: Action,
        t: u128,
        bus: &mut dyn Bus,
        rx_dma_left: u32,
    ) -> Result<(), String> {
        match a {
            Action::Start => {
                self.stats.starts += 1;
                self.msl = true;
                self.sr1 |= sr1::SB;
                self.sr1 &= !(sr1::BTF | sr1::TXE);
                self.cr1 &= !cr1::START;
                bus.start(t);
            }
            Action::Address(b) => {
                let read = b & 1 != 0;
                if bus.address(b >> 1, read, t) {
                    self.sr1 |= sr1::ADDR;
                    self.tra = !read;
                } else {
                    self.stats.address_nacks += 1;
                    self.sr1 |= sr1::AF;
                }
            }
            Action::Tx(b) => {
                self.stats.bytes += 1;
                if !bus.write_byte(b, t)? {
                    self.sr1 |= sr1::AF;
                } else if let Some(n) = self.dr_tx.take() {
                    self.sr1 |= sr1::TXE;
                    self.action = Some((t + 9 * self.bit_ps(), Action::Tx(n)));
                } else {
                    self.sr1 |= sr1::BTF;
                }
            }
            Action::Rx => {
                self.stats.bytes += 1;
                let b = bus.read_byte()?;
                let pending = self.dr_rx.is_some() as u32;
                let last = self.cr2 & cr2::LAST != 0
                    && self.cr2 & cr2::DMAEN != 0
                    && rx_dma_left.saturating_sub(pending) <= 1;
                let ack = self.cr1 & cr1::ACK != 0 && !last;
                self.last_ack = ack;
                if self.dr_rx.is_none() {
                    self.dr_rx = Some(b);
                    self.sr1 |= sr1::RXNE;
                    if ack && !self.stop_pending {
                        self.action = Some((t + 9 * self.bit_ps(), Action::Rx));
                    }
                } else {
                    self.shift_rx = Some(b);
                    self.sr1 |= sr1::BTF;
                }
            }
            Action::Stop => {
                self.stats.stops += 1;
                self.msl = false;
                self.tra = false;
                self.stop_pending = false;
                self.cr1 &= !cr1::STOP;
                self.sr1 &= !(sr1::BTF | sr1::TXE);
                bus.stop(t);
            }
        }
        Ok(())
    }

    /// The event interrupt line (I2C1_EV).
    pub fn irq_ev(&self) -> bool {
        let ev = self.sr1 & (sr1::SB | sr1::ADDR | sr1::BTF) != 0;
        let buf = self.cr2 & cr2::ITBUFEN != 0 && self.sr1 & (sr1::TXE | sr1::RXNE) != 0;
        self.cr2 & cr2::ITEVTEN != 0 && (ev || buf)
    }

    /// The error interrupt line (I2C1_ER).
    pub fn irq_er(&self) -> bool {
        self.cr2 & cr2::ITERREN != 0 && self.sr1 & sr1::ERRORS != 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bus with one slave at 0x68 that logs what it sees.
    #[derive(Default)]
    struct Log {
        seen: Vec<String>,
        held: bool,
        nack: bool,
    }

    impl Bus for Log {
        fn sda_held(&self) -> bool {
            self.held
        }
        fn start(&mut self, _t: u128) {
            self.seen.push("S".into());
        }
        fn stop(&mut self, _t: u128) {
            self.seen.push("P".into());
        }
        fn address(&mut self, a: u8, read: bool, _t: u128) -> bool {
            self.seen
                .push(format!("A{a:02X}{}", if read { 'R' } else { 'W' }));
            a == 0x68 && !self.nack
        }
        fn write_byte(&mut self, b: u8, _t: u128) -> Result<bool, String> {
            self.seen.push(format!("W{b:02X}"));
            Ok(true)
        }
        fn read_byte(&mut self) -> Result<u8, String> {
            self.seen.push("R".into());
            Ok(0x5A)
        }
    }

    const PCLK1: u64 = 42_000_000;

    fn enabled() -> I2c {
        let mut i = I2c::new(PCLK1);
        i.write(0x04, 42, !0, 0).unwrap();
        // Fast mode, DUTY 0, CCR 35: 3 × 35 / 42 MHz = 2.5 µs per bit.
        i.write(0x1C, (1 << 15) | 35, !0, 0).unwrap();
        i.write(0x00, cr1::PE, !0, 0).unwrap();
        i
    }

    fn run(i: &mut I2c, bus: &mut Log, now: &mut u128, left: u32) {
        while let Some(t) = i.next_event_ps(*now) {
            if t > *now {
                *now = t;
            }
            if !i.step(*now, bus, left).unwrap() {
                break;
            }
        }
    }

    /// RM0383 §18.6: reset values (TRISE 2, the rest 0); fast-mode timing
    /// (§18.6.8: T_high = CCR × T_pclk1, T_low = 2 × CCR × T_pclk1).
    #[test]
    fn reset_values_and_bit_time() {
        let mut i = I2c::new(PCLK1);
        for (off, v) in [
            (0x00, 0),
            (0x04, 0),
            (0x14, 0),
            (0x18, 0),
            (0x1C, 0),
            (0x20, 2),
        ] {
            assert_eq!(i.read(off, 0).unwrap(), v, "+0x{off:02X}");
        }
        let i = enabled();
        assert_eq!(i.bit_ps(), 2_500_000, "400 kHz");
        assert!(I2c::new(PCLK1).read(0x28, 0).is_err(), "unknown offset");
    }

    /// RM0383 §18.3.3, figure 164 (master transmitter): S, EV5 (SB), the
    /// address, EV6 (ADDR), EV8_1 (TxE), data, EV8_2 (BTF), P.
    #[test]
    fn master_transmitter_event_sequence() {
        let mut i = enabled();
        let mut bus = Log::default();
        let mut now = 0;
        i.write(0x00, cr1::PE | cr1::START, !0, now).unwrap();
        run(&mut i, &mut bus, &mut now, 0);
        assert_eq!(i.read(0x14, now).unwrap() & sr1::SB, sr1::SB, "EV5");
        assert_eq!(i.read(0x18, now).unwrap() & 3, 3, "MSL, BUSY");
        assert_eq!(i.read(0x00, now).unwrap() & cr1::START, 0, "START cleared");
        i.write(0x10, 0x68 << 1, !0, now).unwrap();
        assert_eq!(i.read(0x14, now).unwrap() & sr1::SB, 0, "SB cleared by DR");
        let t0 = now;
        run(&mut i, &mut bus, &mut now, 0);
        assert_eq!(now - t0, 9 * 2_500_000, "address: 9 clocks");
        assert_eq!(i.read(0x14, now).unwrap() & sr1::ADDR, sr1::ADDR, "EV6");
        assert_eq!(i.read(0x18, now).unwrap() & 4, 4, "TRA");
        assert_eq!(
            i.read(0x14, now).unwrap() & (sr1::ADDR | sr1::TXE),
            sr1::TXE,
            "EV8_1"
        );
        i.write(0x10, 0x6B, !0, now).unwrap();
        i.write(0x10, 0x01, !0, now).unwrap();
        assert_eq!(i.read(0x14, now).unwrap() & sr1::TXE, 0, "DR full");
        run(&mut i, &mut bus, &mut now, 0);
        assert_eq!(i.read(0x14, now).unwrap() & sr1::BTF, sr1::BTF, "EV8_2");
        i.write(0x00, cr1::PE | cr1::STOP, !0, now).unwrap();
        run(&mut i, &mut bus, &mut now, 0);
        assert_eq!(i.read(0x18, now).unwrap() & 3, 0, "MSL, BUSY cleared");
        assert_eq!(bus.seen, ["S", "A68W", "W6B", "W01", "P"]);
    }

    /// §18.3.3 figure 165 (master receiver) with DMA and LAST (§18.3.7):
    /// the master acknowledges every byte but the last; a NACKed address
    /// sets AF (an error interrupt with ITERREN) and SR1 clears on a 0.
    #[test]
    fn master_receiver_nacks_the_last_byte_and_af() {
        let mut i = enabled();
        i.write(0x04, 42 | cr2::DMAEN | cr2::LAST, !0, 0).unwrap();
        let mut bus = Log::default();
        let mut now = 0;
        i.write(0x00, cr1::PE | cr1::ACK | cr1::START, !0, now)
            .unwrap();
        run(&mut i, &mut bus, &mut now, 3);
        i.write(0x10, (0x68 << 1) | 1, !0, now).unwrap();
        run(&mut i, &mut bus, &mut now, 3);
        i.read(0x14, now).unwrap();
        assert_eq!(i.read(0x18, now).unwrap() & 4, 0, "receiver");
        // One bus event at a time; the DMA takes each byte as RxNE rises.
        let mut got = Vec::new();
        let mut left = 3u32;
        let mut acks = Vec::new();
        while let Some(t) = i.next_event_ps(now) {
            now = now.max(t);
            let bytes = i.stats.bytes;
            if !i.step(now, &mut bus, left).unwrap() {
                break;
            }
            if i.stats.bytes > bytes {
                acks.push(i.last_ack);
            }
            while i.rx_request() && left > 0 {
                got.push(i.dma_read(now));
                left -= 1;
            }
        }
        assert_eq!(
            bus.seen.iter().filter(|s| *s == "R").count(),
            3,
            "no fourth byte clocked"
        );
        assert_eq!(got, [0x5A; 3]);
        assert_eq!(acks, [true, true, false], "NACK on the last byte");
        // Address NACK.
        let mut i = enabled();
        i.write(0x04, 42 | cr2::ITERREN, !0, 0).unwrap();
        let mut bus = Log {
            nack: true,
            ..Log::default()
        };
        i.write(0x00, cr1::PE | cr1::START, !0, now).unwrap();
        run(&mut i, &mut bus, &mut now, 0);
        i.write(0x10, 0x68 << 1, !0, now).unwrap();
        run(&mut i, &mut bus, &mut now, 0);
        assert_eq!(i.read(0x14, now).unwrap() & sr1::AF, sr1::AF);
        assert!(i.irq_er());
        i.write(0x14, !sr1::AF, !0, now).unwrap();
        assert!(!i.irq_er());
    }

    /// A slave holding SDA low: the bus is busy, no START (SB never set).
    #[test]
    fn no_start_while_sda_held() {
        let mut i = enabled();
        let mut bus = Log {
            held: true,
            ..Log::default()
        };
        let mut now = 0;
        i.write(0x00, cr1::PE | cr1::START, !0, now).unwrap();
        i.step(now, &mut bus, 0).unwrap();
        now += 1_000_000_000;
        i.step(now, &mut bus, 0).unwrap();
        assert_eq!(i.read(0x14, now).unwrap() & sr1::SB, 0);
        assert_eq!(i.read(0x18, now).unwrap() & 2, 2, "BUSY");
        assert!(bus.seen.is_empty());
    }
}
