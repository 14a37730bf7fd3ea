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
pub(super) mod tests {
    //! An independent OpenEXR reader, written from the OpenEXR file layout specification
    //! (<https://openexr.com/en/latest/OpenEXRFileLayout.html>), not from the writer above.

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

    /// One header attribute: name, type name, value bytes.
    pub(in crate::image) struct Attribute {
        pub name: String,
        pub kind: String,
        pub value: Vec<u8>,
    }

    /// A decoded file: its header attributes in file order and its pixels.
    pub(in crate::image) struct ExrFile {
        pub attributes: Vec<Attribute>,
        pub image: Image,
    }

    impl ExrFile {
        /// The value of attribute `name`, checking its type name.
        pub fn attribute(&self, name: &str, kind: &str) -> &[u8] {
            let a = self
                .attributes
                .iter()
                .find(|a| a.name == name)
                .unwrap_or_else(|| panic!("missing attribute {name}"));
            assert_eq!(a.kind, kind, "type of attribute {name}");
            &a.value
        }
    }

    /// A little-endian cursor that reports reads past the end as errors.
    struct Cursor<'a> {
        bytes: &'a [u8],
        pos: usize,
    }

    impl<'a> Cursor<'a> {
        fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
            let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len());
            let end = end.ok_or_else(|| format!("truncated at byte {}", self.pos))?;
            let out = &self.bytes[self.pos..end];
            self.pos = end;
            Ok(out)
        }
        fn i32(&mut self) -> Result<i32, String> {
            Ok(i32::from_le_bytes(self.take(4)?.try_into().unwrap()))
        }
        fn u64(&mut self) -> Result<u64, String> {
            Ok(u64::from_le_bytes(self.take(8)?.try_into().unwrap()))
        }
        fn f32(&mut self) -> Result<f32, String> {
            Ok(f32::from_le_bytes(self.take(4)?.try_into().unwrap()))
        }
        /// A null-terminated string of 1 to 255 bytes (short names).
        fn name(&mut self) -> Result<String, String> {
            let len = self.bytes[self.pos..]
                .iter()
                .position(|&b| b == 0)
                .ok_or("unterminated string")?;
            if !(1..=255).contains(&len) {
                return Err(format!("string of {len} bytes at {}", self.pos));
            }
            let s = String::from_utf8(self.take(len)?.to_vec()).map_err(|e| e.to_string())?;
            self.take(1)?;
            Ok(s)
        }
    }

    /// Reads a single-part scanline OpenEXR file with NO_COMPRESSION (one scanline per chunk)
    /// and FLOAT channels R, G and B (in any order, each sampled 1x1), in any line order.
    /// Every scanline of the data window must be stored exactly once and the file must end
    /// with the last chunk.
    pub(in crate::image) fn read_exr(bytes: &[u8]) -> Result<ExrFile, String> {
        let mut c = Cursor { bytes, pos: 0 };
        // Magic number 20000630, then the version field: version 2 in the low byte, flags
        // "single-part scanline" (bit 9 tiled, 10 long names, 11 deep, 12 multi-part all 0).
        if c.i32()? != 20_000_630 {
            return Err("bad magic number".into());
        }
        let version = c.i32()?;
        if version & 0xff != 2 || version >> 8 != 0 {
            return Err(format!("unsupported version field {version:#x}"));
        }
        let mut attributes = Vec::new();
        while c.bytes.get(c.pos) != Some(&0) {
            let name = c.name()?;
            let kind = c.name()?;
            let size = usize::try_from(c.i32()?).map_err(|_| "negative attribute size")?;
            let value = c.take(size)?.to_vec();
            attributes.push(Attribute { name, kind, value });
        }
        c.take(1)?; // end of header
        let find = |name: &str, kind: &str| {
            let a = attributes.iter().find(|a| a.name == name);
            let a = a.ok_or_else(|| format!("missing attribute {name}"))?;
            if a.kind != kind {
                return Err(format!("attribute {name} has type {}", a.kind));
            }
            Ok(a.value.as_slice())
        };

        // chlist: per channel name, i32 pixel type, u8 pLinear, 3 reserved bytes, i32
        // xSampling, i32 ySampling; then a terminating null byte.
        let mut channels = Vec::new();
        let mut ch = Cursor {
            bytes: find("channels", "chlist")?,
            pos: 0,
        };
        while ch.bytes.get(ch.pos) != Some(&0) {
            let name = ch.name()?;
            let pixel_type = ch.i32()?;
            ch.take(4)?;
            let sampling = (ch.i32()?, ch.i32()?);
            if pixel_type != 2 || sampling != (1, 1) {
                return Err(format!("channel {name}: type {pixel_type}, {sampling:?}"));
            }
            channels.push(name);
        }
        if ch.pos + 1 != ch.bytes.len() {
            return Err("channel list not terminated".into());
        }
        let rgb = ["R", "G", "B"].map(|n| channels.iter().position(|c| c == n));
        let rgb = rgb.map(|i| i.ok_or("R, G and B channels required"));
        let rgb = [rgb[0]?, rgb[1]?, rgb[2]?];
        if channels.len() != 3 {
            return Err(format!("channels {channels:?}"));
        }
        if find("compression", "compression")? != [0] {
            return Err("only NO_COMPRESSION is supported".into());
        }
        let mut w = Cursor {
            bytes: find("dataWindow", "box2i")?,
            pos: 0,
        };
        let (x_min, y_min, x_max, y_max) = (w.i32()?, w.i32()?, w.i32()?, w.i32()?);
        if x_max < x_min || y_max < y_min {
            return Err("empty data window".into());
        }
        let width = (i64::from(x_max) - i64::from(x_min) + 1) as usize;
        let height = (i64::from(y_max) - i64::from(y_min) + 1) as usize;

        // Offset table: one u64 per chunk (one scanline per chunk without compression), then
        // each chunk: i32 y, i32 data size, then each channel's `width` values in turn.
        let offsets: Vec<u64> = (0..height).map(|_| c.u64()).collect::<Result<_, _>>()?;
        let mut image = Image::new(width as u32, height as u32);
        let mut seen = vec![false; height];
        let mut end = c.pos;
        for offset in offsets {
            let mut chunk = Cursor {
                bytes,
                pos: usize::try_from(offset).map_err(|e| e.to_string())?,
            };
            let y = i64::from(chunk.i32()?) - i64::from(y_min);
            let row = usize::try_from(y).ok().filter(|&r| r < height);
            let row = row.ok_or_else(|| format!("chunk at {offset} has y outside the window"))?;
            if std::mem::replace(&mut seen[row], true) {
                return Err(format!("scanline {row} stored twice"));
            }
            if chunk.i32()? as i64 != (width * channels.len() * 4) as i64 {
                return Err(format!("scanline {row}: wrong data size"));
            }
            let mut planes = Vec::new();
            for _ in &channels {
                let plane: Vec<f32> = (0..width).map(|_| chunk.f32()).collect::<Result<_, _>>()?;
                planes.push(plane);
            }
            let pixels = &mut image.pixels[row * width..(row + 1) * width];
            for (x, p) in pixels.iter_mut().enumerate() {
                *p = rgb.map(|i| planes[i][x]);
            }
            end = end.max(chunk.pos);
        }
        if end != bytes.len() {
            return Err(format!("{} bytes after the last chunk", bytes.len() - end));
        }
        Ok(ExrFile { attributes, image })
    }

    /// Distinct values in every channel, with signs, a NaN payload, a subnormal and infinity.
    fn sample(w: u32, h: u32) -> Image {
        let mut img = Image::new(w, h);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            *p = [i as f32, i as f32 + 0.25, -(i as f32) - 0.5];
        }
        img.pixels[0] = [f32::from_bits(0x7fc0_1234), 1e-40, f32::INFINITY];
        img
    }

    fn bits(img: &Image) -> Vec<u32> {
        img.pixels.iter().flatten().map(|v| v.to_bits()).collect()
    }

    fn f32s(values: &[f32]) -> Vec<u8> {
        values.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    fn i32s(values: &[i32]) -> Vec<u8> {
        values.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    #[test]
    fn magic_version_and_required_attributes() {
        let bytes = encode_exr(&sample(7, 3));
        assert_eq!(&bytes[..4], &[0x76, 0x2f, 0x31, 0x01], "magic 20000630");
        assert_eq!(
            &bytes[4..8],
            &[2, 0, 0, 0],
            "version 2, single-part scanline"
        );
        let file = read_exr(&bytes).unwrap();
        let names: Vec<&str> = file.attributes.iter().map(|a| a.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "channels",
                "compression",
                "dataWindow",
                "displayWindow",
                "lineOrder",
                "pixelAspectRatio",
                "screenWindowCenter",
                "screenWindowWidth"
            ]
        );
        // B, G, R (alphabetical), each FLOAT (2), pLinear 0, sampling 1x1.
        let mut chlist = Vec::new();
        for name in [b"B\0", b"G\0", b"R\0"] {
            chlist.extend_from_slice(name);
            chlist.extend_from_slice(&[2, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0]);
        }
        chlist.push(0);
        assert_eq!(file.attribute("channels", "chlist"), chlist);
        assert_eq!(file.attribute("compression", "compression"), [0]);
        let window = i32s(&[0, 0, 6, 2]);
        assert_eq!(file.attribute("dataWindow", "box2i"), window);
        assert_eq!(file.attribute("displayWindow", "box2i"), window);
        assert_eq!(
            file.attribute("lineOrder", "lineOrder"),
            [0],
            "INCREASING_Y"
        );
        assert_eq!(file.attribute("pixelAspectRatio", "float"), f32s(&[1.0]));
        assert_eq!(
            file.attribute("screenWindowCenter", "v2f"),
            f32s(&[0.0, 0.0])
        );
        assert_eq!(file.attribute("screenWindowWidth", "float"), f32s(&[1.0]));
        assert_eq!(header(7, 3).len(), HEADER_LEN);
    }

    #[test]
    fn decodes_to_the_source_pixels_bit_exact() {
        for (w, h) in [(1, 1), (2, 1), (1, 4), (3, 2), (17, 9)] {
            let img = sample(w, h);
            let back = read_exr(&encode_exr(&img)).unwrap().image;
            assert_eq!((back.width, back.height), (w, h));
            assert_eq!(bits(&back), bits(&img), "{w}x{h}");
        }
        let back = read_exr(&encode_exr(&sample(3, 2))).unwrap().image;
        assert_eq!(back.get(1, 1), [4.0, 4.25, -4.5]);
        assert_eq!(back.get(2, 0), [2.0, 2.25, -2.5]);
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
    fn reader_rejects_what_it_does_not_understand() {
        let good = encode_exr(&sample(3, 2));
        let mut bad_magic = good.clone();
        bad_magic[0] = 0x77;
        let mut tiled = good.clone();
        tiled[5] = 0x02; // bit 9: tiled
        let mut extra = good.clone();
        extra.push(0);
        for (bytes, msg) in [
            (&bad_magic[..], "bad magic"),
            (&tiled[..], "version field"),
            (&good[..good.len() - 1], "truncated"),
            (&extra[..], "1 bytes after"),
        ] {
            let err = read_exr(bytes).err().expect("an error");
            assert!(err.contains(msg), "{err:?} should contain {msg:?}");
        }
    }
}
