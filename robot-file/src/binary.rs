//! The binary form for the robot's flash and the link:
//!
//! | bytes | content                                   |
//! |-------|-------------------------------------------|
//! | 0..4  | [`MAGIC`] `b"WMRB"`                        |
//! | 4..6  | binary version, u16 little-endian ([`BINARY_VERSION`]) |
//! | 6..8  | payload length n, u16 little-endian        |
//! | 8..8+n | payload: the [`Robot`] by postcard        |
//! | 8+n..12+n | CRC-32 (ISO-HDLC, the zlib/Ethernet one) of bytes 0..8+n, little-endian |
//!
//! [`Robot::decode`] checks all of it and then validates the robot.

use crate::error::RobotError;
use crate::sections::Robot;

/// Version of the binary form this build reads and writes: 2 since the
/// `[control]` section (D139; version 1 had none, and a record of it is
/// refused as [`DecodeError::UnsupportedFormat`], so a board falls back to
/// its compiled-in robot until the robot is pushed again).
pub const BINARY_VERSION: u16 = 2;

/// First four bytes of the binary form.
pub const MAGIC: [u8; 4] = *b"WMRB";
/// Header length \[bytes\] (magic, version, payload length).
pub const HEADER_LEN: usize = 8;
/// CRC length \[bytes\].
const CRC_LEN: usize = 4;
/// Longest binary form \[bytes\]: header, the largest payload (every gain
/// section present, longest name, every varint at its widest) and the CRC,
/// rounded up (a test checks the worst case fits).
pub const MAX_ENCODED_LEN: usize = 512;

const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// [`Robot::encode`] failed.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum EncodeError {
    /// The buffer is shorter than the encoded robot (use [`MAX_ENCODED_LEN`]).
    BufferTooSmall,
}

/// [`Robot::decode`] refused the bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum DecodeError {
    /// Fewer bytes than the header and CRC, or than the header says.
    Truncated,
    /// The first four bytes are not [`MAGIC`].
    BadMagic,
    /// Another format version than this build reads.
    UnsupportedFormat {
        /// The version found.
        found: u16,
    },
    /// Payload length above [`MAX_ENCODED_LEN`], or bytes after the CRC.
    BadLength,
    /// The CRC does not match: corrupted.
    BadCrc,
    /// The payload is not a robot (postcard refused it, or left bytes over).
    Malformed,
    /// A well-formed robot that [`Robot::validate`] refuses.
    Invalid(RobotError),
}

impl core::fmt::Display for EncodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::BufferTooSmall => write!(f, "buffer too small for the robot's binary form"),
        }
    }
}

impl core::fmt::Display for DecodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Truncated => write!(f, "truncated robot record"),
            Self::BadMagic => write!(f, "not a robot record (bad magic)"),
            Self::UnsupportedFormat { found } => {
                write!(f, "robot record format {found}, this build reads {BINARY_VERSION} (push the robot file again: `wmr robot push FILE`)")
            }
            Self::BadLength => write!(f, "robot record length inconsistent"),
            Self::BadCrc => write!(f, "robot record CRC mismatch (corrupted)"),
            Self::Malformed => write!(f, "robot record payload malformed"),
            Self::Invalid(e) => write!(f, "robot record invalid: {e}"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for EncodeError {}
#[cfg(feature = "std")]
impl std::error::Error for DecodeError {}

impl Robot {
    /// Writes the binary form into `buf`, returns its length.
    pub fn encode(&self, buf: &mut [u8]) -> Result<usize, EncodeError> {
        if buf.len() < HEADER_LEN + CRC_LEN {
            return Err(EncodeError::BufferTooSmall);
        }
        let end = buf.len() - CRC_LEN;
        let n = postcard::to_slice(self, &mut buf[HEADER_LEN..end])
            .map_err(|_| EncodeError::BufferTooSmall)?
            .len();
        if HEADER_LEN + n + CRC_LEN > MAX_ENCODED_LEN {
            return Err(EncodeError::BufferTooSmall);
        }
        buf[0..4].copy_from_slice(&MAGIC);
        buf[4..6].copy_from_slice(&BINARY_VERSION.to_le_bytes());
        buf[6..8].copy_from_slice(&(n as u16).to_le_bytes());
        let body = HEADER_LEN + n;
        let crc = CRC32.checksum(&buf[..body]);
        buf[body..body + CRC_LEN].copy_from_slice(&crc.to_le_bytes());
        Ok(body + CRC_LEN)
    }

    /// Reads a binary form written by [`Robot::encode`]: exactly one record
    /// (no bytes after its CRC), then [`Robot::validate`]s it.
    pub fn decode(bytes: &[u8]) -> Result<Robot, DecodeError> {
        if bytes.len() < HEADER_LEN + CRC_LEN {
            return Err(DecodeError::Truncated);
        }
        if bytes[0..4] != MAGIC {
            return Err(DecodeError::BadMagic);
        }
        let version = u16::from_le_bytes([bytes[4], bytes[5]]);
        let n = u16::from_le_bytes([bytes[6], bytes[7]]) as usize;
        if HEADER_LEN + n + CRC_LEN > MAX_ENCODED_LEN {
            return Err(DecodeError::BadLength);
        }
        let body = HEADER_LEN + n;
        if bytes.len() < body + CRC_LEN {
            return Err(DecodeError::Truncated);
        }
        if bytes.len() > body + CRC_LEN {
            return Err(DecodeError::BadLength);
        }
        let crc = u32::from_le_bytes([
            bytes[body],
            bytes[body + 1],
            bytes[body + 2],
            bytes[body + 3],
        ]);
        if CRC32.checksum(&bytes[..body]) != crc {
            return Err(DecodeError::BadCrc);
        }
        // Checked after the CRC: a corrupted version byte is a corruption.
        if version != BINARY_VERSION {
            return Err(DecodeError::UnsupportedFormat { found: version });
        }
        let (robot, rest): (Robot, _) = postcard::take_from_bytes(&bytes[HEADER_LEN..body])
            .map_err(|_| DecodeError::Malformed)?;
        if !rest.is_empty() {
            return Err(DecodeError::Malformed);
        }
        robot.validate().map_err(DecodeError::Invalid)?;
        Ok(robot)
    }
}
