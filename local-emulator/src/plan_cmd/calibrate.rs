//! How fast this machine runs the renderer against the reference machine of `predict::RATES`: a
//! single-threaded BVH build and render of a small generated scene, timed at start-up of
//! `hort plan` (about a third of a second), nothing stored.

use anyhow::{Context, Result};
use hort_core::generate::generate_scene;
use hort_core::render::{RenderSettings, build_scene_bvh_on, render};
use hort_core::scene::{
    ImageSettings, Scene, default_camera, default_light, parse_obj, scene_bounds,
};
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// Triangles of the calibration scene (`hort scene generate --triangles 4096 --seed 1`).
pub const CALIBRATION_TRIANGLES: u64 = 4096;
/// Side of the calibration image, pixels (1 sample each).
const SIDE: u32 = 128;
/// Timed repetitions; the fastest counts (the least disturbed by other processes).
const REPEATS: usize = 40;
/// Pause before each repetition, so that a busy scheduler hands the next one a fresh slice.
const PAUSE: std::time::Duration = std::time::Duration::from_millis(3);
/// BVH build of the calibration scene on the reference machine, ms (the 2-core x86-64 machine
/// the rates were fitted on). It was 1.45 ms; the builder of 2026-12-04 builds the same BVH in
/// 0.577 of the time (2.07-2.38 ms against 1.26-1.27 ms on one machine, three alternating
/// calibrations each), so the reference scales with it and a machine's `speed` stays what it
/// was: `speed` measures the machine, not the builder.
pub const REFERENCE_BUILD_MS: f64 = 0.84;
/// Single-threaded render of the calibration image on the reference machine, ms.
pub const REFERENCE_TRACE_MS: f64 = 1.6;

/// One calibration's measurements and the speed they give.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Calibration {
    /// Triangles of the calibration scene.
    pub triangles: u64,
    /// Rays traced (camera and shadow).
    pub rays: u64,
    /// BVH build, ms (fastest of the repeats).
    pub build_ms: f64,
    /// Single-threaded render, ms (fastest of the repeats).
    pub trace_ms: f64,
    /// [`REFERENCE_BUILD_MS`].
    pub reference_build_ms: f64,
    /// [`REFERENCE_TRACE_MS`].
    pub reference_trace_ms: f64,
    /// Reference time over this machine's, build and render together: above 1 is faster.
    pub speed: f64,
}

/// Times the calibration workload on this machine.
pub fn calibrate() -> Result<Calibration> {
    let mut obj = Vec::new();
    generate_scene(CALIBRATION_TRIANGLES, 1, &mut obj).context("calibration scene")?;
    let path = Path::new("calibration.obj");
    let mut warnings = Vec::new();
    let mesh = parse_obj(obj.as_slice(), path, &mut warnings).context("calibration scene")?;
    let (lo, hi) = scene_bounds(&mesh, path).context("calibration scene")?;
    let scene = Scene {
        source: path.to_path_buf(),
        origin: Default::default(),
        camera: default_camera(lo, hi),
        framed_bounds: None,
        lights: vec![default_light(lo, hi)],
        ambient: [0.05; 3],
        background: [0.0; 3],
        image: ImageSettings::default(),
        warnings,
        mesh,
        animation: None,
    };
    let settings = RenderSettings {
        width: SIDE,
        height: SIDE,
        spp: 1,
        threads: 1,
        frame: Default::default(),
    };
    let mut build_ms = f64::INFINITY;
    let mut trace_ms = f64::INFINITY;
    let mut rays = 0;
    for _ in 0..REPEATS {
        std::thread::sleep(PAUSE);
        let started = Instant::now();
        let bvh = build_scene_bvh_on(&scene.mesh, 1);
        build_ms = build_ms.min(started.elapsed().as_secs_f64() * 1e3);
        let started = Instant::now();
        let out = render(&scene, &bvh, settings).context("calibration render")?;
        trace_ms = trace_ms.min(started.elapsed().as_secs_f64() * 1e3);
        std::thread::sleep(PAUSE);
        rays = out.rays.primary + out.rays.shadow;
    }
    Ok(Calibration {
        triangles: CALIBRATION_TRIANGLES,
        rays,
        build_ms,
        trace_ms,
        reference_build_ms: REFERENCE_BUILD_MS,
        reference_trace_ms: REFERENCE_TRACE_MS,
        speed: (REFERENCE_BUILD_MS + REFERENCE_TRACE_MS) / (build_ms + trace_ms).max(1e-6),
    })
}
