//! The MCU's last reset cause from its reset controller's flags.

use wmr_protocol::ResetCause;

/// RCC_CSR flag bits of the STM32F4 (RM0383 §6.3.20, RM0390 §6.3.21).
pub mod stm32f4_csr {
    /// Low-power reset.
    pub const LPWRRSTF: u32 = 1 << 31;
    /// Window watchdog reset.
    pub const WWDGRSTF: u32 = 1 << 30;
    /// Independent watchdog reset.
    pub const IWDGRSTF: u32 = 1 << 29;
    /// Software reset (SYSRESETREQ).
    pub const SFTRSTF: u32 = 1 << 28;
    /// POR/PDR reset.
    pub const PORRSTF: u32 = 1 << 27;
    /// NRST pin reset.
    pub const PINRSTF: u32 = 1 << 26;
    /// POR/PDR or BOR reset.
    pub const BORRSTF: u32 = 1 << 25;
    /// Write 1: clears every flag above.
    pub const RMVF: u32 = 1 << 24;
}

/// The reset cause from an STM32F4's RCC_CSR, read at boot before the
/// flags are cleared (RMVF). The flags accumulate until cleared and one
/// reset sets several: every internal reset also pulses NRST (PINRSTF),
/// a power-on sets BORRSTF too. So the most specific flag wins: low-power,
/// window watchdog, independent watchdog, software, power-on, brown-out
/// (BORRSTF without PORRSTF), pin (PINRSTF alone); none: unknown.
pub const fn from_stm32f4_csr(csr: u32) -> ResetCause {
    use stm32f4_csr::*;
    if csr & LPWRRSTF != 0 {
        ResetCause::LowPower
    } else if csr & WWDGRSTF != 0 {
        ResetCause::WindowWatchdog
    } else if csr & IWDGRSTF != 0 {
        ResetCause::IndependentWatchdog
    } else if csr & SFTRSTF != 0 {
        ResetCause::Software
    } else if csr & PORRSTF != 0 {
        ResetCause::PowerOn
    } else if csr & BORRSTF != 0 {
        ResetCause::BrownOut
    } else if csr & PINRSTF != 0 {
        ResetCause::Pin
    } else {
        ResetCause::Unknown
    }
}
