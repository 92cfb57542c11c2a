//! Exception entry and return by hand (ARMv7-M B1.5): the frame, EPSR.IT,
//! the FP context, EXC_RETURN, tail-chaining, and Unicorn's interrupt hook.

use super::*;

/// The exception to take now, if any (reads PRIMASK/BASEPRI/FAULTMASK).
pub(super) fn deliverable(uc: &mut Unicorn<Board>) -> Option<usize> {
    let primask = uc.reg_read(RegisterARM::PRIMASK).unwrap_or(0) & 1 != 0;
    let basepri = uc.reg_read(RegisterARM::BASEPRI).unwrap_or(0) as u8;
    let faultmask = uc.reg_read(RegisterARM::FAULTMASK).unwrap_or(0) & 1 != 0;
    uc.get_data().nvic.to_take(primask, basepri, faultmask)
}

pub(super) fn rd(uc: &Unicorn<Board>, r: RegisterARM) -> u32 {
    uc.reg_read(r).unwrap_or(0) as u32
}

const FP_REGS: [RegisterARM; 16] = [
    RegisterARM::S0,
    RegisterARM::S1,
    RegisterARM::S2,
    RegisterARM::S3,
    RegisterARM::S4,
    RegisterARM::S5,
    RegisterARM::S6,
    RegisterARM::S7,
    RegisterARM::S8,
    RegisterARM::S9,
    RegisterARM::S10,
    RegisterARM::S11,
    RegisterARM::S12,
    RegisterARM::S13,
    RegisterARM::S14,
    RegisterARM::S15,
];

/// Exception entry (ARMv7-M B1.5.6): the 8-word basic frame on MSP (8-byte
/// aligned, xPSR bit 9 marking the padding), EXC_RETURN in LR, IPSR, PC
/// from the vector table. The FP caller-saved registers are saved by the
/// harness (no lazy stacking: the guest sees a basic frame).
pub(super) fn enter_exception(uc: &mut Unicorn<Board>, e: usize) -> Result<(), String> {
    let ue = |x: uc_error| format!("exception entry: {x:?}");
    let control = rd(uc, RegisterARM::CONTROL);
    if control & 2 != 0 {
        return Err("exception entry from PSP (CONTROL.SPSEL = 1): not modelled".into());
    }
    let sp = rd(uc, RegisterARM::SP);
    let ipsr = rd(uc, RegisterARM::IPSR) & 0x1FF;
    let xpsr = rd(uc, RegisterARM::XPSR);
    let pc = rd(uc, RegisterARM::PC);
    let frame_sp = (sp - 32) & !7;
    let pad = frame_sp != sp - 32;
    let stacked_xpsr = (xpsr & !(1 << 9)) | (1 << 24) | ((pad as u32) << 9) | ipsr;
    let words = [
        rd(uc, RegisterARM::R0),
        rd(uc, RegisterARM::R1),
        rd(uc, RegisterARM::R2),
        rd(uc, RegisterARM::R3),
        rd(uc, RegisterARM::R12),
        rd(uc, RegisterARM::LR),
        pc & !1,
        stacked_xpsr,
    ];
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let ram = RAM_BASE..RAM_BASE + uc.get_data().chip.ram_size();
    if !ram.contains(&frame_sp) {
        return Err(format!(
            "exception {e} entry: stack 0x{frame_sp:08X} outside SRAM (stack overflow)"
        ));
    }
    uc.mem_write(frame_sp as u64, &bytes).map_err(ue)?;
    let mut fp = [0u64; 17];
    for (i, r) in FP_REGS.iter().enumerate() {
        fp[i] = uc.reg_read(*r).unwrap_or(0);
    }
    fp[16] = uc.reg_read(RegisterARM::FPSCR).unwrap_or(0);
    let vtor = {
        let d = uc.get_data_mut();
        if xpsr & 0x0600_FC00 != 0 {
            d.stats.taken_in_it_block += 1;
        }
        if d.stats.min_sp == 0 || frame_sp < d.stats.min_sp {
            d.stats.min_sp = frame_sp;
        }
        d.exc_log(format!(
            "enter {e} from IPSR {ipsr}: SP 0x{sp:08X} -> frame 0x{frame_sp:08X}, return PC 0x{pc:08X}, LR 0x{:08X}, xPSR 0x{xpsr:08X}",
            words[5]
        ));
        d.fp_stack.push(fp);
        d.nvic.activate(e);
        d.event_reg = true;
        *d.stats.taken.entry(e).or_default() += 1;
        if d.scb.vtor == 0 {
            FLASH_BASE // boot alias: address 0 is flash
        } else {
            d.scb.vtor
        }
    };
    let mut v = [0u8; 4];
    uc.mem_read((vtor + 4 * e as u32) as u64, &mut v)
        .map_err(ue)?;
    let handler = u32::from_le_bytes(v);
    uc.reg_write(RegisterARM::SP, frame_sp as u64).map_err(ue)?;
    // ExceptionTaken (B1.5.6) clears EPSR.IT: the interrupted code may be
    // inside an IT block (Unicorn stops at any translation block's start,
    // and an IT block split over a 1 KiB page is two blocks); its IT state
    // is in the stacked xPSR and comes back on the return. Left set, the
    // handler's first instructions would run as the block's remaining
    // conditional slots (D104).
    uc.reg_write(RegisterARM::EPSR, 1 << 24).map_err(ue)?;
    uc.reg_write(
        RegisterARM::LR,
        if ipsr == 0 { 0xFFFF_FFF9 } else { 0xFFFF_FFF1 },
    )
    .map_err(ue)?;
    uc.reg_write(RegisterARM::IPSR, e as u64).map_err(ue)?;
    rebuild_hflags(uc).map_err(ue)?;
    uc.reg_write(RegisterARM::PC, (handler | 1) as u64)
        .map_err(ue)?;
    if matches!(
        e,
        exc::HARD_FAULT | exc::BUS_FAULT | exc::USAGE_FAULT | exc::MEM_MANAGE | exc::NMI
    ) {
        let d = uc.get_data_mut();
        d.event(format!(
            "exception {e} entered (handler 0x{handler:08X}, return 0x{pc:08X})"
        ));
    }
    Ok(())
}

/// QEMU caches the mode-dependent translation flags (`hflags`: Handler
/// mode among them, which decides whether a branch to EXC_RETURN is an
/// exception return) and rebuilds them only where its own code changes
/// the mode; an IPSR write through Unicorn does not. Writing APSR.NZCV
/// (its own value: nothing changes) makes Unicorn rebuild them, so the
/// blocks translated next see the mode the harness just set.
pub(super) fn rebuild_hflags(uc: &mut Unicorn<Board>) -> Result<(), uc_error> {
    let nzcv = uc.reg_read(RegisterARM::XPSR)? & 0xF000_0000;
    uc.reg_write(RegisterARM::APSR_NZCV, nzcv)
}

/// EXC_RETURN arrives as QEMU's EXCP_EXCEPTION_EXIT (8); UDF as EXCP_UDEF (1).
pub(super) fn intr_hook(uc: &mut Unicorn<Board>, intno: u32) {
    match intno {
        8 => {
            if let Err(e) = exception_return(uc) {
                bad(uc, e);
            }
        }
        _ => {
            let pc = rd(uc, RegisterARM::PC);
            bad(
                uc,
                format!("CPU exception {intno} at PC 0x{pc:08X}: not modelled"),
            );
        }
    }
}

pub(super) fn exception_return(uc: &mut Unicorn<Board>) -> Result<(), String> {
    let ue = |x: uc_error| format!("exception return: {x:?}");
    let exc_return = rd(uc, RegisterARM::PC) | 1;
    if exc_return & 0xF != 0x9 && exc_return & 0xF != 0x1 {
        return Err(format!(
            "EXC_RETURN 0x{exc_return:08X}: only MSP returns are modelled"
        ));
    }
    let cur = (rd(uc, RegisterARM::IPSR) & 0x1FF) as usize;
    uc.get_data_mut().nvic.deactivate(cur)?;
    let sp = rd(uc, RegisterARM::SP);
    let mut b = [0u8; 32];
    uc.mem_read(sp as u64, &mut b).map_err(ue)?;
    let w: Vec<u32> = b
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes(c.try_into().unwrap_or_default()))
        .collect();
    let xpsr = w[7];
    let new_sp = sp + 32 + if xpsr & (1 << 9) != 0 { 4 } else { 0 };
    let ipsr = xpsr & 0x1FF;
    uc.get_data_mut().exc_log(format!(
        "return from {cur} (0x{exc_return:08X}): frame 0x{sp:08X} -> SP 0x{new_sp:08X}, PC 0x{:08X}, LR 0x{:08X}, xPSR 0x{xpsr:08X}",
        w[6], w[5]
    ));
    if (exc_return & 0xF == 0x9) != (ipsr == 0) {
        return Err(format!(
            "EXC_RETURN 0x{exc_return:08X} with stacked IPSR {ipsr}: inconsistent frame"
        ));
    }
    for (r, v) in [
        (RegisterARM::R0, w[0]),
        (RegisterARM::R1, w[1]),
        (RegisterARM::R2, w[2]),
        (RegisterARM::R3, w[3]),
        (RegisterARM::R12, w[4]),
        (RegisterARM::LR, w[5]),
        (RegisterARM::SP, new_sp),
    ] {
        uc.reg_write(r, v as u64).map_err(ue)?;
    }
    // NZCVQ, GE (XPSR alone leaves GE out), IT and T from the frame.
    uc.reg_write(RegisterARM::XPSR_NZCVQG, (xpsr & !(1 << 9)) as u64)
        .map_err(ue)?;
    uc.reg_write(RegisterARM::IPSR, ipsr as u64).map_err(ue)?;
    rebuild_hflags(uc).map_err(ue)?;
    let fp = uc.get_data_mut().fp_stack.pop();
    if let Some(fp) = fp {
        for (i, r) in FP_REGS.iter().enumerate() {
            uc.reg_write(*r, fp[i]).map_err(ue)?;
        }
        uc.reg_write(RegisterARM::FPSCR, fp[16]).map_err(ue)?;
    }
    uc.reg_write(RegisterARM::PC, (w[6] | 1) as u64)
        .map_err(ue)?;
    {
        let d = uc.get_data_mut();
        d.event_reg = true;
        d.update_lines();
    }
    // Tail-chain (or preempt the returned-to context at once).
    if let Some(e) = deliverable(uc) {
        enter_exception(uc, e)?;
    }
    Ok(())
}
