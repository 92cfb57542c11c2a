//! IWDG (RM0390 §19): KR 0x5555 unlocks PR/RLR, 0xCCCC starts the
//! down-counter from its reset value 0xFFF, 0xAAAA reloads it from RLR; it
//! counts at LSI / (4 · 2^PR) and resets the chip when it reaches 0. SR
//! (PVU/RVU) reads 0: prescaler and reload updates take effect at once.

use super::{ticks_to_ps, Access};

/// LSI frequency \[Hz\] (RM0390: 32 kHz typical; datasheet 17-47 kHz).
pub const LSI_HZ: u64 = 32_000;

/// The independent watchdog.
#[derive(Clone, Debug, Default)]
pub struct Iwdg {
    unlocked: bool,
    pr: u32,
    rlr: u32,
    /// Started (cannot be stopped but by a reset).
    pub running: bool,
    /// When it expires \[ps\].
    expiry_ps: u128,
    /// Reloads since reset (feeds).
    pub feeds: u64,
}

impl Iwdg {
    /// At reset (RLR 0xFFF).
    pub fn new() -> Self {
        Self {
            rlr: 0xFFF,
            ..Self::default()
        }
    }

    /// The timeout \[ps\] of a count of `count` at the configured prescaler.
    fn period_ps(&self, count: u32) -> u128 {
        let div = 4u128 << self.pr.min(6);
        ticks_to_ps(count as u128 * div, LSI_HZ)
    }

    /// The configured timeout after a reload \[ps\] ((RLR+1)·4·2^PR / LSI).
    pub fn timeout_ps(&self) -> u128 {
        self.period_ps(self.rlr + 1)
    }

    /// When it resets the chip, if running.
    pub fn expiry_ps(&self) -> Option<u128> {
        self.running.then_some(self.expiry_ps)
    }

    /// Reads the register at `off`.
    pub fn read(&mut self, off: u32) -> Access<u32> {
        match off {
            0x00 => Ok(0),
            0x04 => Ok(self.pr),
            0x08 => Ok(self.rlr),
            0x0C => Ok(0),
            _ => Err(format!("IWDG+0x{off:02X}")),
        }
    }

    /// Writes the register at `off`.
    pub fn write(&mut self, off: u32, value: u32, now_ps: u128) -> Access<()> {
        match off {
            0x00 => match value & 0xFFFF {
                0x5555 => self.unlocked = true,
                0xCCCC => {
                    if !self.running {
                        self.running = true;
                        self.expiry_ps = now_ps + self.period_ps(0x1000);
                    }
                    self.unlocked = false;
                }
                0xAAAA => {
                    self.expiry_ps = now_ps + self.timeout_ps();
                    self.feeds += 1;
                    self.unlocked = false;
                }
                _ => self.unlocked = false,
            },
            0x04 if self.unlocked => self.pr = value & 7,
            0x08 if self.unlocked => self.rlr = value & 0xFFF,
            0x04 | 0x08 => {} // write-protected: ignored, as on the chip
            _ => return Err(format!("IWDG+0x{off:02X}")),
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// RM0390 table 107: PR = 3 (/32), RLR = 0xFFF: 4096 ms at 32 kHz;
    /// writes before the 0x5555 key are ignored; started, it resets
    /// 0x1000 periods later, a reload moves that to RLR+1 periods.
    #[test]
    fn timeout_formula_and_keys() {
        let mut w = Iwdg::new();
        w.write(0x04, 3, 0).unwrap();
        assert_eq!(w.read(0x04).unwrap(), 0, "locked");
        w.write(0x00, 0x5555, 0).unwrap();
        w.write(0x04, 3, 0).unwrap();
        assert_eq!(w.timeout_ps(), 4_096 * 1_000_000_000);
        w.write(0x00, 0x5555, 0).unwrap();
        w.write(0x08, 49, 0).unwrap(); // 50 periods of 1 ms
        w.write(0x00, 0xCCCC, 0).unwrap();
        assert_eq!(w.expiry_ps(), Some(4_096 * 1_000_000_000));
        w.write(0x00, 0xAAAA, 10).unwrap();
        assert_eq!(w.expiry_ps(), Some(10 + 50 * 1_000_000_000));
    }
}
