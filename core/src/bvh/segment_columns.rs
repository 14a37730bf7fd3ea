//! Shadow segments kept column by column ([`SegmentColumns`]): each coordinate of the origins
//! and directions in its own array, as segment packets read them. The renderer's shading lanes
//! write four segments of a coordinate with one vector store, and a packet of sixteen takes
//! each coordinate with one copy, where segments kept as `(Ray, t_max)` pairs were pieced
//! together from the lanes float by float and transposed back into lanes for every packet.

use super::packet_rays::{PacketRays, copy_in_blocks};
use super::ray_packet::{RAY_PACKET, first_bits};
use crate::triangle::Ray;
use glam::Vec3;
use std::ops::Range;

/// Shadow segments `(ray, t_max)`, coordinate by coordinate: segment i's origin is
/// `(origin[0][i], origin[1][i], origin[2][i])`, its direction likewise, and it ends at
/// `t_max[i]`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SegmentColumns {
    origin: [Vec<f32>; 3],
    dir: [Vec<f32>; 3],
    t_max: Vec<f32>,
}

impl SegmentColumns {
    /// How many segments there are.
    pub fn len(&self) -> usize {
        self.t_max.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.t_max.is_empty()
    }

    /// Removes every segment, keeping the memory.
    pub fn clear(&mut self) {
        for a in 0..3 {
            self.origin[a].clear();
            self.dir[a].clear();
        }
        self.t_max.clear();
    }

    /// Appends the segment `(ray, t_max)`.
    #[inline]
    pub fn push(&mut self, ray: &Ray, t_max: f32) {
        for a in 0..3 {
            self.origin[a].push(ray.origin[a]);
            self.dir[a].push(ray.dir[a]);
        }
        self.t_max.push(t_max);
    }

    /// Appends the segments of the `N` lanes set in `mask` (bit k: lane k), lowest lane
    /// first: lane k's origin is `(origin[0][k], origin[1][k], origin[2][k])`, its direction
    /// likewise, and every one ends at `t_max`.
    #[inline]
    pub fn push_lanes<const N: usize>(
        &mut self,
        mask: u32,
        origin: &[[f32; N]; 3],
        dir: &[[f32; N]; 3],
        t_max: f32,
    ) {
        let all = first_bits(N);
        if mask & all == all {
            for a in 0..3 {
                self.origin[a].extend_from_slice(&origin[a]);
                self.dir[a].extend_from_slice(&dir[a]);
            }
            self.t_max.extend_from_slice(&[t_max; N]);
            return;
        }
        for k in super::bits(mask & all) {
            for a in 0..3 {
                self.origin[a].push(origin[a][k]);
                self.dir[a].push(dir[a][k]);
            }
            self.t_max.push(t_max);
        }
    }

    /// Segment `i`.
    pub fn get(&self, i: usize) -> (Ray, f32) {
        let at = |c: &[Vec<f32>; 3]| Vec3::new(c[0][i], c[1][i], c[2][i]);
        let ray = Ray {
            origin: at(&self.origin),
            dir: at(&self.dir),
        };
        (ray, self.t_max[i])
    }

    /// Puts the 1..=[`RAY_PACKET`] segments `range` into a packet's rays and `t_max` (0 past
    /// the last), as [`PacketRays::fill`] does with pairs; says whether every origin and
    /// direction is finite.
    #[inline(always)]
    pub(super) fn fill(
        &self,
        range: Range<usize>,
        rays: &mut PacketRays,
        t_max: &mut [f32; RAY_PACKET],
    ) -> bool {
        let len = range.len();
        copy_in_blocks(&mut t_max[..len], &self.t_max[range.clone()]);
        t_max[len..].fill(0.0);
        rays.fill_columns(
            [&self.origin[0], &self.origin[1], &self.origin[2]].map(|c| &c[range.clone()]),
            [&self.dir[0], &self.dir[1], &self.dir[2]].map(|c| &c[range.clone()]),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Segments pushed one by one and four lanes at a time (every mask, and a whole and a
    /// partial sixteen) come back as pushed, in order.
    #[test]
    fn pushed_segments_come_back_in_order() {
        let mut columns = SegmentColumns::default();
        let mut expected = Vec::new();
        let lane = |k: usize, m: u32, a: usize| (m * 100 + k as u32 * 10 + a as u32) as f32;
        for mask in 0..16u32 {
            let origin = [0, 1, 2].map(|a| [0, 1, 2, 3].map(|k| lane(k, mask, a)));
            let dir = [0, 1, 2].map(|a| [0, 1, 2, 3].map(|k| -lane(k, mask, a)));
            columns.push_lanes(mask, &origin, &dir, mask as f32 + 0.5);
            for k in super::super::bits(mask) {
                let ray = Ray {
                    origin: Vec3::new(lane(k, mask, 0), lane(k, mask, 1), lane(k, mask, 2)),
                    dir: -Vec3::new(lane(k, mask, 0), lane(k, mask, 1), lane(k, mask, 2)),
                };
                expected.push((ray, mask as f32 + 0.5));
            }
            let ray = Ray {
                origin: Vec3::new(-1.0, 2.0, f32::INFINITY),
                dir: Vec3::X,
            };
            columns.push(&ray, 7.0);
            expected.push((ray, 7.0));
        }
        for mask in [0xffff, 0x8421, 0x7ffe] {
            let sixteen =
                |sign: f32| [0, 1, 2].map(|a| std::array::from_fn(|k| sign * lane(k, mask, a)));
            columns.push_lanes::<16>(mask, &sixteen(1.0), &sixteen(-1.0), 3.0);
            for k in super::super::bits(mask) {
                let at = |sign: f32| {
                    sign * Vec3::new(lane(k, mask, 0), lane(k, mask, 1), lane(k, mask, 2))
                };
                expected.push((
                    Ray {
                        origin: at(1.0),
                        dir: at(-1.0),
                    },
                    3.0,
                ));
            }
        }
        assert_eq!(columns.len(), expected.len());
        assert_eq!(columns.len(), 32 + 16 + 16 + 4 + 14);
        let got: Vec<_> = (0..columns.len()).map(|i| columns.get(i)).collect();
        assert_eq!(got, expected);
        columns.clear();
        assert!(columns.is_empty());
    }
}
