//! The controller sides of the closed loop: the bare controller with ideal
//! sensing ([`ideal::IdealSide`]) and the firmware runtime behind the
//! world's simulated hardware ([`runtime::RuntimeSide`]). Above
//! [`crate::closed_loop`], below the runners that choose between them.

pub mod ideal;
pub mod runtime;
