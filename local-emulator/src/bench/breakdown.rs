//! `hort bench samples`' second table (and `hort bench kernel`'s whole-render table,
//! `whole_render.rs`): where one core's time per sample goes, beside native Embree's kernel on
//! the same rays and Mitsuba 3's whole render.
//!
//! Ours: [`render_phases`], the monolithic renderer on one thread with a clock read at the end
//! of each phase of each batch of about 1,000 samples (camera rays, closest hits, shading,
//! shadow rays, accumulation, and the row loop itself), best of `repeats` by total; its image
//! must be the plain render's. Embree: every camera ray of the render (all samples) and every
//! shadow segment the renderer traces, with our answers, through `bench/embree_harness.c`
//! (`rtcIntersect1` and `rtcOccluded1`, and `rtcIntersect16` on 16 consecutive camera rays, on
//! a one-thread device, best of `repeats`). "whole render / Embree rays" is the plain render's
//! time (camera rays, traversal, shading, accumulation) over Embree's single-ray time on the
//! rays it traces: at or below 1, our whole render traces faster than Embree's kernel alone.
//! Mitsuba: its `multijitter` sweep time from `mitsuba.csv`, read, not run (where it has one).

use super::kernel::{EmbreeResult, RaySet, run_embree};
use super::table::{Table, f3};
use anyhow::{Result, bail};
use hort_core::bvh::Bvh;
use hort_core::camera::Camera;
use hort_core::phase_timer::{Phase, PhaseTimes};
use hort_core::render::{RenderSettings, render_phases, surface_of};
use hort_core::sampling::TraceOrder;
use hort_core::scene::Scene;
use hort_core::shading::shadow_test;
use hort_core::unoccludable::unoccludable_lights;
use std::path::Path;

/// One scene's breakdown.
pub(super) struct Breakdown {
    name: String,
    triangles: usize,
    samples: f64,
    /// The plain render's best seconds (no clock reads).
    plain_s: f64,
    /// The phase-timed render's best run: its wall seconds and its phases.
    timed_s: f64,
    phases: PhaseTimes,
    embree: Option<EmbreeResult>,
    /// Mitsuba's seconds for the same image, where the references have it.
    mitsuba_s: Option<f64>,
}

/// Measures `scene` at `settings` (one thread): the phase-timed render, whose pixels must be
/// `expected_pixels` (the plain render's), and Embree on the same rays when `harness` (the
/// compiled harness and a folder for its ray file) is given. `plain_s` and `mitsuba_s` are the
/// plain render's and (where known) Mitsuba's seconds, for the table.
#[allow(clippy::too_many_arguments)]
pub(super) fn measure(
    name: &str,
    scene: &Scene,
    bvh: &Bvh,
    settings: RenderSettings,
    repeats: u32,
    plain_s: f64,
    mitsuba_s: Option<f64>,
    expected_pixels: &[[f32; 3]],
    harness: Option<(&Path, &Path)>,
) -> Result<Breakdown> {
    let mut best: Option<(f64, PhaseTimes)> = None;
    for _ in 0..repeats.max(1) {
        let (out, phases) = render_phases(scene, bvh, settings)?;
        if out.image.pixels != expected_pixels {
            bail!("{name}: the phase-timed render differs from the plain render");
        }
        if best.as_ref().is_none_or(|(s, _)| out.render_seconds < *s) {
            best = Some((out.render_seconds, phases));
        }
    }
    let (timed_s, phases) = best.expect("at least one run");
    let embree = match harness {
        None => None,
        Some((harness, work_dir)) => {
            let (primary, hits, shadow, occluded) = render_rays(scene, bvh, settings)?;
            let rays = RaySet {
                primary: &primary,
                hits: &hits,
                shadow: &shadow,
                occluded: &occluded,
            };
            let file = work_dir.join(format!("samples-{}.bin", name.replace(' ', "-")));
            let result = run_embree(harness, &file, name, scene, &rays, repeats)?;
            if result.primary_same_id as usize != primary.len()
                || result.shadow_same as usize != shadow.len()
            {
                eprintln!(
                    "{name}: Embree agrees on {} of {} hits and {} of {} shadow answers",
                    result.primary_same_id,
                    primary.len(),
                    result.shadow_same,
                    shadow.len()
                );
            }
            Some(result)
        }
    };
    Ok(Breakdown {
        name: name.to_owned(),
        triangles: bvh.triangle_count(),
        samples: f64::from(settings.width) * f64::from(settings.height) * f64::from(settings.spp),
        plain_s,
        timed_s,
        phases,
        embree,
        mitsuba_s,
    })
}

type Rays = (
    Vec<hort_core::triangle::Ray>,
    Vec<Option<hort_core::bvh::ClosestHit>>,
    Vec<(hort_core::triangle::Ray, f32)>,
    Vec<bool>,
);

/// Every camera ray of the render (all samples, pixel by pixel, each pixel's in the renderer's
/// trace order) with its closest hit, and every shadow segment the renderer traces (lights
/// some surface can occlude) with its answer.
fn render_rays(scene: &Scene, bvh: &Bvh, s: RenderSettings) -> Result<Rays> {
    let camera = Camera::new(&scene.camera_for(s.width, s.height), s.width, s.height)?;
    let order = TraceOrder::new(s.spp);
    let mut primary = Vec::new();
    let pixels: Vec<u64> = (0..u64::from(s.width) * u64::from(s.height)).collect();
    camera.pixels_rays(&pixels, &order, &mut primary);
    let mut hits = vec![None; primary.len()];
    bvh.closest_hits(&primary, &mut hits);
    let free = unoccludable_lights(&scene.mesh, &scene.lights);
    let mut shadow = Vec::new();
    for (ray, hit) in primary.iter().zip(&hits) {
        let Some(hit) = hit else { continue };
        let sp = surface_of(&scene.mesh, bvh, hit, ray);
        for (light, &free) in scene.lights.iter().zip(&free) {
            if let Some(test) = shadow_test(&sp, light).filter(|_| !free) {
                shadow.push((test.ray, test.t_max));
            }
        }
    }
    let mut occluded = vec![false; shadow.len()];
    bvh.occluded_many(&shadow, &mut occluded);
    Ok((primary, hits, shadow, occluded))
}

/// The table: nanoseconds per sample, each phase with its share of the timed render.
pub(super) fn table(rows: &[Breakdown], s: RenderSettings) -> Table {
    let mut header = vec!["scene", "triangles", "ours ns/sample"];
    header.extend(Phase::ALL.iter().map(|p| p.name()));
    header.extend([
        "unaccounted",
        "our rays ns/sample",
        "Embree rays ns/sample",
        "rays ours / Embree",
        "whole render / Embree rays",
        "closest hits ours / Embree x16",
        "closest hits ours / Embree x16 coherent",
        "Mitsuba ns/sample",
        "ours / Mitsuba",
    ]);
    let mut table = Table::new(
        &format!(
            "where one core's time per sample goes, {}x{}, {} spp (ns per sample; phases: share of the phase-timed render)",
            s.width, s.height, s.spp
        ),
        &header,
    );
    for r in rows {
        let ns = |seconds: f64| seconds * 1e9 / r.samples;
        let timed_ns = ns(r.timed_s);
        let phase_ns = |p: Phase| r.phases.of(p) as f64 / r.samples;
        let mut row = vec![r.name.clone(), r.triangles.to_string(), f3(ns(r.plain_s))];
        for &p in &Phase::ALL {
            row.push(format!(
                "{} ({:.0}%)",
                f3(phase_ns(p)),
                100.0 * phase_ns(p) / timed_ns
            ));
        }
        let accounted: f64 = Phase::ALL.iter().map(|&p| phase_ns(p)).sum();
        row.push(f3(timed_ns - accounted));
        let ours_rays = phase_ns(Phase::ClosestHits) + phase_ns(Phase::ShadowRays);
        row.push(f3(ours_rays));
        match &r.embree {
            Some(e) => {
                let embree_rays = ns(e.primary_s + e.shadow_s);
                row.push(f3(embree_rays));
                row.push(f3(ours_rays / embree_rays));
                row.push(f3(ns(r.plain_s) / embree_rays));
                row.push(f3(phase_ns(Phase::ClosestHits) / ns(e.primary16_s)));
                row.push(f3(phase_ns(Phase::ClosestHits) / ns(e.primary16_coherent_s)));
            }
            None => row.extend(std::iter::repeat_n("-".to_owned(), 5)),
        }
        match r.mitsuba_s {
            Some(mitsuba_s) => {
                row.push(f3(ns(mitsuba_s)));
                row.push(f3(ns(r.plain_s) / ns(mitsuba_s)));
            }
            None => row.extend(std::iter::repeat_n("-".to_owned(), 2)),
        }
        table.push(row);
    }
    table
}
