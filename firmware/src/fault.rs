//! The panic and fault paths: HardFault, NMI, the default handler (every
//! exception and interrupt without a handler) and both panic handlers.
//!
//! Each one cuts the motor outputs **before anything touches the stack**:
//! its first instructions are [`motors_off_asm!`], register-only stores
//! (no push, no stack access), and only then does it continue (log, wait
//! for the watchdog). The reason is the stack overflow that flip-link
//! turns into a fault: the stack then sits at the bottom of RAM with SP at
//! or below its start, the exception entry's own frame is already lost,
//! and a handler that pushed first (any Rust function's prologue) would
//! fault inside HardFault: the core locks up with the motors at their last
//! duty until the watchdog resets it (34-94 ms). `firmware/ci.sh`
//! disassembles every entry below and fails when an instruction before the
//! motor-off stores uses the stack (with a negative control: the
//! `ci-fault-entry-pushes` feature puts a push first and the check must
//! fail on it).
//!
//! What the stores do (the pins of `motors.rs`, every bridge mode, the
//! same on both chips):
//!
//! | store | effect |
//! |---|---|
//! | GPIOB_BSRR = BR0, BR1, BR12-BR15 | ENABLE / STBY (PB14) low: the driver is off; the DIR / IN lines (PB0, PB1, PB12, PB13, PB15) low |
//! | GPIOB_MODER0/1/12-15 = output | the same lines as GPIO outputs, low (TwoPwm's IN2 lines PB13 / PB0 were TIM1 CH1N / CH2N) |
//! | TIM1_CCR1 = TIM1_CCR2 = 0 | zero duty |
//! | TIM1_BDTR.MOE = 0 | main output off: with OSSI = 1 the timer drives the idle levels OISx = OISxN = 0 (low) |
//! | GPIOA_BSRR = BR8, BR9; GPIOA_MODER8/9 = output | PA8 / PA9 (PWM / IN1) as GPIO outputs, low |
//!
//! The stores use r1-r3 only (caller-saved; r0 stays the panic handler's
//! argument) and are idempotent.

use defmt::error;

/// The motor-off stores (see the module's table), as assembly text.
/// Registers only: r1 (peripheral base), r2 (value), r3 (scratch).
macro_rules! motors_off_asm {
    () => {
        concat!(
            // GPIOB (0x4002_0400) BSRR (+0x18): reset PB0, PB1,
            // PB12-PB15 (motors::GPIOB_MOTOR_MASK); MODER (+0x00) those
            // pins = 0b01 (general-purpose output).
            "movw r1, #0x0400\n",
            "movt r1, #0x4002\n",
            "movw r2, #0x0000\n",
            "movt r2, #0xF003\n",
            "str r2, [r1, #0x18]\n",
            "ldr r3, [r1, #0x00]\n",
            "movw r2, #0x000F\n",
            "movt r2, #0xFF00\n",
            "bic r3, r3, r2\n",
            "movw r2, #0x0005\n",
            "movt r2, #0x5500\n",
            "orr r3, r3, r2\n",
            "str r3, [r1, #0x00]\n",
            // TIM1 (0x4001_0000): CCR1 (+0x34) = CCR2 (+0x38) = 0,
            // BDTR (+0x44) MOE (bit 15) = 0.
            "movw r1, #0x0000\n",
            "movt r1, #0x4001\n",
            "movs r2, #0\n",
            "str r2, [r1, #0x34]\n",
            "str r2, [r1, #0x38]\n",
            "ldr r3, [r1, #0x44]\n",
            "bic r3, r3, #0x8000\n",
            "str r3, [r1, #0x44]\n",
            // GPIOA (0x4002_0000): BSRR (+0x18) reset PA8, PA9; MODER
            // (+0x00) pins 8, 9 = 0b01 (general-purpose output).
            "movw r1, #0x0000\n",
            "movt r1, #0x4002\n",
            "movw r2, #0x0000\n",
            "movt r2, #0x0300\n",
            "str r2, [r1, #0x18]\n",
            "ldr r3, [r1, #0x00]\n",
            "bic r3, r3, #0xF0000\n",
            "orr r3, r3, #0x50000\n",
            "str r3, [r1, #0x00]\n",
            // The stores have reached the peripherals before anything else.
            "dsb\n",
        )
    };
}

/// What comes before the motor-off stores: nothing (the design).
#[cfg(not(feature = "ci-fault-entry-pushes"))]
macro_rules! entry_prefix {
    () => {
        ""
    };
}
/// CI's negative control only (`ci-fault-entry-pushes`): a push before the
/// motor-off stores, the defect `ci.sh`'s disassembly check must catch.
#[cfg(feature = "ci-fault-entry-pushes")]
macro_rules! entry_prefix {
    () => {
        "push {{r4, lr}}\npop {{r4, lr}}\n"
    };
}

/// Defines the exception or function symbol `$name` (in `.text.$name`):
/// the motor-off stores first, then `$then` (assembly).
macro_rules! cut_first {
    ($name:literal, $then:literal $(, $op:ident = $arg:tt $val:path)*) => {
        core::arch::global_asm!(
            concat!(
                ".section .text.", $name, ",\"ax\",%progbits\n",
                ".global ", $name, "\n",
                ".type ", $name, ",%function\n",
                ".thumb_func\n",
                ".p2align 2\n",
                $name, ":\n",
            ),
            entry_prefix!(),
            motors_off_asm!(),
            $then,
            concat!(".size ", $name, ", . - ", $name, "\n"),
            $($op = $arg $val),*
        );
    };
}

// HardFault (cortex-m-rt's vector table takes the `HardFault` symbol; no
// `#[exception]`, so no trampoline): outputs off, then spin in place until
// the watchdog resets the chip. No stack, no log: after a stack overflow
// there is no stack to use. probe-rs halts here (vector catch) and shows
// the faulting frame.
cut_first!("HardFault", "1: b 1b\n");

// NMI (the clock security system on an HSE failure, or any other source):
// outputs off, no logging (an NMI may interrupt a log in progress), then
// spin until the watchdog resets the chip.
cut_first!("NonMaskableInt", "1: b 1b\n");

// Every exception and interrupt without a handler (cortex-m-rt's default
// is an endless loop that leaves the outputs running): outputs off, then
// the Rust part logs the interrupt number and waits for the watchdog.
cut_first!("DefaultHandler", "b {rest}\n", rest = sym default_handler_rest);

// `defmt::panic!` / `unwrap!` end here (after logging their message):
// outputs off, then `udf` into HardFault (probe-rs halts there).
cut_first!("_defmt_panic", "udf #0\n");

/// The default handler after the outputs are off: logs device interrupts
/// (`irqn` >= 0; system exceptions are not logged), then waits.
extern "C" fn default_handler_rest() -> ! {
    let ipsr: u32;
    // SAFETY: reads the exception number, no side effect.
    unsafe { core::arch::asm!("mrs {}, IPSR", out(reg) ipsr, options(nomem, nostack)) };
    let irqn = (ipsr & 0x1FF) as i16 - 16;
    if irqn >= 0 {
        error!("unexpected interrupt {=i16} (motors off)", irqn);
    }
    wait_for_watchdog()
}

/// Panic: motor outputs off first, then [`panic_rest`] logs and stops in a
/// fault the debugger sees; without a debugger the watchdog resets the
/// chip, which boots with the motors disabled.
///
/// A panic handler cannot be a naked function (rustc 1.95), so its body is
/// a single `noreturn`, `nostack` assembly block: the motor-off stores,
/// then a tail branch to [`panic_rest`]. The compiler still gives it the
/// frame-pointer prologue (`push {r7, lr}`), and the panic machinery
/// before it (`core::panicking::panic_fmt` builds the `PanicInfo` on the
/// stack) uses the stack anyway; that is safe: a fault in any of those
/// pushes (an exhausted stack) is taken as a HardFault, whose entry cuts
/// the motors without the stack. `ci.sh` checks that nothing but that
/// prologue comes before the stores.
///
/// Out of line (`inline(never)`), so the check finds it under its own
/// symbol. It does not pass `info` on unless the `panic-location` feature
/// is on: handing it to the assembly would keep every panic site's message,
/// file name and `core::fmt` in the image (12 to 19 KiB of flash). probe-rs
/// halts on the `udf` after the log (HardFault) and prints the backtrace
/// with file and line.
#[panic_handler]
#[inline(never)]
fn panic(info: &core::panic::PanicInfo) -> ! {
    #[cfg(not(feature = "panic-location"))]
    {
        let _ = info;
        // SAFETY: stores to the motor peripherals' registers (the
        // module's table), then a branch to a `-> !` function.
        unsafe {
            core::arch::asm!(
                entry_prefix!(),
                motors_off_asm!(),
                "b {rest}",
                rest = sym panic_rest,
                options(noreturn, nostack),
            )
        }
    }
    #[cfg(feature = "panic-location")]
    // SAFETY: as above; `info` in r0, the Rust ABI's first argument.
    unsafe {
        core::arch::asm!(
            entry_prefix!(),
            motors_off_asm!(),
            "b {rest}",
            rest = sym panic_rest,
            in("r0") info,
            options(noreturn, nostack),
        )
    }
}

/// The panic after the outputs are off: the log line, then `udf` into
/// HardFault (which waits for the watchdog).
#[cfg(not(feature = "panic-location"))]
fn panic_rest() -> ! {
    error!("PANIC (motors off; location: the backtrace, or build with `panic-location`)");
    cortex_m::asm::udf()
}

/// The panic after the outputs are off (`panic-location`): the log line
/// with the location, then `udf` into HardFault.
#[cfg(feature = "panic-location")]
fn panic_rest(info: &core::panic::PanicInfo) -> ! {
    if let Some(loc) = info.location() {
        error!("PANIC at {}:{} (motors off)", loc.file(), loc.line());
    } else {
        error!("PANIC (motors off)");
    }
    cortex_m::asm::udf()
}

/// Spins until the independent watchdog resets the chip (within
/// `WATCHDOG_TIMEOUT_US` of the last feed when it runs; before it is
/// started, e.g. a fault during init, the board stays here with the outputs
/// off until power-cycled or reset by a debugger).
pub fn wait_for_watchdog() -> ! {
    loop {
        cortex_m::asm::nop();
    }
}
