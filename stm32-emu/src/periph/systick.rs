//! SysTick (ARMv7-M B3.3) on the core clock (CLKSOURCE = 1) or /8, and the
//! DWT cycle counter (CYCCNT counting core cycles while CYCCNTENA and
//! DEMCR.TRCENA). Both are evaluated from the emulated cycle count.

use super::{merge, Access};

/// SysTick.
#[derive(Clone, Debug, Default)]
pub struct SysTick {
    csr: u32,
    rvr: u32,
    /// Cycle count when CVR was last reloaded / written, and its value then.
    base_cycles: u64,
    base_cvr: u32,
}

impl SysTick {
    fn div(&self) -> u64 {
        if self.csr & 4 != 0 {
            1
        } else {
            8
        }
    }

    fn enabled(&self) -> bool {
        self.csr & 1 != 0
    }

    fn sync(&mut self, cycles: u64) {
        if !self.enabled() {
            return;
        }
        let ticks = (cycles - self.base_cycles) / self.div();
        if ticks < self.base_cvr as u64 {
            return;
        }
        if ticks > 0 {
            self.csr |= 1 << 16; // COUNTFLAG
        }
        let period = self.rvr as u64 + 1;
        let past = (ticks - self.base_cvr as u64) % period;
        let wraps = (ticks - self.base_cvr as u64) / period;
        self.base_cycles += (self.base_cvr as u64 + wraps * period) * self.div();
        self.base_cvr = self.rvr;
        let _ = past;
    }

    /// When the counter next reaches 0 with TICKINT \[core cycles\].
    pub fn next_irq_cycles(&self) -> Option<u64> {
        (self.enabled() && self.csr & 2 != 0 && self.rvr != 0)
            .then(|| self.base_cycles + self.base_cvr.max(1) as u64 * self.div())
    }

    /// Reads `off` from 0xE000_E010.
    pub fn read(&mut self, off: u32, cycles: u64) -> Access<u32> {
        self.sync(cycles);
        Ok(match off {
            0x0 => {
                let v = self.csr;
                self.csr &= !(1 << 16);
                v
            }
            0x4 => self.rvr,
            0x8 => {
                if self.enabled() {
                    let t = (cycles - self.base_cycles) / self.div();
                    self.base_cvr.saturating_sub(t as u32)
                } else {
                    self.base_cvr
                }
            }
            0xC => 0x4000_0000 | 20_999, // CALIB: NOREF, TENMS unknown-ish
            _ => return Err(format!("SysTick+0x{off:X}")),
        })
    }

    /// Writes `off` from 0xE000_E010.
    pub fn write(&mut self, off: u32, value: u32, mask: u32, cycles: u64) -> Access<()> {
        self.sync(cycles);
        match off {
            0x0 => {
                let was = self.enabled();
                self.csr = merge(self.csr, value, mask) & 0x1_0007;
                if !was && self.enabled() {
                    self.base_cycles = cycles;
                }
            }
            0x4 => self.rvr = merge(self.rvr, value, mask) & 0xFF_FFFF,
            0x8 => {
                self.base_cvr = 0;
                self.base_cycles = cycles;
                self.csr &= !(1 << 16);
            }
            _ => return Err(format!("SysTick+0x{off:X}")),
        }
        Ok(())
    }
}

/// The DWT's control and cycle counter.
#[derive(Clone, Debug, Default)]
pub struct Dwt {
    ctrl: u32,
    /// CYCCNT at `base_cycles` while counting.
    base_cnt: u32,
    base_cycles: u64,
}

impl Dwt {
    fn counting(&self) -> bool {
        self.ctrl & 1 != 0
    }

    fn cyccnt(&self, cycles: u64) -> u32 {
        if self.counting() {
            self.base_cnt
                .wrapping_add((cycles - self.base_cycles) as u32)
        } else {
            self.base_cnt
        }
    }

    /// Reads `off` from 0xE000_1000 (`trcena`: DEMCR.TRCENA).
    pub fn read(&mut self, off: u32, cycles: u64, trcena: bool) -> Access<u32> {
        if !trcena {
            return Err(format!("DWT+0x{off:X} read with DEMCR.TRCENA = 0"));
        }
        match off {
            0x0 => Ok(0x4000_0000 | self.ctrl), // NUMCOMP = 4
            0x4 => Ok(self.cyccnt(cycles)),
            _ => Err(format!("DWT+0x{off:X}")),
        }
    }

    /// Writes `off` from 0xE000_1000.
    pub fn write(&mut self, off: u32, value: u32, mask: u32, cycles: u64) -> Access<()> {
        match off {
            0x0 => {
                let cnt = self.cyccnt(cycles);
                self.ctrl = merge(self.ctrl, value, mask) & 1;
                self.base_cnt = cnt;
                self.base_cycles = cycles;
            }
            0x4 => {
                self.base_cnt = merge(self.cyccnt(cycles), value, mask);
                self.base_cycles = cycles;
            }
            _ => return Err(format!("DWT+0x{off:X}")),
        }
        Ok(())
    }
}
