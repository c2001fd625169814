//! CRC-16/MODBUS (polynomial 0xA001 reflected, initial value 0xFFFF), sent low byte first.

/// The CRC of `data`.
pub fn crc16(data: &[u8]) -> u16 {
    let mut crc: u16 = 0xFFFF;
    for &b in data {
        crc ^= u16::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xA001
            } else {
                crc >> 1
            };
        }
    }
    crc
}

/// Append the CRC of `frame` (low byte first, as Modbus RTU sends it).
pub fn append_crc(frame: &mut Vec<u8>) {
    let c = crc16(frame);
    frame.extend_from_slice(&c.to_le_bytes());
}

/// Whether the last two bytes of `adu` are the CRC of the rest.
pub fn crc_ok(adu: &[u8]) -> bool {
    match adu.len().checked_sub(2) {
        Some(n) if n > 0 => crc16(&adu[..n]).to_le_bytes() == [adu[n], adu[n + 1]],
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_frames() {
        // Read holding registers 0x006B..0x006D from slave 0x11 (the Modbus spec's example):
        // CRC 0x8776 sent as 76 87.
        let f = [0x11, 0x03, 0x00, 0x6B, 0x00, 0x03];
        assert_eq!(crc16(&f), 0x8776);
        // Robotiq manual example: read 3 input registers at 0x07D0 from slave 9 -> CRC bytes B1 CE.
        let mut r = vec![0x09, 0x04, 0x07, 0xD0, 0x00, 0x03];
        append_crc(&mut r);
        assert_eq!(&r[6..], &[0xB1, 0xCE]);
        assert!(crc_ok(&r));
        r[3] ^= 1;
        assert!(!crc_ok(&r));
        assert!(!crc_ok(&[0x01, 0x02]));
    }
}
