//! Runs the unmodified STM32F446RE / STM32F411CE release image (the ELF
//! `firmware/ci.sh` builds) on Unicorn's Cortex-M4 core, with a model of
//! every peripheral the image touches, closed through sim-robot's plant.
//! GPL-2.0-only (it links Unicorn); never linked into the firmware or the
//! MIT/Apache crates. See README.md for what is modelled and what is not.
#![deny(missing_docs)]

pub mod bridge;
pub mod elf;
pub mod machine;
pub mod mpu6050;
pub mod periph;
pub mod robot;
pub mod usb_host;
