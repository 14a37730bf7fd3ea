//! Minimal OpenEXR 2.0 writer: single-part scanline file, no compression, 32-bit float B, G, R.

use super::{Image, pixel_count};

/// Magic number and version field: version 2, single-part scanline, short names.
const MAGIC_VERSION: [u8; 8] = [0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0];
/// EXR pixel type FLOAT (32-bit IEEE).
const PIXEL_FLOAT: i32 = 2;

/// Encodes `image` as a minimal valid OpenEXR 2.0 file that any conforming reader accepts.
///
/// Layout: magic/version (`76 2f 31 01 02 00 00 00`); header attributes `channels` (B, G, R —
/// alphabetical, as EXR requires — each FLOAT, sampling 1x1), `compression` (NO_COMPRESSION),
/// `dataWindow` and `displayWindow` (both `(0, 0)-(w-1, h-1)`), `lineOrder` (INCREASING_Y),
/// `pixelAspectRatio` 1, `screenWindowCenter` (0, 0), `screenWindowWidth` 1, then the header
/// terminator; a line offset table of `h` little-endian u64 file offsets; and `h` chunks, one per
/// scanline from the top: `i32 y`, `i32 byte count (12 w)`, then w B values, w G values and w R
/// values as little-endian f32 (bit-exact, linear radiance). Total length
/// `header_len + 8 h + h (8 + 12 w)`, deterministic.
///
/// Panics if the image is inconsistent or has a zero dimension (see [`Image::validate`]).
pub fn encode_exr(image: &Image) -> Vec<u8> {
    assert!(
        image.width > 0 && image.height > 0,
        "EXR: zero image dimension"
    );
    assert_eq!(
        pixel_count(image.width, image.height),
        Some(image.pixels.len()),
        "EXR: bad pixel buffer"
    );
    let (w, h) = (image.width as usize, image.height as usize);
    let header = header(image.width, image.height);
    let chunk_len = 8 + 12 * w;
    let mut out = Vec::with_capacity(header.len() + h * (8 + chunk_len));
    out.extend_from_slice(&header);
    let first_chunk = (header.len() + 8 * h) as u64;
    for y in 0..h as u64 {
        out.extend_from_slice(&(first_chunk + y * chunk_len as u64).to_le_bytes());
    }
    for (y, row) in image.pixels.chunks_exact(w).enumerate() {
        out.extend_from_slice(&(y as i32).to_le_bytes());
        out.extend_from_slice(&((12 * w) as i32).to_le_bytes());
        for channel in [2, 1, 0] {
            for p in row {
                out.extend_from_slice(&p[channel].to_le_bytes());
            }
        }
    }
    out
}

/// Magic, version and the attribute list, terminated by a zero byte.
fn header(width: u32, height: u32) -> Vec<u8> {
    let mut out = MAGIC_VERSION.to_vec();
    let mut chlist = Vec::new();
    for name in ["B", "G", "R"] {
        chlist.extend_from_slice(name.as_bytes());
        chlist.push(0);
        chlist.extend_from_slice(&PIXEL_FLOAT.to_le_bytes());
        chlist.extend_from_slice(&[0, 0, 0, 0]); // pLinear, reserved x3
        chlist.extend_from_slice(&1i32.to_le_bytes()); // xSampling
        chlist.extend_from_slice(&1i32.to_le_bytes()); // ySampling
    }
    chlist.push(0);
    let window = box2i(width, height);
    attribute(&mut out, "channels", "chlist", &chlist);
    attribute(&mut out, "compression", "compression", &[0]);
    attribute(&mut out, "dataWindow", "box2i", &window);
    attribute(&mut out, "displayWindow", "box2i", &window);
    attribute(&mut out, "lineOrder", "lineOrder", &[0]);
    attribute(&mut out, "pixelAspectRatio", "float", &1.0f32.to_le_bytes());
    attribute(&mut out, "screenWindowCenter", "v2f", &[0; 8]);
    attribute(
        &mut out,
        "screenWindowWidth",
        "float",
        &1.0f32.to_le_bytes(),
    );
    out.push(0);
    out
}

fn box2i(width: u32, height: u32) -> Vec<u8> {
    let max_x = i32::try_from(width - 1).expect("EXR: width exceeds i32");
    let max_y = i32::try_from(height - 1).expect("EXR: height exceeds i32");
    [0, 0, max_x, max_y]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect()
}

fn attribute(out: &mut Vec<u8>, name: &str, kind: &str, value: &[u8]) {
    out.extend_from_slice(name.as_bytes());
    out.push(0);
    out.extend_from_slice(kind.as_bytes());
    out.push(0);
    out.extend_from_slice(&(value.len() as i32).to_le_bytes());
    out.extend_from_slice(value);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Header length for this fixed attribute set (independent of the image size).
    const HEADER_LEN: usize = 8
        + (9 + 7 + 4 + 55)
        + (12 + 12 + 4 + 1)
        + (11 + 6 + 4 + 16)
        + (14 + 6 + 4 + 16)
        + (10 + 10 + 4 + 1)
        + (17 + 6 + 4 + 4)
        + (19 + 4 + 4 + 8)
        + (18 + 6 + 4 + 4)
        + 1;

    fn sample(w: u32, h: u32) -> Image {
        let mut img = Image::new(w, h);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            *p = [i as f32, i as f32 + 0.25, -(i as f32) - 0.5];
        }
        img
    }

    #[test]
    fn magic_version_and_header() {
        let bytes = encode_exr(&sample(2, 1));
        assert_eq!(
            &bytes[..8],
            &[0x76, 0x2f, 0x31, 0x01, 0x02, 0x00, 0x00, 0x00]
        );
        assert_eq!(&bytes[8..24], b"channels\0chlist\0");
        assert_eq!(header(7, 3).len(), HEADER_LEN);
        assert_eq!(bytes[HEADER_LEN - 1], 0);
    }

    #[test]
    fn total_length_formula() {
        for (w, h) in [(1, 1), (2, 1), (5, 3), (17, 9)] {
            let len = encode_exr(&sample(w, h)).len();
            let (w, h) = (w as usize, h as usize);
            assert_eq!(len, HEADER_LEN + 8 * h + h * (8 + 12 * w));
        }
    }

    #[test]
    fn offsets_and_chunks() {
        let (w, h) = (3usize, 2usize);
        let img = sample(w as u32, h as u32);
        let bytes = encode_exr(&img);
        let u64_at = |i: usize| u64::from_le_bytes(bytes[i..i + 8].try_into().unwrap());
        let i32_at = |i: usize| i32::from_le_bytes(bytes[i..i + 4].try_into().unwrap());
        let f32_at = |i: usize| f32::from_le_bytes(bytes[i..i + 4].try_into().unwrap());
        for y in 0..h {
            let off = u64_at(HEADER_LEN + 8 * y) as usize;
            assert_eq!(off, HEADER_LEN + 8 * h + y * (8 + 12 * w));
            assert_eq!(i32_at(off), y as i32);
            assert_eq!(i32_at(off + 4), 12 * w as i32);
            for x in 0..w {
                let [r, g, b] = img.get(x as u32, y as u32);
                assert_eq!(f32_at(off + 8 + 4 * x), b);
                assert_eq!(f32_at(off + 8 + 4 * (w + x)), g);
                assert_eq!(f32_at(off + 8 + 4 * (2 * w + x)), r);
            }
        }
    }
}
