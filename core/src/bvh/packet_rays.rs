//! The rays of a packet (`ray_packet.rs`, `segment_packet.rs`) in the layout lanes read
//! directly: one array per coordinate, ray i at index i. Made once per packet, from the rays'
//! usual layout (origin and direction side by side) four rays at a time: each ray's six floats
//! come in as two overlapping four-float loads and are transposed in registers, where gathering
//! them lane by lane took one insert per float. The packet's interval tester
//! ([`super::ray_packet::RayPacketTester`]) and the leaf tests in lanes (`leaf_lanes.rs`) then
//! load a group's coordinates with one vector load each.
//!
//! Guarantee: coordinate `a` of ray `i`'s origin is `origin[a][i]`, bit for bit, and so for the
//! direction; places past the packet's last ray repeat it, so extremes and signs over all
//! places are those over the rays.

use super::lanes::RayGroupLanes;
use super::ray_packet::{GROUPS, RAY_PACKET};
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

    /// Holds the rays `ray(&items[i])` of 1..=[`RAY_PACKET`] `items` (every place written).
    #[inline(always)]
    pub fn fill<T>(&mut self, items: &[T], ray: impl Fn(&T) -> &Ray) {
        match <&[T; RAY_PACKET]>::try_from(items) {
            // A full packet (the common case) reads each ray at a fixed place.
            Ok(full) => {
                for g in 0..GROUPS {
                    let at = 4 * g;
                    let four = [
                        ray(&full[at]),
                        ray(&full[at + 1]),
                        ray(&full[at + 2]),
                        ray(&full[at + 3]),
                    ];
                    self.put4(at, four);
                }
            }
            Err(_) => {
                let last = items.len() - 1;
                for i in 0..RAY_PACKET {
                    let r = ray(&items[i.min(last)]);
                    for a in 0..3 {
                        self.origin[a][i] = r.origin[a];
                        self.dir[a][i] = r.dir[a];
                    }
                }
            }
        }
    }

    /// Writes four rays at places `at..at + 4`: each ray's `[ox, oy, oz, dx]` and
    /// `[oz, dx, dy, dz]` as vectors, transposed.
    #[inline(always)]
    fn put4(&mut self, at: usize, rays: [&Ray; 4]) {
        let head = |r: &Ray| f32x4::from([r.origin.x, r.origin.y, r.origin.z, r.dir.x]);
        let tail = |r: &Ray| f32x4::from([r.origin.z, r.dir.x, r.dir.y, r.dir.z]);
        let [ox, oy, oz, dx] =
            f32x4::transpose([head(rays[0]), head(rays[1]), head(rays[2]), head(rays[3])]);
        let [_, _, dy, dz] =
            f32x4::transpose([tail(rays[0]), tail(rays[1]), tail(rays[2]), tail(rays[3])]);
        let put = |column: &mut [f32; RAY_PACKET], lanes: f32x4| {
            column[at..at + 4].copy_from_slice(&lanes.to_array());
        };
        put(&mut self.origin[0], ox);
        put(&mut self.origin[1], oy);
        put(&mut self.origin[2], oz);
        put(&mut self.dir[0], dx);
        put(&mut self.dir[1], dy);
        put(&mut self.dir[2], dz);
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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

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
