//! FLASH interface registers (RM0390 §3.8): ACR (latency, caches) is
//! storage with read-back; the key, status and control registers are
//! storage with the reset LOCK bit. Program/erase is not modelled yet (the
//! main-branch image has no flash store): setting PG, SER or MER fails the
//! run rather than pretending to write.

use super::{merge, Access};

const REGS: &[(u32, &str, u32)] = &[
    (0x00, "ACR", 0),
    (0x04, "KEYR", 0),
    (0x08, "OPTKEYR", 0),
    (0x0C, "SR", 0),
    (0x10, "CR", 0x8000_0000),
    (0x14, "OPTCR", 0x0FFF_AAED),
];

/// The flash interface.
#[derive(Clone, Debug)]
pub struct Flash {
    regs: [u32; 6],
}

impl Default for Flash {
    fn default() -> Self {
        let mut regs = [0; 6];
        for &(o, _, v) in REGS {
            regs[o as usize / 4] = v;
        }
        Self { regs }
    }
}

impl Flash {
    /// Reads the register at `off`.
    pub fn read(&mut self, off: u32) -> Access<u32> {
        match REGS.iter().find(|r| r.0 == off) {
            Some(_) if off == 0x04 || off == 0x08 => Ok(0), // write-only keys
            Some(_) => Ok(self.regs[off as usize / 4]),
            None => Err(format!("FLASH+0x{off:02X}")),
        }
    }

    /// Writes the register at `off`.
    pub fn write(&mut self, off: u32, value: u32, mask: u32) -> Access<()> {
        let Some(&(_, name, _)) = REGS.iter().find(|r| r.0 == off) else {
            return Err(format!("FLASH+0x{off:02X}"));
        };
        let i = off as usize / 4;
        let v = merge(self.regs[i], value, mask);
        if name == "CR" && v & 0x7 != 0 {
            return Err("FLASH.CR PG/SER/MER (program/erase): not modelled".into());
        }
        if name == "SR" {
            self.regs[i] &= !(v & 0xF3); // rc_w1 flags
        } else {
            self.regs[i] = v;
        }
        Ok(())
    }
}
