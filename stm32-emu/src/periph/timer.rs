//! TIM1 (advanced), TIM2-TIM5 (general purpose) (RM0390 §12-§13): an
//! up-counter on the timer kernel clock / (PSC+1), evaluated lazily from
//! the emulated time (no per-tick work): update (UIF) on overflow with the
//! preloads (PSC, ARR with ARPE, CCRx with OCxPE) applied there, CCxIF on
//! compare matches of output channels, UG/URS, rc_w0 status flags, MOE /
//! AOE / OSSI / break in BDTR, and encoder mode (SMS 1-3) whose CNT follows
//! a position supplied by the harness (the simulated wheel). Up-counting,
//! edge-aligned only; anything else fails the run.

use super::{merge, ps_to_ticks, ticks_to_ps, Access};

/// Which register set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// TIM1/TIM8: RCR, BDTR.
    Advanced,
    /// TIM2-TIM5.
    General,
}

/// What a channel's output pin is driven to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChannelOutput {
    /// Output disabled (CCxE = 0, or MOE = 0 with OSSI = 0): the pin is
    /// released (the board's pull decides).
    Released,
    /// A constant level.
    Level(bool),
    /// PWM: high for `high` of every `period` counts.
    Pwm {
        /// Counts high per period.
        high: u32,
        /// Counts per period (ARR + 1).
        period: u32,
    },
}

/// One timer.
#[derive(Clone, Debug)]
pub struct Timer {
    /// Name, e.g. "TIM5".
    pub name: &'static str,
    kind: Kind,
    cr1: u32,
    cr2: u32,
    smcr: u32,
    dier: u32,
    sr: u32,
    ccmr: [u32; 2],
    ccer: u32,
    psc: u32,
    psc_act: u32,
    arr: u32,
    arr_act: u32,
    rcr: u32,
    ccr: [u32; 4],
    ccr_act: [u32; 4],
    bdtr: u32,
    dcr: u32,
    or: u32,
    /// Counter value at `base_ps` (free-running mode).
    base_cnt: u128,
    base_ps: u128,
    /// Counter ticks since `base_ps` at the last evaluation.
    last_ticks: u128,
    /// Encoder mode: CNT at `enc_base_pos`.
    enc_base_cnt: u32,
    enc_base_pos: u16,
    /// Kernel clock \[Hz\].
    clk_hz: u64,
}

impl Timer {
    /// A timer at its reset values on a kernel clock of `clk_hz`.
    pub fn new(name: &'static str, kind: Kind, clk_hz: u64) -> Self {
        Self {
            name,
            kind,
            cr1: 0,
            cr2: 0,
            smcr: 0,
            dier: 0,
            sr: 0,
            ccmr: [0; 2],
            ccer: 0,
            psc: 0,
            psc_act: 0,
            arr: 0xFFFF,
            arr_act: 0xFFFF,
            rcr: 0,
            ccr: [0; 4],
            ccr_act: [0; 4],
            bdtr: 0,
            dcr: 0,
            or: 0,
            base_cnt: 0,
            base_ps: 0,
            last_ticks: 0,
            enc_base_cnt: 0,
            enc_base_pos: 0,
            clk_hz,
        }
    }

    fn cen(&self) -> bool {
        self.cr1 & 1 != 0
    }

    fn encoder(&self) -> bool {
        matches!(self.smcr & 7, 1..=3)
    }

    fn counting(&self) -> bool {
        self.cen() && !self.encoder()
    }

    fn period(&self) -> u128 {
        self.arr_act as u128 + 1
    }

    fn f_cnt(&self) -> u64 {
        self.clk_hz / (self.psc_act as u64 + 1)
    }

    fn output_channel(&self, ch: usize) -> bool {
        (self.ccmr[ch / 2] >> (8 * (ch % 2))) & 3 == 0
    }

    fn preload_ccr(&self, ch: usize) -> bool {
        (self.ccmr[ch / 2] >> (3 + 8 * (ch % 2))) & 1 != 0
    }

    /// Changes the kernel clock (RCC reprogrammed); the count so far is kept.
    pub fn set_clock(&mut self, now_ps: u128, clk_hz: u64) {
        if clk_hz != self.clk_hz {
            self.sync(now_ps);
            self.rebase(now_ps);
            self.clk_hz = clk_hz;
        }
    }

    fn rebase(&mut self, now_ps: u128) {
        self.base_cnt = (self.base_cnt + self.last_ticks) % self.period();
        self.base_ps = now_ps;
        self.last_ticks = 0;
    }

    /// The update event: preloads to the active registers, MOE from AOE.
    fn update_event(&mut self, now_ps: u128) {
        let changed = self.arr_act != self.arr || self.psc_act != self.psc;
        if changed {
            self.rebase(now_ps);
        }
        self.arr_act = self.arr;
        self.psc_act = self.psc;
        for ch in 0..4 {
            self.ccr_act[ch] = self.ccr[ch];
        }
        if self.kind == Kind::Advanced && self.bdtr & (1 << 14) != 0 {
            self.bdtr |= 1 << 15;
        }
    }

    /// Advances the counter to `now_ps`, setting the flags of what it passed.
    pub fn sync(&mut self, now_ps: u128) {
        if !self.counting() || now_ps < self.base_ps {
            return;
        }
        let ticks = ps_to_ticks(now_ps - self.base_ps, self.f_cnt());
        if ticks == self.last_ticks {
            return;
        }
        let p = self.period();
        let c0 = self.base_cnt + self.last_ticks;
        let c1 = self.base_cnt + ticks;
        self.last_ticks = ticks;
        for ch in 0..4 {
            let v = self.ccr_act[ch] as u128;
            if self.output_channel(ch) && v < p {
                // Values ≡ v (mod p) in (c0, c1].
                let n = |c: u128| if c >= v { (c - v) / p + 1 } else { 0 };
                if n(c1) > n(c0) {
                    self.sr |= 1 << (ch + 1);
                }
            }
        }
        if c1 / p > c0 / p && self.cr1 & 2 == 0 {
            self.sr |= 1;
            self.update_event(now_ps);
        }
    }

    /// When the next enabled interrupt flag sets \[ps\], if any.
    pub fn next_irq_ps(&self) -> Option<u128> {
        if !self.counting() {
            return None;
        }
        let p = self.period();
        let c = (self.base_cnt + self.last_ticks) % p;
        let mut best: Option<u128> = None;
        let mut consider = |d: u128| {
            let t = self.base_ps + ticks_to_ps(self.last_ticks + d, self.f_cnt());
            best = Some(best.map_or(t, |b: u128| b.min(t)));
        };
        if self.dier & 1 != 0 && self.sr & 1 == 0 {
            consider(p - c);
        }
        for ch in 0..4 {
            let bit = 1 << (ch + 1);
            let v = self.ccr_act[ch] as u128;
            if self.dier & bit != 0 && self.sr & bit == 0 && self.output_channel(ch) && v < p {
                let d = (v + p - c) % p;
                consider(if d == 0 { p } else { d });
            }
        }
        best
    }

    /// Interrupt lines: (update, capture/compare, break).
    pub fn irq_lines(&self) -> (bool, bool, bool) {
        let a = self.sr & self.dier;
        (a & 1 != 0, a & 0x1E != 0, a & (1 << 7) != 0)
    }

    fn counter(&self, enc_pos: u16) -> u32 {
        if self.encoder() {
            if !self.cen() {
                return self.enc_base_cnt;
            }
            let d = enc_pos.wrapping_sub(self.enc_base_pos);
            let d = if self.encoder_reversed() {
                d.wrapping_neg()
            } else {
                d
            };
            (self.enc_base_cnt as u16).wrapping_add(d) as u32
        } else {
            ((self.base_cnt + self.last_ticks) % self.period()) as u32
        }
    }

    /// Encoder mode counts down for a forward position when exactly one
    /// input is inverted (CC1P xor CC2P).
    fn encoder_reversed(&self) -> bool {
        ((self.ccer >> 1) ^ (self.ccer >> 5)) & 1 != 0
    }

    fn set_counter(&mut self, now_ps: u128, value: u32, enc_pos: u16) {
        if self.encoder() {
            self.enc_base_cnt = value & 0xFFFF;
            self.enc_base_pos = enc_pos;
        }
        self.base_cnt = value as u128 % self.period();
        self.base_ps = now_ps;
        self.last_ticks = 0;
    }

    /// Reads the register at `off`; `enc_pos` is the position an encoder
    /// input would count (the harness's wheel, raw 16-bit counts).
    pub fn read(&mut self, off: u32, now_ps: u128, enc_pos: u16) -> Access<u32> {
        self.sync(now_ps);
        let adv = self.kind == Kind::Advanced;
        Ok(match off {
            0x00 => self.cr1,
            0x04 => self.cr2,
            0x08 => self.smcr,
            0x0C => self.dier,
            0x10 => self.sr,
            0x14 => 0,
            0x18 => self.ccmr[0],
            0x1C => self.ccmr[1],
            0x20 => self.ccer,
            0x24 => self.counter(enc_pos),
            0x28 => self.psc,
            0x2C => self.arr,
            0x30 if adv => self.rcr,
            0x34..=0x40 => self.ccr[(off as usize - 0x34) / 4],
            0x44 if adv => self.bdtr,
            0x48 => self.dcr,
            0x50 if !adv => self.or,
            _ => return Err(self.reg_name(off)),
        })
    }

    fn reg_name(&self, off: u32) -> String {
        let n = match off {
            0x4C => "DMAR (DMA burst, not modelled)",
            0x30 => "RCR (advanced timers only)",
            0x44 => "BDTR (advanced timers only)",
            _ => "unknown register",
        };
        format!("{}+0x{off:02X} {n}", self.name)
    }

    /// Writes the register at `off`.
    pub fn write(
        &mut self,
        off: u32,
        value: u32,
        mask: u32,
        now_ps: u128,
        enc_pos: u16,
    ) -> Access<()> {
        self.sync(now_ps);
        let adv = self.kind == Kind::Advanced;
        match off {
            0x00 => {
                let new = merge(self.cr1, value, mask);
                if new & 1 != 0 && (new & (1 << 4) != 0 || (new >> 5) & 3 != 0) {
                    return Err(format!(
                        "{}.CR1 = 0x{new:X}: down/centre-aligned counting not modelled",
                        self.name
                    ));
                }
                let was = self.cen();
                let cnt = self.counter(enc_pos);
                self.cr1 = new;
                if was != self.cen() {
                    self.set_counter(now_ps, cnt, enc_pos);
                }
            }
            0x04 => self.cr2 = merge(self.cr2, value, mask),
            0x08 => {
                let cnt = self.counter(enc_pos);
                let new = merge(self.smcr, value, mask);
                if !matches!(new & 7, 0..=3) || new & 0xFFF0 & !0x00F0 != 0 {
                    return Err(format!(
                        "{}.SMCR = 0x{new:X}: slave/trigger modes other than encoder not modelled",
                        self.name
                    ));
                }
                self.smcr = new;
                self.set_counter(now_ps, cnt, enc_pos);
            }
            0x0C => self.dier = merge(self.dier, value, mask),
            0x10 => self.sr &= merge(self.sr, value, mask) | !0x1FFF,
            0x14 => {
                let v = value & mask;
                if v & 1 != 0 {
                    self.set_counter(now_ps, 0, enc_pos);
                    self.update_event(now_ps);
                    if self.cr1 & (1 << 2) == 0 {
                        self.sr |= 1;
                    }
                }
                self.sr |= v & 0x1E; // CCxG
                if v & (1 << 7) != 0 && adv {
                    self.break_event();
                }
            }
            0x18 => self.ccmr[0] = merge(self.ccmr[0], value, mask),
            0x1C => self.ccmr[1] = merge(self.ccmr[1], value, mask),
            0x20 => {
                let cnt = self.counter(enc_pos);
                self.ccer = merge(self.ccer, value, mask);
                if self.encoder() {
                    self.set_counter(now_ps, cnt, enc_pos);
                }
            }
            0x24 => {
                let v = merge(self.counter(enc_pos), value, mask);
                self.set_counter(now_ps, v, enc_pos);
            }
            0x28 => self.psc = merge(self.psc, value, mask) & 0xFFFF,
            0x2C => {
                self.arr = merge(self.arr, value, mask);
                if self.cr1 & (1 << 7) == 0 {
                    self.rebase(now_ps);
                    self.arr_act = self.arr;
                    self.base_cnt %= self.period();
                }
            }
            0x30 if adv => {
                self.rcr = merge(self.rcr, value, mask) & 0xFF;
                if self.rcr != 0 {
                    return Err(format!(
                        "{}.RCR = {}: repetition counter not modelled",
                        self.name, self.rcr
                    ));
                }
            }
            0x34..=0x40 => {
                let ch = (off as usize - 0x34) / 4;
                self.ccr[ch] = merge(self.ccr[ch], value, mask);
                if !self.preload_ccr(ch) {
                    self.ccr_act[ch] = self.ccr[ch];
                }
            }
            0x44 if adv => self.bdtr = merge(self.bdtr, value, mask),
            0x48 => self.dcr = merge(self.dcr, value, mask),
            0x50 if !adv => self.or = merge(self.or, value, mask),
            _ => return Err(self.reg_name(off)),
        }
        Ok(())
    }

    /// A break event (BRK input active with BKE, or BG): MOE cleared, BIF set.
    pub fn break_event(&mut self) {
        self.sr |= 1 << 7;
        self.bdtr &= !(1 << 15);
    }

    /// Main output enable (advanced timers; always true on the others).
    pub fn moe(&self) -> bool {
        self.kind != Kind::Advanced || self.bdtr & (1 << 15) != 0
    }

    /// What channel `ch` (0-3) drives its pin to (the main output OCx).
    pub fn output(&self, ch: usize, enc_pos: u16) -> Access<ChannelOutput> {
        Ok(match self.waveform(ch, false, enc_pos)? {
            Wave::Released => ChannelOutput::Released,
            Wave::Level(l) => ChannelOutput::Level(l),
            Wave::Pwm { from, to, period } => ChannelOutput::Pwm {
                high: to - from,
                period,
            },
        })
    }

    /// What channel `ch`'s main output OCx (`complementary` false) or its
    /// complementary output OCxN (true, advanced timers only) drives its
    /// pin to, with the phase of the high interval within the period
    /// (RM0090 Table 94, "Output control bits for complementary OCx and
    /// OCxN channels with break feature"): with MOE = 1 an enabled output
    /// is OCxREF xor its polarity (OCxN the complement of OCxREF when both
    /// are enabled; the dead time is not modelled), a disabled one is its
    /// off-state level CCxP / CCxNP when OSSR = 1 and the other output of
    /// the pair is enabled, else released; with MOE = 0 both take their
    /// idle levels OISx / OISxN when OSSI = 1 and either is enabled, else
    /// they are released.
    pub fn waveform(&self, ch: usize, complementary: bool, enc_pos: u16) -> Access<Wave> {
        if !self.output_channel(ch) || (complementary && self.kind != Kind::Advanced) {
            return Ok(Wave::Released);
        }
        let bits = self.ccer >> (4 * ch);
        let (e, p, ne, np) = (bits & 1 != 0, bits & 2 != 0, bits & 4 != 0, bits & 8 != 0);
        let (mine, pol, other) = if complementary {
            (ne, np, e)
        } else {
            (e, p, ne)
        };
        if !self.moe() {
            if (e || ne) && self.bdtr & (1 << 10) != 0 {
                let bit = 8 + 2 * ch + complementary as usize;
                return Ok(Wave::Level(self.cr2 & (1 << bit) != 0));
            }
            return Ok(Wave::Released);
        }
        if !mine {
            let ossr = self.bdtr & (1 << 11) != 0;
            return Ok(if ossr && other && self.kind == Kind::Advanced {
                Wave::Level(pol)
            } else {
                Wave::Released
            });
        }
        // OCxREF's high interval [from, to) of the period.
        let period = self.period() as u32;
        let ccr = self.ccr_act[ch].min(period);
        let ocm = (self.ccmr[ch / 2] >> (4 + 8 * (ch % 2))) & 7;
        let (from, to) = match ocm {
            0b110 => (0, ccr),
            0b111 => (ccr, period),
            0b100 => (0, 0),
            0b101 => (0, period),
            _ => {
                return Err(format!(
                    "{} channel {} output mode {ocm:03b}: not modelled",
                    self.name,
                    ch + 1
                ))
            }
        };
        // Complemented when OCxN runs beside OCx, inverted by the polarity.
        let invert = pol ^ (complementary && e);
        if !self.cen() {
            // Stopped counter: OCxREF frozen at its value for CNT.
            let cnt = self.counter(enc_pos);
            return Ok(Wave::Level(((from..to).contains(&cnt)) != invert));
        }
        let (from, to) = if invert {
            if from == 0 {
                (to, period)
            } else {
                (0, from)
            }
        } else {
            (from, to)
        };
        Ok(if from >= to {
            Wave::Level(false)
        } else if to - from == period {
            Wave::Level(true)
        } else {
            Wave::Pwm { from, to, period }
        })
    }
}

/// A timer output's waveform with its phase: high during \[`from`, `to`)
/// of every `period` counts (edge-aligned up-counting: the counter's
/// position in the period).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wave {
    /// Not driven by the timer (the board's pull decides).
    Released,
    /// A constant level.
    Level(bool),
    /// PWM.
    Pwm {
        /// First count of the high interval.
        from: u32,
        /// One past its last count.
        to: u32,
        /// Counts per period (ARR + 1).
        period: u32,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u128 = 1_000_000_000;

    /// embassy's TIM5 time driver setup: 84 MHz / 84 = 1 MHz, ARR 0xFFFF,
    /// UG with URS (no UIF), CC1 at 0x8000: CC1IF at 32.768 ms, UIF at
    /// 65.536 ms, CNT in µs; rc_w0 clearing.
    #[test]
    fn time_driver_counter_and_flags() {
        let mut t = Timer::new("TIM5", Kind::General, 84_000_000);
        t.write(0x28, 83, !0, 0, 0).unwrap();
        t.write(0x00, 1 << 2, !0, 0, 0).unwrap();
        t.write(0x14, 1, !0, 0, 0).unwrap();
        assert_eq!(t.read(0x10, 0, 0).unwrap() & 1, 0, "URS: no UIF from UG");
        t.write(0x34, 0x8000, !0, 0, 0).unwrap();
        t.write(0x0C, 0b11, !0, 0, 0).unwrap();
        t.write(0x00, 1, !0, 0, 0).unwrap();
        assert_eq!(t.next_irq_ps(), Some(32_768 * MS / 1000));
        assert_eq!(t.read(0x24, 10 * MS, 0).unwrap(), 10_000);
        assert_eq!(t.read(0x10, 32 * MS, 0).unwrap() & 3, 0);
        assert_eq!(t.read(0x10, 33 * MS, 0).unwrap() & 3, 2);
        assert!(t.irq_lines().1);
        t.write(0x10, !2, !0, 33 * MS, 0).unwrap();
        assert_eq!(t.next_irq_ps(), Some(65_536 * MS / 1000));
        assert_eq!(t.read(0x10, 66 * MS, 0).unwrap() & 1, 1);
        assert_eq!(t.read(0x24, 66 * MS, 0).unwrap(), 66_000 - 65_536);
    }

    /// TIM1 PWM: 168 MHz, ARR 8399 (20 kHz), CCR1 preloaded: the new duty
    /// reaches the output at the next update (50 µs), MOE = 0 with OSSI
    /// drives the idle level.
    #[test]
    fn pwm_preload_and_moe() {
        let mut t = Timer::new("TIM1", Kind::Advanced, 168_000_000);
        t.write(0x2C, 8399, !0, 0, 0).unwrap();
        t.write(0x18, (0b110 << 4) | (1 << 3), !0, 0, 0).unwrap();
        t.write(0x20, 1, !0, 0, 0).unwrap();
        t.write(0x44, (1 << 15) | (1 << 10), !0, 0, 0).unwrap();
        t.write(0x14, 1, !0, 0, 0).unwrap();
        t.write(0x00, 1 | (1 << 7), !0, 0, 0).unwrap();
        t.write(0x34, 4200, !0, 1000, 0).unwrap();
        assert_eq!(t.output(0, 0).unwrap(), ChannelOutput::Level(false));
        t.sync(50_001_000);
        assert_eq!(
            t.output(0, 0).unwrap(),
            ChannelOutput::Pwm {
                high: 4200,
                period: 8400
            }
        );
        t.write(0x44, 1 << 10, !0, 60_000_000, 0).unwrap();
        assert_eq!(t.output(0, 0).unwrap(), ChannelOutput::Level(false));
    }

    /// Encoder mode: CNT follows the position from where it was enabled,
    /// wrapping at 16 bits, reversed by one inverted input.
    #[test]
    fn encoder_mode() {
        let mut t = Timer::new("TIM3", Kind::General, 84_000_000);
        t.write(0x18, 0x0101, !0, 0, 100).unwrap();
        t.write(0x08, 3, !0, 0, 100).unwrap();
        t.write(0x00, 1, !0, 0, 100).unwrap();
        assert_eq!(t.read(0x24, 0, 100).unwrap(), 0);
        assert_eq!(t.read(0x24, 0, 90).unwrap(), 0xFFF6);
        t.write(0x20, 1 << 1, !0, 0, 90).unwrap();
        assert_eq!(t.read(0x24, 0, 80).unwrap(), 0);
    }
}
