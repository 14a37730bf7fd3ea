//! Shadow segments traced group by group ([`Bvh::occluded_grouped`]): with several lights, the
//! segments of neighbouring samples alternate lights (sample by sample, light by light), so a
//! 16-segment packet ran toward every light at once; grouped by light, a packet's segments
//! converge on one.

use super::Bvh;
use crate::triangle::Ray;

/// The scratch space of [`Bvh::occluded_grouped`], kept from call to call.
#[derive(Default)]
pub struct SegmentGroups {
    /// Segment indices, group by group (each group in input order).
    order: Vec<u32>,
    grouped: Vec<(Ray, f32)>,
    answers: Vec<bool>,
    starts: Vec<usize>,
}

impl Bvh {
    /// [`Bvh::occluded_many`] of `segments` (`out[i]` for `segments[i]`), traced group by
    /// group: `groups[i] < group_count` is segment `i`'s group (its light), and each group's
    /// segments are traced together in input order. The answers are `occluded_many`'s: tracing
    /// order changes none. With one group there is nothing to reorder. Panics if the lengths
    /// differ or a group is out of range.
    pub fn occluded_grouped(
        &self,
        segments: &[(Ray, f32)],
        (groups, group_count): (&[u32], usize),
        out: &mut [bool],
        scratch: &mut SegmentGroups,
    ) {
        assert_eq!(segments.len(), groups.len(), "one group per segment");
        if group_count <= 1 {
            self.occluded_many(segments, out);
            return;
        }
        // Counting sort of the indices by group, stable.
        let s = scratch;
        s.starts.clear();
        s.starts.resize(group_count + 1, 0);
        for &g in groups {
            s.starts[g as usize + 1] += 1;
        }
        for g in 0..group_count {
            s.starts[g + 1] += s.starts[g];
        }
        s.order.clear();
        s.order.resize(segments.len(), 0);
        for (i, &g) in groups.iter().enumerate() {
            let at = &mut s.starts[g as usize];
            s.order[*at] = i as u32;
            *at += 1;
        }
        s.grouped.clear();
        s.grouped
            .extend(s.order.iter().map(|&i| segments[i as usize]));
        s.answers.clear();
        s.answers.resize(segments.len(), false);
        self.occluded_many(&s.grouped, &mut s.answers);
        for (&i, &answer) in s.order.iter().zip(&s.answers) {
            out[i as usize] = answer;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::tests::Rng;
    use glam::Vec3;

    /// Grouped or not, every segment gets `occluded_many`'s answer: random segments toward
    /// three points, their groups interleaved and uneven, and one group.
    #[test]
    fn grouped_answers_are_occluded_many_answers() {
        let mut r = Rng(7);
        let mut v = || Vec3::new(r.unit(), r.unit(), r.unit()) * 4.0 - Vec3::splat(2.0);
        let tris: Vec<[Vec3; 3]> = (0..400)
            .map(|_| {
                let a = v();
                [a, a + v() * 0.1, a + v() * 0.1]
            })
            .collect();
        let bvh = Bvh::build(tris, (0..400).collect());
        let lights = [
            Vec3::new(0.3, 3.0, 0.2),
            Vec3::new(-2.5, 0.5, 1.0),
            Vec3::new(0.0, -3.0, 0.0),
        ];
        let mut segments = Vec::new();
        let mut groups = Vec::new();
        for k in 0..997u32 {
            let f = k as f32;
            let origin = Vec3::new(
                (f * 0.37).sin() * 2.0,
                (f * 0.11).cos() * 2.0,
                (f * 0.23).sin(),
            );
            let light = (k * k % 7 % 3) as usize;
            segments.push((
                Ray {
                    origin,
                    dir: lights[light] - origin,
                },
                0.999,
            ));
            groups.push(light as u32);
        }
        let mut expected = vec![false; segments.len()];
        bvh.occluded_many(&segments, &mut expected);
        let blocked = expected.iter().filter(|b| **b).count();
        assert!(
            blocked > 50 && blocked < 950,
            "{blocked} blocked: a test that can fail"
        );
        let mut scratch = SegmentGroups::default();
        for group_count in [3usize, 1] {
            let groups: Vec<u32> = groups
                .iter()
                .map(|&g| g.min(group_count as u32 - 1))
                .collect();
            let mut got = vec![!expected[0]; segments.len()];
            bvh.occluded_grouped(&segments, (&groups, group_count), &mut got, &mut scratch);
            assert_eq!(got, expected, "{group_count} groups");
        }
    }
}
