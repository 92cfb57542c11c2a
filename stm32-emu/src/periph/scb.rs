//! SCB and the other System Control Space registers (ARMv7-M B3.2): CPUID,
//! ICSR (set/clear pending PendSV, SysTick, NMI), VTOR, AIRCR (VECTKEY,
//! PRIGROUP, SYSRESETREQ), SCR, CCR, SHPR1-3, SHCSR, the fault status
//! registers (CFSR, HFSR, MMFAR, BFAR), CPACR, FPCCR/FPCAR/FPDSCR, ICTR,
//! ACTLR and the debug DEMCR (TRCENA for the DWT).

use super::nvic::{exc, Nvic};
use super::{merge, Access};

/// The SCB registers the model keeps.
#[derive(Clone, Debug)]
pub struct Scb {
    /// Vector table offset.
    pub vtor: u32,
    scr: u32,
    ccr: u32,
    /// SHCSR enable bits (MEMFAULTENA 16, BUSFAULTENA 17, USGFAULTENA 18).
    pub shcsr: u32,
    /// Configurable fault status.
    pub cfsr: u32,
    /// HardFault status.
    pub hfsr: u32,
    /// Bus fault address.
    pub bfar: u32,
    mmfar: u32,
    cpacr: u32,
    fpccr: u32,
    fpcar: u32,
    fpdscr: u32,
    actlr: u32,
    /// DEMCR (TRCENA bit 24).
    pub demcr: u32,
    /// SYSRESETREQ written: the machine resets.
    pub reset_requested: bool,
}

impl Default for Scb {
    fn default() -> Self {
        Self {
            vtor: 0,
            scr: 0,
            ccr: 0x200,
            shcsr: 0,
            cfsr: 0,
            hfsr: 0,
            bfar: 0,
            mmfar: 0,
            cpacr: 0,
            fpccr: 0xC000_0000,
            fpcar: 0,
            fpdscr: 0,
            actlr: 0,
            demcr: 0,
            reset_requested: false,
        }
    }
}

impl Scb {
    /// Reads `off` from 0xE000_E000.
    pub fn read(&mut self, off: u32, nvic: &Nvic, vectactive: u32) -> Access<u32> {
        Ok(match off {
            0x004 => ((nvic.n_irq as u32).div_ceil(32)).saturating_sub(1), // ICTR
            0x008 => self.actlr,
            0xD00 => 0x410F_C241, // Cortex-M4 r0p1
            0xD04 => {
                let mut v = vectactive & 0x1FF;
                if let Some((e, _)) = nvic.highest_pending() {
                    v |= (e as u32) << 12;
                }
                if (16..16 + nvic.n_irq).any(|e| nvic.is_pending(e)) {
                    v |= 1 << 22;
                }
                if nvic.is_pending(exc::PENDSV) {
                    v |= 1 << 28;
                }
                if nvic.is_pending(exc::SYSTICK) {
                    v |= 1 << 26;
                }
                if nvic.is_pending(exc::NMI) {
                    v |= 1 << 31;
                }
                if nvic.active_count() <= 1 {
                    v |= 1 << 11; // RETTOBASE
                }
                v
            }
            0xD08 => self.vtor,
            0xD0C => 0xFA05_0000 | (nvic.prigroup << 8),
            0xD10 => self.scr,
            0xD14 => self.ccr,
            0xD18..=0xD20 => {
                let first = 4 + (off as usize - 0xD18);
                (0..4).fold(0, |a, k| a | ((nvic.prio(first + k) as u32) << (8 * k)))
            }
            0xD24 => {
                let mut v = self.shcsr & 0x7_0000;
                for (e, bit) in [
                    (exc::MEM_MANAGE, 0),
                    (exc::BUS_FAULT, 1),
                    (exc::USAGE_FAULT, 3),
                ] {
                    if nvic.is_active(e) {
                        v |= 1 << bit;
                    }
                }
                v
            }
            0xD28 => self.cfsr,
            0xD2C => self.hfsr,
            0xD30 => 0, // DFSR
            0xD34 => self.mmfar,
            0xD38 => self.bfar,
            0xD3C => 0, // AFSR
            0xD88 => self.cpacr,
            0xDFC => self.demcr,
            0xF34 => self.fpccr,
            0xF38 => self.fpcar,
            0xF3C => self.fpdscr,
            _ => return Err(format!("SCS+0x{off:03X}")),
        })
    }

    /// Writes `off` from 0xE000_E000.
    pub fn write(&mut self, off: u32, value: u32, mask: u32, nvic: &mut Nvic) -> Access<()> {
        let v = value & mask;
        match off {
            0x008 => self.actlr = merge(self.actlr, value, mask),
            0xD04 => {
                if v & (1 << 31) != 0 {
                    nvic.set_pending(exc::NMI);
                }
                if v & (1 << 28) != 0 {
                    nvic.set_pending(exc::PENDSV);
                }
                if v & (1 << 26) != 0 {
                    nvic.set_pending(exc::SYSTICK);
                }
                if v & (1 << 27) != 0 || v & (1 << 25) != 0 {
                    return Err("SCB.ICSR PENDSTCLR/PENDSVCLR: not modelled".into());
                }
            }
            0xD08 => self.vtor = merge(self.vtor, value, mask) & 0xFFFF_FF80,
            0xD0C => {
                if mask != 0xFFFF_FFFF || value >> 16 != 0x05FA {
                    return Err(format!(
                        "SCB.AIRCR = 0x{value:08X} without VECTKEY 0x05FA (ignored on the chip)"
                    ));
                }
                nvic.prigroup = (value >> 8) & 7;
                if value & (1 << 2) != 0 {
                    self.reset_requested = true;
                }
                if value & 3 != 0 {
                    return Err("SCB.AIRCR VECTRESET/VECTCLRACTIVE (debug only)".into());
                }
            }
            0xD10 => self.scr = merge(self.scr, value, mask),
            0xD14 => self.ccr = merge(self.ccr, value, mask),
            0xD18..=0xD20 => {
                let first = 4 + (off as usize - 0xD18);
                for k in 0..4 {
                    if mask & (0xFF << (8 * k)) != 0 {
                        nvic.set_prio(first + k, (value >> (8 * k)) as u8);
                    }
                }
            }
            0xD24 => self.shcsr = merge(self.shcsr, value, mask) & 0x7_0000,
            0xD28 => self.cfsr &= !v,
            0xD2C => self.hfsr &= !v,
            0xD34 => self.mmfar = merge(self.mmfar, value, mask),
            0xD38 => self.bfar = merge(self.bfar, value, mask),
            0xD88 => self.cpacr = merge(self.cpacr, value, mask),
            0xDFC => self.demcr = merge(self.demcr, value, mask),
            0xF34 => self.fpccr = merge(self.fpccr, value, mask),
            0xF38 => self.fpcar = merge(self.fpcar, value, mask),
            0xF3C => self.fpdscr = merge(self.fpdscr, value, mask),
            _ => return Err(format!("SCS+0x{off:03X}")),
        }
        Ok(())
    }

    /// SCR SEVONPEND.
    pub fn sevonpend(&self) -> bool {
        self.scr & (1 << 4) != 0
    }
}
