//! A job's plan estimated from its scene's sizes, without loading the scene: what the HTTP API
//! predicts for a scene given by key, which it never loads (the Plan function loads the scene
//! and plans it exactly, and checks the budget again on that plan).
//!
//! The triangle count comes from samples of each OBJ file: a small file is read whole and its
//! faces counted exactly; a larger one is read in [`OBJ_SAMPLES`] windows spread over the file,
//! and the triangles per byte of the complete lines in them, times the file's size, is the
//! estimate. Every split's box is the whole scene's, so no (span, split) pair is left out: the
//! task counts are upper bounds.

use std::ops::Range;

use super::PipelineError;
use super::partition::scene_range_bytes;
use super::{JobPlan, PlanRequest, ScenePartsShape, SplitInfo, plan_job, resolve_counts};
use crate::scene::Scene;

/// Bytes of one sample window of an OBJ file; a file of at most [`OBJ_SAMPLES`] windows is
/// read whole.
pub const OBJ_SAMPLE_BYTES: u64 = 4 << 10;

/// Sample windows per OBJ file at most (256 KiB of a file of any size). Many small windows,
/// not a few large ones: OBJ files alternate long runs of vertices and of faces, and the rate
/// of a few windows depends on which runs they land in (on a generated 5-million-triangle
/// scene, 8 windows of 32 KiB estimated 2.8 million; 64 windows of 4 KiB, 4.8 million).
pub const OBJ_SAMPLES: u64 = 64;

/// Bytes of OBJ text per triangle assumed when no sample of a large file holds a face: the
/// generated scenes' (`hort scene generate`: 849 MB for 20 million triangles, faces and
/// vertices).
pub const FALLBACK_BYTES_PER_TRIANGLE: u64 = 42;

/// The byte ranges of an OBJ file of `len` bytes to read for the estimate: the whole file when
/// it is at most `samples` windows long, else `samples` windows of [`OBJ_SAMPLE_BYTES`], one at
/// a pseudo-random place (fixed: the same file is sampled the same way) in each of `samples`
/// equal strata of the file, so regular layouts do not line up with the windows.
pub fn obj_sample_ranges(len: u64, samples: u64) -> Vec<Range<u64>> {
    let samples = samples.max(1);
    if len == 0 {
        return Vec::new();
    }
    if len <= samples * OBJ_SAMPLE_BYTES {
        return std::iter::once(0..len).collect();
    }
    let stratum = (len - OBJ_SAMPLE_BYTES) / samples;
    (0..samples)
        .map(|i| {
            let start = i * stratum + splitmix64(i) % stratum.max(1);
            start..start + OBJ_SAMPLE_BYTES
        })
        .collect()
}

/// SplitMix64's output function of `i`: the window places of [`obj_sample_ranges`].
fn splitmix64(i: u64) -> u64 {
    let mut x = i
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// What the complete lines of one sample hold: triangles (a face of n corners is n - 2) and
/// the lines' bytes. A line cut by the window's start (unless it starts the file) or end
/// (unless it ends the file) is not counted.
pub fn count_sample(bytes: &[u8], range: Range<u64>, len: u64) -> (u64, u64) {
    let mut text = bytes;
    if range.start > 0 {
        // The first line began before the window (or just at it: then it is whole, but a
        // window cannot tell, and one line makes no difference to the rate).
        match text.iter().position(|&b| b == b'\n') {
            Some(at) => text = &text[at + 1..],
            None => return (0, 0),
        }
    }
    if range.start + (bytes.len() as u64) < len {
        match text.iter().rposition(|&b| b == b'\n') {
            Some(at) => text = &text[..=at],
            None => return (0, 0),
        }
    }
    let triangles = text
        .split(|&b| b == b'\n')
        .map(|line| {
            let line = line.split(|&b| b == b'#').next().unwrap_or_default();
            let mut words = line
                .split(u8::is_ascii_whitespace)
                .filter(|word| !word.is_empty());
            if words.next() != Some(b"f".as_slice()) {
                return 0;
            }
            (words.count() as u64).saturating_sub(2)
        })
        .sum();
    (triangles, text.len() as u64)
}

/// The triangles of an OBJ file of `len` bytes, from `samples` (each range read and its
/// bytes, as [`obj_sample_ranges`] gives them): exact when the file was read whole, else the
/// rate of triangles per byte in the samples times `len`, rounded up (or, when no sample holds
/// a face, one triangle per [`FALLBACK_BYTES_PER_TRIANGLE`]).
pub fn estimate_obj_triangles(len: u64, samples: &[(Range<u64>, Vec<u8>)]) -> u64 {
    let (mut triangles, mut bytes) = (0u64, 0u64);
    for (range, sample) in samples {
        let (t, b) = count_sample(sample, range.clone(), len);
        triangles += t;
        bytes += b;
    }
    if bytes >= len {
        return triangles;
    }
    if triangles == 0 {
        // The samples fell on vertices only: assume the generated scenes' density.
        return len.div_ceil(FALLBACK_BYTES_PER_TRIANGLE);
    }
    let estimate = (u128::from(triangles) * u128::from(len)).div_ceil(u128::from(bytes));
    u64::try_from(estimate).unwrap_or(u64::MAX)
}

/// The plan of `request` for `scene` (its camera, lights and image settings, without geometry:
/// `scene.framed_bounds` or the box the caller gave it stands for the geometry) with about
/// `triangles` triangles in OBJ files of `obj_bytes` bytes: the split and span counts the
/// exact plan would choose for that many triangles, each split as large as the scene's box and
/// `bytes_per_triangle` bytes per triangle, and the byte ranges of a scene split by tasks when
/// the files are too large to load whole for the request's memory.
pub fn estimated_plan(
    scene: &Scene,
    triangles: u64,
    obj_bytes: u64,
    request: &PlanRequest,
    bounds: ([f32; 3], [f32; 3]),
    bytes_per_triangle: u64,
) -> Result<JobPlan, PipelineError> {
    let (shape, s) = resolve_counts(request, triangles)?;
    let k = u64::from(shape.splits);
    let infos = (0..k)
        .map(|i| {
            let split_triangles = (i + 1) * triangles / k - i * triangles / k;
            SplitInfo {
                id: i as u32,
                triangles: split_triangles,
                lo: bounds.0,
                hi: bounds.1,
                bytes: split_triangles * bytes_per_triangle,
            }
        })
        .collect();
    let mut plan = plan_job(scene, request, infos, &shape, s)?;
    plan.scene_parts =
        scene_range_bytes(obj_bytes, request.memory_mb).map(|range| ScenePartsShape {
            ranges: obj_bytes.div_ceil(range).min(u64::from(u32::MAX)) as u32,
            scene_bytes: obj_bytes,
            // A closed triangle mesh has about half as many vertices as triangles.
            vertices: triangles / 2,
            normals: 0,
        });
    Ok(plan)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_files_are_read_whole_and_counted_exactly() {
        let obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 1 2 4 3 # a quad\nf 1 2\n";
        let ranges = obj_sample_ranges(obj.len() as u64, OBJ_SAMPLES);
        assert_eq!(ranges.len(), 1);
        assert_eq!(ranges[0], 0..obj.len() as u64);
        let samples = vec![(ranges[0].clone(), obj.to_vec())];
        assert_eq!(estimate_obj_triangles(obj.len() as u64, &samples), 3);
        // No newline at the end: the last line still counts.
        let obj = b"v 0 0 0\nf 1 1 1";
        let samples = vec![(0..obj.len() as u64, obj.to_vec())];
        assert_eq!(estimate_obj_triangles(obj.len() as u64, &samples), 1);
    }

    #[test]
    fn large_files_are_sampled_in_strata_and_the_rate_scaled() {
        // 200,000 faces of 8 bytes each after 8-byte vertices: 2.4 MB.
        let mut obj = Vec::new();
        for _ in 0..100_000 {
            obj.extend_from_slice(b"v 0 0 0\n");
        }
        for _ in 0..200_000 {
            obj.extend_from_slice(b"f 1 2 3\n");
        }
        let len = obj.len() as u64;
        let ranges = obj_sample_ranges(len, OBJ_SAMPLES);
        assert_eq!(ranges.len() as u64, OBJ_SAMPLES);
        assert!(
            ranges
                .windows(2)
                .all(|w| w[0].end <= w[1].start || w[0].start < w[1].start)
        );
        assert!(ranges.last().unwrap().end <= len);
        let samples: Vec<_> = ranges
            .iter()
            .map(|r| (r.clone(), obj[r.start as usize..r.end as usize].to_vec()))
            .collect();
        let estimate = estimate_obj_triangles(len, &samples);
        // A third of the file is vertices: the windows there count no faces, the rest do.
        let error = (estimate as f64 - 200_000.0).abs() / 200_000.0;
        assert!(error < 0.1, "estimated {estimate} triangles of 200000");
    }

    #[test]
    fn cut_lines_at_window_edges_are_not_counted() {
        // A window starting inside "f 1 2 3 4\n" must not count its tail "3 4" as a face.
        let text = b"f 1 2 3 4\nf 1 2 3\nf 1 2";
        let (t, b) = count_sample(text, 5..5 + text.len() as u64, 1000);
        assert_eq!((t, b), (1, 8), "only the one whole line");
    }
}
