//! 8-bit sRGB PNG encoding.

use super::{Image, ImageError};

/// Converts one linear channel value to an 8-bit sRGB code value.
///
/// IEC 61966-2-1 transfer: `12.92 v` for `v <= 0.0031308`, else `1.055 v^(1/2.4) - 0.055`
/// (computed with `libm::powf`, so identical on every machine). The input is clamped to [0, 1]
/// first, NaN maps to 0, and the result is rounded to nearest: `(s * 255 + 0.5) as u8`.
pub fn linear_to_srgb8(v: f32) -> u8 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    let s = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * libm::powf(v, 1.0 / 2.4) - 0.055
    };
    (s.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// Encodes `image` as an 8-bit RGB PNG with an sRGB chunk (perceptual intent), each channel
/// mapped by [`linear_to_srgb8`].
///
/// The bytes are deterministic: fixed filter (Paeth) and the pure-Rust `fdeflate` compressor,
/// no CPU-dependent code paths. Fails if the image is inconsistent ([`Image::validate`]).
pub fn encode_png(image: &Image) -> Result<Vec<u8>, ImageError> {
    image.validate()?;
    let data: Vec<u8> = image
        .pixels
        .iter()
        .flat_map(|p| p.map(linear_to_srgb8))
        .collect();
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
    fn png_is_deterministic_and_rejects_bad_images() {
        assert_eq!(
            encode_png(&sample_image()).unwrap(),
            encode_png(&sample_image()).unwrap()
        );
        assert!(encode_png(&Image::new(0, 0)).is_err());
    }
}
