//! The centripetal Catmull-Rom segment (alpha 0.5) of a keyframed camera path, in the
//! Barry-Goldman pyramid form, clamped into the bounds of its two keys. Only `+`, `-`, `*`, `/`
//! and `sqrt` (correctly rounded everywhere; no fused multiply-add), so every machine computes
//! the same bits.

use glam::DVec3;

/// The point at parameter `u` in (0, 1) of the segment from `p1` to `p2` of the centripetal
/// Catmull-Rom spline through `p0, p1, p2, p3`, each coordinate clamped into the bounds of `p1`
/// and `p2` (so the path never overshoots its keys). A missing end neighbour (`None`) is the
/// reflection of the segment's far key through its near key (`2 p1 - p2`, `2 p2 - p1`). When
/// two consecutive points coincide (a zero knot interval), or the spline is not finite, the
/// segment is the straight line from `p1` to `p2`.
pub(super) fn clamped_segment(
    p0: Option<DVec3>,
    p1: DVec3,
    p2: DVec3,
    p3: Option<DVec3>,
    u: f64,
) -> DVec3 {
    let lo = p1.min(p2);
    let hi = p1.max(p2);
    unclamped_segment(p0, p1, p2, p3, u).max(lo).min(hi)
}

/// [`clamped_segment`] before the clamping: the spline itself, or the straight line where it
/// has no knots.
pub(super) fn unclamped_segment(
    p0: Option<DVec3>,
    p1: DVec3,
    p2: DVec3,
    p3: Option<DVec3>,
    u: f64,
) -> DVec3 {
    let linear = p1 + (p2 - p1) * u;
    let p0 = p0.unwrap_or(p1 * 2.0 - p2);
    let p3 = p3.unwrap_or(p2 * 2.0 - p1);
    // Knot intervals |p_{k+1} - p_k|^0.5: the fourth root of the squared distance.
    let interval = |a: DVec3, b: DVec3| {
        let d = b - a;
        (d.x * d.x + d.y * d.y + d.z * d.z).sqrt().sqrt()
    };
    let (d01, d12, d23) = (interval(p0, p1), interval(p1, p2), interval(p2, p3));
    let usable = |d: f64| d > 0.0 && d.is_finite();
    if !(usable(d01) && usable(d12) && usable(d23)) {
        return linear;
    }
    let t0 = 0.0;
    let t1 = d01;
    let t2 = t1 + d12;
    let t3 = t2 + d23;
    let t = t1 + d12 * u;
    // The weighted sum (tb - t)/(tb - ta) a + (t - ta)/(tb - ta) b.
    let mix = |a: DVec3, b: DVec3, ta: f64, tb: f64| {
        let span = tb - ta;
        a * ((tb - t) / span) + b * ((t - ta) / span)
    };
    let a1 = mix(p0, p1, t0, t1);
    let a2 = mix(p1, p2, t1, t2);
    let a3 = mix(p2, p3, t2, t3);
    let b1 = mix(a1, a2, t0, t2);
    let b2 = mix(a2, a3, t1, t3);
    let c = mix(b1, b2, t1, t2);
    if c.is_finite() { c } else { linear }
}
