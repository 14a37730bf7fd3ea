//! OpenEXR writer: the `exr` crate (the `image` crate's OpenEXR backend) with ZIP compression.

use super::{Image, ImageError};
use exr::prelude::{
    Blocks, Compression, Encoding, LineOrder, SpecificChannels, Vec2, WritableImage,
};

/// ZIP compression (zlib, 16 scanlines per chunk), scanline blocks, increasing y.
///
/// `image::codecs::openexr::OpenExrEncoder` always writes RLE in 64x64 tiles; ZIP is lossless
/// and gives much smaller files for rendered images (a 480x270 bunny: 343 kB against 797 kB
/// with RLE tiles and 1.56 MB uncompressed), so the file is written through `exr` directly.
const ENCODING: Encoding = Encoding {
    compression: Compression::ZIP16,
    blocks: Blocks::ScanLines,
    line_order: LineOrder::Increasing,
};

/// Encodes `image` as a single-part scanline OpenEXR 2.0 file: channels B, G, R (alphabetical,
/// as EXR stores them) as 32-bit float, bit-exact linear radiance (NaN payloads included),
/// ZIP compression (16 scanlines per chunk; a chunk that would not shrink is stored raw),
/// increasing y, data and display window `(0, 0)-(w-1, h-1)`.
///
/// The bytes are deterministic: `exr` compresses with the pure-Rust `miniz_oxide` on the
/// calling thread (`non_parallel`, and no `rayon` feature), and the header carries no time
/// stamp. Fails if the image is inconsistent ([`Image::validate`]) or `exr` refuses it.
pub fn encode_exr(image: &Image) -> Result<Vec<u8>, ImageError> {
    image.validate()?;
    let (w, h) = (image.width as usize, image.height as usize);
    let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
        let [r, g, b] = image.pixels[p.y() * w + p.x()];
        (r, g, b)
    });
    let file = exr::image::Image::from_encoded_channels((w, h), ENCODING, channels);
    let mut out = std::io::Cursor::new(Vec::new());
    file.write()
        .non_parallel()
        .to_buffered(&mut out)
        .map_err(|e| ImageError::Exr(e.to_string()))?;
    Ok(out.into_inner())
}

#[cfg(test)]
pub(super) mod tests {
    //! An independent OpenEXR reader, written from the OpenEXR file layout specification
    //! (<https://openexr.com/en/latest/OpenEXRFileLayout.html>) and its description of ZIP
    //! compression, not from the writer: zlib is inflated by `fdeflate` (the `exr` crate
    //! deflates with `miniz_oxide` and inflates with `zune-inflate`).

    use super::*;

    /// One header attribute: name, type name, value bytes.
    pub(in crate::image) struct Attribute {
        pub name: String,
        pub kind: String,
        pub value: Vec<u8>,
    }

    /// A decoded file: its header attributes in file order, its pixels, and how many chunks
    /// were stored zlib-compressed and how many raw.
    pub(in crate::image) struct ExrFile {
        pub attributes: Vec<Attribute>,
        pub image: Image,
        pub compressed_chunks: usize,
        pub raw_chunks: usize,
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

    /// Undoes ZIP's two byte transforms (applied by the writer after splitting the scanline
    /// bytes, before zlib): the predictor (each byte stored as the difference to the previous
    /// byte, plus 128, modulo 256), then the interleave (the first half of the block holds
    /// the bytes at even offsets, the second half those at odd offsets).
    fn unzip_transforms(mut t: Vec<u8>) -> Vec<u8> {
        for i in 1..t.len() {
            t[i] = t[i - 1].wrapping_add(t[i]).wrapping_sub(128);
        }
        let (even, odd) = t.split_at(t.len().div_ceil(2));
        let mut out = Vec::with_capacity(t.len());
        for i in 0..t.len() {
            out.push(if i % 2 == 0 { even[i / 2] } else { odd[i / 2] });
        }
        out
    }

    /// Reads a single-part scanline OpenEXR file with FLOAT channels R, G and B (in any
    /// order, each sampled 1x1), NO_COMPRESSION (one scanline per chunk), ZIPS (one, zlib) or
    /// ZIP (16, zlib), in any line order. A compressed chunk whose data size equals the raw
    /// size is stored raw. Every chunk of the data window must be stored exactly once and the
    /// file must end with the last chunk.
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
        // Compression: 0 NO_COMPRESSION, 2 ZIPS_COMPRESSION, 3 ZIP_COMPRESSION.
        let (lines_per_chunk, zlib) = match find("compression", "compression")? {
            [0] => (1, false),
            [2] => (1, true),
            [3] => (16, true),
            other => return Err(format!("unsupported compression {other:?}")),
        };
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

        // Offset table: one u64 per chunk, then each chunk: i32 y of its first scanline,
        // i32 data size, then the data; uncompressed, that is each scanline in turn, and in a
        // scanline each channel's `width` values in turn.
        let chunk_count = height.div_ceil(lines_per_chunk);
        let offsets: Vec<u64> = (0..chunk_count)
            .map(|_| c.u64())
            .collect::<Result<_, _>>()?;
        let mut image = Image::new(width as u32, height as u32);
        let (mut compressed_chunks, mut raw_chunks) = (0, 0);
        let mut seen = vec![false; chunk_count];
        let mut end = c.pos;
        for offset in offsets {
            let mut chunk = Cursor {
                bytes,
                pos: usize::try_from(offset).map_err(|e| e.to_string())?,
            };
            let y = i64::from(chunk.i32()?) - i64::from(y_min);
            let first = usize::try_from(y).ok().filter(|&r| r < height);
            let first = first.filter(|r| r % lines_per_chunk == 0);
            let first = first.ok_or_else(|| format!("chunk at {offset}: bad y"))?;
            if std::mem::replace(&mut seen[first / lines_per_chunk], true) {
                return Err(format!("chunk of scanline {first} stored twice"));
            }
            let lines = lines_per_chunk.min(height - first);
            let raw_size = lines * width * channels.len() * 4;
            let size = usize::try_from(chunk.i32()?).map_err(|_| "negative chunk size")?;
            let data = chunk.take(size)?;
            let raw = if size == raw_size {
                raw_chunks += 1;
                data.to_vec()
            } else if zlib && size < raw_size {
                compressed_chunks += 1;
                let inflated = fdeflate::decompress_to_vec(data)
                    .map_err(|e| format!("chunk of scanline {first}: {e:?}"))?;
                if inflated.len() != raw_size {
                    return Err(format!("chunk of scanline {first}: wrong inflated size"));
                }
                unzip_transforms(inflated)
            } else {
                return Err(format!("chunk of scanline {first}: wrong data size"));
            };
            let mut values = Cursor {
                bytes: &raw,
                pos: 0,
            };
            for row in first..first + lines {
                let mut planes = Vec::new();
                for _ in &channels {
                    let plane: Vec<f32> =
                        (0..width).map(|_| values.f32()).collect::<Result<_, _>>()?;
                    planes.push(plane);
                }
                let pixels = &mut image.pixels[row * width..(row + 1) * width];
                for (x, p) in pixels.iter_mut().enumerate() {
                    *p = rgb.map(|i| planes[i][x]);
                }
            }
            end = end.max(chunk.pos);
        }
        if end != bytes.len() {
            return Err(format!("{} bytes after the last chunk", bytes.len() - end));
        }
        Ok(ExrFile {
            attributes,
            image,
            compressed_chunks,
            raw_chunks,
        })
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

    /// Pseudo-random bit patterns (no NaNs): data zlib cannot shrink.
    fn noise(w: u32, h: u32) -> Image {
        let mut img = Image::new(w, h);
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        for p in &mut img.pixels {
            *p = [(); 3].map(|()| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                f32::from_bits((state >> 32) as u32 & 0x3fff_ffff)
            });
        }
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
    fn unzip_transforms_by_hand() {
        // Bytes 1 2 3 4 5 interleave to 1 3 5 2 4; predicted: 1, then each difference + 128.
        assert_eq!(
            unzip_transforms(vec![1, 130, 130, 125, 130]),
            [1, 2, 3, 4, 5]
        );
    }

    #[test]
    fn magic_version_and_required_attributes() {
        let bytes = encode_exr(&sample(7, 3)).unwrap();
        assert_eq!(&bytes[..4], &[0x76, 0x2f, 0x31, 0x01], "magic 20000630");
        assert_eq!(
            &bytes[4..8],
            &[2, 0, 0, 0],
            "version 2, single-part scanline"
        );
        let file = read_exr(&bytes).unwrap();
        let mut names: Vec<&str> = file.attributes.iter().map(|a| a.name.as_str()).collect();
        names.sort_unstable();
        assert_eq!(
            names,
            [
                "channels",
                "chunkCount",
                "compression",
                "dataWindow",
                "displayWindow",
                "lineOrder",
                "pixelAspectRatio",
                "screenWindowCenter",
                "screenWindowWidth",
                "type"
            ]
        );
        // The two OpenEXR 2.0 part attributes (optional in a single-part file): the part
        // type and its number of chunks (3 scanlines, one chunk of up to 16).
        assert_eq!(file.attribute("type", "string"), b"scanlineimage");
        assert_eq!(file.attribute("chunkCount", "int"), i32s(&[1]));
        let tall = read_exr(&encode_exr(&sample(2, 33)).unwrap()).unwrap();
        assert_eq!(tall.attribute("chunkCount", "int"), i32s(&[3]));
        // B, G, R (alphabetical), each FLOAT (2), pLinear 0, sampling 1x1.
        let mut chlist = Vec::new();
        for name in [b"B\0", b"G\0", b"R\0"] {
            chlist.extend_from_slice(name);
            chlist.extend_from_slice(&[2, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0]);
        }
        chlist.push(0);
        assert_eq!(file.attribute("channels", "chlist"), chlist);
        assert_eq!(file.attribute("compression", "compression"), [3], "ZIP");
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
    }

    #[test]
    fn decodes_to_the_source_pixels_bit_exact() {
        // Heights below, at and across the 16-scanline chunks.
        for (w, h) in [
            (1, 1),
            (2, 1),
            (1, 4),
            (3, 2),
            (17, 9),
            (5, 16),
            (4, 17),
            (9, 40),
        ] {
            for img in [sample(w, h), noise(w, h)] {
                let bytes = encode_exr(&img).unwrap();
                assert_eq!(encode_exr(&img).unwrap(), bytes, "deterministic");
                let back = read_exr(&bytes).unwrap().image;
                assert_eq!((back.width, back.height), (w, h));
                assert_eq!(bits(&back), bits(&img), "{w}x{h}");
            }
        }
        let back = read_exr(&encode_exr(&sample(3, 2)).unwrap()).unwrap().image;
        assert_eq!(back.get(1, 1), [4.0, 4.25, -4.5]);
        assert_eq!(back.get(2, 0), [2.0, 2.25, -2.5]);
    }

    #[test]
    fn smooth_images_are_compressed_and_noise_is_stored_raw() {
        let (w, h) = (64, 40);
        let uncompressed = w as usize * h as usize * 12;
        let mut smooth = Image::new(w, h);
        for y in 0..h {
            for x in 0..w {
                smooth.set(x, y, [x as f32 / 64.0, y as f32 / 40.0, 0.5]);
            }
        }
        let bytes = encode_exr(&smooth).unwrap();
        let file = read_exr(&bytes).unwrap();
        assert_eq!(file.image, smooth);
        assert_eq!((file.compressed_chunks, file.raw_chunks), (3, 0));
        assert!(bytes.len() * 4 < uncompressed, "{} bytes", bytes.len());

        let file = read_exr(&encode_exr(&noise(w, h)).unwrap()).unwrap();
        assert_eq!((file.compressed_chunks, file.raw_chunks), (0, 3));
    }

    #[test]
    fn exr_rejects_bad_images() {
        assert!(encode_exr(&Image::new(0, 3)).is_err());
        let mut img = Image::new(2, 2);
        img.pixels.pop();
        assert!(encode_exr(&img).is_err());
    }

    #[test]
    fn reader_rejects_what_it_does_not_understand() {
        let good = encode_exr(&sample(3, 2)).unwrap();
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
