//! Minimal ELF holding only what the firmware's control loop runs per step
//! (reference sampling and `Controller::step` for all three kinds), with a
//! panic handler that formats nothing and no semihosting. `run.sh` checks
//! its symbol table: no f64 soft-float routine (`__aeabi_d*`, `__adddf3`,
//! ...) and no `core::fmt` code may be linked.
#![no_std]
#![no_main]

use core::hint::black_box;
use core::panic::PanicInfo;

use controller_core::trajectory::{PaperCurve, PaperHeading, Trajectory};
use controller_core::{Controller, ControllerConfig, ControllerKind, StepInput};
use cortex_m_rt::entry;

#[entry]
fn main() -> ! {
    let kind = ControllerKind::ALL[black_box(2usize) % 3];
    let Ok(mut ctrl) = Controller::new(black_box(ControllerConfig::paper(kind))) else {
        loop {
            cortex_m::asm::nop();
        }
    };
    let traj = black_box(PaperCurve::paper(PaperHeading::SignedSmooth));
    let mut t = 0.0f32;
    loop {
        let mut input: StepInput = black_box(StepInput::default());
        input.reference = traj.sample(t);
        let out = ctrl.step(&input);
        black_box(out);
        t += 1e-3;
    }
}

#[panic_handler]
fn panic(_: &PanicInfo) -> ! {
    loop {
        cortex_m::asm::nop();
    }
}
