//! The Dynamixel Protocol 2.0 packet format, written from the ROBOTIS specification
//! independently of the `dynamixel2` crate: the emulator speaks it, and the tests check each
//! implementation against the other and both against the specification's example packets.
//!
//! ```text
//! instruction: FF FF FD 00 | id | len_lo len_hi | instruction | params… | crc_lo crc_hi
//! status:      FF FF FD 00 | id | len_lo len_hi | 0x55 | error | params… | crc_lo crc_hi
//! ```
//!
//! `len` counts the bytes after it (instruction, error, stuffed parameters, CRC). Between the
//! instruction byte and the CRC, every `FF FF FD` is followed by an extra `FD` ("byte
//! stuffing"), so that the header never appears inside a packet. The CRC covers everything
//! from the header to the last parameter, as sent (stuffed).

/// The four bytes every packet starts with.
pub(crate) const HEADER: [u8; 4] = [0xFF, 0xFF, 0xFD, 0x00];

/// Instruction byte of status packets.
pub(crate) const STATUS: u8 = 0x55;

/// Instruction bytes the emulator understands.
pub(crate) mod instruction {
    /// Ping: answers model number and firmware version.
    pub(crate) const PING: u8 = 0x01;
    /// Read `length` bytes from `address`.
    pub(crate) const READ: u8 = 0x02;
    /// Write bytes to `address`.
    pub(crate) const WRITE: u8 = 0x03;
    /// Reboot the servo.
    pub(crate) const REBOOT: u8 = 0x08;
}

/// Status error numbers (low 7 bits of the error byte of a status packet).
pub(crate) mod status_error {
    /// The instruction could not be executed.
    pub(crate) const RESULT_FAIL: u8 = 1;
    /// Undefined instruction, or an instruction the servo cannot take now.
    pub(crate) const INSTRUCTION: u8 = 2;
    /// The CRC of the instruction packet did not match.
    pub(crate) const CRC: u8 = 3;
    /// The value to write is out of range.
    pub(crate) const DATA_RANGE: u8 = 4;
    /// The packet is shorter than the instruction needs.
    pub(crate) const DATA_LENGTH: u8 = 5;
    /// The value to write exceeds a limit.
    pub(crate) const DATA_LIMIT: u8 = 6;
    /// Read-only address, undefined address, or EEPROM written with the torque on.
    pub(crate) const ACCESS: u8 = 7;
    /// Bit 7: the servo has a hardware error (see Hardware Error Status).
    pub(crate) const ALERT: u8 = 0x80;
}

/// Longest packet the emulator accepts (a read of the whole table fits many times over); a
/// longer declared length is garbage.
pub(crate) const MAX_PACKET_LEN: usize = 1024;

/// CRC-16 polynomial of Protocol 2.0 (x¹⁶ + x¹⁵ + x² + 1), MSB first, initial value 0,
/// no reflection and no final XOR (the "CRC-16/BUYPASS" parameters).
const CRC_POLYNOMIAL: u16 = 0x8005;

/// The Protocol 2.0 CRC-16 of `bytes` (header through last parameter, as sent).
///
/// ```
/// // The specification's ping to id 1: FF FF FD 00 01 03 00 01, CRC 0x4E19 (sent 19 4E).
/// let crc = sl_rig::dynamixel_crc16(&[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01]);
/// assert_eq!(crc, 0x4E19);
/// ```
pub fn dynamixel_crc16(bytes: &[u8]) -> u16 {
    let mut crc: u16 = 0;
    for &byte in bytes {
        crc ^= u16::from(byte) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ CRC_POLYNOMIAL
            } else {
                crc << 1
            };
        }
    }
    crc
}

/// Adds the stuffing byte after every `FF FF FD`.
pub(crate) fn stuff(body: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(body.len() + body.len() / 3);
    for &b in body {
        out.push(b);
        if out.ends_with(&[0xFF, 0xFF, 0xFD]) {
            out.push(0xFD);
        }
    }
    out
}

/// Removes the stuffing byte after every `FF FF FD`.
pub(crate) fn unstuff(body: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(body.len());
    let mut i = 0;
    while let Some(&b) = body.get(i) {
        out.push(b);
        i += 1;
        if out.ends_with(&[0xFF, 0xFF, 0xFD]) && body.get(i) == Some(&0xFD) {
            i += 1;
        }
    }
    out
}

/// A whole packet: header, `id`, length, `first` (the instruction, or `0x55` and the error
/// byte of a status), stuffed `params`, CRC.
fn packet(id: u8, first: &[u8], params: &[u8]) -> Vec<u8> {
    let mut body = first.to_vec();
    body.extend_from_slice(params);
    let body = stuff(&body);
    // Bodies are at most a few hundred bytes here; the length field is 16 bits.
    let len = u16::try_from(body.len() + 2).unwrap_or(u16::MAX);
    let mut out = HEADER.to_vec();
    out.push(id);
    out.extend_from_slice(&len.to_le_bytes());
    out.extend_from_slice(&body);
    let crc = dynamixel_crc16(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// An instruction packet as a controller sends it.
#[cfg(test)]
pub(crate) fn instruction_packet(id: u8, instruction: u8, params: &[u8]) -> Vec<u8> {
    packet(id, &[instruction], params)
}

/// A status packet as a servo sends it.
pub(crate) fn status_packet(id: u8, error: u8, params: &[u8]) -> Vec<u8> {
    packet(id, &[STATUS, error], params)
}

/// What [`take_packet`] found at the front of a receive buffer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Received {
    /// A packet with a valid CRC.
    Packet {
        /// Packet id.
        id: u8,
        /// Instruction byte.
        instruction: u8,
        /// Parameters, unstuffed.
        params: Vec<u8>,
    },
    /// A complete packet whose CRC does not match.
    BadCrc {
        /// Packet id (as received).
        id: u8,
    },
}

/// Takes the first complete packet out of `buf`, dropping any garbage before it. Returns
/// `None` (and keeps the partial packet) when no complete packet is there yet.
pub(crate) fn take_packet(buf: &mut Vec<u8>) -> Option<Received> {
    loop {
        let start = find_header(buf);
        buf.drain(..start);
        let (Some(&id), Some(&lo), Some(&hi)) = (buf.get(4), buf.get(5), buf.get(6)) else {
            return None;
        };
        let len = usize::from(u16::from_le_bytes([lo, hi]));
        let total = 7 + len;
        if !(3..=MAX_PACKET_LEN).contains(&len) {
            // Not a packet after all: skip this header and look further.
            buf.drain(..1);
            continue;
        }
        if buf.len() < total {
            return None;
        }
        let packet: Vec<u8> = buf.drain(..total).collect();
        let (content, crc_bytes) = packet.split_at(total - 2);
        let crc = u16::from_le_bytes([crc_bytes[0], crc_bytes[1]]);
        if crc != dynamixel_crc16(content) {
            return Some(Received::BadCrc { id });
        }
        let body = unstuff(&content[7..]);
        let (&instruction, params) = body.split_first()?;
        return Some(Received::Packet {
            id,
            instruction,
            params: params.to_vec(),
        });
    }
}

/// Index of the first possible header in `buf` (a partial header at the end counts), or
/// `buf.len()`.
fn find_header(buf: &[u8]) -> usize {
    (0..buf.len())
        .find(|&i| {
            let rest = &buf[i..];
            let n = rest.len().min(HEADER.len());
            rest[..n] == HEADER[..n]
        })
        .unwrap_or(buf.len())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The example packets of the ROBOTIS Protocol 2.0 specification (e-Manual, "Protocol
    /// 2.0", sections Ping, Read, Write, Reboot and Status Packet), byte for byte.
    pub(super) const SPEC_EXAMPLES: &[(&str, &[u8])] = &[
        (
            "ping id 1",
            &[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4E],
        ),
        (
            "broadcast ping",
            &[0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x03, 0x00, 0x01, 0x31, 0x42],
        ),
        (
            "ping status: model 1030, firmware 38",
            &[
                0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x55, 0x00, 0x06, 0x04, 0x26, 0x65, 0x5D,
            ],
        ),
        (
            "read present position (132, 4 bytes)",
            &[
                0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x02, 0x84, 0x00, 0x04, 0x00, 0x1D, 0x15,
            ],
        ),
        (
            "write goal position (116) = 512",
            &[
                0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x09, 0x00, 0x03, 0x74, 0x00, 0x00, 0x02, 0x00, 0x00,
                0xCA, 0x89,
            ],
        ),
        (
            "reboot id 1",
            &[0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x08, 0x2F, 0x4E],
        ),
        (
            "empty status",
            &[
                0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x04, 0x00, 0x55, 0x00, 0xA1, 0x0C,
            ],
        ),
    ];

    #[test]
    fn crc_matches_the_specification_examples() {
        for (name, bytes) in SPEC_EXAMPLES {
            let (content, crc) = bytes.split_at(bytes.len() - 2);
            let expected = u16::from_le_bytes([crc[0], crc[1]]);
            assert_eq!(dynamixel_crc16(content), expected, "{name}");
            // The library the driver uses agrees.
            assert_eq!(
                dynamixel2::checksum::calculate_checksum(0, content),
                expected,
                "{name}"
            );
        }
    }

    #[test]
    fn packets_are_encoded_as_in_the_specification() {
        let ex = |i: usize| SPEC_EXAMPLES[i].1.to_vec();
        assert_eq!(instruction_packet(1, instruction::PING, &[]), ex(0));
        assert_eq!(instruction_packet(0xFE, instruction::PING, &[]), ex(1));
        assert_eq!(status_packet(1, 0, &[0x06, 0x04, 0x26]), ex(2));
        assert_eq!(
            instruction_packet(1, instruction::READ, &[0x84, 0x00, 0x04, 0x00]),
            ex(3)
        );
        let mut write = vec![116, 0];
        write.extend_from_slice(&512u32.to_le_bytes());
        assert_eq!(instruction_packet(1, instruction::WRITE, &write), ex(4));
        assert_eq!(instruction_packet(1, instruction::REBOOT, &[]), ex(5));
        assert_eq!(status_packet(1, 0, &[]), ex(6));
    }

    #[test]
    fn stuffing_follows_the_specification() {
        // The specification's rule: FF FF FD in the body gains an FD.
        assert_eq!(
            stuff(&[0xFF, 0xFF, 0xFD, 0x00]),
            [0xFF, 0xFF, 0xFD, 0xFD, 0x00]
        );
        assert_eq!(stuff(&[0xFF, 0xFF, 0x01, 0xFD]), [0xFF, 0xFF, 0x01, 0xFD]);
        assert_eq!(
            stuff(&[0xFF, 0xFF, 0xFD, 0xFF, 0xFF, 0xFD]),
            [0xFF, 0xFF, 0xFD, 0xFD, 0xFF, 0xFF, 0xFD, 0xFD]
        );
    }

    #[test]
    fn garbage_and_partial_packets() {
        let mut buf = vec![0x00, 0x13, 0xFF];
        buf.extend_from_slice(SPEC_EXAMPLES[0].1);
        let whole = buf.len();
        buf.truncate(whole - 1);
        assert_eq!(take_packet(&mut buf), None);
        buf.push(0x4E);
        assert_eq!(
            take_packet(&mut buf),
            Some(Received::Packet {
                id: 1,
                instruction: instruction::PING,
                params: vec![]
            })
        );
        assert!(buf.is_empty());
        let mut bad = SPEC_EXAMPLES[5].1.to_vec();
        bad[8] ^= 1;
        assert_eq!(take_packet(&mut bad), Some(Received::BadCrc { id: 1 }));
    }

    proptest! {
        #[test]
        fn crc_agrees_with_dynamixel2(data in proptest::collection::vec(any::<u8>(), 0..300)) {
            // Two independent implementations (bitwise here, table-driven there).
            prop_assert_eq!(
                dynamixel_crc16(&data),
                dynamixel2::checksum::calculate_checksum(0, &data)
            );
        }

        #[test]
        fn packets_round_trip(
            id in 0u8..=252,
            inst in any::<u8>(),
            params in proptest::collection::vec(prop_oneof![Just(0xFFu8), Just(0xFD), any::<u8>()], 0..64),
        ) {
            let mut buf = instruction_packet(id, inst, &params);
            prop_assert_eq!(unstuff(&stuff(&params)), params.clone());
            prop_assert_eq!(
                take_packet(&mut buf),
                Some(Received::Packet { id, instruction: inst, params })
            );
        }
    }
}
