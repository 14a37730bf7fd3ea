//! Golden digests of monolithic renders of the bundled scenes.
//!
//! Each case loads a scene with `load_scene`, builds the BVH, renders it monolithically at a
//! small size, and hashes (64-bit FNV-1a) the PFM bytes of the linear image and the hit-buffer
//! bytes. The digests are pinned: any change to what the renderer computes (loading, BVH,
//! intersection, camera, sampling, shading) or to the two encodings changes them.
//!
//! The same digests must hold on x86-64 and on aarch64: the renderer uses no fused multiply-add
//! and no platform libm, so its output is the same bits on both. A digest that differs on one
//! architecture is a portability bug, not a reason to re-pin. Likewise at every SIMD width of
//! the ray kernels (`hort_core::bvh::KernelWidth`): each case runs at every width the host has,
//! and with the BVH of every build preset (`hort_core::bvh::BuildPreset`).
//!
//! To re-pin after an intended change of the output, run
//! `cargo test -p hort-core --test golden -- --nocapture` and copy the printed lines.

use hort_core::bvh::{BuildPreset, KernelWidth, available_kernel_widths, force_kernel_width};
use hort_core::hits::encode_hits;
use hort_core::image::encode_pfm;
use hort_core::render::{RenderSettings, build_scene_bvh_with, render};
use hort_core::scene::load_scene;
use std::path::Path;

// 64-bit FNV-1a (offset basis 0xcbf29ce484222325, prime 0x100000001b3): the project's one.
use hort_core::digest::fnv1a64;

/// One pinned render: scene path (relative to the repository root), size, samples per pixel,
/// and the FNV-1a 64 digests of the PFM and of the hit buffer.
struct Golden {
    scene: &'static str,
    width: u32,
    height: u32,
    spp: u32,
    pfm: u64,
    hits: u64,
}

const GOLDEN: [Golden; 7] = [
    Golden {
        scene: "scenes/bunny/bunny.json",
        width: 64,
        height: 48,
        spp: 1,
        pfm: 0x70a5_7be8_427c_cabb,
        hits: 0x5aab_df75_e561_4b2f,
    },
    Golden {
        scene: "scenes/teapot/teapot.json",
        width: 64,
        height: 48,
        spp: 1,
        pfm: 0x2841_efe0_88f9_d2d7,
        hits: 0x12a1_2b15_d81e_b603,
    },
    Golden {
        scene: "scenes/cornell/cornell.json",
        width: 64,
        height: 48,
        spp: 1,
        pfm: 0x0b18_c5e9_4f63_2e97,
        hits: 0x640e_04dc_d458_5f75,
    },
    Golden {
        scene: "scenes/bunny/bunny.obj",
        width: 64,
        height: 48,
        spp: 1,
        pfm: 0x3365_c19d_bbbd_e214,
        hits: 0xdbcb_80a5_ae54_17e0,
    },
    Golden {
        scene: "scenes/bunny/bunny.json",
        width: 64,
        height: 48,
        spp: 4,
        pfm: 0xa3ee_5c64_ef25_f156,
        hits: 0x577a_6ac5_85e8_7987,
    },
    // A count that is not a power of 2: three lane groups of the sampler per pixel.
    Golden {
        scene: "scenes/cornell/cornell.json",
        width: 64,
        height: 48,
        spp: 12,
        pfm: 0x7df9_b24a_b27d_4c00,
        hits: 0x35ce_ac67_d9bb_3f36,
    },
    // Vertex normals and two diffuse textures (bilinear, repeat, sRGB).
    Golden {
        scene: "scenes/globe/globe.json",
        width: 64,
        height: 48,
        spp: 4,
        pfm: 0x7929_f71d_36f3_0568,
        hits: 0x4a98_9fbb_860a_c613,
    },
];

/// Every case at every kernel width this host runs (4-wide, and 8-wide on x86-64 with AVX2)
/// and with every build preset: the width and the tree change speed, never bits.
#[test]
fn bundled_scenes_render_to_the_pinned_digests() {
    let mut failures = Vec::new();
    for width in available_kernel_widths() {
        force_kernel_width(Some(width));
        for preset in [BuildPreset::Quality, BuildPreset::Fast] {
            failures.extend(render_the_cases(width, preset));
        }
    }
    force_kernel_width(None);
    assert!(
        failures.is_empty(),
        "digests changed:\n{}",
        failures.join("\n")
    );
}

/// The cases whose digests differ from the pinned ones, described.
fn render_the_cases(width: KernelWidth, preset: BuildPreset) -> Vec<String> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut failures = Vec::new();
    for g in &GOLDEN {
        let scene = load_scene(&root.join(g.scene)).unwrap_or_else(|e| panic!("{}: {e}", g.scene));
        let bvh = build_scene_bvh_with(&scene.mesh, 2, preset);
        let settings = RenderSettings {
            width: g.width,
            height: g.height,
            spp: g.spp,
            threads: 2,
            frame: Default::default(),
        };
        let out = render(&scene, &bvh, settings).unwrap_or_else(|e| panic!("{}: {e}", g.scene));
        assert!(
            out.hits.iter().any(|h| !h.is_miss()),
            "{}: the camera sees nothing",
            g.scene
        );
        let pfm = fnv1a64(&encode_pfm(&out.image));
        let hits = fnv1a64(&encode_hits(&out.hits));
        let (w, h, spp) = (g.width, g.height, g.spp);
        println!(
            "{} {w}x{h} spp {spp} ({width:?}, {preset:?}): pfm: {pfm:#018x}, hits: {hits:#018x},",
            g.scene
        );
        if (pfm, hits) != (g.pfm, g.hits) {
            failures.push(format!(
                "{} {w}x{h} spp {spp} ({width:?}, {preset:?}): pfm {pfm:#018x} (pinned {:#018x}), hits {hits:#018x} (pinned {:#018x})",
                g.scene, g.pfm, g.hits
            ));
        }
    }
    failures
}
