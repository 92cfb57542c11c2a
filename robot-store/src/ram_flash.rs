//! [`RamFlash`]: NOR flash in RAM for the simulated device (`hil-sim
//! device`), which keeps it across a simulated reset.

use embedded_storage_async::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// `SIZE` bytes of NOR flash in pages of `PAGE` bytes, 4-byte words: erase
/// sets a page to 0xFF, a write can only clear bits (the new byte is ANDed
/// in, as on real NOR flash), and an optional power cut stops the flash
/// after a number of byte operations (the simulated device's "pull the
/// plug during a write"). Erases are counted per page (wear).
#[derive(Clone)]
pub struct RamFlash<const SIZE: usize, const PAGE: usize> {
    data: [u8; SIZE],
    /// Byte operations (bytes erased or written) left before the power cut;
    /// `None`: no cut.
    pub cut_after: Option<u32>,
    erases: [u32; 64],
}

/// A refused [`RamFlash`] operation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RamFlashError {
    /// Outside the flash or not aligned.
    Bounds,
    /// The power was cut ([`RamFlash::cut_after`] ran out).
    PowerCut,
}

impl NorFlashError for RamFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            Self::Bounds => NorFlashErrorKind::OutOfBounds,
            Self::PowerCut => NorFlashErrorKind::Other,
        }
    }
}

impl<const SIZE: usize, const PAGE: usize> Default for RamFlash<SIZE, PAGE> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const SIZE: usize, const PAGE: usize> RamFlash<SIZE, PAGE> {
    /// Erased flash (every byte 0xFF). At most 64 pages.
    pub const fn new() -> Self {
        assert!(SIZE.is_multiple_of(PAGE) && SIZE / PAGE <= 64 && PAGE.is_multiple_of(4));
        Self {
            data: [0xFF; SIZE],
            cut_after: None,
            erases: [0; 64],
        }
    }

    /// The raw bytes (tests corrupt them).
    pub fn bytes_mut(&mut self) -> &mut [u8; SIZE] {
        &mut self.data
    }

    /// Erases of each page so far.
    pub fn erases(&self) -> &[u32] {
        &self.erases[..SIZE / PAGE]
    }

    fn tick(&mut self) -> Result<(), RamFlashError> {
        match self.cut_after.as_mut() {
            Some(0) => Err(RamFlashError::PowerCut),
            Some(n) => {
                *n -= 1;
                Ok(())
            }
            None => Ok(()),
        }
    }

    fn check(offset: u32, len: usize, align: usize) -> Result<usize, RamFlashError> {
        let o = offset as usize;
        if !o.is_multiple_of(align)
            || !len.is_multiple_of(align)
            || o.checked_add(len).is_none_or(|e| e > SIZE)
        {
            return Err(RamFlashError::Bounds);
        }
        Ok(o)
    }
}

impl<const SIZE: usize, const PAGE: usize> ErrorType for RamFlash<SIZE, PAGE> {
    type Error = RamFlashError;
}

impl<const SIZE: usize, const PAGE: usize> ReadNorFlash for RamFlash<SIZE, PAGE> {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let o = Self::check(offset, bytes.len(), 1)?;
        bytes.copy_from_slice(&self.data[o..o + bytes.len()]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        SIZE
    }
}

impl<const SIZE: usize, const PAGE: usize> NorFlash for RamFlash<SIZE, PAGE> {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = PAGE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if from > to {
            return Err(RamFlashError::Bounds);
        }
        let o = Self::check(from, (to - from) as usize, PAGE)?;
        for page in o / PAGE..to as usize / PAGE {
            self.erases[page] += 1;
            for i in page * PAGE..(page + 1) * PAGE {
                self.tick()?;
                self.data[i] = 0xFF;
            }
        }
        Ok(())
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let o = Self::check(offset, bytes.len(), 4)?;
        for (i, b) in bytes.iter().enumerate() {
            self.tick()?;
            self.data[o + i] &= *b;
        }
        Ok(())
    }
}
