//! USART (RM0390 §25, the F4's "v1" USART): SR flags TXE, TC, RXNE, IDLE,
//! ORE with their clearing sequences, DR, BRR, CR1-3, GTPR. Characters move
//! at the configured rate: one frame (start + 8 or 9 data + stop bits) per
//! BRR-derived bit time in both directions, so the firmware sees the
//! real UART's pacing and overruns. Transmitted bytes go to the host, host
//! bytes arrive one frame apart.

use super::{merge, ticks_to_ps, Access};
use std::collections::VecDeque;

/// SR bits.
pub mod sr {
    /// Overrun.
    pub const ORE: u32 = 1 << 3;
    /// Idle line.
    pub const IDLE: u32 = 1 << 4;
    /// Receive register not empty.
    pub const RXNE: u32 = 1 << 5;
    /// Transmission complete.
    pub const TC: u32 = 1 << 6;
    /// Transmit register empty.
    pub const TXE: u32 = 1 << 7;
}

/// One USART.
#[derive(Clone, Debug)]
pub struct Usart {
    /// Name, e.g. "USART2".
    pub name: &'static str,
    sr: u32,
    dr_rx: u8,
    brr: u32,
    cr1: u32,
    cr2: u32,
    cr3: u32,
    gtpr: u32,
    /// SR was read with ORE/IDLE set (the first half of their clearing).
    sr_read: u32,
    tdr: Option<u8>,
    /// The byte in the shift register and when its stop bit ends \[ps\].
    shifting: Option<(u8, u128)>,
    /// Bytes from the host not yet on the wire.
    pub rx_queue: VecDeque<u8>,
    /// When the next host byte completes \[ps\] (one frame after the last).
    rx_next_ps: u128,
    /// A byte was received since the last IDLE: the line can go idle.
    rx_since_idle: bool,
    /// When the line becomes idle \[ps\] (one frame after the last byte).
    idle_at_ps: Option<u128>,
    /// Bytes sent to the host.
    pub tx_out: Vec<u8>,
    /// Bytes received from the host.
    pub rx_bytes: u64,
    /// Bytes transmitted to the host.
    pub tx_bytes: u64,
    /// Overrun events (a byte lost because RXNE was still set).
    pub overruns: u64,
    /// Kernel clock (its APB) \[Hz\].
    clk_hz: u64,
}

impl Usart {
    /// At reset on a kernel clock of `clk_hz`.
    pub fn new(name: &'static str, clk_hz: u64) -> Self {
        Self {
            name,
            sr: sr::TXE | sr::TC,
            dr_rx: 0,
            brr: 0,
            cr1: 0,
            cr2: 0,
            cr3: 0,
            gtpr: 0,
            sr_read: 0,
            tdr: None,
            shifting: None,
            rx_queue: VecDeque::new(),
            rx_next_ps: 0,
            rx_since_idle: false,
            idle_at_ps: None,
            tx_out: Vec::new(),
            rx_bytes: 0,
            tx_bytes: 0,
            overruns: 0,
            clk_hz,
        }
    }

    /// Changes the kernel clock.
    pub fn set_clock(&mut self, clk_hz: u64) {
        self.clk_hz = clk_hz;
    }

    fn enabled(&self) -> bool {
        self.cr1 & (1 << 13) != 0
    }

    /// Baud rate from BRR (OVER8 = 0: baud = f_ck / BRR; OVER8 = 1 with the
    /// fraction's three bits), 0 when BRR is unset.
    pub fn baud(&self) -> u64 {
        if self.brr == 0 {
            return 0;
        }
        if self.cr1 & (1 << 15) != 0 {
            let div8 = ((self.brr >> 4) << 3) | (self.brr & 7);
            return (self.clk_hz * 2).checked_div(div8 as u64).unwrap_or(0);
        }
        self.clk_hz / self.brr as u64
    }

    /// One frame \[ps\]: start + 8/9 data (+ parity in them) + 1/2 stop bits.
    pub fn frame_ps(&self) -> u128 {
        let data = if self.cr1 & (1 << 12) != 0 { 9 } else { 8 };
        let stop = match (self.cr2 >> 12) & 3 {
            2 => 2,
            _ => 1,
        };
        let baud = self.baud().max(1);
        ticks_to_ps(1 + data + stop, baud)
    }

    /// Advances to `now_ps`: transmissions complete, host bytes arrive,
    /// the line goes idle.
    pub fn sync(&mut self, now_ps: u128) {
        if !self.enabled() {
            return;
        }
        // Transmitter.
        while let Some((b, done)) = self.shifting {
            if done > now_ps {
                break;
            }
            self.tx_out.push(b);
            self.tx_bytes += 1;
            self.shifting = self.tdr.take().map(|n| (n, done + self.frame_ps()));
            if self.shifting.is_some() {
                self.sr |= sr::TXE;
            } else {
                self.sr |= sr::TC;
            }
        }
        // Receiver (RE set and a baud rate).
        if self.cr1 & (1 << 2) != 0 && self.baud() > 0 {
            while !self.rx_queue.is_empty() && self.rx_next_ps <= now_ps {
                let b = self.rx_queue.pop_front().unwrap_or(0);
                if self.sr & sr::RXNE != 0 {
                    self.sr |= sr::ORE;
                    self.overruns += 1;
                } else {
                    self.dr_rx = b;
                    self.sr |= sr::RXNE;
                }
                self.rx_bytes += 1;
                self.rx_since_idle = true;
                let at = self.rx_next_ps;
                self.idle_at_ps = Some(at + self.frame_ps());
                self.rx_next_ps = at + self.frame_ps();
            }
            if let Some(t) = self.idle_at_ps {
                if t <= now_ps && self.rx_queue.is_empty() && self.rx_since_idle {
                    self.sr |= sr::IDLE;
                    self.rx_since_idle = false;
                    self.idle_at_ps = None;
                }
            }
        }
    }

    /// Host bytes arrive: they start on the wire at `now_ps` at the
    /// earliest, one frame apart.
    pub fn host_send(&mut self, bytes: &[u8], now_ps: u128) {
        if self.rx_queue.is_empty() && self.rx_next_ps < now_ps + self.frame_ps() {
            self.rx_next_ps = now_ps + self.frame_ps();
        }
        self.rx_queue.extend(bytes);
    }

    /// When the state next changes by itself \[ps\].
    pub fn next_event_ps(&self) -> Option<u128> {
        if !self.enabled() {
            return None;
        }
        let mut t: Option<u128> = self.shifting.map(|s| s.1);
        let mut add = |x: u128| t = Some(t.map_or(x, |y: u128| y.min(x)));
        if !self.rx_queue.is_empty() && self.cr1 & (1 << 2) != 0 {
            add(self.rx_next_ps);
        }
        if let Some(i) = self.idle_at_ps {
            add(i);
        }
        t
    }

    /// The interrupt line (flags & their enables in CR1/CR3).
    pub fn irq(&self) -> bool {
        let c = self.cr1;
        let s = self.sr;
        (c & (1 << 7) != 0 && s & sr::TXE != 0)
            || (c & (1 << 6) != 0 && s & sr::TC != 0)
            || (c & (1 << 5) != 0 && s & (sr::RXNE | sr::ORE) != 0)
            || (c & (1 << 4) != 0 && s & sr::IDLE != 0)
            || (self.cr3 & 1 != 0 && s & 0xF & !sr::ORE != 0)
    }

    /// Reads the register at `off`.
    pub fn read(&mut self, off: u32, now_ps: u128) -> Access<u32> {
        self.sync(now_ps);
        Ok(match off {
            0x00 => {
                self.sr_read = self.sr & (sr::ORE | sr::IDLE | 0x7 | sr::TC);
                self.sr
            }
            0x04 => {
                // RXNE cleared by the read; ORE/IDLE/NF/FE/PE by SR then DR.
                self.sr &= !(sr::RXNE | self.sr_read);
                self.sr_read = 0;
                self.dr_rx as u32
            }
            0x08 => self.brr,
            0x0C => self.cr1,
            0x10 => self.cr2,
            0x14 => self.cr3,
            0x18 => self.gtpr,
            _ => return Err(format!("{}+0x{off:02X}", self.name)),
        })
    }

    /// Writes the register at `off`.
    pub fn write(&mut self, off: u32, value: u32, mask: u32, now_ps: u128) -> Access<()> {
        self.sync(now_ps);
        match off {
            0x00 => {
                // Only TC and RXNE may be cleared by writing 0 (rc_w0).
                let v = merge(self.sr, value, mask);
                self.sr &= v | !(sr::TC | sr::RXNE);
            }
            0x04 => {
                let b = (value & mask & 0xFF) as u8;
                if self.sr_read & sr::TC != 0 {
                    self.sr &= !sr::TC; // SR read then DR write
                }
                self.sr_read = 0;
                if !self.enabled() || self.cr1 & (1 << 3) == 0 {
                    return Err(format!(
                        "{}.DR written with UE or TE off (byte 0x{b:02X} would be lost)",
                        self.name
                    ));
                }
                if self.shifting.is_none() {
                    self.shifting = Some((b, now_ps + self.frame_ps()));
                    self.sr &= !sr::TC;
                } else if self.tdr.is_none() {
                    self.tdr = Some(b);
                    self.sr &= !(sr::TXE | sr::TC);
                } else {
                    return Err(format!(
                        "{}.DR written while TXE = 0 (byte 0x{b:02X} overwrites one not yet sent)",
                        self.name
                    ));
                }
            }
            0x08 => self.brr = merge(self.brr, value, mask) & 0xFFFF,
            0x0C => {
                let was = self.enabled();
                self.cr1 = merge(self.cr1, value, mask);
                if !was && self.enabled() {
                    self.rx_next_ps = now_ps + self.frame_ps();
                }
            }
            0x10 => self.cr2 = merge(self.cr2, value, mask),
            0x14 => {
                self.cr3 = merge(self.cr3, value, mask);
                if self.cr3 & ((1 << 6) | (1 << 7) | (1 << 8) | (1 << 9)) != 0 {
                    return Err(format!(
                        "{}.CR3 = 0x{:X}: DMA or hardware flow control not modelled",
                        self.name, self.cr3
                    ));
                }
            }
            0x18 => self.gtpr = merge(self.gtpr, value, mask),
            _ => return Err(format!("{}+0x{off:02X}", self.name)),
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 42 MHz APB1, BRR for 115 200 baud (42e6/115200 = 364.58 → 365):
    /// a frame is 10 bits = 86.9 µs; two host bytes arrive one frame apart,
    /// the second overruns when the first is not read; IDLE one frame after.
    #[test]
    fn pacing_overrun_idle() {
        let mut u = Usart::new("USART2", 42_000_000);
        u.write(0x08, 365, !0, 0).unwrap();
        u.write(0x0C, (1 << 13) | (1 << 3) | (1 << 2), !0, 0)
            .unwrap();
        assert_eq!(u.baud(), 42_000_000 / 365);
        let f = u.frame_ps();
        assert_eq!(f, (10u128 * 1_000_000_000_000).div_ceil(115_068));
        u.host_send(&[1, 2], 0);
        u.sync(f - 1);
        assert_eq!(u.read(0, f - 1).unwrap() & sr::RXNE, 0);
        u.sync(f);
        assert_ne!(u.read(0, f).unwrap() & sr::RXNE, 0);
        u.sync(2 * f);
        let s = u.read(0, 2 * f).unwrap();
        assert_ne!(s & sr::ORE, 0);
        assert_eq!(u.read(0x04, 2 * f).unwrap(), 1, "first byte kept");
        assert_eq!(u.read(0, 2 * f).unwrap() & (sr::ORE | sr::RXNE), 0);
        u.sync(3 * f);
        assert_ne!(u.read(0, 3 * f).unwrap() & sr::IDLE, 0);
    }

    /// TX: TXE stays set for the first byte (shift register empty), the
    /// second fills DR; both leave one frame apart, then TC.
    #[test]
    fn transmit_pacing() {
        let mut u = Usart::new("USART2", 42_000_000);
        u.write(0x08, 365, !0, 0).unwrap();
        u.write(0x0C, (1 << 13) | (1 << 3), !0, 0).unwrap();
        let f = u.frame_ps();
        u.write(0x04, b'a' as u32, !0, 0).unwrap();
        assert_ne!(u.read(0, 0).unwrap() & sr::TXE, 0);
        u.write(0x04, b'b' as u32, !0, 0).unwrap();
        assert_eq!(u.read(0, 0).unwrap() & (sr::TXE | sr::TC), 0);
        u.sync(f);
        assert_eq!(u.tx_out, b"a");
        u.sync(2 * f);
        assert_eq!(u.tx_out, b"ab");
        assert_ne!(u.read(0, 2 * f).unwrap() & sr::TC, 0);
    }
}
