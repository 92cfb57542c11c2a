//! RCC (RM0390 §6 / RM0383 §6): clock enables and resets stored, the
//! oscillator and PLL ready bits following their enables at once, SWS
//! following SW (when the selected source is ready), the reset flags in
//! CSR (kept across resets, cleared by RMVF), and the clock tree computed
//! from the registers (SYSCLK, AHB, APB1/APB2 and their timer clocks).

use super::{merge, Access};

/// HSI frequency \[Hz\].
pub const HSI_HZ: u64 = 16_000_000;

/// CSR reset flags (bit numbers).
pub mod csr {
    /// LSI on.
    pub const LSION: u32 = 1 << 0;
    /// LSI ready.
    pub const LSIRDY: u32 = 1 << 1;
    /// Remove reset flags.
    pub const RMVF: u32 = 1 << 24;
    /// Brown-out reset.
    pub const BORRSTF: u32 = 1 << 25;
    /// NRST pin reset (set by every internal reset too).
    pub const PINRSTF: u32 = 1 << 26;
    /// Power-on reset.
    pub const PORRSTF: u32 = 1 << 27;
    /// Software reset (AIRCR SYSRESETREQ).
    pub const SFTRSTF: u32 = 1 << 28;
    /// Independent watchdog reset.
    pub const IWDGRSTF: u32 = 1 << 29;
    /// Window watchdog reset.
    pub const WWDGRSTF: u32 = 1 << 30;
    /// Low-power reset.
    pub const LPWRRSTF: u32 = 1 << 31;
}

/// Which reset the chip comes out of.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResetCause {
    /// Power on (PORRSTF, BORRSTF, PINRSTF).
    PowerOn,
    /// Independent watchdog (IWDGRSTF, PINRSTF).
    Iwdg,
    /// AIRCR SYSRESETREQ (SFTRSTF, PINRSTF).
    Software,
}

/// Registers by offset: (offset, name, reset value).
const REGS: &[(u32, &str, u32)] = &[
    (0x00, "CR", 0x0000_0083),
    (0x04, "PLLCFGR", 0x2400_3010),
    (0x08, "CFGR", 0),
    (0x0C, "CIR", 0),
    (0x10, "AHB1RSTR", 0),
    (0x14, "AHB2RSTR", 0),
    (0x18, "AHB3RSTR", 0),
    (0x20, "APB1RSTR", 0),
    (0x24, "APB2RSTR", 0),
    (0x30, "AHB1ENR", 0x0010_0000),
    (0x34, "AHB2ENR", 0),
    (0x38, "AHB3ENR", 0),
    (0x40, "APB1ENR", 0),
    (0x44, "APB2ENR", 0),
    (0x50, "AHB1LPENR", 0x7E67_91FF),
    (0x54, "AHB2LPENR", 0x0000_00F1),
    (0x58, "AHB3LPENR", 0x0000_0003),
    (0x60, "APB1LPENR", 0x3FFF_CDFF),
    (0x64, "APB2LPENR", 0x00CF_7F33),
    (0x70, "BDCR", 0),
    (0x74, "CSR", 0x0E00_0000),
    (0x80, "SSCGR", 0),
    (0x84, "PLLI2SCFGR", 0x2400_3010),
    (0x88, "PLLSAICFGR", 0x2400_3010),
    (0x8C, "DCKCFGR", 0),
    (0x90, "CKGATENR", 0),
    (0x94, "DCKCFGR2", 0),
];

/// The RCC.
#[derive(Clone, Debug)]
pub struct Rcc {
    regs: [u32; 0x98 / 4],
    /// HSE frequency when it runs \[Hz\] (the board's crystal or MCO);
    /// `None`: no HSE on the board (HSERDY never sets).
    pub hse_hz: Option<u64>,
}

/// The clock tree as configured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Clocks {
    /// Core clock \[Hz\].
    pub sysclk_hz: u64,
    /// AHB \[Hz\].
    pub hclk_hz: u64,
    /// APB1 \[Hz\].
    pub pclk1_hz: u64,
    /// APB2 \[Hz\].
    pub pclk2_hz: u64,
    /// APB1 timers \[Hz\].
    pub timclk_apb1_hz: u64,
    /// APB2 timers \[Hz\].
    pub timclk_apb2_hz: u64,
}

impl Rcc {
    /// Out of a power-on reset.
    pub fn new(hse_hz: Option<u64>) -> Self {
        let mut regs = [0u32; 0x98 / 4];
        for &(off, _, v) in REGS {
            regs[off as usize / 4] = v;
        }
        Self { regs, hse_hz }
    }

    /// The state after a system reset of `cause` (the reset flags of
    /// earlier resets stay until RMVF).
    pub fn reset(&mut self, cause: ResetCause) {
        let flags = self.regs[0x74 / 4] & 0xFF00_0000;
        *self = Self::new(self.hse_hz);
        let new = match cause {
            ResetCause::PowerOn => csr::PORRSTF | csr::BORRSTF | csr::PINRSTF,
            ResetCause::Iwdg => flags | csr::IWDGRSTF | csr::PINRSTF,
            ResetCause::Software => flags | csr::SFTRSTF | csr::PINRSTF,
        };
        self.regs[0x74 / 4] = new;
    }

    fn name(off: u32) -> Option<&'static str> {
        REGS.iter().find(|r| r.0 == off).map(|r| r.1)
    }

    /// CSR as the firmware reads it.
    pub fn csr(&self) -> u32 {
        self.regs[0x74 / 4]
    }

    /// A register's value (0 for unknown offsets).
    pub fn reg(&self, off: u32) -> u32 {
        self.regs.get(off as usize / 4).copied().unwrap_or(0)
    }

    /// Reads the register at `off` (word aligned).
    pub fn read(&mut self, off: u32) -> Access<u32> {
        Self::name(off).ok_or_else(|| format!("RCC+0x{off:02X}"))?;
        Ok(self.regs[off as usize / 4])
    }

    /// Writes the register at `off`; returns true when the clock tree may
    /// have changed.
    pub fn write(&mut self, off: u32, value: u32, mask: u32) -> Access<bool> {
        let name = Self::name(off).ok_or_else(|| format!("RCC+0x{off:02X}"))?;
        let i = off as usize / 4;
        let v = merge(self.regs[i], value, mask);
        match name {
            "CR" => {
                // Ready bits (HSIRDY 1, HSERDY 17, PLLRDY 25, PLLI2SRDY 27,
                // PLLSAIRDY 29) follow their ON bits at once; HSERDY only
                // with an HSE on the board.
                let mut r = v & !((1 << 1) | (1 << 17) | (1 << 25) | (1 << 27) | (1 << 29));
                if v & 1 != 0 {
                    r |= 1 << 1;
                }
                if v & (1 << 16) != 0 && self.hse_hz.is_some() {
                    r |= 1 << 17;
                }
                for on in [24, 26, 28] {
                    if v & (1 << on) != 0 {
                        r |= 1 << (on + 1);
                    }
                }
                self.regs[i] = r;
                // SWS follows SW once its source runs.
                self.update_sws();
            }
            "CFGR" => {
                self.regs[i] = (v & !0xC) | (self.regs[i] & 0xC);
                self.update_sws();
            }
            "CSR" => {
                let mut r = (v & 0x0100_0001) | (self.regs[i] & 0xFE00_0000);
                if r & csr::RMVF != 0 {
                    r &= !0xFE00_0000;
                }
                r &= !csr::RMVF;
                if r & csr::LSION != 0 {
                    r |= csr::LSIRDY;
                }
                self.regs[i] = r;
            }
            "BDCR" => {
                // LSERDY (1) follows LSEON (0): no LSE used; store only.
                self.regs[i] = v;
            }
            _ => self.regs[i] = v,
        }
        Ok(matches!(name, "CR" | "CFGR" | "PLLCFGR" | "DCKCFGR"))
    }

    fn update_sws(&mut self) {
        let cr = self.regs[0];
        let cfgr = &mut self.regs[2];
        let sw = *cfgr & 3;
        let ready = match sw {
            0 => cr & (1 << 1) != 0,
            1 => cr & (1 << 17) != 0,
            2 | 3 => cr & (1 << 25) != 0,
            _ => false,
        };
        if ready {
            *cfgr = (*cfgr & !0xC) | (sw << 2);
        }
    }

    /// PLL48CLK, the USB clock \[Hz\]: the main PLL's Q output (its
    /// source × PLLN / PLLM / PLLQ), 0 while the PLL is off or Q < 2.
    pub fn pll48_hz(&self) -> u64 {
        let cr = self.regs[0];
        let pll = self.regs[1];
        let src = if pll & (1 << 22) != 0 {
            self.hse_hz.unwrap_or(0)
        } else {
            HSI_HZ
        };
        let m = (pll & 0x3F) as u64;
        let n = ((pll >> 6) & 0x1FF) as u64;
        let q = ((pll >> 24) & 0xF) as u64;
        if cr & (1 << 25) == 0 || m < 2 || q < 2 {
            return 0;
        }
        src * n / m / q
    }

    /// True when the peripheral clock enable `bit` of the enable register
    /// at `off` (0x30 AHB1ENR, 0x34 AHB2ENR, 0x40 APB1ENR, 0x44 APB2ENR) is set.
    pub fn enabled(&self, off: u32, bit: u32) -> bool {
        self.regs[off as usize / 4] & (1 << bit) != 0
    }

    /// The clock tree from the registers; an error names a setting the
    /// model does not cover.
    pub fn clocks(&self) -> Access<Clocks> {
        let cr = self.regs[0];
        let pll = self.regs[1];
        let cfgr = self.regs[2];
        let hse = self.hse_hz.unwrap_or(0);
        let sysclk = match (cfgr >> 2) & 3 {
            0 => HSI_HZ,
            1 => hse,
            2 => {
                let src = if pll & (1 << 22) != 0 { hse } else { HSI_HZ };
                let m = (pll & 0x3F) as u64;
                let n = ((pll >> 6) & 0x1FF) as u64;
                let p = (((pll >> 16) & 3) as u64 + 1) * 2;
                if m < 2 || n < 50 {
                    return Err(format!("RCC PLLCFGR 0x{pll:08X}: invalid PLLM/PLLN"));
                }
                if cr & (1 << 25) == 0 {
                    return Err("RCC: SYSCLK from a PLL that is off".into());
                }
                src * n / m / p
            }
            _ => return Err("RCC CFGR SWS = PLLR: not modelled".into()),
        };
        if sysclk == 0 {
            return Err("RCC: SYSCLK from a stopped HSE".into());
        }
        let hpre = match (cfgr >> 4) & 0xF {
            h if h < 8 => 1,
            8 => 2,
            9 => 4,
            10 => 8,
            11 => 16,
            12 => 64,
            13 => 128,
            14 => 256,
            _ => 512,
        };
        let ppre = |b: u32| match b & 7 {
            p if p < 4 => 1,
            4 => 2,
            5 => 4,
            6 => 8,
            _ => 16,
        };
        let (p1, p2) = (ppre(cfgr >> 10), ppre(cfgr >> 13));
        if self.regs[0x8C / 4] & (1 << 24) != 0 {
            return Err("RCC DCKCFGR TIMPRE = 1: not modelled".into());
        }
        let hclk = sysclk / hpre;
        let (pclk1, pclk2) = (hclk / p1, hclk / p2);
        Ok(Clocks {
            sysclk_hz: sysclk,
            hclk_hz: hclk,
            pclk1_hz: pclk1,
            pclk2_hz: pclk2,
            timclk_apb1_hz: if p1 == 1 { pclk1 } else { 2 * pclk1 },
            timclk_apb2_hz: if p2 == 1 { pclk2 } else { 2 * pclk2 },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The F446 board's tree (board.rs: 8 MHz /4 ×168 /2, APB1 /4, APB2 /2):
    /// 168 MHz SYSCLK, 42/84 MHz APB, 84/168 MHz timers (RM0390 fig. 13).
    #[test]
    fn f446_clock_tree() {
        let mut r = Rcc::new(Some(8_000_000));
        // PLLSRC HSE, M 4, N 168, P /2 (00), Q 7.
        let pll = (7 << 24) | (1 << 22) | (168 << 6) | 4;
        r.write(0x04, pll, !0).unwrap();
        r.write(0x00, (1 << 16) | (1 << 24) | 0x83, !0).unwrap();
        assert_eq!(r.read(0).unwrap() & (1 << 25 | 1 << 17), 1 << 25 | 1 << 17);
        r.write(0x08, (5 << 10) | (4 << 13) | 2, !0).unwrap();
        assert_eq!((r.read(0x08).unwrap() >> 2) & 3, 2, "SWS follows SW");
        let c = r.clocks().unwrap();
        assert_eq!(c.sysclk_hz, 168_000_000);
        assert_eq!((c.pclk1_hz, c.pclk2_hz), (42_000_000, 84_000_000));
        assert_eq!(
            (c.timclk_apb1_hz, c.timclk_apb2_hz),
            (84_000_000, 168_000_000)
        );
    }

    /// Without an HSE, SW = HSE never switches (SWS stays HSI), and the
    /// reset flags accumulate across resets until RMVF.
    #[test]
    fn no_hse_and_reset_flags() {
        let mut r = Rcc::new(None);
        r.write(0x00, (1 << 16) | 0x83, !0).unwrap();
        assert_eq!(r.read(0).unwrap() & (1 << 17), 0);
        r.write(0x08, 1, !0).unwrap();
        assert_eq!((r.read(0x08).unwrap() >> 2) & 3, 0);
        r.reset(ResetCause::Iwdg);
        assert_ne!(r.csr() & csr::IWDGRSTF, 0);
        assert_ne!(r.csr() & csr::PORRSTF, 0, "earlier flags kept");
        r.write(0x74, csr::RMVF, !0).unwrap();
        assert_eq!(r.csr() & 0xFF00_0000, 0);
        assert!(r.read(0x1C).is_err(), "a hole in the map is unmodelled");
    }
}
