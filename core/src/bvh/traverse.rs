//! Closest-hit and any-hit traversal. Box tests are conservative (pbrt-v4's slab test with the
//! far distance scaled by 1 + 2·gamma(3)), and a node is skipped only when its entry distance
//! exceeds the current bound by a relative margin, so culling never changes the answer.

use super::{Aabb, Bvh};
use crate::triangle::{Ray, RayPrep, gamma, intersect};
use glam::Vec3;

/// Relative margin on culling distances: far larger than the rounding error of a box entry
/// distance or of a triangle's t, so culling stays conservative.
const CULL_MARGIN: f32 = 1.0 + 1e-4;
/// 1 + 2·gamma(3) with gamma(n) = n·u / (1 - n·u), u = 2^-24 (pbrt-v4, Bounds3::IntersectP).
const FAR_SCALE: f32 = 1.0 + 2.0 * gamma(3.0);
/// One stack entry per tree level suffices: the builder caps depth at `MAX_DEPTH`.
const STACK: usize = super::build::MAX_DEPTH;

/// The nearest hit of a ray: scene-wide triangle id, distance and barycentrics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestHit {
    pub id: u32,
    pub t: f32,
    pub b: [f32; 3],
    /// The triangle's corners (as stored in the BVH), for shading without another lookup.
    pub corners: [Vec3; 3],
    /// The triangle's position in the BVH's leaf order (indexes per-triangle data stored in
    /// that order, as split objects do).
    pub index: u32,
}

struct SlabRay {
    origin: Vec3,
    inv_dir: Vec3,
}

impl SlabRay {
    fn new(ray: &Ray) -> Self {
        SlabRay {
            origin: ray.origin,
            inv_dir: Vec3::ONE / ray.dir,
        }
    }

    /// Entry distance into `b` (0 when the origin is inside), or `None` if the ray misses it
    /// or enters beyond `t_max`.
    #[inline]
    fn entry(&self, b: &Aabb, t_max: f32) -> Option<f32> {
        let mut t0 = 0.0f32;
        let mut t1 = t_max;
        for axis in 0..3 {
            let inv = self.inv_dir[axis];
            let mut near = (b.lo[axis] - self.origin[axis]) * inv;
            let mut far = (b.hi[axis] - self.origin[axis]) * inv;
            if near > far {
                std::mem::swap(&mut near, &mut far);
            }
            far *= FAR_SCALE;
            // NaN (0 * inf when the origin lies on a slab plane) leaves the interval unchanged.
            if near > t0 {
                t0 = near;
            }
            if far < t1 {
                t1 = far;
            }
            if t0 > t1 {
                return None;
            }
        }
        Some(t0)
    }
}

/// Whether a shadow segment (`0 < t < t_max` along `ray`) can meet a BVH with root `bounds`:
/// exactly the root test of [`Bvh::occluded`], so `false` here guarantees `occluded` is false.
pub fn segment_may_hit(bounds: &Aabb, ray: &Ray, t_max: f32) -> bool {
    SlabRay::new(ray)
        .entry(bounds, t_max * CULL_MARGIN)
        .is_some()
}

impl Bvh {
    /// The nearest hit with `t > 0`: smaller t wins, equal t goes to the smaller id.
    pub fn closest_hit(&self, ray: &Ray) -> Option<ClosestHit> {
        let root = self.nodes.first()?;
        let prep = RayPrep::new(ray);
        let slab = SlabRay::new(ray);
        let mut best: Option<ClosestHit> = None;
        let mut best_t = f32::INFINITY;
        let mut stack = [0u32; STACK];
        let mut depth = 0usize;
        slab.entry(&root.bounds, f32::INFINITY)?;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            if n.count > 0 {
                let first = n.first as usize;
                for i in first..first + n.count as usize {
                    let [p0, p1, p2] = self.triangles[i];
                    let Some(h) = intersect(&prep, p0, p1, p2, f32::INFINITY) else {
                        continue;
                    };
                    let id = self.ids[i];
                    let better = match best {
                        None => true,
                        Some(b) => h.t < b.t || (h.t == b.t && id < b.id),
                    };
                    if better {
                        best_t = h.t;
                        best = Some(ClosestHit {
                            id,
                            t: h.t,
                            b: h.b,
                            corners: [p0, p1, p2],
                            index: i as u32,
                        });
                    }
                }
            } else {
                let limit = best_t * CULL_MARGIN;
                let (l, r) = (n.first as usize, n.first as usize + 1);
                let el = slab.entry(&self.nodes[l].bounds, limit);
                let er = slab.entry(&self.nodes[r].bounds, limit);
                match (el, er) {
                    (Some(a), Some(b)) => {
                        let (near, far) = if b < a { (r, l) } else { (l, r) };
                        push(&mut stack, &mut depth, far);
                        node = near;
                        continue;
                    }
                    (Some(_), None) => {
                        node = l;
                        continue;
                    }
                    (None, Some(_)) => {
                        node = r;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Pop the next node still worth visiting.
            loop {
                if depth == 0 {
                    return best;
                }
                depth -= 1;
                let candidate = stack[depth] as usize;
                if slab
                    .entry(&self.nodes[candidate].bounds, best_t * CULL_MARGIN)
                    .is_some()
                {
                    node = candidate;
                    break;
                }
            }
        }
    }

    /// True when some triangle is hit with `0 < t < t_max` (shadow rays).
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        let Some(root) = self.nodes.first() else {
            return false;
        };
        if !segment_may_hit(&root.bounds, ray, t_max) {
            return false;
        }
        let prep = RayPrep::new(ray);
        let slab = SlabRay::new(ray);
        let limit = t_max * CULL_MARGIN;
        let mut stack = [0u32; STACK];
        let mut depth = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            if n.count > 0 {
                let first = n.first as usize;
                for [p0, p1, p2] in &self.triangles[first..first + n.count as usize] {
                    if intersect(&prep, *p0, *p1, *p2, t_max).is_some() {
                        return true;
                    }
                }
            } else {
                let (l, r) = (n.first as usize, n.first as usize + 1);
                let hit_l = slab.entry(&self.nodes[l].bounds, limit).is_some();
                let hit_r = slab.entry(&self.nodes[r].bounds, limit).is_some();
                if hit_l && hit_r {
                    push(&mut stack, &mut depth, r);
                    node = l;
                    continue;
                } else if hit_l {
                    node = l;
                    continue;
                } else if hit_r {
                    node = r;
                    continue;
                }
            }
            if depth == 0 {
                return false;
            }
            depth -= 1;
            node = stack[depth] as usize;
        }
    }
}

#[inline]
fn push(stack: &mut [u32; STACK], depth: &mut usize, node: usize) {
    stack[*depth] = node as u32;
    *depth += 1;
}
