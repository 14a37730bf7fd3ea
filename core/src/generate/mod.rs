//! Deterministic synthetic scenes for benchmarks (`hort scene generate`).
//!
//! A scene is a gently undulating ground grid (about 1/8 of the triangles) with many seeded,
//! closed, outward-facing objects scattered over it: 3 to 5 big boulders that give the scene
//! its height, then many displaced "rocks" and smooth ellipsoids of power-law sizes, all
//! tessellated in proportion to their size and partly sunk into the ground so nothing floats.
//! The ground is 100 (x) by 60 (z) centred on the origin, y up; objects reach at most about 30
//! units high, so the bounding box is wide and not tall, and the default framing (eye above and
//! in front, +z) sees depth complexity, occlusion and cast shadows. A flat landscape cannot fill
//! a 16:9 frame under the bounding-sphere framing; this one covers roughly the middle third.
//!
//! Output bytes are a pure function of `(triangles, seed)`: coordinates are computed in f64 with
//! the `libm` crate (no platform libm) and written as f32 with Rust's shortest round-trip
//! `Display`, so every machine writes the same file.

use std::f64::consts::PI;
use std::io::{self, BufWriter, Write};

/// Smallest accepted triangle count.
pub const MIN_TRIANGLES: u64 = 1;
/// Largest accepted triangle count.
pub const MAX_TRIANGLES: u64 = 50_000_000;
/// Extent of the ground along x (across the default view) in scene units.
const WIDTH: f64 = 100.0;
/// Extent of the ground along z (away from the default camera) in scene units.
const DEPTH: f64 = 60.0;
/// Largest object radius before displacement and vertical stretch.
const MAX_RADIUS: f64 = 6.0;
/// Largest radius of the few big boulders.
const BOULDER_RADIUS: f64 = 11.0;
/// Fraction of the ground area covered by objects (sum of pi r^2 over the area).
const COVERAGE: f64 = 0.35;
/// Triangles of the coarsest closed object (a triangular bipyramid).
const MIN_OBJECT_TRIANGLES: u64 = 6;

/// What [`generate_scene`] wrote.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GenerateSummary {
    /// Number of `f` lines (triangles) written; always equal to the requested count.
    pub triangles: u64,
    /// Number of `v` lines written.
    pub vertices: u64,
}

/// Checks that `n` is an accepted triangle count (`1..=50_000_000`); the error says the range.
pub fn check_triangle_count(n: u64) -> Result<(), String> {
    if (MIN_TRIANGLES..=MAX_TRIANGLES).contains(&n) {
        Ok(())
    } else {
        Err(format!(
            "triangle count must be between {MIN_TRIANGLES} and {MAX_TRIANGLES}, got {n}"
        ))
    }
}

/// Writes an OBJ scene with exactly `triangles` faces (`f a b c`, 1-based indices, every index
/// in range), one `o` group per object and the ground last.
///
/// Deterministic: the bytes depend only on `(triangles, seed)`, on every machine; different
/// seeds give different scenes. Streams with memory independent of the scene size (output is
/// buffered internally and flushed before returning). An out-of-range count is an
/// `InvalidInput` error carrying the [`check_triangle_count`] message.
pub fn generate_scene<W: Write>(
    triangles: u64,
    seed: u64,
    out: &mut W,
) -> io::Result<GenerateSummary> {
    check_triangle_count(triangles).map_err(|m| io::Error::new(io::ErrorKind::InvalidInput, m))?;
    let plan = Plan::new(triangles);
    let mut rng = SplitMix64::new(seed ^ triangles.wrapping_mul(0xa076_1d64_78bd_642f));
    let ground = Ground::random(&mut rng);
    let mut obj = ObjWriter {
        out: BufWriter::with_capacity(1 << 16, out),
        vertices: 0,
        faces: 0,
    };
    writeln!(
        obj.out,
        "# HORT synthetic scene: {triangles} triangles, seed {seed}"
    )?;
    let mut budget = triangles - plan.ground_triangles;
    let boulders = 3 + rng.next_u64() % 3;
    let mut index = 0u64;
    while budget >= MIN_OBJECT_TRIANGLES {
        let object = Blob::random(&mut rng, &plan, &ground, budget, index < boulders);
        writeln!(obj.out, "o {}_{index}", object.kind_name())?;
        object.write(&mut obj)?;
        budget -= object.triangles();
        index += 1;
    }
    writeln!(obj.out, "o ground")?;
    let ground_triangles = triangles - obj.faces;
    ground.write(&mut obj, ground_triangles)?;
    obj.out.flush()?;
    Ok(GenerateSummary {
        triangles: obj.faces,
        vertices: obj.vertices,
    })
}

/// splitmix64 (Steele, Lea, Flood 2014): tiny, fast, fully specified.
struct SplitMix64(u64);

impl SplitMix64 {
    fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }

    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1) with 53 random bits.
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    fn unit_vector(&mut self) -> [f64; 3] {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, 2.0 * PI);
        let r = (1.0 - z * z).max(0.0).sqrt();
        [r * libm::cos(phi), z, r * libm::sin(phi)]
    }
}

/// Scene-wide parameters derived from the triangle count alone.
struct Plan {
    ground_triangles: u64,
    mean_object_triangles: f64,
    radius_scale: f64,
}

impl Plan {
    fn new(n: u64) -> Plan {
        let ground_triangles = if n < 64 { n } else { n / 8 };
        let mean = (0.6 * (n as f64).sqrt()).clamp(MIN_OBJECT_TRIANGLES as f64, 20_000.0);
        let objects = ((n - ground_triangles) as f64 / mean).max(1.0);
        // About 35% of the ground covered; 1.46 is E[size^2] of the size distribution.
        let radius_scale = (COVERAGE * WIDTH * DEPTH / (PI * objects * 1.46)).sqrt();
        Plan {
            ground_triangles,
            mean_object_triangles: mean,
            radius_scale,
        }
    }
}

/// Buffered OBJ output that counts what it wrote.
struct ObjWriter<W: Write> {
    out: W,
    vertices: u64,
    faces: u64,
}

impl<W: Write> ObjWriter<W> {
    fn vertex(&mut self, p: [f64; 3]) -> io::Result<()> {
        self.vertices += 1;
        // `+ 0.0` turns -0 into 0 so the text never says "-0".
        let [x, y, z] = p.map(|c| c as f32 + 0.0);
        writeln!(self.out, "v {x} {y} {z}")
    }

    /// A face from 0-based indices relative to `base` (the vertex count before the object).
    fn face(&mut self, base: u64, a: u64, b: u64, c: u64) -> io::Result<()> {
        self.faces += 1;
        writeln!(
            self.out,
            "f {} {} {}",
            base + a + 1,
            base + b + 1,
            base + c + 1
        )
    }
}

/// The ground height field: a gentle product of sines, at most 1.2% of the ground's side.
struct Ground {
    amplitude: f64,
    freq: [f64; 3],
    phase: [f64; 3],
}

impl Ground {
    fn random(rng: &mut SplitMix64) -> Ground {
        let mut wave = || {
            (
                2.0 * PI / (WIDTH * rng.range(0.3, 0.8)),
                rng.range(0.0, 2.0 * PI),
            )
        };
        let (w0, w1, w2) = (wave(), wave(), wave());
        Ground {
            amplitude: 0.008 * WIDTH,
            freq: [w0.0, w1.0, w2.0],
            phase: [w0.1, w1.1, w2.1],
        }
    }

    fn height(&self, x: f64, z: f64) -> f64 {
        let (f, p) = (self.freq, self.phase);
        self.amplitude
            * (libm::sin(x * f[0] + p[0]) * libm::cos(z * f[1] + p[1])
                + 0.5 * libm::sin((x + z) * f[2] + p[2]))
    }

    /// A grid of `count` triangles: full rows of quads from the front (+z) edge backwards, the
    /// last row possibly partial (at the far edge). Normals face +y.
    fn write<W: Write>(&self, obj: &mut ObjWriter<W>, count: u64) -> io::Result<()> {
        let cols = ((count as f64 / 2.0 * WIDTH / DEPTH).sqrt().round() as u64).max(1);
        let rows = count.div_ceil(2 * cols);
        let base = obj.vertices;
        for i in 0..=rows {
            let z = DEPTH * (0.5 - i as f64 / rows as f64);
            for j in 0..=cols {
                let x = WIDTH * (j as f64 / cols as f64 - 0.5);
                obj.vertex([x, self.height(x, z), z])?;
            }
        }
        let stride = cols + 1;
        let mut left = count;
        'rows: for i in 0..rows {
            for j in 0..cols {
                let (v00, v01) = (i * stride + j, i * stride + j + 1);
                let (v10, v11) = (v00 + stride, v01 + stride);
                for [a, b, c] in [[v00, v01, v10], [v01, v11, v10]] {
                    if left == 0 {
                        break 'rows;
                    }
                    obj.face(base, a, b, c)?;
                    left -= 1;
                }
            }
        }
        Ok(())
    }
}

/// A closed object: a UV sphere (`segments` around, `rings` vertex rings between the poles),
/// scaled to an ellipsoid, displaced by a few random sine lobes (zero for smooth ones), turned
/// about y and placed on the ground.
struct Blob {
    smooth: bool,
    segments: u64,
    rings: u64,
    centre: [f64; 3],
    radii: [f64; 3],
    yaw: f64,
    lobes: [([f64; 3], f64, f64, f64); 3],
}

impl Blob {
    /// A random object; a `boulder` is one of the few big rocks that give the scene its height.
    fn random(
        rng: &mut SplitMix64,
        plan: &Plan,
        ground: &Ground,
        budget: u64,
        boulder: bool,
    ) -> Blob {
        let (radius, size) = if boulder {
            let radius = rng.range(0.6, 1.0) * BOULDER_RADIUS;
            (radius, (radius / plan.radius_scale).min(12.0))
        } else {
            // u * u * u, not powi: powi's rounding is not specified across platforms.
            let u = rng.unit();
            let size = 0.4 + 2.4 * (u * u * u);
            ((plan.radius_scale * size).min(MAX_RADIUS), size)
        };
        let smooth = !boulder && rng.unit() < 0.3;
        let tall = match (boulder, smooth) {
            (true, _) => rng.range(0.9, 1.4),
            (false, true) => rng.range(0.6, 1.6),
            (false, false) => rng.range(0.5, 1.1),
        };
        let radii = [
            radius * rng.range(0.8, 1.2),
            radius * tall,
            radius * rng.range(0.8, 1.2),
        ];
        let amp = if smooth { 0.0 } else { 1.0 };
        let lobes = [(); 3].map(|()| {
            (
                rng.unit_vector(),
                rng.range(2.0, 6.0),
                rng.range(0.0, 2.0 * PI),
                amp * rng.range(0.04, 0.12),
            )
        });
        // Keep the whole object over the ground (lobes displace by at most 36%).
        let margin = 1.4 * radii[0].max(radii[2]);
        let (rx, rz) = (0.5 * WIDTH - margin, 0.5 * DEPTH - margin);
        let (x, z) = (rng.range(-rx, rx), rng.range(-rz, rz));
        let sink = if boulder {
            rng.range(0.75, 0.9)
        } else {
            rng.range(0.55, 0.85)
        };
        let y = ground.height(x, z) + radii[1] * sink;
        let yaw = rng.range(0.0, 2.0 * PI);
        let wanted = plan.mean_object_triangles * size * rng.range(0.7, 1.4);
        let mut rings = (((wanted / 4.0).sqrt().round()) as u64).max(1);
        let mut segments = (((2 * rings) as f64 * rng.range(0.8, 1.25)).round() as u64).max(3);
        if 2 * segments * rings > budget {
            rings = rings.min(budget / (2 * 3));
            segments = budget / (2 * rings);
        }
        Blob {
            smooth,
            segments,
            rings,
            centre: [x, y, z],
            radii,
            yaw,
            lobes,
        }
    }

    fn kind_name(&self) -> &'static str {
        if self.smooth { "ellipsoid" } else { "rock" }
    }

    fn triangles(&self) -> u64 {
        2 * self.segments * self.rings
    }

    fn point(&self, n: [f64; 3]) -> [f64; 3] {
        let f = 1.0
            + self
                .lobes
                .iter()
                .map(|(d, w, p, a)| {
                    a * libm::sin(w * (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) + p)
                })
                .sum::<f64>();
        let [lx, ly, lz] = [0, 1, 2].map(|i| self.radii[i] * f * n[i]);
        let (s, c) = (libm::sin(self.yaw), libm::cos(self.yaw));
        let [cx, cy, cz] = self.centre;
        [cx + c * lx + s * lz, cy + ly, cz - s * lx + c * lz]
    }

    /// Vertices: north pole, `rings` rings of `segments`, south pole. Faces wound outwards.
    fn write<W: Write>(&self, obj: &mut ObjWriter<W>) -> io::Result<()> {
        let (s, k) = (self.segments, self.rings);
        let base = obj.vertices;
        obj.vertex(self.point([0.0, 1.0, 0.0]))?;
        for q in 1..=k {
            let theta = PI * q as f64 / (k + 1) as f64;
            let (st, ct) = (libm::sin(theta), libm::cos(theta));
            for j in 0..s {
                let phi = 2.0 * PI * j as f64 / s as f64;
                obj.vertex(self.point([st * libm::cos(phi), ct, st * libm::sin(phi)]))?;
            }
        }
        obj.vertex(self.point([0.0, -1.0, 0.0]))?;
        let ring = |q: u64, j: u64| 1 + (q - 1) * s + j % s;
        let south = 1 + k * s;
        for j in 0..s {
            obj.face(base, 0, ring(1, j + 1), ring(1, j))?;
        }
        for q in 1..k {
            for j in 0..s {
                let (u0, u1, l0, l1) = (
                    ring(q, j),
                    ring(q, j + 1),
                    ring(q + 1, j),
                    ring(q + 1, j + 1),
                );
                obj.face(base, u0, u1, l1)?;
                obj.face(base, u0, l1, l0)?;
            }
        }
        for j in 0..s {
            obj.face(base, south, ring(k, j), ring(k, j + 1))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
