//! DBGMCU (RM0390 §33.16): the device ID and the freeze bits, stored (no
//! debugger halts the emulated core; the bits are reported).

use super::{merge, Access};

/// The debug MCU block.
#[derive(Clone, Debug)]
pub struct Dbgmcu {
    idcode: u32,
    regs: [u32; 3],
}

impl Dbgmcu {
    /// With the chip's IDCODE (0x1000_6421 F446, 0x1000_6431 F411).
    pub fn new(idcode: u32) -> Self {
        Self {
            idcode,
            regs: [0; 3],
        }
    }

    /// APB1_FZ, APB2_FZ as written.
    pub fn freeze(&self) -> (u32, u32) {
        (self.regs[1], self.regs[2])
    }

    /// Reads the register at `off`.
    pub fn read(&mut self, off: u32) -> Access<u32> {
        match off {
            0x00 => Ok(self.idcode),
            0x04 | 0x08 | 0x0C => Ok(self.regs[off as usize / 4 - 1]),
            _ => Err(format!("DBGMCU+0x{off:02X}")),
        }
    }

    /// Writes the register at `off`.
    pub fn write(&mut self, off: u32, value: u32, mask: u32) -> Access<()> {
        match off {
            0x04 | 0x08 | 0x0C => {
                let i = off as usize / 4 - 1;
                self.regs[i] = merge(self.regs[i], value, mask);
                Ok(())
            }
            _ => Err(format!("DBGMCU+0x{off:02X}")),
        }
    }
}
