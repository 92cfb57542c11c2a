//! embassy-time driver: SysTick is the time base, the CMSDK APB Timer0 the
//! alarm.
//!
//! * SysTick runs on the 25 MHz CPU clock (`CLKSOURCE` = processor clock)
//!   with a 1 ms reload; its handler counts the wraps. Now is wraps · 1000 µs
//!   plus the counts of the current period / 25. Under QEMU's
//!   `-icount shift=0` one guest instruction is one virtual ns, so a
//!   SysTick count is 40 instructions: [`instructions`] is the board's
//!   `cycles()` counter (resolution 40).
//! * Alarms: the timer queue (embassy-time-queue-utils) sits in a
//!   critical-section mutex; the next deadline is programmed into Timer0
//!   (0x4000_0000, IRQ 8), a 32-bit down-counter at the same 25 MHz, as a
//!   one-shot. Its interrupt (and SysTick's, as a backstop) wakes the
//!   expired timers. A 1 ms SysTick alone would round every deadline up to
//!   the next millisecond boundary; the plant task runs half a period after
//!   each control tick and needs finer alarms.

use core::cell::{Cell, RefCell};
use core::ptr::write_volatile;
use core::task::Waker;

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::{SCB, SYST};
use critical_section::{CriticalSection, Mutex};
use embassy_time_driver::Driver;
use embassy_time_queue_utils::Queue;

/// The CPU (and APB) clock of QEMU's MPS2 boards \[Hz\].
pub const CPU_HZ: u32 = 25_000_000;
/// SysTick wraps per second (the time base's period is 1 ms).
const SYSTICK_HZ: u32 = 1_000;
/// SysTick counts per period.
const COUNTS_PER_PERIOD: u32 = CPU_HZ / SYSTICK_HZ;
/// SysTick counts per embassy tick (1 µs).
const COUNTS_PER_US: u32 = CPU_HZ / 1_000_000;
/// Virtual ns (guest instructions under `-icount shift=0`) per SysTick count.
pub const NS_PER_COUNT: u32 = 1_000_000_000 / CPU_HZ;

/// CMSDK APB Timer0.
const TIMER0: usize = 0x4000_0000;
const TIMER_CTRL: usize = 0x00;
const TIMER_VALUE: usize = 0x04;
const TIMER_RELOAD: usize = 0x08;
const TIMER_INTCLEAR: usize = 0x0C;
const TIMER_CTRL_ENABLE: u32 = 1 << 0;
const TIMER_CTRL_IRQ_ENABLE: u32 = 1 << 3;
/// Timer0's interrupt number on mps2-an385/an386.
pub const TIMER0_IRQ: i16 = 8;

struct SysTickDriver {
    /// SysTick wraps since [`init`].
    periods: Mutex<Cell<u64>>,
    /// The deadline programmed into Timer0 (u64::MAX: none).
    alarm_us: Mutex<Cell<u64>>,
    queue: Mutex<RefCell<Queue>>,
}

embassy_time_driver::time_driver_impl!(static DRIVER: SysTickDriver = SysTickDriver {
    periods: Mutex::new(Cell::new(0)),
    alarm_us: Mutex::new(Cell::new(u64::MAX)),
    queue: Mutex::new(RefCell::new(Queue::new())),
});

/// Starts SysTick (1 ms reload, CPU clock, interrupt on wrap) and leaves
/// Timer0 stopped until the first alarm.
pub fn init(mut syst: SYST) {
    syst.disable_counter();
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(COUNTS_PER_PERIOD - 1);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
    timer_write(TIMER_CTRL, 0);
    timer_write(TIMER_INTCLEAR, 1);
    // SAFETY: Timer0's handler only takes the driver's critical sections.
    unsafe { cortex_m::peripheral::NVIC::unmask(Timer0Irq) };
}

#[derive(Clone, Copy)]
struct Timer0Irq;

// SAFETY: Timer0's interrupt number on the mps2-an386.
unsafe impl cortex_m::interrupt::InterruptNumber for Timer0Irq {
    fn number(self) -> u16 {
        TIMER0_IRQ as u16
    }
}

fn timer_write(off: usize, v: u32) {
    // SAFETY: a CMSDK APB timer register of the mps2 memory map; only this
    // module touches Timer0.
    unsafe { write_volatile((TIMER0 + off) as *mut u32, v) }
}

/// SysTick counts since [`init`] (25 MHz), wrap-safe: SysTick's handler may
/// not have counted a wrap that already happened (its exception pending).
fn counts(cs: CriticalSection<'_>) -> u64 {
    let periods = DRIVER.periods.borrow(cs).get();
    let c1 = SYST::get_current();
    let pending = SCB::is_pendst_pending();
    let c2 = SYST::get_current();
    // A down-counter: a wrap makes the second reading larger, or it
    // happened before the pending bit was read.
    let wrapped = pending || c2 > c1;
    let periods = periods + wrapped as u64;
    let elapsed = (COUNTS_PER_PERIOD - 1).saturating_sub(c2) as u64;
    periods * COUNTS_PER_PERIOD as u64 + elapsed
}

fn now_us(cs: CriticalSection<'_>) -> u64 {
    counts(cs) / COUNTS_PER_US as u64
}

/// Guest instructions since [`init`] (virtual ns under `-icount shift=0`),
/// wrapping, resolution [`NS_PER_COUNT`].
pub fn instructions() -> u32 {
    critical_section::with(|cs| (counts(cs) * NS_PER_COUNT as u64) as u32)
}

impl Driver for SysTickDriver {
    fn now(&self) -> u64 {
        critical_section::with(now_us)
    }

    fn schedule_wake(&self, at: u64, waker: &Waker) {
        critical_section::with(|cs| {
            let mut queue = self.queue.borrow(cs).borrow_mut();
            if queue.schedule_wake(at, waker) {
                let next = queue.next_expiration(now_us(cs));
                drop(queue);
                set_alarm(cs, next);
            }
        })
    }
}

/// Programs Timer0 to interrupt at `at_us` (stops it for u64::MAX).
fn set_alarm(cs: CriticalSection<'_>, at_us: u64) {
    DRIVER.alarm_us.borrow(cs).set(at_us);
    timer_write(TIMER_CTRL, 0);
    timer_write(TIMER_INTCLEAR, 1);
    if at_us == u64::MAX {
        return;
    }
    let now = now_us(cs);
    // At least one count; deadlines more than 100 s ahead are re-armed by
    // SysTick's backstop check long before.
    let delta_us = at_us.saturating_sub(now).clamp(1, 100_000_000);
    let counts = delta_us as u32 * COUNTS_PER_US;
    timer_write(TIMER_RELOAD, counts);
    timer_write(TIMER_VALUE, counts);
    timer_write(TIMER_CTRL, TIMER_CTRL_ENABLE | TIMER_CTRL_IRQ_ENABLE);
}

/// Wakes the expired timers and programs the next deadline.
fn on_alarm(cs: CriticalSection<'_>) {
    let now = now_us(cs);
    let next = DRIVER.queue.borrow(cs).borrow_mut().next_expiration(now);
    set_alarm(cs, next);
}

/// SysTick: one more period; a deadline that is due (Timer0 is the precise
/// path, this a backstop) wakes its timers.
pub fn on_systick() {
    critical_section::with(|cs| {
        let p = DRIVER.periods.borrow(cs);
        p.set(p.get() + 1);
        if now_us(cs) >= DRIVER.alarm_us.borrow(cs).get() {
            on_alarm(cs);
        }
    })
}

/// Timer0's interrupt: the programmed deadline.
pub fn on_timer0() {
    critical_section::with(on_alarm)
}
