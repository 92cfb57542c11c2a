//! PWR (RM0390 §5.4): CR is storage; CSR's VOSRDY is set (the regulator
//! is ready at once), ODRDY / ODSWRDY follow CR's ODEN / ODSWEN.

use super::{merge, Access};

/// The power controller.
#[derive(Clone, Debug)]
pub struct Pwr {
    cr: u32,
}

impl Default for Pwr {
    fn default() -> Self {
        Self { cr: 0x0000_C000 }
    }
}

impl Pwr {
    /// Reads the register at `off`.
    pub fn read(&mut self, off: u32) -> Access<u32> {
        match off {
            0x00 => Ok(self.cr),
            0x04 => {
                let mut csr = 1 << 14; // VOSRDY
                if self.cr & (1 << 16) != 0 {
                    csr |= 1 << 16; // ODRDY
                }
                if self.cr & (1 << 17) != 0 {
                    csr |= 1 << 17; // ODSWRDY
                }
                Ok(csr)
            }
            _ => Err(format!("PWR+0x{off:02X}")),
        }
    }

    /// Writes the register at `off`.
    pub fn write(&mut self, off: u32, value: u32, mask: u32) -> Access<()> {
        match off {
            0x00 => {
                self.cr = merge(self.cr, value, mask);
                Ok(())
            }
            0x04 => Ok(()), // EWUP/BRE: stored nowhere (no backup domain model)
            _ => Err(format!("PWR+0x{off:02X}")),
        }
    }
}
