//! Shading a batch of camera samples: their surfaces, their shadow rays traced as packets light
//! by light, and each sample's radiance.

use super::surfaces::Surfaces;
use crate::bvh::{Bvh, ClosestHit, SegmentColumns, bits};
use crate::phase_timer::{Phase, PhaseTimer};
use crate::scene::Light;
use crate::shading::{
    FlatHit, LastFrame, ShadowTest, ShadowTester, SurfacePoint, TestLanes, add_ambient, add_light,
    flat_test_lanes, smooth_test_lanes,
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
    sample: u32,
    /// The light.
    light: u32,
    /// Whether its segment was traced (the light is occludable). Each light's traced tests'
    /// answers are its segments' answers in the same order.
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
    /// Per light, the shadow segments to trace, in sample order, and whether each is blocked.
    segments: Vec<SegmentColumns>,
    blocked: Vec<Vec<bool>>,
    /// Per light, how many of its answers the sum has read.
    read: Vec<usize>,
    /// Per lit (sample, light), each sample's lights in light order.
    tests: Vec<Lit>,
    /// Per sample, its radiance.
    colours: Vec<[f32; 3]>,
    tester: ShadowTester,
    points: Vec<SurfacePoint>,
}

/// Where a batch's shadow tests go: each traced one's segment to its light's columns, and
/// every one to the list the sum over lights reads.
struct TestSink<'a> {
    unoccludable: &'a [bool],
    segments: &'a mut [SegmentColumns],
    tests: &'a mut Vec<Lit>,
}

impl TestSink<'_> {
    /// Light `light`'s tests at the four samples `four` (lane k: sample `four[k]`).
    #[inline(always)]
    fn lanes(&mut self, four: &[usize], light: usize, lanes: &TestLanes) {
        let traced = !self.unoccludable[light];
        if traced {
            let columns = &mut self.segments[light];
            columns.push_lanes(lanes.lit, &lanes.origin, &lanes.dir, lanes.t_max);
        }
        for k in bits(lanes.lit) {
            self.tests.push(Lit {
                sample: four[k] as u32,
                light: light as u32,
                traced,
                unoccluded: lanes.unoccluded(k),
            });
        }
    }

    /// Light `light`'s test at `sample`.
    #[inline(always)]
    fn one(&mut self, sample: usize, light: usize, test: ShadowTest) {
        let traced = !self.unoccludable[light];
        if traced {
            self.segments[light].push(&test.ray, test.t_max);
        }
        self.tests.push(Lit {
            sample: sample as u32,
            light: light as u32,
            traced,
            unoccluded: test.unoccluded,
        });
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
    (rays, hits): (&[Ray], &[Option<ClosestHit>]),
    scratch: &'s mut ShadingScratch,
    timer: &mut impl PhaseTimer,
) -> &'s [[f32; 3]] {
    let lights = lighting.lights;
    let ShadingScratch {
        samples,
        reflectances,
        segments,
        blocked,
        read,
        tests,
        colours,
        tester,
        points,
    } = scratch;
    // Per hit, in sample order, its lights' tests, and its reflectance. Four hits are shaded
    // at once in lanes, their tests handed over light by light: on flat, untextured triangles
    // by the flat lanes, else with their vertex normals (zeros for a flat triangle) and their
    // reflectances at the hits; a last group of fewer than four goes through its surface
    // points. The same tests every way, and each sample's in light order.
    samples.clear();
    samples.extend((0..hits.len()).filter(|&s| hits[s].is_some()));
    segments.resize_with(lights.len(), SegmentColumns::default);
    segments.iter_mut().for_each(SegmentColumns::clear);
    tests.clear();
    reflectances.clear();
    let mut sink = TestSink {
        unoccludable: lighting.unoccludable,
        segments,
        tests,
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
                flat_test_lanes(&flat_hits, lights, |l, lanes| sink.lanes(four, l, lanes));
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
                smooth_test_lanes(&lane_hits, &normals, lights, |l, lanes| {
                    sink.lanes(four, l, lanes)
                });
            }
            _ => {
                for &s in four {
                    let point = surfaces.surface(bvh, hit(s), &rays[s], &mut last);
                    reflectances.push(point.kd);
                    points.push(point);
                }
                tester.shadow_tests(points, lights, |p, l, test| sink.one(four[p], l, test));
                points.clear();
            }
        }
    }
    timer.lap(Phase::Shading);
    // Light by light, each light's segments in sample order.
    blocked.resize_with(lights.len(), Vec::new);
    for (segments, blocked) in segments.iter().zip(blocked.iter_mut()) {
        blocked.clear();
        blocked.resize(segments.len(), false);
        bvh.occluded_columns(segments, blocked);
    }
    timer.lap(Phase::ShadowRays);
    // A hit sample's colour is its lights' sum until the ambient term is added: from +0, each
    // test's radiance added unless its segment is blocked, in one pass over the tests. Each
    // sample's tests come in light order, so each sum adds its lights in light order, as
    // `combine` does.
    colours.clear();
    colours.resize(hits.len(), lighting.background);
    for &sample in samples.iter() {
        colours[sample] = [0.0; 3];
    }
    if let [blocked] = blocked.as_slice() {
        // One light: its answers in test order.
        let mut blocked = blocked.iter();
        for test in tests.iter() {
            if !(test.traced && *blocked.next().expect("an answer per traced test")) {
                add_light(&mut colours[test.sample as usize], test.unoccluded);
            }
        }
    } else {
        read.clear();
        read.resize(lights.len(), 0);
        for test in tests.iter() {
            let light = test.light as usize;
            let blocked = test.traced && {
                let answer = blocked[light][read[light]];
                read[light] += 1;
                answer
            };
            if !blocked {
                add_light(&mut colours[test.sample as usize], test.unoccluded);
            }
        }
    }
    for (&sample, &kd) in samples.iter().zip(reflectances.iter()) {
        colours[sample] = add_ambient(colours[sample], kd, lighting.ambient);
    }
    timer.lap(Phase::Shading);
    colours
}
