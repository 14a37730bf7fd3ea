//! The rays of a packet (`ray_packet.rs`, `segment_packet.rs`) in the layout lanes read
//! directly: one array per coordinate, ray i at index i. Made once per packet, from the rays'
//! usual layout (origin and direction side by side) four rays at a time: each ray's six floats
//! come in as two overlapping four-float loads and are transposed in registers, where gathering
//! them lane by lane took one insert per float. The packet's interval tester
//! ([`super::ray_packet::RayPacketTester`]) and the leaf tests in lanes (`leaf_lanes.rs`) then
//! load a group's coordinates with one vector load each.
//!
//! Guarantee: coordinate `a` of ray `i`'s origin is `origin[a][i]`, bit for bit, and so for the
//! direction; places past the packet's last ray, up to the end of its group of four, repeat
//! it, so extremes and signs over the groups holding rays are those over the rays.

use super::lanes::RayGroupLanes;
use super::ray_packet::{CLOSEST_PACKET, GROUPS, RAY_PACKET, is_finite};
use crate::triangle::Ray;
use wide::f32x4;

/// 1..=[`RAY_PACKET`] rays, coordinate by coordinate.
#[derive(Clone, Copy)]
#[repr(C, align(64))]
pub(super) struct PacketRays {
    pub origin: [[f32; RAY_PACKET]; 3],
    pub dir: [[f32; RAY_PACKET]; 3],
}

impl PacketRays {
    /// Room for a packet's rays, to be [`Self::fill`]ed: made once for all the packets of a
    /// call, where making it per packet cost a clear and a copy of its 384 bytes.
    pub const EMPTY: PacketRays = PacketRays {
        origin: [[0.0; RAY_PACKET]; 3],
        dir: [[0.0; RAY_PACKET]; 3],
    };

    /// Holds the rays `ray(&items[i])` of 1..=[`RAY_PACKET`] `items`, and says whether every
    /// origin and direction is finite (`ray_packet::is_finite`). Places past the last ray
    /// repeat it to the end of the packet, except after [`CLOSEST_PACKET`] rays: those places
    /// are left as they were, and nothing reads them for these rays (the loops over a packet's
    /// groups stop at the last one holding a ray, `ray_packet::groups_of`).
    #[inline(always)]
    pub fn fill<T>(&mut self, items: &[T], ray: impl Fn(&T) -> &Ray) -> bool {
        // Full packets, and closest-hit packets of camera rays below 64 spp, read each ray at
        // a fixed place.
        if let Ok(full) = <&[T; RAY_PACKET]>::try_from(items) {
            return self.fill_groups(full, ray);
        }
        if let Ok(closest) = <&[T; CLOSEST_PACKET]>::try_from(items) {
            return self.fill_groups(closest, ray);
        }
        let last = items.len() - 1;
        for i in 0..RAY_PACKET {
            let r = ray(&items[i.min(last)]);
            for a in 0..3 {
                self.origin[a][i] = r.origin[a];
                self.dir[a][i] = r.dir[a];
            }
        }
        items.iter().all(|item| is_finite(ray(item)))
    }

    /// [`Self::fill`] of `N` rays, `N` a multiple of four: four at a time ([`Self::put4`]).
    #[inline(always)]
    fn fill_groups<T, const N: usize>(&mut self, items: &[T; N], ray: impl Fn(&T) -> &Ray) -> bool {
        // 0 · x is a zero for finite x and NaN for an infinity or NaN, so the sum of these
        // products over the packet is a zero exactly when all are finite.
        let mut zeros = f32x4::ZERO;
        for at in (0..N).step_by(4) {
            let four = [
                ray(&items[at]),
                ray(&items[at + 1]),
                ray(&items[at + 2]),
                ray(&items[at + 3]),
            ];
            zeros += self.put4(at, four);
        }
        zeros.simd_eq(f32x4::ZERO).all()
    }

    /// Holds the 1..=[`RAY_PACKET`] rays whose coordinate `a` is `origin[a][i]` and `dir[a][i]`
    /// (all six slices of one length; every place written), and says whether every coordinate
    /// is finite: [`Self::fill`] for rays kept column by column, with one copy per coordinate.
    #[inline(always)]
    pub fn fill_columns(&mut self, origin: [&[f32]; 3], dir: [&[f32]; 3]) -> bool {
        let len = origin[0].len();
        let put = |column: &mut [f32; RAY_PACKET], from: &[f32]| {
            copy_in_blocks(&mut column[..len], from);
            column[len..].fill(from[len - 1]);
        };
        for a in 0..3 {
            put(&mut self.origin[a], origin[a]);
            put(&mut self.dir[a], dir[a]);
        }
        // As in `fill`: 0 · x is a zero exactly when x is finite, and places past the end
        // repeat the last ray.
        let zero = f32x4::ZERO;
        let mut zeros = zero;
        for g in 0..GROUPS {
            for a in 0..3 {
                zeros += self.origin4(a, g) * zero + self.dir4(a, g) * zero;
            }
        }
        zeros.simd_eq(zero).all()
    }

    /// Writes four rays at places `at..at + 4`: each ray's `[ox, oy, oz, dx]` and
    /// `[oz, dx, dy, dz]` as vectors, transposed. Returns the sum of 0 · x over their
    /// coordinates x (zeros where all are finite, else NaN in some lane).
    #[inline(always)]
    fn put4(&mut self, at: usize, rays: [&Ray; 4]) -> f32x4 {
        let head = |r: &Ray| f32x4::from([r.origin.x, r.origin.y, r.origin.z, r.dir.x]);
        let tail = |r: &Ray| f32x4::from([r.origin.z, r.dir.x, r.dir.y, r.dir.z]);
        let [ox, oy, oz, dx] =
            f32x4::transpose([head(rays[0]), head(rays[1]), head(rays[2]), head(rays[3])]);
        let [_, _, dy, dz] =
            f32x4::transpose([tail(rays[0]), tail(rays[1]), tail(rays[2]), tail(rays[3])]);
        let zero = f32x4::ZERO;
        let zeros = (ox * zero + oy * zero) + (oz * zero + dx * zero) + (dy * zero + dz * zero);
        let put = |column: &mut [f32; RAY_PACKET], lanes: f32x4| {
            column[at..at + 4].copy_from_slice(&lanes.to_array());
        };
        put(&mut self.origin[0], ox);
        put(&mut self.origin[1], oy);
        put(&mut self.origin[2], oz);
        put(&mut self.dir[0], dx);
        put(&mut self.dir[1], dy);
        put(&mut self.dir[2], dz);
        zeros
    }

    /// Ray `i`, bit for bit as it was put in.
    #[inline(always)]
    pub fn ray(&self, i: usize) -> Ray {
        let at = |c: &[[f32; RAY_PACKET]; 3]| glam::Vec3::new(c[0][i], c[1][i], c[2][i]);
        Ray {
            origin: at(&self.origin),
            dir: at(&self.dir),
        }
    }

    /// Group `g`'s origins along axis `a` (rays `4g..4g + 4`).
    #[inline(always)]
    pub fn origin4(&self, a: usize, g: usize) -> f32x4 {
        f32x4::load_at(&self.origin[a], 4 * g)
    }

    /// Group `g`'s directions along axis `a` (rays `4g..4g + 4`).
    #[inline(always)]
    pub fn dir4(&self, a: usize, g: usize) -> f32x4 {
        f32x4::load_at(&self.dir[a], 4 * g)
    }
}

/// Copies `from` to `to` (of one length): a whole packet's as four copies of sixteen values
/// (64 bytes) written out, which the baseline instruction set makes inline, where a copy of
/// 256 bytes (or a loop of smaller ones, which the compiler merges into one) is a call to
/// `memcpy`.
#[inline(always)]
pub(super) fn copy_in_blocks<T: Copy>(to: &mut [T], from: &[T]) {
    match (
        <&mut [T; RAY_PACKET]>::try_from(&mut *to),
        <&[T; RAY_PACKET]>::try_from(from),
    ) {
        (Ok(to), Ok(from)) => {
            let (to, from) = (to.as_chunks_mut::<16>().0, from.as_chunks::<16>().0);
            to[0] = from[0];
            to[1] = from[1];
            to[2] = from[2];
            to[3] = from[3];
        }
        _ => to.copy_from_slice(from),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// `fill` says a packet is finite exactly when every coordinate of every ray is: one
    /// infinity or NaN at any coordinate of any ray, in full and short packets, makes it false.
    #[test]
    fn fill_finds_any_coordinate_that_is_not_finite() {
        let finite = |i: usize| Ray {
            origin: Vec3::new(i as f32, -1e30, 0.5),
            dir: Vec3::new(-0.0, 3e-40, f32::MAX),
        };
        let mut packet = PacketRays::EMPTY;
        for len in [1, 5, 16] {
            let rays: Vec<Ray> = (0..len).map(finite).collect();
            assert!(packet.fill(&rays, |r| r), "len {len}");
            for bad in [f32::INFINITY, f32::NEG_INFINITY, f32::NAN] {
                for i in [0, len / 2, len - 1] {
                    for c in 0..6 {
                        let mut rays = rays.clone();
                        let r = &mut rays[i];
                        match c {
                            0..3 => r.origin[c] = bad,
                            _ => r.dir[c - 3] = bad,
                        }
                        assert!(
                            !packet.fill(&rays, |r| r),
                            "len {len} ray {i} coordinate {c}"
                        );
                    }
                }
            }
        }
    }

    /// Every coordinate of every ray lands at its place, full packets and short ones alike,
    /// and places past the end repeat the last ray.
    #[test]
    fn coordinates_land_at_their_ray_and_the_last_ray_repeats() {
        let ray = |i: usize| {
            let f = |k: usize| (i * 6 + k) as f32 + 0.25;
            Ray {
                origin: Vec3::new(f(0), f(1), f(2)),
                dir: Vec3::new(-f(3), f(4), -f(5)),
            }
        };
        for len in [1, 3, 4, 5, 15, 16] {
            let rays: Vec<Ray> = (0..len).map(ray).collect();
            let mut packet = PacketRays::EMPTY;
            packet.fill(&rays, |r| r);
            for i in 0..RAY_PACKET {
                let r = &rays[i.min(len - 1)];
                for a in 0..3 {
                    assert_eq!(
                        packet.origin[a][i], r.origin[a],
                        "len {len} ray {i} axis {a}"
                    );
                    assert_eq!(packet.dir[a][i], r.dir[a], "len {len} ray {i} axis {a}");
                    let g = i / 4;
                    assert_eq!(packet.origin4(a, g).to_array()[i % 4], r.origin[a]);
                    assert_eq!(packet.dir4(a, g).to_array()[i % 4], r.dir[a]);
                }
            }
        }
    }
}
