//! A ray packet's setup ([`super::ray_packet::RayPacketTester::new`]) in lanes of the kernel
//! width: each ray's inverse direction, and the extremes of the origins and inverse directions
//! over the packet, four rays a step everywhere, eight with AVX2 and sixteen with AVX-512F
//! (`dispatch.rs`). Every packet pays for it once, before its traversal: at 64 spp the setup
//! was 5-6% of a render of the Cornell box (48 four-lane divisions a packet of 64 rays, the
//! divider's throughput the bound, and SSE's sixteen registers spilled).
//!
//! Guarantee: each inverse direction is the single-ray testers' `1 / dir` (a correctly rounded
//! division in every instruction set), and each extreme is the least or greatest value over
//! the packet's places (inverse directions are never NaN; of a +0 and a -0 origin, either), so
//! every width gives the same tester.

#![allow(unsafe_code)]

use super::lanes::RayGroupLanes;
#[cfg(target_arch = "x86_64")]
use super::lanes::{F32x8, F32x16};
use super::packet_rays::PacketRays;
use super::ray_packet::RAY_PACKET;
use wide::f32x4;

/// What a packet's tester is made of: per axis, each ray's inverse direction (ray i at index
/// i), and the least and greatest origin coordinate and inverse direction over the packet.
pub(super) struct PacketSetup {
    pub inv_dir: [[f32; RAY_PACKET]; 3],
    pub origin_lo: [f32; 3],
    pub origin_hi: [f32; 3],
    pub inv_lo: [f32; 3],
    pub inv_hi: [f32; 3],
}

/// The setup of the packet `rays` over its first `places` (a multiple of four, at most
/// [`RAY_PACKET`]; places past its last ray repeat it), in lanes of the kernel width `WIDTH`
/// (4, 8 or 16). Wider lanes may also read places past `places` up to their multiple of eight
/// or sixteen, which [`PacketRays::fill`] leaves repeating the packet's last ray (or holding
/// rays of a full packet of [`super::CLOSEST_PACKET`]).
///
/// # Safety
/// `WIDTH` 8 only on hosts with AVX2, 16 only on hosts with AVX-512F (the kernel widths
/// `dispatch.rs` offers there).
#[inline(always)]
pub(super) unsafe fn packet_setup<const WIDTH: usize>(
    rays: &PacketRays,
    places: usize,
    out: &mut PacketSetup,
) {
    match WIDTH {
        // SAFETY: the caller's contract.
        #[cfg(target_arch = "x86_64")]
        16 => unsafe { packet_setup16(rays, places, out) },
        // SAFETY: the caller's contract.
        #[cfg(target_arch = "x86_64")]
        8 => unsafe { packet_setup8(rays, places, out) },
        _ => packet_setup_lanes::<f32x4>(rays, places, out),
    }
}

/// [`packet_setup`] compiled for AVX2, eight rays a step.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn packet_setup8(rays: &PacketRays, places: usize, out: &mut PacketSetup) {
    packet_setup_lanes::<F32x8>(rays, places, out);
}

/// [`packet_setup`] compiled for AVX-512F, sixteen rays a step.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn packet_setup16(rays: &PacketRays, places: usize, out: &mut PacketSetup) {
    packet_setup_lanes::<F32x16>(rays, places, out);
}

/// [`packet_setup`] in lanes of `L`. Only in code compiled with `L`'s instruction set.
#[inline(always)]
fn packet_setup_lanes<L: RayGroupLanes>(rays: &PacketRays, places: usize, out: &mut PacketSetup) {
    let one = L::splat(1.0);
    let (inf, neg_inf) = (L::splat(f32::INFINITY), L::splat(f32::NEG_INFINITY));
    for a in 0..3 {
        let (mut inv_lo, mut inv_hi) = (inf, neg_inf);
        let (mut o_lo, mut o_hi) = (inf, neg_inf);
        for from in (0..places).step_by(L::LANES) {
            // The same correctly rounded division as the single-ray testers
            // (`Vec3::ONE / dir`).
            let inv = one / L::load_at(&rays.dir[a], from);
            inv.store_at(&mut out.inv_dir[a], from);
            inv_lo = inv.lesser(inv_lo);
            inv_hi = inv.greater(inv_hi);
            let o = L::load_at(&rays.origin[a], from);
            o_lo = o.lesser(o_lo);
            o_hi = o.greater(o_hi);
        }
        // The greatest lane is minus the least of the negated lanes.
        let neg = L::splat(-0.0);
        out.inv_lo[a] = inv_lo.lowest();
        out.inv_hi[a] = -(inv_hi ^ neg).lowest();
        out.origin_lo[a] = o_lo.lowest();
        out.origin_hi[a] = -(o_hi ^ neg).lowest();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::dispatch::{KernelWidth, available_kernel_widths};
    use crate::bvh::tests::Rng;
    use crate::triangle::Ray;
    use glam::Vec3;

    /// Every width this host has makes the four-lane setup, bit for bit (origin extremes by
    /// value: of a +0 and a -0, either), for packets of every length, with zero direction
    /// components of both signs (infinite inverses) and tiny ones, and after a longer packet
    /// left other rays in the places past a shorter one's groups.
    #[test]
    fn every_width_makes_the_same_setup() {
        let mut rng = Rng(5);
        let component = |rng: &mut Rng| match rng.next() % 8 {
            0 => 0.0,
            1 => -0.0,
            2 => 1e-30,
            3 => -3e-39,
            _ => rng.unit() * 4.0 - 2.0,
        };
        let mut packet = PacketRays::EMPTY;
        for len in (1..=RAY_PACKET).chain([64, 32, 5, 32, 64, 17]) {
            let rays: Vec<Ray> = (0..len)
                .map(|_| Ray {
                    origin: Vec3::new(component(&mut rng), rng.unit(), -rng.unit()) * 3.0,
                    dir: Vec3::new(component(&mut rng), component(&mut rng), 0.25),
                })
                .collect();
            packet.fill(&rays, |r| r);
            let places = 4 * len.div_ceil(4);
            let setup = |width: KernelWidth| {
                let mut out = PacketSetup {
                    inv_dir: [[f32::NAN; RAY_PACKET]; 3],
                    origin_lo: [f32::NAN; 3],
                    origin_hi: [f32::NAN; 3],
                    inv_lo: [f32::NAN; 3],
                    inv_hi: [f32::NAN; 3],
                };
                // SAFETY: only the widths this host has.
                unsafe {
                    match width {
                        KernelWidth::Four => packet_setup::<4>(&packet, places, &mut out),
                        KernelWidth::Eight => packet_setup::<8>(&packet, places, &mut out),
                        KernelWidth::Sixteen => packet_setup::<16>(&packet, places, &mut out),
                    }
                }
                out
            };
            let four = setup(KernelWidth::Four);
            for (i, ray) in rays.iter().enumerate() {
                for a in 0..3 {
                    assert_eq!(four.inv_dir[a][i].to_bits(), (1.0 / ray.dir[a]).to_bits());
                }
            }
            let extreme = |f: fn(f32, f32) -> f32, v: &dyn Fn(&Ray) -> f32| {
                rays.iter().map(v).reduce(f).expect("a ray")
            };
            for a in 0..3 {
                let inv = move |r: &Ray| 1.0 / r.dir[a];
                let origin = move |r: &Ray| r.origin[a];
                assert_eq!(four.inv_lo[a].to_bits(), extreme(f32::min, &inv).to_bits());
                assert_eq!(four.inv_hi[a].to_bits(), extreme(f32::max, &inv).to_bits());
                assert_eq!(four.origin_lo[a], extreme(f32::min, &origin));
                assert_eq!(four.origin_hi[a], extreme(f32::max, &origin));
            }
            for width in available_kernel_widths() {
                let got = setup(width);
                let bits = |x: &[f32]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                for a in 0..3 {
                    let context = format!("{width:?}, {len} rays, axis {a}");
                    let inv = |s: &PacketSetup| bits(&s.inv_dir[a][..len]);
                    assert_eq!(inv(&got), inv(&four), "{context}");
                    assert_eq!(
                        got.inv_lo[a].to_bits(),
                        four.inv_lo[a].to_bits(),
                        "{context}"
                    );
                    assert_eq!(
                        got.inv_hi[a].to_bits(),
                        four.inv_hi[a].to_bits(),
                        "{context}"
                    );
                    assert_eq!(got.origin_lo[a], four.origin_lo[a], "{context}");
                    assert_eq!(got.origin_hi[a], four.origin_hi[a], "{context}");
                }
            }
        }
    }
}
