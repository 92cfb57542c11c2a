//! FLASH interface registers (RM0390 §3.8) and the robot store's sectors.
//!
//! ACR (latency, caches) is storage with read-back; KEYR unlocks CR
//! (0x4567_0123 then 0xCDEF_89AB); SR has BSY and the rc_w1 flags.
//! Program and erase are modelled for the robot record's sectors 6 and 7
//! (0x0804_0000..0x0808_0000, firmware/src/store.rs, `memory.x` keeps the
//! program out of them): a 32-bit word write with PG set (PSIZE x32) ANDs
//! the word into the NOR array, a sector erase (SER, SNB 6 or 7, STRT)
//! sets every byte to 0xFF. Both keep BSY set for the datasheet's time
//! and stall the CPU for it (every flash read, instruction fetches and
//! the vector table included, waits while the array is busy: RM0390
//! §3.5.4/3.6.1), which [`Flash::take_stall_ps`] hands to the run loop.
//! Anything else (program or erase of sectors 0-5, mass erase, another
//! PSIZE, a write without PG, CR written while locked) fails the run.
//!
//! Times (STM32F446xC/E datasheet DS10693, "Flash memory programming";
//! the STM32F411xC/E's DS10314 gives the same figures), x32 parallelism
//! (2.7-3.6 V, embassy's PSIZE32): word program typ 16 µs, max 100 µs;
//! 128 KB sector erase typ 1 s, max 2 s. [`FlashTiming::TYPICAL`] and
//! [`FlashTiming::MAX`] (`--flash-timing typ|max`).

use super::{merge, Access};

const REGS: &[(u32, &str, u32)] = &[
    (0x00, "ACR", 0),
    (0x04, "KEYR", 0),
    (0x08, "OPTKEYR", 0),
    (0x0C, "SR", 0),
    (0x10, "CR", 0x8000_0000),
    (0x14, "OPTCR", 0x0FFF_AAED),
];

/// First byte of the store's sectors (sector 6).
pub const STORE_BASE: u32 = 0x0804_0000;
/// The store's sectors 6 and 7, 128 KiB each \[B\].
pub const STORE_SIZE: u32 = 0x4_0000;
const SECTOR_BYTES: u32 = 0x2_0000;

const CR_PG: u32 = 1 << 0;
const CR_SER: u32 = 1 << 1;
const CR_MER: u32 = 1 << 2;
const CR_STRT: u32 = 1 << 16;
const CR_LOCK: u32 = 1 << 31;
const SR_EOP: u32 = 1 << 0;
const SR_BSY: u32 = 1 << 16;

/// Program and erase durations \[ps\].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FlashTiming {
    /// One 32-bit word (x32).
    pub word_program_ps: u128,
    /// One 128 KB sector (x32).
    pub sector_erase_ps: u128,
}

impl FlashTiming {
    /// The datasheets' typical figures: 16 µs, 1 s.
    pub const TYPICAL: Self = Self {
        word_program_ps: 16_000_000,
        sector_erase_ps: 1_000_000_000_000,
    };
    /// The datasheets' maximum figures: 100 µs, 2 s.
    pub const MAX: Self = Self {
        word_program_ps: 100_000_000,
        sector_erase_ps: 2_000_000_000_000,
    };
}

/// The flash interface and the store's NOR array.
#[derive(Clone, Debug)]
pub struct Flash {
    regs: [u32; 6],
    key_step: u8,
    busy_until_ps: u128,
    stall_ps: u128,
    /// Program and erase durations.
    pub timing: FlashTiming,
    /// Sectors 6 and 7 (kept over a reset: it is flash).
    pub store: Vec<u8>,
    /// Sector erases done (all boots).
    pub erases: u32,
    /// Words programmed (all boots).
    pub words_programmed: u64,
}

impl Default for Flash {
    fn default() -> Self {
        let mut regs = [0; 6];
        for &(o, _, v) in REGS {
            regs[o as usize / 4] = v;
        }
        Self {
            regs,
            key_step: 0,
            busy_until_ps: 0,
            stall_ps: 0,
            timing: FlashTiming::TYPICAL,
            store: vec![0xFF; STORE_SIZE as usize],
            erases: 0,
            words_programmed: 0,
        }
    }
}

impl Flash {
    /// The interface after a system reset: registers to their reset
    /// values, the array (and the counters, timing) kept.
    pub fn reset(&mut self) {
        let array = std::mem::take(&mut self.store);
        *self = Self {
            store: array,
            timing: self.timing,
            erases: self.erases,
            words_programmed: self.words_programmed,
            ..Self::default()
        };
    }

    /// The CPU stall an operation started since the last call asks for
    /// \[ps\] (0: none).
    pub fn take_stall_ps(&mut self) -> u128 {
        std::mem::take(&mut self.stall_ps)
    }

    /// Reads the register at `off` at time `now_ps`.
    pub fn read(&mut self, off: u32, now_ps: u128) -> Access<u32> {
        match REGS.iter().find(|r| r.0 == off) {
            Some(_) if off == 0x04 || off == 0x08 => Ok(0), // write-only keys
            Some(_) if off == 0x0C => {
                let bsy = if now_ps < self.busy_until_ps {
                    SR_BSY
                } else {
                    0
                };
                Ok(self.regs[3] | bsy)
            }
            Some(_) => Ok(self.regs[off as usize / 4]),
            None => Err(format!("FLASH+0x{off:02X}")),
        }
    }

    /// Writes the register at `off` at time `now_ps`.
    pub fn write(&mut self, off: u32, value: u32, mask: u32, now_ps: u128) -> Access<()> {
        let Some(&(_, name, _)) = REGS.iter().find(|r| r.0 == off) else {
            return Err(format!("FLASH+0x{off:02X}"));
        };
        let i = off as usize / 4;
        let v = merge(self.regs[i], value, mask);
        match name {
            "KEYR" => {
                self.key_step = match (self.key_step, v) {
                    (0, 0x4567_0123) => 1,
                    (1, 0xCDEF_89AB) => {
                        self.regs[4] &= !CR_LOCK;
                        0
                    }
                    _ => return Err(format!("FLASH.KEYR: wrong key sequence (0x{v:08X})")),
                };
                Ok(())
            }
            "SR" => {
                self.regs[i] &= !(v & 0xF3); // rc_w1 flags
                Ok(())
            }
            "CR" => self.write_cr(v, now_ps),
            _ => {
                self.regs[i] = v;
                Ok(())
            }
        }
    }

    fn write_cr(&mut self, v: u32, now_ps: u128) -> Access<()> {
        // LOCK is set by a write of 1 and cleared only by the KEYR sequence.
        let v = v | (self.regs[4] & CR_LOCK);
        if self.regs[4] & CR_LOCK != 0 && v != self.regs[4] {
            return Err("FLASH.CR written while locked (no KEYR sequence)".into());
        }
        if now_ps < self.busy_until_ps && v & (CR_STRT | CR_PG) != 0 {
            return Err("FLASH.CR: an operation started while BSY".into());
        }
        if v & CR_MER != 0 {
            return Err(
                "FLASH.CR MER (mass erase): not modelled (it would erase the program)".into(),
            );
        }
        if v & CR_STRT != 0 {
            if v & CR_SER == 0 {
                return Err("FLASH.CR STRT without SER: not modelled".into());
            }
            let snb = (v >> 3) & 0xF;
            if !(6..=7).contains(&snb) {
                return Err(format!(
                    "FLASH.CR: erase of sector {snb}: only the robot store's sectors 6 and 7 are modelled (the program is in 0-5)"
                ));
            }
            let o = ((snb - 6) * SECTOR_BYTES) as usize;
            self.store[o..o + SECTOR_BYTES as usize].fill(0xFF);
            self.erases += 1;
            self.busy_until_ps = now_ps + self.timing.sector_erase_ps;
            self.stall_ps = self.timing.sector_erase_ps;
            self.regs[3] |= SR_EOP;
            self.regs[4] = v & !CR_STRT;
            return Ok(());
        }
        self.regs[4] = v;
        Ok(())
    }

    /// A read of the store's array at `addr` (word-aligned).
    pub fn read_array(&self, addr: u32) -> Access<u32> {
        let o = (addr - STORE_BASE) as usize;
        let b = &self.store[o..o + 4];
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// A write to the store's array at `addr` (word `addr & !3`, lanes
    /// `mask`) at `now_ps`: a program with PG set and PSIZE x32.
    pub fn write_array(&mut self, addr: u32, value: u32, mask: u32, now_ps: u128) -> Access<()> {
        let cr = self.regs[4];
        if cr & CR_PG == 0 {
            return Err(format!(
                "write of 0x{value:08X} to flash 0x{addr:08X} without FLASH.CR PG"
            ));
        }
        if (cr >> 8) & 3 != 2 || mask != 0xFFFF_FFFF {
            return Err(format!(
                "flash program at 0x{addr:08X}: only 32-bit words with PSIZE x32 are modelled (CR 0x{cr:08X})"
            ));
        }
        if now_ps < self.busy_until_ps {
            return Err("flash program while BSY".into());
        }
        let o = (addr - STORE_BASE) as usize;
        let old = self.read_array(addr)?;
        self.store[o..o + 4].copy_from_slice(&(old & value).to_le_bytes());
        self.words_programmed += 1;
        self.busy_until_ps = now_ps + self.timing.word_program_ps;
        self.stall_ps = self.timing.word_program_ps;
        self.regs[3] |= SR_EOP;
        Ok(())
    }
}

/// The store's sectors as the firmware's own store code (robot-store over
/// sequential-storage) leaves them after saving `blob` again and again
/// until the next save would erase a sector: both sectors used, the
/// active one full. The next `wmr robot push` then erases (the F4's
/// seconds-long stall, measured by run.sh's check (m)). Returns the
/// sectors' bytes and the saves it took.
pub fn aged_store(blob: &[u8]) -> Result<(Vec<u8>, u32), String> {
    type Ram = robot_store::RamFlash<{ STORE_SIZE as usize }, { SECTOR_BYTES as usize }>;
    let mut ram: Box<Ram> = Box::new(Ram::new());
    for saves in 0..100_000u32 {
        let mut snapshot = ram.clone();
        let erased_before: u32 = ram.erases().iter().sum();
        let mut store = robot_store::RobotStore::new(&mut *ram, 0..STORE_SIZE)
            .map_err(|_| "robot store: range refused".to_string())?;
        embassy_futures::block_on(store.save(robot_store::validate_robot, blob))
            .map_err(|e| format!("robot store: save {saves} failed: {e:?}"))?;
        if ram.erases().iter().sum::<u32>() > erased_before {
            return Ok((snapshot.bytes_mut().to_vec(), saves));
        }
    }
    Err("robot store: no erase after 100 000 saves".into())
}

/// The store's sectors as the firmware's store code leaves them after one
/// save of `blob` (a record pushed once): what a board flashed with a
/// record boots from. `validate` is the save's check: robot-store's
/// `validate_robot` for a real record, one that accepts anything to put a
/// crafted record there (a valid CRC around fields robot-file refuses),
/// which only a tool other than the firmware could have written.
pub fn stored_store(blob: &[u8], validate: robot_store::RobotValidator) -> Result<Vec<u8>, String> {
    type Ram = robot_store::RamFlash<{ STORE_SIZE as usize }, { SECTOR_BYTES as usize }>;
    let mut ram: Box<Ram> = Box::new(Ram::new());
    let mut store = robot_store::RobotStore::new(&mut *ram, 0..STORE_SIZE)
        .map_err(|_| "robot store: range refused".to_string())?;
    embassy_futures::block_on(store.save(validate, blob))
        .map_err(|e| format!("robot store: save failed: {e:?}"))?;
    Ok(store.into_flash().bytes_mut().to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One save leaves a store that robot-store loads the same record
    /// from (what the firmware's boot does), the rest erased.
    #[test]
    fn stored_store_loads_back_the_record() {
        let robot = robot_file::Robot::paper();
        let mut blob = [0u8; robot_file::MAX_ENCODED_LEN];
        let n = robot.encode(&mut blob).unwrap();
        let mut bytes = stored_store(&blob[..n], robot_store::validate_robot).unwrap();
        assert_eq!(bytes.len(), STORE_SIZE as usize);
        type Ram = robot_store::RamFlash<{ STORE_SIZE as usize }, { SECTOR_BYTES as usize }>;
        let mut ram: Box<Ram> = Box::new(Ram::new());
        ram.bytes_mut().copy_from_slice(&bytes);
        let mut store = robot_store::RobotStore::new(&mut *ram, 0..STORE_SIZE).unwrap();
        let mut out = [0u8; robot_store::ROBOT_BLOB_MAX];
        let got = embassy_futures::block_on(store.load(robot_store::validate_robot, &mut out));
        assert_eq!(got, Ok(n));
        assert_eq!(&out[..n], &blob[..n]);
        // The second sector untouched.
        assert!(bytes
            .split_off(SECTOR_BYTES as usize)
            .iter()
            .all(|&b| b == 0xFF));
    }

    fn unlocked() -> Flash {
        let mut f = Flash::default();
        f.write(0x04, 0x4567_0123, !0, 0).unwrap();
        f.write(0x04, 0xCDEF_89AB, !0, 0).unwrap();
        f
    }

    /// Program ANDs into the erased array and is busy for the word time;
    /// an erase of sector 7 restores 0xFF there only, busy for the
    /// sector time, and asks the CPU to stall for it.
    #[test]
    fn program_and_erase_follow_nor_flash() {
        let mut f = unlocked();
        f.write(0x10, CR_PG | (2 << 8), !0, 0).unwrap();
        f.write_array(STORE_BASE, 0x1234_5678, !0, 0).unwrap();
        f.write_array(STORE_BASE + SECTOR_BYTES, 0x0F0F_0F0F, !0, 20_000_000)
            .unwrap();
        assert_eq!(f.read_array(STORE_BASE).unwrap(), 0x1234_5678);
        assert_eq!(f.take_stall_ps(), FlashTiming::TYPICAL.word_program_ps);
        assert_eq!(f.read(0x0C, 30_000_000).unwrap() & SR_BSY, SR_BSY);
        f.write(0x10, CR_SER | (7 << 3), !0, 50_000_000).unwrap();
        f.write(0x10, CR_SER | (7 << 3) | CR_STRT, !0, 50_000_000)
            .unwrap();
        assert_eq!(f.take_stall_ps(), FlashTiming::TYPICAL.sector_erase_ps);
        assert_eq!(f.read_array(STORE_BASE + SECTOR_BYTES).unwrap(), !0);
        assert_eq!(f.read_array(STORE_BASE).unwrap(), 0x1234_5678);
        let end = 50_000_000 + FlashTiming::TYPICAL.sector_erase_ps;
        assert_eq!(f.read(0x0C, end - 1).unwrap() & SR_BSY, SR_BSY);
        assert_eq!(f.read(0x0C, end).unwrap() & SR_BSY, 0);
        // Kept over a reset.
        f.reset();
        assert_eq!(f.read_array(STORE_BASE).unwrap(), 0x1234_5678);
        assert_eq!(f.erases, 1);
    }

    /// The program's sectors, a write without PG and a locked CR fail.
    #[test]
    fn what_is_not_modelled_fails() {
        let mut f = unlocked();
        let e = f
            .write(0x10, CR_SER | (2 << 3) | CR_STRT, !0, 0)
            .unwrap_err();
        assert!(e.contains("sector 2"), "{e}");
        assert!(f
            .write_array(STORE_BASE, 0, !0, 0)
            .unwrap_err()
            .contains("PG"));
        let mut locked = Flash::default();
        assert!(locked.write(0x10, CR_LOCK | CR_PG, !0, 0).is_err());
        assert!(locked.write(0x10, CR_MER, !0, 0).is_err());
    }
}
