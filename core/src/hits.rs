//! The hit buffer (`--hits FILE`): one record per pixel, row-major from the top-left pixel,
//! each record 8 bytes: little-endian `u32 triangle` then little-endian `f32 t`. A miss is
//! `triangle = u32::MAX`, `t = +inf`.

/// Size of one encoded record in bytes.
pub const HIT_RECORD_BYTES: usize = 8;

/// The nearest hit of one pixel's primary ray (sample 0): the global triangle index in scene
/// order and the ray parameter `t`, or [`Hit::MISS`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Index of the triangle in scene order; `u32::MAX` for a miss.
    pub triangle: u32,
    /// Ray parameter of the hit; `+inf` for a miss.
    pub t: f32,
}

impl Hit {
    /// The record of a pixel whose ray hits nothing: `(u32::MAX, +inf)`.
    pub const MISS: Hit = Hit {
        triangle: u32::MAX,
        t: f32::INFINITY,
    };

    /// True if this record is a miss (`triangle == u32::MAX`).
    pub fn is_miss(&self) -> bool {
        self.triangle == u32::MAX
    }
}

/// Errors from decoding a hit buffer.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum HitsError {
    /// The byte length is not `width * height * 8`.
    #[error(
        "hit buffer for {width}x{height} pixels must be {expected} bytes (8 per pixel), found {found}"
    )]
    Length {
        /// Image width in pixels.
        width: u32,
        /// Image height in pixels.
        height: u32,
        /// Expected length in bytes.
        expected: u128,
        /// Actual length in bytes.
        found: usize,
    },
}

/// Encodes hits in order (the caller passes them row-major from the top-left pixel): 8 bytes
/// per record, LE `u32` triangle then LE `f32` t, bit-exact (the `t` bit pattern is preserved).
pub fn encode_hits(hits: &[Hit]) -> Vec<u8> {
    let mut out = Vec::with_capacity(hits.len() * HIT_RECORD_BYTES);
    for hit in hits {
        out.extend_from_slice(&hit.triangle.to_le_bytes());
        out.extend_from_slice(&hit.t.to_le_bytes());
    }
    out
}

/// Decodes a hit buffer of `width x height` pixels, the exact inverse of [`encode_hits`]
/// (bit-exact `t`). Errors if the length is not exactly `width * height * 8` bytes, saying
/// the expected and the found length.
pub fn decode_hits(bytes: &[u8], width: u32, height: u32) -> Result<Vec<Hit>, HitsError> {
    let expected = u128::from(width) * u128::from(height) * HIT_RECORD_BYTES as u128;
    if bytes.len() as u128 != expected {
        return Err(HitsError::Length {
            width,
            height,
            expected,
            found: bytes.len(),
        });
    }
    Ok(bytes
        .chunks_exact(HIT_RECORD_BYTES)
        .map(|r| Hit {
            triangle: u32::from_le_bytes([r[0], r[1], r[2], r[3]]),
            t: f32::from_le_bytes([r[4], r[5], r[6], r[7]]),
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Vec<Hit> {
        vec![
            Hit {
                triangle: 0,
                t: 1.5,
            },
            Hit::MISS,
            Hit {
                triangle: 0x0102_0304,
                t: f32::from_bits(0x3f80_0001),
            },
            Hit {
                triangle: 7,
                t: -0.0,
            },
            Hit {
                triangle: 8,
                t: f32::from_bits(0x7fc0_beef),
            },
            Hit {
                triangle: u32::MAX - 1,
                t: f32::MIN_POSITIVE / 4.0,
            },
        ]
    }

    #[test]
    fn miss_record() {
        assert!(Hit::MISS.is_miss());
        assert_eq!(Hit::MISS.triangle, u32::MAX);
        assert_eq!(Hit::MISS.t, f32::INFINITY);
        assert!(
            !Hit {
                triangle: 3,
                t: f32::INFINITY
            }
            .is_miss()
        );
        assert_eq!(
            encode_hits(&[Hit::MISS]),
            [0xff, 0xff, 0xff, 0xff, 0x00, 0x00, 0x80, 0x7f]
        );
    }

    #[test]
    fn layout_is_little_endian() {
        let bytes = encode_hits(&[Hit {
            triangle: 0x0102_0304,
            t: 1.0,
        }]);
        assert_eq!(bytes, [4, 3, 2, 1, 0x00, 0x00, 0x80, 0x3f]);
    }

    /// `sample()` encoded by hand: LE u32 triangle, then the LE bits of t.
    #[rustfmt::skip]
    const SAMPLE_BYTES: [u8; 48] = [
        0x00, 0x00, 0x00, 0x00,  0x00, 0x00, 0xc0, 0x3f, // 0, 1.5 = 0x3fc00000
        0xff, 0xff, 0xff, 0xff,  0x00, 0x00, 0x80, 0x7f, // miss: u32::MAX, +inf = 0x7f800000
        0x04, 0x03, 0x02, 0x01,  0x01, 0x00, 0x80, 0x3f, // 0x01020304, 0x3f800001
        0x07, 0x00, 0x00, 0x00,  0x00, 0x00, 0x00, 0x80, // 7, -0.0 = 0x80000000
        0x08, 0x00, 0x00, 0x00,  0xef, 0xbe, 0xc0, 0x7f, // 8, NaN 0x7fc0beef
        0xfe, 0xff, 0xff, 0xff,  0x00, 0x00, 0x20, 0x00, // u32::MAX - 1, 2^-128 = 0x00200000
    ];

    #[test]
    fn encodes_to_hand_written_bytes() {
        assert_eq!(encode_hits(&sample()), SAMPLE_BYTES);
    }

    #[test]
    fn decodes_hand_written_bytes_bit_exact() {
        let back = decode_hits(&SAMPLE_BYTES, 3, 2).unwrap();
        assert_eq!(back.len(), 6);
        for (a, b) in sample().iter().zip(&back) {
            assert_eq!(a.triangle, b.triangle);
            assert_eq!(a.t.to_bits(), b.t.to_bits());
        }
        assert!(back[1].is_miss());
    }

    #[test]
    fn wrong_length_is_an_error() {
        let bytes = encode_hits(&sample());
        let err = decode_hits(&bytes[..47], 3, 2).unwrap_err();
        assert_eq!(
            err.to_string(),
            "hit buffer for 3x2 pixels must be 48 bytes (8 per pixel), found 47"
        );
        assert!(decode_hits(&bytes, 2, 2).is_err());
        assert_eq!(decode_hits(&[], 0, 5).unwrap(), vec![]);
    }
}
