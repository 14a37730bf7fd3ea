//! 8-bit sRGB JPEG encoding (the `image` crate's baseline encoder).

use super::png8::srgb8_rgb;
use super::{Image, ImageError};

/// The JPEG quality (1 to 100, IJG scaling of the standard quantisation tables).
pub const JPEG_QUALITY: u8 = 90;

/// Encodes `image` as a baseline JFIF JPEG of quality [`JPEG_QUALITY`]: the same 8-bit sRGB
/// values as the PNG ([`linear_to_srgb8`](super::linear_to_srgb8)), converted to YCbCr
/// without chroma subsampling.
///
/// The bytes are deterministic: `image`'s encoder converts colours in fixed point, uses an
/// integer DCT and IEEE-rounded quantisation, with no CPU-dependent code paths. Fails if the
/// image is inconsistent ([`Image::validate`]) or a dimension exceeds 65535 (the JPEG limit).
pub fn encode_jpeg(image: &Image) -> Result<Vec<u8>, ImageError> {
    image.validate()?;
    let data = srgb8_rgb(image);
    let mut out = Vec::new();
    ::image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, JPEG_QUALITY)
        .encode(
            &data,
            image.width,
            image.height,
            ::image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| ImageError::Jpeg(e.to_string()))?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::linear_to_srgb8;

    /// Decodes with `image`'s JPEG decoder (`zune-jpeg`, independent of the encoder).
    fn decode(bytes: &[u8]) -> ::image::RgbImage {
        ::image::load_from_memory_with_format(bytes, ::image::ImageFormat::Jpeg)
            .unwrap()
            .into_rgb8()
    }

    /// A smooth gradient with a flat patch, values across the whole sRGB range.
    fn gradient(w: u32, h: u32) -> Image {
        let mut img = Image::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let u = x as f32 / (w.max(2) - 1) as f32;
                let v = y as f32 / (h.max(2) - 1) as f32;
                img.set(x, y, [u, v, 0.25 * (u + v)]);
            }
        }
        for y in 0..h.min(8) {
            for x in 0..w.min(8) {
                img.set(x, y, [0.18, 0.5, 1.0]);
            }
        }
        img
    }

    #[test]
    fn jpeg_decodes_close_to_the_srgb_values() {
        for (w, h) in [(1, 1), (2, 2), (7, 5), (64, 40), (33, 17)] {
            let img = gradient(w, h);
            let bytes = encode_jpeg(&img).unwrap();
            assert_eq!(encode_jpeg(&img).unwrap(), bytes, "deterministic");
            assert_eq!(&bytes[..2], [0xff, 0xd8], "SOI");
            assert_eq!(&bytes[bytes.len() - 2..], [0xff, 0xd9], "EOI");
            let back = decode(&bytes);
            assert_eq!(back.dimensions(), (img.width, img.height));
            let (mut worst, mut total) = (0, 0);
            for (p, q) in img.pixels.iter().zip(back.pixels()) {
                for (c, &d) in p.iter().zip(&q.0) {
                    let e = linear_to_srgb8(*c).abs_diff(d);
                    worst = worst.max(e);
                    total += u32::from(e);
                }
            }
            // Quality 90: a few steps at most (8 at the flat patch's hard edge), about one on
            // average.
            let mean = total as f32 / (3 * w * h) as f32;
            assert!(
                worst <= 12 && mean <= 2.0,
                "{w}x{h}: max {worst}, mean {mean}"
            );
        }
        // The flat 8x8 block (sRGB 118, 188, 255) comes back within a step or two.
        let back = decode(&encode_jpeg(&gradient(64, 40)).unwrap());
        let p = back.get_pixel(3, 3).0;
        for (got, want) in p.iter().zip([118u8, 188, 255]) {
            assert!(got.abs_diff(want) <= 2, "{p:?}");
        }
    }

    #[test]
    fn jpeg_quantisation_is_quality_90() {
        // IJG scaling at quality 90: each table entry becomes (q * 20 + 50) / 100, clamped to
        // at least 1; the standard luminance table starts 16, 11, 12 -> 3, 2, 2 (zig-zag).
        let bytes = encode_jpeg(&gradient(16, 16)).unwrap();
        let dqt = bytes
            .windows(2)
            .position(|m| m == [0xff, 0xdb])
            .expect("DQT marker");
        // Marker, length (2 bytes), precision/table id 0, then 64 entries in zig-zag order.
        assert_eq!(bytes[dqt + 4], 0, "8-bit table 0");
        assert_eq!(&bytes[dqt + 5..dqt + 8], [3, 2, 2]);
    }

    #[test]
    fn jpeg_rejects_bad_images() {
        assert!(encode_jpeg(&Image::new(0, 1)).is_err());
        let mut img = Image::new(2, 2);
        img.pixels.pop();
        assert!(encode_jpeg(&img).is_err());
        let err = encode_jpeg(&Image::new(65_536, 1)).unwrap_err();
        assert!(matches!(err, ImageError::Jpeg(_)), "{err}");
    }
}
