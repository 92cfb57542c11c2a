//! The robot record between the device and the flash: the write the control
//! task performs between two ticks ([`RecordWriter`]) and the record the
//! board boots with ([`load_record`]).
//!
//! The robot takes a new record at its next boot (D77): the write stores
//! it while the robot keeps running (in hold) the one it booted with.

use embedded_storage_async::nor_flash::NorFlash;
use robot_store::{LoadFault, RobotStore};
use wmr_protocol::{RobotSource, RobotValidator, ROBOT_BLOB_MAX};

/// Where the control task writes an accepted robot record.
pub trait RecordWriter {
    /// Validates and stores `record`, reads it back; true when stored and
    /// read back equal.
    fn write(&mut self, record: &[u8]) -> impl core::future::Future<Output = bool>;
}

/// No store: every write fails (the device refuses robot requests anyway
/// when no store is attached).
pub struct NoStore;

impl RecordWriter for NoStore {
    async fn write(&mut self, _record: &[u8]) -> bool {
        false
    }
}

/// A [`RobotStore`] with the validator of its records.
pub struct FlashRecord<F: NorFlash> {
    /// The store.
    pub store: RobotStore<F>,
    /// The records' validator (robot-file's decode for the real robot).
    pub validate: RobotValidator,
}

impl<F: NorFlash> RecordWriter for FlashRecord<F> {
    async fn write(&mut self, record: &[u8]) -> bool {
        self.store.save(self.validate, record).await.is_ok()
    }
}

/// The record the robot boots with: the one in flash when it loads and
/// validates, else `default` (the compiled-in robot's encoding); copied
/// into `out`. Returns its length, where it came from and, for a
/// fallback, why.
pub async fn load_record<F: NorFlash>(
    rec: &mut FlashRecord<F>,
    default: &[u8],
    out: &mut [u8; ROBOT_BLOB_MAX],
) -> (usize, RobotSource, Option<LoadFault>) {
    match rec.store.load(rec.validate, out).await {
        Ok(n) => (n, RobotSource::Flash, None),
        Err(fault) => {
            let n = default.len().min(ROBOT_BLOB_MAX);
            out[..n].copy_from_slice(&default[..n]);
            (n, fault.source(), Some(fault))
        }
    }
}
