//! Animated GIF previews of a run of frames (the `image` crate's GIF encoder).

use super::png8::srgb8_rgb;
use super::{Image, ImageError};
use ::image::codecs::gif::{GifEncoder, Repeat};
use ::image::{Delay, Frame, RgbaImage};

/// The palette quantiser's speed, 1 (best, slowest) to 30: the encoder's default balance.
const GIF_QUANTIZER_SPEED: i32 = 10;

/// Encodes `frames` (at least one, all of one size) as a looping animated GIF showing each for
/// `delay_ms` milliseconds: the PNG's 8-bit sRGB values, each frame quantised to its own
/// palette of 256 colours (NeuQuant at [`GIF_QUANTIZER_SPEED`]).
///
/// A preview, not a lossless output: use PNG frames for the exact pixels. The bytes are
/// deterministic (integer quantisation, no threads). Fails if a frame is inconsistent
/// ([`Image::validate`]), the sizes differ, a side exceeds 65535 (the GIF limit) or there is
/// no frame.
pub fn encode_gif(frames: &[Image], delay_ms: u32) -> Result<Vec<u8>, ImageError> {
    let Some(first) = frames.first() else {
        return Err(ImageError::InvalidImage(
            "an animation needs a frame".into(),
        ));
    };
    let mut out = Vec::new();
    {
        let mut encoder = GifEncoder::new_with_speed(&mut out, GIF_QUANTIZER_SPEED);
        encoder
            .set_repeat(Repeat::Infinite)
            .map_err(|e| ImageError::InvalidImage(format!("GIF: {e}")))?;
        for (index, image) in frames.iter().enumerate() {
            image.validate()?;
            if (image.width, image.height) != (first.width, first.height) {
                return Err(ImageError::InvalidImage(format!(
                    "GIF frame {index} is {}x{}, frame 0 {}x{}",
                    image.width, image.height, first.width, first.height
                )));
            }
            let rgba: Vec<u8> = srgb8_rgb(image)
                .chunks_exact(3)
                .flat_map(|c| [c[0], c[1], c[2], 255])
                .collect();
            let buffer = RgbaImage::from_raw(image.width, image.height, rgba)
                .ok_or_else(|| ImageError::InvalidImage("GIF frame buffer".into()))?;
            let frame = Frame::from_parts(buffer, 0, 0, Delay::from_numer_denom_ms(delay_ms, 1));
            encoder
                .encode_frame(frame)
                .map_err(|e| ImageError::InvalidImage(format!("GIF frame {index}: {e}")))?;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ::image::AnimationDecoder;
    use ::image::codecs::gif::GifDecoder;

    fn flat(w: u32, h: u32, rgb: [f32; 3]) -> Image {
        Image {
            width: w,
            height: h,
            pixels: vec![rgb; (w * h) as usize],
        }
    }

    /// Decoded again (by the `image` crate's decoder), the GIF has the frames in order, their
    /// size and delay, and flat frames keep their sRGB colour exactly; the bytes repeat.
    #[test]
    fn frames_come_back_in_order_with_their_colours() {
        let frames = [flat(5, 3, [0.0; 3]), flat(5, 3, [1.0, 0.2, 0.05])];
        let bytes = encode_gif(&frames, 80).unwrap();
        assert_eq!(bytes, encode_gif(&frames, 80).unwrap());
        let decoded: Vec<Frame> = GifDecoder::new(std::io::Cursor::new(&bytes))
            .unwrap()
            .into_frames()
            .collect_frames()
            .unwrap();
        assert_eq!(decoded.len(), 2);
        for (frame, image) in decoded.iter().zip(&frames) {
            assert_eq!(frame.buffer().dimensions(), (5, 3));
            assert_eq!(frame.delay().numer_denom_ms(), (80, 1));
            let srgb = image.pixels[0].map(super::super::linear_to_srgb8);
            let got = frame.buffer().get_pixel(2, 1).0;
            assert_eq!([got[0], got[1], got[2]], srgb);
        }
    }

    #[test]
    fn no_frames_or_mixed_sizes_are_errors() {
        assert_eq!(
            encode_gif(&[], 40).unwrap_err().to_string(),
            "invalid image: an animation needs a frame"
        );
        let e = encode_gif(&[flat(2, 2, [0.5; 3]), flat(3, 2, [0.5; 3])], 40).unwrap_err();
        assert_eq!(
            e.to_string(),
            "invalid image: GIF frame 1 is 3x2, frame 0 2x2"
        );
    }
}
