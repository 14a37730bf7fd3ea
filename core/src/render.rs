//! The monolithic renderer (the paper's TRAD): one process, one BVH over the whole scene.
//!
//! Bands of rows are traced tile by tile, each pixel's samples in trace order
//! ([`TraceOrder`]), in batches of camera samples (primary rays, then all their shadow rays
//! light by light, as packets: [`Bvh::closest_hits`], [`Bvh::occluded_grouped`]); the colours
//! are those of tracing each sample alone, and the result does not depend on the thread count.

use crate::bvh::{BuildPreset, Bvh, ClosestHit, SegmentGroups};
use crate::camera::Camera;
use crate::error::SceneError;
use crate::hits::Hit;
use crate::image::Image;
use crate::phase_timer::{NoTimer, Phase, PhaseTimer, PhaseTimes};
use crate::pipeline::FrameChoice;
use crate::sampling::{PixelSum, TraceOrder};
use crate::scene::{Mesh, NO_NORMAL, Scene, TriangleShading, check_image_size};
use crate::shading::{
    FlatHit, FlatShader, ShadowTest, SurfacePoint, combine, shadow_tests, surface_point,
};
use crate::texture::TexturedCorners;
use crate::tiles::{BAND_ROWS, tile_order};
use crate::triangle::Ray;
use crate::unoccludable::unoccludable_lights;
use crate::worker_pool::{available_cores, run_indexed};
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
    let normals =
        (normal_ids[0] != NO_NORMAL).then(|| normal_ids.map(|i| mesh.normals[i as usize]));
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
    surface_with(mesh, bvh, &shading_of(mesh, hit.id), hit, ray)
}

/// The reflectance of the scene's triangle `id` when it is flat (no vertex normals) and
/// untextured: what [`surface_of`] gives as `kd` for a hit on it.
#[inline]
fn flat_kd(mesh: &Mesh, id: u32) -> Option<[f32; 3]> {
    let i = id as usize;
    let flat = mesh.triangle_normals[i][0] == NO_NORMAL && mesh.texture_of(i).is_none();
    flat.then(|| mesh.materials[mesh.triangle_materials[i] as usize].kd)
}

/// [`surface_of`] given the triangle's shading data `s` ([`shading_of`]).
#[inline]
fn surface_with(
    mesh: &Mesh,
    bvh: &Bvh,
    s: &TriangleShading,
    hit: &ClosestHit,
    ray: &Ray,
) -> SurfacePoint {
    let kd = match &s.texture {
        None => s.kd,
        Some(t) => t.kd_at(s.kd, &mesh.textures[t.texture as usize], hit.b),
    };
    let corners = bvh.hit_corners(hit).corners();
    surface_point(corners, hit.b, ray.dir, s.normals, kd)
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

/// The radiance of every sample of a batch whose primary rays `rays` have the closest hits
/// `hits`: the background for a miss, else Lambert shading with the lights its shadow rays
/// reach (summed in light order) plus ambient. The shadow rays of the whole batch are traced as
/// packets, light by light ([`Bvh::occluded_grouped`]), each light's in sample order.
///
/// `unoccludable[l]` says light `l` can be occluded by no surface
/// ([`crate::unoccludable::unoccludable_lights`]): its shadow rays are not traced and count as
/// unblocked, which is what tracing them would give.
pub(crate) fn shade_batch(
    scene: &Scene,
    bvh: &Bvh,
    unoccludable: &[bool],
    rays: &[Ray],
    hits: &[Option<ClosestHit>],
) -> Vec<[f32; 3]> {
    shade_batch_timed(scene, bvh, unoccludable, rays, hits, &mut NoTimer)
}

/// [`shade_batch`], reporting its shading and shadow-ray phases to `timer`.
#[inline(always)]
fn shade_batch_timed(
    scene: &Scene,
    bvh: &Bvh,
    unoccludable: &[bool],
    rays: &[Ray],
    hits: &[Option<ClosestHit>],
    timer: &mut impl PhaseTimer,
) -> Vec<[f32; 3]> {
    // Per hit, in sample order, its lights' tests in light order (the order `combine` sums
    // them in), and its reflectance. Four hits on flat, untextured triangles are shaded at
    // once in lanes; any other group of four goes through its surface points: the same tests
    // either way.
    let samples: Vec<usize> = (0..hits.len()).filter(|&s| hits[s].is_some()).collect();
    let most = samples.len() * scene.lights.len();
    let mut segments = Vec::with_capacity(most);
    let mut segment_lights = Vec::with_capacity(most);
    let mut tests = Vec::with_capacity(most);
    let mut reflectances = Vec::with_capacity(samples.len());
    let mut visit = |sample: usize, light: usize, test: ShadowTest| {
        let free = unoccludable[light];
        if !free {
            segments.push((test.ray, test.t_max));
            segment_lights.push(light as u32);
        }
        tests.push((sample, test.unoccluded, free));
    };
    let mut shader = FlatShader::default();
    let mut points = Vec::with_capacity(4);
    let hit = |s: usize| hits[s].as_ref().expect("samples with hits");
    for four in samples.chunks(4) {
        let flat = |k: usize| four.get(k).and_then(|&s| flat_kd(&scene.mesh, hit(s).id));
        match (four, [flat(0), flat(1), flat(2), flat(3)]) {
            (&[s0, s1, s2, s3], [Some(kd0), Some(kd1), Some(kd2), Some(kd3)]) => {
                let flat_hit = |s: usize, kd: [f32; 3]| FlatHit {
                    corners: bvh.hit_corners(hit(s)),
                    b: &hit(s).b,
                    dir: &rays[s].dir,
                    kd,
                };
                let flat_hits = [
                    flat_hit(s0, kd0),
                    flat_hit(s1, kd1),
                    flat_hit(s2, kd2),
                    flat_hit(s3, kd3),
                ];
                // One push each: built as one array, the four were stored piece by piece
                // and read back whole, a store-forwarding stall of 3-4% of a render.
                reflectances.push(kd0);
                reflectances.push(kd1);
                reflectances.push(kd2);
                reflectances.push(kd3);
                shader.shadow_tests4(&flat_hits, &scene.lights, |k, l, test| {
                    visit(four[k], l, test)
                });
            }
            _ => {
                for &s in four {
                    let point = surface_of(&scene.mesh, bvh, hit(s), &rays[s]);
                    reflectances.push(point.kd);
                    points.push(point);
                }
                shadow_tests(&points, &scene.lights, |p, l, test| visit(four[p], l, test));
                points.clear();
            }
        }
    }
    let mut traced = vec![false; segments.len()];
    timer.lap(Phase::Shading);
    // Light by light: with several lights, neighbouring segments alternate lights.
    let lights = (segment_lights.as_slice(), scene.lights.len());
    bvh.occluded_grouped(
        &segments,
        lights,
        &mut traced,
        &mut SegmentGroups::default(),
    );
    timer.lap(Phase::ShadowRays);
    // Each test's answer in test order: unblocked when not traced, else its segment's.
    let mut traced = traced.into_iter();
    let mut next = tests.iter().peekable();
    let mut colours = vec![scene.background; hits.len()];
    for (&sample, &kd) in samples.iter().zip(&reflectances) {
        // This sample's unblocked lights, in light order, straight from the test list (no
        // per-sample allocation).
        let contributions = std::iter::from_fn(|| {
            next.next_if(|(s, _, _)| *s == sample)
                .map(|&(_, unoccluded, free)| {
                    let blocked = !free && traced.next().unwrap_or(false);
                    (!blocked).then_some(unoccluded)
                })
        })
        .flatten();
        colours[sample] = combine(kd, contributions, scene.ambient);
    }
    timer.lap(Phase::Shading);
    colours
}

/// Camera samples traced per `closest_hits` call (rounded to whole pixels).
pub(crate) const BATCH_SAMPLES: usize = 1024;

/// A band's pixels, row-major from its first row, and its ray counts.
struct Band {
    colours: Vec<[f32; 3]>,
    hits: Vec<Hit>,
    rays: RayCounts,
}

/// Renders the band of up to [`BAND_ROWS`] rows from row `y0`, tile by tile
/// ([`crate::tiles`]). Each pixel is the mean of its samples in sample order, whatever order
/// the pixels are traced in, so the band's bits are those of rendering its rows one by one.
fn render_band(
    scene: &Scene,
    bvh: &Bvh,
    setup: &Setup,
    s: RenderSettings,
    y0: u32,
    timer: &mut impl PhaseTimer,
) -> Band {
    let rows = BAND_ROWS.min(s.height - y0);
    let width = s.width as usize;
    let pixels = width * rows as usize;
    let mut band = Band {
        colours: vec![[0.0; 3]; pixels],
        hits: vec![Hit::MISS; pixels],
        rays: RayCounts::default(),
    };
    // The band's pixels tile by tile ([`crate::tiles`]), each pixel's samples together in
    // trace order ([`TraceOrder`]), in batches of about `BATCH_SAMPLES` samples (whole pixels):
    // memory stays bounded whatever the width and spp.
    let first_pixel = u64::from(y0) * u64::from(s.width);
    let order = tile_order(first_pixel..first_pixel + pixels as u64, s.width)
        .map(|p| (p - first_pixel) as usize);
    let samples = s.spp as usize;
    let pixels_per_batch = (BATCH_SAMPLES / samples).max(1);
    let mut batch = Vec::with_capacity(pixels_per_batch);
    let mut order = order.peekable();
    let mut rays = Vec::new();
    let mut hits = Vec::new();
    while order.peek().is_some() {
        timer.lap(Phase::Loop);
        batch.clear();
        batch.extend(order.by_ref().take(pixels_per_batch));
        rays.clear();
        for &i in &batch {
            let pixel = first_pixel + i as u64;
            setup.camera.pixel_rays(pixel, &setup.order, &mut rays);
        }
        // `closest_hits` writes every place: only a new length is filled.
        hits.resize(rays.len(), None);
        timer.lap(Phase::CameraRays);
        bvh.closest_hits(&rays, &mut hits);
        timer.lap(Phase::ClosestHits);
        let colours = shade_batch_timed(scene, bvh, &setup.unoccludable, &rays, &hits, timer);
        for ((&i, colours), hits) in batch
            .iter()
            .zip(colours.chunks(samples))
            .zip(hits.chunks(samples))
        {
            // The mean in sample order, whatever the trace order.
            let mut sum = PixelSum::default();
            for sample in 0..s.spp {
                sum.add(colours[setup.order.position(sample)]);
            }
            // One primary ray per sample, and for a hit one shadow ray per light.
            let hit_samples = hits.iter().filter(|hit| hit.is_some()).count() as u64;
            band.rays += RayCounts {
                primary: u64::from(s.spp),
                shadow: hit_samples * scene.lights.len() as u64,
            };
            band.colours[i] = sum.mean(s.spp);
            band.hits[i] = hits[setup.order.position(0)].map_or(Hit::MISS, |h| Hit {
                triangle: h.id,
                t: h.t,
            });
        }
        timer.lap(Phase::Accumulation);
    }
    band
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::sample_offset;
    use crate::scene::load_scene;
    use crate::shading::shadow_test;

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
        // 64 spp: rows of several batches; 1 and 3 spp: tiles across batches, and sizes that
        // end in a partial tile and a partial band.
        for (width, height, spp) in [(42, 6, 64), (37, 7, 1), (29, 5, 3)] {
            check_against_single_samples(&scene, &bvh, width, height, spp);
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
