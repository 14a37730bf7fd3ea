//! LEB128 varints: the one implementation behind column headers and sorted-delta columns
//! ([`super::columns`]).
//!
//! A value is written as 7-bit groups, least significant first, each byte's high bit set when
//! another byte follows; the writer always emits the shortest form. Readers accept exactly the
//! encodings of values of their width (at most 10 bytes for [`read_u64`], no bits beyond the
//! width); longer-than-shortest forms within that length are accepted, as
//! they always were. Reading never panics.

/// Why a varint could not be read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VarintError {
    /// The input ends before the varint's last byte.
    Truncated,
    /// The varint has more bytes or more bits than its type allows.
    Malformed,
}

/// Appends `value` in its shortest form (1 byte below 128, at most 10 bytes). A `u32` written
/// through `u64::from` gives the same bytes as any other width would.
pub fn write(out: &mut Vec<u8>, mut value: u64) {
    while value >= 0x80 {
        out.push((value as u8 & 0x7f) | 0x80);
        value >>= 7;
    }
    out.push(value as u8);
}

/// Reads a varint of at most 64 bits (at most 10 bytes) from the front of `input`, advancing
/// it past the bytes read. On error, `input` is left somewhere within the bad varint.
#[inline]
pub fn read_u64(input: &mut &[u8]) -> Result<u64, VarintError> {
    read(input, 64)
}

/// A varint of at most `bits` bits: the one-byte case inline, longer ones out of line.
#[inline(always)]
fn read(input: &mut &[u8], bits: u32) -> Result<u64, VarintError> {
    match input.split_first() {
        Some((&byte, rest)) if byte < 0x80 => {
            *input = rest;
            Ok(u64::from(byte))
        }
        _ => read_long(input, bits),
    }
}

#[cold]
fn read_long(input: &mut &[u8], bits: u32) -> Result<u64, VarintError> {
    let mut value = 0u64;
    for shift in (0..bits).step_by(7) {
        let (&byte, rest) = input.split_first().ok_or(VarintError::Truncated)?;
        *input = rest;
        let group = u64::from(byte & 0x7f);
        // The last group may only use the bits left below `bits`.
        if (group >> (bits - shift).min(7)) != 0 {
            return Err(VarintError::Malformed);
        }
        value |= group << shift;
        if byte & 0x80 == 0 {
            return Ok(value);
        }
    }
    Err(VarintError::Malformed)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A varint of at most 32 bits: `read`'s width check at a width other than 64.
    fn read_u32(input: &mut &[u8]) -> Result<u32, VarintError> {
        read(input, 32).map(|v| v as u32)
    }

    fn encoded(value: u64) -> Vec<u8> {
        let mut out = Vec::new();
        write(&mut out, value);
        out
    }

    #[test]
    fn shortest_form_round_trips_at_every_length() {
        for value in [
            0,
            1,
            0x7f,
            0x80,
            300,
            0x3fff,
            0x4000,
            u64::from(u32::MAX),
            1 << 35,
            u64::MAX,
        ] {
            let bytes = encoded(value);
            let expected_len = (64 - value.leading_zeros()).div_ceil(7).max(1) as usize;
            assert_eq!(bytes.len(), expected_len, "{value}");
            let mut input = &bytes[..];
            assert_eq!(read_u64(&mut input), Ok(value));
            assert!(input.is_empty());
            let mut input = &bytes[..];
            let as_u32 = read_u32(&mut input);
            match u32::try_from(value) {
                Ok(v) => assert_eq!(as_u32, Ok(v), "{value}"),
                Err(_) => assert_eq!(as_u32, Err(VarintError::Malformed), "{value}"),
            }
        }
        assert_eq!(encoded(300), [0xac, 0x02]);
    }

    #[test]
    fn reads_stop_after_the_varint() {
        let bytes = [0x96, 0x01, 0x05];
        let mut input = &bytes[..];
        assert_eq!(read_u32(&mut input), Ok(150));
        assert_eq!(input, [0x05]);
    }

    #[test]
    fn bad_varints_are_errors() {
        /// Input, then what `read_u32` and `read_u64` return.
        type Case = (
            &'static [u8],
            Result<u32, VarintError>,
            Result<u64, VarintError>,
        );
        let cases: [Case; 7] = [
            (
                &[],
                Err(VarintError::Truncated),
                Err(VarintError::Truncated),
            ),
            (
                &[0x80],
                Err(VarintError::Truncated),
                Err(VarintError::Truncated),
            ),
            // 2^32 needs a fifth group of 0x10: one bit too many for 32 bits.
            (
                &[0x80, 0x80, 0x80, 0x80, 0x10],
                Err(VarintError::Malformed),
                Ok(1 << 32),
            ),
            (
                &[0xff, 0xff, 0xff, 0xff, 0x0f],
                Ok(u32::MAX),
                Ok(u64::from(u32::MAX)),
            ),
            // A sixth byte is too long for 32 bits; a longer-than-shortest 0 is fine for 64.
            (
                &[0x80, 0x80, 0x80, 0x80, 0x80, 0x00],
                Err(VarintError::Malformed),
                Ok(0),
            ),
            // Tenth group above 1: a 65th bit.
            (
                &[0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x02],
                Err(VarintError::Malformed),
                Err(VarintError::Malformed),
            ),
            // Eleven bytes.
            (
                &[
                    0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x00,
                ],
                Err(VarintError::Malformed),
                Err(VarintError::Malformed),
            ),
        ];
        for (bytes, expected_u32, expected_u64) in cases {
            assert_eq!(read_u32(&mut &bytes[..]), expected_u32, "{bytes:x?}");
            assert_eq!(read_u64(&mut &bytes[..]), expected_u64, "{bytes:x?}");
        }
    }
}
