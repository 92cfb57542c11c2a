//! CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final
//! XOR): the frame check of every envelope. Table-free, bitwise: a frame of
//! at most [`MAX_BODY`](crate::MAX_BODY) bytes costs a few thousand cycles.

/// The CRC-16/CCITT-FALSE of `bytes` continuing from `crc` (start with
/// [`CRC_INIT`]).
pub const fn crc16_update(mut crc: u16, bytes: &[u8]) -> u16 {
    let mut i = 0;
    while i < bytes.len() {
        crc ^= (bytes[i] as u16) << 8;
        let mut b = 0;
        while b < 8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
            b += 1;
        }
        i += 1;
    }
    crc
}

/// Initial value of CRC-16/CCITT-FALSE.
pub const CRC_INIT: u16 = 0xFFFF;

/// CRC-16/CCITT-FALSE of `bytes`.
pub const fn crc16(bytes: &[u8]) -> u16 {
    crc16_update(CRC_INIT, bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The catalogue check value of CRC-16/CCITT-FALSE: CRC of "123456789"
    /// is 0x29B1 (Greg Cook's CRC catalogue, "CRC-16/IBM-3740").
    #[test]
    fn check_value() {
        assert_eq!(crc16(b"123456789"), 0x29B1);
        assert_eq!(crc16(b""), 0xFFFF);
    }

    #[test]
    fn incremental_equals_whole() {
        let data = b"differential drive robot";
        let (a, b) = data.split_at(7);
        assert_eq!(crc16_update(crc16(a), b), crc16(data));
    }

    /// Every single-bit error in a 64-byte message changes the CRC (a CRC
    /// with more than one term detects all single-bit errors).
    #[test]
    fn detects_every_single_bit_flip() {
        let mut data = [0u8; 64];
        for (i, d) in data.iter_mut().enumerate() {
            *d = (i * 37 + 11) as u8;
        }
        let good = crc16(&data);
        for byte in 0..data.len() {
            for bit in 0..8 {
                data[byte] ^= 1 << bit;
                assert_ne!(crc16(&data), good);
                data[byte] ^= 1 << bit;
            }
        }
    }
}
