//! Images: a linear-radiance RGB buffer and its encoders (8-bit sRGB PNG and JPEG, PFM,
//! OpenEXR).
//!
//! Every encoder is a pure function of the [`Image`]: the same pixels give the same bytes on
//! every machine (no platform libm, fixed compression settings, explicit little-endian floats,
//! no threads). PFM is written by hand; PNG by the `png` crate, JPEG by the `image` crate and
//! OpenEXR by the `exr` crate, at the versions pinned by `Cargo.lock`.

mod exr;
mod gif;
mod jpeg;
mod pfm;
mod png8;

use std::ffi::OsString;
use std::path::{Path, PathBuf};

pub use exr::encode_exr;
pub use gif::encode_gif;
pub use jpeg::{JPEG_QUALITY, encode_jpeg};
pub use pfm::{decode_pfm, encode_pfm};
pub use png8::{encode_png, linear_to_srgb8};

/// Errors from encoding, decoding or writing images. Every message names what went wrong and,
/// for file operations, the path.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The pixel buffer does not match `width * height`, or a dimension is zero.
    #[error("invalid image: {0}")]
    InvalidImage(String),
    /// The PNG encoder refused the image.
    #[error("PNG encoding failed: {0}")]
    Png(String),
    /// The JPEG encoder refused the image (for example a dimension over 65535).
    #[error("JPEG encoding failed: {0}")]
    Jpeg(String),
    /// The OpenEXR encoder refused the image.
    #[error("OpenEXR encoding failed: {0}")]
    Exr(String),
    /// A PFM file could not be parsed (bad header, short or excess data).
    #[error("malformed PFM: {0}")]
    Pfm(String),
    /// `write_image` was given a path whose extension is not one of [`IMAGE_EXTENSIONS`].
    #[error("unsupported image extension \"{ext}\" for {path}: use .png, .jpg, .jpeg, .pfm or .exr", path = path.display())]
    UnsupportedExtension {
        /// The extension as given (without the dot; empty if the path has none).
        ext: String,
        /// The path that was asked for.
        path: PathBuf,
    },
    /// Writing the file (or renaming the temporary file into place) failed.
    #[error("cannot write image {path}: {source}", path = path.display())]
    Io {
        /// The destination path the caller asked for.
        path: PathBuf,
        /// The underlying I/O error.
        source: std::io::Error,
    },
}

/// A linear-radiance RGB image: `pixels[y * width + x]`, row-major, row 0 at the top, x to the
/// right. Values are unbounded linear radiance (not sRGB-encoded).
///
/// The fields are public; a consistent image has `pixels.len() == width * height`. The encoders
/// check this (see [`Image::validate`]) and never read out of bounds.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major linear RGB, row 0 at the top; length `width * height`.
    pub pixels: Vec<[f32; 3]>,
}

impl Image {
    /// A black (all zero) image of `width x height` pixels.
    ///
    /// Panics if `width * height` does not fit in memory addressing (`usize`).
    pub fn new(width: u32, height: u32) -> Image {
        let n = pixel_count(width, height).expect("image dimensions overflow usize");
        Image {
            width,
            height,
            pixels: vec![[0.0; 3]; n],
        }
    }

    /// The pixel at column `x`, row `y` (row 0 at the top). Panics if out of range.
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        self.pixels[self.index(x, y)]
    }

    /// Sets the pixel at column `x`, row `y` (row 0 at the top). Panics if out of range.
    pub fn set(&mut self, x: u32, y: u32, rgb: [f32; 3]) {
        let i = self.index(x, y);
        self.pixels[i] = rgb;
    }

    /// Checks that both dimensions are non-zero and `pixels.len() == width * height`.
    pub fn validate(&self) -> Result<(), ImageError> {
        if self.width == 0 || self.height == 0 {
            return Err(ImageError::InvalidImage(format!(
                "{}x{} has a zero dimension",
                self.width, self.height
            )));
        }
        match pixel_count(self.width, self.height) {
            Some(n) if n == self.pixels.len() => Ok(()),
            _ => Err(ImageError::InvalidImage(format!(
                "{}x{} needs {} pixels, buffer has {}",
                self.width,
                self.height,
                u64::from(self.width) * u64::from(self.height),
                self.pixels.len()
            ))),
        }
    }

    fn index(&self, x: u32, y: u32) -> usize {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside {}x{} image",
            self.width,
            self.height
        );
        y as usize * self.width as usize + x as usize
    }
}

/// `width * height` as `usize`, or `None` on overflow.
pub(crate) fn pixel_count(width: u32, height: u32) -> Option<usize> {
    (width as usize).checked_mul(height as usize)
}

/// The file extensions [`write_image`] accepts (compared case-insensitively), in the order the
/// error for any other extension lists them.
pub const IMAGE_EXTENSIONS: [&str; 5] = ["png", "jpg", "jpeg", "pfm", "exr"];

/// Writes `image` to `path`, choosing the format by extension (case-insensitive): `.png`
/// (8-bit sRGB), `.jpg` or `.jpeg` (8-bit sRGB, quality [`JPEG_QUALITY`]), `.pfm` (linear,
/// little-endian) or `.exr` (linear, 32-bit float, ZIP compressed).
///
/// The write is atomic: the bytes go to `{path}.tmp` in the same directory, which is then
/// renamed over `path`, so readers never see a partial file. Any other extension is an
/// [`ImageError::UnsupportedExtension`]; I/O failures are [`ImageError::Io`] naming `path`.
pub fn write_image(path: &Path, image: &Image) -> Result<(), ImageError> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().into_owned())
        .unwrap_or_default();
    let bytes = match ext.to_ascii_lowercase().as_str() {
        "png" => encode_png(image)?,
        "jpg" | "jpeg" => encode_jpeg(image)?,
        "pfm" => {
            image.validate()?;
            encode_pfm(image)
        }
        "exr" => encode_exr(image)?,
        _ => {
            return Err(ImageError::UnsupportedExtension {
                ext,
                path: path.to_path_buf(),
            });
        }
    };
    write_atomic(path, &bytes).map_err(|source| ImageError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Writes `bytes` to `{path}.tmp` and renames it to `path`; removes the temporary on failure.
fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let mut tmp: OsString = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    let result = std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, path));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn new_get_set() {
        let mut img = Image::new(3, 2);
        assert_eq!(img.pixels.len(), 6);
        assert_eq!(img.get(2, 1), [0.0; 3]);
        img.set(2, 1, [1.0, 2.0, 3.0]);
        assert_eq!(img.pixels[5], [1.0, 2.0, 3.0]);
        assert_eq!(img.get(2, 1), [1.0, 2.0, 3.0]);
        assert!(img.validate().is_ok());
    }

    #[test]
    #[should_panic(expected = "outside 3x2")]
    fn get_out_of_range_panics() {
        Image::new(3, 2).get(3, 0);
    }

    #[test]
    fn validate_rejects_inconsistent_buffers() {
        let mut img = Image::new(2, 2);
        img.pixels.pop();
        assert!(
            img.validate()
                .unwrap_err()
                .to_string()
                .contains("needs 4 pixels, buffer has 3")
        );
        assert!(Image::new(0, 5).validate().is_err());
    }

    #[test]
    fn write_image_by_extension_and_atomically() {
        let scratch = tempfile::tempdir().unwrap();
        let dir = scratch.path();
        let mut img = Image::new(2, 2);
        img.set(0, 0, [0.25, 0.5, 1.0]);
        for name in ["a.png", "b.PFM", "c.Exr", "d.jpg", "e.JPEG"] {
            let path = dir.join(name);
            write_image(&path, &img).unwrap();
            assert!(path.exists());
            assert!(!dir.join(format!("{name}.tmp")).exists());
        }
        // Each file decodes (with a reader independent of its encoder) to the image.
        let png = std::fs::read(dir.join("a.png")).unwrap();
        let mut reader = png::Decoder::new(std::io::Cursor::new(&png[..]))
            .read_info()
            .unwrap();
        let mut rgb = vec![0; reader.output_buffer_size().unwrap()];
        let frame = reader.next_frame(&mut rgb).unwrap();
        assert_eq!((frame.width, frame.height), (2, 2));
        // sRGB of linear 0.25, 0.5 and 1.0 is 0.537, 0.735 and 1: 137, 188 and 255.
        assert_eq!(rgb, [137, 188, 255, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
        let pfm = std::fs::read(dir.join("b.PFM")).unwrap();
        assert_eq!(decode_pfm(&pfm).unwrap(), img);
        let exr = std::fs::read(dir.join("c.Exr")).unwrap();
        assert_eq!(exr::tests::read_exr(&exr).unwrap().image, img);
        for name in ["d.jpg", "e.JPEG"] {
            let jpeg = std::fs::read(dir.join(name)).unwrap();
            assert_eq!(jpeg, encode_jpeg(&img).unwrap());
            let back = ::image::load_from_memory_with_format(&jpeg, ::image::ImageFormat::Jpeg)
                .unwrap()
                .into_rgb8();
            assert_eq!(back.dimensions(), (2, 2));
            // One 8x8 block holding one coloured and three black pixels: lossy, but close.
            let near = |got: [u8; 3], want: [u8; 3]| {
                got.iter().zip(want).all(|(g, w)| g.abs_diff(w) <= 40)
            };
            assert!(near(back.get_pixel(0, 0).0, [137, 188, 255]), "{back:?}");
            assert!(near(back.get_pixel(1, 1).0, [0, 0, 0]), "{back:?}");
        }
    }

    #[test]
    fn write_image_rejects_unknown_extension() {
        let err = write_image(Path::new("out/pic.gif"), &Image::new(1, 1)).unwrap_err();
        assert_eq!(
            err.to_string(),
            "unsupported image extension \"gif\" for out/pic.gif: use .png, .jpg, .jpeg, .pfm or .exr"
        );
        let err = write_image(Path::new("out/pic.jpgx"), &Image::new(1, 1)).unwrap_err();
        assert!(matches!(err, ImageError::UnsupportedExtension { ref ext, .. } if ext == "jpgx"));
        let err = write_image(Path::new("noext"), &Image::new(1, 1)).unwrap_err();
        assert!(
            err.to_string()
                .starts_with("unsupported image extension \"\" for noext")
        );
    }

    #[test]
    fn the_error_lists_exactly_the_accepted_extensions() {
        let scratch = tempfile::tempdir().unwrap();
        let dir = scratch.path();
        let err = write_image(Path::new("x.tif"), &Image::new(1, 1)).unwrap_err();
        let listed = err.to_string();
        let listed = listed.split(": use ").nth(1).unwrap();
        let listed: Vec<&str> = listed
            .split([',', ' '])
            .filter(|w| w.starts_with('.'))
            .map(|w| &w[1..])
            .collect();
        assert_eq!(listed, IMAGE_EXTENSIONS);
        for ext in IMAGE_EXTENSIONS {
            write_image(&dir.join(format!("x.{ext}")), &Image::new(3, 2)).unwrap();
        }
    }

    use crate::digest::fnv1a64;

    #[test]
    fn encoder_bytes_are_pinned() {
        // The same image gives the same bytes on every machine and every run. A change here
        // means an encoder or its pinned dependency changed what it writes: check that the
        // new files still decode (the tests above) and re-pin from the printed line.
        let (w, h) = (48, 20);
        let mut img = Image::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
                img.set(x, y, [u * u, v, 1.5 * (1.0 - u) * v]);
            }
        }
        let got = [
            fnv1a64(&encode_png(&img).unwrap()),
            fnv1a64(&encode_jpeg(&img).unwrap()),
            fnv1a64(&encode_exr(&img).unwrap()),
            fnv1a64(&encode_pfm(&img)),
        ];
        println!("{got:#018x?}");
        #[rustfmt::skip]
        let pinned = [
            0x2c0d_0af9_40a5_f1c3, // PNG (the same as before the image crate came in)
            0x9290_fbcd_a34e_1cef, // JPEG
            0xbe03_61ba_0282_3d7f, // OpenEXR
            0x233e_0514_4c2e_73a0, // PFM
        ];
        assert_eq!(got, pinned);
    }

    #[test]
    fn write_image_io_error_names_path() {
        let path = Path::new("/nonexistent-hort-dir/sub/img.pfm");
        let err = write_image(path, &Image::new(1, 1)).unwrap_err();
        assert!(matches!(err, ImageError::Io { .. }));
        assert!(
            err.to_string()
                .starts_with("cannot write image /nonexistent-hort-dir/sub/img.pfm: ")
        );
    }
}
