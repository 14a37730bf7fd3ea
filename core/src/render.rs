//! The monolithic renderer (the paper's TRAD): one process, one BVH over the whole scene.
//! Its loop over a run of pixels ([`render_run`]) also renders a fused task's span, from the
//! task's split object ([`Surfaces`]), so the two give the same bits at the same cost.
//!
//! Bands of rows are traced tile by tile, each pixel's samples in trace order
//! ([`TraceOrder`]), in batches of camera samples (primary rays, then all their shadow rays
//! light by light, as packets: [`Bvh::closest_hits`], [`Bvh::occluded_columns`]); the colours
//! are those of tracing each sample alone, and the result does not depend on the thread count.

mod band;
mod batch;
mod surfaces;

pub(crate) use band::BATCH_SAMPLES;
pub use band::{Band, View, band_runs, render_run};
pub use batch::Lighting;
pub use surfaces::Surfaces;

use crate::bvh::{BuildPreset, Bvh, ClosestHit, HitColumns};
use crate::camera::Camera;
use crate::error::SceneError;
use crate::hits::Hit;
use crate::image::Image;
use crate::phase_timer::{NoTimer, PhaseTimer, PhaseTimes};
use crate::pipeline::FrameChoice;
use crate::sampling::TraceOrder;
use crate::scene::{Mesh, NO_NORMAL, Scene, TriangleShading, check_image_size};
use crate::shading::{LastFrame, SurfacePoint};
use crate::texture::TexturedCorners;
use crate::tiles::BAND_ROWS;
use crate::triangle::Ray;
use crate::unoccludable::unoccludable_lights;
use crate::worker_pool::{available_cores, run_indexed};
pub(crate) use batch::ShadingScratch;
use batch::shade_batch_timed;
use std::convert::Infallible;
use std::time::Instant;

/// Image size, samples per pixel, frame and worker threads of one render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Image width in pixels; [`render`] accepts 1 to 65536.
    pub width: u32,
    /// Image height in pixels; [`render`] accepts 1 to 65536.
    pub height: u32,
    /// Samples per pixel; [`render`] accepts 1 to 65536.
    pub spp: u32,
    /// Worker threads; 0 means one per available core.
    pub threads: usize,
    /// Which frame of which camera path ([`FrameChoice::STILL`]: the scene's camera).
    pub frame: FrameChoice,
}

impl RenderSettings {
    /// The camera of this render of `scene`: the frame's camera for the image size
    /// ([`FrameChoice::camera`]), with the frame's sample streams, as a planned job's tasks
    /// trace it ([`crate::pipeline::JobPlan::ray_camera`]).
    pub fn camera(&self, scene: &Scene) -> Result<Camera, SceneError> {
        let spec = self.frame.camera(scene, self.width, self.height)?;
        Ok(Camera::new(&spec, self.width, self.height)?.with_frame(self.frame.index))
    }
}

/// Everything a render produces.
#[derive(Clone, Debug)]
pub struct RenderOutput {
    /// Linear radiance, each pixel the mean of its samples.
    pub image: Image,
    /// Sample 0 of each pixel, row-major from the top-left.
    pub hits: Vec<Hit>,
    /// Counts of logical rays: one primary per sample, one shadow per hit sample and light.
    pub rays: RayCounts,
    /// Wall-clock seconds of ray work only (no loading, BVH build or output).
    pub render_seconds: f64,
}

/// Logical ray counts of a render.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayCounts {
    /// Camera rays: one per sample, hit or miss.
    pub primary: u64,
    /// Shadow rays: one per light for every sample that hit, whether or not one was traced.
    pub shadow: u64,
}

impl std::ops::AddAssign for RayCounts {
    fn add_assign(&mut self, o: RayCounts) {
        self.primary += o.primary;
        self.shadow += o.shadow;
    }
}

/// Builds the BVH over the whole scene; triangle ids are scene-order indices.
pub fn build_scene_bvh(mesh: &Mesh) -> Bvh {
    build_scene_bvh_on(mesh, available_cores())
}

/// [`build_scene_bvh`] on at most `threads` threads (the same BVH for any count).
pub fn build_scene_bvh_on(mesh: &Mesh, threads: usize) -> Bvh {
    build_scene_bvh_with(mesh, threads, BuildPreset::Quality)
}

/// [`build_scene_bvh_on`] with the construction `preset` (the same hits with any preset).
pub fn build_scene_bvh_with(mesh: &Mesh, threads: usize, preset: BuildPreset) -> Bvh {
    let n = mesh.triangle_count();
    let triangles = (0..n).map(|i| mesh.corners(i)).collect();
    Bvh::build_preset(triangles, (0..n as u32).collect(), threads, preset)
}

/// The vertex normals (if any), material reflectance and texture (if any) of the scene's
/// triangle `id`: what a split object stores of it.
#[inline]
pub fn shading_of(mesh: &Mesh, id: u32) -> TriangleShading {
    let id = id as usize;
    let normal_ids = mesh.triangle_normals[id];
    // Spelled out: `array::map` is not always inlined, and was 5% of a textured render.
    let normal = |k: usize| mesh.normals[normal_ids[k] as usize];
    let normals = (normal_ids[0] != NO_NORMAL).then(|| [normal(0), normal(1), normal(2)]);
    let kd = mesh.materials[mesh.triangle_materials[id] as usize].kd;
    let texture = mesh
        .texture_of(id)
        .map(|(texture, uv)| TexturedCorners { texture, uv });
    TriangleShading {
        normals,
        kd,
        texture,
    }
}

/// The shading data of a hit on the scene's triangle `hit.id`, found by `bvh`.
#[inline]
pub fn surface_of(mesh: &Mesh, bvh: &Bvh, hit: &ClosestHit, ray: &Ray) -> SurfacePoint {
    mesh.surface(bvh, hit, ray, &mut LastFrame::default())
}

/// The reflectance of the scene's triangle `id` when it is flat (no vertex normals) and
/// untextured: what [`surface_of`] gives as `kd` for a hit on it.
#[inline]
fn flat_kd(mesh: &Mesh, id: u32) -> Option<[f32; 3]> {
    let i = id as usize;
    // A mesh without normals or without several materials answers without reading the
    // triangle's entries: a hit's id is as scattered as the mesh is large.
    let flat = (mesh.normals.is_empty() || mesh.triangle_normals[i][0] == NO_NORMAL)
        && mesh.texture_of(i).is_none();
    flat.then(|| match mesh.materials.as_slice() {
        [only] => only.kd,
        all => all[mesh.triangle_materials[i] as usize].kd,
    })
}

/// Renders `scene` with one BVH over all its triangles.
pub fn render(
    scene: &Scene,
    bvh: &Bvh,
    settings: RenderSettings,
) -> Result<RenderOutput, SceneError> {
    let setup = prepare(scene, settings)?;
    let threads = if settings.threads == 0 {
        available_cores()
    } else {
        settings.threads
    };
    let start = Instant::now();
    let mut frame = Frame::new(settings);
    // One item per band of rows; each band lands at its own place, so the thread count changes
    // nothing.
    let Ok(()) = run_indexed(
        std::iter::repeat_n((), threads),
        settings.height.div_ceil(BAND_ROWS) as usize,
        |(), band| {
            Ok::<Band, Infallible>(render_band(
                scene,
                bvh,
                &setup,
                settings,
                band as u32 * BAND_ROWS,
                &mut NoTimer,
            ))
        },
        |band, rows| frame.place(band * BAND_ROWS as usize, rows),
    );
    Ok(frame.finish(start))
}

/// [`render`] on the calling thread alone (`settings.threads` is not used), with the time of
/// each phase of its row loop ([`crate::phase_timer`], for `hort bench samples`). The output
/// has the same bits as [`render`]'s at any thread count.
pub fn render_phases(
    scene: &Scene,
    bvh: &Bvh,
    settings: RenderSettings,
) -> Result<(RenderOutput, PhaseTimes), SceneError> {
    let setup = prepare(scene, settings)?;
    let start = Instant::now();
    let mut frame = Frame::new(settings);
    let mut timer = PhaseTimes::start();
    for y in (0..settings.height).step_by(BAND_ROWS as usize) {
        let band = render_band(scene, bvh, &setup, settings, y, &mut timer);
        frame.place(y as usize, band);
    }
    Ok((frame.finish(start), timer))
}

/// What every band of a render shares, made once by [`prepare`].
struct Setup {
    camera: Camera,
    /// Per light: no surface can occlude it ([`unoccludable_lights`]).
    unoccludable: Vec<bool>,
    /// The order each pixel's samples are traced in.
    order: TraceOrder,
}

/// The checks and per-render setup of [`render`]: the image size, the camera, which lights no
/// surface can occlude, and the samples' trace order.
fn prepare(scene: &Scene, s: RenderSettings) -> Result<Setup, SceneError> {
    check_image_size(s.width, s.height, s.spp)?;
    Ok(Setup {
        camera: s.camera(scene)?,
        unoccludable: unoccludable_lights(&scene.mesh, &scene.lights),
        order: TraceOrder::new(s.spp),
    })
}

/// The image, hit buffer and ray counts as bands of rows arrive (in any order).
struct Frame {
    width: usize,
    image: Image,
    hits: Vec<Hit>,
    rays: RayCounts,
}

impl Frame {
    fn new(s: RenderSettings) -> Self {
        Frame {
            width: s.width as usize,
            image: Image::new(s.width, s.height),
            hits: vec![Hit::MISS; s.width as usize * s.height as usize],
            rays: RayCounts::default(),
        }
    }

    /// Puts `band`, whose first row is `y`, in place.
    fn place(&mut self, y: usize, band: Band) {
        let range = y * self.width..y * self.width + band.colours.len();
        self.image.pixels[range.clone()].copy_from_slice(&band.colours);
        self.hits[range].copy_from_slice(&band.hits);
        self.rays += band.rays;
    }

    fn finish(self, start: Instant) -> RenderOutput {
        RenderOutput {
            image: self.image,
            hits: self.hits,
            rays: self.rays,
            render_seconds: start.elapsed().as_secs_f64(),
        }
    }
}

/// The lights, ambient and background of `scene`, with `unoccludable` per light.
pub(crate) fn lighting<'a>(scene: &'a Scene, unoccludable: &'a [bool]) -> Lighting<'a> {
    Lighting {
        lights: &scene.lights,
        unoccludable,
        ambient: scene.ambient,
        background: scene.background,
    }
}

/// [`shade_batch_lit`] of the scene's own mesh and lighting (for tests).
#[cfg(test)]
pub(crate) fn shade_batch<'s>(
    scene: &Scene,
    bvh: &Bvh,
    unoccludable: &[bool],
    batch: (&[Ray], &[Option<ClosestHit>]),
    scratch: &'s mut ShadingScratch,
) -> &'s [[f32; 3]] {
    let lighting = lighting(scene, unoccludable);
    let (rays, hits) = batch;
    let hits = HitColumns::from_hits(hits);
    shade_batch_lit((&scene.mesh, bvh), &lighting, (rays, &hits), scratch)
}

/// The radiance of every sample of a batch whose primary rays `rays` have the closest hits
/// `hits` (found by `bvh`, on the triangles `surfaces` describes: the scene's mesh, or a split
/// object): the background for a miss, else Lambert shading with the lights its shadow rays
/// reach (summed in light order) plus ambient. The shadow rays of the whole batch are traced as
/// packets, light by light ([`Bvh::occluded_columns`]), each light's in sample order.
///
/// `lighting.unoccludable[l]` says light `l` can be occluded by no surface
/// ([`crate::unoccludable::unoccludable_lights`]): its shadow rays are not traced and count as
/// unblocked, which is what tracing them would give. `scratch` keeps the lists of one batch
/// for the next, and holds the radiances returned.
pub(crate) fn shade_batch_lit<'s>(
    (surfaces, bvh): (&impl Surfaces, &Bvh),
    lighting: &Lighting,
    (rays, hits): (&[Ray], &HitColumns),
    scratch: &'s mut ShadingScratch,
) -> &'s [[f32; 3]] {
    shade_batch_timed(
        (surfaces, bvh),
        lighting,
        (rays, hits),
        scratch,
        &mut NoTimer,
    )
}

/// Renders the band of up to [`BAND_ROWS`] rows from row `y0` ([`render_run`]).
fn render_band(
    scene: &Scene,
    bvh: &Bvh,
    setup: &Setup,
    s: RenderSettings,
    y0: u32,
    timer: &mut impl PhaseTimer,
) -> Band {
    let rows = BAND_ROWS.min(s.height - y0);
    let first_pixel = u64::from(y0) * u64::from(s.width);
    let pixels = first_pixel..first_pixel + u64::from(rows) * u64::from(s.width);
    let view = View {
        camera: &setup.camera,
        width: s.width,
        spp: s.spp,
        order: &setup.order,
    };
    let lighting = lighting(scene, &setup.unoccludable);
    render_run((&scene.mesh, bvh), &lighting, &view, pixels, timer)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase_timer::Phase;
    use crate::sampling::sample_offset;
    use crate::scene::load_scene;
    use crate::shading::{combine, shadow_test};

    fn teapot() -> Scene {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/teapot/teapot.json");
        load_scene(std::path::Path::new(path)).expect("bundled teapot")
    }

    /// The reference: one camera sample shaded alone (single-ray `occluded` per light), with
    /// the logical rays it cast.
    fn shade_sample(
        scene: &Scene,
        bvh: &Bvh,
        ray: &Ray,
        hit: Option<&ClosestHit>,
    ) -> ([f32; 3], RayCounts) {
        let Some(hit) = hit else {
            let rays = RayCounts {
                primary: 1,
                shadow: 0,
            };
            return (scene.background, rays);
        };
        let sp = surface_of(&scene.mesh, bvh, hit, ray);
        let contributions = scene.lights.iter().filter_map(|light| {
            let test = shadow_test(&sp, light)?;
            (!bvh.occluded(&test.ray, test.t_max)).then_some(test.unoccluded)
        });
        let colour = combine(sp.kd, contributions, scene.ambient);
        let rays = RayCounts {
            primary: 1,
            shadow: scene.lights.len() as u64,
        };
        (colour, rays)
    }

    /// The phase-timed render on one thread has the bits of the plain render on several, and
    /// its phases add up to no more than its wall time, the ray work being most of it.
    #[test]
    fn phase_timed_render_is_the_render() {
        let scene = teapot();
        let bvh = build_scene_bvh(&scene.mesh);
        let settings = RenderSettings {
            width: 40,
            height: 30,
            spp: 12,
            threads: 3,
            frame: Default::default(),
        };
        let plain = render(&scene, &bvh, settings).unwrap();
        let (timed, times) = render_phases(&scene, &bvh, settings).unwrap();
        let bits = |o: &RenderOutput| -> Vec<[u32; 3]> {
            o.image.pixels.iter().map(|p| p.map(f32::to_bits)).collect()
        };
        assert_eq!(bits(&timed), bits(&plain));
        assert_eq!(timed.hits, plain.hits);
        assert_eq!(timed.rays, plain.rays);
        let total: u64 = times.nanos.iter().sum();
        assert!(total as f64 <= timed.render_seconds * 1e9, "{times:?}");
        for phase in [
            Phase::CameraRays,
            Phase::ClosestHits,
            Phase::Shading,
            Phase::ShadowRays,
        ] {
            assert!(
                times.of(phase) > 0,
                "{} took no time: {times:?}",
                phase.name()
            );
        }
    }

    /// Bands traced tile by tile, in packets and batches, equal the same samples traced one by
    /// one with `closest_hit`: 42 pixels x 64 samples per row is several batches of whole
    /// pixels; at 1 and 3 spp a batch holds many tiles, and the sizes end in a partial tile and
    /// a partial band.
    #[test]
    fn batched_packet_rows_equal_sample_by_sample_tracing() {
        let mut scene = teapot();
        // Three lights, so that each sample's shadow rays are several and their order matters.
        let first = scene.lights[0];
        scene.lights.push(crate::scene::Light::Directional {
            direction: glam::DVec3::new(0.3, -1.0, -0.2).normalize(),
            irradiance: [0.4, 0.3, 0.2],
        });
        scene.lights.push(first);
        let bvh = build_scene_bvh(&scene.mesh);
        // Without an ambient term (of either zero's sign; the renderer then skips the
        // reflectances) and with one.
        for ambient in [[0.0, -0.0, 0.0], [0.05, 0.02, 0.0]] {
            scene.ambient = ambient;
            // 64 spp: rows of several batches; 1 and 3 spp: tiles across batches, and sizes
            // that end in a partial tile and a partial band.
            for (width, height, spp) in [(42, 6, 64), (37, 7, 1), (29, 5, 3)] {
                check_against_single_samples(&scene, &bvh, width, height, spp);
            }
        }
    }

    /// The same on the textured globe: flat textured floor, a textured sphere with vertex
    /// normals, and groups of samples that straddle triangles of both (flat textured hits take
    /// the flat lanes, with their reflectances looked up per hit).
    #[test]
    fn textured_rows_equal_sample_by_sample_tracing() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/globe/globe.json");
        let mut scene = load_scene(std::path::Path::new(path)).expect("bundled globe");
        assert_eq!(scene.mesh.textures.len(), 2, "the floor's and the sphere's");
        let bvh = build_scene_bvh(&scene.mesh);
        // Without an ambient term and with one (which reads the textured reflectances).
        for ambient in [[0.0; 3], [0.03, 0.05, 0.07]] {
            scene.ambient = ambient;
            for (width, height, spp) in [(40, 24, 64), (37, 21, 3)] {
                check_against_single_samples(&scene, &bvh, width, height, spp);
            }
        }
    }

    fn check_against_single_samples(scene: &Scene, bvh: &Bvh, width: u32, height: u32, spp: u32) {
        let settings = RenderSettings {
            width,
            height,
            spp,
            threads: 2,
            frame: Default::default(),
        };
        assert!(spp < 16 || settings.width as usize * settings.spp as usize > 2 * BATCH_SAMPLES);
        let out = render(scene, bvh, settings).expect("render");
        let camera = Camera::new(&scene.camera, settings.width, settings.height).unwrap();
        let mut hits = 0;
        let mut rays = RayCounts::default();
        for y in 0..settings.height {
            for x in 0..settings.width {
                let pixel = u64::from(y) * u64::from(settings.width) + u64::from(x);
                let mut sum = [0.0f32; 3];
                for sample in 0..settings.spp {
                    let (ox, oy) = sample_offset(pixel, sample, settings.spp);
                    let ray = camera.ray(f64::from(x) + ox, f64::from(y) + oy);
                    let hit = bvh.closest_hit(&ray);
                    if sample == 0 {
                        let expected = hit.map_or(Hit::MISS, |h| Hit {
                            triangle: h.id,
                            t: h.t,
                        });
                        let got = out.hits[pixel as usize];
                        assert_eq!(
                            (got.triangle, got.t.to_bits()),
                            (expected.triangle, expected.t.to_bits())
                        );
                        hits += usize::from(hit.is_some());
                    }
                    let (colour, counts) = shade_sample(scene, bvh, &ray, hit.as_ref());
                    rays += counts;
                    for k in 0..3 {
                        sum[k] += colour[k];
                    }
                }
                let expected = sum.map(|v| (v / settings.spp as f32).to_bits());
                assert_eq!(
                    out.image.pixels[pixel as usize].map(f32::to_bits),
                    expected,
                    "pixel {x},{y}"
                );
            }
        }
        assert!(hits > 20, "the teapot should be in the picture ({hits})");
        assert_eq!(out.rays, rays);
    }
}
