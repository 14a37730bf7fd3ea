//! Diffuse texture maps (`map_Kd`): decoded once, sampled where a hit is shaded.
//!
//! A [`Texture`] holds 8-bit sRGB texels, three bytes per texel, row 0 at the top of the image
//! (as image files store them). [`Texture::sample`] looks one up at texture coordinates (u, v)
//! with the OBJ convention ((0, 0) is the image's bottom-left corner), repeat wrapping and
//! bilinear filtering between the four nearest texel centres, in linear radiance: each texel is
//! decoded from sRGB through one 256-entry table before filtering, as Mitsuba 3's `bitmap`
//! texture does (`filter_type = bilinear`, `wrap_mode = repeat`, `raw = false`). Sampling is
//! plain f32 arithmetic in a fixed order, so it gives the same bits on every CPU.
//!
//! Alpha is ignored (surfaces stay opaque); 16-bit and grey images are converted to 8-bit RGB
//! as the `image` crate does.
//!
//! Within a job a texture is stored once under its content key ([`Texture::content_key`]), as
//! a compressed block of kind [`crate::shuffle::RecordKind::Texture`] ([`encode_texture`]).

mod codec;
mod decode;
mod linear;

pub use codec::{decode_texture, encode_texture};
pub use decode::{MAX_TEXTURE_SIDE, decode_texture_file, decode_texture_image};

use std::sync::OnceLock;

/// A decoded diffuse texture.
#[derive(Clone)]
pub struct Texture {
    /// The file it came from, as the material library names it (for messages).
    pub name: String,
    /// Width in texels (at least 1).
    pub width: u32,
    /// Height in texels (at least 1).
    pub height: u32,
    /// `width * height` sRGB texels, 3 bytes each (r, g, b), rows from the top.
    pub texels: Vec<u8>,
    /// The texels decoded, made at the first lookup in lanes ([`linear`]).
    linear: OnceLock<Option<Vec<[f32; 4]>>>,
}

/// Equal when the name, size and texels are (the decoded texels follow from them).
impl PartialEq for Texture {
    fn eq(&self, other: &Self) -> bool {
        (&self.name, self.width, self.height, &self.texels)
            == (&other.name, other.width, other.height, &other.texels)
    }
}

impl Eq for Texture {}

impl std::fmt::Debug for Texture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Texture {{ name: {:?}, {}x{}, key {} }}",
            self.name,
            self.width,
            self.height,
            self.content_key()
        )
    }
}

impl Texture {
    /// The texture `name` of `width` x `height` sRGB texels (`texels`: 3 bytes each, rows from
    /// the top).
    pub fn new(name: String, width: u32, height: u32, texels: Vec<u8>) -> Texture {
        Texture {
            name,
            width,
            height,
            texels,
            linear: OnceLock::new(),
        }
    }

    /// Bytes the texture holds in memory once decoded and shaded: its texels, and the decoded
    /// texels where a texture that small has them (`texture/linear.rs`).
    pub fn memory_bytes(&self) -> u64 {
        self.texels.len() as u64 + linear::bytes(self.width, self.height)
    }

    /// The content key: 16 hex digits of the FNV-1a 64 digest of the size and the texels (not
    /// the name), so the same picture under two names is stored once per job.
    pub fn content_key(&self) -> String {
        let digest = hort_digest::Fnv1a64::new()
            .bytes(&self.width.to_le_bytes())
            .bytes(&self.height.to_le_bytes())
            .bytes(&self.texels)
            .finish();
        format!("{digest:016x}")
    }

    /// The linear radiance factor at texture coordinates `uv`: bilinear between the four
    /// nearest texel centres, wrapping around at every edge. Non-finite coordinates read
    /// texel (0, 0)'s corner of the grid, as 0 does.
    #[inline]
    pub fn sample(&self, uv: [f32; 2]) -> [f32; 3] {
        let (x0, y0, fx, fy) = self.grid(uv);
        let [a, b, c, d] = self.texels(srgb_to_linear_table(), x0, y0);
        let mut out = [0.0f32; 3];
        for (k, slot) in out.iter_mut().enumerate() {
            *slot = bilinear((fx, fy), [a[k], b[k], c[k], d[k]]);
        }
        out
    }

    /// [`Texture::sample`] at `N` coordinates (`u[k]`, `v[k]`), one per lane: `out[channel][k]`.
    /// The same operations per lane, so every lane is `sample`'s bits: the grid in a plain
    /// array loop that the compiler vectorizes for the calling function's instruction set,
    /// then lane by lane the filter over the texels decoded once (`texture/linear.rs`) where
    /// the texture has them, else the texels read through the table and the filter in array
    /// loops.
    #[inline(always)]
    pub fn sample_lanes<const N: usize>(&self, u: [f32; N], v: [f32; N]) -> [[f32; N]; 3] {
        let (mut x0, mut y0, mut fx, mut fy) = ([0.0; N], [0.0; N], [0.0; N], [0.0; N]);
        for k in 0..N {
            (x0[k], y0[k], fx[k], fy[k]) = self.grid([u[k], v[k]]);
        }
        if let Some(linear) = self.linear_texels() {
            return self.sample_lanes_linear(linear, (&x0, &y0), (&fx, &fy));
        }
        let lut = srgb_to_linear_table();
        let mut corners = [[[0.0f32; N]; 3]; 4];
        for k in 0..N {
            for (lanes, texel) in corners.iter_mut().zip(self.texels(lut, x0[k], y0[k])) {
                for (lanes, value) in lanes.iter_mut().zip(texel) {
                    lanes[k] = value;
                }
            }
        }
        let [a, b, c, d] = &corners;
        let mut out = [[0.0f32; N]; 3];
        for (channel, out) in out.iter_mut().enumerate() {
            let (a, b, c, d) = (&a[channel], &b[channel], &c[channel], &d[channel]);
            for k in 0..N {
                out[k] = bilinear((fx[k], fy[k]), [a[k], b[k], c[k], d[k]]);
            }
        }
        out
    }

    /// Where `uv` falls in the grid of texel centres: the grid cell's corner (x0, y0) (whole
    /// numbers, not yet wrapped) and the fractions (fx, fy) across it.
    #[inline(always)]
    fn grid(&self, uv: [f32; 2]) -> (f32, f32, f32, f32) {
        let (w, h) = (self.width as f32, self.height as f32);
        let finite = |x: f32| if x.is_finite() { x } else { 0.0 };
        let x = finite(uv[0] * w - 0.5);
        let y = finite((1.0 - uv[1]) * h - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        (x0, y0, x - x0, y - y0)
    }

    /// The columns and rows of the four texels around grid cell (x0, y0), wrapped: x0's column
    /// and the next, y0's row and the next.
    #[inline(always)]
    fn wrapped(&self, x0: f32, y0: f32) -> [usize; 4] {
        // `rem_euclid` divides: most coordinates are already in range, and a power-of-two
        // size wraps by a mask (the same value, in two's complement).
        let wrap = |i: f32, n: u32| {
            let (i, n) = (i as i64, i64::from(n));
            let wrapped = if (0..n).contains(&i) {
                i
            } else if n.count_ones() == 1 {
                i & (n - 1)
            } else {
                i.rem_euclid(n)
            };
            wrapped as usize
        };
        let (xa, ya) = (wrap(x0, self.width), wrap(y0, self.height));
        let xb = if xa + 1 == self.width as usize {
            0
        } else {
            xa + 1
        };
        let yb = if ya + 1 == self.height as usize {
            0
        } else {
            ya + 1
        };
        [xa, xb, ya, yb]
    }

    /// The linear values (through `lut`, [`srgb_to_linear_table`]) of the four texels around
    /// grid cell (x0, y0), wrapped: (x0, y0), (x0 + 1, y0), (x0, y0 + 1), (x0 + 1, y0 + 1).
    #[inline(always)]
    fn texels(&self, lut: &[f32; 256], x0: f32, y0: f32) -> [[f32; 3]; 4] {
        let [xa, xb, ya, yb] = self.wrapped(x0, y0);
        // Two rows, then three bytes a texel: six bounds checks, where indexing byte by byte
        // took twelve.
        let row_bytes = 3 * self.width as usize;
        let row = |y: usize| &self.texels[y * row_bytes..][..row_bytes];
        let texel = |row: &[u8], x: usize| {
            let [r, g, b] = row[3 * x..][..3] else {
                unreachable!("three bytes")
            };
            [lut[r as usize], lut[g as usize], lut[b as usize]]
        };
        let (top, bottom) = (row(ya), row(yb));
        [
            texel(top, xa),
            texel(top, xb),
            texel(bottom, xa),
            texel(bottom, xb),
        ]
    }
}

/// Bilinear filtering of one channel: `corners` at (0, 0), (1, 0), (0, 1), (1, 1) of the cell,
/// at fractions `(fx, fy)` across it.
#[inline(always)]
fn bilinear((fx, fy): (f32, f32), [a, b, c, d]: [f32; 4]) -> f32 {
    let top = (1.0 - fx) * a + fx * b;
    let bottom = (1.0 - fx) * c + fx * d;
    (1.0 - fy) * top + fy * bottom
}

/// A textured triangle's texture (an index into the scene's, or the plan's, textures) and its
/// corners' texture coordinates, in corner order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TexturedCorners {
    /// Index of the texture in the scene's textures.
    pub texture: u32,
    /// (u, v) of corners 0, 1 and 2.
    pub uv: [[f32; 2]; 3],
}

impl TexturedCorners {
    /// The diffuse reflectance at barycentrics `b` of a triangle whose material has reflectance
    /// `kd` and whose texture is `texture`: `kd` times the texture's value at the interpolated
    /// texture coordinates. Every renderer path shades through this one function, so textured
    /// hits match bit for bit.
    #[inline]
    pub fn kd_at(&self, kd: [f32; 3], texture: &Texture, b: [f32; 3]) -> [f32; 3] {
        let [t0, t1, t2] = self.uv;
        let uv = [
            b[0] * t0[0] + b[1] * t1[0] + b[2] * t2[0],
            b[0] * t0[1] + b[1] * t1[1] + b[2] * t2[1],
        ];
        let c = texture.sample(uv);
        [kd[0] * c[0], kd[1] * c[1], kd[2] * c[2]]
    }

    /// [`TexturedCorners::kd_at`] at `N` hits on this triangle, one per lane (`b[corner][k]`,
    /// `out[channel][k]`): the same operations per lane ([`Texture::sample_lanes`]).
    #[inline(always)]
    pub fn kd_lanes<const N: usize>(
        &self,
        kd: [f32; 3],
        texture: &Texture,
        b: &[[f32; N]; 3],
    ) -> [[f32; N]; 3] {
        let [t0, t1, t2] = self.uv;
        let (mut u, mut v) = ([0.0; N], [0.0; N]);
        for k in 0..N {
            u[k] = b[0][k] * t0[0] + b[1][k] * t1[0] + b[2][k] * t2[0];
            v[k] = b[0][k] * t0[1] + b[1][k] * t1[1] + b[2][k] * t2[1];
        }
        let mut out = texture.sample_lanes(u, v);
        for (out, kd) in out.iter_mut().zip(kd) {
            for x in out.iter_mut() {
                // `kd * c`, as `kd_at` multiplies (the product commutes bit for bit).
                *x *= kd;
            }
        }
        out
    }
}

/// The sRGB decoding of each 8-bit value (IEC 61966-2-1), computed once with the `libm` crate
/// so the table is the same on every CPU.
pub fn srgb_to_linear_table() -> &'static [f32; 256] {
    static TABLE: OnceLock<[f32; 256]> = OnceLock::new();
    TABLE.get_or_init(|| {
        std::array::from_fn(|i| {
            let c = i as f64 / 255.0;
            let linear = if c <= 0.04045 {
                c / 12.92
            } else {
                libm::pow((c + 0.055) / 1.055, 2.4)
            };
            linear as f32
        })
    })
}

#[cfg(test)]
mod tests;
