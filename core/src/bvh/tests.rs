//! The BVH must agree exactly with brute force, and closed meshes must not leak.

use super::*;
use crate::triangle::{Ray, RayPrep, intersect};

/// splitmix64, for reproducible test data (shared by the BVH's test modules).
pub(crate) struct Rng(pub(crate) u64);
impl Rng {
    pub(crate) fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    pub(crate) fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn vec(&mut self, lo: f32, hi: f32) -> Vec3 {
        Vec3::new(self.unit(), self.unit(), self.unit()) * (hi - lo) + Vec3::splat(lo)
    }
}

fn brute_force(tris: &[[Vec3; 3]], ray: &Ray) -> Option<(u32, u32)> {
    let prep = RayPrep::new(ray);
    let mut best: Option<(f32, u32)> = None;
    for (i, t) in tris.iter().enumerate() {
        if let Some(h) = intersect(&prep, t[0], t[1], t[2], f32::INFINITY) {
            let better = best.is_none_or(|(bt, bi)| h.t < bt || (h.t == bt && (i as u32) < bi));
            if better {
                best = Some((h.t, i as u32));
            }
        }
    }
    best.map(|(t, i)| (i, t.to_bits()))
}

fn brute_occluded(tris: &[[Vec3; 3]], ray: &Ray, t_max: f32) -> bool {
    let prep = RayPrep::new(ray);
    tris.iter()
        .any(|t| intersect(&prep, t[0], t[1], t[2], t_max).is_some())
}

fn bvh_of(tris: &[[Vec3; 3]]) -> Bvh {
    Bvh::build(tris.to_vec(), (0..tris.len() as u32).collect())
}

/// The bits of a hit, so that equality means the same bits (and -0 != +0).
/// A hit's id, t, barycentrics, leaf-order index and corners, as bits.
type HitBits = (u32, u32, [u32; 3], u32, [[u32; 3]; 3]);

/// A hit on `bvh`'s first triangle that no ray of the tests finds (its distance is negative):
/// what columns hold before a call writes them.
fn stale_hit(bvh: &Bvh) -> ClosestHit {
    bvh.closest_result(&super::traverse::BestHit {
        t: -1.0,
        b: [0.5, 0.25, 0.25],
        id: 7,
        place: 0,
    })
    .expect("a finite distance is a hit")
}

fn hit_bits(bvh: &Bvh, h: &ClosestHit) -> HitBits {
    (
        h.id,
        h.t.to_bits(),
        h.b.map(f32::to_bits),
        h.index,
        bvh.hit_corners(h)
            .corners()
            .map(|c| c.to_array().map(f32::to_bits)),
    )
}

/// Runs `check` once at each kernel width this host has, forced for the whole process (the
/// lock keeps other forcing tests out meanwhile; tests that do not force see some width, and
/// every width gives the same answers). Returns the fewest leaf tests in lanes that the checks
/// ran at any one width, so that a caller can show each width's lanes ran.
pub(crate) fn at_every_kernel_width(mut check: impl FnMut(KernelWidth)) -> usize {
    static FORCING: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _only_us = FORCING.lock().unwrap_or_else(|e| e.into_inner());
    let mut fewest: Option<usize> = None;
    for width in available_kernel_widths() {
        force_kernel_width(Some(width));
        let before = leaf_tests_in_lanes(width);
        check(width);
        let ran = leaf_tests_in_lanes(width) - before;
        fewest = Some(fewest.map_or(ran, |f| f.min(ran)));
    }
    force_kernel_width(None);
    fewest.unwrap_or(0)
}

/// How many leaf tests in the lanes of `width` (4, 8 or 16 rays) have run in this process.
/// Only the forcing tests above run them while they hold the lock, so the difference around
/// one width's checks counts what that width ran in its own lanes (width 16 also runs 8-lane
/// tests where 16 lanes do not pay; they count for `Eight`).
fn leaf_tests_in_lanes(width: KernelWidth) -> usize {
    let lanes = match width {
        KernelWidth::Four => 0,
        KernelWidth::Eight => 1,
        KernelWidth::Sixteen => 2,
    };
    super::leaf_lanes::LEAF_TESTS[lanes].load(std::sync::atomic::Ordering::Relaxed)
}

/// Closest-hit ray packets give every ray exactly the single-ray answer, for packets cut at
/// every offset (full, partial and one-ray packets) and of 32 (the default), 64 and 7 rays,
/// with inner children tested at the hull or ray by ray ([`ClosestPackets::inner_tests`]), at
/// every kernel width, whether the answers come as `Option<ClosestHit>`s or as columns
/// ([`Bvh::closest_hits_in_columns`], read back through [`Bvh::hit_in`]).
fn check_ray_packets_against_single_rays(bvh: &Bvh, rays: &[Ray]) -> usize {
    let single: Vec<_> = rays
        .iter()
        .map(|r| bvh.closest_hit(r).map(|h| hit_bits(bvh, &h)))
        .collect();
    at_every_kernel_width(|width| packets_give_single_ray_hits(bvh, rays, &single, width))
}

fn packets_give_single_ray_hits(
    bvh: &Bvh,
    rays: &[Ray],
    single: &[Option<HitBits>],
    width: KernelWidth,
) {
    let packets = [CLOSEST_PACKET, RAY_PACKET, 7]
        .into_iter()
        .flat_map(|rays| [false, true].map(|inner_tests| ClosestPackets { rays, inner_tests }));
    for (skip, packet) in [0, 1, 5, 15, 17, 31, 33, 63]
        .into_iter()
        .flat_map(|skip| packets.clone().map(move |packet| (skip, packet)))
    {
        let rays = &rays[skip.min(rays.len())..];
        let mut out = vec![None; rays.len()];
        if packet == ClosestPackets::DEFAULT {
            bvh.closest_hits(rays, &mut out);
        } else {
            bvh.closest_hits_in_packets(rays, &mut out, packet);
        }
        // Columns start full of another answer, so every place must be written.
        let mut columns = HitColumns::from_hits(&vec![Some(stale_hit(bvh)); rays.len()]);
        bvh.closest_hits_in_columns(rays, &mut columns, packet);
        for (k, (got, expected)) in out
            .iter()
            .zip(&single[skip.min(single.len())..])
            .enumerate()
        {
            assert_eq!(
                &got.as_ref().map(|h| hit_bits(bvh, h)),
                expected,
                "ray {} ({width:?}, {packet:?})",
                k + skip
            );
            assert_eq!(
                &bvh.hit_in(&columns, k).as_ref().map(|h| hit_bits(bvh, h)),
                expected,
                "ray {} in columns ({width:?}, {packet:?})",
                k + skip
            );
        }
    }
}

/// Segment packets give every segment exactly the single-ray answer, for packets cut at every
/// offset, at every kernel width, whether the segments come as pairs or as columns; returns
/// how many segments are blocked and the fewest leaf tests in lanes any width ran
/// ([`at_every_kernel_width`]).
fn check_segment_packets_against_single_rays(bvh: &Bvh, segments: &[(Ray, f32)]) -> (usize, usize) {
    let single: Vec<bool> = segments.iter().map(|(r, t)| bvh.occluded(r, *t)).collect();
    let in_lanes = at_every_kernel_width(|width| {
        for skip in [0, 1, 5, 15, 17, 31, 33, 63] {
            let segments = &segments[skip.min(segments.len())..];
            let expected = &single[skip.min(single.len())..];
            let mut out = vec![false; segments.len()];
            bvh.occluded_many(segments, &mut out);
            assert_eq!(out, expected, "skip {skip} ({width:?})");
            let mut columns = SegmentColumns::default();
            for (ray, t_max) in segments {
                columns.push(ray, *t_max);
            }
            let mut out = vec![!expected.first().copied().unwrap_or(false); segments.len()];
            bvh.occluded_columns(&columns, &mut out);
            assert_eq!(out, expected, "columns, skip {skip} ({width:?})");
        }
    });
    (single.iter().filter(|&&b| b).count(), in_lanes)
}

/// [`check_tree_against_brute_force`] with the tree of every build preset.
fn check_against_brute_force(tris: &[[Vec3; 3]], rays: &[Ray]) {
    for preset in [BuildPreset::Quality, BuildPreset::Fast] {
        let ids = (0..tris.len() as u32).collect();
        let bvh = Bvh::build_preset(tris.to_vec(), ids, 1, preset);
        check_tree_against_brute_force(&bvh, tris, rays);
    }
}

/// Single rays, packets and segments through `bvh` (over `tris`, ids their indices) give the
/// brute-force answers.
fn check_tree_against_brute_force(bvh: &Bvh, tris: &[[Vec3; 3]], rays: &[Ray]) {
    check_ray_packets_against_single_rays(bvh, rays);
    let segments: Vec<(Ray, f32)> = rays
        .iter()
        .filter_map(|r| Some((r, bvh.closest_hit(r)?.t)))
        .flat_map(|(r, t)| {
            [
                (*r, t * 0.999),
                (*r, t * 1.001),
                (*r, f32::INFINITY),
                (*r, t),
            ]
        })
        .collect();
    let (blocked, _) = check_segment_packets_against_single_rays(bvh, &segments);
    assert!(
        blocked > 0 && blocked < segments.len(),
        "both answers occur ({blocked})"
    );
    let mut hits = 0;
    for (k, ray) in rays.iter().enumerate() {
        let expected = brute_force(tris, ray);
        let hit = bvh.closest_hit(ray);
        let got = hit.map(|h| (h.id, h.t.to_bits()));
        assert_eq!(got, expected, "ray {k}: {ray:?}");
        if let Some(h) = hit {
            // The corners the BVH gives a hit are its triangle's.
            assert_eq!(
                bvh.hit_corners(&h).corners(),
                tris[h.id as usize],
                "ray {k}"
            );
        }
        hits += usize::from(expected.is_some());
        if let Some((_, t)) = expected {
            let t = f32::from_bits(t);
            for t_max in [t * 0.999, t * 1.001, f32::INFINITY] {
                assert_eq!(bvh.occluded(ray, t_max), brute_occluded(tris, ray, t_max));
            }
        }
    }
    assert!(
        hits > rays.len() / 10,
        "test rays should mostly hit ({hits})"
    );
}

/// `n` triangles, each with a corner uniform in the cube of half side `spread` around the
/// origin and its two other corners within 1 of it on every axis.
fn random_soup(rng: &mut Rng, n: usize, spread: f32) -> Vec<[Vec3; 3]> {
    (0..n)
        .map(|_| {
            let c = rng.vec(-spread, spread);
            [c, c + rng.vec(-1.0, 1.0), c + rng.vec(-1.0, 1.0)]
        })
        .collect()
}

fn random_rays(rng: &mut Rng, n: usize, around: Vec3, radius: f32) -> Vec<Ray> {
    (0..n)
        .map(|_| {
            let origin = around + rng.vec(-1.0, 1.0).normalize() * radius * 2.0;
            let target = around + rng.vec(-0.6, 0.6) * radius;
            Ray {
                origin,
                dir: (target - origin).normalize(),
            }
        })
        .collect()
}

#[test]
fn closest_hit_equals_brute_force_on_random_triangle_soup() {
    let mut rng = Rng(7);
    let tris: Vec<[Vec3; 3]> = (0..3000)
        .map(|_| {
            let c = rng.vec(-10.0, 10.0);
            [
                c + rng.vec(-1.0, 1.0),
                c + rng.vec(-1.0, 1.0),
                c + rng.vec(-1.0, 1.0),
            ]
        })
        .collect();
    let rays = random_rays(&mut rng, 3000, Vec3::ZERO, 10.0);
    check_against_brute_force(&tris, &rays);
}

/// Segments with an infinite or NaN coordinate, or a NaN end, among finite ones (their packets
/// go ray by ray) get the single-ray answers, as pairs and as columns, in every packet cut.
#[test]
fn segments_that_are_not_finite_get_single_ray_answers() {
    let mut rng = Rng(19);
    let tris = random_soup(&mut rng, 500, 5.0);
    let bvh = Bvh::build(tris, (0..500).collect());
    let rays = random_rays(&mut rng, 400, Vec3::ZERO, 5.0);
    let bad = [f32::INFINITY, f32::NEG_INFINITY, f32::NAN];
    let segments: Vec<(Ray, f32)> = rays
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let mut r = *r;
            let mut t_max = 1e3;
            match i % 37 {
                3 => r.origin[i % 3] = bad[i % 3],
                11 => r.dir[i % 3] = bad[(i + 1) % 3],
                29 => t_max = f32::NAN,
                _ => {}
            }
            (r, t_max)
        })
        .collect();
    let (blocked, _) = check_segment_packets_against_single_rays(&bvh, &segments);
    assert!(
        blocked > 20 && blocked < segments.len() - 20,
        "both answers occur ({blocked})"
    );
}

/// Packets whose directions have a zero component (an infinite inverse direction on that
/// axis, which the whole-packet test leaves out) give the single-ray and brute-force answers:
/// rays parallel to one or two axes, with +0 and -0 components in one packet, from origins
/// on a grid that puts some exactly on the planes of boxes (integer corners), so that
/// `(plane - origin) * inf` is NaN there. (Leaving the axis out is a precaution: with it
/// kept, the test passes too, since an infinite or NaN bound only ever widens the hull.)
#[test]
fn packets_parallel_to_an_axis_give_single_ray_hits() {
    let mut rng = Rng(29);
    // Triangles with integer corners: child boxes have integer planes.
    let mut corner = || {
        let v = rng.vec(-8.0, 8.0);
        Vec3::new(v.x.round(), v.y.round(), v.z.round())
    };
    let tris: Vec<[Vec3; 3]> = (0..600).map(|_| [corner(), corner(), corner()]).collect();
    let bvh = bvh_of(&tris);
    let mut hits = 0;
    for dir in [
        Vec3::new(0.0, 0.0, -1.0),
        Vec3::new(0.0, -0.25, -1.0),
        Vec3::new(0.3, 0.0, -1.0),
        Vec3::new(-0.2, 0.1, 0.0),
    ] {
        // Groups of 16 rays (two a packet): a 4x4 grid of origins on whole and half units,
        // the sign of each zero component alternating ray by ray.
        let rays: Vec<Ray> = (0..16 * 40)
            .map(|i| {
                let (packet, k) = (i / 16, i % 16);
                let (u, v) = (
                    (packet % 8) as f32 * 2.0 - 8.0 + (k % 4) as f32 * 0.5,
                    (packet / 8) as f32 * 3.0 - 7.0 + (k / 4) as f32 * 0.5,
                );
                let sign = |c: f32| if c == 0.0 && k % 2 == 1 { -0.0 } else { c };
                let d = Vec3::new(sign(dir.x), sign(dir.y), sign(dir.z));
                // The origin outside the scene, behind the rays' way in.
                let origin = if dir.z == 0.0 {
                    Vec3::new(9.5, u, v)
                } else {
                    Vec3::new(u, v, 9.5)
                };
                Ray { origin, dir: d }
            })
            .collect();
        check_tree_against_brute_force(&bvh, &tris, &rays);
        hits += rays.iter().filter(|r| bvh.closest_hit(r).is_some()).count();
    }
    assert!(hits > 500, "the rays should meet the triangles ({hits})");
}

/// The fast preset on layouts that stress its grid: every centroid in one cell (split in the
/// middle), a flat scene (a zero extent) and clusters among scattered triangles: the same
/// answers as brute force, and the same tree every time.
#[test]
fn fast_preset_trees_answer_as_brute_force_on_degenerate_layouts() {
    let mut rng = Rng(13);
    let tri = [
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.5),
        Vec3::new(0.0, 1.0, -0.5),
    ];
    let soup = |rng: &mut Rng, n: usize| -> Vec<[Vec3; 3]> {
        (0..n)
            .map(|_| {
                let c = rng.vec(-3.0, 3.0);
                [
                    c + rng.vec(-0.5, 0.5),
                    c + rng.vec(-0.5, 0.5),
                    c + rng.vec(-0.5, 0.5),
                ]
            })
            .collect()
    };
    let flat: Vec<[Vec3; 3]> = soup(&mut rng, 500)
        .into_iter()
        .map(|t| t.map(|p| Vec3::new(p.x, 0.0, p.z)))
        .collect();
    let mut clusters = soup(&mut rng, 300);
    for i in 0..300 {
        clusters.insert(i * 2, tri.map(|p| p + Vec3::splat((i % 3) as f32)));
    }
    for (name, tris) in [
        ("one triangle 100 times", vec![tri; 100]),
        ("flat in y", flat),
        ("clusters", clusters),
    ] {
        let ids: Vec<u32> = (0..tris.len() as u32).collect();
        let bvh = Bvh::build_preset(tris.clone(), ids.clone(), 1, BuildPreset::Fast);
        let again = Bvh::build_preset(tris.clone(), ids, 1, BuildPreset::Fast);
        assert_eq!(bvh, again, "{name}: the same tree");
        let rays = random_rays(&mut rng, 500, Vec3::ZERO, 3.0);
        check_tree_against_brute_force(&bvh, &tris, &rays);
    }
}

#[test]
fn equal_t_ties_go_to_the_smaller_id() {
    // Many copies of one triangle, shuffled ids: the smallest id must win every time.
    let tri = [
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    ];
    let tris = vec![tri; 50];
    let ids: Vec<u32> = (0..50).map(|i| (i * 37 + 11) % 50 + 100).collect();
    let bvh = Bvh::build(tris, ids);
    let ray = Ray {
        origin: Vec3::new(0.1, 0.0, 5.0),
        dir: Vec3::new(0.0, 0.0, -1.0),
    };
    assert_eq!(bvh.closest_hit(&ray).map(|h| h.id), Some(100));
    let mut out = [None; 3];
    bvh.closest_hits(&[ray; 3], &mut out);
    assert_eq!(out.map(|h| h.map(|h| h.id)), [Some(100); 3]);
}

#[test]
fn closest_hit_equals_brute_force_on_the_bunny() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/bunny/bunny.obj");
    let mut warnings = Vec::new();
    let mesh = crate::scene::parse_obj(
        std::io::BufReader::new(std::fs::File::open(path).expect("bundled bunny")),
        std::path::Path::new(path),
        &mut warnings,
    )
    .expect("bunny parses");
    let tris: Vec<[Vec3; 3]> = (0..mesh.triangle_count())
        .map(|i| mesh.corners(i))
        .collect();
    let bounds = tris
        .iter()
        .fold(Aabb::EMPTY, |b, t| b.union(Aabb::of_triangle(t)));
    let centre = (bounds.lo + bounds.hi) * 0.5;
    let radius = (bounds.hi - bounds.lo).length() * 0.5;
    let rays = random_rays(&mut Rng(3), 2000, centre, radius);
    check_against_brute_force(&tris, &rays);
    // Coherent camera rays (what ray packets are for): 16 jittered samples of each pixel of a
    // 32x24 pinhole image of the bunny, in pixel order as the renderer traces them (a packet
    // is one pixel's samples), from an eye outside and from one inside its box.
    let bvh = bvh_of(&tris);
    let mut jitter = Rng(11);
    for eye in [centre + Vec3::new(0.1, 0.5, 1.25) * radius * 2.0, centre] {
        let forward = (centre + Vec3::new(0.01, 0.02, 0.0) - eye).normalize_or(Vec3::Z);
        let right = forward.cross(Vec3::Y).normalize();
        let up = right.cross(forward);
        let rays: Vec<Ray> = (0..24 * 32 * 16)
            .map(|s| {
                let p = s / 16;
                let (px, py) = (
                    (p % 32) as f32 + jitter.unit(),
                    (p / 32) as f32 + jitter.unit(),
                );
                let (x, y) = (px / 16.0 - 1.0, 1.0 - py / 12.0);
                Ray {
                    origin: eye,
                    dir: forward + right * x * 0.5 + up * y * 0.4,
                }
            })
            .collect();
        // Every width, four lanes included, ran its leaves in lanes.
        let in_lanes = check_ray_packets_against_single_rays(&bvh, &rays);
        assert!(in_lanes > 100, "closest-hit leaves in lanes ({in_lanes})");
        let hits = rays.iter().filter(|r| bvh.closest_hit(r).is_some()).count();
        assert!(hits > 200, "camera rays should hit the bunny ({hits})");
        // Coherent shadow segments: from each hit point to a light above the bunny.
        let light = centre + Vec3::new(0.5, 1.0, 0.8) * radius * 2.0;
        let segments: Vec<(Ray, f32)> = rays
            .iter()
            .filter_map(|r| {
                let hit = bvh.closest_hit(r)?;
                let origin = r.origin + r.dir * hit.t;
                Some((
                    Ray {
                        origin,
                        dir: light - origin,
                    },
                    1.0,
                ))
            })
            .collect();
        let (blocked, in_lanes) = check_segment_packets_against_single_rays(&bvh, &segments);
        assert!(
            blocked > 20 && blocked < segments.len(),
            "some shadows ({blocked})"
        );
        assert!(in_lanes > 100, "segment leaves in lanes ({in_lanes})");
    }
}

/// A closed, subdivided cube: every face is a grid of quads split into two triangles.
pub(crate) fn closed_cube(n: usize) -> Vec<[Vec3; 3]> {
    let mut tris = Vec::new();
    for axis in 0..3 {
        for side in [-1.0f32, 1.0] {
            let point = |i: usize, j: usize| {
                let u = -1.0 + 2.0 * i as f32 / n as f32;
                let v = -1.0 + 2.0 * j as f32 / n as f32;
                let mut p = [0.0; 3];
                p[axis] = side;
                p[(axis + 1) % 3] = u;
                p[(axis + 2) % 3] = v;
                Vec3::from(p)
            };
            for i in 0..n {
                for j in 0..n {
                    let (a, b, c, d) = (
                        point(i, j),
                        point(i + 1, j),
                        point(i + 1, j + 1),
                        point(i, j + 1),
                    );
                    tris.push([a, b, c]);
                    tris.push([a, c, d]);
                }
            }
        }
    }
    tris
}

/// Whether `target` is a corner of `tri` or the midpoint of two of its corners, computed as the
/// test computes its targets (so exact comparison is right).
fn on_corner_or_edge_midpoint(tri: &[Vec3; 3], target: Vec3) -> bool {
    let [a, b, c] = *tri;
    [a, b, c, (a + b) * 0.5, (b + c) * 0.5, (a + c) * 0.5].contains(&target)
}

#[test]
fn rays_at_shared_edges_and_vertices_of_a_closed_mesh_never_miss() {
    let n = 7;
    let tris = closed_cube(n);
    assert_eq!(tris.len(), 6 * n * n * 2);
    let bvh = bvh_of(&tris);
    let mut rng = Rng(11);
    let mut targets: Vec<Vec3> = Vec::new();
    for t in &tris {
        targets.extend_from_slice(t); // vertices, exactly
        targets.push((t[0] + t[1]) * 0.5); // points on shared edges
        targets.push((t[1] + t[2]) * 0.5);
        targets.push((t[0] + t[2]) * 0.5);
    }
    let mut tested = 0;
    for &target in &targets {
        for _ in 0..4 {
            // The line through an interior point and the target must cross the closed surface:
            // from outside (beyond the interior point) and from inside alike.
            let interior = rng.vec(-0.5, 0.5);
            let origin = interior + (interior - target) * 3.0;
            let ray = Ray {
                origin,
                dir: (target - origin).normalize(),
            };
            assert!(
                bvh.closest_hit(&ray).is_some(),
                "ray at {target:?} from {origin:?} leaked"
            );
            // From inside the (convex) cube the first surface point is the target itself: the
            // hit must be there, on a triangle that has the target as a corner or on an edge,
            // not on some triangle behind a gap.
            let inside = Ray {
                origin: interior,
                dir: (target - interior).normalize(),
            };
            let hit = bvh.closest_hit(&inside);
            let Some(hit) = hit else {
                panic!("inside ray towards {target:?} leaked");
            };
            let point = inside.origin + inside.dir * hit.t;
            assert!(
                (point - target).length() < 1e-4,
                "inside ray towards {target:?} hit {point:?}"
            );
            assert!(
                on_corner_or_edge_midpoint(&tris[hit.id as usize], target),
                "inside ray towards {target:?} hit triangle {} = {:?}",
                hit.id,
                tris[hit.id as usize]
            );
            tested += 2;
        }
    }
    // Every target (3 corners and 3 edge midpoints per triangle) from 4 interior points, two
    // rays each: nothing skipped.
    assert_eq!(targets.len(), 6 * tris.len());
    assert_eq!(tested, 2 * 4 * targets.len());
}

#[test]
fn empty_bvh_hits_nothing() {
    let bvh = Bvh::build(Vec::new(), Vec::new());
    let ray = Ray {
        origin: Vec3::ZERO,
        dir: Vec3::X,
    };
    assert!(bvh.closest_hit(&ray).is_none());
    assert!(!bvh.occluded(&ray, f32::INFINITY));
    let mut out = [Some(ClosestHit {
        id: 0,
        t: 1.0,
        b: [0.0; 3],
        index: 0,
        place: 0,
    })];
    bvh.closest_hits(&[ray], &mut out);
    assert_eq!(out, [None]);
}

/// The smallest box of the triangles in the subtree under `node`'s `slot`, by plain float
/// comparisons (`None` for an empty slot).
fn subtree_box(bvh: &Bvh, node: usize, slot: usize) -> Option<([f32; 3], [f32; 3])> {
    let n = &bvh.wide[node];
    let (child, count) = (n.child[slot], n.triangle4_count[slot] as usize);
    let mut corners = Vec::new();
    if child & node4::LEAF != 0 {
        let first = (child & !node4::LEAF) as usize;
        for p in &bvh.triangles[first..first + count] {
            corners.extend((0..p.lanes as usize).flat_map(|l| p.corners(l)));
        }
    } else {
        let below: Vec<_> = (0..4)
            .filter_map(|s| subtree_box(bvh, child as usize, s))
            .collect();
        for (lo, hi) in below {
            corners.extend([Vec3::from_array(lo), Vec3::from_array(hi)]);
        }
    }
    let first = corners.first()?;
    let (mut lo, mut hi) = (first.to_array(), first.to_array());
    for c in &corners {
        for a in 0..3 {
            lo[a] = if c[a] < lo[a] { c[a] } else { lo[a] };
            hi[a] = if c[a] > hi[a] { c[a] } else { hi[a] };
        }
    }
    Some((lo, hi))
}

#[test]
fn every_child_box_is_the_smallest_box_of_its_triangles() {
    let mut rng = Rng(21);
    let tris = random_soup(&mut rng, 3000, 20.0);
    let bvh = bvh_of(&tris);
    assert!(bvh.wide.len() > 100);
    for (index, node) in bvh.wide.iter().enumerate() {
        for slot in 0..4 {
            let got = (
                [0, 1, 2].map(|a| node.lo[a][slot]),
                [0, 1, 2].map(|a| node.hi[a][slot]),
            );
            match subtree_box(&bvh, index, slot) {
                Some(expected) => assert_eq!(got, expected, "node {index} slot {slot}"),
                None => assert_eq!(got, ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3])),
            }
        }
    }
}

#[test]
fn a_pack_box_takes_its_used_lanes_in_order_passing_over_nan() {
    // v[corner][axis][lane]; lanes 2 and 3 hold values that must not count.
    let mut pack = node4::Triangle4 {
        v: [[[-100.0; 4]; 3]; 3],
        first: 0,
        lanes: 2,
    };
    let corners = [
        [[1.0, 2.0, 3.0], [4.0, f32::NAN, 6.0]],
        [[-1.0, 5.0, 0.0], [4.0, -7.0, 6.0]],
        [[0.5, f32::NAN, -0.0], [4.0, 5.0, f32::NAN]],
    ];
    for (c, lanes) in corners.iter().enumerate() {
        for (lane, xyz) in lanes.iter().enumerate() {
            for (axis, &x) in xyz.iter().enumerate() {
                pack.v[c][axis][lane] = x;
            }
        }
    }
    let b = refit::pack_box(&pack);
    assert_eq!(
        b.lo.to_array().map(f32::to_bits),
        [-1.0f32, -7.0, 0.0].map(f32::to_bits)
    );
    assert_eq!(
        b.hi.to_array().map(f32::to_bits),
        [4.0f32, 5.0, 6.0].map(f32::to_bits)
    );
    // The +0 of corner 1 came before the -0 of corner 2, and a tie keeps the first.
    assert!(b.lo.z.is_sign_positive());
}
