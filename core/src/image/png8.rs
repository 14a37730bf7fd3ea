//! 8-bit sRGB PNG encoding.

use super::{Image, ImageError};

/// Converts one linear channel value to an 8-bit sRGB code value.
///
/// IEC 61966-2-1 transfer: `12.92 v` for `v <= 0.0031308`, else `1.055 v^(1/2.4) - 0.055`
/// (computed with `libm::powf`, so identical on every machine). The input is clamped to [0, 1]
/// first, NaN maps to 0, and the result is rounded to nearest: `(s * 255 + 0.5) as u8`.
///
/// That formula is [`srgb8_by_formula`]; this function returns the same byte for every `f32`
/// without evaluating it: the code value is the number of [`SrgbTable::thresholds`] at or below
/// `v`, found from a table indexed by the top 16 bits of `v` (its exponent and 7 mantissa bits)
/// and at most one step along the thresholds. A 1080p image's 6.2 million channels took about
/// 0.3 s through `powf` and take 0.02 s here; the test compares the two around every threshold
/// and over a stride of all inputs (every `f32` from 0 to 1 was compared once when this was
/// written).
pub fn linear_to_srgb8(v: f32) -> u8 {
    if v.is_nan() || v <= 0.0 {
        return 0;
    }
    if v >= 1.0 {
        return 255;
    }
    let table = &*SRGB_TABLE;
    let mut code = table.code_at_bucket_start[(v.to_bits() >> 16) as usize];
    while code < 255 && table.thresholds[usize::from(code)] <= v {
        code += 1;
    }
    code
}

/// The IEC 61966-2-1 transfer and rounding of [`linear_to_srgb8`], evaluated directly.
fn srgb8_by_formula(v: f32) -> u8 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    let s = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * libm::powf(v, 1.0 / 2.4) - 0.055
    };
    (s.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// Where [`srgb8_by_formula`] steps up, and the code value at the start of each bucket of
/// positive `f32`s below 1 that share their top 16 bits.
struct SrgbTable {
    /// `thresholds[n]` is the smallest `f32` whose code value is above `n` (255 of them).
    thresholds: [f32; 255],
    /// The code value of the smallest `f32` with the bucket's top 16 bits (`0x3f80` buckets:
    /// every positive `f32` below 1.0). A bucket spans less than one code step (at most 0.44
    /// steps, just below 1.0), so the search from here takes one step at most.
    code_at_bucket_start: Vec<u8>,
}

const ONE_BITS: u32 = 0x3f80_0000;

static SRGB_TABLE: std::sync::LazyLock<SrgbTable> = std::sync::LazyLock::new(|| {
    let mut thresholds = [0.0; 255];
    for (n, threshold) in thresholds.iter_mut().enumerate() {
        // The formula is non-decreasing in `v`, and positive floats order as their bits: a
        // binary search over the bits finds the first `f32` whose code exceeds `n`.
        let (mut low, mut high) = (0u32, ONE_BITS); // code(low) <= n < code(high)
        while high - low > 1 {
            let middle = low + (high - low) / 2;
            if usize::from(srgb8_by_formula(f32::from_bits(middle))) > n {
                high = middle;
            } else {
                low = middle;
            }
        }
        *threshold = f32::from_bits(high);
    }
    let code_at_bucket_start = (0..ONE_BITS >> 16)
        .map(|bucket| {
            let start = f32::from_bits(bucket << 16);
            thresholds.partition_point(|&t| t <= start) as u8
        })
        .collect();
    SrgbTable {
        thresholds,
        code_at_bucket_start,
    }
});

/// The pixels as interleaved 8-bit sRGB R, G, B bytes, row-major from the top-left pixel,
/// each channel mapped by [`linear_to_srgb8`] (shared by the PNG and JPEG encoders).
pub(super) fn srgb8_rgb(image: &Image) -> Vec<u8> {
    image
        .pixels
        .iter()
        .flat_map(|p| p.map(linear_to_srgb8))
        .collect()
}

/// Encodes `image` as an 8-bit RGB PNG with an sRGB chunk (perceptual intent), each channel
/// mapped by [`linear_to_srgb8`].
///
/// The bytes are deterministic: fixed filter (Paeth) and the pure-Rust `fdeflate` compressor,
/// no CPU-dependent code paths. Fails if the image is inconsistent ([`Image::validate`]).
///
/// This drives the `png` crate directly rather than through `image::codecs::png::PngEncoder`:
/// that encoder is a wrapper over the same crate (its `Fast` compression is this
/// `FdeflateUltraFast`, so it would write the same pixel data), but it cannot write the sRGB
/// chunk, only an ICC profile.
pub fn encode_png(image: &Image) -> Result<Vec<u8>, ImageError> {
    image.validate()?;
    let data = srgb8_rgb(image);
    let mut out = Vec::new();
    let png_err = |e: png::EncodingError| ImageError::Png(e.to_string());
    let mut encoder = png::Encoder::new(&mut out, image.width, image.height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    encoder.set_deflate_compression(png::DeflateCompression::FdeflateUltraFast);
    encoder.set_filter(png::Filter::Paeth);
    let mut writer = encoder.write_header().map_err(png_err)?;
    writer.write_image_data(&data).map_err(png_err)?;
    writer.finish().map_err(png_err)?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_known_values() {
        assert_eq!(linear_to_srgb8(0.0), 0);
        assert_eq!(linear_to_srgb8(1.0), 255);
        assert_eq!(linear_to_srgb8(0.5), 188);
        assert_eq!(linear_to_srgb8(0.18), 118);
        // The linear segment and the boundary: 12.92 * 0.0031308 = 0.04045 -> 10.3 -> 10.
        assert_eq!(linear_to_srgb8(0.003_130_8), 10);
        assert_eq!(linear_to_srgb8(0.003_130_9), 10);
        assert_eq!(linear_to_srgb8(0.001), 3);
    }

    #[test]
    fn srgb_clamps_and_maps_nan_to_zero() {
        assert_eq!(linear_to_srgb8(-1.0), 0);
        assert_eq!(linear_to_srgb8(7.5), 255);
        assert_eq!(linear_to_srgb8(f32::INFINITY), 255);
        assert_eq!(linear_to_srgb8(f32::NEG_INFINITY), 0);
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
    }

    #[test]
    fn the_table_gives_the_formula_everywhere() {
        let table = &*SRGB_TABLE;
        let agree = |bits: u32| {
            let v = f32::from_bits(bits);
            assert_eq!(linear_to_srgb8(v), srgb8_by_formula(v), "{v:e} ({bits:#x})");
        };
        // Around every step: 4,096 floats either side of each threshold.
        for threshold in table.thresholds {
            let bits = threshold.to_bits();
            (bits.saturating_sub(4096)..bits + 4096).for_each(agree);
        }
        // A stride over every non-negative float, up to +infinity, and the negatives.
        (0..=f32::INFINITY.to_bits()).step_by(1009).for_each(agree);
        (0x8000_0000..=u32::MAX).step_by(1_000_003).for_each(agree);
        for v in [
            f32::NAN,
            -f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            0.0,
            -0.0,
            1.0,
        ] {
            assert_eq!(linear_to_srgb8(v), srgb8_by_formula(v), "{v}");
        }
        // The thresholds step one code value at a time, in order, and a bucket holds at most
        // one of them (so the lookup's search is short).
        assert!(table.thresholds.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(srgb8_by_formula(table.thresholds[0]), 1);
        let buckets: Vec<u32> = table.thresholds.iter().map(|t| t.to_bits() >> 16).collect();
        assert!(buckets.windows(2).all(|w| w[0] < w[1]), "{buckets:?}");
    }

    #[test]
    fn srgb_is_monotonic() {
        let mut prev = 0;
        for i in 0..=10_000 {
            let s = linear_to_srgb8(i as f32 / 10_000.0);
            assert!(s >= prev);
            prev = s;
        }
        assert_eq!(prev, 255);
    }

    fn sample_image() -> Image {
        let mut img = Image::new(3, 2);
        img.set(0, 0, [1.0, 0.0, 0.5]);
        img.set(1, 0, [0.18, f32::NAN, 2.0]);
        img.set(2, 1, [0.003_130_8, -0.5, 1.0]);
        img
    }

    #[test]
    fn png_decodes_to_expected_bytes() {
        let bytes = encode_png(&sample_image()).unwrap();
        let mut decoder = png::Decoder::new(std::io::Cursor::new(&bytes[..]));
        decoder.set_transformations(png::Transformations::IDENTITY);
        let mut reader = decoder.read_info().unwrap();
        assert_eq!(
            reader.info().srgb,
            Some(png::SrgbRenderingIntent::Perceptual)
        );
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let frame = reader.next_frame(&mut buf).unwrap();
        assert_eq!((frame.width, frame.height), (3, 2));
        assert_eq!(frame.color_type, png::ColorType::Rgb);
        assert_eq!(frame.bit_depth, png::BitDepth::Eight);
        #[rustfmt::skip]
        let expected = [
            255, 0, 188,   118, 0, 255,   0, 0, 0,
            0, 0, 0,       0, 0, 0,       10, 0, 255,
        ];
        assert_eq!(&buf[..frame.buffer_size()], &expected);
    }

    #[test]
    fn tiny_png_bytes_by_hand() {
        // Compressed, a 3x2 image would be larger than stored, so the png crate stores its
        // scanlines unfiltered (a zlib stored block, filter type 0 on each row).
        #[rustfmt::skip]
        let expected: &[u8] = &[
            0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n',
            // IHDR: 3 x 2, bit depth 8, colour type 2 (RGB), compression 0, filter method 0,
            // no interlace; CRC.
            0, 0, 0, 13, b'I', b'H', b'D', b'R',
            0, 0, 0, 3, 0, 0, 0, 2, 8, 2, 0, 0, 0,
            0x12, 0x16, 0xf1, 0x4d,
            // sRGB, rendering intent 0 (perceptual); CRC.
            0, 0, 0, 1, b's', b'R', b'G', b'B', 0, 0xae, 0xce, 0x1c, 0xe9,
            // IDAT: zlib header 78 01; final stored block of 20 = 0x14 bytes (LEN, !LEN); the
            // scanlines (the sRGB bytes of `png_decodes_to_expected_bytes`); their Adler-32; CRC.
            0, 0, 0, 31, b'I', b'D', b'A', b'T',
            0x78, 0x01,
            0x01, 0x14, 0x00, 0xeb, 0xff,
            0, 255, 0, 188, 118, 0, 255, 0, 0, 0,
            0, 0, 0, 0, 0, 0, 0, 10, 0, 255,
            0x35, 0xec, 0x04, 0x3a,
            0xb0, 0xb2, 0x62, 0xa1,
            // IEND; CRC.
            0, 0, 0, 0, b'I', b'E', b'N', b'D', 0xae, 0x42, 0x60, 0x82,
        ];
        assert_eq!(encode_png(&sample_image()).unwrap(), expected);
    }

    /// The Paeth filter (PNG specification, section 9.4) of 8-bit RGB scanlines, each row
    /// prefixed with its filter type 4.
    fn paeth_filtered(rgb: &[u8], width: usize) -> Vec<u8> {
        let stride = 3 * width;
        let mut out = Vec::new();
        let zeros = vec![0; stride];
        for (y, row) in rgb.chunks_exact(stride).enumerate() {
            let above = if y == 0 {
                &zeros[..]
            } else {
                &rgb[(y - 1) * stride..y * stride]
            };
            out.push(4);
            for (i, &x) in row.iter().enumerate() {
                let left = |r: &[u8]| if i >= 3 { i16::from(r[i - 3]) } else { 0 };
                let (a, b, c) = (left(row), i16::from(above[i]), left(above));
                let p = a + b - c;
                let (pa, pb, pc) = ((p - a).abs(), (p - b).abs(), (p - c).abs());
                let predictor = if pa <= pb && pa <= pc {
                    a
                } else if pb <= pc {
                    b
                } else {
                    c
                };
                out.push(x.wrapping_sub(predictor as u8));
            }
        }
        out
    }

    /// Adler-32 (RFC 1950), the checksum that ends a zlib stream.
    fn adler32(data: &[u8]) -> u32 {
        let (mut a, mut b) = (1u32, 0u32);
        for &d in data {
            a = (a + u32::from(d)) % 65_521;
            b = (b + a) % 65_521;
        }
        (b << 16) | a
    }

    #[test]
    fn compressed_png_is_paeth_filtered() {
        // A smooth 32x16 gradient compresses, so the encoder keeps its Paeth-filtered stream:
        // the zlib stream's Adler-32 is that of the Paeth filter of the decoded scanlines.
        let (w, h) = (32, 16);
        let mut img = Image::new(w, h);
        for y in 0..h {
            for x in 0..w {
                img.set(x, y, [x as f32 / 31.0, y as f32 / 15.0, 0.5]);
            }
        }
        let bytes = encode_png(&img).unwrap();
        let mut reader = png::Decoder::new(std::io::Cursor::new(&bytes[..]))
            .read_info()
            .unwrap();
        let mut rgb = vec![0; reader.output_buffer_size().unwrap()];
        reader.next_frame(&mut rgb).unwrap();
        // sRGB of linear 0, 0.5 and 1/31: 0, 188 and 50.
        assert_eq!(&rgb[..6], [0, 0, 188, 50, 0, 188]);

        let mut idat = Vec::new();
        let mut rest = &bytes[33 + 13..]; // after the signature, IHDR and sRGB
        while !rest.is_empty() {
            let len = u32::from_be_bytes(rest[..4].try_into().unwrap()) as usize;
            if &rest[4..8] == b"IDAT" {
                idat.extend_from_slice(&rest[8..8 + len]);
            }
            rest = &rest[12 + len..];
        }
        let filtered = paeth_filtered(&rgb, w as usize);
        assert!(idat.len() < filtered.len(), "not compressed");
        let adler = adler32(&filtered).to_be_bytes();
        assert_eq!(idat[idat.len() - 4..], adler);
    }

    #[test]
    fn png_rejects_bad_images() {
        assert!(encode_png(&Image::new(0, 0)).is_err());
        let mut img = Image::new(2, 2);
        img.pixels.pop();
        assert!(encode_png(&img).is_err());
    }
}
