//! Record layouts of the shuffle blocks, column-wise (see [`crate::shuffle::columns`]): records
//! are sorted by their key, the first key column is delta-encoded, floats are byte planes.

use super::PipelineError;
use crate::hits::Hit;
use crate::shading::SurfacePoint;
use crate::shuffle::columns::{ColumnError, ColumnReader, ColumnWriter};
use crate::shuffle::{RecordKind, decode_block, encode_block};
use glam::Vec3;

/// A camera sample's hit with the shading data of its surface. CastMap emits candidates (kind
/// `CastCandidate`), CastReduce the nearest per sample (kind `Hit`). Key: (pixel, sample).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHit {
    /// Row-major pixel index from the top-left (x = pixel % width).
    pub pixel: u32,
    /// Sample index within the pixel, `0..spp`.
    pub sample: u32,
    /// Distance from the eye along the unit camera ray, in world units.
    pub t: f32,
    /// Global triangle id (scene order).
    pub triangle: u32,
    /// Position, normals and reflectance of the hit, for shading.
    pub surface: SurfacePoint,
}

/// A shadow segment to test against one split: from `origin` to light `light` (the ray is
/// rebuilt with [`crate::shading::shadow_ray`]). Key: (pixel, sample, light).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowQuery {
    /// Row-major pixel index of the hit sample.
    pub pixel: u32,
    /// Sample index within the pixel, `0..spp`.
    pub sample: u32,
    /// Index of the light in the plan's light list.
    pub light: u32,
    /// Segment start in world space: the hit point pushed off the surface by its error bound.
    pub origin: Vec3,
}

/// A (pixel, sample, light) whose shadow segment one split blocks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Occluded {
    /// Row-major pixel index (the first sort key).
    pub pixel: u32,
    /// Sample index within the pixel, `0..spp`.
    pub sample: u32,
    /// Index of the light in the plan's light list.
    pub light: u32,
}

/// A span's finished pixels: the mean radiance of each and, unless left out, the hit of its
/// sample 0 (`triangles` and `ts` either hold one value per pixel or are both empty: a job that
/// stores no hit buffer leaves them out of the blocks it stores, [`PixelBlock::without_hits`]).
#[derive(Clone, Debug, PartialEq)]
pub struct PixelBlock {
    /// First pixel (row-major index) of the span.
    pub start: u64,
    /// Linear RGB radiance of each pixel from `start` on, the mean of its `spp` samples.
    pub colours: Vec<[f32; 3]>,
    /// Triangle id of sample 0, `u32::MAX` on a miss.
    pub triangles: Vec<u32>,
    /// Distance of sample 0, `+inf` on a miss.
    pub ts: Vec<f32>,
}

impl PixelBlock {
    /// An empty block for the `n` pixels from `start` on, with room for them.
    pub fn with_capacity(start: u64, n: usize) -> PixelBlock {
        PixelBlock {
            start,
            colours: Vec::with_capacity(n),
            triangles: Vec::with_capacity(n),
            ts: Vec::with_capacity(n),
        }
    }

    /// The block with its sample-0 hits left out (both lists empty), for a job that stores no
    /// hit buffer: a fifth of a 1-spp job's pixel bytes fewer to compress, store and read.
    pub fn without_hits(mut self) -> PixelBlock {
        self.triangles = Vec::new();
        self.ts = Vec::new();
        self
    }

    /// Whether the block holds its pixels' sample-0 hits (one per pixel).
    pub fn has_hits(&self) -> bool {
        self.triangles.len() == self.colours.len()
    }

    /// Appends pixels: their colours and the hits of their samples 0.
    pub fn extend(&mut self, colours: impl IntoIterator<Item = [f32; 3]>, hits: &[Hit]) {
        self.colours.extend(colours);
        self.triangles.extend(hits.iter().map(|h| h.triangle));
        self.ts.extend(hits.iter().map(|h| h.t));
    }
}

pub(super) fn corrupt(key: &str, e: ColumnError) -> PipelineError {
    PipelineError::Corrupt(format!("shuffle block {key}: {e}"))
}

/// Writes vectors as three f32 delta columns (x, y, z): neighbouring records' vectors are close.
pub(super) fn put_vec3s(w: &mut ColumnWriter, values: impl Iterator<Item = Vec3> + Clone) {
    for axis in 0..3 {
        w.put_f32_delta(&values.clone().map(|v| v[axis]).collect::<Vec<_>>());
    }
}

/// Reads three f32 columns of `n` values each as vectors.
pub(super) fn read_vec3s(
    r: &mut ColumnReader,
    n: usize,
    key: &str,
) -> Result<Vec<Vec3>, PipelineError> {
    let mut axes = Vec::with_capacity(3);
    for axis in ["x", "y", "z"] {
        let values = r.read_f32().map_err(|e| corrupt(key, e))?;
        check_len(key, axis, values.len(), n)?;
        axes.push(values);
    }
    Ok((0..n)
        .map(|i| Vec3::new(axes[0][i], axes[1][i], axes[2][i]))
        .collect())
}

pub(super) fn check_len(
    key: &str,
    what: &str,
    found: usize,
    expected: usize,
) -> Result<(), PipelineError> {
    if found == expected {
        Ok(())
    } else {
        Err(PipelineError::Corrupt(format!(
            "shuffle block {key}: column {what} has {found} values, expected {expected}"
        )))
    }
}

/// Encodes surface hits (sorted by (pixel, sample)) as a block of `kind`.
pub fn encode_surface_hits(kind: RecordKind, hits: &[SurfaceHit]) -> Vec<u8> {
    let mut w = ColumnWriter::new();
    w.put_u32_sorted_delta(&hits.iter().map(|h| h.pixel).collect::<Vec<_>>());
    w.put_u32(&hits.iter().map(|h| h.sample).collect::<Vec<_>>());
    w.put_f32_delta(&hits.iter().map(|h| h.t).collect::<Vec<_>>());
    w.put_u32(&hits.iter().map(|h| h.triangle).collect::<Vec<_>>());
    let s = hits.iter().map(|h| h.surface);
    put_vec3s(&mut w, s.clone().map(|s| s.p));
    put_vec3s(&mut w, s.clone().map(|s| s.p_error));
    put_vec3s(&mut w, s.clone().map(|s| s.n_geo));
    // Flat shading (the common case) has n_shade == n_geo and the shadow point at p: store only
    // the others. Flag bit 0: the shading normal is stored; bit 1: the shadow point and its
    // error bound are (after kd, and only when some record has one, so blocks of flat scenes
    // keep their bytes).
    let flags: Vec<u8> = hits.iter().map(|h| surface_flags(&h.surface)).collect();
    w.put_bytes(&flags);
    let with = |bit: u8| {
        let flags = &flags;
        s.clone()
            .enumerate()
            .filter(move |(i, _)| flags[*i] & bit != 0)
            .map(|(_, s)| s)
    };
    put_vec3s(&mut w, with(SMOOTH_NORMAL).map(|s| s.n_shade));
    put_vec3s(&mut w, s.clone().map(|s| Vec3::from(s.kd)));
    if flags.iter().any(|f| f & SHADOW_POINT != 0) {
        put_vec3s(&mut w, with(SHADOW_POINT).map(|s| s.p_shadow));
        put_vec3s(&mut w, with(SHADOW_POINT).map(|s| s.p_shadow_error));
    }
    encode_block(kind, hits.len() as u64, w.as_bytes())
}

/// Flag of a surface hit record whose shading normal differs from its geometric normal.
const SMOOTH_NORMAL: u8 = 1;
/// Flag of a surface hit record whose shadow point or its bound differs from `p`, `p_error`.
const SHADOW_POINT: u8 = 2;

fn surface_flags(s: &SurfacePoint) -> u8 {
    let bits = |v: Vec3| v.to_array().map(f32::to_bits);
    let mut f = 0;
    if bits(s.n_shade) != bits(s.n_geo) {
        f |= SMOOTH_NORMAL;
    }
    if bits(s.p_shadow) != bits(s.p) || bits(s.p_shadow_error) != bits(s.p_error) {
        f |= SHADOW_POINT;
    }
    f
}

/// Decodes a block written by [`encode_surface_hits`]; `raw_len` receives the raw size.
pub fn decode_surface_hits(
    key: &str,
    bytes: &[u8],
    kind: RecordKind,
) -> Result<Vec<SurfaceHit>, PipelineError> {
    let block =
        decode_block(key, bytes, kind).map_err(|e| PipelineError::Corrupt(e.to_string()))?;
    let mut r = ColumnReader::new(&block.raw);
    let c = |e| corrupt(key, e);
    let pixels = r.read_u32_sorted_delta().map_err(c)?;
    let n = pixels.len();
    check_len(key, "pixel", n, block.record_count as usize)?;
    let samples = r.read_u32().map_err(c)?;
    let ts = r.read_f32().map_err(c)?;
    let triangles = r.read_u32().map_err(c)?;
    check_len(key, "sample", samples.len(), n)?;
    check_len(key, "t", ts.len(), n)?;
    check_len(key, "triangle", triangles.len(), n)?;
    let p = read_vec3s(&mut r, n, key)?;
    let p_error = read_vec3s(&mut r, n, key)?;
    let n_geo = read_vec3s(&mut r, n, key)?;
    let flags = r.read_bytes().map_err(c)?.to_vec();
    check_len(key, "smooth", flags.len(), n)?;
    if flags.iter().any(|&f| f > SMOOTH_NORMAL | SHADOW_POINT) {
        return Err(PipelineError::Corrupt(format!(
            "shuffle block {key}: smooth flags are not 0 to 3"
        )));
    }
    let count = |bit: u8| flags.iter().filter(|&&f| f & bit != 0).count();
    let mut n_smooth = read_vec3s(&mut r, count(SMOOTH_NORMAL), key)?.into_iter();
    let kd = read_vec3s(&mut r, n, key)?;
    let shadow_count = count(SHADOW_POINT);
    let (mut q, mut q_error) = if shadow_count > 0 {
        (
            read_vec3s(&mut r, shadow_count, key)?.into_iter(),
            read_vec3s(&mut r, shadow_count, key)?.into_iter(),
        )
    } else {
        (Vec::new().into_iter(), Vec::new().into_iter())
    };
    r.finish().map_err(c)?;
    // (The counts were checked: the iterators hold one value per flagged record.)
    let pick = |i: usize, bit: u8, it: &mut std::vec::IntoIter<Vec3>, own: Vec3| {
        if flags[i] & bit != 0 {
            it.next().unwrap_or(own)
        } else {
            own
        }
    };
    let mut n_shade = Vec::with_capacity(n);
    let mut p_shadow = Vec::with_capacity(n);
    let mut p_shadow_error = Vec::with_capacity(n);
    for i in 0..n {
        n_shade.push(pick(i, SMOOTH_NORMAL, &mut n_smooth, n_geo[i]));
        p_shadow.push(pick(i, SHADOW_POINT, &mut q, p[i]));
        p_shadow_error.push(pick(i, SHADOW_POINT, &mut q_error, p_error[i]));
    }
    let hits = (0..n)
        .map(|i| SurfaceHit {
            pixel: pixels[i],
            sample: samples[i],
            t: ts[i],
            triangle: triangles[i],
            surface: SurfacePoint {
                p: p[i],
                p_error: p_error[i],
                n_geo: n_geo[i],
                n_shade: n_shade[i],
                p_shadow: p_shadow[i],
                p_shadow_error: p_shadow_error[i],
                kd: kd[i].to_array(),
            },
        })
        .collect();
    Ok(hits)
}

/// Writes (pixel, sample, light) keys sorted by pixel as three columns.
fn put_keys(w: &mut ColumnWriter, keys: impl Iterator<Item = Occluded> + Clone) {
    w.put_u32_sorted_delta(&keys.clone().map(|k| k.pixel).collect::<Vec<_>>());
    w.put_u32(&keys.clone().map(|k| k.sample).collect::<Vec<_>>());
    w.put_u32(&keys.map(|k| k.light).collect::<Vec<_>>());
}

/// Reads the columns of [`put_keys`]; there must be `count` keys.
fn read_keys(r: &mut ColumnReader, key: &str, count: u64) -> Result<Vec<Occluded>, PipelineError> {
    let c = |e| corrupt(key, e);
    let pixels = r.read_u32_sorted_delta().map_err(c)?;
    let n = pixels.len();
    check_len(key, "pixel", n, count as usize)?;
    let samples = r.read_u32().map_err(c)?;
    let lights = r.read_u32().map_err(c)?;
    check_len(key, "sample", samples.len(), n)?;
    check_len(key, "light", lights.len(), n)?;
    Ok((0..n)
        .map(|i| Occluded {
            pixel: pixels[i],
            sample: samples[i],
            light: lights[i],
        })
        .collect())
}

/// Encodes shadow queries (sorted by (pixel, sample, light)).
pub fn encode_queries(queries: &[ShadowQuery]) -> Vec<u8> {
    let mut w = ColumnWriter::new();
    put_keys(
        &mut w,
        queries.iter().map(|q| Occluded {
            pixel: q.pixel,
            sample: q.sample,
            light: q.light,
        }),
    );
    put_vec3s(&mut w, queries.iter().map(|q| q.origin));
    encode_block(RecordKind::ShadowQuery, queries.len() as u64, w.as_bytes())
}

/// Decodes a block written by [`encode_queries`].
pub fn decode_queries(key: &str, bytes: &[u8]) -> Result<Vec<ShadowQuery>, PipelineError> {
    let block = decode_block(key, bytes, RecordKind::ShadowQuery)
        .map_err(|e| PipelineError::Corrupt(e.to_string()))?;
    let mut r = ColumnReader::new(&block.raw);
    let keys = read_keys(&mut r, key, block.record_count)?;
    let origins = read_vec3s(&mut r, keys.len(), key)?;
    r.finish().map_err(|e| corrupt(key, e))?;
    Ok(keys
        .into_iter()
        .zip(origins)
        .map(|(k, origin)| ShadowQuery {
            pixel: k.pixel,
            sample: k.sample,
            light: k.light,
            origin,
        })
        .collect())
}

/// Encodes occluded keys (sorted).
pub fn encode_occluded(keys: &[Occluded]) -> Vec<u8> {
    let mut w = ColumnWriter::new();
    put_keys(&mut w, keys.iter().copied());
    encode_block(RecordKind::ShadowResult, keys.len() as u64, w.as_bytes())
}

/// Decodes a block written by [`encode_occluded`].
pub fn decode_occluded(key: &str, bytes: &[u8]) -> Result<Vec<Occluded>, PipelineError> {
    let block = decode_block(key, bytes, RecordKind::ShadowResult)
        .map_err(|e| PipelineError::Corrupt(e.to_string()))?;
    let mut r = ColumnReader::new(&block.raw);
    let keys = read_keys(&mut r, key, block.record_count)?;
    r.finish().map_err(|e| corrupt(key, e))?;
    Ok(keys)
}

/// Encodes a span's pixels.
pub fn encode_pixels(block: &PixelBlock) -> Vec<u8> {
    let mut w = ColumnWriter::new();
    w.put_u32(&[(block.start >> 32) as u32, block.start as u32]);
    put_vec3s(&mut w, block.colours.iter().map(|c| Vec3::from(*c)));
    // Whether the sample-0 hits follow (1) or were left out (0).
    let hits = block.has_hits();
    debug_assert!(hits || (block.triangles.is_empty() && block.ts.is_empty()));
    w.put_bytes(&[u8::from(hits)]);
    if hits {
        w.put_u32(&block.triangles);
        w.put_f32(&block.ts);
    }
    encode_block(
        RecordKind::PixelColor,
        block.colours.len() as u64,
        w.as_bytes(),
    )
}

/// Decodes a block written by [`encode_pixels`].
pub fn decode_pixels(key: &str, bytes: &[u8]) -> Result<PixelBlock, PipelineError> {
    let block = decode_block(key, bytes, RecordKind::PixelColor)
        .map_err(|e| PipelineError::Corrupt(e.to_string()))?;
    let mut r = ColumnReader::new(&block.raw);
    let c = |e| corrupt(key, e);
    let start = r.read_u32().map_err(c)?;
    check_len(key, "start", start.len(), 2)?;
    let n = block.record_count as usize;
    let colours = read_vec3s(&mut r, n, key)?;
    let (triangles, ts) = match r.read_bytes().map_err(c)? {
        [1] => {
            let triangles = r.read_u32().map_err(c)?;
            let ts = r.read_f32().map_err(c)?;
            check_len(key, "triangle", triangles.len(), n)?;
            check_len(key, "t", ts.len(), n)?;
            (triangles, ts)
        }
        [0] => (Vec::new(), Vec::new()),
        other => {
            return Err(PipelineError::Corrupt(format!(
                "shuffle block {key}: column hits holds {other:?}, expected [0] or [1]"
            )));
        }
    };
    r.finish().map_err(c)?;
    Ok(PixelBlock {
        start: (u64::from(start[0]) << 32) | u64::from(start[1]),
        colours: colours.into_iter().map(|v| v.to_array()).collect(),
        triangles,
        ts,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn surface(i: u32) -> SurfacePoint {
        let f = i as f32;
        let p = Vec3::new(f, 2.0 * f, -f);
        let p_error = Vec3::splat(1e-6 * f);
        // Every third record has a shadow point off p, one in five a shading normal.
        let (p_shadow, p_shadow_error) = if i.is_multiple_of(3) {
            (p + Vec3::new(0.0, 0.01 * f, 0.0), p_error * 2.0)
        } else {
            (p, p_error)
        };
        SurfacePoint {
            p,
            p_error,
            n_geo: Vec3::Y,
            n_shade: if i.is_multiple_of(5) {
                Vec3::new(0.0, 0.6, 0.8)
            } else {
                Vec3::Y
            },
            p_shadow,
            p_shadow_error,
            kd: [0.7, 0.5, f / 100.0],
        }
    }

    /// Flat records (shading normal n_geo, shadow point p) store neither, and a block of flat
    /// records has no shadow point columns at all: its bytes are those of the layout before
    /// the shadow point, pinned here.
    #[test]
    fn flat_surface_hits_store_no_shading_normal_or_shadow_point() {
        let flat = |i: u32| {
            let s = surface(i);
            SurfacePoint {
                n_shade: s.n_geo,
                p_shadow: s.p,
                p_shadow_error: s.p_error,
                ..s
            }
        };
        let hits: Vec<SurfaceHit> = (0..40)
            .map(|i| SurfaceHit {
                pixel: i * 2,
                sample: 0,
                t: 2.0 + i as f32 / 3.0,
                triangle: i / 4,
                surface: flat(i),
            })
            .collect();
        let bytes = encode_surface_hits(RecordKind::Hit, &hits);
        assert_eq!(
            decode_surface_hits("k", &bytes, RecordKind::Hit).unwrap(),
            hits
        );
        assert_eq!(
            crate::digest::fnv1a64(&bytes),
            FLAT_BLOCK_DIGEST,
            "{} bytes",
            bytes.len()
        );
        let mut one = hits.clone();
        one[7].surface.p_shadow.y += 0.5;
        let more = encode_surface_hits(RecordKind::Hit, &one);
        assert!(more.len() > bytes.len());
        assert_eq!(
            decode_surface_hits("k", &more, RecordKind::Hit).unwrap(),
            one
        );
    }

    /// The digest of the flat block above, as the encoder before shadow points wrote it.
    const FLAT_BLOCK_DIGEST: u64 = 0xbe2d_ed94_88e0_bcd5;

    #[test]
    fn all_record_kinds_round_trip_bit_exactly() {
        let hits: Vec<SurfaceHit> = (0..50)
            .map(|i| SurfaceHit {
                pixel: i * 3,
                sample: i % 4,
                t: 1.0 + i as f32 / 7.0,
                triangle: 1000 - i,
                surface: surface(i),
            })
            .collect();
        let bytes = encode_surface_hits(RecordKind::Hit, &hits);
        assert_eq!(
            decode_surface_hits("k", &bytes, RecordKind::Hit).unwrap(),
            hits
        );
        let e = decode_surface_hits("k", &bytes, RecordKind::CastCandidate).unwrap_err();
        assert!(e.to_string().contains("k"));

        let queries: Vec<ShadowQuery> = (0..20)
            .map(|i| ShadowQuery {
                pixel: i,
                sample: 0,
                light: i % 2,
                origin: Vec3::splat(i as f32),
            })
            .collect();
        assert_eq!(
            decode_queries("k", &encode_queries(&queries)).unwrap(),
            queries
        );

        let occluded: Vec<Occluded> = (0..30)
            .map(|i| Occluded {
                pixel: i / 2,
                sample: i % 2,
                light: 0,
            })
            .collect();
        assert_eq!(
            decode_occluded("k", &encode_occluded(&occluded)).unwrap(),
            occluded
        );

        let pixels = PixelBlock {
            start: (1 << 33) + 5,
            colours: vec![[0.1, 0.2, 0.3], [1.0, 0.0, f32::MIN_POSITIVE]],
            triangles: vec![7, u32::MAX],
            ts: vec![2.5, f32::INFINITY],
        };
        assert_eq!(decode_pixels("k", &encode_pixels(&pixels)).unwrap(), pixels);
    }

    /// A pixel block without its hits decodes as it was (no hits, the same colours), in fewer
    /// bytes; a hits flag other than 0 or 1 is refused by name.
    #[test]
    fn pixel_blocks_without_hits_round_trip_and_a_bad_flag_is_named() {
        let colours: Vec<[f32; 3]> = (0..500).map(|i| [i as f32 * 0.01, 0.5, 1.0]).collect();
        let pixels = PixelBlock {
            start: 40,
            triangles: (0..500).map(|i| i * 7 % 13).collect(),
            ts: (0..500).map(|i| 1.0 + i as f32 * 0.37).collect(),
            colours,
        };
        let bare = pixels.clone().without_hits();
        assert!(pixels.has_hits() && !bare.has_hits());
        assert_eq!((bare.start, &bare.colours), (pixels.start, &pixels.colours));
        let (with, without) = (encode_pixels(&pixels), encode_pixels(&bare));
        assert_eq!(decode_pixels("k", &without).unwrap(), bare);
        assert!(
            without.len() < with.len(),
            "{} >= {}",
            without.len(),
            with.len()
        );

        let mut w = ColumnWriter::new();
        w.put_u32(&[0, 3]);
        put_vec3s(&mut w, [Vec3::ONE].into_iter());
        w.put_bytes(&[2]);
        let bytes = encode_block(RecordKind::PixelColor, 1, w.as_bytes());
        let e = decode_pixels("jobs/j/render/3", &bytes).unwrap_err();
        assert_eq!(
            e.to_string(),
            "shuffle block jobs/j/render/3: column hits holds [2], expected [0] or [1]"
        );
    }

    /// Blocks written before the f32 delta columns (every float as plain byte planes, tag 3)
    /// decode to the same queries as the current layout.
    #[test]
    fn plain_f32_columns_of_earlier_blocks_still_decode() {
        let queries: Vec<ShadowQuery> = (0..20)
            .map(|i| ShadowQuery {
                pixel: i,
                sample: 1,
                light: i % 3,
                origin: Vec3::new(i as f32, -0.0, f32::MIN_POSITIVE * i as f32),
            })
            .collect();
        let mut w = ColumnWriter::new();
        w.put_u32_sorted_delta(&queries.iter().map(|q| q.pixel).collect::<Vec<_>>());
        w.put_u32(&queries.iter().map(|q| q.sample).collect::<Vec<_>>());
        w.put_u32(&queries.iter().map(|q| q.light).collect::<Vec<_>>());
        for axis in 0..3 {
            w.put_f32(&queries.iter().map(|q| q.origin[axis]).collect::<Vec<_>>());
        }
        let old = encode_block(RecordKind::ShadowQuery, 20, w.as_bytes());
        let current = encode_queries(&queries);
        assert_ne!(old, current);
        let decoded = decode_queries("k", &old).unwrap();
        assert_eq!(decoded, decode_queries("k", &current).unwrap());
        let bits = |q: &[ShadowQuery]| -> Vec<[u32; 3]> {
            q.iter()
                .map(|q| q.origin.to_array().map(f32::to_bits))
                .collect()
        };
        assert_eq!(bits(&decoded), bits(&queries));
    }
}
