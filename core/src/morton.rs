//! Morton codes: the bits of three grid coordinates interleaved, so that sorting by code
//! walks the grid along a Z-order curve and nearby cells get nearby codes. The spatial
//! splitter, the scene partition tasks and the fast BVH build order triangles by it.

/// The Morton code of the cell `[x, y, z]` (each below 2^21): bit i of x at bit 3i, of y at
/// 3i + 1, of z at 3i + 2; a 63-bit code. Coordinates below 2^b give codes below 2^(3b).
pub(crate) fn morton_code([x, y, z]: [u64; 3]) -> u64 {
    spread(x) | spread(y) << 1 | spread(z) << 2
}

/// The low 21 bits of `v` spread to every third bit.
fn spread(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_spread_interleaves() {
        assert_eq!(spread(0b11), 0b1001);
        assert_eq!(spread(0x1f_ffff).count_ones(), 21);
        for bit in 0..21 {
            assert_eq!(spread(1 << bit), 1 << (3 * bit));
        }
        assert_eq!(morton_code([1, 0, 0]), 1);
        assert_eq!(morton_code([0, 1, 0]), 2);
        assert_eq!(morton_code([0, 0, 1]), 4);
        assert_eq!(morton_code([1023, 1023, 1023]), (1 << 30) - 1);
        assert_eq!(morton_code([0x1f_ffff; 3]), (1 << 63) - 1);
    }
}
