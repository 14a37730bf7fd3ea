//! A texture's texels decoded once, for lookups in lanes.
//!
//! Through the sRGB table, one lookup's four texels are twelve byte reads and twelve table
//! reads, lane by lane. Decoded once into four f32 a texel (red, green, blue, 0), a lane reads
//! its four texels as four 16-byte loads and filters all three channels at once. The
//! measurements (the globe's shading phase before and after, and AVX-512 gathers, tried and
//! dropped) are in `docs/perf/time-per-sample.md`, "Decoded texels for lookups in lanes".
//!
//! The decoded texels cost 16 bytes a texel beside the texel's 3, so only textures of at most
//! [`MAX_TEXELS`] have them (16 MB at most); larger ones are read through the table.
//! [`crate::texture::Texture::memory_bytes`] counts them wherever a texture may have them.
//!
//! Guarantee: a value is the table's for the texel's byte, and the filter is
//! [`super::bilinear`]'s operations in its order on each channel, so every lookup gives the
//! bits the table gives.

use wide::f32x4;

use super::{Texture, srgb_to_linear_table};

/// The most texels a texture has decoded (1024 x 1024).
pub const MAX_TEXELS: u64 = 1 << 20;

/// Bytes of the decoded texels of a `width` x `height` texture: 16 a texel up to
/// [`MAX_TEXELS`], else none.
pub fn bytes(width: u32, height: u32) -> u64 {
    let texels = u64::from(width) * u64::from(height);
    if texels <= MAX_TEXELS { 16 * texels } else { 0 }
}

impl Texture {
    /// The decoded texels, row by row as the bytes are (made at the first call), or `None`
    /// for a texture of more than [`MAX_TEXELS`].
    pub(super) fn linear_texels(&self) -> Option<&[[f32; 4]]> {
        self.linear
            .get_or_init(|| {
                let lut = srgb_to_linear_table();
                let decode = |t: &[u8]| {
                    [
                        lut[t[0] as usize],
                        lut[t[1] as usize],
                        lut[t[2] as usize],
                        0.0,
                    ]
                };
                (bytes(self.width, self.height) > 0)
                    .then(|| self.texels.chunks_exact(3).map(decode).collect())
            })
            .as_deref()
    }

    /// The bilinear filter of each lane's grid cell (`x0[k]`, `y0[k]`) at fractions (`fx[k]`,
    /// `fy[k]`) over the decoded texels `linear`: [`Texture::sample_lanes`]'s values.
    #[inline(always)]
    pub(super) fn sample_lanes_linear<const N: usize>(
        &self,
        linear: &[[f32; 4]],
        (x0, y0): (&[f32; N], &[f32; N]),
        (fx, fy): (&[f32; N], &[f32; N]),
    ) -> [[f32; N]; 3] {
        let mut out = [[0.0f32; N]; 3];
        let w = self.width as usize;
        for k in 0..N {
            let [xa, xb, ya, yb] = self.wrapped(x0[k], y0[k]);
            let texel = |x: usize, y: usize| f32x4::new(linear[y * w + x]);
            let (a, b, c, d) = (texel(xa, ya), texel(xb, ya), texel(xa, yb), texel(xb, yb));
            // `bilinear`'s operations, on the three channels at once.
            let (gx, hx) = (f32x4::splat(1.0 - fx[k]), f32x4::splat(fx[k]));
            let (gy, hy) = (f32x4::splat(1.0 - fy[k]), f32x4::splat(fy[k]));
            let top = gx * a + hx * b;
            let bottom = gx * c + hx * d;
            let [r, g, b, _] = (gy * top + hy * bottom).to_array();
            [out[0][k], out[1][k], out[2][k]] = [r, g, b];
        }
        out
    }
}
