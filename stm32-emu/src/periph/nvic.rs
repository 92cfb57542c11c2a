//! NVIC (ARMv7-M B3.4) and the exception state: enables, pending and
//! active bits of every exception, priorities (4 implemented bits, as on
//! the STM32F4: the low nibble reads as zero), PRIGROUP grouping, the
//! execution priority from the active exceptions, BASEPRI, PRIMASK and
//! FAULTMASK, and the choice of the exception that preempts. Device
//! interrupts are level-sensitive: an asserted line pends its interrupt
//! again after the handler returns.

use super::{merge, Access};

/// Exception numbers.
pub mod exc {
    /// NMI.
    pub const NMI: usize = 2;
    /// HardFault.
    pub const HARD_FAULT: usize = 3;
    /// MemManage.
    pub const MEM_MANAGE: usize = 4;
    /// BusFault.
    pub const BUS_FAULT: usize = 5;
    /// UsageFault.
    pub const USAGE_FAULT: usize = 6;
    /// SVCall.
    pub const SVCALL: usize = 11;
    /// PendSV.
    pub const PENDSV: usize = 14;
    /// SysTick.
    pub const SYSTICK: usize = 15;
    /// First device interrupt (IRQ 0).
    pub const IRQ0: usize = 16;
}

/// Device interrupts modelled (IRQ 0..N).
pub const N_IRQ: usize = 128;
const N_EXC: usize = 16 + N_IRQ;

/// The exception state and the NVIC registers.
#[derive(Clone, Debug)]
pub struct Nvic {
    enabled: [bool; N_IRQ],
    /// Pending, by exception number.
    pending: [bool; N_EXC],
    /// Active, by exception number.
    active: [bool; N_EXC],
    /// Priority bytes, by exception number (4..15 from SHPR, 16.. from IPR).
    prio: [u8; N_EXC],
    /// AIRCR PRIGROUP.
    pub prigroup: u32,
    /// Implemented device interrupts (IRQ numbers below this).
    pub n_irq: usize,
}

impl Nvic {
    /// At reset, with `n_irq` device interrupts (97 on the F446, 86 on the F411).
    pub fn new(n_irq: usize) -> Self {
        Self {
            enabled: [false; N_IRQ],
            pending: [false; N_EXC],
            active: [false; N_EXC],
            prio: [0; N_EXC],
            prigroup: 0,
            n_irq: n_irq.min(N_IRQ),
        }
    }

    /// The group priority of exception `e` (fixed negative ones for
    /// reset, NMI and HardFault).
    pub fn group_prio(&self, e: usize) -> i32 {
        match e {
            1 => -3,
            exc::NMI => -2,
            exc::HARD_FAULT => -1,
            _ => self.group_of(self.prio[e]),
        }
    }

    fn group_of(&self, p: u8) -> i32 {
        let sub_bits = self.prigroup + 1;
        ((p as u32 >> sub_bits) << sub_bits) as i32
    }

    /// Pends exception `e`.
    pub fn set_pending(&mut self, e: usize) {
        self.pending[e] = true;
    }

    /// Is `e` pending.
    pub fn is_pending(&self, e: usize) -> bool {
        self.pending[e]
    }

    /// Is `e` active.
    pub fn is_active(&self, e: usize) -> bool {
        self.active[e]
    }

    /// A device interrupt line's level: asserted pends the interrupt
    /// unless it is active (it pends again when the handler returns and
    /// the line is still asserted).
    pub fn set_line(&mut self, irq: usize, level: bool) {
        let e = exc::IRQ0 + irq;
        if level && !self.active[e] {
            self.pending[e] = true;
        }
    }

    /// Is device interrupt `irq` enabled.
    pub fn irq_enabled(&self, irq: usize) -> bool {
        self.enabled[irq]
    }

    /// The execution priority: the active exceptions, BASEPRI, PRIMASK,
    /// FAULTMASK (ARMv7-M B1.5.4); 256 in thread mode with nothing masked.
    pub fn exec_priority(&self, primask: bool, basepri: u8, faultmask: bool) -> i32 {
        let mut p = 256;
        for e in 1..N_EXC {
            if self.active[e] {
                p = p.min(self.group_prio(e));
            }
        }
        if basepri & 0xF0 != 0 {
            p = p.min(self.group_of(basepri & 0xF0));
        }
        if primask {
            p = p.min(0);
        }
        if faultmask {
            p = p.min(-1);
        }
        p
    }

    /// The pending exception of highest priority (lowest number on a tie)
    /// that is enabled, with its group priority.
    pub fn highest_pending(&self) -> Option<(usize, i32)> {
        let mut best: Option<(usize, i32)> = None;
        for e in 1..16 + self.n_irq {
            if !self.pending[e] || (e >= exc::IRQ0 && !self.enabled[e - exc::IRQ0]) {
                continue;
            }
            let p = self.group_prio(e);
            if best.is_none_or(|(_, bp)| p < bp) {
                best = Some((e, p));
            }
        }
        best
    }

    /// The exception that preempts now, if any.
    pub fn to_take(&self, primask: bool, basepri: u8, faultmask: bool) -> Option<usize> {
        let (e, p) = self.highest_pending()?;
        (p < self.exec_priority(primask, basepri, faultmask)).then_some(e)
    }

    /// Exception entry: pending to active.
    pub fn activate(&mut self, e: usize) {
        self.pending[e] = false;
        self.active[e] = true;
    }

    /// Exception return of `e`.
    pub fn deactivate(&mut self, e: usize) -> Access<()> {
        if !self.active[e] {
            return Err(format!("exception return from {e}, which is not active"));
        }
        self.active[e] = false;
        Ok(())
    }

    /// Active exceptions, for ICSR/SHCSR: (number of active ones, RETTOBASE).
    pub fn active_count(&self) -> usize {
        self.active.iter().filter(|a| **a).count()
    }

    /// Sets the priority byte of exception `e` (implemented bits only).
    pub fn set_prio(&mut self, e: usize, p: u8) {
        self.prio[e] = p & 0xF0;
    }

    /// The priority byte of exception `e`.
    pub fn prio(&self, e: usize) -> u8 {
        self.prio[e]
    }

    /// Reads NVIC registers, `off` from 0xE000_E000.
    pub fn read(&mut self, off: u32) -> Access<u32> {
        let word = |f: &dyn Fn(usize) -> bool, n: usize| -> u32 {
            (0..32)
                .filter(|b| 32 * n + b < self.n_irq && f(32 * n + b))
                .fold(0, |a, b| a | (1 << b))
        };
        Ok(match off {
            0x100..=0x11C => word(&|i| self.enabled[i], (off as usize - 0x100) / 4),
            0x180..=0x19C => word(&|i| self.enabled[i], (off as usize - 0x180) / 4),
            0x200..=0x21C => word(&|i| self.pending[16 + i], (off as usize - 0x200) / 4),
            0x280..=0x29C => word(&|i| self.pending[16 + i], (off as usize - 0x280) / 4),
            0x300..=0x31C => word(&|i| self.active[16 + i], (off as usize - 0x300) / 4),
            0x400..=0x4EC => {
                let i = (off as usize - 0x400) & !3;
                (0..4).fold(0, |a, k| {
                    let irq = i + k;
                    let p = if irq < N_IRQ { self.prio[16 + irq] } else { 0 };
                    a | ((p as u32) << (8 * k))
                })
            }
            _ => return Err(format!("NVIC+0x{off:03X}")),
        })
    }

    /// Writes NVIC registers.
    pub fn write(&mut self, off: u32, value: u32, mask: u32) -> Access<()> {
        let v = value & mask;
        let bits = |n: usize| {
            (0..32)
                .filter(move |b| v & (1 << b) != 0)
                .map(move |b| 32 * n + b)
        };
        match off {
            0x100..=0x11C => {
                for i in bits((off as usize - 0x100) / 4).filter(|&i| i < self.n_irq) {
                    self.enabled[i] = true;
                }
            }
            0x180..=0x19C => {
                for i in bits((off as usize - 0x180) / 4).filter(|&i| i < self.n_irq) {
                    self.enabled[i] = false;
                }
            }
            0x200..=0x21C => {
                for i in bits((off as usize - 0x200) / 4).filter(|&i| i < self.n_irq) {
                    self.pending[16 + i] = true;
                }
            }
            0x280..=0x29C => {
                for i in bits((off as usize - 0x280) / 4).filter(|&i| i < self.n_irq) {
                    self.pending[16 + i] = false;
                }
            }
            0x400..=0x4EC => {
                let i = (off as usize - 0x400) & !3;
                let old = self.read(off & !3)?;
                let new = merge(old, value, mask);
                for k in 0..4 {
                    if i + k < N_IRQ {
                        self.set_prio(16 + i + k, (new >> (8 * k)) as u8);
                    }
                }
            }
            0xF00 => {
                let i = (v & 0x1FF) as usize;
                if i < self.n_irq {
                    self.pending[16 + i] = true;
                }
            }
            _ => return Err(format!("NVIC+0x{off:03X}")),
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Priorities: a lower value preempts; BASEPRI masks at and below its
    /// level, PRIMASK everything configurable; an active handler blocks
    /// its own and lower levels; disabled interrupts never preempt.
    #[test]
    fn preemption_rules() {
        let mut n = Nvic::new(97);
        n.write(0x400 + 48, 0x20 << 16, 0xFF << 16).unwrap(); // IRQ 50 prio 0x20
        n.write(0x400 + 36, 0x40 << 16, 0xFF << 16).unwrap(); // IRQ 38 prio 0x40
        assert_eq!(n.read(0x400 + 48).unwrap() >> 16 & 0xFF, 0x20);
        n.set_line(50, true);
        assert_eq!(n.to_take(false, 0, false), None, "disabled");
        n.write(0x104, (1 << 18) | (1 << 6), !0).unwrap(); // enable 50, 38
        assert_eq!(n.to_take(false, 0, false), Some(16 + 50));
        assert_eq!(n.to_take(true, 0, false), None, "PRIMASK");
        assert_eq!(n.to_take(false, 0x20, false), None, "BASEPRI at its level");
        assert_eq!(n.to_take(false, 0x30, false), Some(16 + 50));
        n.activate(16 + 50);
        n.set_line(38, true);
        assert_eq!(
            n.to_take(false, 0, false),
            None,
            "0x40 does not preempt 0x20"
        );
        n.deactivate(16 + 50).unwrap();
        assert_eq!(n.to_take(false, 0, false), Some(16 + 38));
        n.set_pending(exc::HARD_FAULT);
        assert_eq!(n.to_take(true, 0, false), Some(exc::HARD_FAULT));
    }
}
