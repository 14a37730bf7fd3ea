//! Hits shaded `N` at a time, one hit per lane ([`super::array_lanes`], vectorized for the
//! calling code's instruction set; the renderer takes sixteen): their [`super::surface_point`]s
//! and every light's [`super::shadow_test`], handed over light by light as lanes
//! ([`TestLanes`]). Both take each hit's reflectance at the hit (a texture is looked up per hit
//! before). [`flat_test_lanes`] takes hits on flat triangles (no vertex normals);
//! [`smooth_test_lanes`] any hits, with their triangles' vertex normals (zeros for a flat one,
//! which give the flat lanes' tests): the shading normal and Hanika's shadow point
//! (`smooth_lanes`) are lanes too. Each lane performs the scalar code's IEEE operations in its
//! order (glam's `dot`, `cross` and `normalize_or_zero` spelled out; a point light's incidence
//! in f64 as [`super::incidence`]), so each lane's test is the scalar test bit for bit, at
//! every width. What branches per lane runs in lanes too: the rounding of the shadow origin
//! away from the surface is integer arithmetic on the bits ([`F32s::round_away`]), and a
//! light's side and incidence become lane masks. The tests leave in lanes too: the renderer
//! stores a light's segments a coordinate at a time
//! ([`crate::bvh::SegmentColumns::push_lanes`]).

use super::array_lanes::{F32s, F64s, Mask, three};
use super::lanes::point_incidence_lanes;
use super::{incidence, shadow_ray};
use crate::bvh::{CornerLanes, first_bits};
use crate::scene::Light;
use crate::triangle::gamma;
use glam::Vec3;

/// What shading needs of `N` hits, lane by lane (hit k in lane k): the triangles' corners,
/// the hits' barycentrics, the rays' directions, the diffuse reflectances and, for
/// [`smooth_test_lanes`], the triangles' vertex normals (zeros for a flat triangle). The
/// renderer fills it hit by hit where the hits and rays keep the values
/// ([`HitLanes::set_corners`], [`HitLanes::set_ray`], [`HitLanes::set_kd`]), or a triangle's
/// values into every lane at once ([`HitLanes::set_triangle`], [`HitLanes::set_kd_all`]) when
/// all its hits are on one, and the lanes read each array whole.
#[derive(Clone, Copy, Debug)]
pub struct HitLanes<const N: usize> {
    /// `corners[c][axis][k]`: corner c of hit k's triangle.
    corners: [[[f32; N]; 3]; 3],
    /// `b[c][k]`: hit k's barycentric weight of corner c.
    b: [[f32; N]; 3],
    /// `dir[axis][k]`: hit k's ray direction.
    dir: [[f32; N]; 3],
    /// `kd[channel][k]`: hit k's reflectance.
    kd: [[f32; N]; 3],
    /// `normals[c][axis][k]`: the vertex normal at corner c of hit k's triangle.
    normals: [[[f32; N]; 3]; 3],
}

impl<const N: usize> Default for HitLanes<N> {
    fn default() -> Self {
        HitLanes {
            corners: [[[0.0; N]; 3]; 3],
            b: [[0.0; N]; 3],
            dir: [[0.0; N]; 3],
            kd: [[0.0; N]; 3],
            normals: [[[0.0; N]; 3]; 3],
        }
    }
}

impl<const N: usize> HitLanes<N> {
    /// Lane `k`'s triangle has `corners`. Panics unless `k < N`.
    #[inline(always)]
    pub fn set_corners(&mut self, k: usize, corners: CornerLanes<'_>) {
        for c in 0..3 {
            let corner = corners.corner(c);
            for a in 0..3 {
                self.corners[c][a][k] = corner[a];
            }
        }
    }

    /// Every lane's triangle has `corners` and vertex `normals` (zeros for a flat
    /// triangle): what [`Self::set_corners`] and [`Self::set_normals`] write lane by lane.
    #[inline(always)]
    pub fn set_triangle(&mut self, corners: CornerLanes<'_>, normals: &[Vec3; 3]) {
        for (c, normal) in normals.iter().enumerate() {
            let corner = corners.corner(c);
            for a in 0..3 {
                self.corners[c][a] = [corner[a]; N];
                self.normals[c][a] = [normal[a]; N];
            }
        }
    }

    /// Lane `k`'s hit is at barycentrics `b` along `dir`. Panics unless `k < N`.
    #[inline(always)]
    pub fn set_ray(&mut self, k: usize, b: &[f32; 3], dir: &Vec3) {
        for c in 0..3 {
            self.b[c][k] = b[c];
            self.dir[c][k] = dir[c];
        }
    }

    /// Lane `k`'s hit is along `dir`. Panics unless `k < N`.
    #[inline(always)]
    pub fn set_dir(&mut self, k: usize, dir: &Vec3) {
        for c in 0..3 {
            self.dir[c][k] = dir[c];
        }
    }

    /// Every lane's barycentrics: `b[c][k]` is lane k's weight of corner c.
    #[inline(always)]
    pub fn set_b_lanes(&mut self, b: [&[f32; N]; 3]) {
        for (lanes, b) in self.b.iter_mut().zip(b) {
            *lanes = *b;
        }
    }

    /// Lane `k`'s reflectance at its hit is `kd`. Panics unless `k < N`.
    #[inline(always)]
    pub fn set_kd(&mut self, k: usize, kd: [f32; 3]) {
        for (lanes, kd) in self.kd.iter_mut().zip(kd) {
            lanes[k] = kd;
        }
    }

    /// Lane `k`'s reflectance is `kd[channel][k]`, for every lane.
    #[inline(always)]
    pub fn set_kd_lanes(&mut self, kd: [[f32; N]; 3]) {
        self.kd = kd;
    }

    /// The lanes' barycentrics: `b()[c][k]` is hit k's weight of corner c.
    #[inline(always)]
    pub fn b(&self) -> &[[f32; N]; 3] {
        &self.b
    }

    /// Every lane's reflectance is `kd`.
    #[inline(always)]
    pub fn set_kd_all(&mut self, kd: [f32; 3]) {
        self.kd = three(kd, |kd| [kd; N]);
    }

    /// Lane `k`'s vertex normals: zeros for a flat triangle. Panics unless `k < N`.
    #[inline(always)]
    pub fn set_normals(&mut self, k: usize, normals: &[Vec3; 3]) {
        for (lanes, normal) in self.normals.iter_mut().zip(normals) {
            for (lanes, x) in lanes.iter_mut().zip(normal.to_array()) {
                lanes[k] = x;
            }
        }
    }

    /// Every lane's vertex normals zeros.
    #[inline(always)]
    pub fn clear_normals(&mut self) {
        self.normals = [[[0.0; N]; 3]; 3];
    }

    /// Corner `c` of every lane's triangle.
    #[inline(always)]
    fn corner(&self, c: usize) -> Vec3s<N> {
        Vec3s::of_axes(&self.corners[c])
    }
}

/// Three axes of `N` lanes: glam's `Vec3` operations lane by lane, in glam's order.
#[derive(Clone, Copy)]
struct Vec3s<const N: usize> {
    x: F32s<N>,
    y: F32s<N>,
    z: F32s<N>,
}

impl<const N: usize> Vec3s<N> {
    /// Lanes from each axis's values.
    #[inline(always)]
    fn of_axes(v: &[[f32; N]; 3]) -> Self {
        Vec3s {
            x: F32s(v[0]),
            y: F32s(v[1]),
            z: F32s(v[2]),
        }
    }

    /// `v` in every lane.
    #[inline(always)]
    fn splat(v: Vec3) -> Self {
        Vec3s {
            x: F32s::splat(v.x),
            y: F32s::splat(v.y),
            z: F32s::splat(v.z),
        }
    }

    /// `s * v` (each axis times its lane of `s`).
    #[inline(always)]
    fn scale(self, s: F32s<N>) -> Self {
        Vec3s {
            x: s * self.x,
            y: s * self.y,
            z: s * self.z,
        }
    }

    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Vec3s {
            x: self.x + o.x,
            y: self.y + o.y,
            z: self.z + o.z,
        }
    }

    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Vec3s {
            x: self.x - o.x,
            y: self.y - o.y,
            z: self.z - o.z,
        }
    }

    #[inline(always)]
    fn abs(self) -> Self {
        Vec3s {
            x: self.x.abs(),
            y: self.y.abs(),
            z: self.z.abs(),
        }
    }

    /// glam's `dot`: `(x·x' + y·y') + z·z'`.
    #[inline(always)]
    fn dot(self, o: Self) -> F32s<N> {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// glam's `cross`.
    #[inline(always)]
    fn cross(self, o: Self) -> Self {
        Vec3s {
            x: self.y * o.z - o.y * self.z,
            y: self.z * o.x - o.z * self.x,
            z: self.x * o.y - o.x * self.y,
        }
    }

    /// glam's `normalize_or_zero`: `v · (1 / sqrt(v·v))` where that reciprocal is finite and
    /// positive, else zero.
    #[inline(always)]
    fn normalize_or_zero(self) -> Self {
        let rcp = F32s::splat(1.0) / self.dot(self).sqrt();
        let ok = rcp.positive_finite();
        self.scale(rcp).keep(ok)
    }

    /// Set in the lanes where every axis is zero (either sign), as `v == Vec3::ZERO`.
    #[inline(always)]
    fn is_zero(&self) -> Mask<N> {
        let zero = F32s::ZERO;
        self.x.eq(zero).and(self.y.eq(zero)).and(self.z.eq(zero))
    }

    /// `v` where `mask` is set, +0 elsewhere.
    #[inline(always)]
    fn keep(self, mask: Mask<N>) -> Self {
        Vec3s {
            x: mask.keep(self.x),
            y: mask.keep(self.y),
            z: mask.keep(self.z),
        }
    }

    /// `a` where `mask` is set, else `b`.
    #[inline(always)]
    fn choose(mask: Mask<N>, a: Self, b: Self) -> Self {
        Vec3s {
            x: mask.select(a.x, b.x),
            y: mask.select(a.y, b.y),
            z: mask.select(a.z, b.z),
        }
    }

    /// `-v` where `flip` is set (the sign bit flipped, as scalar negation does).
    #[inline(always)]
    fn negate_where(self, flip: Mask<N>) -> Self {
        Vec3s {
            x: self.x.negate_where(flip),
            y: self.y.negate_where(flip),
            z: self.z.negate_where(flip),
        }
    }
}

/// One light's shadow tests at `N` hits, lane by lane: in `lit` bit k whether hit k has a
/// test (an incidence, and the light on the normal's side); lane k of the others is hit k's
/// test, when it has one: its segment's origin and direction, and the radiance it adds when
/// unblocked. Every segment ends at `t_max`.
#[derive(Clone, Copy, Debug)]
pub struct TestLanes<const N: usize> {
    /// Bit k: hit k has a test.
    pub lit: u32,
    /// The segments' origins, axis by axis.
    pub origin: [[f32; N]; 3],
    /// The segments' directions, axis by axis.
    pub dir: [[f32; N]; 3],
    /// Where every segment ends.
    pub t_max: f32,
    /// The radiance of each test when unblocked, channel by channel.
    pub unoccluded: [[f32; N]; 3],
}

impl<const N: usize> TestLanes<N> {
    /// As [`super::shadow_test_at`] of a flat surface point, lane by lane: the light's
    /// incidence at `p`, the cosine with the normal `n`, the segment from `origin` and the
    /// radiance with reflectances `kd` (channel by channel).
    #[inline(always)]
    fn new(
        light: &Light,
        p: &Vec3s<N>,
        n: &Vec3s<N>,
        origin: &Vec3s<N>,
        kd: &[F32s<N>; 3],
    ) -> Self {
        let all = first_bits(N);
        let (to_light, irradiance, valid) = match *light {
            Light::Point {
                position,
                intensity,
            } => {
                let i = point_incidence_lanes(position, intensity, [p.x, p.y, p.z]);
                let [x, y, z] = i.to_light;
                (Vec3s { x, y, z }, i.irradiance, i.valid)
            }
            Light::Directional { .. } => {
                // The same incidence at every point.
                let i = incidence(Vec3::ZERO, light).expect("a directional light reaches all");
                let e = three(i.irradiance, F32s::splat);
                (Vec3s::splat(i.to_light), e, all)
            }
        };
        let cos = n.dot(to_light);
        // `cos <= 0` has no test; a NaN has one, as in the scalar test.
        let lit = valid & !cos.le(F32s::ZERO).to_bits() & all;
        let (dir, t_max) = shadow_rays(light, origin);
        // As `unoccluded_radiance`: kd · (cos/pi) · E.
        let f = F32s::splat(std::f32::consts::FRAC_1_PI) * cos;
        let radiance = |c: usize| (kd[c] * f * irradiance[c]).0;
        TestLanes {
            lit,
            origin: [origin.x.0, origin.y.0, origin.z.0],
            dir: [dir.x.0, dir.y.0, dir.z.0],
            t_max,
            unoccluded: [radiance(0), radiance(1), radiance(2)],
        }
    }

    /// Hit `k`'s radiance when its segment is unblocked (when bit k of `lit` is set).
    #[inline(always)]
    pub fn unoccluded(&self, k: usize) -> [f32; 3] {
        [
            self.unoccluded[0][k],
            self.unoccluded[1][k],
            self.unoccluded[2][k],
        ]
    }
}

/// [`shadow_ray`]'s direction and `t_max` from each of the `origins`, lane by lane.
#[inline(always)]
fn shadow_rays<const N: usize>(light: &Light, origins: &Vec3s<N>) -> (Vec3s<N>, f32) {
    // The segment from the origin: the same `t_max` from every origin.
    let (from_origin, t_max) = shadow_ray(light, Vec3::ZERO);
    let dir = match *light {
        Light::Point { position, .. } => {
            // As `(position - origin.as_dvec3()).as_vec3()`: exact widening, one f64
            // subtraction, one rounding.
            let axis = |a: usize, o: F32s<N>| (F64s::splat(position[a]) - o.widen()).narrow();
            Vec3s {
                x: axis(0, origins.x),
                y: axis(1, origins.y),
                z: axis(2, origins.z),
            }
        }
        Light::Directional { .. } => Vec3s::splat(from_origin.dir),
    };
    (dir, t_max)
}

/// Every light's [`super::shadow_test`] at the [`super::surface_point`] of each of the `N` hits
/// of `hits`, all on flat triangles (their normals are not read; each hit's `kd` is its
/// reflectance at the hit, textured or not), handed to `visit(light, tests)` light by light, in
/// light order: lane k of `tests` is hit k's test where its bit of `tests.lit` is set, exactly
/// the test [`super::shadow_tests`] gives that surface point and light.
#[inline(always)]
pub fn flat_test_lanes<const N: usize>(
    hits: &HitLanes<N>,
    lights: &[Light],
    visit: impl FnMut(usize, &TestLanes<N>),
) {
    test_lanes(hits, false, lights, visit);
}

/// [`flat_test_lanes`] of `N` hits on any triangles, with their vertex normals (zeros for a
/// flat one); each hit's `kd` is its reflectance at the hit (textured or not).
#[inline(always)]
pub fn smooth_test_lanes<const N: usize>(
    hits: &HitLanes<N>,
    lights: &[Light],
    visit: impl FnMut(usize, &TestLanes<N>),
) {
    test_lanes(hits, true, lights, visit);
}

#[inline(always)]
fn test_lanes<const N: usize>(
    hits: &HitLanes<N>,
    smooth: bool,
    lights: &[Light],
    mut visit: impl FnMut(usize, &TestLanes<N>),
) {
    const { assert!(N > 0 && N <= 32, "1 to 32 lanes") };
    let corners = [hits.corner(0), hits.corner(1), hits.corner(2)];
    let [p0, p1, p2] = corners;
    let b = three(hits.b, F32s);
    let (w0, w1, w2) = (p0.scale(b[0]), p1.scale(b[1]), p2.scale(b[2]));
    // As `surface_point`: p, its error bound, and the geometric normal facing the ray.
    let p = w0.add(w1).add(w2);
    let p_error = w0
        .abs()
        .add(w1.abs())
        .add(w2.abs())
        .scale(F32s::splat(gamma(7.0)));
    let n_geo = p1.sub(p0).cross(p2.sub(p0)).normalize_or_zero();
    let dir = Vec3s::of_axes(&hits.dir);
    let n = n_geo.negate_where(n_geo.dot(dir).gt(F32s::ZERO));
    // The shading normal and where shadow rays start: on a flat triangle the geometric
    // normal and p.
    let (n_shade, p_shadow, p_shadow_error) = if smooth {
        let normals = three(hits.normals, |n| Vec3s::of_axes(&n));
        smooth_lanes(normals, (corners, b), n, (p, p_error))
    } else {
        (n, p, p_error)
    };
    // As `offset_origin(p_shadow, p_shadow_error, n, n)`: n·n is never below zero, so the
    // offset keeps its side, and the origin is rounded away from the surface along it.
    let offset = n.scale(n.abs().dot(p_shadow_error));
    let moved = p_shadow.add(offset);
    let origin = Vec3s {
        x: moved.x.round_away(offset.x),
        y: moved.y.round_away(offset.y),
        z: moved.z.round_away(offset.z),
    };
    let kd = three(hits.kd, F32s);
    for (l, light) in lights.iter().enumerate() {
        visit(l, &TestLanes::new(light, &p, &n_shade, &origin, &kd));
    }
}

/// As the vertex-normal branch of [`super::surface_point_on`], lane by lane: the shading
/// normal (the barycentric blend of the vertex `normals`, normalised and turned to the side of
/// `n_geo`, the geometric normal facing the ray) and Hanika's shadow point with its error
/// bound ([`super::shadow_point`]), from the triangles' `corners`, the barycentrics `b` and the
/// hit point `p` with its bound. Lanes whose blended normal is zero keep `(n_geo, p, p_error)`.
#[inline(always)]
fn smooth_lanes<const N: usize>(
    normals: [Vec3s<N>; 3],
    (corners, b): ([Vec3s<N>; 3], [F32s<N>; 3]),
    n_geo: Vec3s<N>,
    (p, p_error): (Vec3s<N>, Vec3s<N>),
) -> (Vec3s<N>, Vec3s<N>, Vec3s<N>) {
    let zero = F32s::ZERO;
    let [n0, n1, n2] = normals;
    let n = n0
        .scale(b[0])
        .add(n1.scale(b[1]))
        .add(n2.scale(b[2]))
        .normalize_or_zero();
    let none = n.is_zero();
    // The normal and the vertex normals turned to n_geo's side (a negated unit vector is the
    // unit vector of the negated one, bit for bit).
    let flip = n.dot(n_geo).lt(zero);
    let n = n.negate_where(flip);
    // Spelled out: a closure this large is not inlined, and then runs in the baseline's
    // instructions.
    let [u0, u1, u2] = normals;
    let units = [
        u0.normalize_or_zero().negate_where(flip),
        u1.normalize_or_zero().negate_where(flip),
        u2.normalize_or_zero().negate_where(flip),
    ];
    // As `shadow_point_unit`: each vertex plane above p (its normal not within
    // MIN_NORMAL_COS of the triangle's plane) lifts p by its weight; where a term is not
    // taken, +0 is added, which leaves a sum that starts at +0 as it is.
    let (mut offset, mut magnitude) = (Vec3s::splat(Vec3::ZERO), Vec3s::splat(Vec3::ZERO));
    for (i, unit) in units.iter().enumerate() {
        let facing = unit.dot(n_geo).ge(F32s::splat(super::MIN_NORMAL_COS));
        let height = p.sub(corners[i]).dot(*unit);
        let below = height.lt(zero);
        // `b.max(0.0)`: zero for a NaN (the sign of a zero weight never reaches the sums).
        let weight = b[i].gt(zero).select(b[i], zero);
        let term = unit.scale(weight * -height);
        let take = facing.and(below);
        offset = offset.add(term.keep(take));
        magnitude = magnitude.add(term.abs().keep(take));
    }
    let q = p.add(offset);
    let error = p_error
        .add(q.abs().scale(F32s::splat(gamma(2.0))))
        .add(magnitude.scale(F32s::splat(gamma(4.0))))
        .scale(F32s::splat(1.0 + gamma(4.0)));
    let lifted = magnitude.is_zero().not().and(none.not());
    (
        Vec3s::choose(none, n_geo, n),
        Vec3s::choose(lifted, q, p),
        Vec3s::choose(lifted, error, p_error),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shading::tests::rng;
    use crate::shading::{ShadowTest, shadow_test, surface_point};
    use crate::triangle::Ray;
    use glam::DVec3;

    /// Hit `k`'s test in `lanes` (when bit k of `lit` is set).
    fn test_of<const N: usize>(lanes: &TestLanes<N>, k: usize) -> ShadowTest {
        let at = |v: &[[f32; N]; 3]| Vec3::new(v[0][k], v[1][k], v[2][k]);
        ShadowTest {
            ray: Ray {
                origin: at(&lanes.origin),
                dir: at(&lanes.dir),
            },
            t_max: lanes.t_max,
            unoccluded: lanes.unoccluded(k),
        }
    }

    /// Each test's bits: origin, direction, t_max, radiance.
    fn bits(t: &ShadowTest) -> Vec<u32> {
        let mut b = t.ray.origin.to_array().to_vec();
        b.extend(t.ray.dir.to_array());
        b.push(t.t_max);
        b.extend(t.unoccluded);
        b.into_iter().map(f32::to_bits).collect()
    }

    /// (hit, light, test bits).
    type Tests = Vec<(usize, usize, Vec<u32>)>;

    /// Hits tested together in a round.
    const HITS: usize = 16;

    /// One hit: its triangle's corners (where a BVH keeps them), barycentrics, ray direction
    /// and reflectance.
    #[derive(Clone, Copy)]
    struct TestHit<'a> {
        corners: CornerLanes<'a>,
        b: &'a [f32; 3],
        dir: &'a Vec3,
        kd: [f32; 3],
    }

    /// Shading lanes of one group: `(hits, smooth, visit)`, as [`test_lanes`] takes them.
    type Group<'l, const N: usize> =
        &'l dyn Fn(&HitLanes<N>, bool, &mut dyn FnMut(usize, &TestLanes<N>));

    /// The tests of [`HITS`] hits (with their vertex `normals`, if smooth) in lanes of `N`,
    /// group by group through `group`, as (hit, light, test bits) hit by hit, then light by
    /// light: the order of [`crate::shading::shadow_tests`].
    fn in_groups<const N: usize>(
        hits: &[TestHit<'_>; HITS],
        normals: Option<&[[Vec3; 3]; HITS]>,
        group: Group<'_, N>,
    ) -> Tests {
        let mut tests = Vec::new();
        for from in (0..HITS).step_by(N) {
            let mut lanes = HitLanes::<N>::default();
            for k in 0..N {
                let h = hits[from + k];
                lanes.set_corners(k, h.corners);
                lanes.set_ray(k, h.b, h.dir);
                lanes.set_kd(k, h.kd);
                if let Some(normals) = normals {
                    lanes.set_normals(k, &normals[from + k]);
                }
            }
            let mut found = Vec::new();
            group(&lanes, normals.is_some(), &mut |l, t| found.push((l, *t)));
            for k in 0..N {
                for (l, lanes) in &found {
                    if lanes.lit & (1 << k) != 0 {
                        tests.push((from + k, *l, bits(&test_of(lanes, k))));
                    }
                }
            }
        }
        tests
    }

    /// The tests of `hits` (with `normals`, if smooth) under `lights` at 4, 8 and 16 lanes,
    /// and at 16 compiled for every instruction set the host has, each equal to `expected`.
    fn assert_every_width(
        hits: &[TestHit<'_>; HITS],
        normals: Option<&[[Vec3; 3]; HITS]>,
        lights: &[Light],
        expected: &Tests,
        context: &str,
    ) {
        let (four, eight, sixteen): (Group<4>, Group<8>, Group<16>) = (
            &|h, smooth, v| test_lanes(h, smooth, lights, v),
            &|h, smooth, v| test_lanes(h, smooth, lights, v),
            &|h, smooth, v| test_lanes(h, smooth, lights, v),
        );
        assert_eq!(
            &in_groups(hits, normals, four),
            expected,
            "{context}, 4 lanes"
        );
        assert_eq!(
            &in_groups(hits, normals, eight),
            expected,
            "{context}, 8 lanes"
        );
        assert_eq!(
            &in_groups(hits, normals, sixteen),
            expected,
            "{context}, 16 lanes"
        );
        #[cfg(target_arch = "x86_64")]
        #[allow(unsafe_code)]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the host has AVX2.
                let avx2: Group<16> = &|h, smooth, v| unsafe { avx2_lanes(h, smooth, lights, v) };
                assert_eq!(&in_groups(hits, normals, avx2), expected, "{context}, AVX2");
            }
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the host has AVX-512F.
                let avx512: Group<16> =
                    &|h, smooth, v| unsafe { avx512_lanes(h, smooth, lights, v) };
                assert_eq!(
                    &in_groups(hits, normals, avx512),
                    expected,
                    "{context}, AVX-512"
                );
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn avx2_lanes(
        hits: &HitLanes<16>,
        smooth: bool,
        lights: &[Light],
        visit: &mut dyn FnMut(usize, &TestLanes<16>),
    ) {
        test_lanes(hits, smooth, lights, visit);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn avx512_lanes(
        hits: &HitLanes<16>,
        smooth: bool,
        lights: &[Light],
        visit: &mut dyn FnMut(usize, &TestLanes<16>),
    ) {
        test_lanes(hits, smooth, lights, visit);
    }

    /// The corners of triangles four by four in the lanes of one array each, as a BVH keeps
    /// them.
    fn in_lanes(corners: &[[Vec3; 3]; HITS]) -> [[[[f32; 4]; 3]; 3]; HITS / 4] {
        let mut v = [[[[0.0f32; 4]; 3]; 3]; HITS / 4];
        for (i, tri) in corners.iter().enumerate() {
            for (c, corner) in tri.iter().enumerate() {
                for a in 0..3 {
                    v[i / 4][c][a][i % 4] = corner[a];
                }
            }
        }
        v
    }

    /// Hit k on triangle k of `v` ([`in_lanes`]), at barycentrics `b[k]`, along `dir[k]`,
    /// with reflectance `kd[k]`.
    fn lane_hits<'a>(
        v: &'a [[[[f32; 4]; 3]; 3]; HITS / 4],
        b: &'a [[f32; 3]; HITS],
        dir: &'a [Vec3; HITS],
        kd: [[f32; 3]; HITS],
    ) -> [TestHit<'a>; HITS] {
        std::array::from_fn(|k| TestHit {
            corners: CornerLanes::new(&v[k / 4], k % 4),
            b: &b[k],
            dir: &dir[k],
            kd: kd[k],
        })
    }

    /// The tests of light `l` among `expected` (hit, light, test bits), as the tests of a
    /// scene with that light alone.
    fn alone(expected: &[(usize, usize, Vec<u32>)], l: usize) -> Vec<(usize, usize, Vec<u32>)> {
        let of_l = expected.iter().filter(|(_, light, _)| *light == l);
        of_l.map(|(k, _, t)| (*k, 0, t.clone())).collect()
    }

    /// Two point lights (one grey, one coloured) at `scale` and a directional light.
    fn three_lights(scale: f32) -> [Light; 3] {
        [
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
        ]
    }

    /// Every value of `lanes`, as bits, in field order.
    fn lane_bits<const N: usize>(lanes: &HitLanes<N>) -> Vec<u32> {
        let HitLanes {
            corners,
            b,
            dir,
            kd,
            normals,
        } = lanes;
        let axes = [corners, normals].into_iter().flatten().flatten();
        let values = axes.chain([b, dir, kd].into_iter().flatten());
        values.flatten().map(|x| x.to_bits()).collect()
    }

    /// One triangle's corners, normals and reflectance written to every lane at once are
    /// what writing them lane by lane gives, bit for bit (a negative zero included).
    #[test]
    fn one_triangle_in_every_lane_is_the_lane_by_lane_lanes() {
        let mut r = rng(5);
        for round in 0..20 {
            let mut v = || Vec3::new(r() - 0.5, r() - 0.5, -r());
            let corners: [[Vec3; 3]; HITS] = [[v(), v(), v()]; HITS];
            let dir: [Vec3; HITS] = std::array::from_fn(|_| v());
            let normals = match round % 3 {
                0 => [Vec3::ZERO; 3],
                1 => [Vec3::new(-0.0, 1.0, 0.0), dir[0], dir[1]],
                _ => [dir[2], dir[3], dir[4]],
            };
            let kd = [r(), -0.0, r()];
            let b: [[f32; 3]; HITS] = std::array::from_fn(|_| [r(), r(), r()]);
            let v = in_lanes(&corners);
            let hits = lane_hits(&v, &b, &dir, [kd; HITS]);
            let mut at_once = HitLanes::<HITS>::default();
            at_once.set_triangle(hits[0].corners, &normals);
            at_once.set_kd_all(kd);
            let mut lane_by_lane = HitLanes::<HITS>::default();
            for (k, h) in hits.iter().enumerate() {
                at_once.set_ray(k, h.b, h.dir);
                lane_by_lane.set_corners(k, h.corners);
                lane_by_lane.set_normals(k, &normals);
                lane_by_lane.set_ray(k, h.b, h.dir);
                lane_by_lane.set_kd(k, h.kd);
            }
            assert_eq!(
                lane_bits(&at_once),
                lane_bits(&lane_by_lane),
                "round {round}"
            );
        }
    }

    /// The lanes give, hit by hit and light by light, the scalar surface point's shadow tests
    /// bit for bit, at every width: random triangles at several scales seen from either side,
    /// degenerate ones (no normal), hits on a corner, point lights (one at a hit point, grey
    /// and coloured) and a directional light.
    #[test]
    fn flat_hits_in_lanes_are_the_scalar_tests() {
        let mut r = rng(11);
        let mut checked = 0;
        for round in 0..100 {
            let scale = [1e-3f32, 1.0, 3e3][round % 3];
            let mut v = || Vec3::new(r() * 4.0 - 2.0, r() * 2.0 - 1.0, r() * 4.0 - 2.0) * scale;
            let mut corners: [[Vec3; 3]; HITS] = std::array::from_fn(|_| [v(), v(), v()]);
            let mut b = [[0.0f32; 3]; HITS];
            let mut dir = [Vec3::ZERO; HITS];
            let mut kd = [[0.0f32; 3]; HITS];
            for k in 0..HITS {
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
            let v = in_lanes(&corners);
            let hits = lane_hits(&v, &b, &dir, kd);
            let first = surface_point(corners[0], b[0], dir[0], None, [1.0; 3]);
            let mut lights = three_lights(scale).to_vec();
            // At the first hit's point exactly (no incidence there).
            lights.push(Light::Point {
                position: first.p.as_dvec3(),
                intensity: [1.0; 3],
            });
            let mut expected = Vec::new();
            for (k, h) in hits.iter().enumerate() {
                let sp = surface_point(h.corners.corners(), *h.b, *h.dir, None, h.kd);
                for (l, light) in lights.iter().enumerate() {
                    if let Some(t) = shadow_test(&sp, light) {
                        expected.push((k, l, bits(&t)));
                    }
                }
            }
            assert_every_width(&hits, None, &lights, &expected, &format!("round {round}"));
            assert!(!expected.iter().any(|&(k, l, _)| k == 0 && l == 3));
            // Each light alone (the one-light path).
            for (l, light) in lights.iter().enumerate() {
                let context = format!("round {round}, light {l} alone");
                let light = std::slice::from_ref(light);
                assert_every_width(&hits, None, light, &alone(&expected, l), &context);
            }
            checked += expected.len();
        }
        assert!(checked > 2000, "{checked} tests");
    }

    /// Hits on triangles with vertex normals, in lanes, are the scalar surface points' shadow
    /// tests bit for bit, at every width: normals toward either side of the triangle, of any
    /// length, zero (no shading normal), nearly in the triangle's plane (the shadow point's
    /// cutoff) and one the others cancel; hits on a corner and on an edge; point and
    /// directional lights.
    #[test]
    fn smooth_hits_in_lanes_are_the_scalar_tests() {
        let mut r = rng(23);
        let (mut checked, mut lifted) = (0, 0);
        for round in 0..150 {
            let scale = [1e-3f32, 1.0, 3e3][round % 3];
            let mut v = || Vec3::new(r() * 4.0 - 2.0, r() * 2.0 - 1.0, r() * 4.0 - 2.0) * scale;
            let corners: [[Vec3; 3]; HITS] = std::array::from_fn(|_| [v(), v(), v()]);
            let mut b = [[0.0f32; 3]; HITS];
            let mut dir = [Vec3::ZERO; HITS];
            let mut kd = [[0.0f32; 3]; HITS];
            let mut normals = [[Vec3::ZERO; 3]; HITS];
            for k in 0..HITS {
                b[k] = match (round + k) % 6 {
                    0 => [0.0, 1.0, 0.0],
                    1 => [0.5, 0.0, 0.5],
                    _ => {
                        let (b1, b2) = (r() * 0.5, r() * 0.5);
                        [1.0 - b1 - b2, b1, b2]
                    }
                };
                dir[k] = Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5);
                kd[k] = [r(), r(), r()];
                let [p0, p1, p2] = corners[k];
                let n_geo = (p1 - p0).cross(p2 - p0).normalize_or_zero();
                let mut jitter = || Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5);
                normals[k] = match (round + 2 * k) % 7 {
                    // No shading normal: the flat point.
                    0 => [Vec3::ZERO; 3],
                    // Cancelling: the blend is zero at the centroid-ish hit or nearly.
                    1 => [n_geo, -n_geo, Vec3::ZERO],
                    // Nearly in the plane: below and above MIN_NORMAL_COS.
                    2 => {
                        let t = (p1 - p0).normalize_or_zero();
                        [t + n_geo * 5e-4, t + n_geo * 2e-3, n_geo]
                    }
                    // Toward the far side, long.
                    3 => [
                        -n_geo * 3.0 + jitter() * 0.5,
                        -n_geo + jitter(),
                        -n_geo * 7.0,
                    ],
                    // Smooth, bulging: tilted outward, as a coarse sphere's.
                    _ => [
                        (n_geo + jitter() * 0.8) * 2.0,
                        n_geo + jitter() * 0.8,
                        (n_geo + jitter() * 0.8) * 0.3,
                    ],
                };
            }
            let v = in_lanes(&corners);
            let hits = lane_hits(&v, &b, &dir, kd);
            let lights = three_lights(scale);
            let mut expected = Vec::new();
            for (k, h) in hits.iter().enumerate() {
                let sp = surface_point(h.corners.corners(), *h.b, *h.dir, Some(normals[k]), h.kd);
                lifted += usize::from(sp.p_shadow != sp.p);
                for (l, light) in lights.iter().enumerate() {
                    if let Some(t) = shadow_test(&sp, light) {
                        expected.push((k, l, bits(&t)));
                    }
                }
            }
            let context = format!("round {round}");
            assert_every_width(&hits, Some(&normals), &lights, &expected, &context);
            for (l, light) in lights.iter().enumerate() {
                let context = format!("round {round}, light {l} alone");
                let light = std::slice::from_ref(light);
                assert_every_width(&hits, Some(&normals), light, &alone(&expected, l), &context);
            }
            checked += expected.len();
        }
        assert!(checked > 3000, "{checked} tests");
        assert!(lifted > 300, "shadow points moved off the facet: {lifted}");
    }
}
