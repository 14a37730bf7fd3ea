//! Leaves of ray packets (closest-hit and segment packets) a group of rays at a time: each
//! triangle of the leaf is tested against up to four rays of the packet ([`f32x4`]: SSE4.1 on
//! x86-64, NEON on aarch64, every host), eight (AVX2, [`F32x8`]) or sixteen (AVX-512F,
//! [`F32x16`]), one per lane, where the 4-wide path tests each ray against the leaf's
//! [`Triangle4`]s in turn (`dispatch.rs` picks the width: four lanes at kernel width `Four`,
//! eight and sixteen at `Eight` and `Sixteen`). A leaf of n triangles in m `Triangle4`s then
//! costs n tests for the group instead of m per ray; rays of one pixel's samples, which reach
//! the same leaves together, gain most.
//!
//! Guarantee: every ray keeps exactly the hit (and every segment the answer) the 4-wide path
//! gives it, at every group width. Each lane runs the watertight test of
//! [`crate::triangle::intersect`] in its order of operations (`simd4.rs`,
//! `edges_unless_outside`, over [`Lanes`]), which needs the lanes' rays to permute the axes
//! alike (the packet's group falls back to the 4-wide path otherwise); a triangle is left at
//! its edge functions when every lane has mixed signs and none of 0, as the scalar test leaves
//! it; lanes only the scalar test can decide go to it; and each lane keeps its best hit by the
//! rule of [`super::traverse::BestHit::beaten_by`] (smaller t, then smaller id), whose winner
//! does not depend on the order of the hits.
//!
//! The code is written once over [`RayGroupLanes`]; the entry points of each width are thin
//! functions compiled for its instruction set (the `*8` ones for AVX2, the `*16` ones for
//! AVX-512F; the `*4` ones need none), into which the generic code is inlined.

use super::Bvh;
use super::lanes::RayGroupLanes;
#[cfg(target_arch = "x86_64")]
use super::lanes::{F32x8, F32x16};
use super::node4::Triangle4;
use super::packet_hits::PacketHits;
use super::packet_rays::PacketRays;
use super::ray_packet::{RAY_PACKET, bits, first_bits};
use super::simd4::{any_hit_verdict, closest_verdict, edges_unless_outside};
use super::traverse::scalar_hit;
use crate::triangle::{Ray, RayPrep, TriangleHit, intersect};
use wide::f32x4;

/// Group leaf tests run so far (closest-hit and any-hit) in 4 lanes (`[0]`), 8 (`[1]`) and 16
/// (`[2]`), so tests can show each ran.
#[cfg(test)]
pub(super) static LEAF_TESTS: [std::sync::atomic::AtomicUsize; 3] = [
    std::sync::atomic::AtomicUsize::new(0),
    std::sync::atomic::AtomicUsize::new(0),
    std::sync::atomic::AtomicUsize::new(0),
];

#[inline(always)]
fn count_leaf_test(lanes: usize) {
    #[cfg(test)]
    LEAF_TESTS[lanes.trailing_zeros() as usize - 2]
        .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    #[cfg(not(test))]
    let _ = lanes;
}

/// Whether testing a leaf of `count` `Triangle4`s holding `triangles` triangles in `lanes`
/// lanes against the rays of `group` (bit i = lane i) takes fewer tests than the 4-wide path:
/// one test per triangle of the leaf, a 16-lane one counted as two, against one per
/// `Triangle4` per ray. (An 8-lane test costs more than a 4-wide one; weighting it so measured
/// no better on the bundled scenes and a 1M mesh. Counting a 16-lane test as one was slower on
/// the 1M mesh.)
#[inline(always)]
fn pays_in_lanes((count, triangles): (usize, usize), group: u32, lanes: usize) -> bool {
    group.count_ones() as usize * count * 8 > triangles * lanes
}

/// A group of up to [`RayGroupLanes::LANES`] rays in lanes for the triangle test: the
/// permutation they share and, per permuted axis, each lane's origin and shear. Lanes past the
/// last ray repeat it (and are never active).
pub(super) struct RayLanes<L> {
    axes: [usize; 3],
    origin: [L; 3],
    shear: [L; 3],
}

impl<L: RayGroupLanes> RayLanes<L> {
    /// Rays `from..from + LANES` of `rays` in lanes, with exactly
    /// [`crate::triangle::RayPrep::new`]'s permutation and shear for each; `None` when the rays
    /// permute the axes differently (their largest direction components differ in axis or
    /// sign). Inlined into the width's entry point (`ray_lanes4`, `ray_lanes8`, `ray_lanes16`).
    #[inline(always)]
    fn new(rays: &PacketRays, from: usize) -> Option<Self> {
        let (dir, origin) = (&rays.dir, &rays.origin);
        let dir: [L; 3] = [
            L::load_at(&dir[0], from),
            L::load_at(&dir[1], from),
            L::load_at(&dir[2], from),
        ];
        let [ax, ay, az] = [dir[0].abs(), dir[1].abs(), dir[2].abs()];
        // As `RayPrep::new`: z is x when |x| > |y| and |x| > |z|, else y when |y| > |z|, else z.
        let all = first_bits(L::LANES);
        let x_over_y = ax.cmp_gt(ay);
        let z_is_x = x_over_y & ax.cmp_gt(az);
        let z_is_y = !x_over_y & ay.cmp_gt(az);
        let kz = match (z_is_x.bitmask(), z_is_y.bitmask()) {
            (x, _) if x == all => 0,
            (_, y) if y == all => 1,
            (0, 0) => 2,
            _ => return None,
        };
        let negative = dir[kz].cmp_lt(L::splat(0.0)).bitmask();
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        if negative == all {
            std::mem::swap(&mut kx, &mut ky);
        } else if negative != 0 {
            return None;
        }
        let dz = dir[kz];
        Some(RayLanes {
            axes: [kx, ky, kz],
            origin: [
                L::load_at(&origin[kx], from),
                L::load_at(&origin[ky], from),
                L::load_at(&origin[kz], from),
            ],
            shear: [dir[kx] / dz, dir[ky] / dz, L::splat(1.0) / dz],
        })
    }

    /// Lane `lane` of `p` in every lane, on the rays' permuted axes: `[corner][axis]`.
    #[inline(always)]
    fn corners(&self, p: &Triangle4, lane: usize) -> [[L; 3]; 3] {
        let mut corners = [[L::splat(0.0); 3]; 3];
        for (c, corner) in corners.iter_mut().enumerate() {
            for (k, x) in corner.iter_mut().enumerate() {
                *x = L::splat(p.v[c][self.axes[k]][lane]);
            }
        }
        corners
    }
}

/// What each group width runs at a leaf, through its instruction set's entry points.
#[allow(unsafe_code)]
pub(super) trait LeafLanes: RayGroupLanes {
    /// Puts [`RayLanes::new`] in `slot` (made in place: returned, its bytes were copied in).
    /// Call only on hosts with the width's instruction set.
    unsafe fn ray_lanes(rays: &PacketRays, from: usize, slot: &mut Option<Option<RayLanes<Self>>>);
    /// [`closest_in_leaf`]. Call only on hosts with the width's instruction set.
    unsafe fn closest_in_leaf(
        bvh: &Bvh,
        leaf: (usize, usize),
        lanes: &RayLanes<Self>,
        active: u32,
        rays: &[Ray],
        hits: (&mut PacketHits, usize),
    );
    /// [`occluded_in_leaf`]. Call only on hosts with the width's instruction set.
    unsafe fn occluded_in_leaf(
        bvh: &Bvh,
        leaf: (usize, usize),
        lanes: &RayLanes<Self>,
        active: u32,
        rays: &PacketRays,
        t_max: (&[f32; RAY_PACKET], usize),
    ) -> u32;
}

/// The entry points of one width, compiled with `$compile` (the width's instruction set).
macro_rules! leaf_lanes {
    ($lanes:ty, $compile:meta, $ray_lanes:ident, $closest:ident, $occluded:ident) => {
        #[$compile]
        fn $ray_lanes(rays: &PacketRays, from: usize, slot: &mut Option<Option<RayLanes<$lanes>>>) {
            *slot = Some(RayLanes::new(rays, from));
        }

        #[$compile]
        fn $closest(
            bvh: &Bvh,
            leaf: (usize, usize),
            lanes: &RayLanes<$lanes>,
            active: u32,
            rays: &[Ray],
            hits: (&mut PacketHits, usize),
        ) {
            closest_in_leaf(bvh, leaf, lanes, active, rays, hits)
        }

        #[$compile]
        fn $occluded(
            bvh: &Bvh,
            leaf: (usize, usize),
            lanes: &RayLanes<$lanes>,
            active: u32,
            rays: &PacketRays,
            t_max: (&[f32; RAY_PACKET], usize),
        ) -> u32 {
            occluded_in_leaf(bvh, leaf, lanes, active, rays, t_max)
        }

        // (Four lanes' entry points are safe to call, so their `unsafe` blocks are unused.)
        #[allow(unsafe_code, unused_unsafe)]
        impl LeafLanes for $lanes {
            unsafe fn ray_lanes(
                rays: &PacketRays,
                from: usize,
                slot: &mut Option<Option<RayLanes<Self>>>,
            ) {
                // SAFETY: the caller's contract (the host has the instruction set).
                unsafe { $ray_lanes(rays, from, slot) }
            }
            unsafe fn closest_in_leaf(
                bvh: &Bvh,
                leaf: (usize, usize),
                lanes: &RayLanes<Self>,
                active: u32,
                rays: &[Ray],
                hits: (&mut PacketHits, usize),
            ) {
                // SAFETY: the caller's contract (the host has the instruction set).
                unsafe { $closest(bvh, leaf, lanes, active, rays, hits) }
            }
            unsafe fn occluded_in_leaf(
                bvh: &Bvh,
                leaf: (usize, usize),
                lanes: &RayLanes<Self>,
                active: u32,
                rays: &PacketRays,
                t_max: (&[f32; RAY_PACKET], usize),
            ) -> u32 {
                // SAFETY: the caller's contract (the host has the instruction set).
                unsafe { $occluded(bvh, leaf, lanes, active, rays, t_max) }
            }
        }
    };
}

// Four lanes need no instruction set beyond every host's (SSE4.1 in x86-64's baseline here,
// NEON on aarch64); their entry points stay out of line as the wider ones must.
leaf_lanes!(
    f32x4,
    inline(never),
    ray_lanes4,
    closest_in_leaf4,
    occluded_in_leaf4
);
// Call only on hosts with AVX2.
#[cfg(target_arch = "x86_64")]
leaf_lanes!(
    F32x8,
    target_feature(enable = "avx2"),
    ray_lanes8,
    closest_in_leaf8,
    occluded_in_leaf8
);
// Call only on hosts with AVX-512F.
#[cfg(target_arch = "x86_64")]
leaf_lanes!(
    F32x16,
    target_feature(enable = "avx512f"),
    ray_lanes16,
    closest_in_leaf16,
    occluded_in_leaf16
);

/// A packet's groups of rays in lanes (of four, eight or sixteen rays: sixteen, eight or four of
/// them in a packet of [`RAY_PACKET`]), each made from the packet's rays when the group first
/// meets a leaf in lanes (`None` inside: its rays permute the axes differently, so it stays
/// 4-wide).
pub(super) struct PacketLanes<'r, L> {
    rays: &'r PacketRays,
    groups: [Option<Option<RayLanes<L>>>; RAY_PACKET / 4],
}

impl<'r, L> PacketLanes<'r, L> {
    /// No group made yet, of the packet whose rays are `rays`.
    pub fn new(rays: &'r PacketRays) -> Self {
        PacketLanes {
            rays,
            groups: std::array::from_fn(|_| None),
        }
    }

    /// The packet's rays.
    pub fn rays(&self) -> &'r PacketRays {
        self.rays
    }
}

impl<L: LeafLanes> PacketLanes<'_, L> {
    /// Calls `test(from, group, lanes)` for each group of `L::LANES` rays of `active` that
    /// meets the leaf `(first Triangle4, count)` in lanes: the packet's rays `from..from +
    /// LANES`, bit i of `group` standing for ray `from + i`, where that takes fewer tests than
    /// the 4-wide path ([`pays_in_lanes`]) and the group's rays permute the axes alike. Returns
    /// the rays of `active` left for the 4-wide path.
    /// Only on hosts with the instruction set of `L`: four lanes anywhere (at kernel width 4),
    /// eight at width 8 or 16 (AVX2), sixteen at width 16 (AVX-512F).
    #[inline(always)]
    pub fn by_groups(
        &mut self,
        bvh: &Bvh,
        leaf: (usize, usize),
        active: u64,
        mut test: impl FnMut(usize, u32, &RayLanes<L>),
    ) -> u64 {
        let mut rest = active;
        let all = first_bits(L::LANES);
        // Counted once a leaf, not once a group: the `Triangle4`s' lane counts.
        let (first, count) = leaf;
        let triangles: usize = bvh.triangles[first..first + count]
            .iter()
            .map(|p| p.lanes as usize)
            .sum();
        for (g, slot) in self
            .groups
            .iter_mut()
            .take(RAY_PACKET / L::LANES)
            .enumerate()
        {
            let from = g * L::LANES;
            let group = (active >> from) as u32 & all;
            if !pays_in_lanes((count, triangles), group, L::LANES) {
                continue;
            }
            if slot.is_none() {
                // SAFETY: callers reach this only at a kernel width that implies the
                // instruction set of `L` (four lanes anywhere, 8 or 16 for AVX2, 16 for
                // AVX-512F; `dispatch.rs`).
                #[allow(unsafe_code)]
                unsafe {
                    L::ray_lanes(self.rays, from, slot)
                };
            }
            let Some(Some(lanes)) = slot else {
                continue;
            };
            test(from, group, lanes);
            rest &= !(u64::from(group) << from);
        }
        rest
    }
}

/// Tests the `count` `Triangle4`s from `first` (one leaf) against the rays of `active` (bit i =
/// lane i of `lanes`, ray `rays[i]`), keeping each ray's best hit in lane i of the group
/// starting at ray `from` of `hits` (the packet's: ray `from + i`). Inlined into the width's
/// entry point.
#[inline(always)]
fn closest_in_leaf<L: RayGroupLanes>(
    bvh: &Bvh,
    (first, count): (usize, usize),
    lanes: &RayLanes<L>,
    active: u32,
    rays: &[Ray],
    (hits, from): (&mut PacketHits, usize),
) {
    count_leaf_test(L::LANES);
    let mut best = BestLanes::load(hits, from);
    for k in first..first + count {
        let p: &Triangle4 = &bvh.triangles[k];
        for lane in 0..p.lanes as usize {
            let corners = lanes.corners(p, lane);
            let Some(e) = edges_unless_outside(&lanes.origin, &lanes.shear, &corners, active)
            else {
                continue;
            };
            let (exact, scalar) = closest_verdict(&e, active, best.t);
            if exact | scalar == 0 {
                continue;
            }
            let id = bvh.ids[p.first as usize + lane];
            let b = [e.u * e.inv_det, e.v * e.inv_det, e.w * e.inv_det];
            best.offer(exact, e.t, b, id, (k * 4 + lane) as u32);
            for i in bits(scalar) {
                if let Some(h) = scalar_hit(&rays[i], p, lane) {
                    best.offer_one(i, h, id, (k * 4 + lane) as u32);
                }
            }
        }
    }
    best.store(hits, from);
}

/// Each lane's best hit during one leaf: t, barycentrics, triangle id and the hit's place
/// (`Triangle4` index times 4 plus lane), ids and places as `u32` bits.
struct BestLanes<L> {
    t: L,
    b: [L; 3],
    id: L,
    place: L,
    /// Lanes whose best hit changed in this leaf.
    changed: u32,
}

impl<L: RayGroupLanes> BestLanes<L> {
    /// The best hits of the packet's rays `from..from + LANES`.
    #[inline(always)]
    fn load(hits: &PacketHits, from: usize) -> Self {
        BestLanes {
            t: L::load_at(&hits.t, from),
            b: [
                L::load_at(&hits.b[0], from),
                L::load_at(&hits.b[1], from),
                L::load_at(&hits.b[2], from),
            ],
            id: L::load_bits_at(&hits.id, from),
            place: L::load_bits_at(&hits.place, from),
            changed: 0,
        }
    }
    /// Keeps, in the lanes of `hits`, hits at `t` with barycentrics `b` on triangle `id` at
    /// `place` that beat the lane's best: smaller t, or equal t and smaller id.
    #[inline(always)]
    fn offer(&mut self, hits: u32, t: L, b: [L; 3], id: u32, place: u32) {
        if hits == 0 {
            return;
        }
        let better = t.cmp_lt(self.t) | (t.cmp_eq(self.t) & self.id.u32_above(id));
        let better = better & L::lane_mask(hits);
        self.t = better.select(t, self.t);
        self.b = [
            better.select(b[0], self.b[0]),
            better.select(b[1], self.b[1]),
            better.select(b[2], self.b[2]),
        ];
        let id = L::splat(f32::from_bits(id));
        let place = L::splat(f32::from_bits(place));
        self.id = better.select(id, self.id);
        self.place = better.select(place, self.place);
        self.changed |= better.bitmask();
    }

    /// [`Self::offer`] of one hit, in lane `i` (rare: only lanes the scalar test decides).
    #[inline(always)]
    fn offer_one(&mut self, i: usize, h: TriangleHit, id: u32, place: u32) {
        let lane = |v: f32| {
            let mut a = [0.0f32; RAY_PACKET];
            a[i] = v;
            L::load(&a)
        };
        let mut t = [f32::INFINITY; RAY_PACKET];
        t[i] = h.t;
        let b = [lane(h.b[0]), lane(h.b[1]), lane(h.b[2])];
        self.offer(1 << i, L::load(&t), b, id, place);
    }

    /// Writes the lanes back to the packet's rays `from..from + LANES` (unchanged lanes
    /// write what they read).
    #[inline(always)]
    fn store(&self, hits: &mut PacketHits, from: usize) {
        if self.changed == 0 {
            return;
        }
        self.t.store_at(&mut hits.t, from);
        for c in 0..3 {
            self.b[c].store_at(&mut hits.b[c], from);
        }
        self.id.store_bits_at(&mut hits.id, from);
        self.place.store_bits_at(&mut hits.place, from);
    }
}

/// Of the shadow segments of `active` (bit i = lane i of `lanes`, the packet's segment
/// `from + i`: ray `rays.ray(from + i)`, ending at `packet_t_max[from + i]`), those some triangle of the leaf
/// (`count` `Triangle4`s from `first`) blocks (a hit with `0 < t < t_max`), as
/// [`super::Bvh::occluded`]'s leaf test decides. Inlined into the width's entry point.
#[inline(always)]
fn occluded_in_leaf<L: RayGroupLanes>(
    bvh: &Bvh,
    (first, count): (usize, usize),
    lanes: &RayLanes<L>,
    active: u32,
    rays: &PacketRays,
    (packet_t_max, from): (&[f32; RAY_PACKET], usize),
) -> u32 {
    count_leaf_test(L::LANES);
    let t_max = L::load_at(packet_t_max, from);
    let mut open = active;
    for p in &bvh.triangles[first..first + count] {
        for lane in 0..p.lanes as usize {
            let corners = lanes.corners(p, lane);
            let Some(e) = edges_unless_outside(&lanes.origin, &lanes.shear, &corners, open) else {
                continue;
            };
            let (hit, unsure) = any_hit_verdict(&e, open, t_max);
            open &= !hit;
            for i in bits(unsure) {
                let (ray, t_max) = (rays.ray(from + i), packet_t_max[from + i]);
                let [p0, p1, p2] = p.corners(lane);
                if intersect(&RayPrep::new(&ray), p0, p1, p2, t_max).is_some() {
                    open &= !(1 << i);
                }
            }
            if open == 0 {
                return active;
            }
        }
    }
    active & !open
}

#[cfg(test)]
mod tests {
    use super::*;
    #[cfg(target_arch = "x86_64")]
    use crate::bvh::dispatch::{KernelWidth, available_kernel_widths};
    use crate::bvh::simd4::tests::any_vec;
    use crate::bvh::tests::Rng;
    use glam::Vec3;

    /// What one width's lanes say of one triangle against a group of rays.
    struct Verdicts {
        /// Every lane was outside: the test ended at the edge functions' signs.
        outside: bool,
        /// The lanes' permutation, origins and shears.
        axes: [usize; 3],
        origin: [[u32; RAY_PACKET]; 3],
        shear: [[u32; RAY_PACKET]; 3],
        /// Closest-hit `exact` and `scalar`, t, barycentrics, any-hit `hit` and `unsure`.
        exact: u32,
        scalar: u32,
        t: [f32; RAY_PACKET],
        b: [[f32; RAY_PACKET]; 3],
        hit: u32,
        unsure: u32,
    }

    /// The verdicts in lanes of `L` of one triangle (lane 0 of `p`) against `rays` (they
    /// share their permutation); `None` when the lanes find they do not. Inlined into each
    /// width's entry point below.
    #[inline(always)]
    fn verdicts<L: RayGroupLanes>(
        rays: &[Ray],
        p: &Triangle4,
        t_max: &[f32; RAY_PACKET],
    ) -> Option<Verdicts> {
        let mut packet_rays = PacketRays::EMPTY;
        packet_rays.fill(rays, |ray| ray);
        let lanes = RayLanes::<L>::new(&packet_rays, 0)?;
        let valid = first_bits(rays.len());
        let bits = |x: [L; 3]| [x[0].store_bits(), x[1].store_bits(), x[2].store_bits()];
        let corners = lanes.corners(p, 0);
        let Some(e) = edges_unless_outside(&lanes.origin, &lanes.shear, &corners, valid) else {
            return Some(Verdicts {
                outside: true,
                axes: lanes.axes,
                origin: bits(lanes.origin),
                shear: bits(lanes.shear),
                exact: 0,
                scalar: 0,
                t: [f32::NAN; RAY_PACKET],
                b: [[f32::NAN; RAY_PACKET]; 3],
                hit: 0,
                unsure: 0,
            });
        };
        let t_max = L::load(t_max);
        let (exact, scalar) = closest_verdict(&e, valid, t_max);
        let (hit, unsure) = any_hit_verdict(&e, valid, t_max);
        let b = [e.u * e.inv_det, e.v * e.inv_det, e.w * e.inv_det];
        Some(Verdicts {
            outside: false,
            axes: lanes.axes,
            origin: bits(lanes.origin),
            shear: bits(lanes.shear),
            exact,
            scalar,
            t: e.t.store(),
            b: [b[0].store(), b[1].store(), b[2].store()],
            hit,
            unsure,
        })
    }

    fn verdicts4(rays: &[Ray], p: &Triangle4, t_max: &[f32; RAY_PACKET]) -> Option<Verdicts> {
        verdicts::<f32x4>(rays, p, t_max)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn verdicts8(rays: &[Ray], p: &Triangle4, t_max: &[f32; RAY_PACKET]) -> Option<Verdicts> {
        verdicts::<F32x8>(rays, p, t_max)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn verdicts16(rays: &[Ray], p: &Triangle4, t_max: &[f32; RAY_PACKET]) -> Option<Verdicts> {
        verdicts::<F32x16>(rays, p, t_max)
    }

    /// Rays at the triangle as shadow and camera rays meet it: from its corners, from points
    /// on it, from anywhere; toward its corners or anywhere.
    fn ray_at(rng: &mut Rng, tri: &[Vec3; 3]) -> Option<Ray> {
        let origin = match rng.next() % 4 {
            0 => tri[(rng.next() % 3) as usize],
            1 => {
                let (b1, b2) = (rng.unit() * 0.5, rng.unit() * 0.5);
                tri[0] * (1.0 - b1 - b2) + tri[1] * b1 + tri[2] * b2
            }
            _ => any_vec(rng) * 3.0,
        };
        let dir = match rng.next() % 3 {
            0 => any_vec(rng),
            _ => tri[(rng.next() % 3) as usize] - origin + any_vec(rng) * 0.01,
        };
        (dir != Vec3::ZERO && dir.is_finite()).then_some(Ray { origin, dir })
    }

    /// On every lane it decides, the 4-lane test decides as the scalar test: the closest-hit
    /// verdict with the scalar test's exact t and barycentric bits, the any-hit verdict with
    /// its answer. 1,000,000 groups of up to four rays sharing a permutation (4 million
    /// ray/triangle pairs), on random and degenerate triangles (collinear, repeated corners,
    /// signed zeros, huge and tiny coordinates). The lanes' setup is `RayPrep`'s, bit for bit.
    #[test]
    fn four_lane_tests_agree_with_the_scalar_test() {
        lanes_agree_with_the_scalar_test(4, 1_000_000, verdicts4);
    }

    /// The same for eight lanes (AVX2): 500,000 groups of up to eight rays.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn eight_wide_tests_agree_with_the_scalar_test() {
        if !available_kernel_widths().contains(&KernelWidth::Eight) {
            eprintln!("this host has no AVX2: there is no 8-wide path to test");
            return;
        }
        // SAFETY: the host has AVX2 (checked above).
        #[allow(unsafe_code)]
        lanes_agree_with_the_scalar_test(8, 500_000, |rays, p, t_max| unsafe {
            verdicts8(rays, p, t_max)
        });
    }

    /// The same for sixteen lanes (AVX-512F): 300,000 groups of up to sixteen rays.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn sixteen_wide_tests_agree_with_the_scalar_test() {
        if !available_kernel_widths().contains(&KernelWidth::Sixteen) {
            eprintln!("this host has no AVX-512F: there is no 16-wide path to test");
            return;
        }
        // SAFETY: the host has AVX-512F (checked above).
        #[allow(unsafe_code)]
        lanes_agree_with_the_scalar_test(16, 300_000, |rays, p, t_max| unsafe {
            verdicts16(rays, p, t_max)
        });
    }

    fn lanes_agree_with_the_scalar_test(
        width: usize,
        groups: usize,
        verdicts: impl Fn(&[Ray], &Triangle4, &[f32; RAY_PACKET]) -> Option<Verdicts>,
    ) {
        let mut rng = Rng(7);
        let (mut pairs, mut exact_hits, mut any_hits, mut mixed) = (0, 0, 0, 0);
        let mut outside = 0;
        let p_of = |tri: &[Vec3; 3]| {
            let mut v = [[[0.0f32; 4]; 3]; 3];
            for (c, corner) in tri.iter().enumerate() {
                for a in 0..3 {
                    v[c][a][0] = corner[a];
                }
            }
            Triangle4 {
                v,
                first: 0,
                lanes: 1,
            }
        };
        for _ in 0..groups {
            let mut tri = [any_vec(&mut rng), any_vec(&mut rng), any_vec(&mut rng)];
            match rng.next() % 8 {
                0 => tri[2] = tri[0],
                1 => tri[2] = tri[0] + (tri[1] - tri[0]) * 2.0,
                _ => {}
            }
            let p = p_of(&tri);
            let mut rays: Vec<Ray> = Vec::new();
            for _ in 0..4 * width {
                let Some(ray) = ray_at(&mut rng, &tri) else {
                    continue;
                };
                let axes = |r: &Ray| RayPrep::new(r).shear().0;
                if rays.first().is_none_or(|r0| axes(r0) == axes(&ray)) {
                    rays.push(ray);
                } else if mixed < 1000 {
                    // A group whose rays permute the axes differently stays 4-wide.
                    let pair = [rays[0], ray];
                    assert!(
                        verdicts(&pair, &p, &[f32::INFINITY; RAY_PACKET]).is_none(),
                        "{pair:?}"
                    );
                    mixed += 1;
                }
                if rays.len() == width {
                    break;
                }
            }
            if rays.is_empty() {
                continue;
            }
            let t_max: [f32; RAY_PACKET] = std::array::from_fn(|_| {
                [f32::INFINITY, rng.unit() * 4.0][(rng.next() % 2) as usize]
            });
            let v = verdicts(&rays, &p, &t_max).expect("the rays share their permutation");
            assert_eq!(v.exact & v.scalar, 0);
            assert_eq!(v.hit & v.unsure, 0);
            outside += usize::from(v.outside);
            exact_hits += v.exact.count_ones();
            any_hits += v.hit.count_ones();
            for (i, ray) in rays.iter().enumerate() {
                pairs += 1;
                let prep = RayPrep::new(ray);
                let (axes, shear) = prep.shear();
                assert_eq!(axes, v.axes);
                for k in 0..3 {
                    assert_eq!(v.origin[k][i], prep.origin[axes[k]].to_bits());
                    assert_eq!(v.shear[k][i], shear[k].to_bits());
                }
                let [p0, p1, p2] = tri;
                let bit = 1 << i;
                let any = intersect(&prep, p0, p1, p2, t_max[i]).is_some();
                if v.hit & bit != 0 {
                    assert!(any, "a claimed hit the scalar test misses: {ray:?} {tri:?}");
                } else if v.unsure & bit == 0 {
                    assert!(!any, "a claimed miss the scalar test hits: {ray:?} {tri:?}");
                }
                if v.scalar & bit != 0 {
                    continue;
                }
                let wide = (v.exact & bit != 0)
                    .then(|| (v.t[i].to_bits(), [0, 1, 2].map(|c| v.b[c][i].to_bits())));
                let expected = intersect(&prep, p0, p1, p2, f32::INFINITY)
                    .filter(|h| h.t <= t_max[i])
                    .map(|h| (h.t.to_bits(), h.b.map(f32::to_bits)));
                assert_eq!(wide, expected, "{ray:?} {tri:?}");
            }
        }
        assert!(pairs > 3_000_000, "pairs tested ({pairs})");
        assert!(exact_hits > 50_000, "exact hits in lanes ({exact_hits})");
        assert!(any_hits > 50_000, "any hits in lanes ({any_hits})");
        assert_eq!(mixed, 1000, "groups of mixed permutations");
        assert!(outside > groups / 200, "groups all outside ({outside})");
    }
}
