//! The binary targets: split objects and shuffle blocks, as a worker reads them from storage.
//!
//! Input layout, both targets: byte 0 selects; with its high bit set the rest is the object as
//! stored (so the checksums are fuzzed too), otherwise byte 1 is the record count and the rest
//! is the raw column payload, wrapped in a valid block first (so the fuzzer gets past the CRC
//! and zstd and reaches the column decoders).

use hort_core::pipeline::partition::{decode_frame, decode_page, encode_frames};
use hort_core::pipeline::{
    decode_occluded, decode_pixels, decode_queries, decode_refine_list, decode_split,
    decode_surface_hits, encode_occluded, encode_pixels, encode_queries, encode_refine_list,
    encode_split, encode_surface_hits,
};
use hort_core::shuffle::{RecordKind, decode_block, encode_block};
use hort_core::triangle::Ray;

use crate::assert_one_line;

/// The key decoders are given; every error must name it.
const KEY: &str = "jobs/fuzz/stage/part";

/// The block bytes an input stands for, given the kind it is read as.
fn stored(kind: RecordKind, data: &[u8]) -> Option<Vec<u8>> {
    let (&select, rest) = data.split_first()?;
    if select & 0x80 != 0 {
        return Some(rest.to_vec());
    }
    let (&count, raw) = rest.split_first()?;
    Some(encode_block(kind, u64::from(count), raw))
}

/// Panics unless `result` is `Ok` or a one-line error naming [`KEY`].
fn check_error<T, E: std::fmt::Display>(what: &str, result: Result<T, E>) -> Option<T> {
    match result {
        Ok(v) => Some(v),
        Err(e) => {
            let message = e.to_string();
            assert_one_line(what, &message);
            assert!(
                message.contains(KEY),
                "{what}: error does not name the key: {message}"
            );
            None
        }
    }
}

/// Split object target: decode; what decodes must re-encode to an equal object (to the bit),
/// hold one shading entry per triangle, and answer ray queries.
pub fn split_object(data: &[u8]) {
    let Some(bytes) = stored(RecordKind::SplitObject, data) else {
        return;
    };
    let Some(object) = check_error("split object", decode_split(KEY, &bytes)) else {
        return;
    };
    assert_eq!(object.shading.len(), object.bvh.triangle_count());
    let again = decode_split(KEY, &encode_split(&object)).expect("a re-encoded split decodes");
    // Debug shows signed zeros and NaNs; the shading as each triangle gets it (re-encoding
    // merges a reflectance a hostile object stored twice).
    let shown = |o: &hort_core::pipeline::SplitObject| {
        let shading: Vec<_> = o.shading.iter().collect();
        format!("{} {:?} {shading:?}", o.split, o.bvh)
    };
    assert_eq!(shown(&object), shown(&again));
    let bounds = object.bvh.bounds();
    let centre = (bounds.lo + bounds.hi) * 0.5;
    for dir in [
        glam::Vec3::X,
        glam::Vec3::NEG_Y,
        glam::Vec3::new(0.3, 0.5, -0.8),
    ] {
        let ray = Ray {
            origin: centre - dir * 10.0,
            dir,
        };
        if let Some(hit) = object.bvh.closest_hit(&ray) {
            assert!(
                object.bvh.ids().contains(&hit.id),
                "split object: a hit names triangle {} that the split does not hold",
                hit.id
            );
        }
        let _ = object.bvh.occluded(&ray, 20.0);
    }
}

/// Shuffle block target: byte 0 also selects the record kind (low bits); the block is decoded
/// by that kind's decoder, and what decodes must re-encode to the same records.
pub fn shuffle_block(data: &[u8]) {
    let Some(&select) = data.first() else {
        return;
    };
    let kind = RecordKind::ALL[usize::from(select & 0x7f) % RecordKind::ALL.len()];
    let Some(bytes) = stored(kind, data) else {
        return;
    };
    if let Some(block) = check_error("block", decode_block(KEY, &bytes, kind)) {
        assert_eq!(block.kind, kind);
    }
    let what = "shuffle block";
    let debug = |v: &dyn std::fmt::Debug| format!("{v:?}");
    match kind {
        RecordKind::CastCandidate | RecordKind::Hit => {
            if let Some(hits) = check_error(what, decode_surface_hits(KEY, &bytes, kind)) {
                let again = decode_surface_hits(KEY, &encode_surface_hits(kind, &hits), kind)
                    .expect("re-encoded hits decode");
                assert_eq!(debug(&hits), debug(&again));
            }
        }
        RecordKind::ShadowQuery => {
            if let Some(queries) = check_error(what, decode_queries(KEY, &bytes)) {
                let again = decode_queries(KEY, &encode_queries(&queries))
                    .expect("re-encoded queries decode");
                assert_eq!(debug(&queries), debug(&again));
            }
        }
        RecordKind::ShadowResult => {
            if let Some(keys) = check_error(what, decode_occluded(KEY, &bytes)) {
                let again = decode_occluded(KEY, &encode_occluded(&keys))
                    .expect("re-encoded occlusion keys decode");
                assert_eq!(keys, again);
            }
        }
        RecordKind::PixelColor => {
            if let Some(pixels) = check_error(what, decode_pixels(KEY, &bytes)) {
                let again =
                    decode_pixels(KEY, &encode_pixels(&pixels)).expect("re-encoded pixels decode");
                assert_eq!(debug(&pixels), debug(&again));
            }
        }
        RecordKind::SplitObject => {
            check_error(what, decode_split(KEY, &bytes));
        }
        RecordKind::VertexPage => {
            check_error(what, decode_page(KEY, &bytes, 0));
        }
        RecordKind::Texture => {
            if let Some(texture) =
                check_error(what, hort_core::texture::decode_texture(KEY, &bytes))
            {
                let again = hort_core::texture::encode_texture(&texture);
                let back = hort_core::texture::decode_texture(KEY, &again)
                    .expect("a re-encoded texture decodes");
                assert!(back == texture, "a texture changed when re-encoded");
            }
        }
        RecordKind::PartRecords => {
            if let Some(records) = check_error(what, decode_frame(KEY, &bytes)) {
                let (again, offsets) = encode_frames(&records);
                let back: Vec<_> = offsets
                    .windows(2)
                    .flat_map(|w| {
                        decode_frame(KEY, &again[w[0] as usize..w[1] as usize])
                            .expect("re-encoded records decode")
                    })
                    .collect();
                assert_eq!(debug(&records), debug(&back));
            }
        }
        RecordKind::RefineList => {
            if let Some(list) = check_error(what, decode_refine_list(KEY, &bytes)) {
                let again = decode_refine_list(KEY, &encode_refine_list(&list))
                    .expect("re-encoded refine list decodes");
                assert_eq!(debug(&list), debug(&again));
            }
        }
    }
}
