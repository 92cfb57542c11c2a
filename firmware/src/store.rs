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
use static_cell::StaticCell;
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

/// The robot a boot runs and the record the device reports, in a static
/// ([`boot_robot`]): not on `main`'s stack (D104's 62 KiB boot stack).
pub struct BootRobot {
    /// The robot the board, the runtime, the estimator and the link are
    /// configured from.
    pub robot: robot_file::Robot,
    /// Where it came from (`wmr status`).
    pub source: RobotSource,
    record: &'static [u8],
}

impl BootRobot {
    /// The record in force (robot-file's binary form).
    pub fn record(&self) -> &[u8] {
        self.record
    }
}

/// Loads the robot record from flash into a static, or falls back to the
/// compiled-in robot (`config::DEFAULT_ROBOT_BYTES`) when the record is
/// missing, corrupt or invalid (robot-file's decode: header, CRC-32, every
/// field, the `[bridge]` included), saying which and why over defmt
/// (`wmr status` shows the source). Runs before `board::init` starts the
/// motor outputs, which take the returned robot's `[bridge]`: a stored
/// robot of any bridge mode runs at once. Any record robot-file accepts
/// runs on this board's TIM1 (its PWM frequency is checked against every
/// supported timer clock, motors.rs).
/// The record (256 B) and the decoded robot (about 1 KiB) live in statics,
/// not on `main`'s stack. Call once (a second call panics: StaticCell).
pub async fn boot_robot(flash: &mut FlashRecord<StoreFlash>) -> &'static BootRobot {
    static RECORD: StaticCell<[u8; ROBOT_BLOB_MAX]> = StaticCell::new();
    static BOOT: StaticCell<BootRobot> = StaticCell::new();
    let default = crate::config::DEFAULT_ROBOT_BYTES;
    let n_default = default.len().min(ROBOT_BLOB_MAX);
    let record = RECORD.init([0; ROBOT_BLOB_MAX]);
    let (n, source, fault) =
        robot_app::store::load_record(flash, &default[..n_default], record).await;
    let record: &'static [u8] = &record[..n];
    defmt::info!(
        "robot record: {} (CRC-32 {=u32:08x}), fallback reason {}",
        source,
        wmr_device::robot::record_crc32(record),
        fault
    );
    BOOT.init_with(|| BootRobot {
        // Either record decodes (the flash record passed the same decode in
        // load_record's validation, build.rs decoded the compiled-in one).
        robot: robot_file::Robot::decode(record).unwrap_or_else(|_| crate::config::default_robot()),
        source,
        record,
    })
}
