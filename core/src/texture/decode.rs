//! Image files to [`Texture`]s: PNG and JPEG through the `image` crate, with limits so that an
//! absurd header is refused before anything large is allocated.

use super::Texture;
use std::path::Path;

/// The largest accepted texture width or height, in texels (a 16384² texture is 768 MiB
/// decoded, more than most function budgets; the memory check refuses what does not fit).
pub const MAX_TEXTURE_SIDE: u32 = 16_384;

/// Decodes the PNG or JPEG bytes `bytes` (format sniffed from the bytes) into a texture called
/// `name`. The error is one line saying what is wrong.
pub fn decode_texture_image(bytes: &[u8], name: &str) -> Result<Texture, String> {
    let format = image::guess_format(bytes).map_err(|_| {
        "not a PNG or JPEG image (its first bytes match no image format)".to_string()
    })?;
    if !matches!(format, image::ImageFormat::Png | image::ImageFormat::Jpeg) {
        return Err(format!("a {format:?} image; textures must be PNG or JPEG"));
    }
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_TEXTURE_SIDE);
    limits.max_image_height = Some(MAX_TEXTURE_SIDE);
    limits.max_alloc = Some(4 * u64::from(MAX_TEXTURE_SIDE) * u64::from(MAX_TEXTURE_SIDE) * 2);
    reader.limits(limits);
    let decoded = reader.decode().map_err(|e| match e {
        image::ImageError::Limits(_) => format!(
            "larger than {MAX_TEXTURE_SIDE}x{MAX_TEXTURE_SIDE} texels, the largest texture accepted"
        ),
        e => format!("cannot be decoded as {format:?}: {e}"),
    })?;
    let rgb = decoded.into_rgb8();
    let (width, height) = rgb.dimensions();
    if width == 0 || height == 0 {
        return Err("the image has no texels".into());
    }
    Ok(Texture::new(
        name.to_string(),
        width,
        height,
        rgb.into_raw(),
    ))
}

/// The largest texture file read: 1 GiB (a PNG or JPEG of the largest texture accepted is far
/// smaller; this keeps a path to a device or a huge file from being read at all).
pub const MAX_TEXTURE_FILE_BYTES: u64 = 1 << 30;

/// Reads and decodes the image file at `path`, calling the texture `name`. Only a regular file
/// of at most [`MAX_TEXTURE_FILE_BYTES`] is read.
pub fn decode_texture_file(path: &Path, name: &str) -> Result<Texture, String> {
    let unreadable = |e: std::io::Error| match e.kind() {
        std::io::ErrorKind::NotFound => "the file does not exist".to_string(),
        _ => format!("cannot be read: {e}"),
    };
    let meta = std::fs::metadata(path).map_err(unreadable)?;
    if !meta.is_file() {
        return Err("not a regular file".into());
    }
    if meta.len() > MAX_TEXTURE_FILE_BYTES {
        return Err(format!(
            "{} bytes, over the {MAX_TEXTURE_FILE_BYTES} a texture file may have",
            meta.len()
        ));
    }
    let bytes = std::fs::read(path).map_err(unreadable)?;
    decode_texture_image(&bytes, name)
}
