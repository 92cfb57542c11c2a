//! The peripheral models, one module per peripheral. Every model knows its
//! registers by offset and name; an access to an offset it does not know is
//! an [`Unmodelled`] error (the run fails with the address and name, never
//! a silent zero).

pub mod dbgmcu;
pub mod dma;
pub mod flash;
pub mod gpio;
pub mod i2c;
pub mod iwdg;
pub mod nvic;
pub mod otg_fs;
pub mod pwr;
pub mod rcc;
pub mod scb;
pub mod systick;
pub mod timer;
pub mod usart;

/// An access the models do not cover.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Unmodelled {
    /// The bus address.
    pub addr: u32,
    /// The peripheral and register, as far as known (`"TIM2"`, `"TIM1.DMAR"`).
    pub what: String,
    /// Read or write (and the value written).
    pub access: String,
}

impl core::fmt::Display for Unmodelled {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "unmodelled {} at 0x{:08X} ({})",
            self.access, self.addr, self.what
        )
    }
}

/// The result of a register access.
pub type Access<T> = Result<T, String>;

/// Merges a sub-word write: `value` (already shifted to its byte lane) into
/// `old` under the lane mask `mask`.
pub fn merge(old: u32, value: u32, mask: u32) -> u32 {
    (old & !mask) | (value & mask)
}

/// The picoseconds in one second.
pub const PS_PER_S: u128 = 1_000_000_000_000;

/// The time \[ps\] of `ticks` periods of a clock of `hz`, rounded up
/// (the tick happens at or after it).
pub fn ticks_to_ps(ticks: u128, hz: u64) -> u128 {
    (ticks * PS_PER_S).div_ceil(hz as u128)
}

/// Whole periods of a clock of `hz` in `ps`.
pub fn ps_to_ticks(ps: u128, hz: u64) -> u128 {
    ps * hz as u128 / PS_PER_S
}
