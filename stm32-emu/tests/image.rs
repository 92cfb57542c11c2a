//! The unmodified F446RE release image (built by firmware/ci.sh, or by
//! stm32-emu/run.sh) under the models: boot, the 1 kHz loop, determinism.

use stm32_emu::machine::{ChipKind, Machine};

fn image() -> stm32_emu::elf::Image {
    let path = std::env::var("STM32_EMU_ELF").unwrap_or_else(|_| {
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../firmware/target/ci-stm32f446re/thumbv7em-none-eabihf/release/firmware"
        )
        .to_string()
    });
    let bytes = std::fs::read(&path).unwrap_or_else(|e| {
        panic!("{path}: {e}: build the F446RE release image first (bash firmware/ci.sh)")
    });
    stm32_emu::elf::Image::parse(&bytes).expect("the release ELF parses")
}

/// Runs `seconds` of emulated time; returns (instructions, feeds, TIM5 IRQs).
fn run(seconds: f64) -> (u64, u64, u64, bool) {
    let mut m = Machine::new(ChipKind::F446re, image()).expect("machine");
    let until = (seconds * 1e12) as u128;
    m.run_until(until, 1_000_000_000, &mut |_| Ok(()))
        .expect("the image runs without an unmodelled access or fault");
    let d = m.board();
    let tim5 = d.stats.taken.get(&(16 + 50)).copied().unwrap_or(0);
    (d.stats.instructions, d.stats.feeds, tim5, d.idle_reached)
}

/// The image reaches the executor's idle and runs its 1 kHz loop
/// (firmware config CONTROL_HZ = 1000): over 0.3 s, one watchdog feed per
/// completed tick, i.e. between 290 and 300 once the few boot ms are off;
/// the motors stay off in hold. Two runs are identical (deterministic:
/// time is the instruction count, no wall clock).
#[test]
fn boots_runs_the_loop_deterministically() {
    let a = run(0.3);
    assert!(a.3, "executor idle reached");
    assert!(
        (290..=300).contains(&a.1),
        "watchdog feeds in 0.3 s: {}",
        a.1
    );
    assert!(
        a.2 >= a.1,
        "a TIM5 interrupt behind every tick: {} < {}",
        a.2,
        a.1
    );
    let b = run(0.3);
    assert_eq!(a, b, "two runs differ");
}
