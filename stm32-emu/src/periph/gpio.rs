//! GPIO ports (RM0390 §7.4): MODER, OTYPER, OSPEEDR, PUPDR, ODR, AFRL/H
//! stored with their reset values; BSRR sets/resets ODR bits; IDR reads
//! the pin levels: an output's ODR bit, an input's external drive (the
//! harness's, e.g. the arm button) or else its pull (pull-up high,
//! otherwise low: the board's pull-downs).

use super::{merge, Access};

/// Pin mode (MODER field).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Input.
    Input,
    /// General-purpose output.
    Output,
    /// Alternate function (the AF number).
    Alternate(u8),
    /// Analog.
    Analog,
}

/// One GPIO port.
#[derive(Clone, Debug)]
pub struct Port {
    /// Port letter.
    pub name: char,
    moder: u32,
    otyper: u32,
    ospeedr: u32,
    pupdr: u32,
    odr: u32,
    lckr: u32,
    afr: [u32; 2],
    /// Pins driven from outside (bit set: driven), and their levels.
    ext_mask: u16,
    ext_level: u16,
    /// Open-drain lines another device pulls low (an I2C slave on SDA).
    pulled_low: u16,
}

impl Port {
    /// Port `name` at its reset values (RM0390 §7.4: A and B differ for
    /// the debug pins).
    pub fn new(name: char) -> Self {
        let (moder, ospeedr, pupdr) = match name {
            'A' => (0xA800_0000, 0x0C00_0000, 0x6400_0000),
            'B' => (0x0000_0280, 0x0000_00C0, 0x0000_0100),
            _ => (0, 0, 0),
        };
        Self {
            name,
            moder,
            otyper: 0,
            ospeedr,
            pupdr,
            odr: 0,
            lckr: 0,
            afr: [0; 2],
            ext_mask: 0,
            ext_level: 0,
            pulled_low: 0,
        }
    }

    /// The mode of `pin`.
    pub fn mode(&self, pin: u32) -> Mode {
        match (self.moder >> (2 * pin)) & 3 {
            0 => Mode::Input,
            1 => Mode::Output,
            2 => Mode::Alternate(((self.afr[(pin / 8) as usize] >> (4 * (pin % 8))) & 0xF) as u8),
            _ => Mode::Analog,
        }
    }

    /// The ODR bit of `pin`.
    pub fn odr_bit(&self, pin: u32) -> bool {
        self.odr & (1 << pin) != 0
    }

    /// The level of `pin` on the board: an output's ODR bit, an external
    /// drive, else the pull (pull-up high; none or pull-down low).
    pub fn level(&self, pin: u32) -> bool {
        if self.pulled_low & (1 << pin) != 0 {
            return false; // wired-AND: another device holds the line low
        }
        if self.mode(pin) == Mode::Output {
            return self.odr_bit(pin);
        }
        if self.ext_mask & (1 << pin) != 0 {
            return self.ext_level & (1 << pin) != 0;
        }
        (self.pupdr >> (2 * pin)) & 3 == 1
    }

    /// Whether `pin`'s output is open drain (OTYPER).
    pub fn open_drain(&self, pin: u32) -> bool {
        self.otyper & (1 << pin) != 0
    }

    /// Another device on the line pulls `pin` low (`true`) or releases it.
    pub fn pull_low(&mut self, pin: u32, low: bool) {
        if low {
            self.pulled_low |= 1 << pin;
        } else {
            self.pulled_low &= !(1 << pin);
        }
    }

    /// Drives `pin` from outside (`Some(level)`) or releases it (`None`).
    pub fn drive(&mut self, pin: u32, level: Option<bool>) {
        match level {
            Some(l) => {
                self.ext_mask |= 1 << pin;
                if l {
                    self.ext_level |= 1 << pin;
                } else {
                    self.ext_level &= !(1 << pin);
                }
            }
            None => self.ext_mask &= !(1 << pin),
        }
    }

    fn idr(&self) -> u32 {
        (0..16)
            .filter(|&p| self.level(p))
            .fold(0, |a, p| a | (1 << p))
    }

    /// Reads the register at `off`.
    pub fn read(&mut self, off: u32) -> Access<u32> {
        Ok(match off {
            0x00 => self.moder,
            0x04 => self.otyper,
            0x08 => self.ospeedr,
            0x0C => self.pupdr,
            0x10 => self.idr(),
            0x14 => self.odr,
            0x18 => 0, // BSRR reads as 0
            0x1C => self.lckr,
            0x20 => self.afr[0],
            0x24 => self.afr[1],
            _ => return Err(format!("GPIO{}+0x{off:02X}", self.name)),
        })
    }

    /// Writes the register at `off`; true when a pin's level may have
    /// changed.
    pub fn write(&mut self, off: u32, value: u32, mask: u32) -> Access<bool> {
        match off {
            0x00 => self.moder = merge(self.moder, value, mask),
            0x04 => self.otyper = merge(self.otyper, value, mask) & 0xFFFF,
            0x08 => self.ospeedr = merge(self.ospeedr, value, mask),
            0x0C => self.pupdr = merge(self.pupdr, value, mask),
            0x10 => return Err(format!("GPIO{}.IDR write (read-only)", self.name)),
            0x14 => self.odr = merge(self.odr, value, mask) & 0xFFFF,
            0x18 => {
                let v = value & mask;
                // Set wins over reset when both bits are written.
                self.odr = (self.odr & !(v >> 16)) | (v & 0xFFFF);
            }
            0x1C => {
                return Err(format!(
                    "GPIO{}.LCKR write (pin locking not modelled)",
                    self.name
                ))
            }
            0x20 => self.afr[0] = merge(self.afr[0], value, mask),
            0x24 => self.afr[1] = merge(self.afr[1], value, mask),
            _ => return Err(format!("GPIO{}+0x{off:02X}", self.name)),
        }
        Ok(matches!(off, 0x00 | 0x14 | 0x18 | 0x20 | 0x24))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// BSRR: set and reset halves, set winning (RM0390 §7.4.7); IDR of an
    /// input follows the pull and an external drive.
    #[test]
    fn bsrr_and_idr() {
        let mut p = Port::new('B');
        p.write(0x00, 1 << 24, 3 << 24).unwrap(); // PB12 output
        p.write(0x18, 1 << 12, !0).unwrap();
        assert!(p.level(12));
        p.write(0x18, (1 << 28) | (1 << 12), !0).unwrap();
        assert!(p.level(12), "set wins");
        p.write(0x18, 1 << 28, !0).unwrap();
        assert!(!p.level(12));
        p.write(0x0C, 1 << 26, 3 << 26).unwrap(); // PB13 pull-up input
        assert!(p.read(0x10).unwrap() & (1 << 13) != 0);
        p.drive(13, Some(false));
        assert!(p.read(0x10).unwrap() & (1 << 13) == 0);
    }
}
