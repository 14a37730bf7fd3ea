//! Shading a batch of camera samples: their surfaces, their shadow rays traced as packets light
//! by light, and each sample's radiance.

use super::surfaces::Surfaces;
use crate::bvh::{
    Bvh, ClosestHit, HitColumns, KernelWidth, SegmentColumns, bits, first_bits, kernel_width,
};
use crate::phase_timer::{Phase, PhaseTimer};
use crate::scene::{Light, TriangleShading};
use crate::shading::{HitLanes, TestLanes, add_ambient, flat_test_lanes, smooth_test_lanes};
use crate::triangle::Ray;
use glam::Vec3;

/// The lights of a render and what a sample shows besides them.
#[derive(Clone, Copy, Debug)]
pub struct Lighting<'a> {
    /// The lights, in the order their contributions are summed.
    pub lights: &'a [Light],
    /// Per light: no surface can occlude it
    /// ([`crate::unoccludable::unoccludable_lights`]). Its shadow rays are not traced and
    /// count as unblocked, which is what tracing them would give.
    pub unoccludable: &'a [bool],
    /// Radiance added to every hit sample, times its reflectance.
    pub ambient: [f32; 3],
    /// Radiance of a sample that hits nothing.
    pub background: [f32; 3],
}

/// One light's shadow tests in a batch, hit by hit (the batch's hit samples in sample
/// order, shaded in groups of [`SHADING_LANES`]): which hits of each group have a test, the
/// tests' segments in hit order (none when the light is unoccludable), and per hit the
/// radiance the light adds, channel by channel: the test's radiance when unblocked, +0 for a
/// hit without a test or (once [`LightTests::drop_blocked`] ran) a blocked one.
#[derive(Default)]
struct LightTests {
    segments: SegmentColumns,
    /// Per group, bit k: hit k of the group has a test.
    lit: Vec<u32>,
    /// Per hit, the radiance added, channel by channel.
    added: [Vec<f32>; 3],
}

impl LightTests {
    fn clear(&mut self) {
        self.segments.clear();
        self.lit.clear();
        self.added.iter_mut().for_each(Vec::clear);
    }

    /// Sets to +0 the radiance of the hits whose segment is blocked (`blocked[i]` for
    /// segment `i`, one per test). Panics unless there is one answer per segment.
    fn drop_blocked(&mut self, blocked: &[bool]) {
        let mut segment = 0;
        for (group, &lit) in self.lit.iter().enumerate() {
            let run = &blocked[segment..segment + lit.count_ones() as usize];
            segment += run.len();
            if run.contains(&true) {
                for (k, _) in bits(lit).zip(run).filter(|(_, blocked)| **blocked) {
                    for column in &mut self.added {
                        column[group * SHADING_LANES + k] = 0.0;
                    }
                }
            }
        }
        assert_eq!(segment, blocked.len(), "one answer per test");
    }
}

/// What shading a batch needs besides its inputs, kept from batch to batch so each batch
/// reuses the last one's memory instead of allocating its own.
#[derive(Default)]
pub(crate) struct ShadingScratch {
    /// The samples with hits, in sample order.
    samples: Vec<u32>,
    /// Per hit sample, its reflectance.
    reflectances: Vec<[f32; 3]>,
    /// Per light, its tests.
    tests: Vec<LightTests>,
    /// Per light, whether each of its segments is blocked.
    blocked: Vec<Vec<bool>>,
    /// Per hit sample, the sum of its lights, channel by channel.
    sums: [Vec<f32>; 3],
    /// Per sample, its radiance.
    colours: Vec<[f32; 3]>,
}

/// Where a batch's shadow tests go: each light's to its [`LightTests`].
struct TestSink<'a> {
    unoccludable: &'a [bool],
    tests: &'a mut [LightTests],
}

impl TestSink<'_> {
    /// Light `light`'s tests at the hits of `group` (lane k: hit k of the group; lanes past
    /// the group's end have no test).
    #[inline(always)]
    fn lanes<const N: usize>(&mut self, group: &[u32], light: usize, lanes: &TestLanes<N>) {
        let lit = lanes.lit & first_bits(group.len());
        let tests = &mut self.tests[light];
        if !self.unoccludable[light] {
            let columns = &mut tests.segments;
            columns.push_lanes(lit, &lanes.origin, &lanes.dir, lanes.t_max);
        }
        tests.lit.push(lit);
        for (column, lanes) in tests.added.iter_mut().zip(&lanes.unoccluded) {
            let added: [f32; N] =
                std::array::from_fn(|k| if lit & (1 << k) != 0 { lanes[k] } else { 0.0 });
            // A whole group's is a fixed-size copy, where a slice of any length is a call.
            if group.len() == N {
                column.extend_from_slice(&added);
            } else {
                column.extend_from_slice(&added[..group.len()]);
            }
        }
    }
}

/// What [`hit_tests`] reads: the batch's hit samples, their rays and hits, where their
/// triangles' shading data and corners are, and the lights.
struct HitSamples<'a, S> {
    surfaces: &'a S,
    bvh: &'a Bvh,
    lights: &'a [Light],
    rays: &'a [Ray],
    hits: &'a HitColumns,
    /// The samples with hits, in sample order.
    samples: &'a [u32],
    /// Whether the hits' reflectances are pushed (they are read only for an ambient term).
    keep_reflectances: bool,
}

/// A group's hits' barycentrics (per corner) and rays when it is `N` consecutive samples
/// ([`HitSamples::run_of`]), and their first sample.
type Run<'a, const N: usize> = Option<([&'a [f32; N]; 3], &'a [Ray; N], usize)>;

/// The sample in lane `k` of a group of 1 to `N` hit samples: lanes past the group's end
/// repeat its last.
#[inline(always)]
fn lane_sample(group: &[u32], k: usize) -> u32 {
    group[k.min(group.len() - 1)]
}

impl<S: Surfaces> HitSamples<'_, S> {
    /// Sample `s`'s hit.
    #[inline(always)]
    fn hit(&self, s: u32) -> ClosestHit {
        self.bvh
            .hit_in(self.hits, s as usize)
            .expect("samples with hits")
    }

    /// The hits and rays of `group` when it is `N` consecutive samples (most groups where
    /// every sample hits).
    #[inline(always)]
    fn run_of<const N: usize>(&self, group: &[u32]) -> Run<'_, N> {
        let (&first, &last) = (group.first()?, group.last()?);
        if group.len() != N || (last - first) as usize != N - 1 {
            return None;
        }
        let range = first as usize..first as usize + N;
        let b = |c| self.hits.b(c)[range.clone()].try_into().ok();
        Some((
            [b(0)?, b(1)?, b(2)?],
            self.rays[range.clone()].try_into().ok()?,
            range.start,
        ))
    }

    /// The shading data of `hit`'s triangle, from `last` (the last triangle's, which it then
    /// keeps) when it is the same triangle: consecutive samples mostly hit the same one.
    #[inline(always)]
    fn shading_of<'l>(
        &self,
        hit: &ClosestHit,
        last: &'l mut Option<(u32, TriangleShading)>,
    ) -> &'l TriangleShading {
        if last.as_ref().is_none_or(|(index, _)| *index != hit.index) {
            *last = Some((hit.index, self.surfaces.shading(hit)));
        }
        let Some((_, shading)) = last else {
            unreachable!("set above")
        };
        shading
    }

    /// Fills `lanes` with the hits of `group` (lane k: sample `group[k]`, lanes past the
    /// group's end its last hit), all on the triangle `first` hit, and pushes their
    /// reflectances (where [`HitSamples::keep_reflectances`]); whether the triangle needs the
    /// smooth lanes (it has vertex normals; a texture only changes the reflectances). The
    /// triangle's corners, normals and (untextured) reflectance go to every lane at once, and a
    /// texture is looked up in lanes ([`crate::texture::TexturedCorners::kd_lanes`]): the
    /// values [`Self::fill_mixed`] writes lane by lane. `run` is [`Self::run_of`]`(group)`;
    /// `last` is [`Self::shading_of`]'s.
    #[inline(always)]
    fn fill_one_triangle<const N: usize>(
        &self,
        (group, first, run): (&[u32], &ClosestHit, Run<'_, N>),
        last: &mut Option<(u32, TriangleShading)>,
        lanes: &mut HitLanes<N>,
        reflectances: &mut Vec<[f32; 3]>,
    ) -> bool {
        let shading = self.shading_of(first, last);
        let normals = shading.normals.unwrap_or([Vec3::ZERO; 3]);
        lanes.set_triangle(self.bvh.hit_corners(first), &normals);
        if let Some((b, rays, _)) = run {
            // A run of consecutive samples: read in order, without looking each one up.
            lanes.set_b_lanes(b);
            for (k, ray) in rays.iter().enumerate() {
                lanes.set_dir(k, &ray.dir);
            }
        } else {
            for k in 0..N {
                let s = lane_sample(group, k);
                lanes.set_ray(k, &self.hit(s).b, &self.rays[s as usize].dir);
            }
        }
        match &shading.texture {
            None => {
                lanes.set_kd_all(shading.kd);
                if self.keep_reflectances {
                    reflectances.extend(std::iter::repeat_n(shading.kd, group.len()));
                }
            }
            Some(t) => {
                // The texture looked up in lanes, from the barycentrics just written.
                let kd = t.kd_lanes(shading.kd, self.surfaces.texture(t), lanes.b());
                lanes.set_kd_lanes(kd);
                if self.keep_reflectances {
                    let at = |k: usize| [kd[0][k], kd[1][k], kd[2][k]];
                    reflectances.extend((0..group.len()).map(at));
                }
            }
        }
        shading.normals.is_some()
    }

    /// Fills `lanes` with the hits of `group` (lane k: sample `group[k]`, lanes past the
    /// group's end its last hit), hit by hit, and pushes their reflectances (where
    /// [`HitSamples::keep_reflectances`]); whether a hit needs the smooth lanes (has vertex
    /// normals). The normals are written once a hit of the group has them: zeros until then,
    /// and for flat triangles. `last` is [`Self::shading_of`]'s.
    #[inline(always)]
    fn fill_mixed<const N: usize>(
        &self,
        group: &[u32],
        last: &mut Option<(u32, TriangleShading)>,
        lanes: &mut HitLanes<N>,
        reflectances: &mut Vec<[f32; 3]>,
    ) -> bool {
        let mut smooth = false;
        for k in 0..N {
            let s = lane_sample(group, k);
            let h = &self.hit(s);
            let kd = match self.surfaces.flat_kd(h) {
                Some(kd) => {
                    if smooth {
                        lanes.set_normals(k, &[Vec3::ZERO; 3]);
                    }
                    kd
                }
                None => {
                    let shading = self.shading_of(h, last);
                    match &shading.normals {
                        Some(normals) => {
                            if !smooth {
                                smooth = true;
                                lanes.clear_normals();
                            }
                            lanes.set_normals(k, normals);
                        }
                        None if smooth => lanes.set_normals(k, &[Vec3::ZERO; 3]),
                        None => {}
                    }
                    self.surfaces.kd_on(shading, h.b)
                }
            };
            lanes.set_corners(k, self.bvh.hit_corners(h));
            lanes.set_ray(k, &h.b, &self.rays[s as usize].dir);
            lanes.set_kd(k, kd);
            if k < group.len() && self.keep_reflectances {
                reflectances.push(kd);
            }
        }
        smooth
    }
}

/// Every hit sample's lights' tests, handed to `sink` in sample order (each sample's in light
/// order), and its reflectance, pushed to `reflectances` where the input keeps them: `N` hits
/// shaded at once in lanes, their tests handed over light by light, each hit with its
/// reflectance at the hit (textured or not); when all are on flat triangles by the flat lanes,
/// else with their vertex normals (zeros for a flat triangle, which give the flat lanes'
/// tests). A last group of fewer than
/// `N` fills its lanes with its last hit, whose extra tests are dropped. A group whose hits are
/// all on one triangle (most groups: a run of samples lies in one part of a pixel) takes the
/// triangle's data once. The same tests every way and at every `N`.
#[inline(always)]
fn hit_tests<const N: usize, S: Surfaces>(
    input: &HitSamples<'_, S>,
    reflectances: &mut Vec<[f32; 3]>,
    sink: &mut TestSink<'_>,
) {
    let mut lanes = HitLanes::<N>::default();
    let mut last = None;
    let place = input.hits.place();
    for group in input.samples.chunks(N) {
        let first = input.hit(group[0]);
        // Hits on one triangle have one place (every sample of the group hits).
        let run = input.run_of::<N>(group);
        let one_triangle = match run {
            Some((_, _, from)) => {
                let places: &[u32; N] = place[from..from + N].try_into().expect("a run");
                places.iter().all(|&p| p == places[0])
            }
            None => group
                .iter()
                .all(|&s| place[s as usize] == place[group[0] as usize]),
        };
        let smooth = if one_triangle {
            input.fill_one_triangle((group, &first, run), &mut last, &mut lanes, reflectances)
        } else {
            input.fill_mixed(group, &mut last, &mut lanes, reflectances)
        };
        let visit = |l: usize, tests: &TestLanes<N>| sink.lanes(group, l, tests);
        if smooth {
            // Vertex normals: the same tests, with each hit's normals (zeros for a flat
            // triangle).
            smooth_test_lanes(&lanes, input.lights, visit);
        } else {
            flat_test_lanes(&lanes, input.lights, visit);
        }
    }
}

/// Hits shaded at once ([`hit_tests`]): sixteen lanes with every instruction set. They take
/// one AVX-512 register, two AVX ones or four SSE or NEON ones per value. Measured at 64 spp
/// on the bundled scenes, one pinned core, against the four-lane shader it replaced (SSE4.1
/// at every width): the shading phase took 0.78x to 0.82x the time with AVX-512 and with AVX2
/// on the bunny, the Cornell box and the teapot (the textured globe 0.97x and 1.01x, its
/// texture lookups one hit at a time), and 0.92x to 0.96x with SSE4.1 (the globe 1.14x: its
/// smooth lanes spill SSE's sixteen registers). Four lanes with SSE, or eight with AVX2, were
/// 4-26% slower than sixteen: the per-group work is then paid more often.
const SHADING_LANES: usize = 16;

/// [`hit_tests`] compiled with `$compile` (an instruction set).
macro_rules! hit_tests_with {
    ($name:ident, $compile:meta) => {
        #[$compile]
        fn $name<S: Surfaces>(
            input: &HitSamples<'_, S>,
            reflectances: &mut Vec<[f32; 3]>,
            sink: &mut TestSink<'_>,
        ) {
            hit_tests::<SHADING_LANES, S>(input, reflectances, sink)
        }
    };
}
// Every host's instruction set (SSE4.1 in x86-64's baseline here, NEON on aarch64).
hit_tests_with!(hit_tests_baseline, inline(never));
// Call only on hosts with AVX2.
#[cfg(target_arch = "x86_64")]
hit_tests_with!(hit_tests_avx2, target_feature(enable = "avx2"));
// Call only on hosts with AVX-512F.
#[cfg(target_arch = "x86_64")]
hit_tests_with!(hit_tests_avx512, target_feature(enable = "avx512f"));

/// [`hit_tests`] compiled for the instruction set of the ray kernels' width
/// ([`kernel_width`]): AVX-512 at sixteen, AVX2 at eight, else the baseline's. The same
/// tests every way.
#[allow(unsafe_code)]
fn hit_tests_dispatched<S: Surfaces>(
    input: &HitSamples<'_, S>,
    reflectances: &mut Vec<[f32; 3]>,
    sink: &mut TestSink<'_>,
) {
    match kernel_width() {
        KernelWidth::Four => hit_tests_baseline(input, reflectances, sink),
        // SAFETY: the width is Eight only on hosts with AVX2 (`crate::bvh::dispatch`).
        #[cfg(target_arch = "x86_64")]
        KernelWidth::Eight => unsafe { hit_tests_avx2(input, reflectances, sink) },
        // SAFETY: the width is Sixteen only on hosts with AVX-512F.
        #[cfg(target_arch = "x86_64")]
        KernelWidth::Sixteen => unsafe { hit_tests_avx512(input, reflectances, sink) },
        #[cfg(not(target_arch = "x86_64"))]
        KernelWidth::Eight | KernelWidth::Sixteen => hit_tests_baseline(input, reflectances, sink),
    }
}

/// The radiance of every sample of a batch whose primary rays `rays` have the closest hits
/// `hits` (found by `bvh`, whose triangles `surfaces` describes): the background for a miss,
/// else Lambert shading with the lights its shadow rays reach (summed in light order) plus
/// ambient. The shadow rays of the whole batch are traced as packets, light by light
/// ([`Bvh::occluded_columns`]), each light's in sample order. The shading and shadow-ray
/// phases are reported to `timer`.
#[inline(always)]
pub(super) fn shade_batch_timed<'s>(
    (surfaces, bvh): (&impl Surfaces, &Bvh),
    lighting: &Lighting,
    (rays, hits): (&[Ray], &HitColumns),
    scratch: &'s mut ShadingScratch,
    timer: &mut impl PhaseTimer,
) -> &'s [[f32; 3]] {
    let lights = lighting.lights;
    let ShadingScratch {
        samples,
        reflectances,
        tests,
        blocked,
        sums,
        colours,
    } = scratch;
    // The samples with hits, in order: every sample written, the count advanced past hits
    // only (no branch per sample).
    samples.clear();
    samples.resize(hits.len(), 0);
    let mut with_hits = 0;
    for (s, &t) in hits.t().iter().enumerate() {
        samples[with_hits] = s as u32;
        // Hits have finite t: +inf means none was found.
        with_hits += usize::from(t < f32::INFINITY);
    }
    samples.truncate(with_hits);
    tests.resize_with(lights.len(), LightTests::default);
    tests.iter_mut().for_each(LightTests::clear);
    reflectances.clear();
    let mut sink = TestSink {
        unoccludable: lighting.unoccludable,
        tests,
    };
    // Without an ambient term a hit's colour is its lights' sum: its reflectance is not read.
    let keep_reflectances = lighting.ambient != [0.0; 3];
    let input = HitSamples {
        surfaces,
        bvh,
        lights,
        rays,
        hits,
        samples,
        keep_reflectances,
    };
    hit_tests_dispatched(&input, reflectances, &mut sink);
    timer.lap(Phase::Shading);
    // Light by light, each light's segments in sample order.
    blocked.resize_with(lights.len(), Vec::new);
    for (tests, blocked) in tests.iter().zip(blocked.iter_mut()) {
        blocked.clear();
        blocked.resize(tests.segments.len(), false);
        bvh.occluded_columns(&tests.segments, blocked);
    }
    timer.lap(Phase::ShadowRays);
    // A hit sample's colour is its lights' sum plus the ambient term: from +0, each light's
    // radiance added in light order, as `combine` does, +0 where the light is blocked or has
    // no test (adding +0 leaves every sum as it is: a sum from +0 is never -0).
    for (tests, blocked) in tests.iter_mut().zip(blocked.iter()) {
        if !blocked.is_empty() {
            tests.drop_blocked(blocked);
        }
    }
    for (c, sums) in sums.iter_mut().enumerate() {
        sums.clear();
        sums.resize(samples.len(), 0.0);
        for tests in tests.iter() {
            assert_eq!(
                tests.added[c].len(),
                sums.len(),
                "every light's radiance per hit"
            );
            for (sum, added) in sums.iter_mut().zip(&tests.added[c]) {
                *sum += added;
            }
        }
    }
    let [red, green, blue] = sums;
    let sums = red.iter().zip(&*green).zip(&*blue);
    let sums = sums.map(|((&r, &g), &b)| [r, g, b]);
    let place = (
        &mut *colours,
        samples.as_slice(),
        hits.len(),
        lighting.background,
    );
    if keep_reflectances {
        let ambient = lighting.ambient;
        let hit_colours = sums.zip(&*reflectances);
        place_colours(
            place,
            hit_colours.map(|(sum, &kd)| add_ambient(sum, kd, ambient)),
        );
    } else {
        // No ambient term: `sum + kd · 0` is `sum` (reflectances are finite and sums are never
        // -0), so the sums are the colours.
        place_colours(place, sums);
    }
    timer.lap(Phase::Shading);
    colours
}

/// Puts the batch's colours in `colours` (emptied first), one per sample: the hit samples'
/// `hit_colours`, in the order of `samples`, and `background` for the rest of the
/// `sample_count`.
#[inline(always)]
fn place_colours(
    (colours, samples, sample_count, background): (&mut Vec<[f32; 3]>, &[u32], usize, [f32; 3]),
    hit_colours: impl Iterator<Item = [f32; 3]>,
) {
    colours.clear();
    if samples.len() == sample_count {
        // Every sample hits (so hit k is sample k): the colours in order, no background.
        colours.extend(hit_colours);
    } else {
        colours.resize(sample_count, background);
        // A slice taken once: indexing the vector in the loop reloaded its pointer.
        let colours = colours.as_mut_slice();
        for (&sample, colour) in samples.iter().zip(hit_colours) {
            colours[sample as usize] = colour;
        }
    }
}
