//! The one hardware-dependent piece: a free-running counter.
//!
//! * [`SysTickCounter`] (default): SysTick clocked by the core clock. Under
//!   QEMU with `-icount shift=5` (bench-m4/run.sh) virtual time advances
//!   32 ns per guest instruction and `mps2-an386` clocks SysTick at 25 MHz,
//!   so one tick is 1.25 instructions: deterministic, and fine enough for a
//!   maximum against a budget (with `shift=0` a tick was 40 instructions,
//!   and a maximum read 2,996 that was 3,007-3,012: D215). The benchmark
//!   calibrates the ratio with a loop of known length ([`calibrate`]).
//! * [`DwtCounter`] (feature `dwt`): DWT CYCCNT, 32-bit core cycles. It reads
//!   0 under QEMU; on a real Cortex-M4F/M7F board it gives cycles (flash wait
//!   states and pipeline stalls included), with a resolution of one cycle.
//!
//! A board port only needs another implementation of [`Counter`].

use cortex_m::peripheral::syst::SystClkSource;

/// A free-running hardware counter.
pub trait Counter {
    /// What one count is ("SysTick ticks", "cycles").
    const UNIT: &'static str;
    /// Current raw value.
    fn now(&self) -> u32;
    /// Counts from `start` to `end`, across at most one wrap.
    fn elapsed(&self, start: u32, end: u32) -> u32;
}

/// SysTick as a 24-bit down-counter at the core clock.
pub struct SysTickCounter;

impl SysTickCounter {
    /// Starts SysTick free-running over its full 24-bit range, no interrupt.
    pub fn start(mut syst: cortex_m::peripheral::SYST) -> Self {
        syst.disable_interrupt();
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(0x00FF_FFFF);
        syst.clear_current();
        syst.enable_counter();
        Self
    }
}

impl Counter for SysTickCounter {
    const UNIT: &'static str = "SysTick ticks";
    #[inline(always)]
    fn now(&self) -> u32 {
        cortex_m::peripheral::SYST::get_current()
    }
    #[inline(always)]
    fn elapsed(&self, start: u32, end: u32) -> u32 {
        start.wrapping_sub(end) & 0x00FF_FFFF
    }
}

/// DWT CYCCNT: a 32-bit up-counter of core cycles (real hardware only).
pub struct DwtCounter;

impl DwtCounter {
    /// Enables trace and the cycle counter.
    #[allow(dead_code)]
    pub fn start(mut dcb: cortex_m::peripheral::DCB, mut dwt: cortex_m::peripheral::DWT) -> Self {
        dcb.enable_trace();
        dwt.enable_cycle_counter();
        Self
    }
}

impl Counter for DwtCounter {
    const UNIT: &'static str = "cycles";
    #[inline(always)]
    fn now(&self) -> u32 {
        cortex_m::peripheral::DWT::cycle_count()
    }
    #[inline(always)]
    fn elapsed(&self, start: u32, end: u32) -> u32 {
        end.wrapping_sub(start)
    }
}

/// Runs `n` iterations of a two-instruction loop (`subs`, `bne`) and returns
/// the counts it took: 2n instructions, so instructions per count =
/// 2n / result (about 40 for SysTick under QEMU -icount).
#[inline(never)]
pub fn calibrate<C: Counter>(c: &C, n: u32) -> u32 {
    let t0 = c.now();
    // SAFETY: a register-only countdown loop; no memory, no stack.
    unsafe {
        core::arch::asm!(
            "2:",
            "subs {0}, {0}, #1",
            "bne 2b",
            inout(reg) n => _,
            options(nomem, nostack),
        );
    }
    let t1 = c.now();
    c.elapsed(t0, t1)
}
