//! Instructions per call of the control step (`Controller::step`), the
//! function bench-m4 also counts: an entry hook and a check at each block.

use super::{rd, Board};
use crate::elf::Image;
use unicorn_engine::unicorn_const::uc_error;
use unicorn_engine::{RegisterARM, Unicorn};

/// Instructions per call of one function of the image (the control step,
/// `controller_core::controller::Controller::step`, which bench-m4 also
/// counts): from its entry to the first block at its return address with
/// the entry's SP, interrupts taken meanwhile included (block granular).
#[derive(Clone, Debug, Default)]
pub struct StepProbe {
    /// The function's entry (none: the image has no such symbol).
    pub entry: Option<u32>,
    /// A call in progress: (cycles at entry, SP, return address).
    pub(super) open: Option<(u64, u32, u32)>,
    /// The calls measured.
    pub calls: CallStats,
}

/// Instruction counts of the calls measured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CallStats {
    /// Calls.
    pub n: u64,
    /// Sum of their instructions.
    pub sum: u64,
    /// The largest.
    pub max: u64,
}

impl CallStats {
    /// Mean instructions per call (0 before the first).
    pub fn mean(&self) -> u64 {
        self.sum.checked_div(self.n).unwrap_or(0)
    }
}

/// Hooks the control step's entry, when the image has the symbol.
pub(super) fn install(uc: &mut Unicorn<Board>, image: &Image) -> Result<(), uc_error> {
    let step = image
        .symbols
        .iter()
        .find(|s| {
            s.0.contains("15controller_core10controller10Controller4step")
        })
        .map(|s| s.1 & !1);
    if let Some(a) = step {
        uc.get_data_mut().step_probe.entry = Some(a);
        uc.add_code_hook(a as u64, a as u64, |uc, _, _| {
            let sp = rd(uc, RegisterARM::SP);
            let lr = rd(uc, RegisterARM::LR) & !1;
            let d = uc.get_data_mut();
            d.step_probe.open = Some((d.cycles, sp, lr));
        })?;
    }
    Ok(())
}

/// At each block: a call in progress returns when a block starts at its
/// return address with the entry's SP.
pub(super) fn on_block(uc: &mut Unicorn<Board>, addr: u32) {
    let ret = uc.get_data().step_probe.open.map(|o| o.2);
    if ret != Some(addr) {
        return;
    }
    let sp = rd(uc, RegisterARM::SP);
    let d = uc.get_data_mut();
    if let Some((c0, sp0, _)) = d.step_probe.open {
        if sp == sp0 {
            d.step_probe.open = None;
            let n = d.cycles - c0;
            let c = &mut d.step_probe.calls;
            c.n += 1;
            c.sum += n;
            c.max = c.max.max(n);
        }
    }
}
