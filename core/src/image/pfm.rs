//! Portable FloatMap (PFM): `PF` (RGB) or `Pf` (grey) header, rows stored bottom to top, a
//! negative scale for little-endian data.

use super::{Image, ImageError, pixel_count};

/// Encodes `image` as a colour PFM: the header `PF\n{w} {h}\n-1.0\n`, then the rows from the
/// BOTTOM row to the top, each pixel as three little-endian `f32` (R, G, B), bit-exact (NaN and
/// infinities included).
///
/// Panics if `image.pixels.len() != width * height` (see [`Image::validate`]).
pub fn encode_pfm(image: &Image) -> Vec<u8> {
    let (w, h) = (image.width as usize, image.height as usize);
    assert_eq!(
        pixel_count(image.width, image.height),
        Some(image.pixels.len()),
        "PFM: bad pixel buffer"
    );
    let header = format!("PF\n{w} {h}\n-1.0\n");
    let mut out = Vec::with_capacity(header.len() + w * h * 12);
    out.extend_from_slice(header.as_bytes());
    for y in (0..h).rev() {
        for p in &image.pixels[y * w..(y + 1) * w] {
            for c in p {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    out
}

/// Decodes a PFM file: `PF` (RGB) or `Pf` (greyscale, replicated to R = G = B), either
/// endianness (negative scale: little-endian, positive: big-endian), with rows flipped so that
/// row 0 of the result is the top. The scale's magnitude is ignored (values are returned as
/// stored).
///
/// Errors on an unknown magic, missing or non-numeric width/height/scale, zero dimensions, a
/// zero or non-finite scale, a header not followed by exactly one whitespace byte, and pixel
/// data shorter or longer than `width * height * channels * 4` bytes.
pub fn decode_pfm(bytes: &[u8]) -> Result<Image, ImageError> {
    let mut cursor = Header { bytes, pos: 0 };
    let channels = match cursor.token("magic")? {
        "PF" => 3,
        "Pf" => 1,
        other => {
            return Err(pfm_err(format!(
                "unknown magic {other:?} (expected PF or Pf)"
            )));
        }
    };
    let width: u32 = cursor.number("width")?;
    let height: u32 = cursor.number("height")?;
    let scale: f32 = cursor.number("scale")?;
    if width == 0 || height == 0 {
        return Err(pfm_err(format!("zero dimension {width}x{height}")));
    }
    if scale == 0.0 || !scale.is_finite() {
        return Err(pfm_err(format!(
            "scale must be a non-zero finite number, found {scale}"
        )));
    }
    let data = cursor.after_single_whitespace()?;
    let n = pixel_count(width, height).ok_or_else(|| pfm_err("dimensions overflow".into()))?;
    let expected = (n as u128) * channels as u128 * 4;
    if data.len() as u128 != expected {
        return Err(pfm_err(format!(
            "{width}x{height} with {channels} channel(s) needs {expected} data bytes, found {}",
            data.len()
        )));
    }
    let little = scale < 0.0;
    let value = |b: &[u8]| {
        let b = [b[0], b[1], b[2], b[3]];
        if little {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        }
    };
    let mut image = Image::new(width, height);
    let row_bytes = width as usize * channels * 4;
    for (i, row) in data.chunks_exact(row_bytes).enumerate() {
        let y = height as usize - 1 - i;
        let dst = &mut image.pixels[y * width as usize..(y + 1) * width as usize];
        for (px, src) in dst.iter_mut().zip(row.chunks_exact(channels * 4)) {
            *px = if channels == 3 {
                [value(&src[0..4]), value(&src[4..8]), value(&src[8..12])]
            } else {
                [value(src); 3]
            };
        }
    }
    Ok(image)
}

fn pfm_err(msg: String) -> ImageError {
    ImageError::Pfm(msg)
}

/// A tiny cursor over the ASCII header.
struct Header<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Header<'a> {
    fn token(&mut self, what: &str) -> Result<&'a str, ImageError> {
        while self.pos < self.bytes.len() && self.bytes[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        let start = self.pos;
        while self.pos < self.bytes.len() && !self.bytes[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        if start == self.pos {
            return Err(pfm_err(format!("header ends before the {what}")));
        }
        std::str::from_utf8(&self.bytes[start..self.pos])
            .map_err(|_| pfm_err(format!("{what} is not ASCII")))
    }

    fn number<T: std::str::FromStr>(&mut self, what: &str) -> Result<T, ImageError> {
        let tok = self.token(what)?;
        tok.parse()
            .map_err(|_| pfm_err(format!("invalid {what} {tok:?}")))
    }

    fn after_single_whitespace(&self) -> Result<&'a [u8], ImageError> {
        match self.bytes.get(self.pos) {
            Some(b) if b.is_ascii_whitespace() => Ok(&self.bytes[self.pos + 1..]),
            _ => Err(pfm_err(
                "header must end with one whitespace byte after the scale".into(),
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Image {
        let mut img = Image::new(3, 2);
        img.set(0, 0, [1.0, 2.0, 3.0]); // top-left, distinct
        img.set(2, 0, [-0.0, f32::INFINITY, f32::MIN_POSITIVE]);
        img.set(0, 1, [4.0, 5.0, 6.0]); // bottom-left
        img.set(1, 1, [f32::from_bits(0x7fc0_1234), 1e-40, -7.25]);
        img
    }

    fn bits(img: &Image) -> Vec<u32> {
        img.pixels.iter().flatten().map(|v| v.to_bits()).collect()
    }

    #[test]
    fn header_bytes_exact() {
        let bytes = encode_pfm(&sample());
        assert_eq!(&bytes[..12], b"PF\n3 2\n-1.0\n");
        assert_eq!(bytes.len(), 12 + 3 * 2 * 12);
    }

    #[test]
    fn rows_stored_bottom_to_top() {
        let bytes = encode_pfm(&sample());
        // The first stored pixel is the bottom-left one.
        assert_eq!(&bytes[12..16], &4.0f32.to_le_bytes());
        // The first pixel of the last stored row is the top-left one.
        assert_eq!(&bytes[12 + 36..12 + 40], &1.0f32.to_le_bytes());
    }

    #[test]
    fn round_trip_bit_exact() {
        let img = sample();
        let back = decode_pfm(&encode_pfm(&img)).unwrap();
        assert_eq!((back.width, back.height), (3, 2));
        assert_eq!(bits(&back), bits(&img));
        assert_eq!(back.get(0, 0), [1.0, 2.0, 3.0]);
    }

    #[test]
    fn decodes_big_endian_and_grey() {
        let mut be = b"PF\n1 2\n1.0\n".to_vec();
        for v in [4.0f32, 5.0, 6.0, 1.0, 2.0, 3.0] {
            be.extend_from_slice(&v.to_be_bytes());
        }
        let img = decode_pfm(&be).unwrap();
        assert_eq!(img.pixels, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);

        let mut grey = b"Pf 2 1 -0.5\n".to_vec();
        for v in [0.25f32, 0.75] {
            grey.extend_from_slice(&v.to_le_bytes());
        }
        let img = decode_pfm(&grey).unwrap();
        assert_eq!(img.pixels, vec![[0.25; 3], [0.75; 3]]);
    }

    #[test]
    fn rejects_malformed_input() {
        let cases: [(&[u8], &str); 8] = [
            (b"P6\n1 1\n255\n", "unknown magic"),
            (b"PF\n1", "header ends before the height"),
            (b"PF\nx 1\n-1.0\n", "invalid width"),
            (b"PF\n0 1\n-1.0\n", "zero dimension"),
            (b"PF\n1 1\n0.0\n", "non-zero finite"),
            (b"PF\n1 1\n-1.0", "one whitespace byte"),
            (b"PF\n1 1\n-1.0\n\0\0\0\0", "needs 12 data bytes, found 4"),
            (b"Pf\n1 1\n-1.0\n\0\0\0\0\0", "needs 4 data bytes, found 5"),
        ];
        for (bytes, msg) in cases {
            let err = decode_pfm(bytes).unwrap_err().to_string();
            assert!(err.starts_with("malformed PFM: "), "{err}");
            assert!(err.contains(msg), "{err:?} should contain {msg:?}");
        }
    }
}
