//! # robot-store
//!
//! The robot record in the robot's own NOR flash: one item of a
//! [sequential-storage](sequential_storage) **map** over any
//! `embedded-storage-async` flash (the STM32's internal flash in the
//! firmware, [`RamFlash`] in the simulated device, the crate's mock flash
//! with fault injection in the tests).
//!
//! * **Record**: map key [`RECORD_KEY`], value `[RECORD_FORMAT, blob...]`
//!   where the blob is robot-file's binary form (magic, format, length,
//!   payload, CRC-32). Two checks: sequential-storage's item CRCs (header
//!   and data) and the blob's own CRC-32 plus the whole robot's validation
//!   ([`RobotValidator`]).
//! * **Map, not queue**: a map item for one key is superseded only by a
//!   newer *complete* item for that key (the newest item whose CRC checks
//!   wins; a half-written one fails its CRC and is ignored), and when a page
//!   must be erased to make room, the live record is first copied to the
//!   open page. So the old record stays readable until the new one is
//!   whole, with no second key or commit marker to manage. A queue would
//!   need push-new-then-pop-old bookkeeping and gives up the old value on
//!   its own schedule.
//! * **Wear**: items are appended; pages are used cyclically, so erases
//!   spread evenly over the pages (one erase per page-full of records).
//! * **Fallback**: [`RobotStore::load`] says why it found no usable
//!   record ([`LoadFault`]: missing, or corrupt and why); the board then runs
//!   the compiled-in default and reports [`RobotSource`] in its status.
//!
//! Power loss during [`RobotStore::save`] leaves either the old or the new
//! record readable, never anything else (tests/power_loss.rs cuts the power
//! at every byte of a save with the mock flash's fault injection).
#![no_std]
#![deny(missing_docs)]
#![forbid(unsafe_code)]

mod ram_flash;
mod validate;

pub use ram_flash::{RamFlash, RamFlashError};
pub use validate::{decode_fault, robot_fault, validate_robot};
pub use wmr_protocol::{RobotFault, RobotSource, RobotValidator, ROBOT_BLOB_MAX};

use core::ops::Range;
use embedded_storage_async::nor_flash::NorFlash;
use sequential_storage::cache::key_pointers::ArrayKeyPointers;
use sequential_storage::cache::page_pointers::ArrayPagePointers;
use sequential_storage::cache::page_states::ArrayPageStates;
use sequential_storage::cache::Cache;
use sequential_storage::map::{MapConfig, MapStorage};

/// The map key of the robot record.
pub const RECORD_KEY: u8 = 0x52;
/// Version of the record layout around the blob (the first value byte);
/// a record of another version is reported corrupt, never misread.
pub const RECORD_FORMAT: u8 = 1;

/// The work buffer: key, format byte and the largest blob, rounded up to
/// the largest flash word sequential-storage supports (32 bytes).
const BUF_LEN: usize = (1 + 1 + ROBOT_BLOB_MAX).div_ceil(32) * 32;

/// A word-aligned buffer (flash drivers and the mock flash want aligned
/// write buffers).
#[repr(align(32))]
struct Aligned([u8; BUF_LEN]);

/// Why [`RobotStore::load`] found no usable record.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum LoadFault {
    /// No record in flash (new board, erased flash).
    Missing,
    /// The flash could not be read, or sequential-storage found it
    /// corrupted beyond repair.
    Flash,
    /// A record of another [`RECORD_FORMAT`], or empty, or longer than
    /// [`ROBOT_BLOB_MAX`].
    Format,
    /// The blob fails its own CRC-32 or the robot's validation.
    Invalid(RobotFault),
}

impl LoadFault {
    /// What the status reports for this fallback.
    pub fn source(&self) -> RobotSource {
        match self {
            Self::Missing => RobotSource::DefaultMissing,
            _ => RobotSource::DefaultCorrupt,
        }
    }
}

/// Why [`RobotStore::save`] stored nothing new (the previous record is
/// still the stored one unless the error is [`StoreError::ReadBack`]).
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum StoreError {
    /// The blob was refused by the validator: nothing was written.
    Invalid(RobotFault),
    /// Empty or longer than [`ROBOT_BLOB_MAX`]: nothing was written.
    Length,
    /// The flash refused an operation (or power was lost in the tests).
    Flash,
    /// The record read back after the write differs from the blob, or is
    /// missing.
    ReadBack,
}

/// The flash range is not usable as a store (not page-aligned, fewer than
/// two or more than [`MAX_PAGES`] pages, pages too small for a record).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RangeError;

/// Most pages a store may span (the cache's size; the firmware uses 2).
pub const MAX_PAGES: usize = 8;

/// sequential-storage's cache of page states, page pointers and the one
/// key's location. Uncached, the save that fills a page and moves to the
/// next (once per page-full of records: about 936 saves of a 140 B record
/// in a 128 KiB page) searched the page for the newest item of each item
/// it migrated, quadratic in the items: 1.07 s of a 3 GHz host, more than
/// the stretched 8.2 s watchdog on the 168 MHz chip, so that save never
/// finished (stm32-emu's check (m) found it; D105).
type StoreCache =
    Cache<ArrayPageStates<MAX_PAGES>, ArrayPagePointers<MAX_PAGES>, ArrayKeyPointers<u8, 1>, u8>;

/// The robot record over flash `F` in `range`.
pub struct RobotStore<F: NorFlash> {
    map: MapStorage<u8, F, StoreCache>,
    buf: Aligned,
}

impl<F: NorFlash> RobotStore<F> {
    /// A store over `range` of `flash` (page-aligned, at least two pages of
    /// `F::ERASE_SIZE`, each page large enough for the largest record).
    pub fn new(flash: F, range: Range<u32>) -> Result<Self, RangeError> {
        // Page states (2 words) + item header (padded) + the largest item.
        if F::ERASE_SIZE < BUF_LEN + 64 {
            return Err(RangeError);
        }
        if ((range.end.saturating_sub(range.start)) as usize) / F::ERASE_SIZE > MAX_PAGES {
            return Err(RangeError);
        }
        let cfg = MapConfig::<F>::try_new(range).map_err(|_| RangeError)?;
        Ok(Self {
            map: MapStorage::new(
                flash,
                cfg,
                Cache::new(
                    ArrayPageStates::new(),
                    ArrayPagePointers::new(),
                    ArrayKeyPointers::new(),
                ),
            ),
            buf: Aligned([0; BUF_LEN]),
        })
    }

    /// The flash back (e.g. to keep the simulated flash over a reset).
    pub fn into_flash(self) -> F {
        self.map.destroy().0
    }

    /// Reads the newest complete record into `out`, checks its format and
    /// the blob with `validate`; returns its length, or why the default
    /// must be used.
    pub async fn load(
        &mut self,
        validate: RobotValidator,
        out: &mut [u8; ROBOT_BLOB_MAX],
    ) -> Result<usize, LoadFault> {
        let value = match self
            .map
            .fetch_item::<&[u8]>(&mut self.buf.0, &RECORD_KEY)
            .await
        {
            Ok(Some(v)) => v,
            Ok(None) => return Err(LoadFault::Missing),
            Err(_) => return Err(LoadFault::Flash),
        };
        let blob = match value.split_first() {
            Some((&RECORD_FORMAT, blob)) if !blob.is_empty() && blob.len() <= ROBOT_BLOB_MAX => {
                blob
            }
            _ => return Err(LoadFault::Format),
        };
        validate(blob).map_err(LoadFault::Invalid)?;
        out[..blob.len()].copy_from_slice(blob);
        Ok(blob.len())
    }

    /// Validates `blob` as a whole, then stores it as the new record and
    /// reads it back. The previous record stays the one [`Self::load`]
    /// returns until the new item is complete (power loss at any point
    /// leaves one of the two). May erase a flash page (seconds on an F4:
    /// the caller keeps the motors off and the watchdog long).
    pub async fn save(&mut self, validate: RobotValidator, blob: &[u8]) -> Result<(), StoreError> {
        if blob.is_empty() || blob.len() > ROBOT_BLOB_MAX {
            return Err(StoreError::Length);
        }
        validate(blob).map_err(StoreError::Invalid)?;
        let mut value = [0u8; 1 + ROBOT_BLOB_MAX];
        value[0] = RECORD_FORMAT;
        value[1..=blob.len()].copy_from_slice(blob);
        let value = &value[..=blob.len()];
        self.map
            .store_item(&mut self.buf.0, &RECORD_KEY, &value)
            .await
            .map_err(|_| StoreError::Flash)?;
        match self
            .map
            .fetch_item::<&[u8]>(&mut self.buf.0, &RECORD_KEY)
            .await
        {
            Ok(Some(back)) if back == value => Ok(()),
            _ => Err(StoreError::ReadBack),
        }
    }
}

/// robot-file's largest record fits the link's and the store's buffers.
const _: () = assert!(robot_file::MAX_ENCODED_LEN <= ROBOT_BLOB_MAX);
