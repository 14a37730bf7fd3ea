//! Can any camera ray of a pixel span meet a box? A conservative test on the span's pyramid of
//! rays (apex at the eye, through the corners of the span's bounding rectangle on the image):
//! `false` only when every corner of the box lies clearly outside one side of the pyramid, with a
//! relative margin far above the rounding of f32 rays. CastMap pairs that fail it are skipped,
//! which cannot change any hit.

use super::plan::Span;
use crate::bvh::Aabb;
use crate::camera::Camera;
use glam::DVec3;

/// Relative slack of the side-plane test (f32 rays are accurate to ~1e-7).
const MARGIN: f64 = 1e-5;
/// Widening of the span's image rectangle, in pixels.
const WIDEN: f64 = 0.01;

/// Whether some ray of `span` (any sample position inside its pixels) may meet `b`.
pub fn span_may_meet_box(camera: &Camera, width: u32, span: &Span, b: &Aabb) -> bool {
    if span.end <= span.start {
        return false;
    }
    let w = u64::from(width);
    let (y0, y1) = (span.start / w, (span.end - 1) / w);
    let (x0, x1) = if y0 == y1 {
        (span.start % w, (span.end - 1) % w + 1)
    } else {
        (0, w)
    };
    let (xa, xb) = (x0 as f64 - WIDEN, x1 as f64 + WIDEN);
    let (ya, yb) = (y0 as f64 - WIDEN, (y1 + 1) as f64 + WIDEN);
    let corners = [
        camera.direction(xa, ya),
        camera.direction(xb, ya),
        camera.direction(xb, yb),
        camera.direction(xa, yb),
    ];
    let centre = camera.direction((xa + xb) / 2.0, (ya + yb) / 2.0);
    let eye = camera.eye();
    let box_corners: Vec<DVec3> = (0..8)
        .map(|i| {
            let pick = |bit: usize, axis: usize| {
                f64::from(if i & bit == 0 { b.lo[axis] } else { b.hi[axis] })
            };
            DVec3::new(pick(1, 0), pick(2, 1), pick(4, 2))
        })
        .collect();
    for i in 0..4 {
        let mut n = corners[i].cross(corners[(i + 1) % 4]);
        if n.dot(centre) < 0.0 {
            n = -n;
        }
        let scale = n.length() * MARGIN;
        let all_outside = box_corners.iter().all(|q| {
            let v = *q - eye;
            n.dot(v) < -scale * (v.length() + eye.length())
        });
        if all_outside {
            return false;
        }
    }
    true
}
