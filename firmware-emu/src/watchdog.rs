//! The hardware watchdog: the CMSDK APB watchdog QEMU models on the MPS2
//! boards (0x4000_8000, clocked at 25 MHz, its interrupt wired to NMI).
//!
//! The CMSDK watchdog counts down from `WDOGLOAD`; the first time it
//! reaches zero it raises its interrupt (here the NMI) and reloads; the
//! second time, with the interrupt still set and `RESEN` on, it resets the
//! system (QEMU: a guest reset, the board boots again). A feed
//! (`WDOGINTCLR`) clears the interrupt and reloads the counter. The load is
//! half the firmware's timeout, so the board resets
//! [`WATCHDOG_TIMEOUT_US`](crate::config::WATCHDOG_TIMEOUT_US) after the
//! last feed, and the NMI at half that cuts the motors first.

use core::ptr::write_volatile;

const WDOG: usize = 0x4000_8000;
const LOAD: usize = 0x000;
const CONTROL: usize = 0x008;
const INTCLR: usize = 0x00C;
const LOCK: usize = 0xC00;
const CONTROL_INTEN: u32 = 1 << 0;
const CONTROL_RESEN: u32 = 1 << 1;
/// `WDOGLOCK` key that enables register writes.
const UNLOCK_KEY: u32 = 0x1ACC_E551;

fn write(off: usize, v: u32) {
    // SAFETY: a register of the CMSDK watchdog in the mps2 memory map;
    // only this module writes it.
    unsafe { write_volatile((WDOG + off) as *mut u32, v) }
}

/// Starts the watchdog: reset `timeout_us` after the last [`feed`], NMI
/// at half of it. Cannot be stopped afterwards (nothing here does).
pub fn start(cpu_hz: u32, timeout_us: u32) {
    let load = (cpu_hz as u64 * timeout_us as u64 / 2_000_000) as u32;
    write(LOCK, UNLOCK_KEY);
    write(LOAD, load.max(1));
    write(INTCLR, 1);
    write(CONTROL, CONTROL_INTEN | CONTROL_RESEN);
}

/// Clears the interrupt and reloads the counter.
pub fn feed() {
    write(INTCLR, 1);
}
