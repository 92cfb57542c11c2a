//! The robot record on the link (protocol 4): the staged upload
//! ([`wmr_protocol::Request::RobotBegin`] / `RobotChunk`), its validation as
//! a whole on commit, the write the board performs afterwards, and the
//! stored record the host reads back.
//!
//! The device never touches flash: a validated commit becomes a *pending
//! write* ([`RobotRecord::pending_write`]) that the board's application
//! performs outside the control tick, in hold with the motors off, and
//! reports with [`RobotRecord::write_done`]; only then is the commit
//! answered. Nothing is stored before the whole record has arrived and
//! passed the board's validator (robot-file's decode and validation).

pub use wmr_protocol::RobotValidator;
use wmr_protocol::{ErrorCode, RobotFault, RobotReport, RobotSource, ROBOT_BLOB_MAX, ROBOT_CHUNK};

/// The record's own CRC-32: its last four bytes, little-endian (robot-file's
/// binary form ends with the CRC-32 of everything before it); 0 when shorter.
pub fn record_crc32(record: &[u8]) -> u32 {
    match record.len().checked_sub(4) {
        Some(i) => u32::from_le_bytes([record[i], record[i + 1], record[i + 2], record[i + 3]]),
        None => 0,
    }
}

/// The stored record, the upload in progress and the pending write.
pub struct RobotRecord {
    validate: Option<RobotValidator>,
    stored: [u8; ROBOT_BLOB_MAX],
    stored_len: usize,
    staging: [u8; ROBOT_BLOB_MAX],
    staged_len: usize,
    expected_len: Option<usize>,
    pending: Option<u16>,
    reboot: bool,
    report: RobotReport,
}

impl Default for RobotRecord {
    fn default() -> Self {
        Self::new()
    }
}

impl RobotRecord {
    /// No store: every robot request is refused with
    /// [`ErrorCode::NoStore`].
    pub const fn new() -> Self {
        Self {
            validate: None,
            stored: [0; ROBOT_BLOB_MAX],
            stored_len: 0,
            staging: [0; ROBOT_BLOB_MAX],
            staged_len: 0,
            expected_len: None,
            pending: None,
            reboot: false,
            report: RobotReport {
                source: RobotSource::Builtin,
                active_crc32: 0,
                stored_crc32: 0,
                writes: 0,
                write_failures: 0,
            },
        }
    }

    /// Attaches the board's store: `record` is the record in force (the
    /// flash one, or the default's encoding) and where it came from;
    /// `validate` checks uploads. A record longer than
    /// [`ROBOT_BLOB_MAX`] is cut (it cannot come from a valid store).
    pub fn attach(&mut self, validate: RobotValidator, record: &[u8], source: RobotSource) {
        let n = record.len().min(ROBOT_BLOB_MAX);
        self.validate = Some(validate);
        self.stored[..n].copy_from_slice(&record[..n]);
        self.stored_len = n;
        self.report.source = source;
        self.report.active_crc32 = record_crc32(&record[..n]);
        self.report.stored_crc32 = match source {
            RobotSource::Flash => self.report.active_crc32,
            _ => 0,
        };
    }

    /// The status report.
    pub fn report(&self) -> RobotReport {
        self.report
    }

    /// True while a validated record waits for its flash write.
    pub fn write_pending(&self) -> bool {
        self.pending.is_some()
    }

    /// The validated record to write, if a commit was accepted.
    pub fn pending_write(&self) -> Option<&[u8]> {
        self.pending.map(|_| &self.staging[..self.staged_len])
    }

    /// The host asked for a restart (acknowledged).
    pub fn reboot_requested(&self) -> bool {
        self.reboot
    }

    fn store(&self) -> Result<RobotValidator, ErrorCode> {
        self.validate.ok_or(ErrorCode::NoStore)
    }

    /// `RobotBegin` (the caller checked the run state).
    pub fn begin(&mut self, total_len: u16) -> Result<(), ErrorCode> {
        self.store()?;
        if self.pending.is_some() {
            return Err(ErrorCode::Busy);
        }
        let n = total_len as usize;
        if n == 0 || n > ROBOT_BLOB_MAX {
            return Err(ErrorCode::InvalidValue);
        }
        self.expected_len = Some(n);
        self.staged_len = 0;
        Ok(())
    }

    /// `RobotChunk`: in order, within the declared length; the last chunk
    /// again with the same bytes (a retry) is accepted again unchanged.
    pub fn chunk(&mut self, offset: u16, data: &[u8]) -> Result<(), ErrorCode> {
        self.store()?;
        if self.pending.is_some() {
            return Err(ErrorCode::Busy);
        }
        let expected = self.expected_len.ok_or(ErrorCode::OutOfOrder)?;
        let (o, n) = (offset as usize, data.len());
        // The last chunk again, byte for byte (a retry after its lost
        // acknowledgement: the host sends one chunk at a time, issue 31
        // item 5): acknowledged again, no change.
        if n > 0 && o + n == self.staged_len && self.staging[o..o + n] == *data {
            return Ok(());
        }
        if o != self.staged_len {
            return Err(ErrorCode::OutOfOrder);
        }
        let end = self.staged_len + data.len();
        if end > expected {
            return Err(ErrorCode::InvalidValue);
        }
        self.staging[self.staged_len..end].copy_from_slice(data);
        self.staged_len = end;
        Ok(())
    }

    /// `RobotCommit` (the caller checked hold): `Ok(None)` when the record
    /// is valid and its write is now pending (answered by
    /// [`Self::write_done`]), `Ok(Some(fault))` when the validator refused
    /// it (the upload is dropped, nothing stored).
    pub fn commit(&mut self, seq: u16) -> Result<Option<RobotFault>, ErrorCode> {
        let validate = self.store()?;
        if self.pending.is_some() {
            return Err(ErrorCode::Busy);
        }
        match self.expected_len {
            Some(n) if n == self.staged_len => {}
            _ => return Err(ErrorCode::UploadIncomplete),
        }
        self.expected_len = None;
        match validate(&self.staging[..self.staged_len]) {
            Ok(()) => {
                self.pending = Some(seq);
                Ok(None)
            }
            Err(fault) => {
                self.staged_len = 0;
                Ok(Some(fault))
            }
        }
    }

    /// The board finished the pending write (`ok`: stored and read back
    /// equal); returns the commit's sequence number and its answer, `None`
    /// when no write was pending. On success the staged record becomes the
    /// stored one (it takes effect at the next boot).
    pub fn write_done(&mut self, ok: bool) -> Option<(u16, Result<(), ErrorCode>)> {
        let seq = self.pending.take()?;
        if ok {
            let n = self.staged_len;
            self.stored[..n].copy_from_slice(&self.staging[..n]);
            self.stored_len = n;
            self.report.stored_crc32 = record_crc32(&self.stored[..n]);
            self.report.writes = self.report.writes.saturating_add(1);
            Some((seq, Ok(())))
        } else {
            self.report.write_failures = self.report.write_failures.saturating_add(1);
            Some((seq, Err(ErrorCode::StoreFailed)))
        }
    }

    /// `RobotRead`: up to [`ROBOT_CHUNK`] bytes of the stored record from
    /// `offset`; returns (total length, chunk).
    pub fn read(&self, offset: u16) -> Result<(u16, &[u8]), ErrorCode> {
        self.store()?;
        let o = offset as usize;
        if o > self.stored_len {
            return Err(ErrorCode::InvalidValue);
        }
        let end = (o + ROBOT_CHUNK).min(self.stored_len);
        Ok((self.stored_len as u16, &self.stored[o..end]))
    }

    /// `Reboot` (the caller checked hold).
    pub fn request_reboot(&mut self) -> Result<(), ErrorCode> {
        if self.pending.is_some() {
            return Err(ErrorCode::Busy);
        }
        self.reboot = true;
        Ok(())
    }
}
