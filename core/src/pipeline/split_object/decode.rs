//! `decode_split`: one pass over the raw bytes as zstd produces them into a small reused buffer
//! ([`read_block`]), each section converted straight into its final array and checked as it
//! goes; nothing holds the raw bytes whole.

use super::{
    Counts, HEADER_BYTES, PLANE_GROUP, SPLIT_FORMAT_VERSION, ShadingTable, SplitObject,
    TEXTURED_BYTES,
};
use crate::bvh::{Aabb, NODE_BYTES, PartsLoader};
use crate::pipeline::PipelineError;
use crate::shuffle::columns::ColumnReader;
use crate::shuffle::{MAX_TAKE, RawStream, RecordKind, read_block};
use crate::texture::TexturedCorners;
use glam::Vec3;

/// Decodes and validates a split object read from `key`. Every error is one line naming `key`
/// and what is wrong (see the module docs for what is checked). A damaged block gives the
/// block's error (as `decode_block` names it) before anything its raw bytes say, and nothing is
/// returned before the raw CRC has vouched for every raw byte.
pub fn decode_split(key: &str, bytes: &[u8]) -> Result<SplitObject, PipelineError> {
    read_block(key, bytes, RecordKind::SplitObject, read_object)
        .map_err(|e| PipelineError::Corrupt(e.to_string()))?
        .map_err(|what| PipelineError::Corrupt(format!("split object {key}: {what}")))
}

/// What a reader says when the stream ends early; never shown, as `finish` then fails.
const ENDED: &str = "raw bytes end early";

/// The format version of a split object written before version 3, whose raw bytes are columns
/// starting with a u32 column that holds the version; `None` for anything else (raw bytes of
/// version 3 and later start with the version word, which is no u32 column's tag). `head` is
/// the first [`HEADER_BYTES`] raw bytes, or all of them if fewer (enough for that column).
fn older_version(head: &[u8]) -> Option<u32> {
    ColumnReader::new(head).read_u32().ok()?.first().copied()
}

fn read_object(stream: &mut RawStream<'_>) -> Result<SplitObject, String> {
    let raw_len = stream.raw_len();
    let head = stream
        .take(raw_len.min(HEADER_BYTES as u64) as usize)
        .ok_or(ENDED)?;
    if let Some(old) = older_version(head) {
        return Err(format!(
            "format version {old}, this build reads {SPLIT_FORMAT_VERSION}"
        ));
    }
    let Some(&head) = head.first_chunk::<HEADER_BYTES>() else {
        return Err(format!(
            "{raw_len} raw bytes, shorter than the {HEADER_BYTES}-byte header"
        ));
    };
    let (words, _) = head.as_chunks::<4>();
    let word = |k: usize| u32::from_le_bytes(words[k]);
    let version = word(0);
    if version != SPLIT_FORMAT_VERSION {
        return Err(format!(
            "format version {version}, this build reads {SPLIT_FORMAT_VERSION}"
        ));
    }
    let [split, n, w, p, v, c, k, x] = [1, 2, 3, 4, 5, 6, 7, 8].map(word);
    if c > n {
        return Err(format!("header declares {c} triangles with normals of {n}"));
    }
    if x > n {
        return Err(format!("header declares {x} textured triangles of {n}"));
    }
    if k > n || (k == 0 && n > 0) {
        return Err(format!("header declares {k} kd values for {n} triangles"));
    }
    let expected: u64 = Counts {
        n,
        w,
        p,
        v,
        c,
        k,
        x,
    }
    .section_lengths()
    .iter()
    .sum();
    let body = raw_len - HEADER_BYTES as u64;
    if body != expected {
        return Err(format!(
            "{body} bytes after the header, whose counts call for {expected}"
        ));
    }
    // The sections sum to the raw length (at most MAX_RAW_LEN), so every count below fits in
    // usize and every array reserved is at most a few times the raw bytes that fill it.
    let [n, w, p, v, c, k, x] = [n, w, p, v, c, k, x].map(|x| x as usize);
    let f = |b: &[u8; 4]| f32::from_le_bytes(*b);
    let vec3 = |b: &[[u8; 4]]| Vec3::new(f(&b[0]), f(&b[1]), f(&b[2]));
    let bounds = Aabb {
        lo: vec3(&words[9..12]),
        hi: vec3(&words[12..15]),
    };

    let mut bvh = PartsLoader::new(bounds, w);
    let mut nodes_error = None;
    read_units(stream, w, NODE_BYTES, |nodes| {
        // Whole nodes: push_nodes cannot fail here.
        if let Err(e) = bvh.push_nodes(nodes) {
            nodes_error.get_or_insert(e.to_string());
        }
    })?;
    if let Some(e) = nodes_error {
        return Err(e);
    }
    let mut lanes = hort_huge_pages::vec_with_capacity(p);
    read_units(stream, p, 1, |b| lanes.extend_from_slice(b))?;
    bvh.set_lanes(lanes, n).map_err(|e| e.to_string())?;

    let mut vertex_bits: Vec<u32> = hort_huge_pages::vec_with_capacity(3 * v);
    read_planes_into(stream, 3 * v, &mut vertex_bits, |_| Ok(()))?;
    let (vertices, _) = vertex_bits.as_chunks::<3>();
    let corner = |i: u32| {
        vertices
            .get(i as usize)
            .map_or(Vec3::ZERO, |w| Vec3::from_array(w.map(f32::from_bits)))
    };
    let mut corners = FirstUse::new(v, "vertex");
    read_planes(stream, 3 * n, |words| {
        corners.check(words)?;
        let (triangles, _) = words.as_chunks::<3>();
        for &[a, b, c] in triangles {
            bvh.push_triangle([corner(a), corner(b), corner(c)]);
        }
        Ok(())
    })?;
    corners.finish()?;
    drop(vertex_bits);

    let mut ids = hort_huge_pages::vec_with_capacity(n);
    read_planes_into(stream, n, &mut ids, |_| Ok(()))?;

    let mut kd_values: Vec<[f32; 3]> = Vec::with_capacity(k);
    read_units(stream, k, 12, |b| {
        let (values, _) = b.as_chunks::<12>();
        kd_values.extend(values.iter().map(|b| {
            let (w, _) = b.as_chunks::<4>();
            [f(&w[0]), f(&w[1]), f(&w[2])]
        }));
    })?;
    let mut kd_index: Vec<u32> = hort_huge_pages::vec_with_capacity(n);
    let mut kd = FirstUse::new(k, "kd");
    read_planes_into(stream, n, &mut kd_index, |indices| kd.check(indices))?;
    kd.finish()?;

    let flags = read_flags(stream, n, c, x)?;
    let normals = read_normals(stream, c)?;
    let textured = read_textured(stream, x)?;
    Ok(SplitObject {
        split,
        bvh: bvh.finish(ids),
        shading: ShadingTable::from_parts(
            kd_values,
            kd_index,
            flags.normal_slots,
            normals,
            flags.texture_slots,
            textured,
        ),
        textures: Default::default(),
    })
}

/// Each triangle's slot in the normals and in the textured entries (none if the header's
/// count is 0, else one per triangle, [`ShadingTable::NO_SLOT`] where its flag bit is clear).
struct Slots {
    normal_slots: Vec<u32>,
    texture_slots: Vec<u32>,
}

/// Reads the shading flags of `n` triangles, checked: bits 0 (normals) and 1 (textured) only,
/// as many of each set as the header's `c` and `x`.
fn read_flags(stream: &mut RawStream<'_>, n: usize, c: usize, x: usize) -> Result<Slots, String> {
    let sized = |count: usize| hort_huge_pages::vec_with_capacity(if count > 0 { n } else { 0 });
    let mut slots = Slots {
        normal_slots: sized(c),
        texture_slots: sized(x),
    };
    let (mut normals_set, mut textured_set, mut at, mut bad) = (0usize, 0usize, 0usize, None);
    read_units(stream, n, 1, |flags| {
        if flags.iter().all(|&f| f == 0) {
            at += flags.len();
            if c > 0 {
                slots.normal_slots.resize(at, ShadingTable::NO_SLOT);
            }
            if x > 0 {
                slots.texture_slots.resize(at, ShadingTable::NO_SLOT);
            }
            return;
        }
        for &flag in flags {
            if bad.is_none() {
                if flag > 3 {
                    bad = Some(format!(
                        "shading flags of triangle {at} are {flag}, expected bits 0 and 1 only"
                    ));
                }
                let mut take =
                    |bit: u8, set: &mut usize, limit: usize, out: &mut Vec<u32>, what| {
                        if flag & bit == 0 {
                            if limit > 0 {
                                out.push(ShadingTable::NO_SLOT);
                            }
                        } else if *set < limit {
                            out.push(*set as u32);
                            *set += 1;
                        } else {
                            bad.get_or_insert(format!(
                                "shading flags: more {what} than the header's {limit}"
                            ));
                        }
                    };
                take(
                    1,
                    &mut normals_set,
                    c,
                    &mut slots.normal_slots,
                    "triangles with normals",
                );
                take(
                    2,
                    &mut textured_set,
                    x,
                    &mut slots.texture_slots,
                    "textured triangles",
                );
            }
            at += 1;
        }
    })?;
    if let Some(bad) = bad {
        return Err(bad);
    }
    if normals_set != c {
        return Err(format!(
            "shading flags: {normals_set} triangles with normals, the header declares {c}"
        ));
    }
    if textured_set != x {
        return Err(format!(
            "shading flags: {textured_set} textured triangles, the header declares {x}"
        ));
    }
    Ok(slots)
}

/// Reads the `x` textured triangles' entries (texture index, corner texture coordinates).
fn read_textured(stream: &mut RawStream<'_>, x: usize) -> Result<Vec<TexturedCorners>, String> {
    let mut textured = Vec::with_capacity(x);
    read_units(stream, x, TEXTURED_BYTES as usize, |bytes| {
        let (entries, _) = bytes.as_chunks::<28>();
        textured.extend(entries.iter().map(|e| {
            let (w, _) = e.as_chunks::<4>();
            let f = |i: usize| f32::from_le_bytes(w[i]);
            TexturedCorners {
                texture: u32::from_le_bytes(w[0]),
                uv: [[f(1), f(2)], [f(3), f(4)], [f(5), f(6)]],
            }
        }));
    })?;
    Ok(textured)
}

/// Reads the normals of the `c` triangles that have them.
fn read_normals(stream: &mut RawStream<'_>, c: usize) -> Result<Vec<[Vec3; 3]>, String> {
    let mut normals = hort_huge_pages::vec_with_capacity(c);
    read_units(stream, c, 36, |bytes| {
        let (triangles, _) = bytes.as_chunks::<36>();
        normals.extend(triangles.iter().map(|t| {
            let (w, _) = t.as_chunks::<4>();
            let f = |b: &[u8; 4]| f32::from_le_bytes(*b);
            let vec3 = |b: &[[u8; 4]]| Vec3::new(f(&b[0]), f(&b[1]), f(&b[2]));
            [vec3(&w[0..3]), vec3(&w[3..6]), vec3(&w[6..9])]
        }));
    })?;
    Ok(normals)
}

/// Hands `f` the next `count` units of `unit` bytes, as many whole units at a time as the
/// stream gives at once.
fn read_units(
    stream: &mut RawStream<'_>,
    count: usize,
    unit: usize,
    mut f: impl FnMut(&[u8]),
) -> Result<(), String> {
    let per_take = (MAX_TAKE / unit).max(1);
    let mut left = count;
    while left > 0 {
        let units = left.min(per_take);
        f(stream.take(units * unit).ok_or(ENDED)?);
        left -= units;
    }
    Ok(())
}

/// Reads a planes section of `count` words, handing `f` each group's words in order (whole
/// groups of [`PLANE_GROUP`], the last one shorter), from one reused buffer.
fn read_planes(
    stream: &mut RawStream<'_>,
    count: usize,
    mut f: impl FnMut(&[u32]) -> Result<(), String>,
) -> Result<(), String> {
    let mut words = Vec::with_capacity(count.min(PLANE_GROUP));
    for len in group_lengths(count) {
        words.clear();
        unshuffle_group(stream, len, &mut words)?;
        f(&words)?;
    }
    Ok(())
}

/// Reads a planes section of `count` words onto the end of `out`, group by group, handing
/// `check` each group's words once they are in `out`.
fn read_planes_into(
    stream: &mut RawStream<'_>,
    count: usize,
    out: &mut Vec<u32>,
    mut check: impl FnMut(&[u32]) -> Result<(), String>,
) -> Result<(), String> {
    for len in group_lengths(count) {
        let start = out.len();
        unshuffle_group(stream, len, out)?;
        check(&out[start..])?;
    }
    Ok(())
}

/// The word counts of the groups of a planes section of `count` words: [`PLANE_GROUP`] each,
/// the last one shorter.
fn group_lengths(count: usize) -> impl Iterator<Item = usize> {
    (0..count)
        .step_by(PLANE_GROUP)
        .map(move |start| (count - start).min(PLANE_GROUP))
}

/// Appends to `out` the `len` words of the next group: its byte 0s, 1s, 2s and 3s.
fn unshuffle_group(
    stream: &mut RawStream<'_>,
    len: usize,
    out: &mut Vec<u32>,
) -> Result<(), String> {
    let bytes = stream.take(4 * len).ok_or(ENDED)?;
    let (b0, rest) = bytes.split_at(len);
    let (b1, rest) = rest.split_at(len);
    let (b2, b3) = rest.split_at(len);
    out.extend(
        b0.iter()
            .zip(b1)
            .zip(b2)
            .zip(b3)
            .map(|(((&a, &b), &c), &d)| u32::from_le_bytes([a, b, c, d])),
    );
    Ok(())
}

/// Checks, index by index, that indices number a table of `values` values in order of first
/// use (each at most the number used before it, every value used); errors name `what` and the
/// first bad index.
struct FirstUse {
    values: usize,
    what: &'static str,
    used: usize,
    seen: usize,
}

impl FirstUse {
    fn new(values: usize, what: &'static str) -> Self {
        FirstUse {
            values,
            what,
            used: 0,
            seen: 0,
        }
    }

    /// Checks the next indices, in order: after `Ok`, each is below `values`; the error names
    /// the first bad one.
    fn check(&mut self, indices: &[u32]) -> Result<(), String> {
        let mut used = self.used;
        for (k, &index) in indices.iter().enumerate() {
            let index_usize = index as usize;
            if index_usize > used || index_usize >= self.values {
                return Err(format!(
                    "{} index {} is {index}, expected at most {} (values in order of first use)",
                    self.what,
                    self.seen + k,
                    used.min(self.values.saturating_sub(1))
                ));
            }
            used += usize::from(index_usize == used);
        }
        self.used = used;
        self.seen += indices.len();
        Ok(())
    }

    /// Checks that every value was used.
    fn finish(&self) -> Result<(), String> {
        if self.used != self.values {
            return Err(format!(
                "{} values: {} of {} used",
                self.what, self.used, self.values
            ));
        }
        Ok(())
    }
}
