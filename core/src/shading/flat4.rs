//! Four hits on flat (no vertex normals), untextured triangles shaded at once: their
//! [`super::surface_point`]s and every light's [`super::shadow_test`], the f32 arithmetic in
//! f32x4 lanes. Each lane performs the scalar code's IEEE operations in its order (glam's
//! `dot`, `cross` and `normalize_or_zero` spelled out; no FMA; square root and division are
//! correctly rounded in every SIMD instruction set; negation flips the sign bit), so each
//! lane's test is the scalar test bit for bit. What branches per lane (rounding the shadow
//! origin away from the surface, the ray toward the light, the radiance) runs lane by lane in
//! the scalar code.

use super::lanes::point_incidences4;
use super::{Incidence, ShadowTest, incidence, round_away, shadow_ray, unoccluded_radiance};
use crate::scene::Light;
use crate::triangle::gamma;
use glam::Vec3;
use wide::f32x4;

/// What [`FlatShader::shadow_tests4`] needs of one hit: the triangle's corners, the hit's
/// barycentrics, the ray's direction and the diffuse reflectance.
/// (References, not copies: the lanes read each value where the hit and the ray keep it.)
#[derive(Clone, Copy, Debug)]
pub struct FlatHit<'a> {
    /// The triangle's corners.
    pub corners: &'a [Vec3; 3],
    /// The hit's barycentrics.
    pub b: &'a [f32; 3],
    /// The ray's direction.
    pub dir: &'a Vec3,
    /// Diffuse reflectance.
    pub kd: [f32; 3],
}

/// Three axes of four lanes: glam's `Vec3` operations lane by lane, in glam's order.
#[derive(Clone, Copy)]
struct Vec3x4 {
    x: f32x4,
    y: f32x4,
    z: f32x4,
}

impl Vec3x4 {
    #[inline(always)]
    fn of(v: [Vec3; 4]) -> Self {
        Vec3x4 {
            x: f32x4::from([v[0].x, v[1].x, v[2].x, v[3].x]),
            y: f32x4::from([v[0].y, v[1].y, v[2].y, v[3].y]),
            z: f32x4::from([v[0].z, v[1].z, v[2].z, v[3].z]),
        }
    }

    /// The lanes as four `Vec3`s.
    #[inline(always)]
    fn lanes(&self) -> [Vec3; 4] {
        let (x, y, z) = (self.x.to_array(), self.y.to_array(), self.z.to_array());
        let v = |k: usize| Vec3::new(x[k], y[k], z[k]);
        [v(0), v(1), v(2), v(3)]
    }

    /// `s * v` (each axis times its lane of `s`).
    #[inline(always)]
    fn scale(self, s: f32x4) -> Self {
        Vec3x4 {
            x: s * self.x,
            y: s * self.y,
            z: s * self.z,
        }
    }

    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Vec3x4 {
            x: self.x + o.x,
            y: self.y + o.y,
            z: self.z + o.z,
        }
    }

    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Vec3x4 {
            x: self.x - o.x,
            y: self.y - o.y,
            z: self.z - o.z,
        }
    }

    #[inline(always)]
    fn abs(self) -> Self {
        Vec3x4 {
            x: self.x.abs(),
            y: self.y.abs(),
            z: self.z.abs(),
        }
    }

    /// glam's `dot`: `(x·x' + y·y') + z·z'`.
    #[inline(always)]
    fn dot(self, o: Self) -> f32x4 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// glam's `cross`.
    #[inline(always)]
    fn cross(self, o: Self) -> Self {
        Vec3x4 {
            x: self.y * o.z - o.y * self.z,
            y: self.z * o.x - o.z * self.x,
            z: self.x * o.y - o.x * self.y,
        }
    }

    /// glam's `normalize_or_zero`: `v · (1 / sqrt(v·v))` where that reciprocal is finite and
    /// positive, else zero.
    #[inline(always)]
    fn normalize_or_zero(self) -> Self {
        let rcp = f32x4::ONE / self.dot(self).sqrt();
        let ok = rcp.simd_gt(f32x4::ZERO) & rcp.simd_lt(f32x4::splat(f32::INFINITY));
        let n = self.scale(rcp);
        Vec3x4 {
            x: ok & n.x,
            y: ok & n.y,
            z: ok & n.z,
        }
    }

    /// `-v` where `flip` is all ones (the sign bit flipped, as scalar negation does).
    #[inline(always)]
    fn negate_where(self, flip: f32x4) -> Self {
        let sign = flip & f32x4::splat(-0.0);
        Vec3x4 {
            x: self.x ^ sign,
            y: self.y ^ sign,
            z: self.z ^ sign,
        }
    }
}

/// A light seen from the four points: unit directions toward it, irradiance per channel, and
/// whether the lane has an incidence at all (not at a point light's position).
struct LightLanes {
    to_light: Vec3x4,
    irradiance: [[f32; 4]; 3],
    valid: [bool; 4],
}

impl LightLanes {
    #[inline(always)]
    fn new(light: &Light, points: [Vec3; 4]) -> Self {
        let incidences: [Option<Incidence>; 4] = match *light {
            Light::Point {
                position,
                intensity,
            } => point_incidences4(position, intensity, points),
            Light::Directional { .. } => [incidence(points[0], light); 4],
        };
        let at = |k: usize| incidences[k].map_or(Vec3::ZERO, |i| i.to_light);
        let e = |c: usize| {
            let e = |k: usize| incidences[k].map_or(0.0, |i| i.irradiance[c]);
            [e(0), e(1), e(2), e(3)]
        };
        LightLanes {
            to_light: Vec3x4::of([at(0), at(1), at(2), at(3)]),
            irradiance: [e(0), e(1), e(2)],
            valid: [
                incidences[0].is_some(),
                incidences[1].is_some(),
                incidences[2].is_some(),
                incidences[3].is_some(),
            ],
        }
    }
}

/// Shades four flat, untextured hits at a time ([`FlatShader::shadow_tests4`]), keeping its
/// per-light scratch space from call to call.
#[derive(Default)]
pub struct FlatShader {
    lit: Vec<(LightLanes, [f32; 4])>,
}

impl FlatShader {
    /// Every light's [`super::shadow_test`] at the [`super::surface_point`] of each of four
    /// flat, untextured hits, handed to `visit(hit, light, test)` in order of hit, then light:
    /// exactly the tests and calls of [`super::shadow_tests`] over those surface points.
    #[inline]
    pub fn shadow_tests4(
        &mut self,
        hits: &[FlatHit<'_>; 4],
        lights: &[Light],
        mut visit: impl FnMut(usize, usize, ShadowTest),
    ) {
        let corner = |c: usize| {
            let at = |k: usize| hits[k].corners[c];
            Vec3x4::of([at(0), at(1), at(2), at(3)])
        };
        let [p0, p1, p2] = [corner(0), corner(1), corner(2)];
        let weight =
            |c: usize| f32x4::from([hits[0].b[c], hits[1].b[c], hits[2].b[c], hits[3].b[c]]);
        let (w0, w1, w2) = (
            p0.scale(weight(0)),
            p1.scale(weight(1)),
            p2.scale(weight(2)),
        );
        // As `surface_point`: p, its error bound, and the geometric normal facing the ray.
        let p = w0.add(w1).add(w2);
        let p_error = w0
            .abs()
            .add(w1.abs())
            .add(w2.abs())
            .scale(f32x4::splat(gamma(7.0)));
        let n_geo = p1.sub(p0).cross(p2.sub(p0)).normalize_or_zero();
        let dir = Vec3x4::of([*hits[0].dir, *hits[1].dir, *hits[2].dir, *hits[3].dir]);
        let n = n_geo.negate_where(n_geo.dot(dir).simd_gt(f32x4::ZERO));
        // As `offset_origin(p, p_error, n, n)`: n·n is never below zero, so the offset keeps
        // its side; the rounding away from the surface is per lane, below.
        let offset = n.scale(n.abs().dot(p_error));
        let (offsets, origins) = (offset.lanes(), p.add(offset).lanes());
        let points = p.lanes();
        self.lit.clear();
        self.lit.extend(lights.iter().map(|light| {
            let lanes = LightLanes::new(light, points);
            let cos = n.dot(lanes.to_light).to_array();
            (lanes, cos)
        }));
        for (k, hit) in hits.iter().enumerate() {
            let origin = round_away(origins[k], offsets[k]);
            for (l, (light, (lanes, cos))) in lights.iter().zip(&self.lit).enumerate() {
                let cos = cos[k];
                if !lanes.valid[k] || cos <= 0.0 {
                    continue;
                }
                let (ray, t_max) = shadow_ray(light, origin);
                let e = &lanes.irradiance;
                let irradiance = [e[0][k], e[1][k], e[2][k]];
                visit(
                    k,
                    l,
                    ShadowTest {
                        ray,
                        t_max,
                        unoccluded: unoccluded_radiance(hit.kd, cos, irradiance),
                    },
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shading::tests::rng;
    use crate::shading::{shadow_test, surface_point};
    use glam::DVec3;

    /// Each test's bits: origin, direction, t_max, radiance.
    fn bits(t: &ShadowTest) -> Vec<u32> {
        let mut b = t.ray.origin.to_array().to_vec();
        b.extend(t.ray.dir.to_array());
        b.push(t.t_max);
        b.extend(t.unoccluded);
        b.into_iter().map(f32::to_bits).collect()
    }

    /// The lanes give, hit by hit and light by light, the scalar surface point's shadow tests
    /// bit for bit: random triangles at several scales seen from either side, degenerate ones
    /// (no normal), hits on a corner, point lights (one at a hit point, grey and coloured)
    /// and a directional light.
    #[test]
    fn four_flat_hits_in_lanes_are_the_scalar_tests() {
        let mut r = rng(11);
        let mut checked = 0;
        for round in 0..400 {
            let scale = [1e-3f32, 1.0, 3e3][round % 3];
            let mut v = || Vec3::new(r() * 4.0 - 2.0, r() * 2.0 - 1.0, r() * 4.0 - 2.0) * scale;
            let mut corners: [[Vec3; 3]; 4] = std::array::from_fn(|_| [v(), v(), v()]);
            let mut b = [[0.0f32; 3]; 4];
            let mut dir = [Vec3::ZERO; 4];
            let mut kd = [[0.0f32; 3]; 4];
            for k in 0..4 {
                if (round + k) % 7 == 0 {
                    // Collinear corners: no geometric normal.
                    corners[k][2] = corners[k][0] + (corners[k][1] - corners[k][0]) * 0.5;
                }
                b[k] = if (round + k) % 5 == 0 {
                    [0.0, 1.0, 0.0]
                } else {
                    let (b1, b2) = (r() * 0.5, r() * 0.5);
                    [1.0 - b1 - b2, b1, b2]
                };
                dir[k] = Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5);
                kd[k] = [r(), r(), r()];
            }
            let hits: [FlatHit<'_>; 4] = std::array::from_fn(|k| FlatHit {
                corners: &corners[k],
                b: &b[k],
                dir: &dir[k],
                kd: kd[k],
            });
            let first = surface_point(corners[0], b[0], dir[0], None, [1.0; 3]);
            let lights = [
                Light::Point {
                    position: DVec3::new(0.3, 4.0, -0.2) * f64::from(scale),
                    intensity: [5.0; 3],
                },
                Light::Directional {
                    direction: DVec3::new(0.1, -1.0, 0.2).normalize(),
                    irradiance: [0.5, 1.0, 2.0],
                },
                Light::Point {
                    position: DVec3::new(-1.7, -2.5, 1.1) * f64::from(scale),
                    intensity: [3.0, 7.0, 3.0],
                },
                // At the first hit's point exactly (no incidence there).
                Light::Point {
                    position: first.p.as_dvec3(),
                    intensity: [1.0; 3],
                },
            ];
            let mut expected = Vec::new();
            for (k, h) in hits.iter().enumerate() {
                let sp = surface_point(*h.corners, *h.b, *h.dir, None, h.kd);
                for (l, light) in lights.iter().enumerate() {
                    if let Some(t) = shadow_test(&sp, light) {
                        expected.push((k, l, bits(&t)));
                    }
                }
            }
            let mut lanes = Vec::new();
            FlatShader::default()
                .shadow_tests4(&hits, &lights, |k, l, t| lanes.push((k, l, bits(&t))));
            assert_eq!(lanes, expected, "round {round}");
            assert!(!lanes.iter().any(|&(k, l, _)| k == 0 && l == 3));
            checked += expected.len();
        }
        assert!(checked > 2000, "{checked} tests");
    }
}
