//! A ray packet's per-ray box test ([`super::ray_packet::RayPacketTester::rays_in_box`]) in
//! lanes of the kernel width: four rays a test everywhere, eight with AVX2 and sixteen with
//! AVX-512F (`dispatch.rs`), so a packet of [`RAY_PACKET`] rays takes sixteen, eight or four
//! tests. Segment packets run it at every inner child the interval test cannot decide, and
//! on the 1M-triangle mesh they spend much of the shadow phase here.
//!
//! Guarantee: each lane does the single-ray slab test's operations in its order (`SlabRay`:
//! offsets from the near and far planes, times the inverse direction, the far one times
//! `FAR_SCALE`; the running entry and exit kept by `maxps` and `minps` semantics), so every
//! width gives each ray the single-ray test's answer, bit for bit.

#![allow(unsafe_code)]

use super::lanes::RayGroupLanes;
#[cfg(target_arch = "x86_64")]
use super::lanes::{F32x8, F32x16};
use super::ray_packet::RAY_PACKET;
use super::traverse::FAR_SCALE;
use wide::f32x4;

/// A packet's rays as the box test reads them, coordinate by coordinate (ray i at index i):
/// origins and inverse directions (finite, nonzero directions: an inverse is never 0 or NaN).
#[derive(Clone, Copy)]
pub(super) struct BoxRays<'a> {
    pub origin: &'a [[f32; RAY_PACKET]; 3],
    pub inv_dir: &'a [[f32; RAY_PACKET]; 3],
}

/// The rays of `active` (bit i = ray i) that enter the box `lo..hi` at or before their bound
/// (`bound[i]`), and the smallest entry distance among them (+inf when none), in lanes of
/// the kernel width `WIDTH` (4, 8 or 16).
///
/// # Safety
/// `WIDTH` 8 only on hosts with AVX2, 16 only on hosts with AVX-512F (the kernel widths
/// `dispatch.rs` offers there).
#[inline(always)]
pub(super) unsafe fn rays_in_box<const WIDTH: usize>(
    rays: BoxRays<'_>,
    corners: ([f32; 3], [f32; 3]),
    active: u64,
    bound: &[f32; RAY_PACKET],
) -> (u64, f32) {
    match WIDTH {
        // SAFETY: the caller's contract.
        #[cfg(target_arch = "x86_64")]
        16 => unsafe { rays_in_box16(rays, corners, active, bound) },
        // SAFETY: the caller's contract.
        #[cfg(target_arch = "x86_64")]
        8 => unsafe { rays_in_box8(rays, corners, active, bound) },
        _ => rays_in_box_lanes::<f32x4>(rays, corners, active, bound),
    }
}

/// [`rays_in_box`] compiled for AVX2, eight rays a test.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn rays_in_box8(
    rays: BoxRays<'_>,
    corners: ([f32; 3], [f32; 3]),
    active: u64,
    bound: &[f32; RAY_PACKET],
) -> (u64, f32) {
    rays_in_box_lanes::<F32x8>(rays, corners, active, bound)
}

/// [`rays_in_box`] compiled for AVX-512F, sixteen rays a test.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn rays_in_box16(
    rays: BoxRays<'_>,
    corners: ([f32; 3], [f32; 3]),
    active: u64,
    bound: &[f32; RAY_PACKET],
) -> (u64, f32) {
    rays_in_box_lanes::<F32x16>(rays, corners, active, bound)
}

/// [`rays_in_box`] in lanes of `L`, group by group, skipping groups without active rays. Only
/// in code compiled with `L`'s instruction set.
#[inline(always)]
fn rays_in_box_lanes<L: RayGroupLanes>(
    rays: BoxRays<'_>,
    (lo, hi): ([f32; 3], [f32; 3]),
    active: u64,
    bound: &[f32; RAY_PACKET],
) -> (u64, f32) {
    let scale = L::splat(FAR_SCALE);
    let zero = L::splat(0.0);
    let (lo, hi) = (lo.map(L::splat), hi.map(L::splat));
    let group_bits = (1u32 << L::LANES) - 1;
    let mut entered = 0u64;
    let mut entry = L::splat(f32::INFINITY);
    for from in (0..RAY_PACKET).step_by(L::LANES) {
        let lanes = (active >> from) as u32 & group_bits;
        if lanes == 0 {
            continue;
        }
        let mut t0 = zero;
        let mut t1 = L::load_at(bound, from);
        for axis in 0..3 {
            let o = L::load_at(&rays.origin[axis], from);
            let inv = L::load_at(&rays.inv_dir[axis], from);
            // An inverse direction's sign bit is set exactly when it is below zero: then the
            // near plane is the box's hi.
            let near_hi = inv.cmp_lt(zero);
            let near = (near_hi.select(hi[axis], lo[axis]) - o) * inv;
            let far = (near_hi.select(lo[axis], hi[axis]) - o) * inv * scale;
            // As the single-ray test: a NaN never passes, so it changes nothing.
            t0 = near.greater(t0);
            t1 = far.lesser(t1);
        }
        let hit = !t0.cmp_gt(t1).bitmask() & lanes;
        entered |= u64::from(hit) << from;
        entry = (L::lane_mask(hit) & t0.cmp_lt(entry)).select(t0, entry);
    }
    (entered, entry.lowest())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::dispatch::{KernelWidth, available_kernel_widths};
    use crate::bvh::tests::Rng;

    /// One ray's slab test, written out: the single-ray test's operations in its order.
    fn slab(o: [f32; 3], inv: [f32; 3], (lo, hi): ([f32; 3], [f32; 3]), bound: f32) -> Option<f32> {
        let (mut t0, mut t1) = (0.0f32, bound);
        for a in 0..3 {
            let (near, far) = if inv[a] < 0.0 {
                (hi[a], lo[a])
            } else {
                (lo[a], hi[a])
            };
            let near = (near - o[a]) * inv[a];
            let far = (far - o[a]) * inv[a] * FAR_SCALE;
            t0 = if near > t0 { near } else { t0 };
            t1 = if far < t1 { far } else { t1 };
        }
        (t0 <= t1).then_some(t0)
    }

    /// At every kernel width this host has, every ray of `active` is entered exactly when its
    /// own slab test says so, and the entry distance is the least of theirs: random packets
    /// (directions along an axis among them, so infinite inverses), boxes (some flat, some
    /// holding the origins) and bounds (zero and infinite among them), 20,000 times.
    #[test]
    fn every_width_gives_each_ray_its_slab_test() {
        let mut rng = Rng(7);
        let value = |rng: &mut Rng| (rng.unit() - 0.5) * 8.0;
        let (mut tested, mut entered) = (0, 0);
        for round in 0..20_000 {
            let lo = [0, 1, 2].map(|_| value(&mut rng));
            let mut hi = lo.map(|x| x + rng.unit() * 4.0);
            if round % 5 == 0 {
                hi[round % 3] = lo[round % 3];
            }
            let mut origin = [[0.0f32; RAY_PACKET]; 3];
            let mut inv_dir = [[0.0f32; RAY_PACKET]; 3];
            let mut bound = [0.0f32; RAY_PACKET];
            for i in 0..RAY_PACKET {
                // Half the rays aim near a point of the box, a quarter exactly at a corner
                // (where entry and exit meet, and only the exit's scaling lets them pass).
                let (aim, corner) = (rng.next() % 4, rng.next());
                let aim_at_corner = aim == 0;
                let aim = aim < 2;
                for a in 0..3 {
                    origin[a][i] = value(&mut rng);
                    let target = if aim_at_corner {
                        [lo[a], hi[a]][(corner >> a & 1) as usize]
                    } else {
                        lo[a] + (hi[a] - lo[a]) * (rng.unit() * 1.4 - 0.2)
                    };
                    let d = match rng.next() % 8 {
                        0 => [0.0, -0.0][(rng.next() % 2) as usize],
                        _ if aim => target - origin[a][i],
                        _ => value(&mut rng),
                    };
                    inv_dir[a][i] = 1.0 / d;
                }
                bound[i] = match rng.next() % 8 {
                    0 => 0.0,
                    1 => f32::INFINITY,
                    _ => rng.unit() * 10.0,
                };
            }
            let active = if round % 3 == 0 { u64::MAX } else { rng.next() };
            let mut expected = (0u64, f32::INFINITY);
            for i in 0..RAY_PACKET {
                let o = [0, 1, 2].map(|a| origin[a][i]);
                let inv = [0, 1, 2].map(|a| inv_dir[a][i]);
                if let (true, Some(t)) = (active & (1 << i) != 0, slab(o, inv, (lo, hi), bound[i]))
                {
                    expected = (expected.0 | 1 << i, expected.1.min(t));
                }
            }
            tested += active.count_ones();
            entered += expected.0.count_ones();
            let rays = BoxRays {
                origin: &origin,
                inv_dir: &inv_dir,
            };
            for width in available_kernel_widths() {
                // SAFETY: each width only where this host has it.
                let got = unsafe {
                    match width {
                        KernelWidth::Four => rays_in_box::<4>(rays, (lo, hi), active, &bound),
                        KernelWidth::Eight => rays_in_box::<8>(rays, (lo, hi), active, &bound),
                        KernelWidth::Sixteen => rays_in_box::<16>(rays, (lo, hi), active, &bound),
                    }
                };
                assert_eq!(got, expected, "round {round}, {width:?}");
            }
        }
        // Both answers are common.
        assert!(
            entered > tested / 10 && entered < tested * 9 / 10,
            "{entered} of {tested}"
        );
    }
}
