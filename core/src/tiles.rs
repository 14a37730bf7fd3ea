//! The order the monolithic renderer traces camera rays in: bands of [`BAND_ROWS`] image
//! rows, each band tile by tile ([`TILE_WIDTH`] pixels wide, the band's height; tiles left to
//! right, rows top to bottom in a tile). A closest-hit packet of camera rays is
//! [`crate::bvh::RAY_PACKET`] (64) consecutive rays ([`crate::bvh::camera_packet`]), so below
//! 64 samples per pixel it covers whole tiles (one at 4 spp, four side by side at 1 spp)
//! rather than a strip of one row, and its rays stay together deeper in the BVH (measured with
//! packets of 32 at 1 spp: +20% closest-hit packet speed on a 1M-triangle mesh, a few per cent
//! on small ones: `core/src/bvh/README.md`, "Packets of square tiles"). The order never changes
//! a result: every ray's answer is exact, and the renderer puts each pixel where it belongs.

use std::ops::Range;

/// Image rows per band.
pub const BAND_ROWS: u32 = 4;
/// Pixels of one row of a tile.
pub const TILE_WIDTH: u32 = 4;

/// The pixels of `band` (the row-major pixel range of an image `width` pixels wide that lies in
/// one band of [`BAND_ROWS`] rows; it may start or end mid-row) in tile order: tiles left to
/// right, in a tile rows top to bottom, in a row left to right.
pub fn tile_order(band: Range<u64>, width: u32) -> impl Iterator<Item = u64> {
    let width = u64::from(width.max(1));
    let (first_row, last_row) = (band.start / width, band.end.saturating_sub(1) / width);
    (0..width)
        .step_by(TILE_WIDTH as usize)
        .flat_map(move |x0| {
            (first_row..=last_row).flat_map(move |y| {
                (x0..(x0 + u64::from(TILE_WIDTH)).min(width)).map(move |x| y * width + x)
            })
        })
        .filter(move |p| band.contains(p))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_visit_every_pixel_of_a_band_once() {
        // Width 10: tiles of 4, 4 and 2 columns. The band of rows 4..8 from pixel 43 (row 4,
        // column 3) to 75 (row 7, column 5), partial rows at both ends.
        let order: Vec<u64> = tile_order(43..76, 10).collect();
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (43..76).collect::<Vec<_>>());
        assert_eq!(&order[..6], &[43, 50, 51, 52, 53, 60]);
        // A full band of a 6-wide image: the first tile is 4 columns by 4 rows.
        let full: Vec<u64> = tile_order(0..24, 6).collect();
        assert_eq!(
            &full[..16],
            &[0, 1, 2, 3, 6, 7, 8, 9, 12, 13, 14, 15, 18, 19, 20, 21]
        );
        assert_eq!(&full[16..], &[4, 5, 10, 11, 16, 17, 22, 23]);
    }
}
