//! Shading a batch of camera samples: their surfaces, their shadow rays traced as packets light
//! by light, and each sample's radiance.

use super::surfaces::Surfaces;
use crate::bvh::{Bvh, ClosestHit, SegmentGroups};
use crate::phase_timer::{Phase, PhaseTimer};
use crate::scene::Light;
use crate::shading::{
    FlatHit, FlatShader, LastFrame, ShadowTest, ShadowTester, SurfacePoint, add_ambient, add_light,
};
use crate::triangle::Ray;

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

/// One light's shadow test at a sample, as the sum over lights needs it.
struct Lit {
    /// The sample.
    sample: usize,
    /// Whether its segment was traced (the light is occludable). The traced tests' answers
    /// are the segments' answers in the same order.
    traced: bool,
    /// Its radiance when unblocked.
    unoccluded: [f32; 3],
}

/// What shading a batch needs besides its inputs, kept from batch to batch so each batch
/// reuses the last one's memory instead of allocating its own.
#[derive(Default)]
pub(crate) struct ShadingScratch {
    /// The samples with hits, in sample order.
    samples: Vec<usize>,
    /// Per hit sample, its reflectance.
    reflectances: Vec<[f32; 3]>,
    /// The shadow segments to trace, and each one's light.
    segments: Vec<(Ray, f32)>,
    segment_lights: Vec<u32>,
    /// Per lit (sample, light), in order of sample, then light.
    tests: Vec<Lit>,
    /// Per segment, whether it is blocked.
    blocked: Vec<bool>,
    /// Per sample, its radiance.
    colours: Vec<[f32; 3]>,
    groups: SegmentGroups,
    shader: FlatShader,
    tester: ShadowTester,
    points: Vec<SurfacePoint>,
}

/// The radiance of every sample of a batch whose primary rays `rays` have the closest hits
/// `hits` (found by `bvh`, whose triangles `surfaces` describes): the background for a miss,
/// else Lambert shading with the lights its shadow rays reach (summed in light order) plus
/// ambient. The shadow rays of the whole batch are traced as packets, light by light
/// ([`Bvh::occluded_grouped`]), each light's in sample order. The shading and shadow-ray
/// phases are reported to `timer`.
#[inline(always)]
pub(super) fn shade_batch_timed<'s>(
    (surfaces, bvh): (&impl Surfaces, &Bvh),
    lighting: &Lighting,
    (rays, hits): (&[Ray], &[Option<ClosestHit>]),
    scratch: &'s mut ShadingScratch,
    timer: &mut impl PhaseTimer,
) -> &'s [[f32; 3]] {
    let lights = lighting.lights;
    let ShadingScratch {
        samples,
        reflectances,
        segments,
        segment_lights,
        tests,
        blocked,
        colours,
        groups,
        shader,
        tester,
        points,
    } = scratch;
    // Per hit, in sample order, its lights' tests in light order (the order `combine` sums
    // them in), and its reflectance. Four hits are shaded at once in lanes: on flat,
    // untextured triangles by the flat lanes, else with their vertex normals (zeros for a flat
    // triangle) and their reflectances at the hits; a last group of fewer than four goes
    // through its surface points. The same tests every way.
    samples.clear();
    samples.extend((0..hits.len()).filter(|&s| hits[s].is_some()));
    segments.clear();
    segment_lights.clear();
    tests.clear();
    reflectances.clear();
    let mut visit = |sample: usize, light: usize, test: ShadowTest| {
        let free = lighting.unoccludable[light];
        if !free {
            segments.push((test.ray, test.t_max));
            segment_lights.push(light as u32);
        }
        tests.push(Lit {
            sample,
            traced: !free,
            unoccluded: test.unoccluded,
        });
    };
    let mut last = LastFrame::default();
    let hit = |s: usize| hits[s].as_ref().expect("samples with hits");
    for four in samples.chunks(4) {
        let flat = |k: usize| four.get(k).and_then(|&s| surfaces.flat_kd(hit(s)));
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
                shader.shadow_tests4(&flat_hits, lights, |k, l, test| visit(four[k], l, test));
            }
            (&[s0, s1, s2, s3], _) => {
                // Vertex normals or textures: the same tests in lanes, with each hit's
                // normals (zeros for a flat triangle) and reflectance at the hit.
                // Spelled out: `array::map` here was not inlined (5% of a textured render).
                let shade = |s: usize| surfaces.lane_shading(hit(s));
                let shading = [shade(s0), shade(s1), shade(s2), shade(s3)];
                let lane_hit = |s: usize, k: usize| FlatHit {
                    corners: bvh.hit_corners(hit(s)),
                    b: &hit(s).b,
                    dir: &rays[s].dir,
                    kd: shading[k].1,
                };
                let lane_hits = [
                    lane_hit(s0, 0),
                    lane_hit(s1, 1),
                    lane_hit(s2, 2),
                    lane_hit(s3, 3),
                ];
                for (_, kd) in &shading {
                    reflectances.push(*kd);
                }
                let normals = [shading[0].0, shading[1].0, shading[2].0, shading[3].0];
                shader.smooth_tests4(&lane_hits, &normals, lights, |k, l, test| {
                    visit(four[k], l, test)
                });
            }
            _ => {
                for &s in four {
                    let point = surfaces.surface(bvh, hit(s), &rays[s], &mut last);
                    reflectances.push(point.kd);
                    points.push(point);
                }
                tester.shadow_tests(points, lights, |p, l, test| visit(four[p], l, test));
                points.clear();
            }
        }
    }
    blocked.clear();
    blocked.resize(segments.len(), false);
    timer.lap(Phase::Shading);
    // Light by light: with several lights, neighbouring segments alternate lights.
    let by_light = (segment_lights.as_slice(), lights.len());
    bvh.occluded_grouped(segments, by_light, blocked, groups);
    timer.lap(Phase::ShadowRays);
    // A hit sample's colour is its lights' sum until the ambient term is added: from +0, each
    // test's radiance added unless its segment is blocked, in one pass over the tests. Tests
    // come in order of sample, then light, so each sum adds its lights in light order, as
    // `combine` does.
    colours.clear();
    colours.resize(hits.len(), lighting.background);
    for &sample in samples.iter() {
        colours[sample] = [0.0; 3];
    }
    let mut blocked = blocked.iter();
    for test in tests.iter() {
        if !(test.traced && *blocked.next().expect("an answer per traced test")) {
            add_light(&mut colours[test.sample], test.unoccluded);
        }
    }
    for (&sample, &kd) in samples.iter().zip(reflectances.iter()) {
        colours[sample] = add_ambient(colours[sample], kd, lighting.ambient);
    }
    timer.lap(Phase::Shading);
    colours
}
