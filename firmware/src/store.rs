//! The robot record in the chip's own flash (robot-store over
//! embassy-stm32's blocking flash driver, wrapped in embassy-embedded-hal's
//! `BlockingAsync`), and the watchdog around a write.
//!
//! Sectors: the last two 128 KiB sectors of both chips' 512 KiB
//! (sectors 6 and 7, 0x0804_0000..0x0808_0000), which `memory.x` keeps out
//! of the program (FLASH = 256 KiB). They are in embassy's
//! `Bank1Region3` (the 128 KiB sectors 5-7 at 0x0802_0000), so the range is
//! 0x2_0000..0x6_0000 of that region.
//!
//! Why blocking: an F4 erase or program stalls every read of the flash it
//! runs on, including the CPU's instruction fetches; with the program in
//! that same flash, the async mode (FLASH interrupt) cannot run anything
//! else during the erase either, so it buys nothing but an interrupt
//! binding. Writes happen only in hold with the motors off, between two
//! control ticks (robot-app's `ControlTask::write_robot`).
//!
//! The watchdog (50 ms in the loop) is stretched for the write: IWDG
//! prescaler /64 and reload 4095, 8.2 s at the nominal 32 kHz LSI (5.6 s
//! at the F4's fastest LSI, 47 kHz), beyond the datasheets' 2 s maximum for
//! a 128 KiB sector erase at x32 parallelism (embassy's F4 driver programs
//! x32 at 3.3 V); sequential-storage erases one sector per call at most
//! once per save. The loop's 50 ms prescaler and reload are restored and
//! the watchdog fed right after.

use embassy_embedded_hal::adapter::BlockingAsync;
use embassy_stm32::flash::{Bank1Region3, Blocking, Flash};
use embassy_stm32::pac::iwdg::vals::{Key, Pr};
use embassy_stm32::pac::IWDG;
use embassy_stm32::peripherals::FLASH;
use embassy_stm32::Peri;
use robot_app::store::FlashRecord;
use robot_store::RobotStore;
use wmr_protocol::{RobotSource, ROBOT_BLOB_MAX};

/// The store's flash.
pub type StoreFlash = BlockingAsync<Bank1Region3<'static, Blocking>>;

/// The store's range within `Bank1Region3` (sectors 6 and 7).
pub const STORE_RANGE: core::ops::Range<u32> = 0x2_0000..0x6_0000;

/// The robot store over sectors 6 and 7; `None` if the range is refused
/// (never with these constants: robot-store checks the page size).
pub fn store(flash: Peri<'static, FLASH>) -> Option<FlashRecord<StoreFlash>> {
    let region = Flash::new_blocking(flash)
        .into_blocking_regions()
        .bank1_region3;
    let store = RobotStore::new(BlockingAsync::new(region), STORE_RANGE).ok()?;
    Some(FlashRecord {
        store,
        validate: robot_store::validate_robot,
    })
}

/// The loop's IWDG prescaler and reload, saved while a write runs.
pub struct WatchdogStretch {
    pr: Pr,
    rl: u16,
}

fn iwdg_wait_updated() {
    // PR/RLR writes take effect a few LSI cycles later (SR flags).
    while {
        let sr = IWDG.sr().read();
        sr.pvu() || sr.rvu()
    } {}
}

fn iwdg_set(pr: Pr, rl: u16) {
    IWDG.kr().write(|w| w.set_key(Key::RESET));
    iwdg_wait_updated();
    IWDG.kr().write(|w| w.set_key(Key::ENABLE));
    IWDG.pr().write(|w| w.set_pr(pr));
    IWDG.rlr().write(|w| w.set_rl(rl));
    iwdg_wait_updated();
    IWDG.kr().write(|w| w.set_key(Key::RESET));
}

impl WatchdogStretch {
    /// Saves the loop's watchdog setting and stretches it to /64, 4095.
    pub fn begin() -> Self {
        let s = Self {
            pr: IWDG.pr().read().pr(),
            rl: IWDG.rlr().read().rl(),
        };
        iwdg_set(Pr::DIVIDE_BY64, 0x0FFF);
        s
    }

    /// Restores the loop's setting, fed.
    pub fn end(self) {
        iwdg_set(self.pr, self.rl);
    }
}

/// The robot a boot runs and the record the device reports.
pub struct BootRobot {
    /// The robot the runtime is configured from.
    pub robot: robot_file::Robot,
    /// Where it came from (`wmr status`).
    pub source: RobotSource,
    record: [u8; ROBOT_BLOB_MAX],
    len: usize,
}

impl BootRobot {
    /// The record in force (robot-file's binary form).
    pub fn record(&self) -> &[u8] {
        &self.record[..self.len]
    }
}

/// Loads the robot record from flash, or falls back to the compiled-in
/// robot (`config::DEFAULT_ROBOT_BYTES`), saying why over defmt. A flash
/// robot whose `[bridge]` differs from the compiled-in one is not used: the
/// board was started (and its motor lines wired) for the image's bridge;
/// rebuild with that robot file as `ROBOT_FILE` instead.
pub async fn boot_robot(
    flash: &mut FlashRecord<StoreFlash>,
    default_robot: &robot_file::Robot,
) -> BootRobot {
    let default = crate::config::DEFAULT_ROBOT_BYTES;
    let n_default = default.len().min(ROBOT_BLOB_MAX);
    let mut record = [0u8; ROBOT_BLOB_MAX];
    let (n, mut source, fault) =
        robot_app::store::load_record(flash, &default[..n_default], &mut record).await;
    let mut len = n;
    let bridge = crate::config::bridge(default_robot);
    let robot = match robot_file::Robot::decode(&record[..n]) {
        Ok(r) if crate::config::bridge(&r) == bridge => r,
        other => {
            if other.is_ok() {
                defmt::error!(
                    "robot record: its [bridge] differs from the image's; running the compiled-in robot"
                );
                source = RobotSource::DefaultCorrupt;
            }
            record[..n_default].copy_from_slice(&default[..n_default]);
            len = n_default;
            default_robot.clone()
        }
    };
    defmt::info!(
        "robot record: {} (CRC-32 {=u32:08x}), fallback reason {}",
        source,
        wmr_device::robot::record_crc32(&record[..len]),
        fault
    );
    BootRobot {
        robot,
        source,
        record,
        len,
    }
}
